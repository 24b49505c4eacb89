"""Strict readers of the grade files two LMSs import, written from their documented rules (not
from cvkit's writer): a file that breaks a rule raises ``FormatError`` naming it.

Common to both (RFC 4180 as the LMSs read it): UTF-8 (Canvas tolerates a byte-order mark, Moodle
would take it into its first column's name, so it is refused for Moodle), comma separated, every
record the same number of fields, a field quoted exactly when it holds a comma, a quote or a line
break (quotes doubled), records ending in CRLF.

Canvas (gradebook import, the format of its gradebook export): the first five columns are
``Student``, ``ID``, ``SIS User ID``, ``SIS Login ID``, ``Section``; then one column per
assignment, ``Name`` (a new assignment) or ``Name (12345)`` (the existing assignment of Canvas id
12345); the second record is the ``Points Possible`` row (its first cell ``Points Possible``
after stripping blanks, the identity cells empty, a number ≥ 0 or nothing per assignment); a
student record identifies the student by ``ID``, ``SIS User ID`` or ``SIS Login ID``; a score
is a plain decimal number or empty (no score).

Moodle (Grades → Import → CSV file): a header record of column names, unique and not empty; one
column maps to the user (its values: the user's e-mail, username or ID number, never empty,
since a row whose user is not found stops the whole import) — here the first; the others map
to grade items, their values a decimal number, ``-`` or empty (no grade); a dot is the decimal
separator.
"""
from __future__ import annotations

import csv
import io
import re

CANVAS_IDENTITY = ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"]
CANVAS_READ_ONLY = {"Current Points", "Final Points", "Current Score", "Final Score", "Current Grade", "Final Grade",
                    "Unposted Current Score", "Unposted Final Score"}
MOODLE_IDENTIFIERS = {"email": "Email address", "username": "Username", "idnumber": "ID number"}
NUMBER = re.compile(r"^\d+(\.\d+)?$")


class FormatError(ValueError):
    pass


def _records(data: bytes, bom_allowed: bool) -> list[list[str]]:
    if data.startswith(b"\xef\xbb\xbf"):
        if not bom_allowed:
            raise FormatError("a UTF-8 byte-order mark (it would become part of the first column's name)")
        data = data[3:]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise FormatError(f"not UTF-8 at byte {error.start}") from None
    if not text:
        raise FormatError("empty file")
    if not text.endswith("\r\n"):
        raise FormatError("the last record does not end in CRLF")
    try:
        records = list(csv.reader(io.StringIO(text, newline=""), strict=True))
    except csv.Error as error:
        raise FormatError(f"not RFC 4180 CSV: {error}") from None
    # quoted exactly when needed: the records written back the canonical way give the same text
    canonical = io.StringIO(newline="")
    csv.writer(canonical, lineterminator="\r\n", quoting=csv.QUOTE_MINIMAL).writerows(records)
    if canonical.getvalue() != text:
        for number, (got, want) in enumerate(zip(text.split("\r\n"), canonical.getvalue().split("\r\n")), 1):
            if got != want:
                raise FormatError(f"record {number}: quoting or line ends differ from RFC 4180: {got!r}")
        raise FormatError("quoting or line ends differ from RFC 4180")
    width = len(records[0])
    for number, record in enumerate(records, 1):
        if len(record) != width:
            raise FormatError(f"record {number} has {len(record)} fields, the header {width}")
    return records


def _number(text: str, where: str) -> float | None:
    if text == "":
        return None
    if not NUMBER.match(text):
        raise FormatError(f"{where}: {text!r} is not a plain decimal number")
    return float(text)


def parse_canvas(data: bytes) -> dict:
    """A Canvas gradebook-import file → ``{"assignments": [(name, canvas id or None)],
    "points": {column: float|None}, "students": [{column: cell}]}``."""
    records = _records(data, bom_allowed=True)
    header = records[0]
    if header[:5] != CANVAS_IDENTITY:
        raise FormatError(f"the first columns must be {CANVAS_IDENTITY}, got {header[:5]}")
    columns = header[5:]
    if len(set(header)) != len(header):
        raise FormatError("a column name appears twice")
    assignments = []
    for name in columns:
        if not name.strip() or name != name.strip():
            raise FormatError(f"assignment column {name!r}: empty or with blanks around it")
        if name in CANVAS_READ_ONLY:
            raise FormatError(f"{name!r} is a column Canvas computes (read only)")
        found = re.match(r"^(.*\S) \((\d+)\)$", name)
        assignments.append((found[1], found[2]) if found else (name, None))
    if len(records) < 2 or records[1][0].strip() != "Points Possible":
        raise FormatError("the second record must be the Points Possible row")
    if any(records[1][1:5]):
        raise FormatError("the Points Possible row has identity cells")
    points = {c: _number(v, f"Points Possible of {c!r}") for c, v in zip(columns, records[1][5:])}
    students = []
    seen = set()
    for number, record in enumerate(records[2:], 3):
        row = dict(zip(header, record))
        if row["Student"].strip() == "Points Possible":
            raise FormatError(f"record {number}: a second Points Possible row")
        key = (row["ID"], row["SIS User ID"], row["SIS Login ID"])
        if not any(key):
            raise FormatError(f"record {number}: no ID, SIS User ID or SIS Login ID: Canvas cannot match the student")
        if key in seen:
            raise FormatError(f"record {number}: the student {key} appears twice")
        seen.add(key)
        for column in columns:
            _number(row[column], f"record {number}, {column!r}")
        students.append(row)
    return {"assignments": assignments, "points": points, "students": students}


def parse_moodle(data: bytes, field: str) -> dict:
    """A Moodle grade-import file whose first column identifies users by ``field`` (email,
    username, idnumber) → ``{"items": [names], "grades": {identifier: {item: float|None}}}``."""
    records = _records(data, bom_allowed=False)
    header = records[0]
    if header[0] != MOODLE_IDENTIFIERS[field]:
        raise FormatError(f"the first column must identify users by {field} ({MOODLE_IDENTIFIERS[field]!r}), "
                          f"got {header[0]!r}")
    if len(header) < 2:
        raise FormatError("no grade item column")
    if len(set(header)) != len(header) or any(not h.strip() or h != h.strip() for h in header):
        raise FormatError("column names must be unique, not empty, without blanks around them")
    grades: dict[str, dict[str, float | None]] = {}
    for number, record in enumerate(records[1:], 2):
        user = record[0]
        if not user.strip():
            raise FormatError(f"record {number}: no {field}: Moodle stops the import at it")
        if field == "email" and not re.match(r"^[^@\s]+@[^@\s]+$", user):
            raise FormatError(f"record {number}: {user!r} is not an e-mail address")
        if user in grades:
            raise FormatError(f"record {number}: {user!r} appears twice")
        grades[user] = {item: (None if value == "-" else _number(value, f"record {number}, {item!r}"))
                        for item, value in zip(header[1:], record[1:])}
    return {"items": header[1:], "grades": grades}
