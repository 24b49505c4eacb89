"""The feedback pages: nbgrader's ``generate_feedback``, configured by the course's settings
(:mod:`cvkit.course.nbgrader_settings`: the safe exporter of :mod:`.safety`, the waiting marks,
the hidden tests' source removed), in this process or in a grading worker between two jobs.
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterable

from .files import write_whole
from .progress import Phase
from .state import CourseState


def write_feedback(course: CourseState, submissions: Iterable[tuple[str, str]], bar: Phase | None = None) -> None:
    """nbgrader's ``generate_feedback`` (in this process) for these (student, assignment) pairs:
    HTML pages with the trusted reports, hidden tests' source removed (``bar`` counts the pages
    written); a page that fails is named in ``.cvkit/feedback_errors.log``, never stops the others."""
    pairs = sorted(set(submissions))
    if not pairs:
        return
    api = course.nbgrader_api()
    failed = []
    for student, assignment in pairs:
        try:
            outcome = api.generate_feedback(assignment, student_id=student, force=True)
        except Exception as error:  # noqa: BLE001 - one page must not stop the others
            outcome = {"success": False, "error": repr(error)}
        if not outcome.get("success"):
            failed.append(f"{student}/{assignment}: {outcome.get('error', '')[-500:]}")
        if bar is not None:
            bar.update()
    if failed:
        write_whole(course.root / ".cvkit" / "feedback_errors.log", "\n".join(failed))


def feedback_submissions(root: str, db_url: str, project: str, pairs: list[tuple[str, str]]) -> None:
    """:func:`write_feedback` for (student, assignment) pairs of the course at ``root``, in a worker
    process (plain arguments: the worker builds its own :class:`~.state.CourseState`)."""
    write_feedback(CourseState(Path(root), db_url, Path(project)), pairs)
