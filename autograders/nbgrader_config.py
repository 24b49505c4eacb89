"""nbgrader configuration of the cvkit course.

The chapter notebooks in ``lectures/`` are the nbgrader *source*: ``lectures/chNN_topic/``
is the assignment ``chNN_topic``. Generated folders (release/, submitted/, autograded/,
feedback/) and the gradebook live next to this file (or in ``$CVKIT_COURSE_ROOT``) and are
never committed.

Environment overrides (set by ``cvkit course ...``, and by the ``nbgrader_config.py`` cvkit
writes in a course folder of its own, so that plain ``nbgrader`` commands run there work on it):
  CVKIT_COURSE_ROOT  course folder (default: this folder)
  CVKIT_SOURCE_DIR   source notebooks (default: ../lectures)
  CVKIT_DB_URL       any SQLAlchemy URL for the gradebook, e.g.
                     postgresql://grader:secret@localhost/cvkit (default: SQLite in the root)

The plan (``plan.toml`` in the course folder, else next to this file) is the one source of
truth for due dates and late penalties: every nbgrader command that loads this file makes the
gradebook's due dates the plan's and applies the plan's ``[late]`` policy
(:func:`cvkit.course.plan.configure_nbgrader`).
"""
import os
from pathlib import Path

c = get_config()  # noqa: F821  (provided by nbgrader when it loads this file)

HERE = Path(__file__).resolve().parent
ROOT = Path(os.environ.get("CVKIT_COURSE_ROOT") or HERE).resolve()

c.CourseDirectory.course_id = "cvkit-ipcv"  # the plan's [course] id replaces it (configure_nbgrader below)
c.CourseDirectory.root = str(ROOT)
c.CourseDirectory.source_directory = str(Path(os.environ.get("CVKIT_SOURCE_DIR") or HERE.parent / "lectures").resolve())
c.CourseDirectory.db_url = os.environ.get("CVKIT_DB_URL") or f"sqlite:///{ROOT / 'gradebook.db'}"
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

# Trusted grading (cvkit.grading.nbgrader_plugins): after the student's notebook has run, every
# check() of the test cells is decided again outside the student's kernel, in an isolated
# worker, and compared with the reference here; that verdict is what nbgrader records.
# The grading salt is read once and removed from the environment, so the student's kernel
# (started later by nbgrader) never sees it; the kernel only knows that checks are decided
# elsewhere (CVKIT_TRUSTED_GRADING=1) and skips its own evaluation.
from nbconvert.preprocessors import ClearMetadataPreprocessor, CSSHTMLHeaderPreprocessor  # noqa: E402
from nbgrader.preprocessors import (  # noqa: E402
    AssignLatePenalties, CheckCellMetadata, GetGrades, IgnorePattern, LimitOutput, SaveAutoGrades,
)

from cvkit.course.plan import configure_nbgrader  # noqa: E402
from cvkit.grading.nbgrader_plugins import (  # noqa: E402
    HideHiddenTests, SafeFeedbackExporter, SandboxedExecute, SanitizeStudentContent, TrustedChecks,
)
from cvkit.grading.safety import mathjax_post_convert_hook  # noqa: E402

# plan.toml → nbgrader: the course id (its [course] id: the folder of nbgrader's exchange on a
# hub, see docs/deploy-jupyterhub.md), the gradebook's due dates (Assignment.duedate, what autograde and the
# formgrader use for late submissions) and the late penalties (AssignLatePenalties.plugin_class)
configure_nbgrader(c, ROOT, HERE.parent, c.CourseDirectory.source_directory, c.CourseDirectory.db_url,
                   c.CourseDirectory.course_id)

# made by `cvkit course grade` (readable by its owner only); kept for regrading. Without a
# salt, TrustedChecks refuses to grade (hidden cases from the public practice seed would be
# known to every student) and says how to make one
_salt_file = ROOT / ".grading_salt"
c.TrustedChecks.salt = os.environ.pop("CVKIT_GRADING_SALT", "") or (
    _salt_file.read_text().strip() if _salt_file.exists() else "")
c.TrustedChecks.source_directory = c.CourseDirectory.source_directory
os.environ["CVKIT_TRUSTED_GRADING"] = "1"
# nbgrader's own Execute would run the student's notebook with the grader's rights: a plain
# `nbgrader autograde` uses cvkit's SandboxedExecute instead (the same step, in the sandbox)
c.Autograde.autograde_preprocessors = [
    SandboxedExecute, IgnorePattern, ClearMetadataPreprocessor, TrustedChecks, LimitOutput, SaveAutoGrades,
    AssignLatePenalties, CheckCellMetadata,
]
# cvkit's verdicts travel as data in metadata (each test cell's metadata.cvkit.report, the
# notebook's metadata.cvkit: flags, sandbox) and the grade table reads them there: leave
# ClearMetadataPreprocessor disabled (nbconvert's default), or keep "cvkit" in its
# preserve_cell_metadata_mask and preserve_nb_metadata_mask

# Feedback pages (cvkit.grading.safety): nothing the student controls can run in them (outputs,
# Markdown, attachments, metadata are cleaned; only the trusted grader's reports keep their
# layout), and MathJax comes from a mathjax/ folder next to each page, never from the network.
# The mark schemes of open tasks stay with the instructor: nbgrader restores locked task cells
# from the source version when autograding, mark scheme included; SafeFeedbackExporter removes it.
c.GenerateFeedback.preprocessors = [GetGrades, SanitizeStudentContent, HideHiddenTests, CSSHTMLHeaderPreprocessor]
c.GenerateFeedback.exporter_class = SafeFeedbackExporter
c.GenerateFeedback.post_convert_hook = mathjax_post_convert_hook(ROOT / "feedback")
