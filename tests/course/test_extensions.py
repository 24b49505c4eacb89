"""Per-student extensions in ``plan.toml`` and the due date in the released notebook (issue 34,
item 6): the late penalty counts from a student's extension, nbgrader's gradebook records it (its
``extension`` column, which the formgrader shows), the table says "extended to …", the summary's
late line names the extended date; the release says when it is due, in the course's time zone and
in UTC, and what lateness costs. Wrong extensions are refused naming the entry."""
from __future__ import annotations

import contextlib
import datetime as dt
import io
import json
import re

import pytest
import test_course_scaling as tiny
from course_helpers import write_project

from cvkit.cli import main
from cvkit.course import Course
from cvkit.course.plan import read_plan

pytestmark = pytest.mark.slow
DUE = dt.datetime(2027, 3, 1, 22, 59)  # 23:59 in Berlin
PLAN = f"""[course]
id = "ext-test"
timezone = "Europe/Berlin"

[[assignment]]
id = "{tiny.ASSIGNMENT}"
due = "2027-03-01 23:59:00 Europe/Berlin"

[late]
policy = "per_hour"
points_per_hour = 1

[[extension]]
student = "ada"
assignment = "{tiny.ASSIGNMENT}"
days = 2
reason = "illness, note seen"

[[extension]]
student = "cyd"
assignment = "{tiny.ASSIGNMENT}"
until = "2027-03-02 00:59:00 Europe/Berlin"
"""


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    project = write_project(tmp_path_factory.mktemp("project"), None,
                            {f"{tiny.ASSIGNMENT}/{tiny.ASSIGNMENT}.ipynb": tiny.source_notebook()})
    course = Course(tmp_path_factory.mktemp("course"), project=project)
    (course.root / "plan.toml").write_text(PLAN)
    (course.root / ".grading_salt").write_text("extension-salt")
    course.build([tiny.ASSIGNMENT])
    three_hours_late = (DUE + dt.timedelta(hours=3)).replace(tzinfo=dt.timezone.utc)
    for student in ("ada", "bob", "cyd"):  # all right, all three hours after the due date
        course.submit(student, tiny.ASSIGNMENT, {f"{tiny.ASSIGNMENT}.ipynb": tiny._answers()},
                      received_at=three_hours_late)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["course", "grade", "--course-dir", str(course.root), "--workers", "1"]) == 0
    return course, out.getvalue()


def test_the_late_penalty_counts_from_the_extension(graded):
    from nbgrader.api import Gradebook

    course, out = graded
    with Gradebook(course.db_url) as gradebook:
        found = {s.student.id: (s.score, s.late_submission_penalty, s.extension)
                 for s in gradebook.assignment_submissions(tiny.ASSIGNMENT)}
    # (score before the penalty, penalty, the extension nbgrader records)
    assert found["ada"] == (6, 0, dt.timedelta(days=2))        # within her two extra days
    assert found["bob"] == (6, 3, None)                         # three started hours late
    assert found["cyd"] == (6, 2, dt.timedelta(hours=1))        # two hours after her extension
    assert (f"late: cyd {tiny.ASSIGNMENT}: −2 points (handed in 2 h 00 min after their extended due date "
            "(2027-03-01 23:59 UTC); the table shows the points before it)") in out
    assert f"late: bob {tiny.ASSIGNMENT}: −3 points (handed in 3 h 00 min after the due date;" in out
    assert "late: ada" not in out


def test_the_table_says_who_has_an_extension(graded):
    course, _ = graded
    table = course.table(tiny.ASSIGNMENT)
    assert "Extensions (plan.toml; late penalties count from them):" in table
    assert "  ada: extended to 2027-03-03 22:59 UTC (illness, note seen)" in table
    assert "  cyd: extended to 2027-03-01 23:59 UTC" in table
    assert "bob: extended" not in table


def test_the_release_says_when_it_is_due_and_what_lateness_costs(graded):
    course, _ = graded
    release = json.loads(course.release_notebooks(tiny.ASSIGNMENT)[0].read_text())
    notice = release["cells"][1]
    assert notice["metadata"]["cvkit"] == {"notice": "due"}
    assert "".join(notice["source"]) == (
        "**Due: Monday 1 March 2027, 23:59 Europe/Berlin (22:59 UTC).** A late hand-in loses 1 point for every "
        "started hour after it (never more than it scored). An extension your instructor gave you personally "
        "counts instead of this date.")
    assert "illness" not in json.dumps(release) and not re.search(r"\bada\b", json.dumps(release))


@pytest.mark.parametrize("extension, message", [
    ('student = "ada"\nassignment = "ch42"\ndays = 1', "assignment must be one of the plan's (ch99_tiny), got 'ch42'"),
    ('student = "ada"\nassignment = "ch99_tiny"\nuntil = "2027-02-01 00:00:00 UTC"',
     "the extension ends 2027-02-01 00:00 UTC, not after the due date 2027-03-01 22:59 UTC"),
    ('student = "ada"\nassignment = "ch99_tiny"\nuntil = "2027-03-05 00:00:00 UTC"\ndays = 1',
     "give until = \"2027-03-05 23:59:00 UTC\", or days (and/or hours) after the due date — one of them"),
    ('student = "ada"\nassignment = "ch99_tiny"\nweeks = 1', "unknown key 'weeks'"),
    ('assignment = "ch99_tiny"\ndays = 1', "student must be a student id, got None"),
])
def test_wrong_extensions_are_refused_naming_the_entry(tmp_path, extension, message):
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.split("[[extension]]")[0] + "[[extension]]\n" + extension + "\n")
    with pytest.raises(ValueError, match=re.escape(message)):
        read_plan(plan)


def test_two_extensions_for_one_student_and_a_wrong_time_zone_are_refused(tmp_path):
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.replace('student = "cyd"', 'student = "ada"'))
    with pytest.raises(ValueError, match="extension #2: ada has two extensions for ch99_tiny: keep one"):
        read_plan(plan)
    plan.write_text(PLAN.replace("Europe/Berlin\"\n\n[[assignment]]", "Mars/Olympus\"\n\n[[assignment]]"))
    with pytest.raises(ValueError, match="timezone must be a time zone name"):
        read_plan(plan)
