"""The single writer of the gradebook: nbgrader's own ``autograde``, without execution.

Only the instructor's process writes the gradebook. Executed submissions come back from the
parallel phase (:mod:`cvkit.course.parallel`) and are recorded here in batches, one nbgrader
run per assignment; a submission nbgrader refuses is graded from a repaired copy, and one that
cannot be recorded at all is listed as not graded with its reason (:class:`~.journal.Journal`).
"""
from __future__ import annotations

import json
import shutil
import subprocess
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from . import marks, received
from .notebook import REPAIRED_FLAG, repaired_notebook

if TYPE_CHECKING:
    from traitlets.config import Config

    from .state import CourseState
    from .jobs import ExecutedSubmission



@dataclass
class JobResult:
    """One autograde run of one student's submission of one assignment."""

    student: str
    assignment: str
    returncode: int
    attempts: int = 1
    log: str = ""
    executed: bool = True  # False: the notebook could not run, the raw submission was graded
    not_graded: str = ""   # why it could not be graded at all (listed so, never as a zero)

    @property
    def ok(self) -> bool:
        return self.returncode == 0


def _recording_settings(config: Config, verified: bool) -> dict[str, Any]:
    """nbgrader settings of the writer's autograde run. Notebooks verified in the parallel phase
    (checks decided, cell metadata validated) skip nbgrader's CheckCellMetadata, which they have
    passed; nbconvert validates each notebook once after its preprocessors instead of after each."""
    from nbgrader.converters import Autograde
    from nbgrader.preprocessors import CheckCellMetadata

    settings: dict[str, Any] = {"Exporter.optimistic_validation": True}
    if verified:
        for name in ("sanitize_preprocessors", "autograde_preprocessors"):
            configured = config.Autograde.get(name) if name in config.Autograde else None
            steps = configured if configured is not None else Autograde.class_traits()[name].default()
            settings[f"Autograde.{name}"] = [step for step in steps if step is not CheckCellMetadata]
    return settings


class Writer:
    """Records executed submissions of ``course`` in its gradebook (see the module docstring)."""

    def __init__(self, course: CourseState) -> None:
        self.course = course
        self.journal = course.journal
        self.flagged_here: set[tuple[str, str]] = set()  # submissions this writer flagged after nbgrader

    def _flag(self, student: str, assignment: str, note: str) -> None:
        """A flag in the autograded notebooks of a submission (:meth:`~.journal.Journal.add_flag`),
        remembered for the gradebook's "Flagged?" (:meth:`flag_in_gradebook`)."""
        self.journal.add_flag(student, assignment, note)
        self.flagged_here.add((student, assignment))

    def record_many(self, batch: list[ExecutedSubmission], repair: bool = False) -> list[JobResult]:
        """See :meth:`Course.record_many`."""
        try:
            return self._record_many(batch, repair)
        except Exception as error:  # noqa: BLE001 - isolate the submission that breaks the writer
            if len(batch) > 1:
                return [r for e in batch for r in self.record_many([e], repair=repair)]
            executed = batch[0]
            return [self.record_not_graded(executed.student, executed.assignment,
                                           f"the grader could not record it ({type(error).__name__}: {str(error)[:200]})")]

    def _record_many(self, batch: list[ExecutedSubmission], repair: bool) -> list[JobResult]:
        from .jobs import grade_in_fresh_process, payload

        results = []
        groups: dict[str, list[ExecutedSubmission]] = {}
        for executed in batch:  # one nbgrader run per assignment
            if not executed.not_graded and (not (executed.verified and executed.ok)
                                            or (repair and not executed.repaired)):
                # checks not decided yet (a lost worker, a caller's raw submission) or refused by
                # nbgrader: graded (from a repaired copy when refused) in a worker process of
                # its own — the student's code never runs in the process that writes the gradebook
                executed = grade_in_fresh_process(payload(self.course, executed.student, executed.assignment),
                                                  repair=repair)
            if executed.not_graded:
                results.append(self.record_not_graded(executed.student, executed.assignment, executed.not_graded))
                continue
            groups.setdefault(executed.assignment, []).append(executed)
        for assignment, group in sorted(groups.items()):
            done = self._autograde(assignment, group)
            if done.returncode != 0 and len(group) > 1:  # isolate the submission that fails
                results += [r for e in group for r in self.record_many([e], repair=repair)]
                continue
            if done.returncode != 0 and not repair:
                # nbgrader refuses the notebook (graded cells deleted, duplicated, retyped in a
                # way the worker did not see): grade the student's answers in a repaired copy
                results += self.record_many(group, repair=True)
                continue
            if done.returncode != 0:  # not even a repaired copy: not graded, with nbgrader's reason
                reason = (done.stderr or done.stdout or "nbgrader could not record it").strip().splitlines()[-1][:300]
                results += [self.record_not_graded(e.student, assignment, f"nbgrader refused it: {reason}")
                            for e in group]
                continue
            results += self._recorded(assignment, group, repair, done)
        return results

    def _autograde(self, assignment: str, group: list[ExecutedSubmission]) -> subprocess.CompletedProcess:
        """One nbgrader autograde run over ``group`` (staged in ``.cvkit/staging``), as a
        completed process (its log and error) for the journal and the retries. Every notebook
        carries its verdicts (decided in a worker): nbgrader only records, nothing is executed
        or checked here. Notebooks that are not the release's are not staged."""
        course = self.course
        staging = course.root / ".cvkit" / "staging"
        shutil.rmtree(staging, ignore_errors=True)
        for executed in group:
            folder = staging / executed.student / assignment
            folder.mkdir(parents=True)
            # nbgrader reads the submission time from timestamp.txt: the trusted one, never the student's
            trusted = received.received_time(course, executed.student, assignment)
            (folder / received.STAMP_FILE).write_text(received.nbgrader_timestamp(trusted.at))
            files = executed.notebooks
            for name, data in course.submission_files(executed.student, assignment).items():
                if name.partition("/")[0] == received.STAMP_FILE or (name.endswith(".ipynb") and name not in files):
                    continue
                target = folder / name
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(files[name].encode() if name in files else data)

        students = [] if len(group) > 1 else ["--student", group[0].student]
        config = course.config()  # the course's configuration, loaded once
        api = course.nbgrader_api(**{
            "CourseDirectory.submitted_directory": str(staging), "SandboxedExecute.enabled": False,
            "ClearOutput.enabled": False, "TrustedChecks.enabled": False,
            **_recording_settings(config, True)})
        # nbgrader sets every marked answer "to mark" again: the marks are put back after it
        before = marks.snapshot(course, assignment, [e.student for e in group])
        try:
            outcome = api.autograde(assignment, group[0].student if len(group) == 1 else "*", force=True,
                                    create=True)
        except Exception as error:  # noqa: BLE001 - nbgrader's failure on one notebook must not stop the run
            outcome = {"success": False, "error": f"{type(error).__name__}: {error}"}
        if outcome.get("success"):
            for student, note in marks.restore(course, assignment, before, {e.student: e.notebooks for e in group}):
                self._flag(student, assignment, note)
        shutil.rmtree(staging, ignore_errors=True)
        return subprocess.CompletedProcess(["nbgrader", "autograde", assignment, *students],
                                           0 if outcome.get("success") else 1,
                                           outcome.get("log", ""), outcome.get("error", ""))

    def _recorded(self, assignment: str, group: list[ExecutedSubmission], repair: bool,
                  done: subprocess.CompletedProcess) -> list[JobResult]:
        """Journal, not-graded list and flags of a group nbgrader has recorded."""
        results = []
        for executed in group:
            log = (executed.log[-1500:] + "\n" + done.stdout + done.stderr)[-4000:]
            self.journal.set_not_graded(executed.student, assignment, None)
            for note in self.course.refused_files(executed.student, assignment):
                self._flag(executed.student, assignment, f"(notebook): {note}")
            when = received.received_time(self.course, executed.student, assignment)
            for flag in received.cross_check(self.course, executed.student, assignment, when):
                self._flag(executed.student, assignment, flag)
            # the collected timestamp.txt now says what nbgrader recorded (the student's file is kept)
            if received.settle_stamp(self.course.root, executed.student, assignment, when):
                self.course.forget_snapshot(executed.student, assignment)  # the journal hashes the folder as it is now
            if repair or executed.repaired:
                log += "\ngraded from a repaired copy: the submission's graded cells had been tampered with"
                self._flag(executed.student, assignment, REPAIRED_FLAG)
            results.append(JobResult(executed.student, assignment, done.returncode, 1, log, executed=executed.ok))
        pairs = [(executed.student, assignment) for executed in group]
        self.flag_in_gradebook(pairs, {(e.student, assignment): e.flagged for e in group if e.verified and e.flagged})
        self.journal.mark_graded(pairs, self.course.grading_stamps([assignment]))
        return results

    def flag_in_gradebook(self, pairs: list[tuple[str, str]],
                          known: dict[tuple[str, str], dict[str, bool]] | None = None) -> None:
        """Mark the notebooks that carry cvkit flags (:func:`~.results.notebook_flags`) as flagged
        in nbgrader's gradebook (``SubmittedNotebook.flagged``: the formgrader's "Flagged?"
        column). cvkit only ever sets the flag, never clears it: the instructor clears it in the
        formgrader once they have looked. ``known``: which notebooks of a submission carry flags, as
        the worker said (the autograded notebooks are read for the others)."""
        from nbgrader.api import Gradebook, MissingEntry

        from .results import notebook_flags

        flagged = []
        for student, assignment in pairs:
            said = (known or {}).get((student, assignment))
            if said is not None and (student, assignment) not in self.flagged_here:
                flagged += [(student, assignment, name[:-len(".ipynb")]) for name, yes in sorted(said.items()) if yes]
                continue
            flagged += [(student, assignment, path.stem) for path in
                        sorted((self.course.root / "autograded" / student / assignment).glob("*.ipynb"))
                        if notebook_flags(path)]
        if not flagged:
            return
        with Gradebook(self.course.db_url) as gradebook:
            for student, assignment, notebook in flagged:
                try:
                    gradebook.find_submission_notebook(notebook, assignment, student).flagged = True
                except MissingEntry:
                    continue
            gradebook.db.commit()

    def record_not_graded(self, student: str, assignment: str, reason: str) -> JobResult:
        """Keep a submission that cannot be graded visible as such: its reason in the journal
        of not-graded submissions (table, exports), and for the formgrader an entry in the
        gradebook with its notebooks flagged. No score is recorded for it."""
        refused = self.course.refused_files(student, assignment)
        if refused:
            reason += " (refused files: " + "; ".join(refused)[:300] + ")"
        self.journal.set_not_graded(student, assignment, reason)
        self.journal.mark_graded([(student, assignment)], self.course.grading_stamps([assignment]))
        try:
            from nbgrader.api import Gradebook, MissingEntry

            with Gradebook(self.course.db_url) as gb:
                gb.update_or_create_student(student)
                try:
                    submission = gb.find_submission(assignment, student)
                except MissingEntry:
                    submission = gb.add_submission(assignment, student)
                for notebook in submission.notebooks:
                    notebook.flagged = True
                gb.db.commit()
        except Exception:  # noqa: BLE001 - the table and the exports still say it
            pass
        return JobResult(student, assignment, 0, 1, f"not graded: {reason}", executed=False, not_graded=reason)

    def repaired(self, student: str, assignment: str, name: str, notebook: dict[str, Any]) -> dict[str, Any]:
        """See :meth:`Course.repaired`."""
        release = json.loads((self.course.root / "release" / assignment / name).read_text())
        return repaired_notebook(release, notebook)
