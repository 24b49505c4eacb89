"""Results of a graded course: per student and exercise, the score from nbgrader's gradebook,
the mistakes the trusted checks named, the problems they saw and the flags they raised; and the
audit that no submission lost its grade.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable

from ..grading.report import MIME_TYPE
from .cells import exercise_name, grade_id
from .samples import student_order

if TYPE_CHECKING:
    from .course import Course


@dataclass
class ExerciseScore:
    name: str
    score: float
    max_score: float
    mistakes: list = field(default_factory=list)
    problems: list = field(default_factory=list)
    flags: list = field(default_factory=list)
    to_mark: bool = False  # a written question or open task not yet marked by hand (formgrader)


def scores(course: Course, assignment: str) -> dict[str, list[ExerciseScore]]:
    """See :meth:`Course.scores`."""
    from nbgrader.api import Gradebook, MissingEntry

    table: dict[str, list[ExerciseScore]] = {}
    not_graded = course.not_graded()
    order = _grade_order(course, assignment)
    with Gradebook(course.db_url) as gb:
        for student, _ in course.submissions([assignment]):
            if f"{student}/{assignment}" in not_graded:
                continue  # no score: listed as not graded (Course.table, the exports)
            try:
                submission = gb.find_submission(assignment, student)
            except MissingEntry:
                continue
            graded = course.root / "autograded" / student / assignment
            found = _reported_mistakes(graded)
            exercises: dict[str, ExerciseScore] = {}
            for nb in submission.notebooks:
                for grade in sorted(nb.grades, key=lambda g: g.cell_id if hasattr(g, "cell_id") else g.name):
                    name = exercise_name(grade.name, answers=False)
                    entry = exercises.setdefault(name, ExerciseScore(name, 0.0, 0.0))
                    entry.to_mark = entry.to_mark or bool(grade.needs_manual_grade)
                    entry.score += float(grade.score or 0.0)
                    entry.max_score += float(grade.max_score or 0.0)
                    for item in found.get(grade.name, []):
                        bucket = entry.mistakes if item.startswith("mistake:") else entry.problems
                        text = item.split(":", 1)[1]
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


def _grade_order(course: Course, assignment: str) -> dict[str, int]:
    """Exercise name → position of its first graded cell in the released notebooks."""
    order: dict[str, int] = {}
    for path in course.release_notebooks(assignment):
        for cell in json.loads(path.read_text()).get("cells", []):
            cell_id = grade_id(cell)
            if cell_id:
                order.setdefault(exercise_name(cell_id), len(order))
    return order


def _flags(folder: Path) -> list[str]:
    """Tampering flags the trusted grader left in the autograded notebooks' metadata."""
    flags = []
    for path in sorted(folder.glob("*.ipynb")):
        meta = json.loads(path.read_text()).get("metadata", {}).get("cvkit", {})
        flags += [str(f) for f in meta.get("flags", [])]
        if meta.get("sandboxed") is False:
            flags.append("(notebook): GRADED WITHOUT THE SANDBOX (--no-sandbox)")
        if meta.get("worker_problem"):
            flags.append(f"(notebook): {meta['worker_problem']}")
    return flags


def _reported_mistakes(folder: Path) -> dict[str, list[str]]:
    """grade_id → ["mistake:<name>" | "problem:<text>"] from the reports in graded notebooks:
    one item per report, in plain words — the named mistake, else what the first diagnosed
    failing case looks like ("your output is shifted by 1 row down"), else the first clause of
    the first failing case's message (never the tolerances)."""
    found: dict[str, list[str]] = {}
    for path in sorted(folder.glob("*.ipynb")):
        nb = json.loads(path.read_text())
        for cell in nb.get("cells", []):
            cell_id = grade_id(cell)
            for output in cell.get("outputs", []):
                report = output.get("data", {}).get(MIME_TYPE)
                if not report or not cell_id or not isinstance(report, dict):
                    continue
                items = found.setdefault(cell_id, [])
                failures = [c for c in report.get("cases", []) if isinstance(c, dict) and not c.get("passed")]
                if report.get("mistake"):
                    item = f"mistake:{report['mistake']}"
                elif failures:
                    diagnosis = report.get("diagnosis") or next((c.get("diagnosis") for c in failures
                                                                 if c.get("diagnosis")), None)
                    item = f"problem:{_headline(diagnosis or failures[0].get('message') or 'failed')}"
                else:
                    continue
                if item not in items:
                    items.append(item)
    return found


#: the numpy.testing vocabulary of reports written before plain words came first
_TECHNICAL_LINE = re.compile(r"\b(rtol|atol)\b|to tolerance|^Mismatched elements")


def _headline(message: str, width: int = 90) -> str:
    """The first clause of a failure message, in plain words: "calls X, which would..." →
    "calls X"; "60 of 90 values differ, all in the border frame 2 pixels wide (the interior is
    right); first at ..." → up to the semicolon; "Your output is shifted by 1 row down: ..." →
    "your output is shifted by 1 row down". Reports in the old numpy.testing wording ("Not
    equal to tolerance rtol=…") become "N of M values differ"."""
    lines = [line.strip() for line in str(message or "").splitlines() if line.strip()]
    if not lines:
        return "failed"
    first = lines[0]
    if _TECHNICAL_LINE.search(first):
        counted = re.search(r"Mismatched elements: (\d+) / (\d+)", str(message))
        first = (f"{counted.group(1)} of {counted.group(2)} values differ" if counted
                 else "the values differ from the expected ones")
    first = re.sub(r"\s*\([^()]*\b(?:rtol|atol)\b[^()]*\)", "", first)
    prefix = re.match(r"(result \[\d+\]: )?", first)
    first = first[len(prefix.group(0)):] if prefix else first
    if not first.startswith(("shape mismatch", "dtype mismatch", "raised ")):
        first = re.split(r"; |\. (?=[A-Z])", first, maxsplit=1)[0]
        for stop in (", which", ": "):
            if stop in first:
                first = first.split(stop, 1)[0]
                break
    first = (prefix.group(0) if prefix else "") + first
    first = first.rstrip(" .")
    if first[:1].isupper() and first[1:2].islower():
        first = first[0].lower() + first[1:]
    return first if len(first) <= width else first[: width - 1].rsplit(" ", 1)[0] + "…"


def audit(course: Course, jobs: Iterable[tuple[str, str]]) -> list[tuple[str, str]]:
    """See :meth:`Course.audit`."""
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


def unsandboxed(course: Course) -> set[str]:
    """``student/assignment`` of submissions graded with ``--no-sandbox``."""
    found = set()
    for folder in sorted((course.root / "autograded").glob("*/*")):
        for path in folder.glob("*.ipynb"):
            try:
                meta: dict[str, Any] = json.loads(path.read_text()).get("metadata", {}).get("cvkit", {})
            except (OSError, ValueError):
                continue
            if meta.get("sandboxed") is False:
                found.add(f"{folder.parent.name}/{folder.name}")
    return found
