"""Hand marks (written answers, open tasks, overridden scores): one truth, never undone.

nbgrader keeps a grader's ``manual_score``, ``extra_credit`` and ``manual_comment`` when it
autogrades a submission again, but sets ``needs_manual_grade`` back to True on every grade
that has a manual score (``SaveAutoGrades``): after any regrade — a changed due date, late
policy or check, which ``cvkit course grade --regrade`` offers — every marked answer would read
"to mark" again in the formgrader, the table and ``exercises.csv``. And a page written before
the marks would go on showing the student the unmarked score.

- :func:`snapshot` (before the writer's nbgrader run) and :func:`restore` (after it): a mark on
  an answer the student did not change since it was marked comes back exactly (score, extra
  credit, comment, ``needs_manual_grade = False``). A mark on an answer that changed (a new
  hand-in) stays as nbgrader leaves it — to mark again, the old mark as a suggestion — and the
  instructor is told.
- :func:`stale_pages` and :func:`remember_pages`: ``cvkit course grade`` writes again the
  feedback page of every submission whose marks changed since its page was written (the
  fingerprint of its marks when its page was last written is kept in
  ``.cvkit/marks_on_pages.json``), so the page, the table and the exports agree.
- :func:`log_changes`: every mark seen for the first time or changed is appended to
  ``.cvkit/marks.log`` (time, who ran the command that saw it, submission, cell, score and
  whether the comment changed): the course's record of what was marked and when. The
  formgrader does not say which grader marked; on a hub with a shared formgrader every mark is
  made as the course's account.
"""
from __future__ import annotations

import datetime as _dt
import getpass
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

from ..grading.runtime.cells import cell_source
from .files import write_whole

if TYPE_CHECKING:
    from .state import CourseState

__all__ = ["Mark", "Marks", "log_changes", "read", "remember_pages", "restore", "snapshot", "stale_pages"]

PAGES_FILE = "marks_on_pages.json"
SEEN_FILE = "marks_seen.json"
LOG_FILE = "marks.log"


@dataclass(frozen=True)
class Mark:
    """What a grader set on one graded cell of one submitted notebook."""

    manual_score: float | None
    extra_credit: float | None
    needs_manual_grade: bool
    manual_comment: str | None
    answer: str  # digest of the answer(s) the mark was given to

    @property
    def marked(self) -> bool:
        return self.manual_score is not None or self.extra_credit is not None or bool(self.manual_comment)


def _digest(parts: Iterable[str]) -> str:
    hasher = hashlib.sha256()
    for part in parts:
        hasher.update(part.encode("utf-8", "surrogatepass") + b"\0")
    return hasher.hexdigest()[:24]


def _answers(notebook: Mapping[str, Any]) -> dict[str, str]:
    """grade id → digest of what the mark of that cell judges: a solution cell's own source (a
    written answer), and for any other graded cell (an open task, a test cell whose score was
    overridden) everything the student could write — every cell but the release's graded ones
    (answers, cells they added); ``""`` → the latter."""
    cells = notebook.get("cells") if isinstance(notebook, Mapping) else None
    written, own = [], {}
    for cell in cells if isinstance(cells, list) else []:
        if not isinstance(cell, Mapping):
            continue
        nbgrader = (cell.get("metadata") or {}).get("nbgrader") or {}
        source = cell_source(cell)
        grade_id = str(nbgrader.get("grade_id") or "")
        if nbgrader.get("solution") or not grade_id:
            written.append(source)
        if grade_id:
            own[grade_id] = _digest([source]) if nbgrader.get("solution") else None
    everything = _digest(written)
    found = {grade_id: digest or everything for grade_id, digest in own.items()}
    found[""] = everything
    return found


def _read_notebook(path: Path) -> dict[str, Any]:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def _gradebook(course: CourseState) -> Any:
    from nbgrader.api import Gradebook

    return Gradebook(course.db_url)


def snapshot(course: CourseState, assignment: str, students: Iterable[str]) -> dict[tuple[str, str, str], Mark]:
    """The marks of ``students``' recorded submissions of ``assignment``, keyed by (student,
    notebook, grade id), each with the digest of the answer it was given to (read from the
    notebook nbgrader last recorded, ``autograded/``)."""
    marks: dict[tuple[str, str, str], Mark] = {}
    answers: dict[tuple[str, str], dict[str, str]] = {}
    for (student, name, grade_id), state in _marks(course, assignment, students).items():
        if (student, name) not in answers:
            answers[(student, name)] = _answers(
                _read_notebook(course.root / "autograded" / student / assignment / f"{name}.ipynb"))
        found = answers[(student, name)]
        score, extra, needs, comment = state
        marks[(student, name, grade_id)] = Mark(score, extra, needs, comment, found.get(grade_id, found[""]))
    return marks


def restore(course: CourseState, assignment: str, before: Mapping[tuple[str, str, str], Mark],
            notebooks: Mapping[str, Mapping[str, str]]) -> list[tuple[str, str]]:
    """Put back the marks of ``before`` (:func:`snapshot`) after nbgrader recorded
    ``notebooks`` (student → notebook file name → its JSON text, as recorded) again: exactly,
    where the marked answer is unchanged. Returns (student, note) for each mark whose answer
    changed since it was marked (left to mark again)."""
    from nbgrader.api import MissingEntry

    notes: list[tuple[str, str]] = []
    marked = {key: mark for key, mark in before.items() if mark.marked and key[0] in notebooks}
    if not marked:
        return notes
    answers: dict[tuple[str, str], dict[str, str]] = {}
    for student, files in notebooks.items():
        for file_name, text in files.items():
            try:
                answers[(student, file_name[:-len(".ipynb")])] = _answers(json.loads(text))
            except (ValueError, TypeError):
                continue
    with _gradebook(course) as gradebook:
        for (student, name, grade_id), mark in sorted(marked.items()):
            now = answers.get((student, name))
            if now is None:
                continue
            try:
                grade = gradebook.find_grade(grade_id, name, assignment, student)
                comment = gradebook.find_comment(grade_id, name, assignment, student)
            except MissingEntry:
                continue
            if now.get(grade_id, now[""]) != mark.answer:
                grade.needs_manual_grade = True
                notes.append((student, f"{grade_id}: the answer changed since it was marked ("
                                       f"{_score(mark.manual_score)}): to mark again in the formgrader"))
                continue
            grade.manual_score, grade.extra_credit = mark.manual_score, mark.extra_credit
            grade.needs_manual_grade = mark.needs_manual_grade
            comment.manual_comment = mark.manual_comment
        gradebook.db.commit()
    return notes


def _score(value: float | None) -> str:
    return "no score" if value is None else f"{value:g}"


_State = tuple[float | None, float | None, bool, str | None]  # manual score, extra credit, needs a mark, comment
#: every mark of some recorded submissions, read once: (student, assignment) → (notebook, grade id) → state
Marks = dict[tuple[str, str], dict[tuple[str, str], _State]]


def read(course: CourseState, pairs: Iterable[tuple[str, str]]) -> Marks:
    """Every mark of the recorded submissions ``pairs``, in one read of the gradebook per
    assignment; :func:`stale_pages`, :func:`remember_pages` and :func:`log_changes` of one run
    share it (``now``). Read before the pages are written, it can only make a page look stale
    that is not (it is then written again), never the other way round."""
    by_assignment: dict[str, list[str]] = {}
    for student, assignment in sorted(set(pairs)):
        by_assignment.setdefault(assignment, []).append(student)
    found: Marks = {}
    for assignment, students in by_assignment.items():
        for (student, name, grade_id), state in _marks(course, assignment, students).items():
            found.setdefault((student, assignment), {})[(name, grade_id)] = state
    return found


def fingerprints(course: CourseState, pairs: Iterable[tuple[str, str]], now: Marks | None = None) -> dict[str, str]:
    """``"student/assignment"`` → a digest of every mark of that submission (what its page shows);
    ``now``: the marks as :func:`read` gave them (read here when None)."""
    pairs = sorted(set(pairs))
    now = read(course, pairs) if now is None else now
    found: dict[str, str] = {}
    for student, assignment in pairs:  # what a grader set (a page written before any mark shows none)
        own = sorted((name, grade_id, state) for (name, grade_id), state in now.get((student, assignment), {}).items()
                     if state[0] is not None or state[1] is not None or state[3])
        found[f"{student}/{assignment}"] = _digest([json.dumps(own, default=str)])
    return found


#: the fingerprint of a submission nobody has marked
UNMARKED = _digest([json.dumps([])])


def _marks(course: CourseState, assignment: str, students: Iterable[str]) -> dict[tuple[str, str, str], _State]:
    """(student, notebook, grade id) → (manual score, extra credit, needs manual grade, comment)
    of the recorded submissions of ``students``."""
    from nbgrader.api import MissingEntry

    marks: dict[tuple[str, str, str], _State] = {}
    with _gradebook(course) as gradebook:
        try:
            notebooks = [n.name for n in gradebook.find_assignment(assignment).notebooks]
        except MissingEntry:
            return marks
        for student in students:
            for name in notebooks:
                try:
                    submitted = gradebook.find_submission_notebook(name, assignment, student)
                except MissingEntry:
                    continue
                comments = {c.name: c.manual_comment for c in submitted.comments}
                for grade in submitted.grades:
                    marks[(student, name, grade.name)] = (grade.manual_score, grade.extra_credit,
                                                          bool(grade.needs_manual_grade), comments.get(grade.name))
    return marks


def _load(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
        return data if isinstance(data, dict) else {}
    except (OSError, ValueError):
        return {}


def _save(path: Path, data: Mapping[str, Any]) -> None:
    write_whole(path, json.dumps(dict(sorted(data.items())), indent=1))


def stale_pages(course: CourseState, pairs: Iterable[tuple[str, str]], now: Marks | None = None) -> list[tuple[str, str]]:
    """The submissions of ``pairs`` with a feedback page whose marks changed since it was written
    (``now``: see :func:`fingerprints`)."""
    pairs = [(s, a) for s, a in pairs if (course.root / "feedback" / s / a).is_dir()]
    written = _load(course.root / ".cvkit" / PAGES_FILE)
    marked = fingerprints(course, pairs, now)
    return [(s, a) for s, a in pairs if written.get(f"{s}/{a}", UNMARKED) != marked.get(f"{s}/{a}")]


def remember_pages(course: CourseState, pairs: Iterable[tuple[str, str]], now: Marks | None = None) -> None:
    """Record the marks the feedback pages of ``pairs`` now show (their pages were just written;
    ``now``: the marks they were written with, see :func:`fingerprints`)."""
    pairs = list(pairs)
    if not pairs:
        return
    path = course.root / ".cvkit" / PAGES_FILE
    written = _load(path)
    written.update(fingerprints(course, pairs, now))
    _save(path, written)


def log_changes(course: CourseState, pairs: Iterable[tuple[str, str]], now: Marks | None = None) -> int:
    """Append to ``.cvkit/marks.log`` every mark of ``pairs`` first seen or changed since the last
    call; returns how many. Each line: time (UTC), the account that ran the command, submission,
    cell, the score (or "no score"), extra credit, and whether the comment is new (``now``: see
    :func:`fingerprints`)."""
    pairs = sorted(set(pairs))
    now = read(course, pairs) if now is None else now
    seen_path = course.root / ".cvkit" / SEEN_FILE
    seen = _load(seen_path)
    by_assignment: dict[str, list[str]] = {}
    for student, assignment in pairs:
        by_assignment.setdefault(assignment, []).append(student)
    lines = []
    try:
        who = getpass.getuser()
    except Exception:  # noqa: BLE001 - no name for this uid: its number
        who = str(os.getuid())
    when = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    for assignment, students in sorted(by_assignment.items()):
        for (student, name, grade_id), (score, extra, needs, comment) in sorted(
                ((student, name, grade_id), state) for student in students
                for (name, grade_id), state in now.get((student, assignment), {}).items()):
            if score is None and extra is None and not comment:
                continue
            key = f"{student}/{assignment}/{name}/{grade_id}"
            state = {"score": score, "extra": extra, "needs": needs, "comment": _digest([comment or ""])}
            before = seen.get(key)
            if before == state:
                continue
            comment_note = "" if before and before.get("comment") == state["comment"] else (
                ", comment written" if comment else "")
            lines.append(f"{when}\t{who}\t{student}/{assignment}\t{name}:{grade_id}\t{_score(score)}"
                         + (f" (+{extra:g} extra)" if extra else "") + comment_note
                         + ("\tstill to mark" if needs else ""))
            seen[key] = state
    if lines:
        log = course.root / ".cvkit" / LOG_FILE
        log.parent.mkdir(parents=True, exist_ok=True)
        with log.open("a", encoding="utf-8") as handle:
            handle.write("\n".join(lines) + "\n")
        _save(seen_path, seen)
    return len(lines)
