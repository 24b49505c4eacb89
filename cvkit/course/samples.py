"""Sample submissions of a course: the solutions, typical mistakes, a blank copy.

The solutions come from the instructor's source notebooks (:func:`solution_sources`); the
typical mistakes from ``autograders/samples/<assignment>/typical_mistakes.py``
(:func:`typical_mistakes`).
"""
from __future__ import annotations

import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..grading.runtime.cells import cell_source, grade_id
from . import received

if TYPE_CHECKING:
    from .state import CourseState

SOLUTION_BEGIN = "### BEGIN SOLUTION"
SOLUTION_END = "### END SOLUTION"
SAMPLE_STUDENTS = ("sample_complete", "sample_mistakes", "sample_blank")


def solution_sources(notebook: dict[str, Any]) -> dict[str, str]:
    """grade_id → source of each solution cell with the solution markers removed; for a written
    answer, the model answer without its rubric (what a student who knows the answer writes)."""
    from ..grading.runtime.cells import is_solution

    out = {}
    for cell in notebook.get("cells", []):
        name = grade_id(cell)
        if not is_solution(cell) or name is None:
            continue
        source = cell_source(cell)
        if cell.get("cell_type") == "markdown":
            source = source.split("**Rubric", 1)[0].replace("**Model answer.**", "").strip()
        lines = [line for line in source.splitlines() if line.strip() not in (SOLUTION_BEGIN, SOLUTION_END)]
        out[name] = "\n".join(lines)
    return out


def typical_mistakes(folder: Path) -> dict[str, str]:
    """grade_id → cell source, from ``typical_mistakes.py`` (sections ``# %% <grade_id>``)."""
    path = folder / "typical_mistakes.py"
    if not path.exists():
        return {}
    cells: dict[str, str] = {}
    current: str | None = None
    lines: list[str] = []
    for line in path.read_text().splitlines():
        match = re.match(r"^# %% (\S+)\s*$", line)
        if match:
            if current:
                cells[current] = "\n".join(lines).strip("\n")
            current, lines = match.group(1), []
        elif current:
            lines.append(line)
    if current:
        cells[current] = "\n".join(lines).strip("\n")
    return cells


def make_samples(course: CourseState, assignment: str) -> list[str]:
    """Submit the three samples of ``assignment`` (see :meth:`Course.make_samples`)."""
    from ..grading.runtime.cells import is_solution

    source_nbs = {p.name: json.loads(p.read_text()) for p in sorted((course.source_dir / assignment).glob("*.ipynb"))}
    mistakes = typical_mistakes(course.project / "autograders" / "samples" / assignment)
    made = []
    for student in SAMPLE_STUDENTS:
        notebooks = {}
        for release in course.release_notebooks(assignment):
            nb = json.loads(release.read_text())
            source = source_nbs.get(release.name)
            if student != "sample_blank" and source is not None:
                solutions = solution_sources(source)
                for cell in nb["cells"]:
                    name = grade_id(cell)
                    if not is_solution(cell) or name is None:
                        continue
                    if student == "sample_mistakes" and name in mistakes:
                        cell["source"] = mistakes[name]
                    elif name in solutions:
                        cell["source"] = solutions[name]
            notebooks[release.name] = nb
        received.place_submission(course, student, assignment, notebooks)
        made.append(student)
    return made


def student_order(student: str) -> tuple[int, str]:
    """Sort key of students: the samples first, in their order, then by name."""
    if student in SAMPLE_STUDENTS:
        return SAMPLE_STUDENTS.index(student), student
    return len(SAMPLE_STUDENTS), student
