"""``cvkit new exercise <id>``: the files of a new exercise in an instructor's course package.

A course package is an installable folder whose ``pyproject.toml`` declares an entry point in
the group ``cvkit.algorithms`` (see :mod:`cvkit.registry`); its name is the namespace of the
package's ids. For ``mycourse.gamma_correction`` the scaffold writes::

    <package>/pyproject.toml              the entry point mycourse = "mycourse" (only if missing)
    <package>/mycourse/__init__.py        imports every exercise module (only if missing)
    <package>/mycourse/gamma_correction.py
        the reference stub registered with @cvkit.algorithm, its check: one public case, a
        hidden-case generator, a comparator and one named mistake
    <package>/gamma_correction_cells.ipynb
        the notebook cells of the exercise, as in the chapter notebooks of lectures/: the
        statement, the answer cell (### BEGIN/END SOLUTION), the visible test (tagged
        raises-exception) and the hidden test (### BEGIN/END HIDDEN TESTS)

It never overwrites a file: when the exercise module or its cells exist already, nothing is
written. The how-to ``docs/own-exercise.md`` goes on from there.
"""
from __future__ import annotations

import json
import keyword
from pathlib import Path
from typing import Any

from . import registry

try:
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    tomllib = None

__all__ = ["new_exercise", "exercise_cells", "VISIBLE_POINTS", "HIDDEN_POINTS"]

VISIBLE_POINTS = 1
HIDDEN_POINTS = 2

_PYPROJECT = '''\
[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "{distribution}"
version = "0.1.0"
description = "Exercises of {namespace} for the cvkit course kit"
requires-python = ">=3.10"
dependencies = ["cvkit", "numpy"]

# cvkit finds the package through this entry point; its name is the namespace of the ids
[project.entry-points."cvkit.algorithms"]
{namespace} = "{namespace}"

[tool.setuptools]
packages = ["{namespace}"]
'''

_INIT = '''\
"""{namespace}: exercises for the cvkit course kit.

cvkit imports this package through its entry point (group ``cvkit.algorithms``); importing it
imports every exercise module next to this file, and each registers its reference
implementation and check with ``@cvkit.algorithm("{namespace}.<name>", ...)``.
"""
import importlib
import pkgutil

for _module in pkgutil.iter_modules(__path__):
    if not _module.name.startswith("_"):
        importlib.import_module(f"{{__name__}}.{{_module.name}}")
'''

_MODULE = '''\
"""Exercise {id}: its reference implementation and its check.

Written by ``cvkit new exercise {id}``. Replace every TODO: the reference (a correct,
vectorized NumPy version), the public case students see, the hidden cases drawn at grading
time, and the mistake bank (typical wrong versions, each with the hint that fixes it).
``cvkit list {namespace} --validate`` tells whether the reference passes its own public cases.
"""
from __future__ import annotations

import numpy as np

import cvkit
from cvkit.grading import Case, Check, close, mistake


def _public() -> list[Case]:
    """Small fixed cases the students see in the visible test (TODO: your own)."""
    return [Case((np.array([[0.0, 0.25], [0.5, 1.0]]),), {{}}, "2x2 ramp")]


def _hidden(rng: np.random.Generator) -> list[Case]:
    """Cases drawn at grading time from a seed nobody knows in advance (TODO: include inputs
    that tell every mistake of the bank from the right answer)."""
    return [Case((rng.random((int(rng.integers(3, 9)), int(rng.integers(3, 9)))),), {{}}, f"random image {{i}}")
            for i in range(4)]


@mistake("TODO name of the mistake", "TODO: the advice that fixes it")
def _todo_mistake(image):
    """TODO: a typical wrong version of {name} (e.g. the formula with a factor missing)."""
    raise NotImplementedError("write the wrong version students typically write")


CHECK = Check(
    public=_public,
    hidden=_hidden,
    compare=close(rtol=1e-10, atol=1e-12),
    mistakes=[_todo_mistake],  # the bank, in the order the feedback tries them
    allowed=(),  # ids of building blocks students may call, e.g. ("filters.pad",)
)


@cvkit.algorithm("{id}", section="{section}", check=CHECK)
def {name}(image):
    """TODO: one line saying what {name} returns.

    Parameters
    ----------
    image : array_like
        TODO.

    Returns
    -------
    numpy.ndarray
        TODO.
    """
    raise NotImplementedError("write the reference implementation of {id}")
'''


def _cell(kind: str, cell_id: str, source: str, nbgrader: dict | None = None, tags: tuple = ()) -> dict:
    metadata: dict = {}
    if nbgrader is not None:
        metadata["nbgrader"] = dict(nbgrader, schema_version=3)
    if tags:
        metadata["tags"] = list(tags)
    cell: dict[str, Any] = {"cell_type": kind, "id": cell_id, "metadata": metadata, "source": source}
    if kind == "code":
        cell.update(execution_count=None, outputs=[])
    return cell


def exercise_cells(algorithm_id: str, name: str) -> dict:
    """The notebook cells of an exercise (an nbformat 4.5 notebook holding only them)."""
    test = {"grade": True, "locked": True, "solution": False}
    cells = [
        _cell("markdown", f"{name}-statement",
              f"### Exercise — `{name}(image)`\n\nTODO: the statement: what `{name}` computes, its conventions "
              "(dtype, value range, shape) and what it must refuse."),
        _cell("code", f"{name}-answer",
              f'@student("{algorithm_id}")\ndef {name}(image):\n    """TODO: one line saying what it returns."""\n'
              "    ### BEGIN SOLUTION\n    raise NotImplementedError(\"the model solution, written from scratch\")\n"
              "    ### END SOLUTION",
              {"grade": False, "grade_id": f"{name}_answer", "locked": False, "solution": True}),
        _cell("code", f"{name}-visible", f'check("{algorithm_id}", {name})',
              dict(test, grade_id=f"{name}_visible", points=VISIBLE_POINTS), tags=("raises-exception",)),
        _cell("code", f"{name}-hidden",
              f'### BEGIN HIDDEN TESTS\ncheck("{algorithm_id}", {name}, hidden=True, points={HIDDEN_POINTS})\n'
              "### END HIDDEN TESTS",
              dict(test, grade_id=f"{name}_hidden", points=HIDDEN_POINTS)),
    ]
    return {"cells": cells, "nbformat": 4, "nbformat_minor": 5,
            "metadata": {"kernelspec": {"display_name": "Python 3 (ipykernel)", "language": "python",
                                        "name": "python3"}, "language_info": {"name": "python"}}}


def _split(algorithm_id: str) -> tuple[str, str]:
    if not isinstance(algorithm_id, str) or algorithm_id.count(".") != 1:
        raise ValueError(f"algorithm_id must look like '<course>.<name>' (e.g. 'mycourse.gamma_correction'), "
                         f"got {algorithm_id!r}")
    namespace, name = algorithm_id.split(".")
    problem = registry.namespace_problem(namespace)
    if problem is not None:
        raise ValueError(f"algorithm_id {algorithm_id!r}: {problem}")
    if not name.isidentifier() or keyword.iskeyword(name) or name.startswith("_"):
        raise ValueError(f"algorithm_id {algorithm_id!r}: its name {name!r} must be a public Python identifier "
                         "(it is the function's and the module's name)")
    return namespace, name


def _declared_module(pyproject: Path, namespace: str) -> str:
    """The module the ``cvkit.algorithms`` entry point ``namespace`` of ``pyproject`` imports."""
    if tomllib is None:  # pragma: no cover - Python 3.10
        return namespace
    try:
        data = tomllib.loads(pyproject.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise ValueError(f"package_dir: cannot read {pyproject}: {error}") from None
    declared = data.get("project", {}).get("entry-points", {}).get(registry.ALGORITHMS_GROUP, {})
    if namespace not in declared:
        raise ValueError(
            f"package_dir: {pyproject} declares no entry point {namespace!r} in the group "
            f"{registry.ALGORITHMS_GROUP}: add\n[project.entry-points.\"{registry.ALGORITHMS_GROUP}\"]\n"
            f"{namespace} = \"{namespace}\"")
    return str(declared[namespace]).partition(":")[0]


def new_exercise(algorithm_id: str, package_dir: str | Path = ".", section: str = "1") -> list[Path]:
    """Write the files of a new exercise ``algorithm_id`` into the course package folder
    ``package_dir`` (see the module docstring).

    Parameters
    ----------
    algorithm_id : str
        ``"<course>.<name>"``: the course's namespace (its entry point's name, never a cvkit
        topic such as ``filters``) and the function's name.
    package_dir : str or Path
        The course package folder (made if missing). A ``pyproject.toml`` there must declare
        the entry point ``<course>`` in the group ``cvkit.algorithms``; without one, a minimal
        one is written.
    section : str
        The section of the course notes the exercise belongs to (e.g. ``"2.12"``).

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    ValueError
        For a malformed id, a cvkit namespace, an empty section, or a ``pyproject.toml``
        without the entry point.
    FileExistsError
        When the exercise's module or cells exist already (nothing is written).
    """
    namespace, name = _split(algorithm_id)
    if not isinstance(section, str) or not section.strip() or '"' in section or "\\" in section:
        raise ValueError(f"section must be a non-empty string such as '2.12', got {section!r}")
    root = Path(package_dir)
    if root.exists() and not root.is_dir():
        raise ValueError(f"package_dir must be a folder, got the file {root}")
    pyproject = root / "pyproject.toml"
    module = _declared_module(pyproject, namespace) if pyproject.is_file() else namespace
    package = root.joinpath(*module.split("."))
    if package.with_suffix(".py").exists():
        raise ValueError(f"package_dir: the entry point {namespace!r} imports the single-file module {module}; the "
                         f"scaffold needs a package folder {package}/ whose __init__.py imports its exercise modules")
    files = {
        package / f"{name}.py": _MODULE.format(id=algorithm_id, namespace=namespace, name=name, section=section),
        root / f"{name}_cells.ipynb": json.dumps(exercise_cells(algorithm_id, name), indent=1,
                                                 ensure_ascii=False) + "\n",
    }
    existing = [str(path) for path in files if path.exists()]
    if existing:
        raise FileExistsError(f"not overwriting {', '.join(existing)}: choose another name or remove them first")
    if not pyproject.is_file():
        files[pyproject] = _PYPROJECT.format(distribution=f"{namespace}-exercises".replace("_", "-"),
                                             namespace=namespace)
    if not (package / "__init__.py").exists():
        files[package / "__init__.py"] = _INIT.format(namespace=namespace)
    package.mkdir(parents=True, exist_ok=True)
    for path, text in files.items():
        with path.open("x", encoding="utf-8") as handle:  # "x": never overwrite, even in a race
            handle.write(text)
    return sorted(files)
