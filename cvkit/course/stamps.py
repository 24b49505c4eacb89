"""What a grade depends on besides the submission: the due date, the late policy, the checks.

The journal (:mod:`.journal`) keeps, for every graded submission, the due date and the late
policy it was graded under (:func:`due_stamp`, :func:`late_stamp`) and a fingerprint of the
checks that graded it (:func:`checks_fingerprint`). When one changes — a due date or the
``[late]`` policy changed in ``plan.toml``, a check or the notebook's tests edited, cvkit
upgraded — ``cvkit course grade`` lists the submissions graded under the older one and offers
``cvkit course grade --regrade CHAPTER``.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import json
import sys
from pathlib import Path
from typing import Any, Iterable

__all__ = ["checks_fingerprint", "due_stamp", "late_stamp"]


def due_stamp(due: _dt.datetime | None) -> str | None:
    """How the journal writes a due date (ISO 8601, naive UTC; None for no due date)."""
    return due.isoformat(sep=" ") if due is not None else None


def late_stamp(policy: str, points_per_hour: float) -> str:
    """How the journal writes a late policy (``"none"``, ``"zero"``, ``"per_hour 0.5"``)."""
    return f"per_hour {points_per_hour:g}" if policy == "per_hour" else policy


def _modules_of(algorithm_id: str) -> set[str]:
    """The modules that define an algorithm's reference and its check (cases, mistakes, comparator)."""
    from .. import registry

    try:
        record = registry.get(algorithm_id)
        check = record.resolve_check()
    except Exception:  # noqa: BLE001 - an id the registry does not know: graded as missing, stamped by its name
        return set()
    parts: list[Any] = [record.reference, getattr(check, "hidden", None), getattr(check, "public", None),
                        getattr(check, "compare", None)]
    parts += [getattr(mistake, "function", None) for mistake in getattr(check, "mistakes", ())]
    names = set()
    for part in parts:
        if part is not None:
            names.add(getattr(part, "__module__", None) or type(part).__module__)
    names.discard("builtins")
    return names


def _file_digest(module: str) -> str:
    path = getattr(sys.modules.get(module), "__file__", None)
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest() if path else "-"
    except OSError:
        return "-"


def checks_fingerprint(notebooks: Iterable[Path]) -> str:
    """A fingerprint of what grades an assignment: the test cells of its source ``notebooks``
    (their source and points) and the source files of the modules that define the reference
    and the check of every algorithm they call, with cvkit's version.

    Parameters
    ----------
    notebooks : iterable of Path
        The assignment's source notebooks (``lectures/<assignment>/*.ipynb``).

    Returns
    -------
    str
        A hex digest; equal for the same tests and checks.
    """
    import cvkit

    from ..grading.runtime.cells import cell_source, is_test_cell, nbgrader_metadata
    from .trusted import check_calls

    digest = hashlib.sha256(f"cvkit {getattr(cvkit, '__version__', '?')}\n".encode())
    ids: set[str] = set()
    for path in sorted(notebooks):
        try:
            cells = json.loads(path.read_text()).get("cells", [])
        except (OSError, ValueError):
            cells = []
        for cell in cells:
            if not isinstance(cell, dict) or not is_test_cell(cell):
                continue
            source = cell_source(cell)
            digest.update(json.dumps([path.name, nbgrader_metadata(cell).get("points"), source]).encode())
            ids.update(call.algorithm_id for call in check_calls(source, ""))
    modules: set[str] = set()
    for algorithm_id in sorted(ids):
        digest.update(f"\n{algorithm_id}".encode())
        modules |= _modules_of(algorithm_id)
    for module in sorted(modules):
        digest.update(f"\n{module} {_file_digest(module)}".encode())
    return digest.hexdigest()
