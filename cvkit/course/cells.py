"""Cells of nbgrader notebooks as the course reads them: JSON dicts from the course folder.

Which cells are tests or answers is nbgrader's own rule (``nbgrader.utils``), through
:func:`cvkit.grading.nbgrader_plugins.is_test_cell` and
:func:`~cvkit.grading.nbgrader_plugins.is_answer_cell`.
"""
from __future__ import annotations

import re
from typing import Any, Mapping

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
