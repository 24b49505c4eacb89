"""The lecture notebooks: structure, no outputs, solutions written from scratch, and a full run
in which every visible and hidden test passes (its duration: benchmarks/bench_notebooks.py)."""
import ast
import json
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted(p for p in (ROOT / "lectures").glob("ch*/*.ipynb") if ".ipynb_checkpoints" not in p.parts)
# the catalog generated from the registry (docs/catalog.md), and the course's binding list when
# it is at hand (it lives outside the repository)
CATALOGS = [path for path in (ROOT / "docs" / "catalog.md", ROOT.parent / "shared" / "CATALOG.md") if path.exists()]


def _load(path):
    return json.loads(path.read_text())


def _src(cell):
    return cell["source"] if isinstance(cell["source"], str) else "".join(cell["source"])


def _nbg(cell):
    return cell.get("metadata", {}).get("nbgrader", {})


def test_there_are_notebooks():
    assert NOTEBOOKS, "no lecture notebooks found"
    for path in NOTEBOOKS:
        assert path.stem == path.parent.name, f"{path}: notebook must be named like its folder"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_committed_without_outputs(path):
    for cell in _load(path)["cells"]:
        if cell["cell_type"] == "code":
            assert cell.get("outputs") == [] and cell.get("execution_count") is None, _src(cell)[:80]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_valid_nbformat_with_cell_ids(path):
    import nbformat

    nbformat.validate(nbformat.reads(path.read_text(), as_version=4))
    # nbformat only warns about a cell without an id (it will become an error): checked here
    ids = [cell.get("id") for cell in _load(path)["cells"]]
    assert all(ids) and len(set(ids)) == len(ids), "every cell needs its own id (nbformat 4.5)"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_exercise_structure(path):
    nb = _load(path)
    cells = nb["cells"]
    first_code = next(c for c in cells if c["cell_type"] == "code")
    assert _nbg(first_code).get("locked") and "from cvkit.grading import check" in _src(first_code)
    grade_ids = [_nbg(c).get("grade_id") for c in cells if _nbg(c)]
    assert len(grade_ids) == len(set(grade_ids)), "duplicate nbgrader grade ids"
    checked = {}
    for i, cell in enumerate(cells):
        meta = _nbg(cell)
        if not meta.get("grade") or cell["cell_type"] != "code":
            continue  # written questions and open tasks are markdown, graded by hand
        source = _src(cell)
        calls = re.findall(r'check\(\s*"([a-z_]+\.[A-Za-z_0-9]+)",\s*(\w+)(.*?)\)', source)
        assert calls, f"test cell {meta['grade_id']} calls no check()"
        for algorithm_id, function, rest in calls:
            hidden = "hidden=True" in rest
            checked.setdefault(algorithm_id, set()).add("hidden" if hidden else "visible")
            if hidden:
                assert "### BEGIN HIDDEN TESTS" in source and "### END HIDDEN TESTS" in source
                points = float(re.search(r"points=([0-9.]+)", rest).group(1))
                assert points == float(meta["points"]), f"{meta['grade_id']}: points= differs from the cell's points"
            # the function is defined in an autograded answer cell before the test
            answers = [c for c in cells[:i] if _nbg(c).get("solution")
                       and (f"def {function}(" in _src(c) or f"class {function}" in _src(c))]
            assert answers, f"{function} is not defined in an answer cell before {meta['grade_id']}"
    for algorithm_id, kinds in checked.items():
        assert kinds == {"visible", "hidden"}, f"{algorithm_id} needs a visible and a hidden test"


def _catalog_ids():
    ids = []
    for line in (line for path in CATALOGS for line in path.read_text().splitlines()):
        if line.startswith("| ") and not line.startswith(("| id", "|---")):
            for part in line.split("|")[1].split("/"):
                part = part.strip()
                if re.fullmatch(r"[a-z_]+\.[A-Za-z_][A-Za-z0-9_]*", part):
                    ids.append(part)
    return ids


def test_every_catalog_id_of_an_implemented_module_has_an_exercise():
    """Each id of a module cvkit implements is graded (visible + hidden) in some notebook."""
    from cvkit import registry

    modules = set(registry.topic_modules())
    exercised = {}
    for path in NOTEBOOKS:
        for cell in _load(path)["cells"]:
            if _nbg(cell).get("grade"):
                for algorithm_id, rest in re.findall(r'check\(\s*"([a-z_]+\.[A-Za-z_0-9]+)",\s*\w+(.*?)\)', _src(cell)):
                    exercised.setdefault(algorithm_id, set()).add("hidden" if "hidden=True" in rest else "visible")
    wanted = sorted({i for i in _catalog_ids() if i.split(".")[0] in modules})
    assert len(wanted) >= 135
    missing = [i for i in wanted if exercised.get(i) != {"visible", "hidden"}]
    assert not missing, f"catalog ids without a visible and a hidden test in a notebook: {missing}"
    for algorithm_id in wanted:
        assert registry.get(algorithm_id).check is not None, algorithm_id


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_solutions_are_written_from_scratch(path):
    """No answer cell calls cvkit's reference implementations or the forbidden libraries."""
    for cell in _load(path)["cells"]:
        if not _nbg(cell).get("solution") or cell["cell_type"] != "code":
            continue  # a written answer (markdown) holds the model answer and rubric
        source = _src(cell)
        assert "### BEGIN SOLUTION" in source and "### END SOLUTION" in source
        tree = ast.parse(source)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
                assert node.value.id not in {"filters", "noise", "cvkit", "ndimage", "cv2", "skimage"}, (
                    f"{_nbg(cell)['grade_id']} uses {node.value.id}.{node.attr}")
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [getattr(node, "module", None) or ""] + [a.name for a in node.names]
                assert not any(n.startswith(("scipy.ndimage", "skimage", "cv2", "cvkit.filters", "cvkit.noise")) for n in names)


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_source_notebook_runs_and_every_test_passes(path, monkeypatch):
    import nbformat
    from nbclient import NotebookClient

    monkeypatch.setenv("CVKIT_GRADING_SALT", "notebook-test")  # hidden cases other than the practice ones
    monkeypatch.setenv("CVKIT_STUDENT_ID", "instructor")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}})
    client.execute()  # how long it takes is measured by benchmarks/bench_notebooks.py, not asserted here
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        for output in cell.outputs:
            assert output.output_type != "error", f"{_src(cell)[:60]}: {output.get('ename')}: {output.get('evalue')}"
            assert not (output.output_type == "stream" and output.name == "stderr"), (
                f"stderr output (nbgrader would zero a test cell): {output.text[:300]}")
        meta = _nbg(cell)
        if meta.get("grade") and "hidden=True" in _src(cell):
            values = [o for o in cell.outputs if o.output_type == "execute_result"]
            assert values and float(values[0]["data"]["text/plain"]) == float(meta["points"]), meta["grade_id"]
