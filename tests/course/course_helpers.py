"""Test helpers of the course pipeline: the notebooks and projects of the tiny throwaway
courses the course tests grade, and what nbgrader should record for a (trusted) notebook."""
from __future__ import annotations

import ast
import copy
import json
import shutil
from pathlib import Path

from cvkit import registry
from cvkit.grading import evaluate, hidden_seed
from cvkit.grading.runtime.cells import is_solution as is_answer_cell, is_test_cell
from cvkit.course.trusted import _trivial, submission_version

ROOT = Path(__file__).resolve().parents[2]
#: the set-up cell of a tiny chapter
SETUP = "import numpy as np\nimport cvkit\nfrom cvkit.grading import check\nfrom cvkit.registry import student"
#: the released solution of the tiny chapters' exercise (``filters.temporal_mean``)
TEMPORAL_MEAN = ('@student("filters.temporal_mean")\ndef temporal_mean(frames):\n'
                 '    ### BEGIN SOLUTION\n    return np.asarray(frames, dtype=float).mean(axis=0)\n    ### END SOLUTION')
#: a right answer of a student: the mean by a loop
TEMPORAL_MEAN_LOOP = ('@student("filters.temporal_mean")\ndef temporal_mean(frames):\n'
                      '    stack = np.asarray(frames, dtype=float)\n    total = np.zeros(stack.shape[1:])\n'
                      '    for frame in stack:\n        total = total + frame\n    return total / len(stack)')


# --------------------------------------------------------------------------------------------
# the tiny courses' notebooks and projects
# --------------------------------------------------------------------------------------------
def new_cell(source, grade_id=None, *, solution=False, grade=False, points=None, cell_type="code") -> dict:
    """A notebook cell; with ``grade_id`` an nbgrader cell (locked unless it is a solution)."""
    meta = {}
    if grade_id:
        meta["nbgrader"] = {"grade_id": grade_id, "solution": solution, "grade": grade, "locked": not solution,
                            "schema_version": 3, **({"points": points} if points is not None else {})}
    cell = {"cell_type": cell_type, "source": source, "metadata": meta}
    if cell_type == "code":
        cell.update(outputs=[], execution_count=None)
    return cell


def exercise_cells(algorithm_id: str, name: str, answer: str, *, hidden_points: int = 2) -> list[dict]:
    """The answer cell ``{name}_answer``, the visible test ``{name}_visible`` (1 point) and the
    hidden test ``{name}_hidden`` of function ``name`` checked as ``algorithm_id``."""
    return [
        new_cell(answer, f"{name}_answer", solution=True),
        new_cell(f'check("{algorithm_id}", {name})', f"{name}_visible", grade=True, points=1),
        new_cell(f'### BEGIN HIDDEN TESTS\ncheck("{algorithm_id}", {name}, hidden=True, points={hidden_points})\n'
                 '### END HIDDEN TESTS', f"{name}_hidden", grade=True, points=hidden_points),
    ]


def new_notebook(cells: list[dict], *, ids: bool = False) -> dict:
    """An nbformat 4.5 notebook of ``cells`` on a Python 3 kernel; ``ids``: cell N gets the id
    ``cell-N``."""
    if ids:
        for index, cell in enumerate(cells):
            cell["id"] = f"cell-{index}"
    return {"cells": cells, "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3",
                                                        "language": "python"}},
            "nbformat": 4, "nbformat_minor": 5}


def submitted(notebook: dict, answers: dict[str, str]) -> dict:
    """What a student hands in: a copy of the released ``notebook`` with its hidden test cells
    (grade ids ending in ``_hidden``) emptied and the answer cells of ``answers`` ({grade id:
    source}) written."""
    notebook = copy.deepcopy(notebook)
    for cell in notebook["cells"]:
        grade_id = cell["metadata"].get("nbgrader", {}).get("grade_id", "")
        if grade_id.endswith("_hidden"):
            cell["source"] = ""
        if grade_id in answers:
            cell["source"] = answers[grade_id]
    return notebook


def write_project(folder: Path, plan: str | None, notebooks: dict[str, dict]) -> Path:
    """A project in ``folder`` (made if missing, readable by everyone) with the real course
    configuration, ``plan`` as its plan.toml (``None``: none) and ``notebooks`` ({path under
    lectures/: notebook})."""
    (folder / "autograders").mkdir(parents=True)
    shutil.copy(ROOT / "autograders" / "nbgrader_config.py", folder / "autograders" / "nbgrader_config.py")
    if plan is not None:
        (folder / "autograders" / "plan.toml").write_text(plan)
    for path, notebook in notebooks.items():
        (folder / "lectures" / path).parent.mkdir(parents=True, exist_ok=True)
        (folder / "lectures" / path).write_text(json.dumps(notebook))
    folder.chmod(0o755)
    return folder


def cell_grades(course) -> dict[str, dict[str, float]]:
    """The scores nbgrader's gradebook holds: {student: {grade id: score}}."""
    from nbgrader.api import Gradebook

    out = {}
    with Gradebook(course.db_url) as gb:
        for student, assignment in course.submissions():
            submission = gb.find_submission(assignment, student)
            out[student] = {g.name: g.score for nb in submission.notebooks for g in nb.grades}
    return out


# --------------------------------------------------------------------------------------------
# what nbgrader should record
# --------------------------------------------------------------------------------------------


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
                score = report.score if _tells_something(algorithm_id, report, seed) else 0.0
                total = min(total, round(score * float(keywords.get("points", 1.0)), 6))
            elif not report.passed:
                total = 0.0
        scores[grade_id] = total
    return scores


def _tells_something(algorithm_id: str, report, seed: int) -> bool:
    """Whether hidden cases whose answer needs no computing may count (the rule of
    :func:`cvkit.course.trusted.grade_notebook`): there is none that needs computing, or the
    function passed (or earned credit on) one of them."""
    import numpy as np

    cases = registry.get(algorithm_id).check.graded_hidden_cases(np.random.default_rng(seed))
    telling = [c for c in report.cases if not _trivial(cases[c.index], c.expected)]
    return not telling or any(c.passed or c.credit for c in telling)
