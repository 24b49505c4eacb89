"""The course pipeline end to end, through the command line: `cvkit demo` builds the course,
makes the three sample submissions, autogrades them with nbgrader in parallel, writes
feedback and grades. Then every recorded grade is compared with what it must be.

The full pipeline runs on a representative subset of chapters (``DEMO_CHAPTERS``) to keep CI
well inside its time budget; every chapter's "typical mistakes" sample is graded in-process by
the same engine (``test_every_chapters_mistakes_sample``), and every chapter's solutions pass
all their tests in ``tests/lectures/test_notebooks.py``."""
import contextlib
import csv
import io
import json
import re
from pathlib import Path

import pytest

from cvkit.cli import main
from cvkit.course import SAMPLE_STUDENTS, Course, typical_mistakes

from course_helpers import predict_scores

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]


DEMO_CHAPTERS = ["ch01_introduction", "ch03_filtering"]
CHAPTERS = sorted(p.name for p in (ROOT / "lectures").glob("ch*_*") if p.is_dir())
OUTPUT: dict = {}  # what the demo printed (stdout, stderr)


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    folder = tmp_path_factory.mktemp("course") / "demo"
    chosen = [c for c in DEMO_CHAPTERS if c in CHAPTERS]
    args = ["demo", "--dir", str(folder), "--workers", "2"]
    for chapter in chosen:
        args += ["--assignment", chapter]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(args)
    course = Course(folder)
    OUTPUT.update(out=out.getvalue(), err=err.getvalue())
    return status, course


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_every_chapters_mistakes_sample(chapter):
    """The typical-mistakes sample of each chapter: every replaced exercise fails its visible
    test, the total lies strictly between 0 and full marks (graded by the engine, in-process)."""
    from cvkit.course import solution_sources

    mistakes = typical_mistakes(ROOT / "autograders" / "samples" / chapter)
    answers = [c for p in (ROOT / "lectures" / chapter).glob("*.ipynb") for c in json.loads(p.read_text())["cells"]
               if c["cell_type"] == "code" and c.get("metadata", {}).get("nbgrader", {}).get("solution")]
    if not answers:
        assert not mistakes, f"{chapter} has typical mistakes but no exercise"
        pytest.skip(f"{chapter} has written questions only")
    assert mistakes, f"{chapter} has no typical-mistakes sample"
    for path in sorted((ROOT / "lectures" / chapter).glob("*.ipynb")):
        source = json.loads(path.read_text())
        solutions = solution_sources(source)
        nb = json.loads(path.read_text())
        for cell in nb["cells"]:
            grade_id = cell.get("metadata", {}).get("nbgrader", {}).get("grade_id")
            if cell.get("metadata", {}).get("nbgrader", {}).get("solution"):
                cell["source"] = mistakes.get(grade_id, solutions.get(grade_id, cell["source"]))
        scores = predict_scores(nb, "sample_mistakes", "ci-salt", source=source)
        points = {c["metadata"]["nbgrader"]["grade_id"]: float(c["metadata"]["nbgrader"]["points"])
                  for c in source["cells"] if c.get("metadata", {}).get("nbgrader", {}).get("grade")}
        for grade_id in mistakes:
            visible = grade_id.replace("_answer", "_visible")
            if visible in scores:
                assert scores[visible] == 0, f"{chapter}: {grade_id} should fail its visible test"
        assert 0 < sum(scores.values()) < sum(points.values())


def test_demo_succeeds(demo, capsys):
    status, course = demo
    assert status == 0
    assert course.audit(course.submissions()) == []
    chosen = [c for c in DEMO_CHAPTERS if c in CHAPTERS]
    assert sorted(s for s, _ in course.submissions()) == sorted(SAMPLE_STUDENTS * len(chosen))


def test_every_phase_says_how_far_it_got_and_nothing_looks_like_an_error(demo):
    """Where nobody watches a terminal, each phase prints one line with its count and time."""
    status, course = demo
    out, err = OUTPUT["out"], OUTPUT["err"]
    chosen = len([c for c in DEMO_CHAPTERS if c in CHAPTERS])
    subs = 3 * chosen
    for phase in (f"build: {chosen}/{chosen} chapters", f"samples: {chosen}/{chosen} chapters",
                  f"grade: {subs}/{subs} submissions", f"record: {subs}/{subs} submissions",
                  f"feedback: {subs}/{subs} pages", f"exports: {chosen + 1}/{chosen + 1} files",
                  f"similarity: {chosen}/{chosen} assignments"):
        assert re.search(rf"^{re.escape(phase)} in \d+ s$", out, re.MULTILINE), phase
    assert "similar answers:" in out and "never a score change" in out
    assert (course.root / "exports" / "similarity.csv").is_file()
    assert (course.root / "exports" / "similarity.html").is_file()
    assert err == ""


def test_release_has_stubs_and_no_solutions_or_hidden_tests(demo):
    _, course = demo
    for assignment in sorted({a for _, a in course.submissions()}):
        notebooks = course.release_notebooks(assignment)
        assert notebooks
        for path in notebooks:
            text = path.read_text()
            assert "BEGIN SOLUTION" not in text and "BEGIN HIDDEN TESTS" not in text
            assert "Model answer." not in text and "MARK SCHEME" not in text
            source = json.loads((ROOT / "lectures" / assignment / path.name).read_text())
            kinds = {c["cell_type"] for c in source["cells"] if c.get("metadata", {}).get("nbgrader", {}).get("solution")}
            if "code" in kinds:
                assert "raise NotImplementedError()" in text
            if "markdown" in kinds:
                assert "YOUR ANSWER HERE" in text


MANUAL = ("question_", "task_")  # written questions and open tasks: marked by hand in the formgrader


def _cell_grades(course, assignment, student, manual=False):
    """{grade cell: (score, max)} of the autograded cells (``manual``: of the cells marked by hand)."""
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gb:
        submission = gb.find_submission(assignment, student)
        return {g.name: (g.score, g.max_score) for nb in submission.notebooks for g in nb.grades
                if g.name.startswith(MANUAL) == manual}


def test_written_answers_wait_for_the_instructor(demo):
    """Questions and open tasks are recorded as needing a manual grade (never as a zero the
    student earned; an answer left as released is a zero), the table marks them ✎, and no
    feedback page shows a rubric or a mark scheme."""
    from nbgrader.api import Gradebook

    _, course = demo
    for student, assignment in course.submissions():
        with Gradebook(course.db_url) as gb:
            submission = gb.find_submission(assignment, student)
            manual = [g for nb in submission.notebooks for g in nb.grades if g.name.startswith(MANUAL)]
            assert all(g.max_score > 0 for g in manual)
            if student == "sample_blank":  # answers left as released: zero, nothing to mark
                assert all(g.score == 0 for g in manual if g.name.startswith("question_")), [g.name for g in manual]
            else:
                assert all(g.needs_manual_grade for g in manual), [g.name for g in manual if not g.needs_manual_grade]
        for page in (course.root / "feedback" / student / assignment).glob("*.html"):
            text = page.read_text()
            assert "Mark scheme" not in text and "MARK SCHEME" not in text and "Rubric (" not in text, page
    if any(course.scores(a) and any(e.to_mark for es in course.scores(a).values() for e in es)
           for a in {a for _, a in course.submissions()}):
        assert "✎" in course.table(next(a for _, a in course.submissions()))


def test_complete_sample_gets_full_marks(demo):
    _, course = demo
    for assignment in sorted({a for _, a in course.submissions()}):
        grades = _cell_grades(course, assignment, "sample_complete")
        assert grades or _cell_grades(course, assignment, "sample_complete", manual=True), assignment
        for name, (score, top) in grades.items():
            assert score == pytest.approx(top), name


def test_blank_release_scores_zero_everywhere(demo):
    _, course = demo
    for assignment in sorted({a for _, a in course.submissions()}):
        grades = {**_cell_grades(course, assignment, "sample_blank"),
                  **_cell_grades(course, assignment, "sample_blank", manual=True)}
        assert grades and all(score == 0 for score, _ in grades.values()), grades


def test_mistakes_sample_scores_exactly_as_the_engine_predicts(demo):
    _, course = demo
    for assignment in sorted({a for _, a in course.submissions()}):
        path = next((course.root / "submitted" / "sample_mistakes" / assignment).glob("*.ipynb"))
        source = json.loads((ROOT / "lectures" / assignment / path.name).read_text())
        predicted = predict_scores(json.loads(path.read_text()), "sample_mistakes", course.salt(), source=source)
        grades = _cell_grades(course, assignment, "sample_mistakes")
        assert set(predicted) == set(grades)
        if not grades:  # a chapter of written questions only (Chapter 1)
            assert not typical_mistakes(ROOT / "autograders" / "samples" / assignment)
            continue
        graded = json.loads((course.root / "autograded" / "sample_mistakes" / assignment / path.name).read_text())
        cascaded = {c["metadata"].get("nbgrader", {}).get("grade_id") for c in graded["cells"]
                    if any("costs points once" in json.dumps(o) for o in c.get("outputs", []))}
        for name, (score, top) in grades.items():
            if name in cascaded:  # graded with the reference building block: one mistake costs points once
                assert score >= predicted[name] - 1e-6, name
            else:
                assert score == pytest.approx(predicted[name], abs=1e-6), name
        # every exercise replaced by a typical mistake loses its visible test
        for grade_id in typical_mistakes(ROOT / "autograders" / "samples" / assignment):
            name = grade_id.replace("_answer", "_visible")
            assert grades[name][0] == 0, f"{name} should fail with the typical mistake"
        total = sum(s for s, _ in grades.values())
        assert 0 < total < sum(t for _, t in grades.values())


def test_table_names_the_mistakes(demo):
    _, course = demo
    for assignment in sorted({a for _, a in course.submissions()}):
        scores = course.scores(assignment)
        if not _cell_grades(course, assignment, "sample_mistakes"):
            continue  # written questions only: nothing for the checks to recognise
        found = {m for e in scores["sample_mistakes"] for m in e.mistakes}
        assert found, "the typical mistakes should be recognised by name"
        assert not any(e.mistakes for e in scores["sample_complete"])


def test_feedback_and_csv_export(demo):
    _, course = demo
    for assignment in sorted({a for _, a in course.submissions()}):
        for student in SAMPLE_STUDENTS:
            assert list((course.root / "feedback" / student / assignment).glob("*.html")), student
    rows = list(csv.DictReader((course.root / "exports" / "grades.csv").open()))
    assert {r["student_id"] for r in rows} == set(SAMPLE_STUDENTS)


def test_cli_table_and_regrade_is_reproducible(demo, capsys):
    _, course = demo
    assignment = sorted({a for _, a in course.submissions()})[0]
    before = _cell_grades(course, assignment, "sample_mistakes")
    result = course.autograde_one("sample_mistakes", assignment)
    assert result.ok, result.log
    assert _cell_grades(course, assignment, "sample_mistakes") == before
    assert main(["course", "table", "--course-dir", str(course.root)]) == 0
    out = capsys.readouterr().out
    assert "sample_mistakes" in out and "total" in out


def test_scores_are_read_once_within_scores_read_once_and_each_reader_gets_its_own_copy(demo, monkeypatch):
    from cvkit.course import results

    _, course = demo
    assignment = sorted({a for _, a in course.submissions()})[0]
    reads = []
    real = results._scores
    monkeypatch.setattr(results, "_scores", lambda *a: reads.append(1) or real(*a))
    with course.scores_read_once():
        first = course.scores(assignment)
        second = course.scores(assignment)
        assert reads == [1] and first == second and first  # one read of the gradebook
        student = next(iter(first))
        first[student][0].mistakes.append("changed by one reader")
        assert "changed by one reader" not in course.scores(assignment)[student][0].mistakes
    course.scores(assignment)
    assert reads == [1, 1]  # outside the block every call reads the gradebook as it is now
