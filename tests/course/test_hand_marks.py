"""Hand marks are one truth and are never undone (issue 34, item 3).

A tiny chapter with a written question and an open task, graded for real; the instructor marks
them as nbgrader's formgrader does (its ``PUT /formgrader/api/grade/<id>`` and
``/comment/<id>`` set ``manual_score``, ``needs_manual_grade`` and ``manual_comment`` in the
gradebook). Then:

- ``cvkit course grade`` (nothing new to grade) writes the student's page again with the marks,
  and the table and both CSV exports agree with it;
- a regrade of everything (as after a changed due date, late policy or check) keeps every mark,
  comment and ``needs_manual_grade = False`` exactly — on SQLite and on PostgreSQL;
- an answer changed after it was marked (a new hand-in) goes back to "to mark", with a note
  for the instructor; the unchanged one keeps its mark;
- every mark seen is in the course's ``.cvkit/marks.log``;
- ``cvkit course refresh`` writes the pages whose marks changed and the exports, grading nothing.
"""
from __future__ import annotations

import contextlib
import csv
import io
import json

import pytest
import test_written_answers as written
from test_course_scaling import postgres  # noqa: F401  (a PostgreSQL server of our own, a fixture)

import test_course_scaling as tiny
from course_helpers import write_project
from cvkit.cli import main
from cvkit.course import Course

pytestmark = pytest.mark.slow

COMMENT = "Right: a flat image keeps its level. Say what happens at the border."
TASK_COMMENT = "A clear measurement."


def _course(project_root, folder, db_url=None) -> Course:
    course = Course(folder, db_url=db_url, project=project_root)
    (course.root / ".grading_salt").write_text("marks-salt")
    course.build([tiny.ASSIGNMENT])
    return course


def _answered(release: dict, answer: str) -> dict:
    notebook = json.loads(json.dumps(release))
    for cell in notebook["cells"]:
        if cell["metadata"].get("nbgrader", {}).get("grade_id") == "question_99_1":
            cell["source"] = answer
    notebook["cells"].append({"cell_type": "code", "source": "print('my measurement', 0.25)", "metadata": {},
                              "outputs": [], "execution_count": None})
    return notebook


def _mark(course: Course, student: str, grade_id: str, score: float, comment: str) -> None:
    """What the formgrader's grade and comment handlers do."""
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gradebook:
        grade = gradebook.find_grade(grade_id, tiny.ASSIGNMENT, tiny.ASSIGNMENT, student)
        grade.manual_score = score
        grade.needs_manual_grade = False
        gradebook.find_comment(grade_id, tiny.ASSIGNMENT, tiny.ASSIGNMENT, student).manual_comment = comment
        gradebook.db.commit()


def _state(course: Course, student: str) -> dict:
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gradebook:
        out = {}
        for grade_id in ("question_99_1", "task_99"):
            grade = gradebook.find_grade(grade_id, tiny.ASSIGNMENT, tiny.ASSIGNMENT, student)
            comment = gradebook.find_comment(grade_id, tiny.ASSIGNMENT, tiny.ASSIGNMENT, student)
            out[grade_id] = (grade.manual_score, grade.needs_manual_grade, comment.manual_comment)
        return out


def _read(path) -> str:
    return path.read_text() if path.exists() else ""


def _page(course: Course, student: str) -> str:
    return next((course.root / "feedback" / student / tiny.ASSIGNMENT).glob("*.html")).read_text()


def _exercises(course: Course, student: str) -> dict:
    rows = csv.DictReader((course.root / "exports" / "exercises.csv").open())
    return {r["exercise"]: (r["score"], r["status"]) for r in rows if r["student"] == student}


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    return write_project(tmp_path_factory.mktemp("project"), f'[[assignment]]\nid = "{tiny.ASSIGNMENT}"\n',
                         {f"{tiny.ASSIGNMENT}/{tiny.ASSIGNMENT}.ipynb": written._source_notebook()})


def _semester(course: Course) -> dict:
    """Grade, mark, grade (refresh), regrade, a changed hand-in: what each step left."""
    release = json.loads(course.release_notebooks(tiny.ASSIGNMENT)[0].read_text())
    course.submit("ada", tiny.ASSIGNMENT, {f"{tiny.ASSIGNMENT}.ipynb": _answered(release, "It keeps the level.")})
    course.submit("cyd", tiny.ASSIGNMENT, {f"{tiny.ASSIGNMENT}.ipynb": _answered(release, "The mean stays.")})
    assert all(r.ok for r in course.grade([tiny.ASSIGNMENT], workers=1))
    seen = {"unmarked table": course.table(tiny.ASSIGNMENT)}
    for student in ("ada", "cyd"):
        _mark(course, student, "question_99_1", 1.5, COMMENT)
        _mark(course, student, "task_99", 2.0, TASK_COMMENT)
    marked = _state(course, "ada")
    course.grade([tiny.ASSIGNMENT], workers=1)  # nothing new to grade: pages, table and exports follow the marks
    seen.update({"marked": marked, "page": _page(course, "ada"), "table": course.table(tiny.ASSIGNMENT),
                 "exercises": _exercises(course, "ada")})
    course.grade([tiny.ASSIGNMENT], workers=1, regrade=True)  # as after a changed due date or check
    seen.update({"regraded": _state(course, "ada"), "regraded page": _page(course, "ada"),
                 "regraded table": course.table(tiny.ASSIGNMENT), "regraded exercises": _exercises(course, "ada")})
    # cyd hands in again with another written answer
    course.submit("cyd", tiny.ASSIGNMENT, {f"{tiny.ASSIGNMENT}.ipynb": _answered(release, "Averaging keeps it.")})
    course.grade([tiny.ASSIGNMENT], workers=1)
    seen.update({"changed": _state(course, "cyd"), "kept": _state(course, "ada"),
                 "changed table": course.table(tiny.ASSIGNMENT), "changed exercises": _exercises(course, "cyd"),
                 "log": _read(course.root / ".cvkit" / "marks.log")})
    # a second look at ada's answer, then the pages and exports without grading anything
    _mark(course, "ada", "question_99_1", 2.0, "On reflection: complete.")
    before = {p: p.stat().st_mtime_ns for p in (course.root / "autograded").rglob("*.ipynb")}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["course", "refresh", "--course-dir", str(course.root)]
                    + (["--db-url", course.db_url] if not course.db_url.startswith("sqlite") else []))
    seen.update({"refresh": (code, out.getvalue()), "refreshed page": _page(course, "ada"),
                 "refreshed exercises": _exercises(course, "ada"),
                 "untouched": before == {p: p.stat().st_mtime_ns for p in (course.root / "autograded").rglob("*.ipynb")}})
    return seen


def _assert_semester(seen: dict) -> None:
    assert "to mark/2 ✎" in seen["unmarked table"]
    expected = {"question_99_1": (1.5, False, COMMENT), "task_99": (2.0, False, TASK_COMMENT)}
    assert seen["marked"] == expected
    # refreshed without a regrade: the page shows the marks, the table and exercises.csv agree
    assert COMMENT in seen["page"] and TASK_COMMENT in seen["page"] and "waiting for your instructor" not in seen["page"]
    assert "ada" in seen["table"] and "to mark" not in seen["table"].split("ada", 1)[1].split("\n", 1)[0]
    assert seen["exercises"]["question_99_1"] == ("1.5", "graded")
    assert seen["exercises"]["task_99"] == ("2", "graded")
    # a regrade of everything keeps every mark and comment exactly
    assert seen["regraded"] == expected
    assert COMMENT in seen["regraded page"] and seen["regraded exercises"] == seen["exercises"]
    assert "to mark" not in seen["regraded table"]
    # cyd's new hand-in changed what was marked: to mark again (the old mark kept as a suggestion), said;
    # ada's marks are untouched
    assert seen["kept"] == expected
    assert seen["changed"]["question_99_1"] == (1.5, True, COMMENT)
    assert seen["changed"]["task_99"][1] is True
    assert seen["changed exercises"]["question_99_1"][1].startswith("to mark")
    assert "question_99_1: the answer changed since it was marked (1.5): to mark again" in seen["changed table"]
    # cvkit course refresh: ada's page alone is written again, nothing is graded
    assert seen["refresh"][0] == 0 and f"wrote 1 feedback page with new marks (ada/{tiny.ASSIGNMENT})" in seen["refresh"][1]
    assert "On reflection: complete." in seen["refreshed page"] and seen["untouched"]
    assert seen["refreshed exercises"]["question_99_1"] == ("2", "graded")
    log = [line.split("\t") for line in seen["log"].splitlines()]
    assert [(row[2], row[3].split(":")[1], row[4]) for row in log if row[2] == f"ada/{tiny.ASSIGNMENT}"] == [
        (f"ada/{tiny.ASSIGNMENT}", "question_99_1", "1.5, comment written"),
        (f"ada/{tiny.ASSIGNMENT}", "task_99", "2, comment written")]


def test_marks_survive_refresh_and_regrade_on_sqlite(project, tmp_path):
    _assert_semester(_semester(_course(project, tmp_path / "course")))


def test_marks_survive_refresh_and_regrade_on_postgresql(project, postgres, tmp_path):  # noqa: F811
    course = _course(project, tmp_path / "course", db_url=postgres)
    _assert_semester(_semester(course))
    assert not (course.root / "gradebook.db").exists()
