"""Results of a graded course: per student and exercise, the score from nbgrader's gradebook,
the mistakes the trusted checks named, the problems they saw and the flags they raised; and the
audit that no submission lost its grade.

The trusted checks' verdicts are read as data: each graded test cell carries them in its
metadata (``metadata.cvkit.report``), the flags are in the notebook's (``metadata.cvkit``).
"""
from __future__ import annotations

import copy
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

from ..grading.report import MIME_TYPE, finding
from .notebook import exercise_name, grade_id, graded_notebooks, metadata_flags, read_graded
from .samples import student_order

if TYPE_CHECKING:
    from .state import CourseState


@dataclass
class ExerciseScore:
    name: str
    score: float
    max_score: float
    mistakes: list = field(default_factory=list)
    problems: list = field(default_factory=list)
    flags: list = field(default_factory=list)
    to_mark: bool = False  # a written question or open task not yet marked by hand (formgrader)


def scores(course: CourseState, assignment: str) -> dict[str, list[ExerciseScore]]:
    """See :meth:`Course.scores`. Within :meth:`~.state.CourseState.scores_read_once` an
    assignment's scores are read once (each caller gets its own copy)."""
    settled = course.settled_scores
    if settled is None:
        return _scores(course, assignment)
    if assignment not in settled:
        settled[assignment] = _scores(course, assignment)
    return copy.deepcopy(settled[assignment])


def _scores(course: CourseState, assignment: str) -> dict[str, list[ExerciseScore]]:
    from nbgrader.api import Gradebook

    table: dict[str, list[ExerciseScore]] = {}
    submitted = course.submissions([assignment])
    if not submitted:  # nothing to read: the gradebook is not opened (an item analysis asks for every chapter)
        return table
    not_graded = course.not_graded()
    cells = _cell_order(course, assignment)
    order: dict[str, int] = {}  # exercise name → position of its first graded cell
    for cell_id in cells:
        order.setdefault(exercise_name(cell_id), len(order))
    with Gradebook(course.db_url) as gb:
        recorded = _recorded_grades(gb, assignment)
    for student, _ in submitted:
        if f"{student}/{assignment}" in not_graded or student not in recorded:
            continue  # no score: listed as not graded (Course.table, the exports), or not in the gradebook
        graded = course.root / "autograded" / student / assignment
        found = reported_findings(graded)
        exercises: dict[str, ExerciseScore] = {}
        for notebook in recorded[student].values():
            # in the notebook's order (the visible test's findings before the hidden tests'), so
            # that the table's first problem of an exercise is the same on every run
            for grade in sorted(notebook, key=lambda g: (cells.get(g.name, len(cells)), g.name)):
                name = exercise_name(grade.name, answers=False)
                entry = exercises.setdefault(name, ExerciseScore(name, 0.0, 0.0))
                entry.to_mark = entry.to_mark or grade.needs_manual_grade
                entry.score += grade.score
                entry.max_score += grade.max_score
                for kind, text in found.get(grade.name, []):
                    bucket = entry.mistakes if kind == "mistake" else entry.problems
                    if text not in bucket:
                        bucket.append(text)
        for flag in _flags(graded):
            where, _, what = flag.partition(": ")
            name = exercise_name(where)
            target = exercises.get(name)
            if target is None:
                target = exercises.setdefault("(notebook)", ExerciseScore("(notebook)", 0.0, 0.0))
            target.flags.append(what if target.name == name else flag)
        table[student] = sorted(exercises.values(), key=lambda e: order.get(e.name, len(order)))
    return dict(sorted(table.items(), key=lambda item: student_order(item[0])))


@dataclass(frozen=True)
class _Recorded:
    """One grade of nbgrader's gradebook, as the scores use it."""

    name: str
    score: float
    max_score: float
    needs_manual_grade: bool


def _recorded_grades(gb: Any, assignment: str) -> dict[str, dict[str, list[_Recorded]]]:
    """student → notebook → the grades nbgrader recorded for ``assignment``, in two queries
    whatever the size of the class (the gradebook's objects would load each grade's cell and
    maximum one query at a time: two per graded cell of every submission). A student with a
    submission and no grade has an empty entry; the notebooks are in the order of their names."""
    from nbgrader.api import Assignment, BaseCell, Grade, Notebook, SubmittedAssignment, SubmittedNotebook

    found: dict[str, dict[str, list[_Recorded]]] = {
        student: {} for (student,) in gb.db.query(SubmittedAssignment.student_id)
        .join(Assignment, SubmittedAssignment.assignment_id == Assignment.id)
        .filter(Assignment.name == assignment)}
    rows = (gb.db.query(SubmittedAssignment.student_id, Notebook.name, BaseCell.name, Grade.score, Grade.max_score,
                        Grade.needs_manual_grade)
            .select_from(Grade)
            .join(SubmittedNotebook, Grade.notebook_id == SubmittedNotebook.id)
            .join(Notebook, SubmittedNotebook.notebook_id == Notebook.id)
            .join(SubmittedAssignment, SubmittedNotebook.assignment_id == SubmittedAssignment.id)
            .join(Assignment, SubmittedAssignment.assignment_id == Assignment.id)
            .join(BaseCell, Grade.cell_id == BaseCell.id)
            .filter(Assignment.name == assignment))
    for student, notebook, name, score, max_score, manual in rows:
        found.setdefault(student, {}).setdefault(notebook, []).append(
            _Recorded(name, float(score or 0.0), float(max_score or 0.0), bool(manual)))
    return {student: dict(sorted(notebooks.items())) for student, notebooks in found.items()}


def _cell_order(course: CourseState, assignment: str) -> dict[str, int]:
    """Grade id → position of its cell in the released notebooks."""
    order: dict[str, int] = {}
    for path in course.release_notebooks(assignment):
        for cell in json.loads(path.read_text()).get("cells", []):
            cell_id = grade_id(cell)
            if cell_id:
                order.setdefault(cell_id, len(order))
    return order


def _flags(folder: Path) -> list[str]:
    """Tampering flags the trusted grader left in the autograded notebooks' metadata."""
    return [flag for path in sorted(folder.glob("*.ipynb")) for flag in notebook_flags(path)]


def notebook_flags(path: Path) -> list[str]:
    """The flags for the instructor in one autograded notebook's metadata (``metadata.cvkit``):
    the static scan's and the writer's, grading without the sandbox, a worker's problem.

    Parameters
    ----------
    path : Path
        An autograded notebook.

    Returns
    -------
    list of str
        ``"<grade id or (notebook)>: <what>"``; empty for a clean or unreadable notebook.
    """
    found = read_graded(path)
    return [] if found is None else metadata_flags(found.metadata)


def environment(course: CourseState, assignments: Iterable[str]) -> dict[str, dict[str, list[str]]]:
    """What the grading environment lacked when the submissions of ``assignments`` ran: cause
    → assignment → the students whose notebook's cells as released it stopped
    (:func:`cvkit.course.jobs.environment_problems`, kept in the autograded notebooks'
    ``metadata.cvkit.environment``). Not the students' doing: the instructor fixes the
    environment and regrades."""
    found: dict[str, dict[str, list[str]]] = {}
    for assignment in sorted(set(assignments)):
        for folder in sorted((course.root / "autograded").glob(f"*/{assignment}")):
            student = folder.parent.name
            for notebook in graded_notebooks(folder):
                causes = notebook.metadata.get("environment", [])
                for cause in causes if isinstance(causes, list) else []:
                    students = found.setdefault(str(cause), {}).setdefault(assignment, [])
                    if student not in students:
                        students.append(student)
    return {cause: {a: sorted(s, key=student_order) for a, s in per.items()} for cause, per in found.items()}


def reported_findings(folder: Path) -> dict[str, list[tuple[str, str]]]:
    """What the trusted checks found in the graded notebooks of ``folder``, per test cell.

    Parameters
    ----------
    folder : Path
        A submission's folder of autograded notebooks.

    Returns
    -------
    dict
        grade_id → ``(kind, words)`` per check call, without repeats: ``("mistake", name)`` for
        a named mistake, else ``("problem", words)`` with what the first diagnosed failing
        case looks like or the first clause of the first failure (never the tolerances).
        Read from the verdicts the trusted checks store as data in the test cells' metadata
        (:func:`cvkit.course.trusted.cell_report`); a notebook graded before they did
        (no ``metadata.cvkit.reports_in_cells``) is read from its reports' JSON outputs.
    """
    found: dict[str, list[tuple[str, str]]] = {}
    for notebook in graded_notebooks(folder):
        in_cells = bool(notebook.metadata.get("reports_in_cells"))
        for cell in notebook.cells:
            cell_id = cell.grade_id
            if not cell_id:
                continue
            for item in _cell_findings(cell.report) if in_cells else _output_findings(cell.outputs):
                items = found.setdefault(cell_id, [])
                if item not in items:
                    items.append(item)
    return found


def _cell_findings(report: Mapping[str, Any] | None) -> list[tuple[str, str]]:
    """The findings of a test cell's verdicts stored as data (``metadata.cvkit.report``)."""
    checks = report.get("checks") if isinstance(report, dict) else None
    items = []
    for check in checks if isinstance(checks, list) else []:
        if not isinstance(check, dict):
            continue
        if check.get("mistake"):
            items.append(("mistake", str(check["mistake"])))
        elif check.get("problem"):
            items.append(("problem", str(check["problem"])))
    return items


def _output_findings(outputs: Iterable[Mapping[str, Any]]) -> list[tuple[str, str]]:
    """The findings of the reports in a cell's outputs (notebooks graded before the verdicts
    were stored as data)."""
    reports = [output.get("data", {}).get(MIME_TYPE) for output in outputs]
    return [item for item in (finding(r) for r in reports if r and isinstance(r, dict)) if item is not None]


def audit(course: CourseState, jobs: Iterable[tuple[str, str]]) -> list[tuple[str, str]]:
    """Submissions of ``jobs`` with no autograded notebook or no grade in the gradebook (those
    listed as not graded, with their reason, are accounted for)."""
    from nbgrader.api import Gradebook, MissingEntry

    missing = []
    not_graded = course.not_graded()
    with Gradebook(course.db_url) as gb:
        for student, assignment in jobs:
            if f"{student}/{assignment}" in not_graded:
                continue  # accounted for: listed as not graded, with its reason
            graded = list((course.root / "autograded" / student / assignment).glob("*.ipynb"))
            try:
                submission = gb.find_submission(assignment, student)
                has_grades = all(nb.grades for nb in submission.notebooks)
            except MissingEntry:
                has_grades = False
            if not graded or not has_grades:
                missing.append((student, assignment))
    return missing


def is_graded(course: CourseState, student: str, assignment: str) -> bool:
    """Graded already, from this very submission (an interrupted run resumes after it)."""
    return course.journal.is_current(student, assignment) and not audit(course, [(student, assignment)])


def unsandboxed(course: CourseState) -> set[str]:
    """``student/assignment`` of submissions graded with ``--no-sandbox``."""
    found = set()
    for folder in sorted((course.root / "autograded").glob("*/*")):
        for notebook in graded_notebooks(folder):
            if notebook.metadata.get("sandboxed") is False:
                found.add(f"{folder.parent.name}/{folder.name}")
    return found


def late_penalties(course: CourseState, jobs: Iterable[tuple[str, str]]) -> dict[tuple[str, str], tuple[float, float]]:
    """(student, assignment) → (points taken, seconds late) for the submissions of ``jobs`` that
    nbgrader's gradebook records as late with a penalty: the grade table shows the points the
    checks gave, and these come off them (as in ``grades.csv`` and the feedback page)."""
    from nbgrader.api import Gradebook, MissingEntry

    found: dict[tuple[str, str], tuple[float, float]] = {}
    with Gradebook(course.db_url) as gb:
        for student, assignment in sorted(set(jobs)):
            try:
                submission = gb.find_submission(assignment, student)
            except MissingEntry:
                continue
            penalty = float(submission.late_submission_penalty or 0.0)
            if penalty > 0:
                found[(student, assignment)] = (penalty, float(submission.total_seconds_late or 0.0))
    return found
