"""Submission time is trusted data (``cvkit.course.received``): the late penalty is computed
from when a submission was received — the instructor's ``submission_times.csv``, nbgrader's
exchange, cvkit's record of the hand-in, the collection — never from the ``timestamp.txt``
students can write. That file is only a cross-check, flagged when implausible.

- the list, the exchange lookup (ctime of matching inbound notebooks) and the records kept at
  first sight, one by one;
- through the real pipeline (``Course.grade``, the tiny chapter of ``test_course_scaling``):
  a late student whose ``timestamp.txt`` says 1970 and one whose file is garbage are penalised,
  graded and flagged; honest students on time and late are not flagged; a listed time wins,
  a corrected one regrades that submission, a malformed list stops grading naming the line.
"""
import datetime as dt
import json
import os
import shutil

import pytest
from test_course_plan import DUE, PLAN  # the same plan: due 2030-01-01, 0.5 points per started hour
from test_course_scaling import ASSIGNMENT, _answers, make_course
from test_course_scaling import project  # noqa: F401  (the tiny chapter's project, a fixture)

from cvkit.course import Course, received
from cvkit.course.journal import Journal
from cvkit.course.received import (
    Received, SubmissionTimesError, cross_check, exchange_time, read_claim, read_list, received_time,
)
from cvkit.course.results import notebook_flags

UTC = dt.timezone.utc
NOTEBOOK = f"{ASSIGNMENT}.ipynb"
HEADER = "student_id,assignment,timestamp\n"


def ctime_of(path):
    """The inode change time of ``path`` as naive UTC (how cvkit records it)."""
    return dt.datetime.fromtimestamp(os.lstat(path).st_ctime, tz=UTC).replace(tzinfo=None)


def place(root, student, files):
    """A submission put into ``submitted/`` by hand (an unpacked zip, nbgrader's collect)."""
    folder = root / "submitted" / student / ASSIGNMENT
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        (folder / name).write_bytes(data)
    return folder


def inbound_folder(inbound, name, files):
    """A folder of nbgrader's exchange, as ``nbgrader submit`` (run by the student) leaves it."""
    folder = inbound / name
    folder.mkdir(parents=True)
    for relative, data in files.items():
        (folder / relative).write_bytes(data)
    return folder


@pytest.fixture
def course(project, tmp_path):  # noqa: F811 - the imported fixture
    """A course folder (not built) whose nbgrader configuration has an exchange in ``tmp_path``."""
    folder = tmp_path / "course"
    made = Course(folder, project=project)
    (folder / "plan.toml").write_text(PLAN)
    with (folder / "nbgrader_config.py").open("a") as handle:
        handle.write(f"c.Exchange.root = {str(tmp_path / 'exchange')!r}\n")
    course_id = made.config().CourseDirectory.course_id
    (tmp_path / "exchange" / course_id / "inbound").mkdir(parents=True)
    made.inbound = tmp_path / "exchange" / course_id / "inbound"
    return made


# ------------------------------------------------------------------------- the instructor's list
def test_the_list_reads_iso_times_with_their_zones(tmp_path):
    path = tmp_path / "submission_times.csv"
    path.write_text("\ufeffstudent_id,assignment,timestamp,note\n"
                    "ada,ch03,2030-01-01T03:30:00+01:00,by mail\n"
                    " bob , ch03 ,2030-01-01 02:30Z,\n"
                    "\n"
                    "cyd,ch04,2030-01-01T02:30:00.5+00:00,\n")
    assert read_list(path) == {("ada", "ch03"): dt.datetime(2030, 1, 1, 2, 30),
                               ("bob", "ch03"): dt.datetime(2030, 1, 1, 2, 30),
                               ("cyd", "ch04"): dt.datetime(2030, 1, 1, 2, 30, 0, 500000)}
    assert read_list(tmp_path / "none.csv") == {}


def test_a_malformed_list_names_each_bad_line(tmp_path):
    path = tmp_path / "submission_times.csv"
    path.write_text(HEADER
                    + "ada,ch03,2030-01-01 02:30:00\n"     # line 2
                    + "bob,ch03,next monday\n"            # line 3
                    + "cyd,ch03\n"                        # line 4
                    + ",ch03,2030-01-01T02:30:00Z\n"      # line 5
                    + "dan,ch03,2030-01-01T02:30:00Z\n"   # line 6: fine
                    + "dan,ch03,2030-01-02T02:30:00Z\n")  # line 7
    with pytest.raises(SubmissionTimesError) as caught:
        read_list(path)
    message = str(caught.value)
    assert isinstance(caught.value, ValueError)  # the command line prints it, exit status 2
    assert message.startswith(f"{path}: 5 malformed rows")
    assert message.splitlines()[1:] == [
        "  line 2: timestamp '2030-01-01 02:30:00' has no time zone; write it with an offset (+01:00) or Z for UTC",
        "  line 3: timestamp 'next monday' is not an ISO 8601 date and time such as 2027-03-08T23:59:00+01:00",
        "  line 4: 2 cells, the header has 3",
        "  line 5: empty student_id",
        "  line 7: dan ch03 is listed already on line 6",
    ]
    path.write_text("name,when\nada,2030-01-01T02:30:00Z\n")
    with pytest.raises(SubmissionTimesError, match=r"line 1: the header must name the columns student_id, "
                                                   r"assignment, timestamp \(missing student_id, assignment, "
                                                   r"timestamp\)"):
        read_list(path)
    path.write_bytes(HEADER.encode() + b"ada,ch03,2030-01-01T02:30:00Z \xff\n")
    with pytest.raises(SubmissionTimesError, match="not UTF-8 text"):
        read_list(path)


def test_a_listed_time_is_part_of_the_journal_hash(course):
    """A corrected row makes that submission (and only it) not current: the next run regrades it."""
    for student in ("ada", "bob"):
        place(course.root, student, {NOTEBOOK: b"{}"})
    journal = Journal(course.root)
    before = {s: journal.submission_hash(s, ASSIGNMENT) for s in ("ada", "bob")}
    lists = course.root / "submission_times.csv"
    lists.write_text(HEADER + f"ada,{ASSIGNMENT},2030-01-01T02:30:00Z\n")
    listed = journal.submission_hash("ada", ASSIGNMENT)
    assert listed != before["ada"] and journal.submission_hash("bob", ASSIGNMENT) == before["bob"]
    lists.write_text(HEADER + f"ada,{ASSIGNMENT},2030-01-01T03:30:00Z\n")  # same size, same inode
    assert journal.submission_hash("ada", ASSIGNMENT) not in (listed, before["ada"])
    lists.write_text(HEADER + f"ada,{ASSIGNMENT},yesterday\n")
    with pytest.raises(SubmissionTimesError, match="line 2: timestamp 'yesterday'"):
        journal.is_current("ada", ASSIGNMENT)


# ------------------------------------------------------------------------- nbgrader's exchange
def test_the_exchange_time_is_the_ctime_of_the_matching_notebooks(tmp_path):
    inbound = tmp_path / "inbound"
    work = json.dumps(_answers()).encode()
    # the names are the student's own: "1970" in one says nothing, the content decides
    inbound_folder(inbound, "ada+ch99_tiny+1970-01-01 00:00:00.000000 UTC+a1", {NOTEBOOK: b'{"other": 1}'})
    honest = inbound_folder(inbound, "ada+ch99_tiny+2030-01-01 02:30:00.000000 UTC+b2", {NOTEBOOK: work})
    inbound_folder(inbound, "bob+ch99_tiny+1970-01-01 00:00:00.000000 UTC+c3", {NOTEBOOK: work})
    assert exchange_time(inbound, "ada", ASSIGNMENT, {NOTEBOOK: work}) == ctime_of(honest / NOTEBOOK)
    assert exchange_time(inbound, "ada", ASSIGNMENT, {NOTEBOOK: b"never handed in"}) is None
    assert exchange_time(inbound, "cyd", ASSIGNMENT, {NOTEBOOK: work}) is None
    assert exchange_time(tmp_path / "no exchange", "ada", ASSIGNMENT, {NOTEBOOK: work}) is None
    # a link to a file with the collected content is no record of a hand-in
    shutil.rmtree(honest)
    outside = tmp_path / "kept.ipynb"
    outside.write_bytes(work)
    linked = inbound / "ada+ch99_tiny+1970-01-01 00:00:00.000000 UTC+d4"
    linked.mkdir()
    (linked / NOTEBOOK).symlink_to(outside)
    assert exchange_time(inbound, "ada", ASSIGNMENT, {NOTEBOOK: work}) is None


def test_an_exchange_submission_keeps_its_time_after_the_exchange_is_cleaned(course):
    work = json.dumps(_answers()).encode()
    handed_in = inbound_folder(course.inbound, f"ada+{ASSIGNMENT}+1970-01-01 00:00:00.000000 UTC+e5", {NOTEBOOK: work})
    place(course.root, "ada", {NOTEBOOK: work, "timestamp.txt": b"1970-01-01 00:00:00.000000 UTC"})
    expected = Received(ctime_of(handed_in / NOTEBOOK), "exchange")
    assert received_time(course, "ada", ASSIGNMENT) == expected and expected.exact
    shutil.rmtree(handed_in)  # the instructor empties the exchange after collecting
    assert received_time(course, "ada", ASSIGNMENT) == expected


# ------------------------------------------------------------------------- cvkit's records
def test_the_collection_time_is_recorded_at_first_sight_and_kept(course):
    folder = place(course.root, "ada", {NOTEBOOK: b'{"v": 1}', "timestamp.txt": b"1970-01-01 00:00:00 UTC"})
    first = received_time(course, "ada", ASSIGNMENT)
    assert first == Received(ctime_of(folder / NOTEBOOK), "collected") and not first.exact
    records = course.root / ".cvkit" / "received.json"
    entry = json.loads(records.read_text())["submissions"][f"ada/{ASSIGNMENT}"]
    assert entry["source"] == "collected" and entry["at"] == first.at.isoformat() + "Z"
    # later runs read the record: a chmod (a later ctime) or a new claim changes nothing
    (folder / NOTEBOOK).chmod(0o600)
    (folder / "timestamp.txt").write_text("2029-12-31 00:00:00 UTC")
    assert received_time(course, "ada", ASSIGNMENT) == first
    data = json.loads(records.read_text())
    data["submissions"][f"ada/{ASSIGNMENT}"]["at"] = "2031-06-01T12:00:00Z"
    records.write_text(json.dumps(data))
    assert received_time(course, "ada", ASSIGNMENT) == Received(dt.datetime(2031, 6, 1, 12), "collected")
    # a new version of the work is a new hand-in
    (folder / NOTEBOOK).write_bytes(b'{"v": 2}')
    assert received_time(course, "ada", ASSIGNMENT) == Received(ctime_of(folder / NOTEBOOK), "collected")
    assert json.loads(records.read_text())["submissions"][f"ada/{ASSIGNMENT}"]["files"] != entry["files"]


def test_submit_records_when_it_was_received(course):
    when = dt.datetime(2030, 1, 1, 3, 30, tzinfo=dt.timezone(dt.timedelta(hours=1)))
    folder = course.submit("ada", ASSIGNMENT, {NOTEBOOK: _answers()}, received_at=when)
    expected = Received(dt.datetime(2030, 1, 1, 2, 30), "submitted")
    assert received_time(course, "ada", ASSIGNMENT) == expected
    assert (folder / "timestamp.txt").read_text() == "2030-01-01 02:30:00.000000 UTC"  # as nbgrader writes it
    assert sorted(p.name for p in folder.iterdir()) == [NOTEBOOK, "timestamp.txt"]  # the record is not there
    (folder / "timestamp.txt").write_text("1970-01-01 00:00:00.000000 UTC")
    assert received_time(course, "ada", ASSIGNMENT) == expected
    with pytest.raises(ValueError, match="received_at must be a datetime with a time zone"):
        course.submit("bob", ASSIGNMENT, {NOTEBOOK: _answers()}, received_at=dt.datetime(2030, 1, 1))
    assert not (course.root / "submitted" / "bob").exists()


# ------------------------------------------------------------------------- the cross-check
@pytest.mark.parametrize("content, expected", [
    (b"2030-01-01 02:30:00.000000 UTC", (dt.datetime(2030, 1, 1, 2, 30), "")),
    (b"2030-01-01 03:30:00.000000 Europe/Berlin", (dt.datetime(2030, 1, 1, 2, 30), "")),
    (b"1970-01-01 00:00:00", (dt.datetime(1970, 1, 1), "")),
    (b"not a date", (None, "not a date and time")),
    (b"2030-13-45 99:99:99 UTC", (None, "not a date and time")),
    (b"\xff\xfe2\x000\x003\x000\x00", (None, "not UTF-8 text")),
    (b"  \n", (None, "empty")),
    (b"2030-01-01 02:30:00 UTC" + b" " * 2000, (None, "longer than 1024 bytes")),
])
def test_the_claim_is_read_as_nbgrader_would_or_said_unreadable(tmp_path, content, expected):
    path = tmp_path / "timestamp.txt"
    path.write_bytes(content)
    assert read_claim(path) == expected


def test_no_claim_is_no_flag(tmp_path):
    assert read_claim(tmp_path / "timestamp.txt") == (None, "")
    (tmp_path / "elsewhere").write_text("1970-01-01 00:00:00 UTC")
    (tmp_path / "timestamp.txt").symlink_to(tmp_path / "elsewhere")  # refused (and flagged) by the collection
    assert read_claim(tmp_path / "timestamp.txt") == (None, "")


def test_a_claim_is_checked_against_an_exact_record(course):
    """The list (like the exchange) records the hand-in itself: a claim more than five minutes
    from it either way is flagged; within five minutes, clock skew."""
    folder = place(course.root, "ada", {NOTEBOOK: b"{}"})
    (course.root / "submission_times.csv").write_text(HEADER + f"ada,{ASSIGNMENT},2030-01-01T00:30:00Z\n")
    graded = "graded as received at 2030-01-01 00:30:00 UTC (the instructor's list submission_times.csv)"
    claims = {
        "2029-12-31 23:30:00 UTC": [f"(notebook): submission time: timestamp.txt says 2029-12-31 23:30:00 UTC, "
                                    f"earlier than the record of its hand-in; {graded}"],
        "2030-01-01 00:26:00 UTC": [],
        "2030-01-01 00:34:00 UTC": [],
        "2030-01-01 00:40:00 UTC": [f"(notebook): submission time: timestamp.txt says 2030-01-01 00:40:00 UTC, "
                                    f"after the submission was received; {graded}"],
    }
    for claim, flags in claims.items():
        (folder / "timestamp.txt").write_text(claim)
        assert cross_check(course, "ada", ASSIGNMENT) == flags, claim


def test_an_on_time_claim_timed_only_by_a_late_collection_is_flagged(course):
    """No record of the hand-in but its collection, after the due date: graded late, and
    flagged when the student's file says it was on time (the instructor's list can correct it)."""
    (course.root / "plan.toml").write_text(PLAN.replace("2030-01-01", "2020-01-01"))
    folder = place(course.root, "ada", {NOTEBOOK: b"{}", "timestamp.txt": b"2019-12-31 23:00:00.000000 UTC"})
    when = received_time(course, "ada", ASSIGNMENT)
    assert when.source == "collected" and when.at > dt.datetime(2020, 1, 1)
    assert cross_check(course, "ada", ASSIGNMENT) == [
        f"(notebook): submission time: timestamp.txt says 2019-12-31 23:00:00 UTC, by the due date, but the only "
        f"record of the hand-in is its collection, after it; graded as received at {when.describe()}; if it was "
        f"on time, list its time in submission_times.csv"]
    (folder / "timestamp.txt").write_text("2020-01-01 00:30:00.000000 UTC")  # late by its own account
    assert cross_check(course, "ada", ASSIGNMENT) == []


# ------------------------------------------------------------------------- the real pipeline
def _at(**delta):
    return (DUE + dt.timedelta(**delta)).replace(tzinfo=UTC)


#: student → (received, what their timestamp.txt says; None: the one submit wrote, honest)
HAND_INS = {
    "forger": (_at(hours=2, minutes=30), "1970-01-01 00:00:00.000000 UTC"),
    "garbler": (_at(hours=1, minutes=10), "not a date"),
    "punctual": (_at(hours=-12), None),
    "tardy": (_at(hours=4, minutes=50), None),
}
#: the trusted time (naive UTC) and the penalty: 0.5 points per started hour late, 6 points scored
EXPECTED = {
    "forger": (dt.datetime(2030, 1, 1, 2, 30), 1.5),
    "garbler": (dt.datetime(2030, 1, 1, 1, 10), 1.0),
    "punctual": (dt.datetime(2029, 12, 31, 12, 0), 0.0),
    "tardy": (dt.datetime(2030, 1, 1, 4, 50), 2.5),
    "listed": (dt.datetime(2030, 1, 1, 0, 30), 0.5),
}


def _submission(course, student):
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gb:
        found = gb.find_submission(ASSIGNMENT, student)
        return {"timestamp": found.timestamp, "penalty": found.late_submission_penalty, "max": found.max_score,
                "raw": sum(g.score for nb in found.notebooks for g in nb.grades),
                "flagged": [nb.flagged for nb in found.notebooks]}


def _time_flags(course, student):
    folder = course.root / "autograded" / student / ASSIGNMENT
    return [f for path in sorted(folder.glob("*.ipynb")) for f in notebook_flags(path) if "submission time" in f]


@pytest.fixture(scope="module")
def graded(project, tmp_path_factory):  # noqa: F811 - the imported fixture
    """Five students, all with the right answers (6 points), due 2030-01-01 00:00 UTC: four
    handed in through ``Course.submit`` with their received times, two of them then writing
    their own ``timestamp.txt``; one zip unpacked by hand, without one, timed by the list."""
    folder = tmp_path_factory.mktemp("times") / "course"
    folder.mkdir()
    (folder / "plan.toml").write_text(PLAN)
    course = make_course(project, folder, students={})
    for student, (when, claim) in HAND_INS.items():
        path = course.submit(student, ASSIGNMENT, {NOTEBOOK: _answers()}, received_at=when)
        if claim is not None:
            (path / "timestamp.txt").write_text(claim)
    place(course.root, "listed", {NOTEBOOK: json.dumps(_answers()).encode()})
    (course.root / "submission_times.csv").write_text(HEADER + f"listed,{ASSIGNMENT},2030-01-01T01:30:00+01:00\n")
    results = course.grade(workers=2)
    return course, results


@pytest.mark.slow
def test_penalties_come_from_the_trusted_time(graded):
    course, results = graded
    assert all(r.ok for r in results), [r.log[-800:] for r in results if not r.ok]
    assert course.not_graded() == {}
    for student, (when, penalty) in EXPECTED.items():
        found = _submission(course, student)
        assert (found["timestamp"], found["raw"], found["max"]) == (when, pytest.approx(6), 6), student
        assert found["penalty"] == pytest.approx(penalty), student


@pytest.mark.slow
def test_forged_and_garbage_claims_are_flagged_never_trusted(graded):
    course, _ = graded
    release = received.release_time(course, ASSIGNMENT)
    record = "cvkit's record of the hand-in"
    assert {s: _time_flags(course, s) for s in EXPECTED} == {
        "forger": [f"(notebook): submission time: timestamp.txt says 1970-01-01 00:00:00 UTC, before the assignment "
                   f"was released ({release:%Y-%m-%d %H:%M:%S} UTC); graded as received at 2030-01-01 02:30:00 UTC "
                   f"({record})"],
        "garbler": [f"(notebook): submission time: timestamp.txt is unreadable (not a date and time); graded as "
                    f"received at 2030-01-01 01:10:00 UTC ({record})"],
        "punctual": [], "tardy": [], "listed": [],
    }
    assert {s: _submission(course, s)["flagged"] for s in EXPECTED} == {
        "forger": [True], "garbler": [True], "punctual": [False], "tardy": [False], "listed": [False]}
    assert "forger · (notebook): submission time: timestamp.txt says 1970-01-01" in course.table(ASSIGNMENT)
    # what nbgrader read was the trusted time, never the student's file
    staged = course.root / "autograded" / "forger" / ASSIGNMENT / "timestamp.txt"
    assert not staged.exists() or staged.read_text() == "2030-01-01 02:30:00.000000 UTC"


@pytest.mark.slow
def test_a_corrected_list_regrades_that_submission(graded):
    course, _ = graded
    before = {s: _submission(course, s) for s in EXPECTED}
    (course.root / "submission_times.csv").write_text(HEADER + f"listed,{ASSIGNMENT},2030-01-01T02:10:00Z\n")
    results = course.grade(workers=2)
    assert [(r.student, r.ok) for r in results] == [("listed", True)]
    assert _submission(course, "listed")["timestamp"] == dt.datetime(2030, 1, 1, 2, 10)
    assert _submission(course, "listed")["penalty"] == pytest.approx(1.5)  # three started hours × 0.5
    assert {s: _submission(course, s) for s in EXPECTED if s != "listed"} == \
        {s: v for s, v in before.items() if s != "listed"}


@pytest.mark.slow
def test_a_malformed_list_stops_grading_naming_the_line(graded):
    course, _ = graded
    lists = course.root / "submission_times.csv"
    kept = lists.read_text()
    lists.write_text(kept + "tardy,ch99_tiny,yesterday\n")
    try:
        with pytest.raises(SubmissionTimesError, match=r"submission_times.csv: 1 malformed row .*\n  line 3: "
                                                       r"timestamp 'yesterday' is not an ISO 8601 date and time"):
            course.grade(workers=2)
    finally:
        lists.write_text(kept)
    assert course.grade(workers=2) == []  # nothing changed meanwhile
