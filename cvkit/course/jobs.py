"""The jobs of the parallel phase, run by local worker processes or Dask workers (picklable
top-level functions of plain data): execute a submission in the sandbox, decide its checks
with the trusted checks, write feedback pages.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any


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


def _notebook_names(files: dict[str, Any]) -> list[str]:
    return sorted(name for name in files if name.endswith(".ipynb"))


def execute_submission(project: Any, student: str, assignment: str, files: dict[str, bytes],
                       releases: dict[str, str] | None = None) -> ExecutedSubmission:
    """Run a submission's notebooks in the grading sandbox (picklable, for Dask).

    Each notebook is first sanitized here as nbgrader does (locked and test cells restored from
    its release notebook in ``releases``, outputs cleared), then executed by
    ``python -m cvkit.grading.execute`` inside a bubblewrap sandbox
    (:mod:`cvkit.grading.isolation`) that sees the Python environment read-only, a writable
    copy of this one submission and a private ``/tmp`` — no course folder, ``lectures/``,
    gradebook, salt or other submission, no network — under memory, CPU, process and
    file-size limits, and a wall-clock limit enforced from here. Grades are not decided here:
    checks in the kernel are no-ops; the notebook is run for the student's own figures.
    """
    from ..grading.execute import execute_in_sandbox, prepare

    releases = releases or {}
    prepared_files: dict[str, Any] = dict(files)
    jobs = []
    for name in _notebook_names(files):
        try:
            release = json.loads(releases[name]) if name in releases else None
            prepared_files[name] = json.dumps(prepare(json.loads(files[name]), release)).encode()
        except (ValueError, TypeError, AttributeError, KeyError) as error:
            return ExecutedSubmission(student, assignment, {}, False, f"{name}: not a notebook ({error})")
        jobs.append(name)
    notebooks, log = {}, ""
    for name in jobs:
        executed, note = execute_in_sandbox(prepared_files, name)
        log += f"{name}: {note}\n"
        if executed is None:
            return ExecutedSubmission(student, assignment, {}, False, log)
        notebooks[name] = executed
    return ExecutedSubmission(student, assignment, notebooks, bool(notebooks), log)


def _unreadable(files: dict[str, bytes], releases: dict[str, str]) -> list[str]:
    """Why a submission cannot be graded at all: notebooks that are not notebooks, or none of
    the assignment's notebooks submitted ([] when it can be graded)."""
    import nbformat

    notebook_names = _notebook_names(files)
    expected = _notebook_names(releases)
    problems = []
    for name in notebook_names:
        try:
            nb = json.loads(files[name])
            if not isinstance(nb, dict) or not isinstance(nb.get("cells"), list):
                raise ValueError("no list of cells")
            data = files[name]
            nbformat.reads(data.decode("utf-8") if isinstance(data, bytes) else data, as_version=4)
        except Exception as error:  # noqa: BLE001 - any unreadable file is a reason, never a crash
            problems.append(f"{name} is not a valid notebook ({type(error).__name__}: {str(error)[:120]})")
    if not any(name in expected for name in notebook_names):
        problems.append(f"no notebook of this assignment was submitted (expected {', '.join(expected) or 'none'}, "
                        f"got {', '.join(notebook_names) or 'none'})")
    return problems


def grade_submission(project: Any, student: str, assignment: str, files: dict[str, bytes], releases: dict[str, str],
                     sources: dict[str, str], salt: str, memory_mb: int = 3072) -> ExecutedSubmission:
    """Execute a submission (:func:`execute_submission`), then decide its checks with the
    trusted checks (:func:`cvkit.grading.nbgrader_plugins.apply_trusted_checks`, every line of
    student code again in the sandbox): the parallel phase of :meth:`Course.grade`, run by a
    local worker process or a Dask worker. ``sources`` are the instructor's source notebooks
    (JSON text by file name); ``salt`` is the course's grading salt, so Dask workers must be
    the instructor's own. A notebook that could not run is graded from its answers as
    submitted (sanitized as nbgrader does); one that is not a notebook at all comes back
    ``not_graded`` with the reason — never as a zero."""
    import nbformat

    from ..grading.execute import prepare
    from ..grading.nbgrader_plugins import apply_trusted_checks

    problems = _unreadable(files, releases)
    if problems:
        return ExecutedSubmission(student, assignment, {}, False, "; ".join(problems), not_graded="; ".join(problems))
    executed = execute_submission(project, student, assignment, files, releases)
    notebooks = dict(executed.notebooks)
    if not executed.ok:  # graded from the answers as submitted; the run's problem is reported
        for name in _notebook_names(files):
            release = json.loads(releases[name]) if name in releases else None
            notebooks[name] = json.dumps(prepare(json.loads(files[name]), release))
    verified = {}
    for name, text in notebooks.items():
        try:
            nb = nbformat.reads(text, as_version=4)
            source = json.loads(sources[name]) if name in sources else None
            apply_trusted_checks(nb, student=student, salt=salt, source_notebook=source, memory_mb=memory_mb)
            if not executed.ok:
                meta = dict(nb.metadata.get("cvkit", {}))
                meta["flags"] = list(meta.get("flags", [])) + [
                    "(notebook): the notebook could not run to the end in the sandbox; graded from its answers"]
                nb.metadata["cvkit"] = meta
        except Exception as error:  # noqa: BLE001 - the grader's own failure: not graded, with the reason
            reason = f"{name}: the grader failed on this notebook ({type(error).__name__}: {str(error)[:200]})"
            return ExecutedSubmission(student, assignment, {}, False, executed.log + "\n" + reason, not_graded=reason)
        verified[name] = nbformat.writes(nb)
    # nbgrader's cell-metadata check, here in the parallel phase rather than twice in the single
    # writer (about a fifth of its recording time): a notebook that fails it is recorded by the
    # writer's full pipeline instead, which refuses it and grades a repaired copy
    metadata_valid = all(_valid_cell_metadata(nbformat.reads(text, as_version=4)) for text in verified.values())
    return ExecutedSubmission(student, assignment, verified, True, executed.log, verified=metadata_valid)


def _valid_cell_metadata(nb: Any) -> bool:
    from nbgrader.preprocessors import CheckCellMetadata

    try:
        CheckCellMetadata().preprocess(nb, {})
    except Exception:  # noqa: BLE001 - any complaint means: let the writer's full pipeline decide
        return False
    return True


def feedback_submissions(root: str, db_url: str, project: str, pairs: list[tuple[str, str]]) -> None:
    """nbgrader feedback for (student, assignment) pairs of a course, in a worker process."""
    from .course import Course

    Course(Path(root), db_url, Path(project)).feedback(pairs)
