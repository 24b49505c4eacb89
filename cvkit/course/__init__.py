"""The nbgrader course pipeline behind ``cvkit course ...`` and ``cvkit demo``.

Small steps, each a plain nbgrader command run in the course folder where nbgrader has one
(so instructors can run any step by hand): ``generate_assignment`` → submissions → the
parallel phase (each submission executed in isolation, then its checks decided by the trusted
checks; several at once, or on a Dask cluster) → nbgrader's ``autograde`` as the single,
batched writer of the gradebook → ``generate_feedback`` → ``export``. Around nbgrader, cvkit
adds only what a course needs: a grading salt kept for regrading, per-student hidden cases, a
journal and a final audit so that no submission and no grade is lost, and a grade table with
the mistakes the checks recognised and the flags they raised.

One job per module:

- :mod:`.state` — :class:`~.state.CourseState`, at the bottom: the folder and its plan, salt,
  environment, nbgrader's configuration and API, the submissions as they lie, the journal;
  every module below works on one;
- :mod:`.notebook` — the notebook model: a submitted notebook parsed once
  (:class:`~.notebook.Submitted`: repair, preparation for execution), the cells' readers;
- :mod:`.course` — :class:`Course`, at the top: the state with the actions gathered (build,
  submit, grade, feedback, exports); the one object the command line uses;
- :mod:`.plan` — ``plan.toml``, the one source of truth for cvkit and plain nbgrader: due dates
  (into nbgrader's gradebook), the late-submission policy, which chapters are graded;
- :mod:`.samples` — sample submissions (solutions, typical mistakes, blank);
- :mod:`.jobs`, :mod:`.feedback` and :mod:`.parallel` — the parallel phase: its picklable
  jobs (:func:`execute_submission`, :func:`grade_submission`, :func:`feedback_submissions`)
  and their driving on local processes or Dask;
- :mod:`.trusted` and :mod:`.nbgrader_plugins` — the checks of a notebook's test cells decided
  outside the student's kernel, in the sandbox, and cvkit's steps in nbgrader's pipelines;
- :mod:`.safety` — feedback pages with nothing executable from the student;
- :mod:`.similarity` — answers compared across the class, in groups;
- :mod:`.writer`, :mod:`.journal` and :mod:`.stamps` — the single writer of the gradebook
  (not-graded submissions, flags for the formgrader; it never runs student code: repairs are
  graded in worker processes) and its bookkeeping (journal with the due date and checks each
  grade was decided under, not-graded list, flags);
- :mod:`.received` — when a submission was received: trusted data (the instructor's list,
  nbgrader's exchange, cvkit's own records), never the student's ``timestamp.txt``;
- :mod:`.results` and :mod:`.exports` — scores, mistakes and flags per exercise, the audit,
  the grade table, the CSV exports and the similarity report;
- :mod:`.progress` — each phase's count and time left;
- :mod:`.hub` — the course on JupyterHub: what ``cvkit hub init`` writes (the hub, nbgrader's
  exchange, the course folders), what ``cvkit hub check`` verifies, and what the exchange tells
  the instructor at grading time (hand-ins not collected, hand-ins without their secret).

Local parallel grading uses worker processes forked from a ``forkserver`` (a fresh interpreter
that imported what they need once): a script that calls :meth:`Course.grade` needs the usual
``if __name__ == "__main__":`` guard.
"""
from ..sandbox.startup import skip_unused_schema_grammars

skip_unused_schema_grammars()  # 1.4 s of CPU per grading process (see cvkit.sandbox.startup)

from .course import PACKAGE_DIR, Course, project_root  # noqa: E402
from .exports import format_table  # noqa: E402
from .feedback import feedback_submissions  # noqa: E402
from .jobs import ExecutedSubmission, execute_submission, grade_submission  # noqa: E402
from .results import ExerciseScore  # noqa: E402
from .samples import SAMPLE_STUDENTS, SOLUTION_BEGIN, SOLUTION_END, solution_sources, typical_mistakes  # noqa: E402
from .writer import JobResult  # noqa: E402

__all__ = [
    "Course", "JobResult", "ExecutedSubmission", "ExerciseScore", "execute_submission", "grade_submission",
    "feedback_submissions", "format_table", "solution_sources", "typical_mistakes", "project_root",
    "SAMPLE_STUDENTS", "SOLUTION_BEGIN", "SOLUTION_END", "PACKAGE_DIR",
]
