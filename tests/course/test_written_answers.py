"""Written questions and open tasks through the real pipeline, on a tiny throwaway chapter:
the release keeps neither the model answer nor the mark scheme; grading records them as waiting
for the instructor (never as a zero the student earned); the table marks them ✎ and both CSV
exports say "to mark"; the student's answer reaches the feedback page cleaned of anything that
could run, and the page shows no mark scheme."""
import csv
import json

import pytest

import test_course_scaling as tiny
from course_helpers import write_project
from cvkit.course import Course

pytestmark = pytest.mark.slow

QUESTION = {"cell_type": "markdown", "source": "**Question 99.1** (2 points) — Why does the mean kernel sum to one?",
            "metadata": {}}
ANSWER = {"cell_type": "markdown",
          "source": "**Model answer.** So that a flat image keeps its level.\n\n**Rubric (2 points).** 2 for 'keeps the level'.",
          "metadata": {"nbgrader": {"grade": True, "solution": True, "locked": False, "points": 2,
                                    "grade_id": "question_99_1", "schema_version": 3}}}
TASK = {"cell_type": "markdown",
        "source": "**Open task 99** (3 points) — Measure the noise left by the mean filter.\n\n"
                  "<!-- BEGIN MARK SCHEME -->\n**Mark scheme.** 3 for a measurement and a reason.\n<!-- END MARK SCHEME -->",
        "metadata": {"nbgrader": {"task": True, "grade": False, "solution": False, "locked": True, "points": 3,
                                  "grade_id": "task_99", "schema_version": 3}}}


def _source_notebook():
    nb = tiny.source_notebook()
    nb["cells"][4:4] = [QUESTION, ANSWER]
    nb["cells"].append(TASK)
    return nb


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    project = write_project(tmp_path_factory.mktemp("project"), f'[[assignment]]\nid = "{tiny.ASSIGNMENT}"\n',
                            {f"{tiny.ASSIGNMENT}/{tiny.ASSIGNMENT}.ipynb": _source_notebook()})
    course = Course(project / "course", project=project)
    (course.root / ".grading_salt").write_text("written-salt")
    course.build([tiny.ASSIGNMENT])
    release = json.loads(course.release_notebooks(tiny.ASSIGNMENT)[0].read_text())
    answered = json.loads(json.dumps(release))
    for cell in answered["cells"]:
        if cell["metadata"].get("nbgrader", {}).get("grade_id") == "question_99_1":
            cell["source"] = "It keeps the **level** <script>alert('x')</script><img src=x onerror=alert(1)>."
    answered["cells"].append({"cell_type": "code", "source": "print('my measurement', 0.25)", "metadata": {},
                              "outputs": [], "execution_count": None})
    course.submit("ada", tiny.ASSIGNMENT, {f"{tiny.ASSIGNMENT}.ipynb": answered})
    course.submit("bob", tiny.ASSIGNMENT, {f"{tiny.ASSIGNMENT}.ipynb": release})
    results = course.grade([tiny.ASSIGNMENT], workers=1)
    assert all(r.ok for r in results), [r.log for r in results]
    return course, release


def test_release_has_no_model_answer_or_mark_scheme(graded):
    _, release = graded
    text = json.dumps(release)
    assert "Model answer" not in text and "Rubric" not in text and "MARK SCHEME" not in text and "Mark scheme" not in text
    assert "YOUR ANSWER HERE" in text and "Open task 99" in text


def test_written_answers_wait_for_the_instructor(graded):
    from nbgrader.api import Gradebook

    course, _ = graded
    with Gradebook(course.db_url) as gb:
        grades = {g.name: g for nb in gb.find_submission(tiny.ASSIGNMENT, "ada").notebooks for g in nb.grades}
        assert grades["question_99_1"].needs_manual_grade and grades["question_99_1"].max_score == 2
        assert grades["task_99"].needs_manual_grade and grades["task_99"].max_score == 3
        assert not grades["mean_kernel_visible"].needs_manual_grade
        # an answer left as released ("YOUR ANSWER HERE") is a zero, as nbgrader decides
        untouched = {g.name: g for nb in gb.find_submission(tiny.ASSIGNMENT, "bob").notebooks for g in nb.grades}
        assert not untouched["question_99_1"].needs_manual_grade and untouched["question_99_1"].score == 0
    scores = {e.name: e for e in course.scores(tiny.ASSIGNMENT)["ada"]}
    assert scores["question_99_1"].to_mark and scores["task_99"].to_mark and not scores["mean_kernel"].to_mark
    assert not {e.name: e for e in course.scores(tiny.ASSIGNMENT)["bob"]}["question_99_1"].to_mark
    table = course.table(tiny.ASSIGNMENT)
    assert "to mark/2 ✎" in table and "to mark/3 ✎" in table and "+5✎" in table
    rows = list(csv.DictReader((course.root / "exports" / "exercises.csv").open()))
    question = next(r for r in rows if r["student"] == "ada" and r["exercise"] == "question_99_1")
    assert question["score"] == "" and question["status"].startswith("to mark")
    assert next(r for r in rows if r["student"] == "ada" and r["exercise"] == "mean_kernel")["status"] == "graded"


def test_answer_reaches_the_feedback_cleaned_and_without_mark_scheme(graded):
    course, _ = graded
    page = next((course.root / "feedback" / "ada" / tiny.ASSIGNMENT).glob("*.html")).read_text()
    assert "<strong>level</strong>" in page, "the student's answer is shown, rendered"
    assert "my measurement" in page, "the cells the student added for the open task are shown"
    assert "onerror" not in page and "<script>alert" not in page
    assert "Mark scheme" not in page and "3 for a measurement" not in page
    assert "Open task 99" in page


def test_the_page_says_what_waits_for_the_instructor_never_a_zero(graded):
    """ada's written answer (2 points) and open task (3 points) wait for a hand mark: her page says
    so where nbgrader's template printed "Score: 0.0 / 2.0"; bob left the answer as released, a
    zero nbgrader decided, and his page shows that score."""
    import re

    course, _ = graded
    page = next((course.root / "feedback" / "ada" / tiny.ASSIGNMENT).glob("*.html")).read_text()
    text = " ".join(re.sub(r"<[^>]+>", " ", page).split())
    assert "Waiting for your instructor (2 points)" in text and "Waiting for your instructor (3 points)" in text
    assert "(waiting for your instructor: 2 points)" in text and "(waiting for your instructor: 3 points)" in text
    assert re.search(r"\(Score: [0-9.]+ / [0-9.]+\) — 5 points still waiting for your instructor", text)
    assert "Written response (Score" not in text and "Task (Score" not in text
    assert not re.search(r"Student's answer Score: 0\.0 / 2\.0|Student's task Score: 0\.0 / 3\.0", text)
    bob = " ".join(re.sub(r"<[^>]+>", " ", next((course.root / "feedback" / "bob" / tiny.ASSIGNMENT)
                                                .glob("*.html")).read_text()).split())
    assert "Written response (Score: 0.0 / 2.0)" in bob and "Student's answer Score: 0.0 / 2.0" in bob
