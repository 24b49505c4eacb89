"""*Run All* on a released (student) notebook runs to the end (issue #19.4).

The released notebook is executed as JupyterLab's *Run All* does: cells in order, stopping at the
first error except in cells tagged ``raises-exception`` (JupyterLab and nbclient both honour the
tag). Only visible test cells may carry the tag, and on an unanswered exercise they say so in one
line; demos that need a student's answer say so in one line too (``needs_answer``) instead of
stopping the notebook.
"""
from __future__ import annotations

import pytest

import lecture_release as L

IDS = [p.parent.name for p in L.NOTEBOOKS]


def _is_visible_test(cell) -> bool:
    meta = L.nbgrader(cell)
    return cell.cell_type == "code" and meta.get("grade") and not meta.get("solution")


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


@pytest.mark.slow
@pytest.mark.parametrize("path", L.NOTEBOOKS, ids=IDS)
def test_run_all_on_the_release_reaches_the_end(path, monkeypatch, tmp_path):
    from nbclient import NotebookClient

    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("CVKIT_STUDENT_ID", "student")
    nb = L.release(path)
    # the student's folder holds only the released notebook
    client = NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}})
    client.execute()  # raises CellExecutionError at an error in an untagged cell, as Run All stops there
    code = [c for c in nb.cells if c.cell_type == "code" and c.source.strip()]
    assert all(c.get("execution_count") for c in code), "every code cell ran"
    for cell in code:
        errors = [o for o in cell.outputs if o.output_type == "error"]
        if not errors:
            continue
        assert _is_visible_test(cell), cell.source[:80]
        assert errors[0].ename == "CheckFailed" and "not answered yet" in errors[0].evalue, (
            f"{L.nbgrader(cell)['grade_id']}: an unanswered exercise fails with one line, got "
            f"{errors[0].ename}: {errors[0].evalue[:200]}")
        printed = "".join(o.get("text", "") for o in cell.outputs if o.output_type == "stream")
        assert printed.count("\n") <= 1, f"one line on an unanswered exercise, got: {printed[:300]}"
