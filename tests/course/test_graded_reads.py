"""After a run, the exports, the item analysis, the class notes and the leaderboard read the graded
course: each autograded notebook is parsed once for all of them, and each assignment's grades
come from the gradebook in two queries, however large the class (nbgrader's objects would load
each grade's cell and maximum one query at a time)."""
import json
import os

import pytest
from sqlalchemy import event

from cvkit.course import notebook as notebook_model
from cvkit.course.notebook import cell_outputs, graded_read_once, read_graded
from cvkit.course.results import _recorded_grades, notebook_flags, reported_findings
from cvkit.grading.report import MIME_TYPE

REPORT = {"algorithm": "filters.mean_kernel", "mistake": "all ones", "cases": [{"label": "3x3", "passed": False}]}


def _graded_notebook(flags=("mean_kernel_hidden: printed the hidden inputs",)):
    test_cell = {
        "cell_type": "code", "source": "check(...)", "execution_count": 1,
        "metadata": {"nbgrader": {"grade_id": "mean_kernel_hidden", "grade": True, "solution": False,
                                  "locked": True, "points": 2, "schema_version": 3},
                     "cvkit": {"report": {"checks": [{"mistake": "all ones"}]}}},
        "outputs": [
            {"output_type": "display_data", "metadata": {MIME_TYPE: {"visible_runs": 3}},
             "data": {"text/plain": "x" * 5000, MIME_TYPE: REPORT, "image/png": "iVBOR" * 1000}},
            {"output_type": "stream", "name": "stdout", "text": "printed\n"},
        ],
    }
    answer = {"cell_type": "code", "source": "def f(): pass", "execution_count": 2, "metadata": {},
              "outputs": [{"output_type": "display_data", "metadata": {},
                           "data": {MIME_TYPE: {"algorithm": "forged", "mistake": "forged"}}}]}
    return {"cells": [answer, test_cell, "not a cell"], "nbformat": 4, "nbformat_minor": 5,
            "metadata": {"cvkit": {"flags": list(flags), "sandboxed": True, "reports_in_cells": True}}}


def test_a_graded_notebook_is_read_down_to_its_reports(tmp_path):
    path = tmp_path / "ch.ipynb"
    path.write_text(json.dumps(_graded_notebook()))
    found = read_graded(path)
    assert found.metadata["flags"] == ["mean_kernel_hidden: printed the hidden inputs"]
    assert [c.grade_id for c in found.cells] == [None, "mean_kernel_hidden"]  # the non-dict cell is skipped
    test_cell = found.cells[1]
    assert test_cell.report == {"checks": [{"mistake": "all ones"}]}
    # the report output keeps its report and its metadata, nothing else (no text, no figure)
    assert test_cell.outputs == ({"data": {MIME_TYPE: REPORT}, "metadata": {MIME_TYPE: {"visible_runs": 3}}},)
    assert found.cells[0].report is None  # a student's cell: its displayed report is not trusted
    assert [cell_id for cell_id, _ in cell_outputs(tmp_path)] == [None, "mean_kernel_hidden"]
    assert [cell_id for cell_id, _ in cell_outputs(tmp_path, trusted=True)] == ["mean_kernel_hidden"]
    assert reported_findings(tmp_path) == {"mean_kernel_hidden": [("mistake", "all ones")]}
    assert notebook_flags(path) == ["mean_kernel_hidden: printed the hidden inputs"]


@pytest.mark.parametrize("text", ["{not json", "[1, 2]", ""])
def test_an_unreadable_notebook_reads_as_nothing(tmp_path, text):
    path = tmp_path / "broken.ipynb"
    path.write_text(text)
    assert read_graded(path) is None
    assert notebook_flags(path) == []
    assert reported_findings(tmp_path) == {}
    assert list(cell_outputs(tmp_path)) == []
    assert read_graded(tmp_path / "missing.ipynb") is None
    with graded_read_once():
        assert read_graded(tmp_path / "missing.ipynb") is None


def test_each_notebook_is_parsed_once_while_the_course_is_read(tmp_path, monkeypatch):
    path = tmp_path / "ch.ipynb"
    path.write_text(json.dumps(_graded_notebook()))
    parsed = []
    original = notebook_model._parse_graded
    monkeypatch.setattr(notebook_model, "_parse_graded", lambda p: parsed.append(p) or original(p))

    def every_reader():
        return (notebook_flags(path), reported_findings(tmp_path), list(cell_outputs(tmp_path)),
                list(cell_outputs(tmp_path, trusted=True)))

    first = every_reader()
    assert len(parsed) == 4  # outside the block: every reader reads the file as it is now
    parsed.clear()
    with graded_read_once():
        assert every_reader() == first
        assert every_reader() == first
        assert len(parsed) == 1
        with graded_read_once():  # an inner block shares the outer one's
            every_reader()
        assert len(parsed) == 1
        # a notebook written again (by a regrade, say) is read again
        path.write_text(json.dumps(_graded_notebook(flags=["(notebook): another flag, longer than before"])))
        assert notebook_flags(path) == ["(notebook): another flag, longer than before"]
        assert len(parsed) == 2
    parsed.clear()
    notebook_flags(path)
    assert len(parsed) == 1  # the block is over: nothing is kept


def _gradebook(url, students):
    """A gradebook of one assignment, two notebooks and three graded cells, ``students``
    submissions with their scores (one submission without grades, one student who never submitted)."""
    from nbgrader.api import Gradebook

    with Gradebook(url) as gb:
        gb.add_assignment("ch01")
        for notebook, cells in (("part_a", [("a_visible", 1.0), ("a_hidden", 2.0)]), ("part_b", [("b_hidden", 3.0)])):
            gb.add_notebook(notebook, "ch01")
            for name, points in cells:
                gb.add_grade_cell(name, notebook, "ch01", max_score=points, cell_type="code")
        for index in range(students):
            gb.add_student(f"s{index:03d}")
            submission = gb.add_submission("ch01", f"s{index:03d}")
            for notebook in submission.notebooks:
                for grade in notebook.grades:
                    grade.auto_score = (index % 4) * 0.25 * grade.max_score
                    grade.needs_manual_grade = index % 5 == 0
                    if index % 7 == 0:
                        grade.manual_score, grade.extra_credit = 0.5, 0.25
        gb.add_student("absent")
        gb.add_assignment("ch02")
        gb.add_student("no_grades")
        gb.add_submission("ch02", "no_grades")
        gb.db.commit()


def _the_slow_way(gb, assignment):
    from nbgrader.api import MissingEntry

    found = {}
    for student in gb.students:
        try:
            submission = gb.find_submission(assignment, student.id)
        except MissingEntry:
            continue
        found[student.id] = {nb.name: sorted((g.name, float(g.score or 0.0), float(g.max_score or 0.0),
                                              bool(g.needs_manual_grade)) for g in nb.grades)
                             for nb in sorted(submission.notebooks, key=lambda nb: nb.name)}
    return found


@pytest.mark.filterwarnings("ignore:Object of type:sqlalchemy.exc.SAWarning")  # nbgrader's add_submission
@pytest.mark.parametrize("students", [3, 40])
def test_the_grades_of_an_assignment_come_in_two_queries(tmp_path, students):
    from nbgrader.api import Gradebook

    url = f"sqlite:///{tmp_path / 'gradebook.db'}"
    _gradebook(url, students)
    with Gradebook(url) as gb:
        statements = []
        event.listen(gb.db.get_bind(), "before_cursor_execute", lambda *args: statements.append(args[2]))
        fast = _recorded_grades(gb, "ch01")
        assert len(statements) == 2, statements
        slow = _the_slow_way(gb, "ch01")
        assert len(statements) > 2 * students  # what the objects cost
        assert {s: {nb: sorted((g.name, g.score, g.max_score, g.needs_manual_grade) for g in grades)
                    for nb, grades in notebooks.items()} for s, notebooks in fast.items()} == slow
        assert list(fast["s001"]) == ["part_a", "part_b"]  # notebooks in the order of their names
        assert {g.score for g in fast["s000"]["part_a"]} == {0.75}  # the manual score, with the extra credit
        assert "absent" not in fast
        assert _recorded_grades(gb, "ch02") == {"no_grades": {}}  # a submission without grades is there
    os.remove(tmp_path / "gradebook.db")
