"""cvkit's nbgrader settings, in one function every course's ``nbgrader_config.py`` calls.

The checkout's ``autograders/nbgrader_config.py`` and the ``nbgrader_config.py`` of a course
folder of its own (``cvkit new course``) both call :func:`configure`, so a course needs nothing
of the checkout at grading time: plain ``nbgrader`` commands and the formgrader run in the
course folder work on that course, its ``source/``, its ``plan.toml`` and its gradebook.

Environment overrides (set by ``cvkit course ...`` for the nbgrader it runs):
  CVKIT_COURSE_ROOT  course folder
  CVKIT_SOURCE_DIR   source notebooks
  CVKIT_DB_URL       any SQLAlchemy URL for the gradebook, e.g.
                     postgresql://grader:secret@localhost/cvkit (default: SQLite in the root)

The plan (``plan.toml`` in the course folder, else the checkout's ``autograders/plan.toml``) is
the one source of truth for due dates and late penalties: every nbgrader command that loads the
configuration makes the gradebook's due dates the plan's and applies the plan's ``[late]``
policy (:func:`cvkit.course.plan.configure_nbgrader`).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

__all__ = ["configure"]


def configure(c: Any, root: str | os.PathLike[str], source: str | os.PathLike[str] | None = None,
              project: str | os.PathLike[str] | None = None) -> None:
    """Fill nbgrader's configuration ``c`` for the course in ``root``.

    Parameters
    ----------
    c : traitlets.config.Config
        What ``get_config()`` returns in ``nbgrader_config.py``.
    root : path
        The course folder (``$CVKIT_COURSE_ROOT`` overrides it).
    source : path, optional
        The source notebooks (``$CVKIT_SOURCE_DIR`` overrides it; default ``<root>/source``).
    project : path, optional
        A cvkit checkout whose ``autograders/plan.toml`` is the plan when the course folder has
        none (default: the course folder alone).
    """
    from nbconvert.preprocessors import CSSHTMLHeaderPreprocessor, ClearMetadataPreprocessor
    from nbgrader.preprocessors import (
        AssignLatePenalties, CheckCellMetadata, GetGrades, IgnorePattern, LimitOutput,
    )

    from .nbgrader_plugins import (
        HideHiddenTests, PlanExtensions, SafeFeedbackExporter, SandboxedExecute, SanitizeStudentContent,
        SaveAutoGradesAtOnce, TrustedChecks, WaitingForInstructor,
    )
    from .safety import mathjax_post_convert_hook
    from .plan import configure_nbgrader

    root = Path(os.environ.get("CVKIT_COURSE_ROOT") or root).resolve()
    source = Path(os.environ.get("CVKIT_SOURCE_DIR") or source or root / "source").resolve()
    c.CourseDirectory.course_id = "cvkit-ipcv"  # the plan's [course] id replaces it (configure_nbgrader below)
    c.CourseDirectory.root = str(root)
    c.CourseDirectory.source_directory = str(source)
    c.CourseDirectory.db_url = os.environ.get("CVKIT_DB_URL") or f"sqlite:///{root / 'gradebook.db'}"
    # only the notebooks are course material; never copy caches or checkpoints
    c.CourseDirectory.ignore = [".ipynb_checkpoints", "*.pyc", "__pycache__", "feedback", ".DS_Store"]

    # what students see where a solution was
    c.ClearSolutions.code_stub = {"python": "# YOUR CODE HERE\nraise NotImplementedError()"}
    c.ClearSolutions.text_stub = "YOUR ANSWER HERE"

    # autograding: a generous per-cell limit (notebooks run in well under a minute), and the
    # kernel's environment carries the grading salt and student id (see cvkit.grading.hidden_seed)
    c.Execute.timeout = int(os.environ.get("CVKIT_CELL_TIMEOUT", "180"))
    c.Execute.interrupt_on_timeout = True
    c.Autograde.create_student = True

    # plan.toml → nbgrader: the course id (its [course] id: the folder of nbgrader's exchange on a
    # hub, see docs/deploy-jupyterhub.md), the gradebook's due dates (Assignment.duedate, what
    # autograde and the formgrader use for late submissions) and the late penalties
    configure_nbgrader(c, root, Path(project) if project else root, source, c.CourseDirectory.db_url,
                       c.CourseDirectory.course_id)

    # Trusted grading (cvkit.course.nbgrader_plugins): after the student's notebook has run,
    # every check() of the test cells is decided again outside the student's kernel, in an
    # isolated worker, and compared with the reference; that verdict is what nbgrader records.
    # The grading salt (made by `cvkit course grade`, readable by its owner only, kept for
    # regrading) is read once and removed from the environment, so the student's kernel (started
    # later by nbgrader) never sees it; the kernel only knows that checks are decided elsewhere
    # (CVKIT_TRUSTED_GRADING=1) and skips its own evaluation. Without a salt, TrustedChecks
    # refuses to grade (hidden cases from the public practice seed would be known to every
    # student) and says how to make one.
    salt_file = root / ".grading_salt"
    c.TrustedChecks.salt = os.environ.pop("CVKIT_GRADING_SALT", "") or (
        salt_file.read_text().strip() if salt_file.exists() else "")
    c.TrustedChecks.source_directory = str(source)
    os.environ["CVKIT_TRUSTED_GRADING"] = "1"
    # nbgrader's own Execute would run the student's notebook with the grader's rights: a plain
    # `nbgrader autograde` uses cvkit's SandboxedExecute instead (the same step, in the sandbox).
    # cvkit's verdicts travel as data in metadata (each test cell's metadata.cvkit.report, the
    # notebook's metadata.cvkit: flags, sandbox) and the grade table reads them there: leave
    # ClearMetadataPreprocessor disabled (nbconvert's default), or keep "cvkit" in its
    # preserve_cell_metadata_mask and preserve_nb_metadata_mask
    c.Autograde.autograde_preprocessors = [
        SandboxedExecute, IgnorePattern, ClearMetadataPreprocessor, TrustedChecks, LimitOutput, SaveAutoGradesAtOnce,
        PlanExtensions, AssignLatePenalties, CheckCellMetadata,
    ]

    # Feedback pages (cvkit.course.safety): nothing the student controls can run in them
    # (outputs, Markdown, attachments, metadata are cleaned; only the trusted grader's reports
    # keep their layout), and MathJax comes from a mathjax/ folder next to each page, never from
    # the network. The mark schemes of open tasks stay with the instructor: nbgrader restores
    # locked task cells from the source version when autograding, mark scheme included;
    # SafeFeedbackExporter removes it.
    # Written answers and open tasks that wait for a hand mark say so (WaitingForInstructor), never "0".
    c.GenerateFeedback.preprocessors = [GetGrades, WaitingForInstructor, SanitizeStudentContent, HideHiddenTests,
                                        CSSHTMLHeaderPreprocessor]
    c.GenerateFeedback.exporter_class = SafeFeedbackExporter
    c.GenerateFeedback.post_convert_hook = mathjax_post_convert_hook(root / "feedback")
