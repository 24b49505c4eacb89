"""What a notebook cell is to nbgrader: an answer cell, a test cell, or neither.

The same answers as nbgrader's ``nbgrader.utils.is_grade`` and ``is_solution``, read from the
cell's ``metadata["nbgrader"]``, for plain dicts (JSON read with :mod:`json`) and nbformat's
``NotebookNode`` alike, without importing nbgrader: importing its package takes seconds (it
loads its server extensions), and the library and the grading sandbox do without it.

>>> answer = {"cell_type": "code", "metadata": {"nbgrader": {"solution": True, "grade": False}}}
>>> test = {"cell_type": "code", "metadata": {"nbgrader": {"solution": False, "grade": True}}}
>>> is_solution(answer), is_test_cell(answer), is_test_cell(test)
(True, False, True)
"""
from __future__ import annotations

from typing import Any, Mapping, TypeVar

_Default = TypeVar("_Default", str, None)

__all__ = ["nbgrader_metadata", "is_grade", "is_solution", "is_test_cell", "is_code", "cell_source", "grade_id",
           "cells_of"]


def nbgrader_metadata(cell: Any) -> dict:
    """A copy of the cell's nbgrader metadata (``{}`` when it has none).

    Parameters
    ----------
    cell : dict or nbformat.NotebookNode
        A notebook cell.

    Returns
    -------
    dict
        ``cell["metadata"]["nbgrader"]``, copied; empty for a cell nbgrader does not manage, and
        for metadata that is not a mapping (a student can edit the notebook's JSON).
    """
    metadata = cell.get("metadata", {}) if isinstance(cell, Mapping) else getattr(cell, "metadata", {})
    found = metadata.get("nbgrader", {}) if isinstance(metadata, Mapping) else {}
    return dict(found) if isinstance(found, Mapping) else {}


def is_grade(cell: Any) -> bool:
    """Whether nbgrader grades the cell (``grade: true``: a test cell, or a manually graded answer)."""
    return bool(nbgrader_metadata(cell).get("grade", False))


def is_solution(cell: Any) -> bool:
    """Whether the cell is an answer cell (``solution: true``), the student's to write."""
    return bool(nbgrader_metadata(cell).get("solution", False))


def is_test_cell(cell: Any) -> bool:
    """Whether the cell is an autograded test cell: graded, and not an answer."""
    return is_grade(cell) and not is_solution(cell)


def is_code(cell: Any) -> bool:
    """Whether the cell is a code cell (for a dict or an nbformat node)."""
    kind = cell.get("cell_type") if isinstance(cell, Mapping) else getattr(cell, "cell_type", None)
    return kind == "code"


def cells_of(notebook: Any) -> list[Any]:
    """A notebook's cells (a dict or an nbformat node); what is not a cell is left out, and a
    notebook without a list of cells has none (a student can edit the JSON)."""
    cells = notebook.get("cells") if isinstance(notebook, Mapping) else getattr(notebook, "cells", None)
    return [cell for cell in cells if isinstance(cell, Mapping)] if isinstance(cells, list) else []


def cell_source(cell: Any, default: _Default = "") -> str | _Default:  # type: ignore[assignment]
    """A cell's source as one string (nbformat allows a string or a list of lines): the one
    join every reader of notebooks uses. A source that is neither (a hand-edited file) gives
    ``default``."""
    source = cell.get("source", "") if isinstance(cell, Mapping) else getattr(cell, "source", "")
    if isinstance(source, str):
        return source
    if isinstance(source, list) and all(isinstance(part, str) for part in source):
        return "".join(source)
    return default


def grade_id(cell: Any) -> str | None:
    """The nbgrader grade id of a cell (None for a cell nbgrader does not track)."""
    found = nbgrader_metadata(cell).get("grade_id")
    return found if isinstance(found, str) and found else None
