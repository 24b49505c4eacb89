"""Hand-ins into the course from the command line (issue 34, item 4): ``cvkit course collect``
from an LMS download (Canvas's file names in a zip, Moodle's folders, a folder per student), from
one student's notebook — each hand-in whole or not at all, every refused file listed with its
reason, nothing written outside ``submitted/``. (From nbgrader's exchange: the hub round trip,
``tests/system/test_hub_round_trip.py``, collects with it.)"""
from __future__ import annotations

import contextlib
import datetime as dt
import io
import json
import zipfile
from pathlib import Path

import pytest
from test_course_scaling import ASSIGNMENT, WRONG_KERNEL, _answers
from test_course_scaling import project  # noqa: F401  (the tiny chapter's project, a fixture)

from cvkit.cli import main
from cvkit.course import Course
from cvkit.course.collect import collect_files

pytestmark = pytest.mark.slow
NOTEBOOK = f"{ASSIGNMENT}.ipynb"


@pytest.fixture
def course(project, tmp_path):  # noqa: F811
    course = Course(tmp_path / "course", project=project)
    course.build([ASSIGNMENT])
    return course


def _notebook(kernel=None) -> bytes:
    return json.dumps(_answers(kernel=kernel)).encode()


def _zip(path: Path, entries: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in entries.items():
            archive.writestr(name, data)
    return path


def _collect(course: Course, *args: str) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        code = main(["course", "collect", "--course-dir", str(course.root), "--assignment", ASSIGNMENT, *args])
    return code, out.getvalue()


def test_a_canvas_download_is_taken_student_by_student(course, tmp_path):
    download = _zip(tmp_path / "submissions.zip", {
        f"adalovelace_123_456_{NOTEBOOK}": _notebook(),
        f"bob_LATE_124_457_{ASSIGNMENT}-1.ipynb": _notebook(kernel=WRONG_KERNEL),
        f"cyd_125_458_{NOTEBOOK}": _notebook(),
        "cyd_125_459_notes.txt": b"my notes",
        f"dan_126_460_{NOTEBOOK}": b"{not json",
        f"../evil_1_2_{NOTEBOOK}": _notebook(),
        "README.txt": b"exported by Canvas",
    })
    roster = tmp_path / "roster.csv"
    roster.write_text("lms,student_id\nadalovelace,ada\n")
    code, out = _collect(course, "--from", str(download), "--roster", str(roster),
                         "--received-at", "2027-03-01 23:10:00 UTC")
    assert code == 1, out  # something was refused
    assert f"collected ada: {NOTEBOOK}" in out and f"collected bob: {NOTEBOOK}" in out
    assert f"!! refused cyd: nothing imported — cyd_125_459_notes.txt: not a notebook of {ASSIGNMENT}" in out
    assert f"!! refused dan: nothing imported — dan_126_460_{NOTEBOOK}: not a notebook that can be read" in out
    assert f"!! refused ../evil_1_2_{NOTEBOOK}: a path outside its folder (not extracted)" in out
    assert "!! refused README.txt: whose is it?" in out
    assert "2 hand-ins collected" in out and "4 refused" in out
    submitted = course.root / "submitted"
    assert sorted(p.name for p in submitted.iterdir()) == ["ada", "bob"]
    ada = submitted / "ada" / ASSIGNMENT
    assert (ada / NOTEBOOK).read_bytes() == _notebook()
    assert (ada / "timestamp.txt").read_text() == "2027-03-01 23:10:00.000000 UTC"
    assert len((ada / "submission_secret.txt").read_text()) == 32  # for nbgrader's release_feedback
    assert not (course.root / ".cvkit" / "incoming").exists() or not any((course.root / ".cvkit" / "incoming").iterdir())
    assert not (tmp_path / f"evil_1_2_{NOTEBOOK}").exists()
    # the trusted time is the one given, and grading uses it
    from cvkit.course import received

    assert received.received_time(course, "ada", ASSIGNMENT).at == dt.datetime(2027, 3, 1, 23, 10)


def test_moodle_folders_need_a_roster_and_one_notebook_needs_a_student(course, tmp_path):
    download = tmp_path / "moodle"
    (download / "Ada Lovelace_111_assignsubmission_file_").mkdir(parents=True)
    (download / "Ada Lovelace_111_assignsubmission_file_" / NOTEBOOK).write_bytes(_notebook())
    result = collect_files(course, ASSIGNMENT, download)
    assert not result.imported
    assert result.refused == ["Ada Lovelace: nothing imported — 'Ada Lovelace' is not a student id (letters, digits, "
                              "'_', '.', '@', '-'): map the LMS's names to your students' ids with --roster (a CSV "
                              "with the columns lms and student_id)"]
    roster = tmp_path / "roster.csv"
    roster.write_text("lms,student_id\nAda Lovelace,ada\n")
    assert collect_files(course, ASSIGNMENT, download, roster=roster).imported == [("ada", [NOTEBOOK])]
    single = tmp_path / "work.ipynb"
    single.write_bytes(_notebook())
    assert collect_files(course, ASSIGNMENT, single, student="eve").imported == [("eve", [NOTEBOOK])]


def test_collecting_again_keeps_or_updates(course, tmp_path):
    first = tmp_path / "first"
    (first / "ada").mkdir(parents=True)
    (first / "ada" / NOTEBOOK).write_bytes(_notebook())
    assert collect_files(course, ASSIGNMENT, first).imported == [("ada", [NOTEBOOK])]
    assert collect_files(course, ASSIGNMENT, first).unchanged == ["ada"]
    (first / "ada" / NOTEBOOK).write_bytes(_notebook(kernel=WRONG_KERNEL))
    kept = collect_files(course, ASSIGNMENT, first)
    assert kept.kept == ["ada"] and (course.root / "submitted" / "ada" / ASSIGNMENT / NOTEBOOK).read_bytes() == _notebook()
    assert collect_files(course, ASSIGNMENT, first, update=True).imported == [("ada", [NOTEBOOK])]
    assert (course.root / "submitted" / "ada" / ASSIGNMENT / NOTEBOOK).read_bytes() != _notebook()
    assert sorted(p.name for p in (course.root / "submitted" / "ada").iterdir()) == [ASSIGNMENT]  # no leftovers


def test_collected_hand_ins_are_graded(course, tmp_path):
    download = _zip(tmp_path / "d.zip", {f"ada/{NOTEBOOK}": _notebook()})
    assert collect_files(course, ASSIGNMENT, download).imported == [("ada", [NOTEBOOK])]
    results = course.grade([ASSIGNMENT], workers=1)
    assert [(r.student, r.ok) for r in results] == [("ada", True)]
    assert sum(e.score for e in course.scores(ASSIGNMENT)["ada"]) == pytest.approx(6)


@pytest.mark.parametrize("args, message", [
    (["--from", "/nonexistent/download.zip"], "/nonexistent/download.zip does not exist"),
    (["--student", "ada"], "--student, --pattern, --roster and --received-at describe a download"),
    (["--from", ".", "--pattern", "(?P<student_id>x"], "is not a regular expression"),
    (["--from", ".", "--pattern", "(?P<who>.*)"], "needs the groups (?P<student_id>...) and (?P<file_id>...)"),
    ([], "this course has no nbgrader exchange"),
])
def test_bad_collect_options_say_what_to_do(course, args, message):
    code, out = _collect(course, *args)
    assert code == 2 and message in out, out
