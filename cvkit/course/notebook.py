"""The course's notebook model: nbgrader notebooks as JSON dicts, and what the course does to them.

Every reader of a notebook in the course goes through here or through the cell rules of
:mod:`cvkit.grading.runtime.cells` (which cells are answers or tests — nbgrader's own rule, for
dicts and nbformat nodes alike —, a cell's source, its grade id):

- :class:`Submitted`: one submitted notebook, parsed once where it is collected, with its
  release; it knows whether nbgrader would refuse it (:meth:`Submitted.needs_repair`), its
  repaired copy and the copy prepared for execution, and travels in that form through the
  worker (:func:`cvkit.course.jobs.grade_submission`);
- :func:`prepare` (what nbgrader's sanitizing steps make of a notebook before execution),
  :func:`repaired_notebook`, :func:`graded_layout`;
- the readers of graded notebooks: :func:`read_graded` (a notebook reduced to what the course's
  readers use, parsed once a run within :func:`graded_read_once`), :func:`cell_outputs`,
  :func:`exercise_name`.
"""
from __future__ import annotations

import contextlib
import copy
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping

from ..grading.report import MIME_TYPE
from ..grading.runtime.cells import cell_source, grade_id, is_code, is_solution, is_test_cell, nbgrader_metadata

#: the flag of a notebook graded from its repaired copy (:meth:`Submitted.to_grade`)
REPAIRED_FLAG = "(notebook): graded cells were deleted, duplicated or retyped; graded from a repaired copy"

#: the suffixes of an exercise's cells: ``gaussian_answer``, ``gaussian_visible``, ...
_CELL_SUFFIX = re.compile(r"_(answer|visible|hidden|test)$")
_GRADE_SUFFIX = re.compile(r"_(visible|hidden|test)$")


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
        elif (not nbgrader_metadata(cell) and is_code(cell)
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


@dataclass(frozen=True)
class GradedCell:
    """What the course's readers take from one cell of a graded notebook."""

    grade_id: str | None
    #: the trusted grader's verdicts as data (``metadata.cvkit.report``), which it alone writes;
    #: None for every other cell
    report: Mapping[str, Any] | None
    #: the cell's outputs that carry a cvkit report, reduced to it (``data`` and ``metadata`` of
    #: :data:`cvkit.grading.report.MIME_TYPE`): the figures and text are never read back
    outputs: tuple[Mapping[str, Any], ...]


@dataclass(frozen=True)
class GradedNotebook:
    """A graded (or handed-in) notebook as the course's readers use it: its ``metadata.cvkit``
    (flags, sandbox, environment) and its cells' grade ids, verdicts and reports. Read with
    :func:`read_graded`."""

    metadata: Mapping[str, Any]
    cells: tuple[GradedCell, ...]


_graded_memo: dict[str, tuple[tuple[int, ...], GradedNotebook | None]] | None = None


@contextlib.contextmanager
def graded_read_once() -> Iterator[None]:
    """Within this block each graded notebook file is parsed once (:func:`read_graded`), however
    many readers ask for it — the exports, the item analysis, the class notes and the leaderboard
    each walk every autograded notebook of the course; a file that changed since is read again.
    What is kept is small (:class:`GradedNotebook`: no figures, no text outputs)."""
    global _graded_memo
    outer = _graded_memo
    _graded_memo = {} if outer is None else outer
    try:
        yield
    finally:
        _graded_memo = outer


def read_graded(path: Path) -> GradedNotebook | None:
    """The parts of the notebook at ``path`` the course's readers use, or None when it cannot be
    read (missing, not JSON, not a notebook). See :func:`graded_read_once`."""
    memo = _graded_memo
    if memo is None:
        return _parse_graded(path)
    try:
        stat = path.stat()
    except OSError:
        return None
    identity = (stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns)
    kept = memo.get(str(path))
    if kept is None or kept[0] != identity:
        kept = memo[str(path)] = (identity, _parse_graded(path))
    return kept[1]


def _parse_graded(path: Path) -> GradedNotebook | None:
    try:
        nb = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(nb, dict):
        return None
    meta = nb.get("metadata")
    meta = meta.get("cvkit") if isinstance(meta, dict) else None
    cells = nb.get("cells")
    graded = []
    for cell in cells if isinstance(cells, list) else []:
        if not isinstance(cell, dict):
            continue
        outputs = []
        for output in cell.get("outputs", []) or []:
            if not isinstance(output, dict):
                continue
            kept = {part: {MIME_TYPE: found[MIME_TYPE]} for part, found in
                    (("data", output.get("data")), ("metadata", output.get("metadata")))
                    if isinstance(found, dict) and MIME_TYPE in found}
            if kept:
                outputs.append(kept)
        cvkit_meta = cell.get("metadata")
        cvkit_meta = cvkit_meta.get("cvkit") if isinstance(cvkit_meta, dict) else None
        report = cvkit_meta.get("report") if isinstance(cvkit_meta, dict) else None
        graded.append(GradedCell(grade_id(cell), report if isinstance(report, dict) else None, tuple(outputs)))
    return GradedNotebook(meta if isinstance(meta, dict) else {}, tuple(graded))


def graded_notebooks(folder: Path) -> Iterator[GradedNotebook]:
    """The readable notebooks of ``folder`` (a submission's), in the order of their names."""
    for path in sorted(folder.glob("*.ipynb")):
        found = read_graded(path)
        if found is not None:
            yield found


def cell_outputs(folder: Path, *, trusted: bool = False) -> Iterator[tuple[str | None, Mapping[str, Any]]]:
    """(grade id or None, output) of every output that carries a cvkit report (the data and
    metadata of :data:`cvkit.grading.report.MIME_TYPE`, nothing else of it) of every cell of
    the notebooks in ``folder`` (a hand-in's or an autograded submission's), skipping what
    cannot be read: the one walk the course's readers of reports (named mistakes, case
    verdicts, visible-test runs) share. ``trusted``: only the outputs of the test cells the
    trusted grader wrote (those with its ``metadata.cvkit.report``, which it alone writes),
    never a report a student's own cell displayed."""
    for notebook in graded_notebooks(folder):
        for cell in notebook.cells:
            if trusted and cell.report is None:
                continue
            for output in cell.outputs:
                yield cell.grade_id, output


def metadata_flags(meta: Mapping[str, Any]) -> list[str]:
    """The flags for the instructor in a graded notebook's ``metadata.cvkit``: the static scan's
    and the worker's, grading without the sandbox, a worker's problem."""
    flags = [str(f) for f in meta.get("flags", [])]
    if meta.get("sandboxed") is False:
        flags.append("(notebook): GRADED WITHOUT THE SANDBOX (--no-sandbox)")
    if meta.get("worker_problem"):
        flags.append(f"(notebook): {meta['worker_problem']}")
    return flags


def prepare(notebook: Mapping[str, Any], release: Mapping[str, Any] | None) -> dict[str, Any]:
    """The notebook as nbgrader would execute it: locked and test cells restored from
    ``release`` (by grade id, as nbgrader's ``OverwriteCells`` does), the release's kernel,
    every output cleared. ``notebook`` is not modified."""
    nb = copy.deepcopy(dict(notebook))
    originals = {}
    if release is not None:
        for cell in release.get("cells", []):
            meta = nbgrader_metadata(cell)
            if meta.get("grade_id") and (meta.get("locked") or is_test_cell(cell)):
                originals[meta["grade_id"]] = cell
        kernelspec = release.get("metadata", {}).get("kernelspec")
        if kernelspec:
            nb.setdefault("metadata", {})["kernelspec"] = copy.deepcopy(kernelspec)
    for index, cell in enumerate(nb.get("cells", [])):
        original = originals.get(nbgrader_metadata(cell).get("grade_id"))
        if original is not None and not is_solution(cell):
            cell = nb["cells"][index] = dict(cell, source=original["source"], cell_type=original["cell_type"],
                                             metadata=copy.deepcopy(original.get("metadata", {})))
        if is_code(cell):
            cell["outputs"] = []
            cell["execution_count"] = None
        else:
            cell.pop("outputs", None)
            cell.pop("execution_count", None)
    return nb


def valid_cell_metadata(notebook: Mapping[str, Any]) -> bool:
    """Whether nbgrader's ``CheckCellMetadata`` accepts the notebook's cells."""
    import nbformat
    from nbgrader.preprocessors import CheckCellMetadata

    nb = notebook if isinstance(notebook, nbformat.NotebookNode) else nbformat.from_dict(notebook)
    try:
        CheckCellMetadata().preprocess(nb, {})
    except Exception:  # noqa: BLE001 - any complaint means: let the writer's full pipeline decide
        return False
    return True


def as_node(notebook: Mapping[str, Any]) -> Any:
    """The ``nbformat.NotebookNode`` (format 4) that ``nbformat.reads(text, as_version=4)`` gives for
    the text ``notebook`` was parsed from — sources joined, transient data removed, older formats
    converted — and the same exception for what it refuses, without parsing the text again.
    ``notebook`` is not modified (nbformat builds new nodes)."""
    import nbformat
    from nbformat import NBFormatError, versions
    from nbformat.reader import ValidationError, get_version

    major, minor = get_version(notebook)
    if major not in versions:
        raise NBFormatError("Unsupported nbformat version %s" % major)
    try:
        nb = versions[major].to_notebook_json(notebook, minor=minor)
    except AttributeError as e:
        raise ValidationError(f"The notebook is invalid and is missing an expected key: {e}") from None
    return nbformat.convert(nb, 4)


@dataclass
class Submitted:
    """One submitted notebook on its way to a grade: parsed once from the submitted file's
    text, with its release (``None`` when the assignment has none to compare with).

    ``problem`` says why the file is not a notebook at all (then ``notebook`` is ``None``)."""

    name: str
    notebook: dict[str, Any] | None
    release: dict[str, Any] | None
    problem: str = ""
    repaired: bool = field(default=False)

    @classmethod
    def parse(cls, name: str, data: bytes | str, release: Mapping[str, Any] | None) -> Submitted:
        """The one parse of a submitted notebook: JSON, a list of cells, and nbformat's schema
        (what nbgrader will read); a file that fails is kept with its ``problem``."""
        import nbformat

        try:
            text = data.decode("utf-8") if isinstance(data, bytes) else data
            notebook = json.loads(text)
            if not isinstance(notebook, dict) or not isinstance(notebook.get("cells"), list):
                raise ValueError("no list of cells")
            # what nbformat.reads(text, as_version=4) would refuse, without reading the text again
            as_node(notebook)  # what nbformat.reads(text, as_version=4) refuses
        except Exception as error:  # noqa: BLE001 - any unreadable file is a reason, never a crash
            return cls(name, None, dict(release) if release else None,
                       f"{name} is not a valid notebook ({type(error).__name__}: {str(error)[:120]})")
        return cls(name, notebook, dict(release) if release else None)

    def needs_repair(self) -> bool:
        """Whether nbgrader would refuse the notebook: its cell metadata fails nbgrader's check,
        or its graded cells (grade id and type, in order) are not the release's — deleted,
        duplicated or retyped."""
        assert self.notebook is not None
        if not valid_cell_metadata(self.notebook):
            return True
        return self.release is not None and graded_layout(self.notebook) != graded_layout(self.release)

    def to_grade(self, repair: bool) -> dict[str, Any]:
        """The notebook that is graded: the student's, or (``repair``, or when nbgrader would
        refuse it) the release with the student's answers put back (:func:`repaired_notebook`)."""
        assert self.notebook is not None
        self.repaired = repair or self.needs_repair()
        return repaired_notebook(self.release, self.notebook) if self.repaired and self.release else self.notebook

    def prepared(self, repair: bool) -> dict[str, Any]:
        """The notebook to execute: :meth:`to_grade`, sanitized as nbgrader does (:func:`prepare`)."""
        return prepare(self.to_grade(repair), self.release)
