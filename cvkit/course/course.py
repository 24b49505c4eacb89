"""The nbgrader course pipeline behind ``cvkit course ...`` and ``cvkit demo``.

Small steps, each a plain nbgrader command run in the course folder where nbgrader has one
(so instructors can run any step by hand): ``generate_assignment`` → submissions → the
parallel phase (each submission executed in isolation, then its checks decided by the trusted
checks; several at once, or on a Dask cluster) → nbgrader's ``autograde`` as the single,
batched writer of the gradebook → ``generate_feedback`` → ``export``. Around nbgrader, cvkit
adds only what a course needs: a grading salt kept for regrading, per-student hidden cases, a
journal and a final audit so that no submission and no grade is lost, and a grade table with
the mistakes the checks recognised and the flags they raised.

Local parallel grading uses worker processes started with ``spawn``: a script that calls
:meth:`Course.grade` needs the usual ``if __name__ == "__main__":`` guard.
"""
from __future__ import annotations

import concurrent.futures
import datetime as _dt
import hashlib
import json
import os
import re
import secrets
import shutil
import subprocess
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

from ..grading.isolation import collect_files

from ..grading.startup import skip_unused_schema_grammars

skip_unused_schema_grammars()  # 1.4 s of CPU per grading process (see cvkit.grading.startup)
from ..grading.report import MIME_TYPE

try:  # Python ≥ 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    tomllib = None

PACKAGE_DIR = Path(__file__).resolve().parent.parent
SOLUTION_BEGIN = "### BEGIN SOLUTION"
SOLUTION_END = "### END SOLUTION"
SAMPLE_STUDENTS = ("sample_complete", "sample_mistakes", "sample_blank")


def project_root(start: Path | None = None) -> Path:
    """The checkout holding ``lectures/`` and ``autograders/nbgrader_config.py``."""
    candidates = []
    here = Path(start or Path.cwd()).resolve()
    candidates += [here, *here.parents]
    candidates += [PACKAGE_DIR.parent]
    for folder in candidates:
        if (folder / "autograders" / "nbgrader_config.py").is_file() and (folder / "lectures").is_dir():
            return folder
    raise FileNotFoundError(
        "cannot find the cvkit project (a folder with lectures/ and autograders/nbgrader_config.py); "
        "run from a checkout of the project"
    )


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


@dataclass
class ExecutedSubmission:
    """A submission's notebooks after execution in isolation (JSON text by file name).

    ``verified`` is True when the trusted checks have already replaced the test cells'
    outputs by their verdicts (:func:`grade_submission`); the writer then only records."""

    student: str
    assignment: str
    notebooks: dict
    ok: bool
    log: str = ""
    verified: bool = False
    not_graded: str = ""  # why this submission cannot be graded at all (never shown as a zero)


def execute_submission(project, student: str, assignment: str, files: dict,
                       releases: dict | None = None) -> ExecutedSubmission:
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
    prepared_files = dict(files)
    jobs = []
    for name in sorted(n for n in files if n.endswith(".ipynb")):
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


def grade_submission(project, student: str, assignment: str, files: dict, releases: dict,
                     sources: dict, salt: str, memory_mb: int = 3072) -> ExecutedSubmission:
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

    notebook_names = sorted(n for n in files if n.endswith(".ipynb"))
    expected = sorted(n for n in releases if n.endswith(".ipynb"))
    problems = []
    for name in notebook_names:
        try:
            nb = json.loads(files[name])
            if not isinstance(nb, dict) or not isinstance(nb.get("cells"), list):
                raise ValueError("no list of cells")
            nbformat.reads(files[name].decode("utf-8") if isinstance(files[name], bytes) else files[name], as_version=4)
        except Exception as error:  # noqa: BLE001 - any unreadable file is a reason, never a crash
            problems.append(f"{name} is not a valid notebook ({type(error).__name__}: {str(error)[:120]})")
    if not any(name in expected for name in notebook_names):
        problems.append(f"no notebook of this assignment was submitted (expected {', '.join(expected) or 'none'}, "
                        f"got {', '.join(notebook_names) or 'none'})")
    if problems:
        return ExecutedSubmission(student, assignment, {}, False, "; ".join(problems), not_graded="; ".join(problems))
    executed = execute_submission(project, student, assignment, files, releases)
    notebooks = dict(executed.notebooks)
    if not executed.ok:  # graded from the answers as submitted; the run's problem is reported
        for name in notebook_names:
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


def _valid_cell_metadata(nb) -> bool:
    from nbgrader.preprocessors import CheckCellMetadata

    try:
        CheckCellMetadata().preprocess(nb, {})
    except Exception:  # noqa: BLE001 - any complaint means: let the writer's full pipeline decide
        return False
    return True


def _recording_settings(config, verified: bool) -> dict:
    """nbgrader settings of the writer's autograde run. Notebooks verified in the parallel phase
    (checks decided, cell metadata validated) skip nbgrader's CheckCellMetadata, which they have
    passed; nbconvert validates each notebook once after its preprocessors instead of after each."""
    from nbgrader.converters import Autograde
    from nbgrader.preprocessors import CheckCellMetadata

    settings: dict = {"Exporter.optimistic_validation": True}
    if verified:
        for name in ("sanitize_preprocessors", "autograde_preprocessors"):
            configured = config.Autograde.get(name) if name in config.Autograde else None
            steps = configured if configured is not None else Autograde.class_traits()[name].default()
            settings[f"Autograde.{name}"] = [step for step in steps if step is not CheckCellMetadata]
    return settings


def feedback_submissions(root, db_url, project, pairs) -> None:
    """nbgrader feedback for (student, assignment) pairs of a course, in a worker process."""
    Course(Path(root), db_url, Path(project)).feedback(pairs)


@dataclass
class ExerciseScore:
    name: str
    score: float
    max_score: float
    mistakes: list = field(default_factory=list)
    problems: list = field(default_factory=list)
    flags: list = field(default_factory=list)
    to_mark: bool = False  # a written question or open task not yet marked by hand (formgrader)


@dataclass
class Course:
    """An nbgrader course folder fed by the project's ``lectures/``.

    Parameters
    ----------
    root : path, optional
        Course folder (release/, submitted/, autograded/, feedback/, gradebook). Default the
        project's ``autograders/``. Another folder gets a small ``nbgrader_config.py`` that
        loads the project's configuration.
    db_url : str, optional
        SQLAlchemy URL of the gradebook (default SQLite ``gradebook.db`` in ``root``); use
        PostgreSQL when several graders write at once.
    """

    root: Path | None = None
    db_url: str | None = None
    project: Path | None = None

    def __post_init__(self):
        self.project = Path(self.project or project_root()).resolve()
        base = self.project / "autograders"
        self.root = Path(self.root or base).resolve()
        self.root.mkdir(parents=True, exist_ok=True)
        # graders only: the isolated student processes (user nobody) cannot look inside
        self.root.chmod(0o700)
        config = self.root / "nbgrader_config.py"
        if self.root != base and not config.exists():
            config.write_text(
                "# generated by cvkit: the project's nbgrader configuration, rooted here\n"
                f"load_subconfig({str(base / 'nbgrader_config.py')!r})  # noqa: F821\n"
            )
        self.db_url = self.db_url or os.environ.get("CVKIT_DB_URL") or f"sqlite:///{self.root / 'gradebook.db'}"

    # ------------------------------------------------------------------ environment
    @property
    def source_dir(self) -> Path:
        return self.project / "lectures"

    def plan(self) -> dict:
        path = self.project / "autograders" / "plan.toml"
        if tomllib is None or not path.exists():
            return {"assignment": [{"id": p.name} for p in sorted(self.source_dir.glob("ch*_*")) if p.is_dir()]}
        return tomllib.loads(path.read_text())

    def assignments(self) -> list[str]:
        """Assignment ids of the plan that have a source folder in ``lectures/``."""
        ids = [a["id"] for a in self.plan().get("assignment", [])]
        return [a for a in ids if (self.source_dir / a).is_dir()]

    def salt(self) -> str:
        """The grading salt of this course: made once, kept for reproducible regrading."""
        path = self.root / ".grading_salt"
        if not path.exists():
            path.write_text(secrets.token_hex(16))
            path.chmod(0o600)
        return path.read_text().strip()

    def env(self, student: str | None = None) -> dict:
        env = dict(os.environ)
        env.update(
            CVKIT_COURSE_ROOT=str(self.root),
            CVKIT_SOURCE_DIR=str(self.source_dir),
            CVKIT_DB_URL=self.db_url,
            CVKIT_GRADING_SALT=self.salt(),
            MPLBACKEND="Agg",
            OMP_NUM_THREADS="1",
            OPENBLAS_NUM_THREADS="1",
            MKL_NUM_THREADS="1",
        )
        if student is not None:
            env["CVKIT_STUDENT_ID"] = student
        bin_dir = str(Path(sys.executable).parent)
        env["PATH"] = bin_dir + os.pathsep + env.get("PATH", "")
        return env

    def nbgrader(self, *args: str, student: str | None = None, timeout: float | None = None) -> subprocess.CompletedProcess:
        """Run one nbgrader command in the course folder."""
        return subprocess.run(
            [sys.executable, "-m", "nbgrader", *args],
            cwd=self.root, env=self.env(student), capture_output=True, text=True, timeout=timeout,
        )

    _CONFIG_VARIABLES = ("CVKIT_COURSE_ROOT", "CVKIT_SOURCE_DIR", "CVKIT_DB_URL", "CVKIT_GRADING_SALT",
                         "CVKIT_CELL_TIMEOUT", "CVKIT_TRUSTED_GRADING")

    def nbgrader_api(self, **settings):
        """nbgrader's own API in this process, configured by the course's ``nbgrader_config.py``
        (read once, with the course's environment) and ``settings`` such as
        ``{"SandboxedExecute.enabled": False}``. In-process steps skip nbgrader's start-up (≈3 s a run)."""
        import copy

        from nbgrader.apps import NbGraderAPI
        from nbgrader.coursedir import CourseDirectory

        if getattr(self, "_nbgrader_config", None) is None:
            from traitlets.config.loader import PyFileConfigLoader

            saved = {k: os.environ.get(k) for k in self._CONFIG_VARIABLES}
            env = self.env()
            try:  # the config file reads (and pops) these; restore them for the rest of this process
                os.environ.update({k: env[k] for k in self._CONFIG_VARIABLES if k in env})
                self._nbgrader_config = PyFileConfigLoader("nbgrader_config.py", path=str(self.root)).load_config()
            finally:
                for key, value in saved.items():
                    if value is None:
                        os.environ.pop(key, None)
                    else:
                        os.environ[key] = value
        warnings.filterwarnings("ignore", message=r"Object of type <\w+> not in session")  # nbgrader + SQLAlchemy 2
        config = copy.deepcopy(self._nbgrader_config)
        for key, value in settings.items():
            section, name = key.rsplit(".", 1)
            config[section][name] = value
        return NbGraderAPI(coursedir=CourseDirectory(config=config), config=config)

    # ------------------------------------------------------------------ build / release
    def build(self, assignments: Iterable[str] | None = None, progress: bool = False) -> list[str]:
        """``nbgrader generate_assignment`` for each chapter; due dates from the plan."""
        chosen = list(assignments or self.assignments())
        plan = {a["id"]: a for a in self.plan().get("assignment", [])}
        for assignment in _progress(chosen, "build", progress):
            duedate = plan.get(assignment, {}).get("due")
            done = self.nbgrader("db", "assignment", "add", assignment, *( [f"--duedate={duedate}"] if duedate else []))
            if done.returncode != 0:
                raise RuntimeError(f"nbgrader db assignment add {assignment} failed:\n{done.stderr[-2000:]}")
            done = self.nbgrader("generate_assignment", assignment, "--force")
            if done.returncode != 0:
                raise RuntimeError(f"nbgrader generate_assignment {assignment} failed:\n{done.stderr[-3000:]}")
        return chosen

    def release_notebooks(self, assignment: str) -> list[Path]:
        return sorted((self.root / "release" / assignment).glob("*.ipynb"))

    # ------------------------------------------------------------------ submissions
    def submit(self, student: str, assignment: str, notebooks: dict[str, dict]) -> Path:
        """Place a submission (``{filename: notebook json}``) as nbgrader's collect would."""
        folder = self.root / "submitted" / student / assignment
        folder.mkdir(parents=True, exist_ok=True)
        for name, nb in notebooks.items():
            (folder / name).write_text(json.dumps(nb, indent=1))
        stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S.%f %Z")
        (folder / "timestamp.txt").write_text(stamp)
        return folder

    def submissions(self, assignments: Iterable[str] | None = None) -> list[tuple[str, str]]:
        """(student, assignment) of every submission folder holding a notebook (or what claims
        to be one: a link or an empty file is listed, and refused when it is graded)."""
        wanted = set(assignments) if assignments else None
        found = []
        for folder in sorted((self.root / "submitted").glob("*/*")):
            if folder.parent.is_symlink() or folder.is_symlink() or not folder.is_dir():
                continue
            if any(folder.glob("*.ipynb")) and (wanted is None or folder.name in wanted):
                found.append((folder.parent.name, folder.name))
        return found

    def make_samples(self, assignment: str) -> list[str]:
        """Three sample submissions: complete (the solutions), typical mistakes, blank."""
        source_nbs = {p.name: json.loads(p.read_text()) for p in sorted((self.source_dir / assignment).glob("*.ipynb"))}
        mistakes = typical_mistakes(self.project / "autograders" / "samples" / assignment)
        made = []
        for student in SAMPLE_STUDENTS:
            notebooks = {}
            for release in self.release_notebooks(assignment):
                nb = json.loads(release.read_text())
                source = source_nbs.get(release.name)
                if student != "sample_blank" and source is not None:
                    solutions = solution_sources(source)
                    for cell in nb["cells"]:
                        grade_id = cell.get("metadata", {}).get("nbgrader", {}).get("grade_id")
                        if not cell.get("metadata", {}).get("nbgrader", {}).get("solution"):
                            continue
                        if student == "sample_mistakes" and grade_id in mistakes:
                            cell["source"] = mistakes[grade_id]
                        elif grade_id in solutions:
                            cell["source"] = solutions[grade_id]
                notebooks[release.name] = nb
            self.submit(student, assignment, notebooks)
            made.append(student)
        return made

    # ------------------------------------------------------------------ autograde
    def _journal_path(self) -> Path:
        return self.root / ".cvkit" / "journal.json"

    def _journal(self) -> dict:
        path = self._journal_path()
        try:
            return json.loads(path.read_text()) if path.exists() else {}
        except ValueError:
            return {}

    def _submission_hash(self, student: str, assignment: str) -> str:
        digest = hashlib.sha256()
        files, refused = collect_files(self.root / "submitted" / student / assignment)
        for name, data in sorted(files.items()):
            digest.update(name.encode())
            digest.update(data)
        for note in refused:
            digest.update(note.encode())
        return digest.hexdigest()

    def is_graded(self, student: str, assignment: str) -> bool:
        """Graded already, from this very submission (an interrupted run resumes after it)."""
        key = f"{student}/{assignment}"
        return (self._journal().get(key) == self._submission_hash(student, assignment)
                and not self.audit([(student, assignment)]))

    def autograde_one(self, student: str, assignment: str) -> JobResult:
        """Execute one submission in isolation, then record its trusted grades."""
        return self.record(grade_submission(*self._payload(student, assignment)))

    def _payload(self, student: str, assignment: str) -> tuple:
        """Arguments of :func:`grade_submission` for one submission."""
        def texts(folder: Path) -> dict[str, str]:
            return {str(p.relative_to(folder)): p.read_text() for p in sorted(folder.rglob("*.ipynb"))}

        return (str(self.project), student, assignment, self._submission_files(student, assignment),
                texts(self.root / "release" / assignment), texts(self.source_dir / assignment), self.salt())

    def _submission_files(self, student: str, assignment: str) -> dict[str, bytes]:
        """The submission's regular files (links, devices and the like are refused, see
        :func:`collect_files`, and flagged when the submission is recorded)."""
        return collect_files(self.root / "submitted" / student / assignment)[0]

    def _refused_files(self, student: str, assignment: str) -> list[str]:
        return collect_files(self.root / "submitted" / student / assignment)[1]

    def record(self, executed: "ExecutedSubmission") -> JobResult:
        """Record one executed submission (see :meth:`record_many`)."""
        return self.record_many([executed])[0]

    def repaired(self, student: str, assignment: str, name: str, notebook: dict) -> dict:
        """The release notebook with the student's answers put back in: for a submission whose
        graded cells were deleted, duplicated or retyped so badly that nbgrader refuses it.
        Answer cells are matched by grade id (their source kept, their type restored); cells
        the student added come along after the answer cell they followed."""
        release = json.loads((self.root / "release" / assignment / name).read_text())
        answers: dict[str, str] = {}
        added_after: dict[str, list] = {}
        known = {_cell_source(c).strip() for c in release["cells"]}
        last = None
        for cell in notebook.get("cells", []):
            meta = cell.get("metadata", {}).get("nbgrader", {})
            if meta.get("solution") and meta.get("grade_id") and meta["grade_id"] not in answers:
                answers[meta["grade_id"]] = _cell_source(cell)
                last = meta["grade_id"]
            elif not meta and cell.get("cell_type") == "code" and _cell_source(cell).strip() not in known:
                added_after.setdefault(last, []).append(_cell_source(cell))
        def added(anchor):
            return [{"cell_type": "code", "source": source, "metadata": {}, "outputs": [], "execution_count": None}
                    for source in added_after.get(anchor, [])]

        cells = []
        for cell in release["cells"]:
            meta = cell.get("metadata", {}).get("nbgrader", {})
            if meta.get("solution") and meta.get("grade_id") in answers:
                cell = dict(cell, source=answers[meta["grade_id"]])
            cells.append(cell)
            if meta.get("grade_id") == "setup":
                cells += added(None)
            elif meta.get("solution"):
                cells += added(meta.get("grade_id"))
        return dict(release, cells=cells)

    def record_many(self, batch: list, repair: bool = False) -> list[JobResult]:
        """The single writer: nbgrader's own autograde, without execution, on executed
        notebooks (one nbgrader run per assignment for the whole batch); only this process
        writes the gradebook. Notebooks whose checks were decided in the parallel phase are
        recorded as they are; a repaired copy (graded cells tampered with) is verified here by
        nbgrader's TrustedChecks (sandboxed too). Never raises for a submission: what cannot be
        recorded is listed as not graded, with the reason."""
        try:
            return self._record_many(batch, repair)
        except Exception as error:  # noqa: BLE001 - isolate the submission that breaks the writer
            if len(batch) > 1:
                return [r for e in batch for r in self.record_many([e], repair=repair)]
            executed = batch[0]
            return [self._record_not_graded(executed.student, executed.assignment,
                                            f"the grader could not record it ({type(error).__name__}: {str(error)[:200]})")]

    def _record_many(self, batch: list, repair: bool = False) -> list[JobResult]:
        results = []
        groups = {}
        for executed in batch:  # one nbgrader run per assignment and kind of verification
            if executed.not_graded:
                results.append(self._record_not_graded(executed.student, executed.assignment, executed.not_graded))
                continue
            key = (executed.assignment, bool(executed.verified and executed.ok))
            groups.setdefault(key, []).append(executed)
        for (assignment, _), group in sorted(groups.items()):
            staging = self.root / ".cvkit" / "staging"
            shutil.rmtree(staging, ignore_errors=True)
            for executed in group:
                folder = staging / executed.student / assignment
                folder.mkdir(parents=True)
                files = executed.notebooks if executed.ok and not repair else {}
                for name, data in self._submission_files(executed.student, assignment).items():
                    target = folder / name
                    target.parent.mkdir(parents=True, exist_ok=True)
                    if repair and name.endswith(".ipynb"):
                        data = json.dumps(self.repaired(executed.student, assignment, name, json.loads(data))).encode()
                    target.write_bytes(files[name].encode() if name in files else data)

            students = [] if len(group) > 1 else ["--student", group[0].student]
            # notebooks verified in the parallel phase carry their verdicts; any other
            # (execution failed, repaired copy) is verified here by nbgrader's TrustedChecks
            verified = all(e.verified and e.ok for e in group) and not repair
            self.nbgrader_api()  # the course's configuration, loaded once
            api = self.nbgrader_api(**{
                "CourseDirectory.submitted_directory": str(staging), "SandboxedExecute.enabled": False,
                "ClearOutput.enabled": False, "TrustedChecks.enabled": not verified,
                **_recording_settings(self._nbgrader_config, verified)})
            try:
                outcome = api.autograde(assignment, group[0].student if len(group) == 1 else "*", force=True,
                                        create=True)
            except Exception as error:  # noqa: BLE001 - nbgrader's failure on one notebook must not stop the run
                outcome = {"success": False, "error": f"{type(error).__name__}: {error}"}
            done = subprocess.CompletedProcess(["nbgrader", "autograde", assignment, *students],
                                               0 if outcome.get("success") else 1,
                                               outcome.get("log", ""), outcome.get("error", ""))
            shutil.rmtree(staging, ignore_errors=True)
            if done.returncode != 0 and len(group) > 1:  # isolate the submission that fails
                results += [r for e in group for r in self.record_many([e], repair=repair)]
                continue
            if done.returncode != 0 and not repair:
                # nbgrader refuses the notebook (graded cells deleted, duplicated, retyped):
                # grade the student's answers in a repaired copy of the release instead
                results += self.record_many(group, repair=True)
                continue
            if done.returncode != 0:  # not even a repaired copy: not graded, with nbgrader's reason
                reason = (done.stderr or done.stdout or "nbgrader could not record it").strip().splitlines()[-1][:300]
                results += [self._record_not_graded(e.student, assignment, f"nbgrader refused it: {reason}")
                            for e in group]
                continue
            journal = self._journal()
            for executed in group:
                log = (executed.log[-1500:] + "\n" + done.stdout + done.stderr)[-4000:]
                if done.returncode == 0:
                    journal[f"{executed.student}/{assignment}"] = self._submission_hash(executed.student, assignment)
                    self._set_not_graded(executed.student, assignment, None)
                    for note in self._refused_files(executed.student, assignment):
                        self._add_flag(executed.student, assignment, f"(notebook): {note}")
                if repair and done.returncode == 0:
                    log += "\ngraded from a repaired copy: the submission's graded cells had been tampered with"
                    self._add_flag(executed.student, assignment,
                                   "(notebook): graded cells were deleted, duplicated or retyped; graded from a repaired copy")
                results.append(JobResult(executed.student, assignment, done.returncode, 1, log, executed=executed.ok))
            self._journal_path().parent.mkdir(parents=True, exist_ok=True)
            self._journal_path().write_text(json.dumps(journal, indent=1))
        return results

    # ------------------------------------------------------------------ not graded
    def _not_graded_path(self) -> Path:
        return self.root / ".cvkit" / "not_graded.json"

    def not_graded(self) -> dict[str, str]:
        """``"student/assignment"`` → why it could not be graded (never a zero)."""
        try:
            data = json.loads(self._not_graded_path().read_text())
            return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}
        except (OSError, ValueError):
            return {}

    def _set_not_graded(self, student: str, assignment: str, reason: str | None) -> None:
        data = self.not_graded()
        key = f"{student}/{assignment}"
        if reason is None and key not in data:
            return
        if reason is None:
            data.pop(key, None)
        else:
            data[key] = reason
        self._not_graded_path().parent.mkdir(parents=True, exist_ok=True)
        self._not_graded_path().write_text(json.dumps(data, indent=1))

    def _record_not_graded(self, student: str, assignment: str, reason: str) -> JobResult:
        """Keep a submission that cannot be graded visible as such: its reason in the journal
        of not-graded submissions (table, exports), and for the formgrader an entry in the
        gradebook with its notebooks flagged. No score is recorded for it."""
        refused = self._refused_files(student, assignment)
        if refused:
            reason += " (refused files: " + "; ".join(refused)[:300] + ")"
        self._set_not_graded(student, assignment, reason)
        journal = self._journal()
        journal[f"{student}/{assignment}"] = self._submission_hash(student, assignment)
        self._journal_path().parent.mkdir(parents=True, exist_ok=True)
        self._journal_path().write_text(json.dumps(journal, indent=1))
        try:
            from nbgrader.api import Gradebook, MissingEntry

            with Gradebook(self.db_url) as gb:
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

    def _add_flag(self, student: str, assignment: str, flag: str) -> None:
        """Append a flag to the metadata of a student's autograded notebooks."""
        for path in (self.root / "autograded" / student / assignment).glob("*.ipynb"):
            nb = json.loads(path.read_text())
            meta = nb.setdefault("metadata", {}).setdefault("cvkit", {})
            meta.setdefault("flags", []).append(flag)
            path.write_text(json.dumps(nb, indent=1))

    def grade(
        self,
        assignments: Iterable[str] | None = None,
        workers: int = 2,
        scheduler: str | None = None,
        progress: bool = False,
        regrade: bool = False,
        batch: int | None = None,
        sandbox: bool = True,
    ) -> list[JobResult]:
        """Autograde every submission, then write feedback and the CSV exports.

        Every line of student code runs in the operating-system sandbox
        (:mod:`cvkit.grading.isolation`); when it cannot be made, this raises
        :class:`~cvkit.grading.isolation.SandboxUnavailable` before grading anything, with how
        to install it. ``sandbox=False`` (``--no-sandbox``, one trusted machine only) grades
        with resource limits alone and marks every such grade in the table, the exports and
        the feedback.

        The parallel phase (:func:`grade_submission`: execution in isolation, then the trusted
        checks) runs in ``workers`` local processes, or on the workers of the Dask distributed
        ``scheduler`` (they need the project, not this course folder). Results come back to
        this process, which alone writes the gradebook, in batches of ``batch`` submissions
        (default ``max(2, workers)``). Local workers get a few submissions at a time, so that
        the feedback pages of each recorded batch are written by the workers between grading
        jobs instead of all at the end. Submissions
        graded before from the same files are skipped unless ``regrade``.
        """
        from ..grading import isolation

        if sandbox:
            isolation.require()
            os.environ.pop("CVKIT_NO_SANDBOX", None)
        else:
            os.environ["CVKIT_NO_SANDBOX"] = "1"  # inherited by the grading workers
        jobs = self.submissions(assignments)
        todo = [(s, a) for s, a in jobs if regrade or not self.is_graded(s, a)]
        payloads = [self._payload(s, a) for s, a in todo]
        batch = max(1, batch if batch is not None else max(2, workers))
        if payloads:
            self.nbgrader_api()  # load nbgrader and the configuration while the workers start
        results: list[JobResult] = []
        bar = _progress(None, "autograde", progress, total=len(payloads))
        finished: list = []
        owners: dict = {}
        recorded_pairs: list = []
        local_pool: list = []       # the local process pool, once it exists
        feedback_steps: list = []   # its feedback jobs

        def outcome(future) -> ExecutedSubmission:
            try:
                return future.result()
            except Exception as error:  # a lost worker: the writer grades the raw files
                student, assignment = owners[future]
                return ExecutedSubmission(student, assignment, {}, False, f"parallel phase failed: {error!r}")

        def drain(done_futures, pending_count: int) -> None:
            # record what has finished, once a batch is full or nothing else is coming
            finished.extend(outcome(f) for f in done_futures)
            if finished and (len(finished) >= batch or pending_count == 0):
                written = list(finished)
                finished.clear()
                recorded = self.record_many(written)
                results.extend(recorded)
                pairs = [(r.student, r.assignment) for r in recorded if r.ok]
                recorded_pairs.extend(pairs)
                if local_pool:  # feedback pages of this batch by the workers, between grading jobs
                    step = max(1, -(-len(pairs) // max(1, workers)))
                    for chunk in (pairs[i:i + step] for i in range(0, len(pairs), step)):
                        feedback_steps.append(local_pool[0].submit(
                            feedback_submissions, str(self.root), self.db_url, str(self.project), chunk))
                if bar is not None:
                    bar.update(len(written))

        if scheduler and payloads:
            from dask.distributed import Client, wait

            with Client(scheduler) as client:
                owners.update({client.submit(grade_submission, *payload, pure=False): payload[1:3]
                               for payload in payloads})
                pending = set(owners)
                while pending:
                    done = wait(pending, return_when="FIRST_COMPLETED").done
                    pending -= done
                    drain(done, len(pending))
        elif payloads:
            import multiprocessing

            context = multiprocessing.get_context("spawn")  # no inherited threads or state
            with concurrent.futures.ProcessPoolExecutor(max_workers=max(1, workers), mp_context=context) as pool:
                local_pool.append(pool)
                waiting = list(payloads)  # submitted a few at a time, so that feedback jobs queued
                pending = set()           # by `drain` run before the submissions still waiting

                def submit_next() -> None:
                    if waiting:
                        payload = waiting.pop(0)
                        future = pool.submit(grade_submission, *payload)
                        owners[future] = payload[1:3]
                        pending.add(future)

                for _ in range(max(1, workers) + 1):
                    submit_next()
                while pending:
                    done, _ = concurrent.futures.wait(pending, return_when=concurrent.futures.FIRST_COMPLETED)
                    pending.difference_update(done)
                    for _ in done:
                        submit_next()
                    drain(done, len(pending) + len(waiting))
                # feedback pages (nbconvert, CPU-heavy) were queued batch by batch behind the
                # grading jobs, so a worker with no submission left writes them meanwhile
                for step in feedback_steps:
                    try:
                        step.result()
                    except Exception:  # a lost worker or a busy gradebook: this process writes them (below)
                        pass
        if bar is not None:
            bar.close()
        missing = missing_before = self.audit(jobs)
        for student, assignment in missing:  # never lose a grade: one more, plain attempt
            results = [r for r in results if (r.student, r.assignment) != (student, assignment)]
            results.append(self.autograde_one(student, assignment))
        missing = self.audit(jobs)
        results += [JobResult(s, a, 1, 0, "no grade recorded after autograding") for s, a in missing]
        retried = [(r.student, r.assignment) for r in results if r.ok and (r.student, r.assignment) in missing_before]
        not_graded = self.not_graded()
        self.feedback([pair for pair in retried + [(s, a) for s, a in jobs if not (self.root / "feedback" / s / a).is_dir()]
                       if f"{pair[0]}/{pair[1]}" not in not_graded])
        self.export()
        return sorted(results, key=lambda r: (r.assignment, r.student))

    def feedback(self, submissions: Iterable[tuple[str, str]]) -> None:
        """nbgrader's ``generate_feedback`` (in this process) for these (student, assignment)
        pairs: HTML pages with the trusted reports, hidden tests' source removed."""
        pairs = sorted(set(submissions))
        if not pairs:
            return
        api = self.nbgrader_api()
        failed = []
        for student, assignment in pairs:
            try:
                outcome = api.generate_feedback(assignment, student_id=student, force=True)
            except Exception as error:  # noqa: BLE001 - one page must not stop the others
                outcome = {"success": False, "error": repr(error)}
            if not outcome.get("success"):
                failed.append(f"{student}/{assignment}: {outcome.get('error', '')[-500:]}")
        if failed:
            log = self.root / ".cvkit" / "feedback_errors.log"
            log.parent.mkdir(parents=True, exist_ok=True)
            log.write_text("\n".join(failed))

    def audit(self, jobs: Iterable[tuple[str, str]]) -> list[tuple[str, str]]:
        """Submissions with no autograded notebook or no grade in the gradebook."""
        from nbgrader.api import Gradebook, MissingEntry

        missing = []
        not_graded = self.not_graded()
        with Gradebook(self.db_url) as gb:
            for student, assignment in jobs:
                if f"{student}/{assignment}" in not_graded:
                    continue  # accounted for: listed as not graded, with its reason
                graded = list((self.root / "autograded" / student / assignment).glob("*.ipynb"))
                try:
                    submission = gb.find_submission(assignment, student)
                    has_grades = all(nb.grades for nb in submission.notebooks)
                except MissingEntry:
                    has_grades = False
                if not graded or not has_grades:
                    missing.append((student, assignment))
        return missing

    def export(self) -> Path:
        """All grades as CSV: nbgrader's ``exports/grades.csv`` (one row per submission) and
        cvkit's ``exports/exercises.csv`` (one row per exercise, with the mistakes the checks
        recognised, the problems, and the tampering flags for the instructor)."""
        import csv

        from ..grading.safety import csv_safe

        target = self.root / "exports" / "grades.csv"
        target.parent.mkdir(exist_ok=True)
        from nbgrader.api import Gradebook
        from nbgrader.plugins import CsvExportPlugin

        with Gradebook(self.db_url) as gradebook:
            CsvExportPlugin(to=str(target)).export(gradebook)
        not_graded = self.not_graded()
        unsandboxed = self._unsandboxed()
        with target.open(newline="") as handle:
            rows = list(csv.reader(handle))
        if rows:
            header = rows[0]
            column = {name: i for i, name in enumerate(header)}
            out = [header + ["status"]]
            for row in rows[1:]:
                key = f"{row[column['student_id']]}/{row[column['assignment']]}" if "student_id" in column else ""
                status = "graded"
                if key in not_graded:
                    status = f"not graded: {not_graded[key]}"
                    for name in ("raw_score", "score", "late_submission_penalty"):
                        if name in column:
                            row[column[name]] = ""
                elif key in unsandboxed:
                    status = "graded WITHOUT SANDBOX (--no-sandbox)"
                out.append([csv_safe(cell) for cell in row] + [csv_safe(status)])
            with target.open("w", newline="") as handle:
                csv.writer(handle).writerows(out)
        with (self.root / "exports" / "exercises.csv").open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["assignment", "student", "exercise", "score", "max_score", "mistakes", "problems", "flags",
                             "status"])
            for assignment in sorted({a for _, a in self.submissions()}):
                for student, exercises in self.scores(assignment).items():
                    for e in exercises:
                        writer.writerow([csv_safe(x) for x in (
                            assignment, student, e.name, "" if e.to_mark else f"{e.score:g}", f"{e.max_score:g}",
                            "; ".join(e.mistakes), "; ".join(e.problems), "; ".join(e.flags),
                            "to mark by hand (formgrader)" if e.to_mark else "graded")])
                for key, reason in sorted(not_graded.items()):
                    student, _, a = key.partition("/")
                    if a == assignment:
                        writer.writerow([csv_safe(x) for x in (assignment, student, "(submission)", "", "", "",
                                                                f"not graded: {reason}", "not graded", "not graded")])
        return target

    def _unsandboxed(self) -> set[str]:
        """``student/assignment`` of submissions graded with ``--no-sandbox``."""
        found = set()
        for folder in sorted((self.root / "autograded").glob("*/*")):
            for path in folder.glob("*.ipynb"):
                try:
                    meta = json.loads(path.read_text()).get("metadata", {}).get("cvkit", {})
                except (OSError, ValueError):
                    continue
                if meta.get("sandboxed") is False:
                    found.add(f"{folder.parent.name}/{folder.name}")
        return found

    def table(self, assignment: str) -> str:
        """The grade table of one assignment, not-graded submissions and unsandboxed grading
        included (see :func:`format_table`)."""
        not_graded = {k.partition("/")[0]: v for k, v in self.not_graded().items() if k.endswith(f"/{assignment}")}
        unsandboxed = sorted(k.partition("/")[0] for k in self._unsandboxed() if k.endswith(f"/{assignment}"))
        return format_table(self.scores(assignment), not_graded=not_graded, unsandboxed=unsandboxed)

    # ------------------------------------------------------------------ results
    def scores(self, assignment: str) -> dict[str, list[ExerciseScore]]:
        """Per student, per exercise: score, maximum, and the mistakes the checks named."""
        from nbgrader.api import Gradebook, MissingEntry

        table: dict[str, list[ExerciseScore]] = {}
        not_graded = self.not_graded()
        with Gradebook(self.db_url) as gb:
            for student, a in self.submissions([assignment]):
                if f"{student}/{assignment}" in not_graded:
                    continue  # no score: listed as not graded (Course.table, the exports)
                try:
                    submission = gb.find_submission(assignment, student)
                except MissingEntry:
                    continue
                found = _reported_mistakes(self.root / "autograded" / student / assignment)
                flags = _flags(self.root / "autograded" / student / assignment)
                exercises: dict[str, ExerciseScore] = {}
                for nb in submission.notebooks:
                    for grade in sorted(nb.grades, key=lambda g: g.cell_id if hasattr(g, "cell_id") else g.name):
                        name = re.sub(r"_(visible|hidden|test)$", "", grade.name)
                        entry = exercises.setdefault(name, ExerciseScore(name, 0.0, 0.0))
                        entry.to_mark = entry.to_mark or bool(grade.needs_manual_grade)
                        entry.score += float(grade.score or 0.0)
                        entry.max_score += float(grade.max_score or 0.0)
                        for item in found.get(grade.name, []):
                            bucket = entry.mistakes if item.startswith("mistake:") else entry.problems
                            text = item.split(":", 1)[1]
                            if text not in bucket:
                                bucket.append(text)
                for flag in flags:
                    where, _, what = flag.partition(": ")
                    name = re.sub(r"_(answer|visible|hidden|test)$", "", where)
                    target = exercises.get(name)
                    if target is None:
                        target = exercises.setdefault("(notebook)", ExerciseScore("(notebook)", 0.0, 0.0))
                    target.flags.append(what if target.name == name else flag)
                order = self._grade_order(assignment)
                table[student] = sorted(
                    exercises.values(), key=lambda e: order.get(e.name, len(order))
                )
        return dict(sorted(table.items(), key=lambda item: _student_order(item[0])))

    def _grade_order(self, assignment: str) -> dict[str, int]:
        """Exercise name → position of its first graded cell in the released notebooks."""
        order: dict[str, int] = {}
        for path in self.release_notebooks(assignment):
            for cell in json.loads(path.read_text()).get("cells", []):
                grade_id = cell.get("metadata", {}).get("nbgrader", {}).get("grade_id")
                if grade_id:
                    order.setdefault(re.sub(r"_(answer|visible|hidden|test)$", "", grade_id), len(order))
        return order


def _student_order(student: str) -> tuple:
    return (SAMPLE_STUDENTS.index(student), student) if student in SAMPLE_STUDENTS else (len(SAMPLE_STUDENTS), student)


def _flags(folder: Path) -> list[str]:
    """Tampering flags the trusted grader left in the autograded notebooks' metadata."""
    flags = []
    for path in sorted(folder.glob("*.ipynb")):
        meta = json.loads(path.read_text()).get("metadata", {}).get("cvkit", {})
        flags += [str(f) for f in meta.get("flags", [])]
        if meta.get("sandboxed") is False:
            flags.append("(notebook): GRADED WITHOUT THE SANDBOX (--no-sandbox)")
        if meta.get("worker_problem"):
            flags.append(f"(notebook): {meta['worker_problem']}")
    return flags


def _reported_mistakes(folder: Path) -> dict[str, list[str]]:
    """grade_id → ["mistake:<name>" | "problem:<text>"] from the reports in graded notebooks:
    one item per report, in plain words — the named mistake, else what the first diagnosed
    failing case looks like ("your output is shifted by 1 row down"), else the first clause of
    the first failing case's message (never the tolerances)."""
    found: dict[str, list[str]] = {}
    for path in sorted(folder.glob("*.ipynb")):
        nb = json.loads(path.read_text())
        for cell in nb.get("cells", []):
            grade_id = cell.get("metadata", {}).get("nbgrader", {}).get("grade_id")
            for output in cell.get("outputs", []):
                report = output.get("data", {}).get(MIME_TYPE)
                if not report or not grade_id or not isinstance(report, dict):
                    continue
                items = found.setdefault(grade_id, [])
                failures = [c for c in report.get("cases", []) if isinstance(c, dict) and not c.get("passed")]
                if report.get("mistake"):
                    item = f"mistake:{report['mistake']}"
                elif failures:
                    diagnosis = report.get("diagnosis") or next((c.get("diagnosis") for c in failures
                                                                 if c.get("diagnosis")), None)
                    item = f"problem:{_headline(diagnosis or failures[0].get('message') or 'failed')}"
                else:
                    continue
                if item not in items:
                    items.append(item)
    return found


#: the numpy.testing vocabulary of reports written before plain words came first
_TECHNICAL_LINE = re.compile(r"\b(rtol|atol)\b|to tolerance|^Mismatched elements")


def _headline(message: str, width: int = 90) -> str:
    """The first clause of a failure message, in plain words: "calls X, which would..." →
    "calls X"; "60 of 90 values differ, all in the border frame 2 pixels wide (the interior is
    right); first at ..." → up to the semicolon; "Your output is shifted by 1 row down: ..." →
    "your output is shifted by 1 row down". Reports in the old numpy.testing wording ("Not
    equal to tolerance rtol=…") become "N of M values differ"."""
    lines = [line.strip() for line in str(message or "").splitlines() if line.strip()]
    if not lines:
        return "failed"
    first = lines[0]
    if _TECHNICAL_LINE.search(first):
        counted = re.search(r"Mismatched elements: (\d+) / (\d+)", str(message))
        first = (f"{counted.group(1)} of {counted.group(2)} values differ" if counted
                 else "the values differ from the expected ones")
    first = re.sub(r"\s*\([^()]*\b(?:rtol|atol)\b[^()]*\)", "", first)
    prefix = re.match(r"(result \[\d+\]: )?", first).group(0)
    first = first[len(prefix):]
    if not first.startswith(("shape mismatch", "dtype mismatch", "raised ")):
        first = re.split(r"; |\. (?=[A-Z])", first, maxsplit=1)[0]
        for stop in (", which", ": "):
            if stop in first:
                first = first.split(stop, 1)[0]
                break
    first = prefix + first
    first = first.rstrip(" .")
    if first[:1].isupper() and first[1:2].islower():
        first = first[0].lower() + first[1:]
    return first if len(first) <= width else first[: width - 1].rsplit(" ", 1)[0] + "…"


def solution_sources(notebook: dict) -> dict[str, str]:
    """grade_id → source of each solution cell with the solution markers removed; for a written
    answer, the model answer without its rubric (what a student who knows the answer writes)."""
    out = {}
    for cell in notebook.get("cells", []):
        meta = cell.get("metadata", {}).get("nbgrader", {})
        if not meta.get("solution"):
            continue
        source = cell["source"] if isinstance(cell["source"], str) else "".join(cell["source"])
        if cell.get("cell_type") == "markdown":
            source = source.split("**Rubric", 1)[0].replace("**Model answer.**", "").strip()
        lines = [line for line in source.splitlines() if line.strip() not in (SOLUTION_BEGIN, SOLUTION_END)]
        out[meta.get("grade_id")] = "\n".join(lines)
    return out


def typical_mistakes(folder: Path) -> dict[str, str]:
    """grade_id → cell source, from ``typical_mistakes.py`` (sections ``# %% <grade_id>``)."""
    path = folder / "typical_mistakes.py"
    if not path.exists():
        return {}
    cells, current, lines = {}, None, []
    for line in path.read_text().splitlines():
        match = re.match(r"^# %% (\S+)\s*$", line)
        if match:
            if current:
                cells[current] = "\n".join(lines).strip("\n")
            current, lines = match.group(1), []
        elif current:
            lines.append(line)
    if current:
        cells[current] = "\n".join(lines).strip("\n")
    return cells


def _progress(iterable, desc: str, enabled: bool, total: int | None = None):
    """A tqdm progress bar over ``iterable`` (or a manual bar when ``iterable`` is None)."""
    if not enabled:
        return iterable
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        return iterable
    return tqdm(iterable, desc=desc, total=total, unit="job", file=sys.stderr)


def format_table(scores: dict[str, list[ExerciseScore]], students: Iterable[str] | None = None,
                 not_graded: dict[str, str] | None = None, unsandboxed: Iterable[str] = ()) -> str:
    """A plain-text table: one row per exercise, one column per student, totals, mistakes;
    then the submissions that could not be graded (``not_graded``: student → reason, never
    shown as zeros) and a loud warning for those graded without the sandbox."""
    not_graded = dict(not_graded or {})
    unsandboxed = sorted(unsandboxed)
    tail = []
    if unsandboxed:
        tail.append("\n!! GRADED WITHOUT THE SANDBOX (--no-sandbox): student code ran with the grader's rights for "
                    + ", ".join(unsandboxed))
    if not_graded:
        tail.append("\nNot graded (no score recorded; fix the cause and grade again):")
        tail += [f"  {s}: not graded: {reason}" for s, reason in sorted(not_graded.items())]
    students = [s for s in (students or scores) if s in scores]
    if not students:
        return "(no graded submissions)" + "\n".join(tail)
    exercises = []
    for s in students:
        for e in scores[s]:
            if e.name not in exercises:
                exercises.append(e.name)
    cell = {}
    for s in students:
        for e in scores[s]:
            if e.to_mark:
                cell[(e.name, s)] = f"to mark/{e.max_score:g} ✎"
                continue
            mark = "✓" if e.score >= e.max_score - 1e-9 else ("·" if e.score > 0 else "✗")
            cell[(e.name, s)] = f"{e.score:.2f}/{e.max_score:g} {mark}"
    width = max(len(x) for x in exercises + ["exercise"]) + 2
    colw = max(14, *(len(s) + 2 for s in students))
    lines = ["exercise".ljust(width) + "".join(s.rjust(colw) for s in students)]
    lines.append("-" * len(lines[0]))
    for name in exercises:
        lines.append(name.ljust(width) + "".join(cell.get((name, s), "-").rjust(colw) for s in students))
    lines.append("-" * len(lines[0]))
    totals = []
    for s in students:
        got = sum(e.score for e in scores[s] if not e.to_mark)
        top = sum(e.max_score for e in scores[s])
        pending = sum(e.max_score for e in scores[s] if e.to_mark)
        totals.append((f"{got:.2f}/{top:g}" + (f" +{pending:g}✎" if pending else "")).rjust(colw))
    lines.append("total".ljust(width) + "".join(totals))
    if any(e.to_mark for s in students for e in scores[s]):
        lines.append("✎ written answers and open tasks to mark by hand in nbgrader's formgrader "
                     "(`+N✎`: points still to mark); the totals add them once marked")
    notes = []
    for s in students:
        missing = [e.name for e in scores[s] if any(p.startswith("not implemented") for p in e.problems)]
        for e in scores[s]:
            # one line per student × exercise (its visible and hidden tests together): the named
            # mistake(s), else the first problem, in the reports' plain words
            mistakes = list(dict.fromkeys(e.mistakes))
            problems = [p for p in dict.fromkeys(e.problems) if not p.startswith("not implemented")]
            if mistakes:
                notes.append(f"  {s} · {e.name}: mistake{'s' if len(mistakes) > 1 else ''} "
                             + ", ".join(f"“{m}”" for m in mistakes))
            elif problems:
                notes.append(f"  {s} · {e.name}: {problems[0]}")
        if missing:
            shown = ", ".join(missing) if len(missing) <= 4 else f"{len(missing)} exercises"
            notes.append(f"  {s} · not attempted: {shown}")
    if notes:
        lines.append("\nWhat the checks found:")
        lines += notes
    flagged = [f"  {s} · {e.name}: {flag}" for s in students for e in scores[s] for flag in e.flags]
    if flagged:
        lines.append("\nFlags for the instructor (code that tries to get around the grader):")
        lines += flagged
    return "\n".join(lines + tail)


def _cell_source(cell: dict) -> str:
    return cell["source"] if isinstance(cell["source"], str) else "".join(cell["source"])


def predict_scores(notebook: dict, student: str, salt: str, source: dict | None = None) -> dict[str, float]:
    """What nbgrader should record for each test cell of a (trusted) notebook.

    Runs the setup cell and the answer cells in this process, then grades every
    ``check(...)`` call of the test cells with the seeds the kernel would use. As nbgrader's
    autograde does, test cells are taken from the ``source`` notebook when given (the
    submitted copy has its hidden tests stripped). Used by the tests to confirm that the
    course pipeline records exactly the engine's verdicts. Never use it on untrusted
    submissions: it executes their code here.
    """
    originals = {}
    for cell in (source or {}).get("cells", []):
        meta = cell.get("metadata", {}).get("nbgrader", {})
        if meta.get("grade") and not meta.get("solution"):
            originals[meta.get("grade_id")] = _cell_source(cell)
    import ast

    from ..grading import evaluate, hidden_seed

    from .. import registry

    student_provider = registry.provider("student")
    saved = (dict(student_provider.functions), dict(student_provider.sources))
    try:
        return _predict(notebook, student, salt, originals, evaluate, hidden_seed)
    finally:  # the answer cells' @student decorators must not leak into this process
        student_provider.functions.clear()
        student_provider.functions.update(saved[0])
        student_provider.sources.clear()
        student_provider.sources.update(saved[1])


def _predict(notebook, student, salt, originals, evaluate, hidden_seed) -> dict[str, float]:
    import ast

    namespace: dict = {"__name__": "__cvkit_prediction__"}
    tests = []
    for cell in notebook.get("cells", []):
        if cell.get("cell_type") != "code":
            continue
        meta = cell.get("metadata", {}).get("nbgrader", {})
        source = _cell_source(cell)
        if meta.get("grade_id") == "setup" or meta.get("solution"):
            code = "\n".join(line for line in source.splitlines() if not line.lstrip().startswith(("%", "!")))
            try:
                exec(compile(code, f"<cell {meta.get('grade_id')}>", "exec"), namespace)
            except Exception:
                pass  # a broken answer cell: its tests will fail in the kernel too
        elif meta.get("grade"):
            tests.append((meta["grade_id"], float(meta.get("points", 0)), originals.get(meta["grade_id"], source)))
    scores = {}
    for grade_id, points, source in tests:
        calls = [n for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Call)
                 and getattr(n.func, "id", None) == "check"]
        total = points
        for call in calls:
            algorithm_id = ast.literal_eval(call.args[0])
            function = namespace.get(call.args[1].id) if isinstance(call.args[1], ast.Name) else None
            keywords = {k.arg: ast.literal_eval(k.value) for k in call.keywords}
            hidden = keywords.get("hidden", False)
            if function is None:
                total = 0.0
                continue
            seed = hidden_seed(algorithm_id, student=student, salt=salt)
            report = evaluate(algorithm_id, function, hidden=hidden, seed=seed if hidden else None)
            if hidden:
                total = min(total, round(report.score * float(keywords.get("points", 1.0)), 6))
            elif not report.passed:
                total = 0.0
        scores[grade_id] = total
    return scores
