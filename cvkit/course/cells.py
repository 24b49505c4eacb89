"""Cells of nbgrader notebooks as the course reads them: JSON dicts from the course folder.

Which cells are tests or answers is nbgrader's own rule (``nbgrader.utils``), through
:func:`cvkit.grading.nbgrader_plugins.is_test_cell` and
:func:`~cvkit.grading.nbgrader_plugins.is_answer_cell`.
"""
from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, Iterator, Mapping

from ..grading.runtime.cells import is_solution

#: the suffixes of an exercise's cells: ``gaussian_answer``, ``gaussian_visible``, ...
_CELL_SUFFIX = re.compile(r"_(answer|visible|hidden|test)$")
_GRADE_SUFFIX = re.compile(r"_(visible|hidden|test)$")


def cell_source(cell: Mapping[str, Any]) -> str:
    """A cell's source as one string (nbformat allows a list of lines)."""
    source = cell["source"]
    return source if isinstance(source, str) else "".join(source)


def grade_id(cell: Mapping[str, Any]) -> str | None:
    """The nbgrader grade id of a cell (None for a cell nbgrader does not track)."""
    return cell.get("metadata", {}).get("nbgrader", {}).get("grade_id")


def exercise_name(cell_id: str, *, answers: bool = True) -> str:
    """The exercise a cell belongs to: its grade id without ``_answer``/``_visible``/``_hidden``/
    ``_test`` (``answers=False``: an ``_answer`` suffix is kept, as for graded cells, whose
    names never end so)."""
    return (_CELL_SUFFIX if answers else _GRADE_SUFFIX).sub("", cell_id)


def _is_answer(cell: Mapping[str, Any]) -> bool:
    return bool(is_solution(cell))


def graded_layout(notebook: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(grade id, cell type) of every cell nbgrader tracks, in order: what a submission must
    keep of its release for nbgrader to record it."""
    return [(str(grade_id(cell)), str(cell.get("cell_type"))) for cell in notebook.get("cells", [])
            if grade_id(cell)]


def repaired_notebook(release: Mapping[str, Any], notebook: Mapping[str, Any]) -> dict[str, Any]:
    """The ``release`` notebook with the student's answers of ``notebook`` put back in: for a
    submission whose graded cells were deleted, duplicated or retyped so badly that nbgrader
    refuses it. Answer cells are matched by grade id (their source kept, their type the
    release's); code cells the student added come along after the answer cell they followed."""
    answers: dict[str, str] = {}
    added_after: dict[str | None, list[str]] = {}
    known = {cell_source(c).strip() for c in release["cells"]}
    last = None
    for cell in notebook.get("cells", []):
        cell_id = grade_id(cell)
        if _is_answer(cell) and cell_id and cell_id not in answers:
            answers[cell_id] = cell_source(cell)
            last = cell_id
        elif (not cell.get("metadata", {}).get("nbgrader", {}) and cell.get("cell_type") == "code"
              and cell_source(cell).strip() not in known):
            added_after.setdefault(last, []).append(cell_source(cell))

    def added(anchor: str | None) -> list[dict[str, Any]]:
        return [{"cell_type": "code", "source": source, "metadata": {}, "outputs": [], "execution_count": None}
                for source in added_after.get(anchor, [])]

    cells = []
    for cell in release["cells"]:
        cell_id = grade_id(cell)
        if _is_answer(cell) and cell_id in answers:
            cell = dict(cell, source=answers[str(cell_id)])
        cells.append(cell)
        if cell_id == "setup":
            cells += added(None)
        elif _is_answer(cell):
            cells += added(cell_id)
    return dict(release, cells=cells)


def cell_outputs(folder: Path) -> Iterator[tuple[str | None, Mapping[str, Any]]]:
    """(grade id or None, output) of every output of every cell of the notebooks in ``folder``
    (a hand-in's or an autograded submission's), skipping what cannot be read: the one walk the
    course's readers of reports (named mistakes, case verdicts, visible-test runs) share."""
    for path in sorted(folder.glob("*.ipynb")):
        try:
            cells = json.loads(path.read_text()).get("cells", [])
        except (OSError, ValueError, AttributeError):
            continue
        for cell in cells if isinstance(cells, list) else []:
            if not isinstance(cell, dict):
                continue
            cell_id = grade_id(cell)
            for output in cell.get("outputs", []) or []:
                if isinstance(output, dict):
                    yield cell_id, output
