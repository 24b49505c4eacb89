"""cvkit's plugins for nbgrader (configured in ``autograders/nbgrader_config.py``).

- :class:`TrustedChecks` — an autograde preprocessor placed after execution: it decides every
  ``check(...)`` of the test cells outside the student's kernel (:mod:`cvkit.course.trusted`)
  and replaces those cells' outputs by the trusted report and partial credit, which is what
  nbgrader then records (:func:`cvkit.course.trusted.apply_trusted_checks`, which the parallel
  phase of ``cvkit course grade`` calls directly, outside nbgrader's pipeline).
- :class:`LatePenalty` — nbgrader's late-submission plugin with the policies of ``plan.toml``
  (``[late]``: none, zero, points per started hour).
- :class:`SaveAutoGradesAtOnce` — nbgrader's ``SaveAutoGrades`` with a notebook's grades and
  comments recorded in one transaction.
- :class:`HideHiddenTests` — a feedback preprocessor: students see the results of the hidden
  tests, never their source.
- :class:`SanitizeStudentContent` and :class:`SafeFeedbackExporter` (from
  :mod:`cvkit.course.safety`) — feedback pages without anything executable from the student,
  with MathJax served from the pages' folder.
"""
from __future__ import annotations

import json
from pathlib import Path

from nbgrader.plugins import LateSubmissionPlugin
from nbgrader.preprocessors import NbGraderPreprocessor, SaveAutoGrades
from traitlets import Bool, Dict, Enum, Float, Int, Unicode

from .safety import SafeFeedbackExporter, SanitizeStudentContent  # noqa: F401  (re-exported for the config)
from .trusted import apply_trusted_checks, hide_hidden_tests


MISSING_SALT = (
    "cvkit refuses to grade without a grading salt: the hidden cases would be drawn from the public practice "
    "seed, which every student can reproduce. `cvkit course grade` makes one (<course folder>/.grading_salt, "
    "readable by its owner only); or write a secret of your own there, e.g. "
    "`python3 -c \"import secrets; print(secrets.token_hex(16))\" > .grading_salt && chmod 600 .grading_salt`, "
    "and keep it for regrading (nbgrader_config.py reads it into TrustedChecks.salt)")


class MissingSalt(RuntimeError):
    """Raised by :class:`TrustedChecks` when the course has no grading salt."""


class TrustedChecks(NbGraderPreprocessor):
    """Replace the outputs of test cells by verdicts computed outside the student's kernel.

    Refuses (:class:`MissingSalt`) to grade without ``salt``: hidden cases drawn from the
    public practice seed would be known to every student."""

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
        if not self.salt.strip():
            raise MissingSalt(MISSING_SALT)
        flags = apply_trusted_checks(nb, student=student, salt=self.salt, source_notebook=source_nb,
                                     memory_mb=self.memory_mb)
        for flag in flags:
            self.log.warning("cvkit flag for %s: %s", student, flag)
        return nb, resources

    def preprocess_cell(self, cell, resources, index):  # pragma: no cover - whole-notebook preprocessor
        return cell, resources


class LatePenalty(LateSubmissionPlugin):
    """nbgrader's late-submission plugin, with the policies of ``plan.toml``'s ``[late]`` table
    (:class:`cvkit.course.plan.LatePolicy`; set by :func:`cvkit.course.plan.configure_nbgrader`
    as ``AssignLatePenalties.plugin_class``).

    nbgrader calls it for each notebook of a submission whose timestamp (``timestamp.txt``) is
    after the assignment's due date, and keeps the penalty between 0 and the notebook's score.
    """

    policy = Enum(("none", "zero", "per_hour"), default_value="none",
                  help="none: no penalty; zero: a late notebook scores 0; "
                       "per_hour: points_per_hour for every started hour late").tag(config=True)
    points_per_hour = Float(1.0, help="points taken per started hour late (policy per_hour)").tag(config=True)

    def late_submission_penalty(self, student_id: str, score: float, total_seconds_late: float) -> float | None:
        """The penalty of a notebook ``total_seconds_late`` seconds late that scored ``score``.

        Returns
        -------
        float or None
            None for no penalty; ``score`` for ``zero``; for ``per_hour``,
            ``points_per_hour × ⌈hours late⌉``, at most ``score``.
        """
        if total_seconds_late <= 0 or self.policy == "none":
            return None
        if self.policy == "zero":
            return score
        hours = -(-float(total_seconds_late) // 3600.0)
        return min(float(score), hours * float(self.points_per_hour))


class _OneTransaction(NbGraderPreprocessor):
    """The cell-by-cell pass of :class:`SaveAutoGradesAtOnce`, inside nbgrader's own
    ``SaveAutoGrades.preprocess`` (which opens ``self.gradebook`` and calls it as its parent's
    ``preprocess``): nbgrader's per-cell commits become flushes, and the notebook is committed
    once at the end, or rolled back whole if a cell fails."""

    def preprocess(self, nb, resources):
        gradebook = getattr(self, "gradebook", None)
        session = getattr(gradebook, "db", None)
        if session is None:  # not inside SaveAutoGrades' open gradebook (another nbgrader): as nbgrader does
            return super().preprocess(nb, resources)
        session.commit = session.flush  # shadows the method on this session only, for this pass
        try:
            nb, resources = super().preprocess(nb, resources)
        except BaseException:
            session.rollback()
            raise
        finally:
            del session.commit
        session.commit()
        return nb, resources


class SaveAutoGradesAtOnce(SaveAutoGrades, _OneTransaction):
    """nbgrader's ``SaveAutoGrades`` (the same score, comment and "needs manual grade" for every
    cell, by nbgrader's own code), with a notebook's grades and comments written in **one
    transaction** instead of one commit per cell (about 50 per chapter notebook, each a
    synchronous write of the gradebook file, after which every loaded row is read again): a
    notebook's grades are recorded whole or not at all — an interrupted run never leaves a
    notebook half recorded — and the single writer spends less on each."""


class PlanExtensions(NbGraderPreprocessor):
    """The plan's per-student extensions (``[[extension]]`` of ``plan.toml``) into nbgrader's
    gradebook, before ``AssignLatePenalties`` (set by :func:`cvkit.course.plan.configure_nbgrader`).

    nbgrader keeps an extension per submission (``SubmittedAssignment.extension``) and counts a
    submission late only after the due date plus its extension; its formgrader shows it. This
    step makes the recorded extension the plan's for the notebook's student and assignment (and
    removes one the plan no longer gives), so the late penalty, the gradebook and the table agree.
    """

    enabled = Bool(True).tag(config=True)
    extensions = Dict(help="'student/assignment' → the student's own due date, 'YYYY-MM-DD HH:MM:SS' (UTC)"
                      ).tag(config=True)

    def preprocess(self, nb, resources):
        import datetime as dt

        from nbgrader.api import Gradebook

        info = resources["nbgrader"]
        until = self.extensions.get(f"{info['student']}/{info['assignment']}")
        with Gradebook(info["db_url"]) as gradebook:
            submission = gradebook.find_submission(info["assignment"], info["student"])
            due = submission.assignment.duedate
            extension = None
            if until and due is not None:
                extension = max(dt.datetime.strptime(until, "%Y-%m-%d %H:%M:%S") - due, dt.timedelta(0)) or None
            if submission.extension != extension:
                submission.extension = extension
                gradebook.db.commit()
        return nb, resources


class SandboxedExecute(NbGraderPreprocessor):
    """nbgrader's *Execute* step, in the grading sandbox (:func:`cvkit.sandbox.notebook_run.execute_in_sandbox`).

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

        from ..sandbox.notebook_run import execute_in_sandbox
        from ..sandbox.isolation import collect_files

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


class DueDateNotice(NbGraderPreprocessor):
    """A step of ``generate_assignment``: the released notebook says, right after its title, when
    it is due — in the course's time zone and in UTC — and what a late hand-in costs (the plan's
    ``[late]`` policy), so students need not look it up elsewhere. Set by
    :func:`cvkit.course.plan.configure_nbgrader`; a chapter without a due date gets no notice.
    The cell is Markdown, read-only, marked ``metadata.cvkit.notice = "due"``."""

    enabled = Bool(True).tag(config=True)
    due = Dict(help="assignment → due date 'YYYY-MM-DD HH:MM:SS' (UTC)").tag(config=True)
    timezone = Unicode("UTC", help="the course's time zone (IANA name)").tag(config=True)
    late = Unicode("", help="what a late hand-in costs, in a sentence").tag(config=True)

    def preprocess(self, nb, resources):
        import datetime as dt

        import dateutil.tz
        from nbformat.v4 import new_markdown_cell

        due = self.due.get(resources.get("nbgrader", {}).get("assignment", ""))
        if not due:
            return nb, resources
        moment = dt.datetime.strptime(due, "%Y-%m-%d %H:%M:%S").replace(tzinfo=dt.timezone.utc)
        zone = self.timezone if self.timezone.upper() not in ("UTC", "GMT", "Z") else "UTC"
        local = moment.astimezone(dateutil.tz.gettz(zone) or dt.timezone.utc)
        when = f"{local:%A %-d %B %Y, %H:%M} {zone}" + ("" if zone == "UTC" else f" ({moment:%H:%M} UTC)")
        text = (f"**Due: {when}.** {self.late} An extension your instructor gave you personally counts instead "
                "of this date.").replace("  ", " ")
        cell = new_markdown_cell(text, metadata={"cvkit": {"notice": "due"}, "editable": False, "deletable": False})
        cell.pop("id", None)
        at = 1 if nb.cells and nb.cells[0].cell_type == "markdown" else 0
        nb.cells.insert(at, cell)
        if nb.nbformat_minor >= 5:
            import uuid

            cell["id"] = f"cvkit-due-{uuid.uuid4().hex[:8]}"
        return nb, resources


def late_policy_sentence(policy: str, points_per_hour: float) -> str:
    """What a late hand-in costs, for the released notebook (:class:`DueDateNotice`)."""
    if policy == "zero":
        return "A notebook handed in late scores zero."
    if policy == "per_hour":
        points = f"{points_per_hour:g} point{'s' * (points_per_hour != 1)}"
        return f"A late hand-in loses {points} for every started hour after it (never more than it scored)."
    return "A late hand-in is accepted without a penalty."


class WaitingForInstructor(NbGraderPreprocessor):
    """A step of ``generate_feedback`` (after ``GetGrades``): the grade cells that still wait for a
    hand mark (nbgrader's ``needs_manual_grade``), as ``resources["cvkit_waiting"]`` (grade id →
    points), so that the page says "waiting for your instructor" where nbgrader's template would
    print a score of 0 the student has not earned (:class:`~cvkit.course.safety.SafeFeedbackExporter`)."""

    enabled = Bool(True).tag(config=True)

    def preprocess(self, nb, resources):
        from nbgrader.api import Gradebook, MissingEntry

        info = resources.get("nbgrader", {})
        waiting: dict[str, float] = {}
        try:
            with Gradebook(info["db_url"]) as gradebook:
                notebook = gradebook.find_submission_notebook(info["notebook"], info["assignment"], info["student"])
                waiting = {g.name: float(g.max_score) for g in notebook.grades if g.needs_manual_grade}
        except (KeyError, MissingEntry):
            pass
        resources["cvkit_waiting"] = waiting
        return nb, resources


class HideHiddenTests(NbGraderPreprocessor):
    """In feedback, show the hidden tests' results but not their source."""

    enabled = Bool(True).tag(config=True)

    def preprocess_cell(self, cell, resources, index):
        if cell.cell_type == "code" and "### BEGIN HIDDEN TESTS" in cell.source:
            cell.source = hide_hidden_tests(cell.source)
        return cell, resources


