"""Attempts before passing (issue 37, item 6; analytics only): ``check()`` counts, in the
student's kernel, the runs of each visible test and saves the count in the report's output
metadata; the item analysis reads it from the hand-ins and reports its distribution, marked as
data the student controls. Values a student could have forged into something else are ignored."""
from __future__ import annotations

import csv
import json

import nbformat
import pytest

from cvkit.course import item_analysis
from cvkit.course.item_stats import Response, analyse
from cvkit.grading.report import MIME_TYPE

pytestmark = pytest.mark.slow


def _cell(source: str, grade_id: str | None = None):
    cell = nbformat.v4.new_code_cell(source)
    if grade_id:
        cell.metadata["nbgrader"] = {"grade_id": grade_id, "grade": True, "solution": False, "locked": True,
                                     "points": 1, "schema_version": 3}
    return cell


def test_the_kernel_counts_the_runs_of_each_visible_test(tmp_path):
    from nbclient import NotebookClient

    nb = nbformat.v4.new_notebook()
    nb.cells = [
        _cell("import numpy as np\nfrom cvkit.grading import check"),
        _cell("def mean_kernel(size):\n    return np.ones((size, size))  # wrong"),
        _cell('check("filters.mean_kernel", mean_kernel)', "mean_kernel_visible"),
        _cell("def mean_kernel(size):\n    return np.full((size, size), 1.0 / size ** 2)"),
        _cell('check("filters.mean_kernel", mean_kernel)', "mean_kernel_visible_again"),
        _cell('check("filters.mean_kernel", mean_kernel, hidden=True, points=2)', "mean_kernel_hidden"),
    ]
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    NotebookClient(nb, timeout=300, kernel_name="python3", allow_errors=True,
                   resources={"metadata": {"path": str(tmp_path)}}).execute()

    def runs(cell):
        return [o.get("metadata", {}).get(MIME_TYPE, {}).get("visible_runs") for o in cell.outputs
                if o.get("output_type") == "display_data"]

    assert runs(nb.cells[2]) == [1] and runs(nb.cells[4]) == [2]  # the failed run counts too
    assert runs(nb.cells[5]) == [None]  # a hidden test is not a visible run


def _hand_in(folder, runs_value):
    nb = nbformat.v4.new_notebook()
    cell = _cell('check("filters.mean_kernel", mean_kernel)', "mean_kernel_visible")
    cell.outputs = [nbformat.v4.new_output("display_data", data={"text/plain": "report"},
                                           metadata={MIME_TYPE: {"visible_runs": runs_value}})]
    nb.cells = [cell]
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "ch99.ipynb").write_text(json.dumps(nb))


@pytest.mark.parametrize("value, expected", [(3, {"mean_kernel": 3}), (True, {}), (-2, {}), (10**9, {}),
                                             ("7", {}), (2.5, {})])
def test_the_runs_are_read_from_the_hand_in_and_forged_values_ignored(tmp_path, value, expected):
    _hand_in(tmp_path / "ada", value)
    assert item_analysis.visible_runs(tmp_path / "ada") == expected


def test_the_analysis_reports_their_distribution_as_student_controlled(tmp_path):
    answers = {f"s{i}": {"mean_kernel": Response(1.0, 1.0, visible_runs=runs)}
               for i, runs in enumerate([1, 2, 2, 5, 9, None])}
    result = analyse("ch99", answers, ["mean_kernel"])
    (exercise,) = result.exercises
    assert exercise.visible_runs == [1, 2, 2, 5, 9]
    item_analysis.write_csv([result], tmp_path / "item_analysis.csv")
    rows = {r["measure"]: r for r in csv.DictReader((tmp_path / "item_analysis.csv").open())}
    assert rows["visible_test_runs_median"]["value"] == "2.0" and rows["visible_test_runs_median"]["of"] == "5"
    assert rows["visible_test_runs_max"]["value"] == "9"
    assert rows["visible_test_runs_median"]["note"].startswith("student-controlled data")
    page = item_analysis.write_html([result], tmp_path / "item_analysis.html").read_text()
    assert "Runs of the visible test before handing in" in page and "median 2, middle half 2–5, at most 9" in page
    assert "student-controlled data" in page
