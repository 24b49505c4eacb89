"""cvkit's plugins for nbgrader (configured in ``autograders/nbgrader_config.py``).

- :class:`TrustedChecks` — an autograde preprocessor placed after execution: it decides every
  ``check(...)`` of the test cells outside the student's kernel (:mod:`cvkit.grading.trusted`)
  and replaces those cells' outputs by the trusted report and partial credit, which is what
  nbgrader then records. Flags from the static scan go into the notebook's metadata
  (``metadata.cvkit.flags``) for the grade export.
- :class:`HideHiddenTests` — a feedback preprocessor: students see the results of the hidden
  tests, never their source.
- :class:`SanitizeStudentContent` and :class:`SafeFeedbackExporter` (from
  :mod:`cvkit.grading.safety`) — feedback pages without anything executable from the student,
  with MathJax served from the pages' folder.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from nbformat import NotebookNode
from nbformat.v4 import new_output
from nbgrader.preprocessors import NbGraderPreprocessor
from nbgrader.utils import is_grade, is_solution
from traitlets import Bool, Int, Unicode

from .report import MIME_TYPE
from .safety import SafeFeedbackExporter, SanitizeStudentContent  # noqa: F401  (re-exported for the config)
from .trusted import grade_notebook, hide_hidden_tests

TRUSTED_VARIABLE = "CVKIT_TRUSTED_GRADING"


def _cell_node(cell: Any) -> NotebookNode:
    """nbgrader's cell tests read ``cell.metadata``: a cell's JSON dict is wrapped, not copied."""
    return cell if isinstance(cell, NotebookNode) else NotebookNode(metadata=cell.get("metadata") or {})


def is_test_cell(cell: Any) -> bool:
    """True for a test cell: graded by nbgrader and not an answer, by nbgrader's own rule
    (:func:`nbgrader.utils.is_grade` and not :func:`nbgrader.utils.is_solution`).

    Parameters
    ----------
    cell : NotebookNode or dict
        A notebook cell, as nbformat reads it or as its JSON dict.

    Returns
    -------
    bool
    """
    node = _cell_node(cell)
    return bool(is_grade(node) and not is_solution(node))


def is_answer_cell(cell: Any) -> bool:
    """True for an answer cell (nbgrader's ``solution`` cells: code or written answers), by
    :func:`nbgrader.utils.is_solution`; ``cell`` is a NotebookNode or a cell's JSON dict."""
    return bool(is_solution(_cell_node(cell)))


def _bundle(report) -> dict:
    bundle = {"text/plain": report.text(), MIME_TYPE: json.loads(json.dumps(report.to_dict(), default=str))}
    try:
        bundle["text/html"] = report._repr_html_()
    except Exception:  # a report that cannot draw its images still says what is wrong
        pass
    return bundle


class TrustedChecks(NbGraderPreprocessor):
    """Replace the outputs of test cells by verdicts computed outside the student's kernel."""

    enabled = Bool(True).tag(config=True)
    salt = Unicode("", help="grading salt of the hidden cases (keep it for regrading)").tag(config=True)
    source_directory = Unicode("", help="folder of the instructor's source notebooks").tag(config=True)
    memory_mb = Int(3072, help="address-space limit of the isolated worker, in MiB").tag(config=True)

    def preprocess(self, nb, resources):
        info = resources.get("nbgrader", {})
        student = info.get("student", "student")
        source_nb = None
        if self.source_directory and info.get("assignment") and info.get("notebook"):
            path = Path(self.source_directory) / info["assignment"] / f"{info['notebook']}.ipynb"
            if path.exists():
                source_nb = json.loads(path.read_text())
        flags = apply_trusted_checks(nb, student=student, salt=self.salt or "practice", source_notebook=source_nb,
                                     memory_mb=self.memory_mb)
        for flag in flags:
            self.log.warning("cvkit flag for %s: %s", student, flag)
        return nb, resources

    def preprocess_cell(self, cell, resources, index):  # pragma: no cover - whole-notebook preprocessor
        return cell, resources


class SandboxedExecute(NbGraderPreprocessor):
    """nbgrader's *Execute* step, in the grading sandbox (:func:`cvkit.grading.execute.execute_in_sandbox`).

    Replaces nbgrader's ``Execute`` in ``Autograde.autograde_preprocessors`` so that even a
    plain ``nbgrader autograde`` never runs a student's notebook with the grader's rights. The
    notebook runs with the regular files of its folder (never links), and a notebook that
    cannot run to the end is left as submitted (outputs cleared): :class:`TrustedChecks`, which
    comes later, decides its grades in the sandbox either way.
    """

    enabled = Bool(True).tag(config=True)
    timeout = Int(900, help="wall-clock seconds for the whole notebook, enforced from outside").tag(config=True)

    def preprocess(self, nb, resources):
        import nbformat

        from .execute import execute_in_sandbox
        from .isolation import collect_files

        name = f"{resources.get('unique_key') or 'notebook'}.ipynb"
        folder = (resources.get("metadata") or {}).get("path")
        files = {}
        if folder:
            files, refused = collect_files(Path(folder))
            files = {k: v for k, v in files.items() if not k.endswith(".ipynb")}
        files[name] = nbformat.writes(nb).encode()
        text, log = execute_in_sandbox(files, name, wall_seconds=self.timeout)
        if text is None:
            self.log.warning("cvkit: %s could not run to the end in the sandbox: %s", name, log[-500:])
            return nb, resources
        return nbformat.reads(text, as_version=nbformat.NO_CONVERT), resources

    def preprocess_cell(self, cell, resources, index):  # pragma: no cover - whole-notebook preprocessor
        return cell, resources


class HideHiddenTests(NbGraderPreprocessor):
    """In feedback, show the hidden tests' results but not their source."""

    enabled = Bool(True).tag(config=True)

    def preprocess_cell(self, cell, resources, index):
        if cell.cell_type == "code" and "### BEGIN HIDDEN TESTS" in cell.source:
            cell.source = hide_hidden_tests(cell.source)
        return cell, resources


def apply_trusted_checks(nb, *, student: str, salt: str, source_notebook=None, memory_mb: int = 3072) -> list[str]:
    """Decide every check of ``nb`` (a NotebookNode) outside the student's kernel and put the
    verdicts in place: each test cell's outputs become the trusted reports and its credit
    (an error for a failed visible test, the partial credit of a hidden one), which is what
    nbgrader's ``SaveAutoGrades`` records. Returns the flags of the static scan, which also go
    into ``nb.metadata.cvkit``. Used by :class:`TrustedChecks` and by the parallel phase of
    :meth:`cvkit.course.Course.grade`."""
    grade = grade_notebook(nb, student=student, salt=salt, source_notebook=source_notebook, memory_mb=memory_mb)
    for cell in nb.cells:
        meta = cell.metadata.get("nbgrader", {})
        grade_id = meta.get("grade_id")
        if not (meta.get("grade") and not meta.get("solution")) or grade_id not in grade.reports:
            continue
        outputs = [new_output("display_data", data=_bundle(report)) for _, report in grade.reports[grade_id]]
        credit, reasons = grade.credit(grade_id, float(meta.get("points", 0)))
        hidden = any(call.hidden for call, _ in grade.reports[grade_id])
        if hidden:
            outputs.append(new_output("execute_result", data={"text/plain": repr(credit)},
                                      execution_count=cell.get("execution_count")))
        elif credit <= 0:
            message = "; ".join(reasons) or "failed"
            outputs.append(new_output("error", ename="AssertionError", evalue=message,
                                      traceback=[f"AssertionError: {message}"]))
        cell.outputs = outputs
    if not grade.sandboxed and not nb.metadata.get("cvkit", {}).get("unsandboxed_note"):
        from nbformat.v4 import new_markdown_cell

        nb.cells.insert(0, new_markdown_cell(
            "**⚠ Graded without the sandbox** (`cvkit course grade --no-sandbox`): your code ran with the "
            "grader's rights on the grading machine. Ask your instructor if this is unexpected."))
    cvkit_meta = dict(nb.metadata.get("cvkit", {}))
    cvkit_meta.update(trusted=True, flags=grade.flags, worker_problem=grade.worker_problem,
                      cell_errors=grade.cell_errors[:20], sandboxed=grade.sandboxed,
                      unsandboxed_note=not grade.sandboxed)
    nb.metadata["cvkit"] = cvkit_meta
    return list(grade.flags)


def trusted_grading_active() -> bool:
    """True inside a kernel run by the trusted autograder (checks are decided outside)."""
    return os.environ.get(TRUSTED_VARIABLE) == "1"
