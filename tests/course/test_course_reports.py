"""The trusted verdicts travel as data: each graded test cell carries them in its metadata
(``metadata.cvkit.report``), the course's results read them there and not from the output text,
the output students see is unchanged, and nothing a student writes into cell metadata counts."""
import copy
import json

import nbformat
import pytest

from cvkit.course.results import reported_findings
from cvkit.course.trusted import apply_trusted_checks, cell_report
from cvkit.grading.runtime.cells import is_solution as is_answer_cell, is_test_cell
from cvkit.grading.report import MIME_TYPE, finding, headline

SETUP = ("import numpy as np\nimport cvkit\nfrom cvkit import filters\nfrom cvkit.grading import check\n"
         "from cvkit.registry import student")
ALL_ONES = '@student("filters.mean_kernel")\ndef mean_kernel(size):\n    return np.ones((size, size))'
SHIFTED = ('@student("filters.temporal_mean")\ndef temporal_mean(frames):\n'
           '    return np.roll(np.asarray(frames, dtype=float).mean(axis=0), 1, axis=0)')
FORGED = {"report": {"checks": [{"mistake": "forged by the student"}]}}


def _cell(source, grade_id=None, *, solution=False, grade=False, points=None):
    meta = {}
    if grade_id:
        meta["nbgrader"] = {"grade_id": grade_id, "solution": solution, "grade": grade, "locked": not solution,
                            "schema_version": 3, **({"points": points} if points is not None else {})}
    return {"cell_type": "code", "source": source, "metadata": meta, "outputs": [], "execution_count": None}


def _notebook():
    cells = [
        _cell(SETUP, "setup"),
        _cell(ALL_ONES, "mean_kernel_answer", solution=True),
        _cell('check("filters.mean_kernel", mean_kernel)', "mean_kernel_visible", grade=True, points=1),
        _cell('check("filters.mean_kernel", mean_kernel, hidden=True, points=2)', "mean_kernel_hidden",
              grade=True, points=2),
        _cell(SHIFTED, "temporal_mean_answer", solution=True),
        _cell('check("filters.temporal_mean", temporal_mean)', "temporal_mean_visible", grade=True, points=1),
    ]
    for index, cell in enumerate(cells):
        cell["id"] = f"cell-{index}"
    return {"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5}


@pytest.fixture(scope="module")
def graded():
    """A notebook graded by the trusted checks, whose student put ``cvkit`` metadata in two cells."""
    submitted = _notebook()
    for index in (1, 2):  # the answer cell and a test cell
        submitted["cells"][index]["metadata"]["cvkit"] = copy.deepcopy(FORGED)
    nb = nbformat.from_dict(submitted)
    flags = apply_trusted_checks(nb, student="ann", salt="report-salt", source_notebook=_notebook())
    return json.loads(nbformat.writes(nb)), flags


def _output_reports(cell):
    return [o["data"][MIME_TYPE] for o in cell["outputs"] if MIME_TYPE in o.get("data", {})]


def test_cell_roles_are_nbgraders():
    cells = _notebook()["cells"]
    assert [is_test_cell(c) for c in cells] == [False, False, True, True, False, True]
    assert [is_answer_cell(c) for c in cells] == [False, True, False, False, True, False]
    assert is_test_cell(nbformat.from_dict(cells[2])) and not is_test_cell(nbformat.from_dict(cells[1]))


def test_each_test_cell_carries_its_verdicts_as_data(graded):
    nb, _ = graded
    assert nb["metadata"]["cvkit"]["reports_in_cells"] is True
    tests = [c for c in nb["cells"] if is_test_cell(c)]
    assert len(tests) == 3
    for cell in tests:
        report = cell["metadata"]["cvkit"]["report"]
        shown = _output_reports(cell)
        assert len(report["checks"]) == len(shown) == 1
        for check, output in zip(report["checks"], shown):
            assert check["algorithm"] == output["algorithm"] and check["hidden"] == output["hidden"]
            assert check["total"] == len(output["cases"])
            assert check["passed"] == sum(c["passed"] for c in output["cases"])
            assert check["score"] == pytest.approx(output["score"])
            kind, words = finding(output)
            assert check[kind] == words and check["problem" if kind == "mistake" else "mistake"] is None
        assert report["points"] == cell["metadata"]["nbgrader"]["points"]
    visible, hidden, temporal = tests
    assert visible["metadata"]["cvkit"]["report"]["credit"] == 0.0
    assert visible["metadata"]["cvkit"]["report"]["checks"][0]["mistake"] == "not normalised (all ones)"
    assert visible["metadata"]["cvkit"]["report"]["checks"][0]["function"] == "mean_kernel"
    # the partial credit stored is the one nbgrader records from the output
    credit = "".join(next(o for o in hidden["outputs"] if o["output_type"] == "execute_result")["data"]["text/plain"])
    assert hidden["metadata"]["cvkit"]["report"]["credit"] == pytest.approx(float(credit))
    assert 0 <= float(credit) < 2
    assert temporal["metadata"]["cvkit"]["report"]["checks"][0]["problem"].startswith("your output is shifted")


def test_what_students_see_is_the_report_text(graded):
    nb, _ = graded
    visible = next(c for c in nb["cells"] if c["metadata"].get("nbgrader", {}).get("grade_id") == "mean_kernel_visible")
    text = "".join(visible["outputs"][0]["data"]["text/plain"])
    assert "matches a known mistake: not normalised (all ones)" in text
    assert visible["outputs"][-1]["output_type"] == "error"


def test_student_metadata_is_dropped(graded):
    nb, _ = graded
    answer = next(c for c in nb["cells"] if c["metadata"].get("nbgrader", {}).get("grade_id") == "mean_kernel_answer")
    assert "cvkit" not in answer["metadata"]
    assert "forged" not in json.dumps([c["metadata"] for c in nb["cells"]])


def test_results_read_the_data_not_the_output_text(graded, tmp_path):
    nb, _ = graded
    (tmp_path / "chapter.ipynb").write_text(json.dumps(nb))
    found = reported_findings(tmp_path)
    assert found["mean_kernel_visible"] == [("mistake", "not normalised (all ones)")]
    assert found["temporal_mean_visible"][0][0] == "problem"
    # outputs changed after grading (or forged) do not change what the results read
    tampered = copy.deepcopy(nb)
    for cell in tampered["cells"]:
        for report in _output_reports(cell):
            report["mistake"] = "text in the output"
    (tmp_path / "chapter.ipynb").write_text(json.dumps(tampered))
    assert reported_findings(tmp_path) == found


def test_notebooks_graded_before_are_read_from_their_reports(graded, tmp_path):
    """A notebook graded before the verdicts were stored as data (no marker, no cell metadata)
    gives the same findings from its reports' JSON outputs."""
    nb, _ = graded
    (tmp_path / "now.ipynb").write_text(json.dumps(nb))
    old = copy.deepcopy(nb)
    del old["metadata"]["cvkit"]["reports_in_cells"]
    for cell in old["cells"]:
        cell["metadata"].pop("cvkit", None)
    (tmp_path / "before").mkdir()
    (tmp_path / "before" / "chapter.ipynb").write_text(json.dumps(old))
    assert reported_findings(tmp_path / "before") == reported_findings(tmp_path)


def test_cell_report_keeps_the_cells_own_flags():
    record = cell_report("x_visible", [], 1.0, 0.0, ["x_visible: passes only the public cases (f.g)",
                                                     "x_answer: imports os", "(notebook): killed"])
    assert record == {"points": 1.0, "credit": 0.0, "checks": [], "flags": ["passes only the public cases (f.g)"]}


def test_headline_keeps_plain_words():
    assert headline("Not equal to tolerance rtol=1e-07\nMismatched elements: 60 / 90 (66.7%)") == "60 of 90 values differ"
    assert headline("Your output is shifted by 1 row down: first at [0, 0]") == "your output is shifted by 1 row down"
    assert headline("") == "failed"
    assert finding({"mistake": None, "cases": [{"passed": True}]}) is None


# ---------------------------------------------------------------- issue #35: small inconsistencies
def _flagged_scores():
    from cvkit.course import ExerciseScore

    return {"ann": [ExerciseScore("pad", 3.0, 3.0),
                    ExerciseScore("(notebook)", 0.0, 0.0, flags=["(notebook): the code was killed by signal 9"])]}


def test_a_row_of_flags_only_shows_no_points():
    """The whole notebook's flags get a row of their own: it has no points, so it is neither
    "0.00/0" nor passed (✓)."""
    from cvkit.course import format_table

    table = format_table(_flagged_scores())
    row = next(line for line in table.splitlines() if line.startswith("(notebook)"))
    assert "0.00/0" not in row and "✓" not in row and "flagged" in row, row
    assert "total" in table and "3.00/3" in table


def test_exercises_csv_gives_a_flags_only_row_no_score(tmp_path, monkeypatch):
    import csv

    from cvkit.course import exports
    from cvkit.course.exports import _export_exercises

    class Course:  # what _export_exercises reads of a course state
        def not_graded(self):
            return {}

    monkeypatch.setattr(exports, "scores", lambda course, assignment: _flagged_scores())

    class Bar:
        def update(self, *args):
            pass

    target = tmp_path / "exercises.csv"
    _export_exercises(Course(), target, ["ch03"], Bar())
    rows = {row["exercise"]: row for row in csv.DictReader(target.open())}
    assert rows["pad"]["score"] == "3" and rows["pad"]["status"] == "graded"
    flags = rows["(notebook)"]
    assert flags["score"] == flags["max_score"] == "" and flags["status"] == "flags for the instructor (no points)"
    assert "killed by signal 9" in flags["flags"]
