"""Grades into a learning management system: a CSV file Canvas imports, a CSV file Moodle
imports, and the grade sheet both are made from (:func:`grade_sheet`), which LTI's Assignment
and Grade Services (:mod:`cvkit.course.lti`) posts too.

What a cell holds (one rule for every LMS):

- the points the student **earned**: nbgrader's score *after* the late penalty (the same number
  as ``score`` in ``grades.csv``; never below 0), rounded to two decimals;
- **blank, never 0**, when there is no such number yet: written answers or open tasks still to be
  marked by hand in the formgrader, a submission that could not be graded (with its reason), a
  submission not graded yet or handed in again since it was graded, no submission at all. Each blank cell is listed with its reason in a
  side file (``exports/canvas_blank_reasons.csv``, ``exports/moodle_blank_reasons.csv``), and so
  is every student who is in the LMS's roster but not in the course or the reverse.

The files are UTF-8 (no byte-order mark), comma-separated, quoted as RFC 4180 says (a cell with a
comma, a quote or a line break is quoted, quotes doubled), lines ending in CRLF. docs/lms.md says
how to import them.
"""
from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Iterable

from .._text import printable
from .files import whole_file

if TYPE_CHECKING:
    from .state import CourseState

#: the identity columns Canvas's gradebook import requires, in its order
CANVAS_IDENTITY = ("Student", "ID", "SIS User ID", "SIS Login ID", "Section")
#: the first cell of the row of maximum points in Canvas's gradebook CSV (as Canvas writes it)
CANVAS_POINTS_ROW = "    Points Possible"
#: Moodle's user fields a grade import can map a column to → the column's name in the file
MOODLE_FIELDS = {"email": "Email address", "username": "Username", "idnumber": "ID number"}
#: the reasons a cell is blank
PENDING = "written answers or open tasks still to be marked by hand (formgrader): no grade until marked"
NO_SUBMISSION = "no submission"
NOT_GRADED_YET = "submitted, not graded yet (run cvkit course grade)"
HANDED_IN_AGAIN = "handed in again since it was graded: grade it (cvkit course grade), then export again"


@dataclass(frozen=True)
class Grade:
    """One student's grade of one assignment.

    Attributes
    ----------
    points : float or None
        What the student earned (after the late penalty); None for a blank cell.
    reason : str
        Why the cell is blank (empty when it holds points).
    pending : bool
        Written answers wait for a hand mark (LTI: ``gradingProgress`` ``PendingManual``).
    submitted : bool
        The student handed something in.
    penalty : float
        The late penalty taken off (points).
    """

    points: float | None
    reason: str = ""
    pending: bool = False
    submitted: bool = True
    penalty: float = 0.0


@dataclass
class GradeSheet:
    """Students × assignments of a course, as an LMS takes them (:func:`grade_sheet`)."""

    assignments: list[str]
    students: list[str]
    grades: dict[tuple[str, str], Grade]
    points_possible: dict[str, float | None] = field(default_factory=dict)
    titles: dict[str, str] = field(default_factory=dict)
    emails: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def grade(self, student: str, assignment: str) -> Grade:
        return self.grades.get((student, assignment), Grade(None, NO_SUBMISSION, submitted=False))


def points_text(value: float | None) -> str:
    """A number of points as the LMSs read it: plain decimal, at most two decimals, no
    exponent (``7.5``, ``10``, ``0.33``); ``""`` for None."""
    if value is None:
        return ""
    text = f"{round(float(value), 2):.2f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def _grade_cells(sheet: GradeSheet, student: str, blank: list[tuple[str, str, str]]) -> list[str]:
    """The student's row of points, one cell per assignment of ``sheet``; a blank cell's reason
    goes to ``blank`` (student, assignment, why)."""
    cells = []
    for assignment in sheet.assignments:
        grade = sheet.grade(student, assignment)
        cells.append(points_text(grade.points))
        if grade.points is None:
            blank.append((student, assignment, grade.reason))
    return cells


def grade_sheet(course: CourseState, assignments: Iterable[str] | None = None) -> GradeSheet:
    """The course's grade sheet, read from nbgrader's gradebook.

    Parameters
    ----------
    course : CourseState
    assignments : iterable of str, optional
        Only these (default: every assignment of the plan, in its order).

    Returns
    -------
    GradeSheet
        The students are the gradebook's and those with a submission folder; the points possible
        are the gradebook's maximum of the assignment (None, with a note, for one never built).
    """
    from nbgrader.api import MissingEntry

    from .plan import gradebook_of

    plan = course.plan()
    chosen = list(dict.fromkeys(assignments)) if assignments else plan.ids()
    unknown = [a for a in chosen if plan.get(a) is None]
    if unknown:
        raise ValueError(f"--assignment: {', '.join(unknown)} not in {plan.name} (its assignments: "
                         f"{', '.join(plan.ids()) or 'none'})")
    not_graded = course.not_graded()
    submitted = set(course.submissions(chosen)) | {tuple(k.split("/", 1)) for k in not_graded}
    sheet = GradeSheet(chosen, [], {}, titles={a: (plan.get(a).title or a) for a in chosen})  # type: ignore[union-attr]
    students: set[str] = {s for s, a in submitted if a in chosen}
    journal = course.journal  # the files each submission was graded from (same package)
    recorded = journal.graded()
    with gradebook_of(course.db_url) as gb:  # a course never graded has an empty one
        for student in gb.students:
            students.add(student.id)
            if student.email:
                sheet.emails[student.id] = student.email
        for assignment in chosen:
            try:
                top = float(gb.find_assignment(assignment).max_score or 0.0)
            except MissingEntry:
                top = 0.0
            sheet.points_possible[assignment] = top if top > 0 else None
            if top <= 0:
                sheet.notes.append(f"{assignment}: no points possible (not built: cvkit course build --assignment "
                                   f"{assignment}); its column has no maximum")
            if not any(a == assignment for _, a in submitted):
                sheet.notes.append(f"{assignment}: nobody has submitted it: its column is blank")
        from .samples import student_order

        sheet.students = sorted(students, key=student_order)
        for student in sheet.students:
            for assignment in chosen:
                key = f"{student}/{assignment}"
                if key in not_graded:
                    sheet.grades[(student, assignment)] = Grade(None, f"not graded: {not_graded[key]}")
                    continue
                try:
                    submission = gb.find_submission(assignment, student)
                except MissingEntry:
                    sheet.grades[(student, assignment)] = (
                        Grade(None, NOT_GRADED_YET) if (student, assignment) in submitted
                        else Grade(None, NO_SUBMISSION, submitted=False))
                    continue
                if key in recorded and (student, assignment) in submitted \
                        and recorded[key] != journal.submission_hash(student, assignment):
                    sheet.grades[(student, assignment)] = Grade(None, HANDED_IN_AGAIN)  # the grade is the old files'
                    continue
                penalty = float(submission.late_submission_penalty or 0.0)
                if submission.needs_manual_grade:
                    sheet.grades[(student, assignment)] = Grade(None, PENDING, pending=True, penalty=penalty)
                    continue
                earned = max(0.0, float(submission.score or 0.0) - penalty)
                sheet.grades[(student, assignment)] = Grade(earned, penalty=penalty)
    if not sheet.students:
        sheet.notes.append("the course has no students (no submission and none in the gradebook): "
                           "the file holds no student")
    return sheet


# ---------------------------------------------------------------------------------------------- CSV

def _student_cell(text: str) -> str:
    """A student id (a folder name) as a cell: printable and never a spreadsheet formula."""
    from .safety import csv_safe

    return csv_safe(printable(text))


def _unsafe_identifier(text: str) -> str:
    """Why ``text`` cannot identify a user in an LMS file ("" when it can): a cell is made
    printable and never a spreadsheet formula, so such an id would reach the LMS changed, and
    match nobody (or stop a Moodle import)."""
    if not text.strip():
        return "empty"
    return "" if _student_cell(text) == text else f"{_student_cell(text)!r} would be written changed (control " \
        "characters or a leading =, +, -, @ that spreadsheets run)"


def write_csv(path: Path, rows: list[list[str]]) -> Path:
    """``rows`` as RFC 4180 CSV in UTF-8 (no byte-order mark), CRLF line ends."""
    with whole_file(path, newline="") as handle:
        csv.writer(handle, lineterminator="\r\n", quoting=csv.QUOTE_MINIMAL).writerows(rows)
    return path


@dataclass
class Export:
    """A file for an LMS and what the instructor must know about it."""

    path: Path
    reasons: Path
    lines: list[str]
    blank: list[tuple[str, str, str]]  # (student, assignment, reason), also in ``reasons``


def _reasons_rows(blank: list[tuple[str, str, str]]) -> list[list[str]]:
    return [["student", "assignment", "reason"]] + [[_student_cell(s), _student_cell(a), _student_cell(r)] for s, a, r in blank]


def read_canvas_roster(path: Path, column: str = "SIS Login ID") -> tuple[list[str], list[dict[str, str]]]:
    """A Canvas gradebook export (Grades → Export → CSV): its header and its students' rows.

    The rows that are not students (``Points Possible``, posting-policy rows: no ``Student``
    name or no ``ID``) are left out. Raises ValueError naming ``--roster`` / ``--roster-column``
    when the file is not such an export."""
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise ValueError(f"--roster {path}: not UTF-8 ({error.reason} at byte {error.start}); export the "
                         "gradebook from Canvas again") from None
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise ValueError(f"--roster {path}: empty; expected Canvas's gradebook export")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in CANVAS_IDENTITY[:2] if c not in header]
    if missing:
        raise ValueError(f"--roster {path}: no column {', '.join(map(repr, missing))}: not a Canvas gradebook export "
                         f"(its columns: {', '.join(header[:8])})")
    if column not in header:
        raise ValueError(f"--roster-column {column!r} is not a column of {path} (its identity columns: "
                         f"{', '.join(h for h in header if h in CANVAS_IDENTITY)})")
    students = []
    for row in rows[1:]:
        entry = dict(zip(header, row))
        name = entry.get("Student", "").strip()
        if not name or name == "Points Possible" or not entry.get("ID", "").strip():
            continue
        students.append(entry)
    return header, students


_CANVAS_COLUMN = re.compile(r"^(?P<name>.*\S)\s+\((?P<id>\d+)\)$")


def canvas_export(sheet: GradeSheet, target: Path, roster: Path | None = None,
                  column: str = "SIS Login ID") -> Export:
    """Write the Canvas gradebook-import CSV of ``sheet`` to ``target`` and the blank cells'
    reasons next to it (``canvas_blank_reasons.csv``).

    Without a roster, a student's row has their cvkit id as ``Student`` and ``SIS Login ID``
    (Canvas matches the row by it) and the other identity cells empty; an assignment's column is
    named by its id, and Canvas makes it a new assignment on the first import. With ``roster``
    (Canvas's own gradebook export), each student's identity cells are copied from the roster
    row whose ``column`` is their id, and an assignment whose name (its id or its plan title) is
    a column of the roster gets that column's exact name, ``name (canvas id)``, so that Canvas
    updates it instead of making a second one."""
    lines: list[str] = list(sheet.notes)
    blank: list[tuple[str, str, str]] = []
    headers = {a: a for a in sheet.assignments}
    identities: dict[str, list[str]] = {}
    extra: list[list[str]] = []
    if roster is not None:
        header, entries = read_canvas_roster(roster, column)
        for name in header:
            found = _CANVAS_COLUMN.match(name)
            if found:
                for a in sheet.assignments:
                    if found["name"] in (a, sheet.titles.get(a)):
                        headers[a] = name
        by_key: dict[str, dict[str, str]] = {}
        for entry in entries:
            key = entry.get(column, "").strip()
            if not key:
                lines.append(f"roster: {entry['Student']} has no {column}: their row is in the file with blank grades")
                blank.append((entry["Student"], "", f"in the Canvas roster without a {column}: grades blank"))
                extra.append([entry.get(c, "") for c in CANVAS_IDENTITY] + [""] * len(sheet.assignments))
                continue
            if key in by_key:
                lines.append(f"roster: {column} {key} is on two rows ({by_key[key]['Student']}, {entry['Student']}): "
                             "the second left out of the file; fix the roster")
                blank.append((entry["Student"], "", f"a second Canvas roster row with {column} {key}: not in the file"))
                continue
            by_key[key] = entry
        for student in sheet.students:
            if student not in by_key:
                lines.append(f"{printable(student)} is in the course but not in the Canvas roster ({column}): "
                             "left out of the file (add them in Canvas, export the gradebook again)")
                blank.append((student, "", f"in the course, not in the Canvas roster ({column}): not in the file"))
                continue
            matched = by_key.pop(student)
            identities[student] = [matched.get(c, "") for c in CANVAS_IDENTITY]
        for key, entry in sorted(by_key.items()):
            lines.append(f"{entry['Student']} ({column} {key}) is in the Canvas roster but not in the course: "
                         "their row is in the file with blank grades")
            blank.append((key, "", "in the Canvas roster, not in the course: grades blank"))
            extra.append([entry.get(c, "") for c in CANVAS_IDENTITY] + [""] * len(sheet.assignments))
    else:
        for student in sheet.students:
            why = _unsafe_identifier(student)
            if why:
                lines.append(f"{_student_cell(student)}: left out of the file: the id {why}; use --roster")
                blank.append((student, "", f"left out: the id {why}"))
                continue
            identities[student] = [student, "", "", student, ""]
    rows = [list(CANVAS_IDENTITY) + [headers[a] for a in sheet.assignments],
            [CANVAS_POINTS_ROW, "", "", "", ""] + [points_text(sheet.points_possible.get(a))
                                                    for a in sheet.assignments]]
    for student in sheet.students:
        if student not in identities:
            continue
        rows.append(identities[student] + _grade_cells(sheet, student, blank))
    rows += extra
    new = [a for a in sheet.assignments if headers[a] == a]
    if new:
        lines.append(f"new in Canvas on the first import (no Canvas id known): {', '.join(new)}; to update them "
                     "later, export Canvas's gradebook and pass it with --roster")
    reasons = target.with_name("canvas_blank_reasons.csv")
    write_csv(target, rows)
    write_csv(reasons, _reasons_rows(blank))
    return Export(target, reasons, lines, blank)


def read_moodle_roster(path: Path, field_name: str) -> dict[str, str]:
    """A roster CSV with the columns ``student_id`` and ``field_name`` (email, username or
    idnumber): cvkit's student id → the Moodle user's field."""
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise ValueError(f"--roster {path}: not UTF-8 ({error.reason} at byte {error.start})") from None
    reader = csv.DictReader(text.splitlines())
    names = [n.strip() for n in reader.fieldnames or []]
    if "student_id" not in names or field_name not in names:
        raise ValueError(f"--roster {path}: needs the columns student_id and {field_name} (for --moodle "
                         f"{field_name}); it has {', '.join(names) or 'none'}")
    found = {}
    for row in reader:
        row = {k.strip(): (v or "").strip() for k, v in row.items() if k}
        if row.get("student_id") and row.get(field_name):
            found[row["student_id"]] = row[field_name]
    return found


def moodle_export(sheet: GradeSheet, target: Path, field_name: str, roster: Path | None = None) -> Export:
    """Write Moodle's grade-import CSV of ``sheet`` to ``target`` (and the blank cells' reasons,
    ``moodle_blank_reasons.csv``): the identifier column first (``field_name``: ``email``,
    ``username`` or ``idnumber``, named as Moodle's own exports name it), then one column per
    assignment (a grade item) named by its id.

    The identifier comes from ``roster`` (student_id → field), else for ``email`` from the
    gradebook's e-mail addresses, for ``username`` and ``idnumber`` from the student id. A
    student without one is left out and listed: Moodle stops the whole import at a row whose
    user it cannot find."""
    if field_name not in MOODLE_FIELDS:
        raise ValueError(f"--moodle must be one of {', '.join(MOODLE_FIELDS)}, got {field_name!r}")
    lines: list[str] = list(sheet.notes)
    blank: list[tuple[str, str, str]] = []
    if roster is not None:
        ids = read_moodle_roster(roster, field_name)
        source = f"the roster {roster.name}"
        for student in sorted(set(ids) - set(sheet.students)):
            lines.append(f"{printable(student)} is in the roster but not in the course: left out (no grades)")
            blank.append((student, "", "in the roster, not in the course: no grades"))
    elif field_name == "email":
        ids, source = dict(sheet.emails), "the gradebook's e-mail addresses"
    else:
        ids, source = {s: s for s in sheet.students}, "the student ids"
    rows = [[MOODLE_FIELDS[field_name]] + list(sheet.assignments)]
    for student in sheet.students:
        identifier = ids.get(student, "")
        why = _unsafe_identifier(identifier) if identifier else ""
        if why:
            lines.append(f"{_student_cell(student)}: left out of the file: their {field_name} {why}")
            blank.append((student, "", f"left out: their {field_name} {why}"))
            continue
        if not identifier:
            lines.append(f"{printable(student)}: no {field_name} in {source}: left out of the file (Moodle stops the "
                         "import at a user it cannot find)")
            blank.append((student, "", f"in the course, no {field_name} in {source}: not in the file"))
            continue
        rows.append([identifier] + _grade_cells(sheet, student, blank))
    tops = ", ".join(f"{a} {points_text(sheet.points_possible.get(a)) or '?'}" for a in sheet.assignments)
    if tops:
        lines.append(f"grade items' maximum points (set them in Moodle; a new item gets 100): {tops}")
    reasons = target.with_name("moodle_blank_reasons.csv")
    write_csv(target, rows)
    write_csv(reasons, _reasons_rows(blank))
    return Export(target, reasons, lines, blank)
