"""*Run All* on a released (student) notebook runs to the end (issue #19.4): its tags.

JupyterLab's *Run All* (and nbclient) runs the cells in order and stops at the first error, except
in cells tagged ``raises-exception``. Only visible test cells may carry the tag; on an unanswered
exercise they say so in one line, and demos that need a student's answer say so in one line too
(``needs_answer``) instead of stopping the notebook. *Run All* itself runs on every released
chapter in the environment a course gets, from a fresh clone
(``tests/system/test_fresh_clone.py`` with ``tests/lectures/run_all_released.py``), and on one
chapter in JupyterLab (``tests/system/test_browser.py``).
"""
from __future__ import annotations

import pytest

import lecture_release as L

IDS = [p.parent.name for p in L.NOTEBOOKS]


@pytest.mark.parametrize("path", L.NOTEBOOKS, ids=IDS)
def test_only_visible_test_cells_may_raise(path):
    nb = L.load(path)
    for cell in nb["cells"]:
        tags = cell.get("metadata", {}).get("tags", [])
        meta = L.nbgrader(cell)
        visible_test = (cell["cell_type"] == "code" and meta.get("grade") and not meta.get("solution")
                        and "BEGIN HIDDEN TESTS" not in L.source(cell))
        if visible_test:
            assert "raises-exception" in tags, f"{meta['grade_id']}: visible test cells carry 'raises-exception'"
        else:
            assert "raises-exception" not in tags, f"only visible test cells may raise: {L.source(cell)[:60]}"


def _source_notebook(path, cells):
    """A source notebook of ``(kind, source, nbgrader metadata or None, tags)`` cells at ``path``."""
    import nbformat

    nb = nbformat.v4.new_notebook()
    for kind, source, meta, tags in cells:
        cell = nbformat.v4.new_code_cell(source) if kind == "code" else nbformat.v4.new_markdown_cell(source)
        if meta is not None:
            cell.metadata["nbgrader"] = dict(meta, schema_version=3)
        if tags:
            cell.metadata["tags"] = list(tags)
        nb.cells.append(cell)
    nbformat.write(nb, path)
    return path


@pytest.mark.slow
def test_the_run_all_script_reports_what_stops_a_chapter(tmp_path, monkeypatch):
    """``run_all_released.run_all`` (what the fresh-clone test runs on every chapter) finds each
    kind of problem: an error outside a visible test stops Run All; a visible test that fails
    with more than its one line, or with something other than "not answered yet"."""
    import run_all_released

    monkeypatch.setenv("CVKIT_STUDENT_ID", "student")
    answer = {"grade": False, "solution": True, "locked": False, "grade_id": "f_answer"}
    visible = {"grade": True, "solution": False, "locked": True, "grade_id": "f_visible", "points": 1}
    unanswered = "raise CheckFailed('f: not answered yet')"
    define = "class CheckFailed(Exception):\n    pass"
    good = _source_notebook(tmp_path / "good.ipynb", [
        ("code", define, None, ()),
        ("code", "def f():\n    ### BEGIN SOLUTION\n    return 1\n    ### END SOLUTION", answer, ()),
        ("code", unanswered, visible, ("raises-exception",))])
    assert run_all_released.run_all(str(good))[1] == []
    chatty = _source_notebook(tmp_path / "chatty.ipynb", [
        ("code", define, None, ()),
        ("code", "print('a\\nb\\nc')\n" + unanswered, visible, ("raises-exception",))])
    (problem,) = run_all_released.run_all(str(chatty))[1]
    assert "one line on an unanswered exercise" in problem
    wrong_error = _source_notebook(tmp_path / "wrong_error.ipynb", [
        ("code", "1 / 0", visible, ("raises-exception",))])
    (problem,) = run_all_released.run_all(str(wrong_error))[1]
    assert "ZeroDivisionError" in problem and "fails with one line" in problem
    stopped = _source_notebook(tmp_path / "stopped.ipynb", [
        ("code", "x = 1", None, ()), ("code", "undefined_name", None, ()), ("code", "y = 2", None, ())])
    problems = run_all_released.run_all(str(stopped))[1]
    assert any("Run All stopped at code cell 2" in p and "NameError" in p for p in problems), problems
    assert any("not a visible test" in p for p in problems), problems
