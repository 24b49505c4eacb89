"""*Run All* on every released chapter, in the Python environment that runs this script.

    python tests/lectures/run_all_released.py RESULT.json [WORKERS]

Used by ``tests/system/test_fresh_clone.py`` with the virtual environment ``scripts/demo`` created
from a fresh clone: exactly what a course gets (``cvkit[course]``), not the test suite's own.
Each chapter's source notebook is released as ``nbgrader generate_assignment`` does
(:func:`lecture_release.release`) and executed as JupyterLab's *Run All*: cells in order,
stopping at the first error except in cells tagged ``raises-exception``. The kernel is this
environment's (checked: its ``sys.prefix`` is this script's). Writes ``{"prefix": the kernel's
sys.prefix, "chapters": {chapter: [problems]}}`` to RESULT.json: no problem means the chapter ran
to its end, every code cell ran, and only visible tests of unanswered exercises failed, each with
one line (its error, and at most one printed line). This is the suite's only *Run All* of the
released notebooks outside the browser: the test suite's own environment holds everything a
course's does, so a chapter that runs here runs there too.
"""
from __future__ import annotations

import concurrent.futures
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import lecture_release as L  # noqa: E402


def _client(nb, folder: str):
    from nbclient import NotebookClient

    return NotebookClient(nb, timeout=180, kernel_name="python3", resources={"metadata": {"path": folder}})


def kernel_prefix() -> str:
    """``sys.prefix`` of the kernel ``python3`` as Run All starts it here."""
    import nbformat

    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("import sys; print(sys.prefix)")])
    with tempfile.TemporaryDirectory() as folder:
        _client(nb, folder).execute()
    return "".join(o.get("text", "") for o in nb.cells[0].outputs).strip()


def _is_visible_test(cell) -> bool:
    meta = L.nbgrader(cell)
    return cell.cell_type == "code" and bool(meta.get("grade")) and not meta.get("solution")


def run_all(path: str) -> tuple[str, list[str]]:
    """(chapter, problems) of *Run All* on the release of the source notebook at ``path``."""
    from nbclient.exceptions import CellExecutionError

    path_ = Path(path)
    nb = L.release(path_)
    problems = []
    with tempfile.TemporaryDirectory() as folder:  # the student's folder holds only the released notebook
        try:
            _client(nb, folder).execute()
        except CellExecutionError as error:
            ran = [i for i, c in enumerate(nb.cells) if c.cell_type == "code" and c.get("execution_count")]
            where = f"code cell {len(ran)} (cell {ran[-1] + 1} of {len(nb.cells)})" if ran else "its first code cell"
            problems.append(f"Run All stopped at {where}: {error.ename}: {str(error.evalue)[:300]}")
        except Exception as error:  # noqa: BLE001 - a kernel that died, a timeout: the finding
            problems.append(f"Run All failed: {type(error).__name__}: {str(error)[:300]}")
    code = [c for c in nb.cells if c.cell_type == "code" and c.source.strip()]
    if not problems and not all(c.get("execution_count") for c in code):
        problems.append("not every code cell ran")
    for cell in code:
        errors = [o for o in cell.outputs if o.output_type == "error"]
        if not errors:
            continue
        error = errors[0]
        if not _is_visible_test(cell):
            problems.append(f"an error in a cell that is not a visible test: {error.ename}: {error.evalue[:200]}")
            continue
        grade_id = L.nbgrader(cell).get("grade_id")
        if error.ename != "CheckFailed" or "not answered yet" not in error.evalue:
            problems.append(f"{grade_id}: an unanswered exercise fails with one line, got {error.ename}: {error.evalue[:200]}")
        printed = "".join(o.get("text", "") for o in cell.outputs if o.output_type == "stream")
        if printed.count("\n") > 1:
            problems.append(f"{grade_id}: one line on an unanswered exercise, got: {printed[:300]}")
    return path_.parent.name, list(dict.fromkeys(problems))


def main(argv: list[str]) -> int:
    target = Path(argv[0])
    workers = int(argv[1]) if len(argv) > 1 else 2
    result = {"prefix": kernel_prefix(), "python_prefix": sys.prefix, "chapters": {}}
    with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
        for chapter, problems in pool.map(run_all, [str(p) for p in L.NOTEBOOKS]):
            result["chapters"][chapter] = problems
    target.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
