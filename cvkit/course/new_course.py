"""A course folder of its own (``cvkit new course DIR``): nothing of it lives in a cvkit checkout.

The folder is nbgrader's own layout, and every ``cvkit course …`` command, plain ``nbgrader …``
and the formgrader work on it from inside it::

    DIR/
      nbgrader_config.py   calls cvkit.course.nbgrader_settings.configure with DIR as the root
      plan.toml            the chapters, due dates, late policy and [course] id
      source/<chapter>/    the chapters' source notebooks: copies of cvkit's chapters (from a
                           checkout), and the instructor's own (docs/own-course.md)
      release/ submitted/ autograded/ feedback/ exports/ gradebook.db  (made by the commands)

:func:`new_course` makes it (or adds chapters to it); nothing is written anywhere else.
"""
from __future__ import annotations

import os
import re
import shutil
from pathlib import Path
from typing import Sequence

from .state import COURSE_CONFIG, is_course_folder, project_root

__all__ = ["COURSE_CONFIG", "CourseFolderError", "is_course_folder", "kit_chapters", "new_course"]

_CONFIG_BODY = (COURSE_CONFIG
                + "# (cvkit.course.nbgrader_settings explains them; edit plan.toml for due dates and late penalties)\n"
                + "from pathlib import Path\n\n"
                + "from cvkit.course.nbgrader_settings import configure\n\n"
                + "configure(get_config(), Path(__file__).resolve().parent)  # noqa: F821\n")
_COURSE_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_IGNORE = shutil.ignore_patterns(".ipynb_checkpoints", "__pycache__", "*.pyc", ".DS_Store")


class CourseFolderError(ValueError):
    """What is wrong with a course folder or the chapters asked for, and what to do."""


def kit_chapters(project: str | os.PathLike[str]) -> list[str]:
    """cvkit's chapters in the checkout ``project`` (``lectures/chNN_*``)."""
    return sorted(p.name for p in (Path(project) / "lectures").glob("ch*_*") if p.is_dir())


def new_course(folder: str | os.PathLike[str], chapters: Sequence[str] = (), course_id: str | None = None,
               project: str | os.PathLike[str] | None = None) -> list[Path]:
    """Make the course folder ``folder`` with cvkit's ``chapters``, or add them to it.

    Parameters
    ----------
    folder : path
        The course folder: new or empty, or one made by this function before (then the chapters
        not in it yet are added, to ``source/`` and to the plan).
    chapters : sequence of str
        cvkit's chapters to copy (ids of ``lectures/`` of the checkout), e.g.
        ``["ch03_filtering"]``; ``["all"]`` for every chapter; none for a course of the
        instructor's own chapters only.
    course_id : str, optional
        nbgrader's course id (``[course] id`` of the plan; the exchange's folder on a hub);
        default: the folder's name.
    project : path, optional
        The cvkit checkout the chapters come from (default: the one this cvkit runs from).

    Returns
    -------
    list of Path
        What was written.

    Raises
    ------
    CourseFolderError
        A folder that is not empty and not a course folder, inside the checkout, an unknown
        chapter, a course id nbgrader cannot use — each with what to do; nothing is written.
    """
    from .plan import LatePolicy, Plan, PlannedAssignment, plan_toml, read_plan

    folder = Path(folder).resolve()
    existing = is_course_folder(folder)
    if folder.exists() and not folder.is_dir():
        raise CourseFolderError(f"{folder} is a file: choose a folder for the course")
    if folder.is_dir() and any(folder.iterdir()) and not existing:
        raise CourseFolderError(f"{folder} is not empty and not a course folder made by cvkit new course: choose a "
                                "new or empty folder")
    course_id = course_id or folder.name
    if not _COURSE_ID.match(course_id):
        raise CourseFolderError(f"course id {course_id!r}: letters, digits, '_', '.', '-' (nbgrader uses it as a "
                                "folder name); give one with --course-id")
    wanted = list(dict.fromkeys(chapters))
    if wanted:
        if project is None:
            try:
                project = project_root()
            except FileNotFoundError:
                raise CourseFolderError("cvkit's chapters come from a cvkit checkout (git clone it, and run cvkit "
                                        "from its environment); a course of your own chapters needs none: "
                                        "leave out --chapter") from None
        project = Path(project).resolve()
        if folder == project or project in folder.parents:
            raise CourseFolderError(f"{folder} is inside the cvkit checkout {project}: a course folder of its own "
                                    "lives outside it (e.g. ~/courses/ipcv-2027)")
        available = kit_chapters(project)
        if wanted == ["all"]:
            wanted = available
        unknown = [c for c in wanted if c not in available]
        if unknown:
            raise CourseFolderError(f"no chapter {', '.join(unknown)} in cvkit (chapters: {', '.join(available)})")
    written: list[Path] = []
    source = folder / "source"
    source.mkdir(parents=True, exist_ok=True)
    for chapter in wanted:
        target = source / chapter
        if target.exists():
            continue
        shutil.copytree(Path(project) / "lectures" / chapter, target, symlinks=False, ignore=_IGNORE)  # type: ignore[arg-type]
        written.append(target)
    config = folder / "nbgrader_config.py"
    if not existing:
        config.write_text(_CONFIG_BODY)
        written.append(config)
    plan_file = folder / "plan.toml"
    if plan_file.exists():  # the instructor's plan: the new chapters appended, nothing else touched
        have = set(read_plan(plan_file, []).ids())
        added = [c for c in wanted if c not in have]
        if added:
            text = plan_file.read_text().rstrip("\n")
            plan_file.write_text(text + "".join(f'\n\n[[assignment]]\nid = "{c}"' for c in added) + "\n")
            written.append(plan_file)
    else:
        plan = Plan(tuple(PlannedAssignment(c, "", None) for c in wanted), LatePolicy(), course_id)
        plan_file.write_text(plan_toml(plan, course_id))
        written.append(plan_file)
    return written
