"""Test helpers of the course pipeline: what nbgrader should record for a (trusted) notebook."""
from __future__ import annotations

import ast

from cvkit import registry
from cvkit.grading import evaluate, hidden_seed
from cvkit.grading.runtime.cells import is_solution as is_answer_cell, is_test_cell
from cvkit.course.trusted import submission_version


def _source(cell: dict) -> str:
    return cell["source"] if isinstance(cell["source"], str) else "".join(cell["source"])


def predict_scores(notebook: dict, student: str, salt: str, source: dict | None = None) -> dict[str, float]:
    """What nbgrader should record for each test cell of a (trusted) notebook.

    Runs the setup cell and the answer cells in this process, then grades every
    ``check(...)`` call of the test cells with the seeds grading uses (salt, student, algorithm and
    the version of the student's code, :func:`~cvkit.course.trusted.submission_version`). As nbgrader's
    autograde does, test cells are taken from the ``source`` notebook when given (the
    submitted copy has its hidden tests stripped). Used by the tests to confirm that the
    course pipeline records exactly the engine's verdicts. Never use it on untrusted
    submissions: it executes their code here.
    """
    originals = {cell["metadata"]["nbgrader"].get("grade_id"): _source(cell)
                 for cell in (source or {}).get("cells", []) if is_test_cell(cell)}
    student_provider = registry.provider("student")
    saved = (dict(student_provider.functions), dict(student_provider.sources))
    try:
        return _predict(notebook, student, salt, originals, submission_version(notebook, source))
    finally:  # the answer cells' @student decorators must not leak into this process
        student_provider.functions.clear()
        student_provider.functions.update(saved[0])
        student_provider.sources.clear()
        student_provider.sources.update(saved[1])


def _predict(notebook: dict, student: str, salt: str, originals: dict[str, str], version: str) -> dict[str, float]:
    namespace: dict = {"__name__": "__cvkit_prediction__"}
    tests = []
    for cell in notebook.get("cells", []):
        if cell.get("cell_type") != "code":
            continue
        meta = cell.get("metadata", {}).get("nbgrader", {})
        source = _source(cell)
        if meta.get("grade_id") == "setup" or is_answer_cell(cell):
            code = "\n".join(line for line in source.splitlines() if not line.lstrip().startswith(("%", "!")))
            try:
                exec(compile(code, f"<cell {meta.get('grade_id')}>", "exec"), namespace)
            except Exception:
                pass  # a broken answer cell: its tests will fail in the kernel too
        elif is_test_cell(cell):
            tests.append((meta["grade_id"], float(meta.get("points", 0)), originals.get(meta["grade_id"], source)))
    scores = {}
    for grade_id, points, source in tests:
        calls = [n for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Call)
                 and getattr(n.func, "id", None) == "check"]
        total = points
        for call in calls:
            algorithm_id = ast.literal_eval(call.args[0])
            function = namespace.get(call.args[1].id) if isinstance(call.args[1], ast.Name) else None
            keywords = {k.arg: ast.literal_eval(k.value) for k in call.keywords}
            hidden = keywords.get("hidden", False)
            if function is None:
                total = 0.0
                continue
            seed = hidden_seed(algorithm_id, student=student, salt=salt, version=version)
            report = evaluate(algorithm_id, function, hidden=hidden, seed=seed if hidden else None)
            if hidden:
                total = min(total, round(report.score * float(keywords.get("points", 1.0)), 6))
            elif not report.passed:
                total = 0.0
        scores[grade_id] = total
    return scores
