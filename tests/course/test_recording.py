"""The writer's nbgrader run records a notebook's grades in one transaction (SaveAutoGradesAtOnce):
the same rows as nbgrader's SaveAutoGrades, one commit instead of one per cell, and nothing of a
notebook recorded when one of its cells fails."""
from __future__ import annotations

import nbformat
import pytest
from nbgrader.api import Gradebook, MissingEntry
from nbgrader.preprocessors import SaveAutoGrades
from sqlalchemy import event
from sqlalchemy.orm import Session

from cvkit.course.nbgrader_plugins import SaveAutoGradesAtOnce
from cvkit.course.nbgrader_settings import configure


def _cell(source, grade_id, *, grade=False, solution=False, points=0, error=False):
    meta = {"nbgrader": {"grade_id": grade_id, "grade": grade, "solution": solution, "locked": not solution,
                         "schema_version": 3, **({"points": points} if grade else {})}}
    outputs = [nbformat.v4.new_output("error", ename="AssertionError", evalue="", traceback=[])] if error else []
    return nbformat.v4.new_code_cell(source, metadata=meta, outputs=outputs)


def _gradebook(tmp_path, name):
    url = f"sqlite:///{tmp_path / name}"
    with Gradebook(url) as gb:
        gb.add_assignment("ch")
        gb.add_notebook("nb", "ch")
        gb.add_solution_cell("answer", "nb", "ch")
        gb.add_source_cell("answer", "nb", "ch", cell_type="code", source="def f(): ...", checksum="x")
        for grade_id, points in (("test_a", 2), ("test_b", 3)):
            gb.add_grade_cell(grade_id, "nb", "ch", max_score=points, cell_type="code")
            gb.add_source_cell(grade_id, "nb", "ch", cell_type="code", source="check(f)", checksum="y")
        gb.add_student("alice")
        gb.add_submission("ch", "alice")
    return url


def _notebook(*extra):
    cells = [_cell("def f(): return 1", "answer", solution=True),
             _cell("check(f)", "test_a", grade=True, points=2),
             *extra,
             _cell("check(f)", "test_b", grade=True, points=3, error=True)]
    return nbformat.v4.new_notebook(cells=cells)


def _recorded(url):
    with Gradebook(url) as gb:
        nb = gb.find_submission_notebook("nb", "ch", "alice")
        grades = {g.name: (g.auto_score, g.needs_manual_grade) for g in nb.grades}
        comments = {c.name: c.auto_comment for c in nb.comments}
    return grades, comments


def _run(step, url, nb):
    resources = {"nbgrader": {"notebook": "nb", "assignment": "ch", "student": "alice", "db_url": url}}
    commits = []
    listener = lambda session: commits.append(session)  # noqa: E731
    event.listen(Session, "after_commit", listener)
    try:
        step().preprocess(nb, resources)
    finally:
        event.remove(Session, "after_commit", listener)
    return len(commits)


def test_the_same_rows_as_nbgrader_in_one_commit(tmp_path):
    ours, theirs = _gradebook(tmp_path, "ours.db"), _gradebook(tmp_path, "theirs.db")
    our_commits = _run(SaveAutoGradesAtOnce, ours, _notebook())
    their_commits = _run(SaveAutoGrades, theirs, _notebook())
    grades, comments = _recorded(ours)
    assert grades == {"test_a": (2.0, False), "test_b": (0.0, False)}
    assert set(comments) == {"answer"}
    assert (grades, comments) == _recorded(theirs)
    # nbgrader commits after each of the three cells it records; we commit the notebook once
    assert their_commits - our_commits == 2


def test_a_failing_cell_leaves_nothing_of_the_notebook_recorded(tmp_path):
    unknown = _cell("check(f)", "not_in_the_gradebook", grade=True, points=1)
    ours, theirs = _gradebook(tmp_path, "ours.db"), _gradebook(tmp_path, "theirs.db")
    with pytest.raises(MissingEntry):
        _run(SaveAutoGradesAtOnce, ours, _notebook(unknown))
    with pytest.raises(MissingEntry):
        _run(SaveAutoGrades, theirs, _notebook(unknown))
    assert _recorded(ours)[0] == {"test_a": (None, True), "test_b": (None, True)}  # as before the run
    assert _recorded(theirs)[0]["test_a"] == (2.0, False)  # nbgrader's: half a notebook recorded


def test_the_course_configuration_records_with_it(tmp_path, monkeypatch):
    from traitlets.config import Config

    # configure() marks this process as the trusted grader's and takes the salt from the
    # environment: both are put back after the test, or the next tests would see a grader
    monkeypatch.setenv("CVKIT_TRUSTED_GRADING", "0")
    monkeypatch.delenv("CVKIT_GRADING_SALT", raising=False)
    c = Config()
    configure(c, tmp_path)
    steps = c.Autograde.autograde_preprocessors
    assert SaveAutoGradesAtOnce in steps and SaveAutoGrades not in steps
