"""The files for Canvas and Moodle (cvkit.course.lms), from a grade sheet made here: golden files,
read back by strict readers of each LMS's documented format (tests/course/lms_formats.py); blank cells
(never 0) with their reasons; rosters that do not match the course; an empty class."""
from __future__ import annotations

import csv
import os
from pathlib import Path

import pytest

from cvkit.course.lms import (CANVAS_IDENTITY, NO_SUBMISSION, PENDING, Grade, GradeSheet, canvas_export,
                              moodle_export, points_text)
from lms_formats import FormatError, parse_canvas, parse_moodle

GOLDEN = Path(__file__).resolve().parent / "golden" / "lms"
UPDATE = os.environ.get("CVKIT_UPDATE_GOLDEN") == "1"  # rewrite the golden files (then read the diff!)


def sheet() -> GradeSheet:
    """Three assignments (one nobody handed in), five students: points after a late penalty, a
    fractional score, a real zero, written answers to mark, a submission not graded, a name
    with a comma and quotes, a non-ASCII id, an id a spreadsheet would run."""
    a1, a2, a3 = "ch01_intro", "ch02_formation", "ch03_empty"
    grades = {
        ("ada", a1): Grade(6.0), ("ada", a2): Grade(5.5),
        ("bob", a1): Grade(2.0 + 2 / 3, penalty=1.0), ("bob", a2): Grade(None, PENDING, pending=True),
        ("cyd", a1): Grade(None, "not graded: the notebook is not valid JSON"), ("cyd", a2): Grade(0.0),
        ("=evil", a1): Grade(1.0),
        ("zoë", a1): Grade(3.0), ("zoë", a2): Grade(8.0),
    }
    return GradeSheet([a1, a2, a3], ["ada", "bob", "cyd", "=evil", "zoë"], grades,
                      points_possible={a1: 6.0, a2: 8.0, a3: 4.0},
                      titles={a1: 'Chapter 1, "images"', a2: "Zoë's chapter", a3: a3},
                      emails={"ada": "ada@example.org", "bob": "bob@example.org", "zoë": "zoe@example.org"})


def check_golden(path: Path, name: str) -> bytes:
    data = path.read_bytes()
    golden = GOLDEN / name
    if UPDATE:
        golden.write_bytes(data)
    assert data == golden.read_bytes(), f"{name} differs from the golden file"
    return data


def reasons(path: Path) -> list[tuple[str, str, str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["student", "assignment", "reason"]
    return [tuple(r) for r in rows[1:]]


def test_points_text():
    assert [points_text(v) for v in (None, 0.0, 10.0, 7.5, 2 + 2 / 3, 1234567.0, 0.004)] == \
        ["", "0", "10", "7.5", "2.67", "1234567", "0"]


def test_canvas_without_roster(tmp_path):
    done = canvas_export(sheet(), tmp_path / "canvas_grades.csv")
    parsed = parse_canvas(check_golden(done.path, "canvas_grades.csv"))
    assert parsed["assignments"] == [("ch01_intro", None), ("ch02_formation", None), ("ch03_empty", None)]
    assert parsed["points"] == {"ch01_intro": 6.0, "ch02_formation": 8.0, "ch03_empty": 4.0}
    rows = {r["SIS Login ID"]: r for r in parsed["students"]}
    assert set(rows) == {"ada", "bob", "cyd", "zoë"}  # =evil cannot be written unchanged: left out, listed
    assert rows["bob"]["ch01_intro"] == "2.67"  # 3.67 earned, 1 point late penalty: what the student has
    assert rows["cyd"]["ch02_formation"] == "0"  # a real zero stays a zero
    # blank, never 0: written answers to mark, not graded, no submission
    assert rows["bob"]["ch02_formation"] == "" and rows["cyd"]["ch01_intro"] == "" and rows["ada"]["ch03_empty"] == ""
    why = {(s, a): r for s, a, r in reasons(done.reasons)}
    assert why[("bob", "ch02_formation")] == PENDING
    assert why[("cyd", "ch01_intro")] == "not graded: the notebook is not valid JSON"
    assert why[("ada", "ch03_empty")] == NO_SUBMISSION
    assert "left out" in why[("'=evil", "")] and any("=evil" in line for line in done.lines)
    # every blank grade cell of the file has its line in the side file
    blanks = {(r["SIS Login ID"], a) for r in parsed["students"] for a, _ in parsed["assignments"] if r[a] == ""}
    assert blanks == {(s, a) for s, a, _ in reasons(done.reasons) if a}
    assert any("new in Canvas" in line for line in done.lines)


def canvas_roster(tmp_path: Path) -> Path:
    """A roster shaped like Canvas's gradebook export: a byte-order mark, the Points Possible row,
    Canvas ids in the assignment columns (one matched by the plan's title), the test student,
    read-only columns, a student not in the course."""
    rows = [["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "ch01_intro (1001)", "Zoë's chapter (1002)",
             "Quiz 1 (2000)", "Current Score", "Final Score"],
            ["    Points Possible", "", "", "", "", "6", "8", "10", "(read only)", "(read only)"],
            ["Lovelace, Ada", "501", "S-1", "ada", "Section A", "", "", "9", "90", "90"],
            ["Builder, Bob", "502", "S-2", "bob", "Section B", "", "", "", "", ""],
            ["Doe, Dan", "503", "S-3", "dan", "Section A", "", "", "7", "70", "70"],
            ["Student, Test", "599", "", "", "Section A", "", "", "", "", ""]]
    path = tmp_path / "canvas_export.csv"
    with path.open("w", newline="", encoding="utf-8-sig") as handle:
        csv.writer(handle).writerows(rows)
    return path


def test_canvas_with_roster(tmp_path):
    done = canvas_export(sheet(), tmp_path / "canvas_grades.csv", roster=canvas_roster(tmp_path))
    parsed = parse_canvas(check_golden(done.path, "canvas_grades_roster.csv"))
    # the columns of assignments Canvas knows carry its ids, by the assignment id or the plan's title;
    # only cvkit's assignments are written (Quiz 1 is not touched)
    assert parsed["assignments"] == [("ch01_intro", "1001"), ("Zoë's chapter", "1002"), ("ch03_empty", None)]
    rows = {r["SIS Login ID"]: r for r in parsed["students"]}
    assert rows["ada"]["Student"] == "Lovelace, Ada" and rows["ada"]["ID"] == "501" and rows["ada"]["Section"] == "Section A"
    assert rows["ada"]["ch01_intro (1001)"] == "6" and rows["bob"]["Zoë's chapter (1002)"] == ""
    # in the roster, not in the course: in the file with blank grades, and listed
    assert rows["dan"]["ID"] == "503" and all(rows["dan"][c] == "" for c in parsed["points"])
    why = reasons(done.reasons)
    assert ("dan", "", "in the Canvas roster, not in the course: grades blank") in why
    # in the course, not in the roster: not in the file, listed (never silently dropped)
    for student in ("cyd", "zoë"):
        assert student not in rows
        assert (student, "", "in the course, not in the Canvas roster (SIS Login ID): not in the file") in why
        assert any(line.startswith(f"{student} is in the course but not in the Canvas roster") for line in done.lines)


def test_canvas_roster_column_and_errors(tmp_path):
    roster = canvas_roster(tmp_path)
    done = canvas_export(sheet(), tmp_path / "by_sis.csv", roster=roster, column="SIS User ID")
    parsed = parse_canvas(done.path.read_bytes())
    # nobody's SIS User ID is a cvkit id: the roster's rows, every grade blank (never a made-up number)
    assert {r["ID"] for r in parsed["students"]} == {"501", "502", "503", "599"}
    assert all(r[c] == "" for r in parsed["students"] for c in parsed["points"])
    assert {b[0] for b in done.blank if "not in the Canvas roster" in b[2]} == set(sheet().students)
    assert any("Student, Test has no SIS User ID" in line for line in done.lines)
    with pytest.raises(ValueError, match="--roster-column 'Email' is not a column"):
        canvas_export(sheet(), tmp_path / "x.csv", roster=roster, column="Email")
    other = tmp_path / "other.csv"
    other.write_text("student_id,email\nada,ada@example.org\n")
    with pytest.raises(ValueError, match="--roster .*not a Canvas gradebook export"):
        canvas_export(sheet(), tmp_path / "x.csv", roster=other)
    other.write_bytes(b"Student,ID\n\xff\xfe\n")
    with pytest.raises(ValueError, match="--roster .*not UTF-8"):
        canvas_export(sheet(), tmp_path / "x.csv", roster=other)


def test_moodle_username(tmp_path):
    done = moodle_export(sheet(), tmp_path / "moodle_grades.csv", "username")
    parsed = parse_moodle(check_golden(done.path, "moodle_grades_username.csv"), "username")
    assert parsed["items"] == ["ch01_intro", "ch02_formation", "ch03_empty"]
    assert parsed["grades"]["bob"] == {"ch01_intro": 2.67, "ch02_formation": None, "ch03_empty": None}
    assert parsed["grades"]["cyd"]["ch01_intro"] is None and parsed["grades"]["cyd"]["ch02_formation"] == 0.0
    assert "=evil" not in parsed["grades"] and "'=evil" not in parsed["grades"]
    assert any("=evil" in s and "left out" in r for s, a, r in reasons(done.reasons))
    assert any("maximum points" in line and "ch02_formation 8" in line for line in done.lines)


def test_moodle_email_from_gradebook_and_roster(tmp_path):
    done = moodle_export(sheet(), tmp_path / "moodle_grades.csv", "email")
    parsed = parse_moodle(check_golden(done.path, "moodle_grades_email.csv"), "email")
    assert set(parsed["grades"]) == {"ada@example.org", "bob@example.org", "zoe@example.org"}
    assert ("cyd", "", "in the course, no email in the gradebook's e-mail addresses: not in the file") in \
        reasons(done.reasons)
    roster = tmp_path / "roster.csv"
    roster.write_text("student_id,idnumber\nada,1001\ncyd,1003\nnina,1009\n", encoding="utf-8")
    done = moodle_export(sheet(), tmp_path / "m2.csv", "idnumber", roster=roster)
    parsed = parse_moodle(done.path.read_bytes(), "idnumber")
    assert parsed["grades"] == {"1001": {"ch01_intro": 6.0, "ch02_formation": 5.5, "ch03_empty": None},
                                "1003": {"ch01_intro": None, "ch02_formation": 0.0, "ch03_empty": None}}
    why = reasons(done.reasons)
    assert ("nina", "", "in the roster, not in the course: no grades") in why
    assert ("bob", "", "in the course, no idnumber in the roster roster.csv: not in the file") in why
    with pytest.raises(ValueError, match="needs the columns student_id and email"):
        moodle_export(sheet(), tmp_path / "m3.csv", "email", roster=roster)
    with pytest.raises(ValueError, match="--moodle must be one of"):
        moodle_export(sheet(), tmp_path / "m3.csv", "name")


def test_empty_class(tmp_path):
    empty = GradeSheet(["ch01_intro"], [], {}, points_possible={"ch01_intro": 6.0},
                       notes=["the course has no students"])
    parsed = parse_canvas(canvas_export(empty, tmp_path / "c.csv").path.read_bytes())
    assert parsed["students"] == [] and parsed["points"] == {"ch01_intro": 6.0}
    done = moodle_export(empty, tmp_path / "m.csv", "username")
    assert parse_moodle(done.path.read_bytes(), "username")["grades"] == {}
    assert "the course has no students" in done.lines


@pytest.mark.parametrize("data, problem", [
    (b"Student,ID,SIS User ID,SIS Login ID,Section,a\r\n    Points Possible,,,,,5\r\nx,1,,,,5\n", "CRLF"),
    (b"Student,ID,SIS User ID,SIS Login ID,Section,a\r\n    Points Possible,,,,,5\r\nx,1,,,,0,5\r\n", "fields"),
    (b"Student,ID,SIS User ID,SIS Login ID,Section,a\r\nx,1,,,,5\r\n", "Points Possible"),
    (b"Student,ID,SIS User ID,SIS Login ID,Section,a\r\n    Points Possible,,,,,5\r\nx,1,,,,5.0e1\r\n", "decimal"),
    (b"Student,ID,SIS User ID,SIS Login ID,Section,a\r\n    Points Possible,,,,,5\r\nx,,,,,5\r\n", "cannot match"),
    (b"Student,ID,SIS User ID,SIS Login ID,Section,\"a\"\r\n    Points Possible,,,,,5\r\n", "quoting"),
    (b"Student,ID,SIS Login ID,SIS User ID,Section,a\r\n    Points Possible,,,,,5\r\n", "first columns"),
    (b"Student,ID,SIS User ID,SIS Login ID,Section,a\r\n    Points Possible,,,,,5\r\n\xe9,1,,,,5\r\n", "UTF-8"),
])
def test_canvas_reader_is_strict(data, problem):
    with pytest.raises(FormatError, match=problem):
        parse_canvas(data)


@pytest.mark.parametrize("data, problem", [
    (b"\xef\xbb\xbfUsername,a\r\nada,5\r\n", "byte-order mark"),
    (b"Email address,a\r\nada,5\r\n", "first column"),
    (b"Username,a\r\n,5\r\n", "stops the import"),
    (b"Username,a\r\nada,5,5\r\n", "fields"),
    (b"Username,a\r\nada,\"5,5\"\r\n", "decimal"),
    (b"Username,a,a\r\nada,5,5\r\n", "unique"),
])
def test_moodle_reader_is_strict(data, problem):
    with pytest.raises(FormatError, match=problem):
        parse_moodle(data, "username")


def test_identity_columns_are_canvas_s():
    assert list(CANVAS_IDENTITY) == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"]
