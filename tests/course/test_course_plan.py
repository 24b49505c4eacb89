"""plan.toml is the one source of truth of a course, for cvkit and plain nbgrader alike, on a
tiny throwaway course graded through the real pipeline (``cvkit course grade``):

- its due dates are nbgrader's (the gradebook's ``Assignment.duedate``, as plain ``nbgrader``
  commands see them), its ``[late]`` policy gives nbgrader's late penalties;
- a chapter that is not in the plan is not graded, and says so;
- a changed due date, late policy or check offers a regrade, which ``--regrade CHAPTER`` does;
- grading without a salt is refused; cvkit's flags reach the formgrader's "Flagged?" column;
- the course folder keeps its permissions (only the salt is private), and git ignores what
  the course generates;
- the similarity report of the run names two students with the same answer, grades unchanged.
"""
import contextlib
import csv
import datetime as dt
import io
import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

from cvkit.cli import main
from cvkit.course import Course
from cvkit.course.plan import LatePolicy, parse_due, read_plan
from cvkit.course import nbgrader_plugins, trusted

from course_helpers import ROOT, SETUP, TEMPORAL_MEAN, exercise_cells, new_cell, new_notebook, submitted, write_project
from course_helpers import TEMPORAL_MEAN_LOOP as LOOP  # a right answer

ASSIGNMENT = "ch99_tiny"
GONE = "ch98_gone"  # has a source folder, but is not in the plan
DUE = dt.datetime(2030, 1, 1)
PLAN = f"""[[assignment]]
id = "{ASSIGNMENT}"
due = "2030-01-01 00:00:00 UTC"

[late]
policy = "per_hour"
points_per_hour = 0.5
"""
RENAMED = LOOP.replace("stack", "movie").replace("total", "running").replace("frame", "image")
FLAGGED = LOOP.replace("    return total", "    _ = globals()\n    return total")


def source_notebook():
    return new_notebook([new_cell("# A tiny chapter", cell_type="markdown"), new_cell(SETUP, "setup"),
                         *exercise_cells("filters.temporal_mean", "temporal_mean", TEMPORAL_MEAN)], ids=True)


def submission(answer):
    return {f"{ASSIGNMENT}.ipynb": submitted(source_notebook(), {"temporal_mean_answer": answer})}


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """A project with the real course configuration, a planned chapter and an unplanned one."""
    notebooks = {f"{chapter}/{ASSIGNMENT}.ipynb": source_notebook() for chapter in (ASSIGNMENT, GONE)}
    return write_project(tmp_path_factory.mktemp("project"), PLAN, notebooks)


def _run(*args):
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = main(list(args))
    return status, out.getvalue()


@pytest.fixture(scope="module")
def graded(project, tmp_path_factory):
    """ada (late by 2 h 30), bob (ada's answer, names changed) and cyd (flagged) on time, and
    ada's submission of the unplanned chapter; graded once by ``cvkit course grade``."""
    folder = tmp_path_factory.mktemp("shared") / "course"
    folder.mkdir(mode=0o750)
    folder.chmod(0o750)  # a folder shared with the teaching assistants' group
    course = Course(folder, project=project)
    course.build([ASSIGNMENT])
    on_time = DUE - dt.timedelta(hours=12)
    for student, answer, when in (("ada", LOOP, DUE + dt.timedelta(hours=2, minutes=30)),
                                  ("bob", RENAMED, on_time), ("cyd", FLAGGED, on_time)):
        # the time a submission was received is cvkit's record, never the student's timestamp.txt
        course.submit(student, ASSIGNMENT, submission(answer), received_at=when.replace(tzinfo=dt.timezone.utc))
    course.submit("ada", GONE, submission(LOOP))
    status, out = _run("course", "grade", "--course-dir", str(folder), "--workers", "2")
    return course, status, out


def _submission(course, student, assignment=ASSIGNMENT):
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gb:
        found = gb.find_submission(assignment, student)
        return {"score": found.score, "max": found.max_score, "penalty": found.late_submission_penalty,
                "grades": {g.name: g.score for nb in found.notebooks for g in nb.grades},
                "flagged": {nb.name: nb.flagged for nb in found.notebooks}}


# ------------------------------------------------------------------------------------ the plan
def test_plan_values_are_checked_naming_the_file_and_key(tmp_path):
    path = tmp_path / "plan.toml"
    bad = {
        '[[assignment]]\nid = "ch01"\ndue = "next monday"\n': "assignment 'ch01' due",
        '[[assignment]]\nid = "ch01"\ndue = "2027-03-01"\n': "a date alone is not enough",
        '[[assignment]]\nid = "ch01"\ndue = "2027-03-01 23:59:00 Mars/Olympus"\n': "unknown time zone",
        '[[assignment]]\nid = "ch01"\n[[assignment]]\nid = "ch01"\n': "listed twice",
        '[[assignment]]\nid = "../up"\n': "assignment #1 id",
        '[late]\npolicy = "half"\n': "[late] policy must be one of",
        '[late]\npolicy = "per_hour"\npoints_per_hour = -1\n': "points_per_hour must be a number > 0",
        '[late]\npolicy = "zero"\npoints = 1\n': "unknown key(s) points",
        '[[assignment]\n': "not valid TOML",
    }
    for text, message in bad.items():
        path.write_text(text)
        with pytest.raises(ValueError, match=r"plan\.toml") as error:
            read_plan(path)
        assert message in str(error.value), text


def test_due_dates_in_every_form_become_nbgraders_naive_utc():
    assert parse_due("2027-03-01 23:59:00 UTC") == dt.datetime(2027, 3, 1, 23, 59)
    assert parse_due("2027-03-01 23:59:00 Europe/Berlin") == dt.datetime(2027, 3, 1, 22, 59)
    assert parse_due("2027-07-01 23:59:00 Europe/Berlin") == dt.datetime(2027, 7, 1, 21, 59)
    assert parse_due("2027-03-01T23:59:00-05:00") == dt.datetime(2027, 3, 2, 4, 59)
    assert parse_due(dt.datetime(2027, 3, 1, 23, 59, tzinfo=dt.timezone.utc)) == dt.datetime(2027, 3, 1, 23, 59)
    assert parse_due("2027-03-01 23:59") == dt.datetime(2027, 3, 1, 23, 59)  # no zone: UTC, as in nbgrader
    assert parse_due(None) is None and parse_due("") is None


def test_the_projects_own_plan_is_valid():
    plan = read_plan(ROOT / "autograders" / "plan.toml")
    assert plan.ids() and all(plan.due(a) is not None for a in plan.ids())
    assert plan.late == LatePolicy("none", 1.0) or plan.late.policy in ("zero", "per_hour")


def test_late_policies():
    def penalty(seconds, score=6.0, **settings):
        return nbgrader_plugins.LatePenalty(**settings).late_submission_penalty("ada", score, seconds)

    assert penalty(3600 * 5) is None  # nbgrader's default: none
    assert penalty(1, policy="zero") == 6.0
    assert penalty(0, policy="zero") is None
    assert penalty(1, policy="per_hour", points_per_hour=0.5) == 0.5            # a started hour
    assert penalty(3600 * 2.5, policy="per_hour", points_per_hour=0.5) == 1.5
    assert penalty(3600 * 100, policy="per_hour", points_per_hour=0.5) == 6.0   # never more than the score


def test_due_dates_reach_nbgraders_gradebook_and_plain_nbgrader(graded):
    course, _, _ = graded
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gb:
        assert gb.find_assignment(ASSIGNMENT).duedate == DUE
        assert GONE not in {a.name for a in gb.assignments}
    listed = course.nbgrader("db", "assignment", "list")  # the real nbgrader command line
    assert listed.returncode == 0, listed.stderr
    assert f"{ASSIGNMENT} (due: 2030-01-01 00:00:00)" in listed.stdout


def test_a_late_submission_gets_the_plans_penalty(graded):
    course, status, out = graded
    assert status == 0, out
    ada, bob = _submission(course, "ada"), _submission(course, "bob")
    assert ada["max"] == 3 and sum(ada["grades"].values()) == pytest.approx(3)
    assert ada["penalty"] == pytest.approx(1.5)  # 2 h 30 late: three started hours × 0.5
    assert not bob["penalty"]
    rows = {row["student_id"]: row for row in csv.DictReader((course.root / "exports" / "grades.csv").open())}
    assert (rows["ada"]["raw_score"], rows["ada"]["late_submission_penalty"], rows["ada"]["score"]) == \
        ("3.0", "1.5", "1.5")
    assert (rows["bob"]["late_submission_penalty"], rows["bob"]["score"]) == ("0.0", "3.0")
    assert rows["ada"]["duedate"] == "2030-01-01 00:00:00"


def test_a_chapter_not_in_the_plan_is_listed_as_not_graded(graded):
    course, _, out = graded
    reason = f"chapter {GONE} is not in plan.toml"
    assert f"not graded: {reason}: 1 submission" in out
    assert course.not_graded()[f"ada/{GONE}"] == reason
    assert not (course.root / "autograded" / "ada" / GONE).exists()
    exercises = (course.root / "exports" / "exercises.csv").read_text()
    assert f"{GONE},ada,(submission),,,,not graded: {reason},not graded,not graded" in exercises
    assert f"ada: not graded: {reason}" in course.table(GONE)


def test_cvkit_flags_reach_the_formgrader(graded):
    course, _, _ = graded
    from nbgrader.api import Gradebook

    assert _submission(course, "cyd")["flagged"] == {ASSIGNMENT: True}
    assert _submission(course, "ada")["flagged"] == {ASSIGNMENT: False}
    with Gradebook(course.db_url) as gb:  # what the formgrader's submissions table shows
        shown = {row["student"]: row["flagged"] for row in gb.notebook_submission_dicts(ASSIGNMENT, ASSIGNMENT)}
    assert shown == {"ada": False, "bob": False, "cyd": True}


def test_similar_answers_are_reported_and_grades_unchanged(graded):
    course, _, out = graded
    with (course.root / "exports" / "similarity.csv").open(newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    groups: dict[str, set[tuple[str, str, str, str]]] = {}
    for row in rows:  # one row per student of a group of similar answers
        groups.setdefault(row["cluster"], set()).add((row["assignment"], row["exercise"], row["student"],
                                                      row["textbook"]))
    together = [found for found in groups.values() if (ASSIGNMENT, "temporal_mean_answer", "ada", "") in found]
    assert len(together) == 1 and (ASSIGNMENT, "temporal_mean_answer", "bob", "") in together[0]
    # the loop is not the vectorized solution or the reference: ada and bob's group is no textbook group
    assert not any(member[3] for member in together[0])
    assert "similar answers:" in out and "ada ↔ bob" in out and "never a score change" in out
    page = (course.root / "exports" / "similarity.html").read_text()
    assert "movie" in page and "stack" in page  # the two answers side by side
    assert _submission(course, "bob")["grades"] == _submission(course, "ada")["grades"]
    assert sum(_submission(course, "bob")["grades"].values()) == pytest.approx(3)


def test_only_the_salt_is_private(graded):
    course, _, _ = graded
    assert stat.S_IMODE(course.root.stat().st_mode) == 0o750
    assert stat.S_IMODE((course.root / ".grading_salt").stat().st_mode) == 0o600


def test_git_ignores_everything_the_course_generates(graded):
    course, _, _ = graded
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    kept = {"nbgrader_config.py"}  # written here because the course is outside autograders/
    generated = sorted(p for p in course.root.iterdir() if p.name not in kept)
    assert {p.name for p in generated} >= {"release", "submitted", "autograded", "feedback", "exports",
                                          "gradebook.db", ".grading_salt", ".cvkit"}
    not_ignored = []
    for path in generated:
        name = f"autograders/{path.name}" + ("/" if path.is_dir() else "")
        done = subprocess.run(["git", "check-ignore", "--no-index", "-q", name], cwd=ROOT)
        if done.returncode != 0:
            not_ignored.append(name)
    assert not not_ignored, f"add to .gitignore: {not_ignored}"


# ---------------------------------------------------------------------- trust and metadata
def test_trusted_checks_refuse_to_grade_without_a_salt():
    nb = nbformat.from_dict(source_notebook())
    with pytest.raises(nbgrader_plugins.MissingSalt, match=r"cvkit course grade.*\.grading_salt"):
        nbgrader_plugins.TrustedChecks(salt="").preprocess(nb, {"nbgrader": {"student": "ada"}})


def test_plain_nbgrader_autograde_without_a_salt_is_an_error(project, tmp_path):
    course = Course(tmp_path / "course", project=project)
    course.build([ASSIGNMENT])
    course.submit("ada", ASSIGNMENT, submission(LOOP))
    assert not (course.root / ".grading_salt").exists()
    done = course.nbgrader("autograde", ASSIGNMENT, "--student", "ada")
    assert done.returncode != 0
    assert "refuses to grade without a grading salt" in done.stdout + done.stderr
    assert not (course.root / ".grading_salt").exists()


def test_student_written_notebook_metadata_never_hides_the_unsandboxed_banner(monkeypatch):
    monkeypatch.setenv("CVKIT_NO_SANDBOX", "1")
    submitted = submission(LOOP)[f"{ASSIGNMENT}.ipynb"]
    submitted["metadata"]["cvkit"] = {"unsandboxed_note": True, "flags": [], "trusted": True, "sandboxed": True}
    nb = nbformat.from_dict(submitted)
    trusted.apply_trusted_checks(nb, student="ada", salt="plan-salt", source_notebook=source_notebook())
    assert nb.cells[0].cell_type == "markdown" and "Graded without the sandbox" in nb.cells[0].source
    assert nb.metadata["cvkit"]["sandboxed"] is False
    again = nbformat.from_dict(json.loads(nbformat.writes(nb)))  # graded twice: one banner
    trusted.apply_trusted_checks(again, student="ada", salt="plan-salt", source_notebook=source_notebook())
    assert sum("Graded without the sandbox" in c.source for c in again.cells) == 1


# ------------------------------------------------------------- changes that offer a regrade
def test_a_changed_check_offers_a_regrade(graded, project):
    course, _, _ = graded
    assert course.outdated() == {}
    path = project / "lectures" / ASSIGNMENT / f"{ASSIGNMENT}.ipynb"
    original = path.read_text()
    changed = json.loads(original)
    changed["cells"][3]["source"] += "  # the visible test, edited"
    try:
        path.write_text(json.dumps(changed))
        fresh = Course(course.root, project=project)
        assert fresh.outdated() == {(s, ASSIGNMENT): ["checks"] for s in ("ada", "bob", "cyd")}
    finally:
        path.write_text(original)


def test_a_changed_due_date_offers_a_regrade_and_regrade_applies_it(graded):
    course, _, _ = graded
    (course.root / "plan.toml").write_text(PLAN.replace("2030-01-01 00:00:00 UTC", "2030-01-01 01:00:00 UTC"))
    fresh = Course(course.root, project=course.project)
    assert fresh.outdated() == {(s, ASSIGNMENT): ["due date"] for s in ("ada", "bob", "cyd")}
    status, out = _run("course", "grade", "--course-dir", str(course.root))
    assert status == 0, out
    assert "cvkit course grade --regrade ch99_tiny" in out and "3 under an older due date" in out
    before = _submission(course, "bob")["grades"]
    status, out = _run("course", "grade", "--course-dir", str(course.root), "--regrade", ASSIGNMENT)
    assert status == 0, out
    assert "--regrade" not in out and Course(course.root, project=course.project).outdated() == {}
    ada = _submission(course, "ada")
    assert ada["penalty"] == pytest.approx(1.0)  # now 1 h 30 late: two started hours × 0.5
    assert _submission(course, "bob")["grades"] == before
    status, out = _run("course", "grade", "--course-dir", str(course.root), "--regrade", "ch00_nothing")
    assert status == 2
    (course.root / "plan.toml").write_text(PLAN.replace('"per_hour"', '"zero"'))
    changed = Course(course.root, project=course.project).outdated()
    assert changed == {(s, ASSIGNMENT): ["due date", "late policy"] for s in ("ada", "bob", "cyd")}


def test_a_new_gradebook_gets_nbgraders_schema_without_the_alembic_process(tmp_path, monkeypatch):
    """gradebook_of stamps a new database with nbgrader's schema version read in-process, so
    nbgrader does not start ``alembic heads`` (seconds of CPU for every new course); the result
    is the database nbgrader makes on its own: the same tables, the same version."""
    import nbgrader.api
    from sqlalchemy import create_engine, inspect, text

    from cvkit.course.plan import gradebook_of, nbgrader_schema_version, stamp_new_gradebook

    def contents(url):
        engine = create_engine(url)
        try:
            with engine.connect() as connection:
                version = connection.execute(text("SELECT version_num FROM alembic_version")).scalars().all()
            return sorted(inspect(engine).get_table_names()), version
        finally:
            engine.dispose()

    # nbgrader alone (the oracle): its Gradebook runs the alembic command of this environment
    plain = f"sqlite:///{tmp_path / 'plain.db'}"
    monkeypatch.setenv("PATH", str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", ""))
    nbgrader.api.Gradebook(plain).close()
    expected_tables, expected_version = contents(plain)
    assert expected_version == [nbgrader_schema_version()] and "assignment" in expected_tables

    def no_process():
        raise AssertionError("nbgrader started the alembic process")

    monkeypatch.setattr(nbgrader.api, "get_alembic_version", no_process)
    stamped = f"sqlite:///{tmp_path / 'stamped.db'}"
    with gradebook_of(stamped, "course101") as gradebook:
        gradebook.add_assignment("ch03_filtering")
    assert contents(stamped) == (expected_tables, expected_version)
    # an existing gradebook is left as it is, whatever its tables
    assert stamp_new_gradebook(stamped) is False and stamp_new_gradebook(plain) is False
    with gradebook_of(stamped, "course101") as gradebook:
        assert [a.name for a in gradebook.assignments] == ["ch03_filtering"]
