"""Load a student's answers from another chapter notebook into the running kernel.

A later chapter sometimes builds on the functions a student wrote in an earlier one (Chapter 12
trains a small CNN on the layers of Chapter 10). Those functions live in the other notebook,
not in this kernel. :func:`load_answers` reads that notebook, runs its answer cells (the
nbgrader ``solution: true`` code cells) in a fresh namespace, so that their
``@student("<id>")`` registrations exist here, and returns the ids it registered. With
``cvkit.use("student")`` cvkit's pipelines then call the student's functions.

Whatever goes wrong (the notebook is absent, as in the grading sandbox, which holds only the
notebook being graded; an answer is still the released stub; a cell raises) ends in one
:class:`AnswersUnavailable` whose message is a single line, and nothing is left registered.

>>> from cvkit.grading.answers import AnswersUnavailable, load_answers
>>> try:
...     load_answers("no/such/notebook.ipynb")
... except AnswersUnavailable as why:
...     print(why)
cannot use your answers from no/such/notebook.ipynb: the notebook is not there
"""
from __future__ import annotations

import ast
import json
import re
from pathlib import Path
from typing import Iterable

from .. import registry
from .runtime.cells import cell_source, is_code, is_grade, is_solution, nbgrader_metadata

__all__ = ["AnswersUnavailable", "load_answers", "DEFAULT_NOTEBOOK"]

#: where nbgrader's release/fetch puts Chapter 10 relative to another chapter's folder
DEFAULT_NOTEBOOK = "../ch10_representations/ch10_representations.ipynb"

# nbgrader replaces a solution region by this; a cell that still holds it is not answered
_STUB = re.compile(r"#\s*YOUR CODE HERE\s*\n\s*raise\s+NotImplementedError\s*\(\s*\)")
_STUDENT_ID = re.compile(r"""@\s*(?:[A-Za-z_][\w.]*\.)?student\(\s*["']([^"']+)["']""")


class AnswersUnavailable(RuntimeError):
    """The answers could not be loaded; the message (one line) says why.

    Shown by IPython and JupyterLab as that single line, without a traceback."""

    def _render_traceback_(self) -> list[str]:
        return [f"\x1b[0;31mAnswersUnavailable\x1b[0m: {self}"]


def _setup_imports(cells: list[dict]) -> str:
    """The import statements of the notebook's locked set-up cells (IPython magics dropped)."""
    lines = []
    for cell in cells:
        if not is_code(cell) or not nbgrader_metadata(cell).get("locked") or is_grade(cell) \
                or is_solution(cell):
            continue
        text = "\n".join(line for line in cell_source(cell).splitlines() if not line.lstrip().startswith(("%", "!")))
        try:
            tree = ast.parse(text)
        except SyntaxError:
            continue
        lines += [ast.unparse(node) for node in tree.body if isinstance(node, (ast.Import, ast.ImportFrom))]
    return "\n".join(lines)


def _restore(snapshot: dict[str, tuple]) -> None:
    """Put the student provider back as it was (ids absent from the snapshot are removed)."""
    prov = registry.provider(registry.STUDENT)
    for algorithm_id in list(prov.functions):
        if algorithm_id not in snapshot:
            prov.remove(algorithm_id)
    for algorithm_id, (function, source) in snapshot.items():
        prov.functions[algorithm_id] = function
        prov.sources[algorithm_id] = source


def load_answers(path: str | Path = DEFAULT_NOTEBOOK, ids: Iterable[str] | None = None) -> list[str]:
    """Run the answer cells of another notebook so that its ``@student`` functions are registered.

    Parameters
    ----------
    path : str or Path
        The other notebook, relative to the working directory (a notebook's own folder in
        Jupyter). The default is Chapter 10 as nbgrader's release and fetch lay it out next to
        the other chapters.
    ids : iterable of str, optional
        The algorithm ids needed (``"nn.conv2d_forward"``, ...). Every one of them must be
        registered by an answer cell that is no longer the released stub; registrations of other
        ids made by the notebook are undone. By default every id the notebook registers is kept,
        and every one must be answered.

    Returns
    -------
    list of str
        The ids now registered from the notebook, sorted.

    Raises
    ------
    TypeError
        If ``path`` is not a path or ``ids`` is a single string.
    AnswersUnavailable
        With a one-line reason, when the notebook is absent or unreadable, an answer needed is
        missing or still a stub, or an answer cell raises. Nothing stays registered then.
    """
    if not isinstance(path, (str, Path)):
        raise TypeError(f"path must be a str or pathlib.Path, got {type(path).__name__}")
    if isinstance(ids, str):
        raise TypeError("ids must be an iterable of algorithm ids, not a single string; wrap it in a list")
    wanted = None if ids is None else list(dict.fromkeys(ids))
    if wanted is not None:
        for algorithm_id in wanted:
            if not isinstance(algorithm_id, str):
                raise TypeError(f"ids must hold strings, got {type(algorithm_id).__name__}")
    where = f"cannot use your answers from {path}"
    path = Path(path)
    if not path.is_file():
        raise AnswersUnavailable(f"{where}: the notebook is not there")
    try:
        cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise AnswersUnavailable(f"{where}: the notebook cannot be read ({type(exc).__name__})") from None

    answers = []   # (cell number, source, ids it registers, is a stub)
    for number, cell in enumerate(cells):
        if is_code(cell) and is_solution(cell):
            source = cell_source(cell)
            answers.append((number, source, _STUDENT_ID.findall(source), bool(_STUB.search(source))))
    declared = {i for _, _, found, _ in answers for i in found}
    stubs = sorted({i for _, _, found, stub in answers if stub for i in found})
    needed = sorted(declared) if wanted is None else wanted
    missing = [i for i in needed if i not in declared]
    if missing:
        raise AnswersUnavailable(f"{where}: no answer cell registers {', '.join(missing)}")
    unanswered = [i for i in needed if i in stubs]
    if unanswered:
        raise AnswersUnavailable(f"{where}: not answered yet: {', '.join(unanswered)}")

    prov = registry.provider(registry.STUDENT)
    snapshot = {i: (prov.functions[i], prov.sources[i]) for i in prov.functions}
    namespace: dict = {"__name__": f"cvkit_answers_{re.sub(r'[^0-9A-Za-z_]', '_', path.stem)}"}
    try:
        exec(compile(_setup_imports(cells), f"{path.name} (set-up imports)", "exec"), namespace)
    except Exception as exc:  # noqa: BLE001  (an import the notebook needs is missing here)
        _restore(snapshot)
        raise AnswersUnavailable(f"{where}: its set-up imports fail ({type(exc).__name__}: {exc})") from None
    for number, source, found, stub in answers:
        try:
            exec(compile(source, f"{path.name}, cell {number}", "exec"), namespace)
        except KeyboardInterrupt:
            _restore(snapshot)
            raise
        except BaseException as exc:  # noqa: BLE001  (a student's cell may raise anything)
            if found and not set(found) & set(needed):
                continue  # an answer this chapter does not use: its error is not ours to report
            _restore(snapshot)
            what = f"the cell of {', '.join(found)}" if found else "an answer cell"
            line = str(exc).splitlines()[0] if str(exc) else ""
            raise AnswersUnavailable(
                f"{where}: {what} (cell {number}) raises {type(exc).__name__}"
                + (f": {line}" if line else "")) from None

    keep = set(needed)
    registered = []
    for algorithm_id in list(prov.functions):
        new = algorithm_id not in snapshot or snapshot[algorithm_id][0] is not prov.functions[algorithm_id]
        if not new:
            continue
        if algorithm_id in keep:
            registered.append(algorithm_id)
        elif algorithm_id in snapshot:
            prov.functions[algorithm_id], prov.sources[algorithm_id] = snapshot[algorithm_id]
        else:
            prov.remove(algorithm_id)
    absent = [i for i in needed if i not in registered]
    if absent:
        _restore(snapshot)
        raise AnswersUnavailable(f"{where}: running its answer cells did not register {', '.join(absent)}")
    return sorted(registered)

