"""The jobs of the parallel phase, run by local worker processes or Dask workers (picklable
top-level functions of plain data): execute a submission in the sandbox, decide its checks
with the trusted checks, write feedback pages.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .notebook import REPAIRED_FLAG, Submitted, as_node, metadata_flags, prepare


@dataclass
class ExecutedSubmission:
    """A submission's notebooks after execution in isolation (JSON text by file name).

    ``verified`` is True when the trusted checks have already replaced the test cells'
    outputs by their verdicts (:func:`grade_submission`); the writer then only records."""

    student: str
    assignment: str
    notebooks: dict[str, str]
    ok: bool
    log: str = ""
    verified: bool = False
    not_graded: str = ""  # why this submission cannot be graded at all (never shown as a zero)
    repaired: list = field(default_factory=list)  # notebooks graded from a repaired copy
    flagged: dict = field(default_factory=dict)   # verified: notebook name -> it carries flags for the instructor


def _notebook_names(files: dict[str, Any]) -> list[str]:
    return sorted(name for name in files if name.endswith(".ipynb"))


def graded_names(files: dict[str, Any], releases: dict[str, Any] | None) -> list[str]:
    """The notebooks of a submission that are graded: those the release has (nbgrader records
    no other); every notebook when there is no release to compare with."""
    names = _notebook_names(files)
    return [name for name in names if name in releases] if releases else names


def extra_notebook_flags(files: dict[str, Any], releases: dict[str, Any] | None) -> list[str]:
    """A flag for each notebook of a submission that is not one of the release's: it is neither
    run nor checked (nbgrader would ignore it), and the instructor is told."""
    graded = set(graded_names(files, releases))
    return [f"(notebook): {name} is not a notebook of this assignment: not run and not graded"
            for name in _notebook_names(files) if name not in graded]


#: exceptions of a cell that mean the grading environment lacks something (a package, a file)
_ENVIRONMENT_ERRORS = ("ModuleNotFoundError", "ImportError", "FileNotFoundError")
_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")
_CELL_FRAME = re.compile(r"\bCell In\s*\[(\d+)\]")
_MISSING_PATH = re.compile(r"No such file or directory: '([^']+)'")


def _installed_folders() -> list[Path]:
    """The folders of the kit and of the installed packages: a file missing there is the
    environment's, never the student's."""
    import sysconfig

    import cvkit

    folders = [Path(cvkit.__file__).resolve().parent]
    for key in ("purelib", "platlib"):
        try:
            folders.append(Path(sysconfig.get_paths()[key]).resolve())
        except (KeyError, OSError):
            continue
    return list(dict.fromkeys(folders))


def environment_problems(executed: dict[str, Any], release: dict[str, Any] | None) -> list[str]:
    """What stopped cells of an executed notebook that is not the student's doing: a package
    that cannot be imported (``ModuleNotFoundError``, ``ImportError``) or a file of the kit or
    of an installed package that is missing (``FileNotFoundError`` for a path there).

    Only cells as released count (the set-up and demo cells: not an answer cell, and its source
    that of a cell of ``release``; with no release, only locked cells), and only when the error
    was raised by that cell's own code or the libraries it called (the last notebook frame of
    the traceback is the cell itself, not an answer the demo called).

    Parameters
    ----------
    executed : dict
        The notebook as executed in the sandbox (JSON).
    release : dict or None
        Its release notebook (JSON).

    Returns
    -------
    list of str
        One ``"<exception>: <first line of its message>"`` per cause, in the order met.
    """
    from ..grading.runtime.cells import cell_source, is_code, is_solution, nbgrader_metadata

    released = {cell_source(c) for c in (release or {}).get("cells", []) if is_code(c)}
    folders: list[Path] | None = None
    causes: list[str] = []
    for cell in executed.get("cells", []):
        if not is_code(cell) or is_solution(cell):
            continue
        as_released = (cell_source(cell) in released) if release is not None \
            else bool(nbgrader_metadata(cell).get("locked"))
        if not as_released:
            continue
        for output in cell.get("outputs", []):
            name = output.get("ename") if output.get("output_type") == "error" else None
            if name not in _ENVIRONMENT_ERRORS:
                continue
            frames = _CELL_FRAME.findall(_ANSI.sub("", "\n".join(map(str, output.get("traceback", [])))))
            if frames and frames[-1] != str(cell.get("execution_count")):
                continue  # raised in another cell's code (an answer the demo called)
            value = str(output.get("evalue", "")).strip()
            if name == "FileNotFoundError":
                found = _MISSING_PATH.search(value)
                if found is None:
                    continue
                folders = _installed_folders() if folders is None else folders
                path = Path(found.group(1))
                if not path.is_absolute() or not any(path.resolve().is_relative_to(f) for f in folders):
                    continue
            cause = f"{name}: {value.splitlines()[0] if value else ''}".rstrip(": ")[:300]
            if cause not in causes:
                causes.append(cause)
    return causes


def execute_submission(project: Any, student: str, assignment: str, files: dict[str, bytes],
                       releases: dict[str, str] | None = None) -> ExecutedSubmission:
    """Run a submission's notebooks in the grading sandbox (picklable, for Dask).

    Each notebook is first sanitized here as nbgrader does (locked and test cells restored from
    its release notebook in ``releases``, outputs cleared), then executed by
    ``python -m cvkit.sandbox.notebook_run`` inside a bubblewrap sandbox
    (:mod:`cvkit.sandbox.isolation`) that sees the Python environment read-only, a writable
    copy of this one submission and a private ``/tmp`` — no course folder, ``lectures/``,
    gradebook, salt or other submission, no network — under memory, CPU, process and
    file-size limits, and a wall-clock limit enforced from here. Grades are not decided here:
    checks in the kernel are no-ops; the notebook is run for the student's own figures.
    """
    release_notebooks = {name: json.loads(text) for name, text in (releases or {}).items()}
    submitted = {}
    for name in graded_names(files, releases):
        found = Submitted.parse(name, files[name], release_notebooks.get(name))
        if found.problem:
            return ExecutedSubmission(student, assignment, {}, False, f"{name}: not a notebook ({found.problem})")
        submitted[name] = found
    return _execute(files, {name: s.prepared(repair=False) for name, s in submitted.items()}, student, assignment)


def _execute(files: dict[str, bytes], prepared: dict[str, dict[str, Any]], student: str,
             assignment: str) -> ExecutedSubmission:
    """Execute the ``prepared`` notebooks (name → notebook) in the sandbox, with the
    submission's other files beside them (never its notebooks that are not graded)."""
    from ..sandbox.notebook_run import execute_in_sandbox

    box_files: dict[str, Any] = {name: data for name, data in files.items() if not name.endswith(".ipynb")}
    box_files.update({name: json.dumps(nb).encode() for name, nb in prepared.items()})
    notebooks, log = {}, ""
    for name in prepared:
        executed, note = execute_in_sandbox(box_files, name)
        log += f"{name}: {note}\n"
        if executed is None:
            return ExecutedSubmission(student, assignment, {}, False, log)
        notebooks[name] = executed
    return ExecutedSubmission(student, assignment, notebooks, bool(notebooks), log)


def grade_submission(project: Any, student: str, assignment: str, files: dict[str, bytes], releases: dict[str, str],
                     sources: dict[str, str], salt: str, memory_mb: int = 3072, repair: bool = False) -> ExecutedSubmission:
    """Execute a submission (:func:`execute_submission`), then decide its checks with the
    trusted checks (:func:`cvkit.course.trusted.apply_trusted_checks`, every line of
    student code again in the sandbox): the parallel phase of :meth:`Course.grade`, run by a
    local worker process or a Dask worker. ``sources`` are the instructor's source notebooks
    (JSON text by file name); ``salt`` is the course's grading salt, kept in this process
    (hidden cases are drawn here and sent into the sandbox one at a time), so Dask workers
    must be the instructor's own trusted machines (``docs/scale-out.md``). A notebook that
    could not run is graded from its answers as submitted (sanitized as nbgrader does); one
    that is not a notebook at all comes back ``not_graded`` with the reason — never as a zero.

    Each submitted notebook is parsed once, here (:meth:`~cvkit.course.notebook.Submitted.parse`),
    and its executed copy once when it comes back from the sandbox; the verdicts travel to the
    writer as the notebook's text, which nbgrader reads.

    A notebook nbgrader would refuse (:meth:`~cvkit.course.notebook.Submitted.needs_repair`:
    graded cells deleted, duplicated or retyped), or every notebook when ``repair``, is graded
    here from a repaired copy (:func:`~cvkit.course.notebook.repaired_notebook`: the release with
    the student's answers and added cells put back) and flagged: the student's code runs in
    this worker like any other submission's, never in the process that writes the gradebook.
    Only the release's notebooks are run and checked; any other is flagged
    (:func:`extra_notebook_flags`)."""
    import nbformat

    from .trusted import apply_trusted_checks

    release_notebooks = {name: json.loads(text) for name, text in releases.items()}
    submitted = {name: Submitted.parse(name, files[name], release_notebooks.get(name))
                 for name in graded_names(files, releases)}
    problems = [s.problem for s in submitted.values() if s.problem]
    expected = _notebook_names(releases)
    if not any(name in expected for name in _notebook_names(files)):
        problems.append(f"no notebook of this assignment was submitted (expected {', '.join(expected) or 'none'}, "
                        f"got {', '.join(_notebook_names(files)) or 'none'})")
    if problems:
        return ExecutedSubmission(student, assignment, {}, False, "; ".join(problems), not_graded="; ".join(problems))
    graded = {name: s.to_grade(repair) for name, s in submitted.items()}
    repairs = sorted(name for name, s in submitted.items() if s.repaired)
    prepared = {name: prepare(nb, submitted[name].release) for name, nb in graded.items()}
    executed = _execute(files, prepared, student, assignment)
    verified, flagged = {}, {}
    extra = extra_notebook_flags(files, releases)
    for name in submitted:
        try:
            if executed.ok:
                as_run = json.loads(executed.notebooks[name])
                environment = environment_problems(as_run, release_notebooks.get(name))
            else:  # graded from the answers as submitted; the run's problem is reported
                as_run, environment = prepared[name], []
            # nbformat.reads without the text: the same node (sources joined, transient data removed)
            nb = as_node(as_run)
            source = json.loads(sources[name]) if name in sources else None
            apply_trusted_checks(nb, student=student, salt=salt, source_notebook=source, memory_mb=memory_mb)
            if environment:
                nb.metadata["cvkit"] = dict(nb.metadata.get("cvkit", {}), environment=environment)
            notes = list(extra)
            if not executed.ok:
                notes.append("(notebook): the notebook could not run to the end in the sandbox; graded from its answers")
            if name in repairs:
                notes.append(REPAIRED_FLAG)
            if notes:
                meta = dict(nb.metadata.get("cvkit", {}))
                meta["flags"] = list(meta.get("flags", [])) + notes
                nb.metadata["cvkit"] = meta
        except Exception as error:  # noqa: BLE001 - the grader's own failure: not graded, with the reason
            reason = f"{name}: the grader failed on this notebook ({type(error).__name__}: {str(error)[:200]})"
            return ExecutedSubmission(student, assignment, {}, False, executed.log + "\n" + reason, not_graded=reason)
        verified[name] = nbformat.writes(nb)
        flagged[name] = bool(metadata_flags(nb.metadata.get("cvkit", {})))
    return ExecutedSubmission(student, assignment, verified, True, executed.log, verified=True, repaired=repairs,
                              flagged=flagged)


def payload(course: Any, student: str, assignment: str) -> tuple[Any, ...]:
    """Arguments of :func:`grade_submission` for one submission of ``course``: plain data only
    — everything a Dask worker needs besides cvkit's environment (the project path travels
    along but is never opened there: the release and source notebooks come as texts)."""
    def texts(folder: Path) -> dict[str, str]:
        return {str(p.relative_to(folder)): p.read_text() for p in sorted(folder.rglob("*.ipynb"))}

    return (str(course.project), student, assignment, course.submission_files(student, assignment),
            texts(course.root / "release" / assignment), texts(course.source_dir / assignment), course.salt())


def checks_fingerprints(sources: dict[str, dict[str, str]]) -> dict[str, str]:
    """The fingerprint of the checks that grade each assignment (:func:`~.stamps.checks_fingerprint`)
    here, from its source notebooks' texts (``{assignment: {file name: JSON text}}``): equal on
    two machines when they grade those notebooks with the same cvkit, checks and course packages."""
    import tempfile

    from .stamps import checks_fingerprint

    found: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix="cvkit-checks-") as scratch:
        for assignment, texts in sorted(sources.items()):
            folder = Path(scratch) / str(len(found))
            folder.mkdir()
            for name, text in texts.items():
                if "/" not in name:  # as the course reads them: the notebooks of the chapter's folder
                    (folder / name).write_text(text)
            found[assignment] = checks_fingerprint(folder.glob("*.ipynb"))
    return found


def sandbox_problem() -> str | None:
    """None when this machine grades in the sandbox (bubblewrap, and the grading worker inside
    it: :func:`cvkit.sandbox.session.require_worker`), else why not (checked once per process)."""
    from ..sandbox import isolation
    from ..sandbox.session import require_worker

    try:
        isolation.require()
        require_worker()
    except isolation.SandboxUnavailable as error:
        return str(error)
    return None


def worker_report(sources: dict[str, dict[str, str]]) -> dict[str, Any]:
    """What a Dask worker says before it grades (run on every worker by the instructor's
    process): whether it can grade in the sandbox (:func:`sandbox_problem`), and the
    fingerprints of its checks (:func:`checks_fingerprints`), to be compared with the
    instructor's; with its user, to name it in a message."""
    import getpass
    import socket

    try:
        user = getpass.getuser()
    except (KeyError, OSError):  # a uid with no name
        import os

        user = str(os.getuid())
    return {"sandbox": sandbox_problem(), "checks": checks_fingerprints(sources),
            "where": f"{user}@{socket.gethostname()}"}


def grade_on_worker(*job: Any) -> ExecutedSubmission:
    """:func:`grade_submission` of ``job`` (a :func:`payload`) on a Dask worker, once this
    worker is known to grade in the sandbox; else it raises
    :class:`~cvkit.sandbox.isolation.SandboxUnavailable` and the instructor's process grades
    the submission locally — never a class of "ended early" zeros from a worker that joined
    with a broken sandbox."""
    from ..sandbox.isolation import SandboxUnavailable

    problem = sandbox_problem()
    if problem:
        raise SandboxUnavailable(problem)
    return grade_submission(*job)


def _grade_job(job: tuple[Any, ...], repair: bool) -> ExecutedSubmission:
    project, student, assignment, files, releases, sources, salt = job[:7]
    return grade_submission(project, student, assignment, files, releases, sources, salt, repair=repair)


def grade_in_fresh_process(job: tuple[Any, ...], repair: bool = False) -> ExecutedSubmission:
    """:func:`grade_submission` of ``job`` (a :func:`payload`) in a worker process of its own
    (``spawn``): for the few submissions graded outside the parallel phase (a lost worker, a
    copy nbgrader refused), so that the process that writes the gradebook never runs, nor
    waits inside, a student's code. A worker that dies leaves the submission not graded,
    with the reason."""
    import concurrent.futures
    import multiprocessing

    student, assignment = job[1], job[2]
    try:
        with concurrent.futures.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
            return pool.submit(_grade_job, job, repair).result()
    except Exception as error:  # noqa: BLE001 - a lost worker: listed as not graded, never a zero
        reason = f"the grading worker was lost ({type(error).__name__}: {str(error)[:200]})"
        return ExecutedSubmission(student, assignment, {}, False, reason, not_graded=reason)
