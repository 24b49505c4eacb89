"""The student's version of a lecture notebook, made in-process with nbgrader's own preprocessors
(the steps of ``nbgrader generate_assignment`` that change content): solutions replaced by
stubs, hidden tests and mark schemes removed, outputs cleared. Shared by the structure and
release tests; ``tests/`` is not a package, import it as ``import lecture_release``."""
from __future__ import annotations

import copy
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted(p for p in (ROOT / "lectures").glob("ch*/*.ipynb") if ".ipynb_checkpoints" not in p.parts)


def source(cell) -> str:
    return cell["source"] if isinstance(cell["source"], str) else "".join(cell["source"])


def nbgrader(cell) -> dict:
    return cell.get("metadata", {}).get("nbgrader", {})


def release(path: Path):
    """The released (student) notebook of the source notebook at ``path``, as an nbformat node."""
    import nbformat
    from nbgrader.preprocessors import ClearHiddenTests, ClearMarkScheme, ClearOutput, ClearSolutions

    nb = nbformat.read(path, as_version=4)
    resources: dict = {}
    for step in (ClearSolutions(), ClearHiddenTests(), ClearMarkScheme(), ClearOutput()):
        nb, resources = step.preprocess(nb, resources)
    return nb


def load(path: Path) -> dict:
    return copy.deepcopy(json.loads(path.read_text()))
