"""The LMS commands on a real graded course (the tiny chapter of test_course_scaling, with a written
question): `cvkit course export --canvas` / `--moodle` and `cvkit course push --lti` give what the
gradebook says a student earned, after the late penalty; written answers to mark, a submission
not graded and an assignment nobody handed in are blank (LTI: PendingManual or nothing), never 0;
an empty class gives a clear line."""
from __future__ import annotations

import copy
import csv
import datetime as dt
import json

import pytest

from cvkit.cli import main
from cvkit.course import Course
from lms_formats import parse_canvas, parse_moodle
from lti_platform import Platform, new_key
from course_helpers import new_cell, write_project
from test_course_scaling import _answers, source_notebook

pytestmark = pytest.mark.slow
TINY, SPARE = "ch99_tiny", "ch98_spare"
UTC = dt.timezone.utc
DUE = dt.datetime(2027, 1, 10, 12, 0, tzinfo=UTC)
WRITTEN = new_cell("Why does a mean filter blur?\n\nYOUR ANSWER HERE", "why_blur", solution=True, grade=True, points=2,
                   cell_type="markdown")


def notebook():
    nb = source_notebook()
    nb["cells"].append(copy.deepcopy(WRITTEN))
    return nb


def answers(written: str | None = None):
    nb = _answers()
    nb["cells"].append(copy.deepcopy(WRITTEN))
    if written is not None:
        nb["cells"][-1]["source"] = written
    return nb


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    plan = (f'[[assignment]]\nid = "{TINY}"\ntitle = "Tiny chapter"\ndue = "2027-01-10 12:00:00 UTC"\n\n'
            f'[[assignment]]\nid = "{SPARE}"\n\n[late]\npolicy = "per_hour"\npoints_per_hour = 1\n')
    project = write_project(tmp_path_factory.mktemp("project"), plan,
                            {f"{chapter}/{chapter}.ipynb": notebook() for chapter in (TINY, SPARE)})
    course = Course(tmp_path_factory.mktemp("course") / "course", project=project)
    (course.root / ".grading_salt").write_text("lms-salt")
    course.build([TINY, SPARE])
    released = json.loads(course.release_notebooks(TINY)[0].read_text())["cells"][-1]["source"]
    as_released = "".join(released) if isinstance(released, list) else released  # the written answer left blank
    course.submit("ada", TINY, {f"{TINY}.ipynb": answers(as_released)}, received_at=DUE - dt.timedelta(days=1))
    course.submit("bob", TINY, {f"{TINY}.ipynb": answers(as_released)}, received_at=DUE + dt.timedelta(hours=2, minutes=30))
    course.submit("cyd", TINY, {f"{TINY}.ipynb": answers("It averages neighbours, so edges spread.")},
                  received_at=DUE - dt.timedelta(hours=1))
    folder = course.submit("dan", TINY, {}, received_at=DUE - dt.timedelta(hours=1))
    (folder / f"{TINY}.ipynb").write_text("{ this is not a notebook")
    results = course.grade(workers=2)
    assert all(r.ok for r in results if not r.not_graded), [r.log[-800:] for r in results if not r.ok]
    return course


def gradebook(course):
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gb:
        return {s: (gb.find_submission(TINY, s).score, gb.find_submission(TINY, s).late_submission_penalty,
                    gb.find_submission(TINY, s).needs_manual_grade) for s in ("ada", "bob", "cyd")}


def test_canvas_export_of_a_graded_course(graded, capsys):
    book = gradebook(graded)
    assert book["bob"][1] == pytest.approx(3.0)  # 2 h 30 late: 3 started hours, 1 point each
    assert book["cyd"][2] and not book["ada"][2]  # cyd wrote an answer to mark; ada's is left blank
    assert main(["course", "export", "--canvas", "--course-dir", str(graded.root)]) == 0
    out = capsys.readouterr().out
    parsed = parse_canvas((graded.root / "exports" / "canvas_grades.csv").read_bytes())
    assert parsed["assignments"] == [(TINY, None), (SPARE, None)]
    assert parsed["points"] == {TINY: 8.0, SPARE: 8.0}
    rows = {r["SIS Login ID"]: r for r in parsed["students"]}
    assert set(rows) == {"ada", "bob", "cyd", "dan"}
    assert float(rows["ada"][TINY]) == pytest.approx(book["ada"][0]) and book["ada"][0] == pytest.approx(6.0)
    # what bob earned: the checks' points less the late penalty
    assert float(rows["bob"][TINY]) == pytest.approx(book["bob"][0] - 3.0) and book["bob"][0] == pytest.approx(6.0)
    assert rows["cyd"][TINY] == "" and rows["dan"][TINY] == ""  # blank, never 0
    assert all(rows[s][SPARE] == "" for s in rows)
    with (graded.root / "exports" / "canvas_blank_reasons.csv").open(encoding="utf-8") as handle:
        why = {(r["student"], r["assignment"]): r["reason"] for r in csv.DictReader(handle)}
    assert why[("cyd", TINY)].startswith("written answers")
    assert why[("dan", TINY)].startswith("not graded: ")
    assert why[("ada", SPARE)] == "no submission"
    assert f"{SPARE}: nobody has submitted it" in out and "canvas_blank_reasons.csv" in out


def test_moodle_export_of_a_graded_course(graded, capsys):
    assert main(["course", "export", "--moodle", "username", "--course-dir", str(graded.root),
                 "--assignment", TINY]) == 0
    parsed = parse_moodle((graded.root / "exports" / "moodle_grades.csv").read_bytes(), "username")
    assert parsed["items"] == [TINY]
    assert parsed["grades"]["ada"][TINY] == pytest.approx(6.0) and parsed["grades"]["bob"][TINY] == pytest.approx(3.0)
    assert parsed["grades"]["cyd"][TINY] is None and parsed["grades"]["dan"][TINY] is None
    assert main(["course", "export", "--moodle", "email", "--course-dir", str(graded.root)]) == 0
    out = capsys.readouterr().out
    assert "ada: no email in the gradebook's e-mail addresses: left out" in out  # never a made-up address
    assert main(["course", "export", "--moodle", "username", "--roster-column", "X", "--course-dir",
                 str(graded.root)]) == 2
    assert "--roster-column goes with --canvas" in capsys.readouterr().err


def test_push_a_graded_course(graded, tmp_path, monkeypatch, capsys):
    for name in ("http_proxy", "HTTP_PROXY", "all_proxy", "ALL_PROXY"):
        monkeypatch.delenv(name, raising=False)
    pem, public = new_key()
    (tmp_path / "tool.pem").write_bytes(pem)
    (tmp_path / "roster.csv").write_text("student_id,lti_user_id\nada,1\nbob,2\ncyd,3\ndan,4\n")
    with Platform("tool", public) as platform:
        (tmp_path / "lti.toml").write_text(
            f'client_id = "tool"\ntoken_url = "{platform.token_url}"\nlineitems_url = "{platform.lineitems_url}"\n'
            'private_key = "tool.pem"\nroster = "roster.csv"\n')
        argv = ["course", "push", "--lti", str(tmp_path / "lti.toml"), "--course-dir", str(graded.root)]
        assert main(argv) == 0
        out = capsys.readouterr().out
        items = {i["resourceId"]: i["id"] for i in platform.line_items}
        scores = {s["userId"]: s for i, s in platform.scores if i == items[TINY]}
        assert set(scores) == {"1", "2", "3"} and scores["1"]["scoreGiven"] == pytest.approx(6.0)
        assert scores["2"]["scoreGiven"] == pytest.approx(3.0) and scores["3"]["gradingProgress"] == "PendingManual"
        assert "ch99_tiny: skipped: nothing posted: not graded: " in out and out.count("ch99_tiny: skipped") == 1
        assert "ch98_spare: skipped: nothing posted: no submission: ada, bob, cyd, dan" in out
        assert "ch99_tiny: pending: PendingManual: cyd" in out
        assert main(argv) == 0 and len(platform.line_items) == 2  # the second push makes no line item
        assert f"line items updated: {TINY}, {SPARE}" in capsys.readouterr().out


def test_an_empty_class(graded, tmp_path, capsys):
    empty = Course(tmp_path / "empty", project=graded.project)
    assert main(["course", "export", "--canvas", "--course-dir", str(empty.root)]) == 0
    out = capsys.readouterr().out
    assert "the course has no students" in out and "not built" in out
    parsed = parse_canvas((empty.root / "exports" / "canvas_grades.csv").read_bytes())
    assert parsed["students"] == [] and parsed["points"] == {TINY: None, SPARE: None}
    assert main(["course", "export", "--canvas", "--assignment", "ch00_nope", "--course-dir", str(empty.root)]) == 2
    assert "--assignment: ch00_nope not in plan.toml" in capsys.readouterr().err


def test_a_hand_in_changed_since_grading_is_blank(graded, capsys):
    from cvkit.course.lms import HANDED_IN_AGAIN

    path = graded.root / "submitted" / "ada" / TINY / f"{TINY}.ipynb"
    before = path.read_bytes()
    try:
        path.write_text(json.dumps(answers("A new answer, handed in after the grading.")))
        assert main(["course", "export", "--canvas", "--course-dir", str(graded.root)]) == 0
        rows = {r["SIS Login ID"]: r for r in
                parse_canvas((graded.root / "exports" / "canvas_grades.csv").read_bytes())["students"]}
        assert rows["ada"][TINY] == "" and float(rows["bob"][TINY]) == pytest.approx(3.0)  # the old grade is not sent
        with (graded.root / "exports" / "canvas_blank_reasons.csv").open(encoding="utf-8") as handle:
            assert {"student": "ada", "assignment": TINY, "reason": HANDED_IN_AGAIN} in list(csv.DictReader(handle))
    finally:
        path.write_bytes(before)
    capsys.readouterr()
