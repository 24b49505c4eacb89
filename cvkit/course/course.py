"""The course, as the commands see it: :class:`Course`, the one object behind ``cvkit course ...``.

A :class:`Course` is a :class:`~cvkit.course.state.CourseState` (the folder, the plan, the salt,
nbgrader's settings, the submissions and the journal) with the course's actions gathered in
one place: build (nbgrader's ``generate_assignment``), submit, grade in parallel
(:mod:`.parallel`: the jobs of :mod:`.jobs` on workers, recorded by the single writer of
:mod:`.writer`), the feedback pages (:mod:`.feedback`), the results and exports
(:mod:`.results`, :mod:`.exports`) and the samples (:mod:`.samples`). It is the top of the
course: the commands import it; the course's own modules work on the state and never import it
(``tests/system/test_architecture.py``).
"""
from __future__ import annotations

import datetime as _dt
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable

from . import exports, feedback, jobs, parallel, received, results, samples
from .progress import Phase
from .state import PACKAGE_DIR, CourseState, made_by_cvkit, project_root, refused_student_ids
from .writer import JobResult, Writer

if TYPE_CHECKING:
    from .jobs import ExecutedSubmission
    from .results import ExerciseScore

__all__ = ["Course", "PACKAGE_DIR", "project_root", "made_by_cvkit", "refused_student_ids"]


class Course(CourseState):
    """An nbgrader course folder fed by the project's ``lectures/`` (or its own ``source/``):
    the state (:class:`~cvkit.course.state.CourseState`, same parameters) and the actions.
    """

    def __init__(self, root: Any = None, db_url: str | None = None, project: Any = None) -> None:
        super().__init__(root, db_url, project)
        self._writer = Writer(self)

    # ------------------------------------------------------------------ build / release
    def build(self, assignments: Iterable[str] | None = None, progress: bool = False) -> list[str]:
        """nbgrader's ``generate_assignment`` for each chapter (in this process, configured by the
        course's ``nbgrader_config.py``), after the gradebook's due dates are made the plan's."""
        chosen = list(assignments or self.assignments())
        missing = [a for a in (chosen if assignments else self.plan().ids()) if not (self.source_dir / a).is_dir()]
        if missing:
            raise FileNotFoundError(f"{self.plan().name} names {', '.join(missing)}, but {self.source_dir} has no such "
                                    f"chapter folder: add its notebook there (source/<chapter>/<chapter>.ipynb), or "
                                    f"take it out of the plan")
        self.claim_gradebook()
        self.sync_due_dates()
        if not chosen:
            return chosen
        api = self.nbgrader_api()
        with Phase("build", len(chosen), progress, unit="chapter") as bar:
            for assignment in chosen:
                bar.describe(f"build {assignment}")
                with warnings.catch_warnings(record=True):  # nbformat's advice to nbgrader (cell ids), not ours
                    outcome = api.generate_assignment(assignment, force=True, create=True)
                if not outcome.get("success"):
                    raise RuntimeError(f"nbgrader generate_assignment {assignment} failed:\n"
                                       f"{(outcome.get('error') or outcome.get('log') or '')[-3000:]}")
                bar.update()
        return chosen

    # ------------------------------------------------------------------ submissions
    def submit(self, student: str, assignment: str, notebooks: dict[str, dict[str, Any]],
               received_at: _dt.datetime | None = None) -> Path:
        """Place a submission (``{filename: notebook json}``) as nbgrader's collect would, and
        record when it was received (:mod:`.received`: in ``.cvkit/``, out of the student's
        folder; the ``timestamp.txt`` written here, as nbgrader's, is only a cross-check).

        Parameters
        ----------
        received_at : datetime, optional
            When the hand-in arrived, with a time zone (e.g. an LMS's upload time for an
            imported zip); default now. The late penalty is computed from it.
        """
        return received.place_submission(self, student, assignment, notebooks, received_at)

    def make_samples(self, assignment: str) -> list[str]:
        """Three sample submissions: complete (the solutions), typical mistakes, blank."""
        return samples.make_samples(self, assignment)

    # ------------------------------------------------------------------ autograde
    def is_graded(self, student: str, assignment: str) -> bool:
        """Graded already, from this very submission (an interrupted run resumes after it)."""
        return results.is_graded(self, student, assignment)

    def autograde_one(self, student: str, assignment: str) -> JobResult:
        """Execute one submission in isolation, decide its checks (in a worker process of its
        own, :func:`~cvkit.course.jobs.grade_in_fresh_process`), then record its trusted grades."""
        return self.record(jobs.grade_in_fresh_process(jobs.payload(self, student, assignment)))

    def record(self, executed: ExecutedSubmission) -> JobResult:
        """Record one executed submission (see :meth:`record_many`)."""
        return self.record_many([executed])[0]

    def repaired(self, student: str, assignment: str, name: str, notebook: dict[str, Any]) -> dict[str, Any]:
        """The release notebook with the student's answers put back in: for a submission whose
        graded cells were deleted, duplicated or retyped so badly that nbgrader refuses it.
        Answer cells are matched by grade id (their source kept, their type restored); cells
        the student added come along after the answer cell they followed."""
        return self._writer.repaired(student, assignment, name, notebook)

    def record_many(self, batch: list[ExecutedSubmission], repair: bool = False) -> list[JobResult]:
        """The single writer: nbgrader's own autograde, without execution, on executed
        notebooks (one nbgrader run per assignment for the whole batch); only this process
        writes the gradebook, and it never runs student code: notebooks whose checks were not
        decided yet, or that nbgrader refuses (then from a repaired copy), are graded first in a
        worker process of their own. Never raises for a submission: what cannot be recorded is
        listed as not graded, with the reason."""
        return self._writer.record_many(batch, repair)

    def grade(
        self,
        assignments: Iterable[str] | None = None,
        workers: int = 2,
        scheduler: str | None = None,
        progress: bool = False,
        regrade: bool | Iterable[str] = False,
        batch: int | None = None,
        sandbox: bool = True,
    ) -> list[JobResult]:
        """Autograde every submission, then write feedback and the CSV exports.

        Every line of student code runs in the operating-system sandbox
        (:mod:`cvkit.sandbox.isolation`); when it cannot be made, this raises
        :class:`~cvkit.sandbox.isolation.SandboxUnavailable` before grading anything, with how
        to install it. ``sandbox=False`` (``--no-sandbox``, one trusted machine only) grades
        with resource limits alone and marks every such grade in the table, the exports and
        the feedback.

        The parallel phase (:func:`~cvkit.course.grade_submission`: execution in isolation,
        then the trusted checks) runs in ``workers`` local processes, or on the workers of the
        Dask distributed ``scheduler`` (they need cvkit's environment and bubblewrap, never this
        course folder; a scheduler that cannot be reached, has no workers, or whose workers
        would grade otherwise raises :class:`~cvkit.course.parallel.ClusterUnavailable` before
        anything is graded: ``docs/scale-out.md``). Results
        come back to this process, which alone writes the gradebook, in batches of ``batch``
        submissions (default ``max(2, workers)``). Local workers get a few submissions at a
        time, so that the feedback pages of each recorded batch are written by the workers
        between grading jobs instead of all at the end. Submissions graded before from the
        same files are skipped unless ``regrade`` (True: all; or the assignments to regrade,
        e.g. after a due date or a check changed, see :meth:`outdated`). Submissions of
        chapters not in the plan are not graded (:meth:`outside_plan`). After grading, the
        similarity report of every graded assignment is written to ``exports/`` (a signal for
        the instructor, never a score change). ``progress`` shows each phase with a count and
        the time left. Local workers are forked from a ``forkserver`` that imported nbgrader
        and cvkit once (:func:`~cvkit.course.parallel.worker_context`): a script that calls
        this needs the usual ``if __name__ == "__main__":`` guard.
        """
        return parallel.grade(self, assignments, workers=workers, scheduler=scheduler, progress_bar=progress,
                              regrade=regrade, batch=batch, sandbox=sandbox)

    def refresh(self, progress: bool = False) -> list[tuple[str, str]]:
        """Bring the feedback pages and the exports up to the gradebook without grading anything:
        after marking written answers in the formgrader, the page of every submission whose marks
        changed is written again, ``.cvkit/marks.log`` records the marks, and the CSV exports are
        written (:mod:`cvkit.course.marks`). Returns the (student, assignment) pages written."""
        return parallel.refresh(self, progress)

    def feedback(self, submissions: Iterable[tuple[str, str]], bar: Phase | None = None) -> None:
        """nbgrader's ``generate_feedback`` (in this process) for these (student, assignment)
        pairs: HTML pages with the trusted reports, hidden tests' source removed (``bar``
        counts the pages written)."""
        feedback.write_feedback(self, submissions, bar)

    # ------------------------------------------------------------------ results
    def audit(self, jobs: Iterable[tuple[str, str]]) -> list[tuple[str, str]]:
        """Submissions with no autograded notebook or no grade in the gradebook."""
        return results.audit(self, jobs)

    def scores(self, assignment: str) -> dict[str, list[ExerciseScore]]:
        """Per student, per exercise: score, maximum, and the mistakes the checks named."""
        return results.scores(self, assignment)

    def table(self, assignment: str) -> str:
        """The grade table of one assignment, not-graded submissions and unsandboxed grading
        included (see :func:`~cvkit.course.format_table`)."""
        return exports.table(self, assignment)

    def export(self, progress: bool = False) -> Path:
        """All grades as CSV: nbgrader's ``exports/grades.csv`` (one row per submission) and
        cvkit's ``exports/exercises.csv`` (one row per exercise, with the mistakes the checks
        recognised, the problems, and the tampering flags for the instructor)."""
        return exports.export(self, progress)

    def similarity(self, assignments: Iterable[str] | None = None, progress: bool = False) -> Path:
        """The similarity report of ``assignments`` (default: every assignment of the plan with
        submissions): ``exports/similarity.csv`` and ``exports/similarity.html``, answers compared
        across students and with the reference and the instructor's solution
        (:func:`cvkit.course.similarity.report`) and gathered into groups of similar answers
        (:func:`cvkit.course.similarity.groups`; the CSV has one row per student of a group). A
        signal for the instructor, never a score change. Returns the CSV's path."""
        return exports.export_similarity(self, assignments, progress)

