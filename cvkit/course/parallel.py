"""The parallel phase of :meth:`Course.grade`: the jobs (:mod:`.jobs`) on local worker
processes or a Dask cluster, their results recorded batch by batch by the single writer, the
feedback pages written by idle workers; then the final audit, the exports and the similarity
report. Each phase shows its count and the time left (:class:`.progress.Phase`): grading and
recording per submission, feedback per page, exports per file, similarity per assignment.

Local workers are forked from a ``forkserver`` that imported what they need once
(:func:`worker_context`): a script that calls :meth:`Course.grade` needs the usual
``if __name__ == "__main__":`` guard. On a Dask cluster (``--scheduler``) every
worker shows that it grades as this process would before anything is graded (:func:`_connect`),
and what the cluster could not grade — a job whose workers died, a lost scheduler — is graded
on this machine (``docs/scale-out.md``).
"""
from __future__ import annotations

import concurrent.futures
import os
import sys
import time
from concurrent.futures import Future
from typing import TYPE_CHECKING, Any, Callable, Iterable

from . import class_notes, exports, item_analysis, jobs, leaderboard, marks, results
from .feedback import feedback_submissions, write_feedback
from .jobs import ExecutedSubmission, grade_in_fresh_process, grade_submission
from .progress import Phase, progress
from .writer import JobResult, Writer

if TYPE_CHECKING:
    from .state import CourseState


payload = jobs.payload  # the arguments of grade_submission for one submission


class _Batches:
    """Results of the parallel phase, recorded once a batch is full or nothing else is coming;
    with a local pool, each recorded batch's feedback pages are queued for its workers."""

    def __init__(self, course: CourseState, size: int, workers: int, bars: dict[str, Phase]) -> None:
        self.course, self.size, self.workers, self.bars = course, size, workers, bars
        self.writer = Writer(course)
        self.finished: list[ExecutedSubmission] = []
        self.owners: dict[Any, tuple[str, str]] = {}   # future -> (student, assignment)
        self.results: list[JobResult] = []
        self.pool: concurrent.futures.Executor | None = None
        self.feedback_steps: dict[Future[None], int] = {}  # feedback job -> its number of pages
        self.meanwhile: list[Callable[[], object]] = []  # work of this process while the first jobs run

    def while_jobs_run(self, last_chance: bool = False) -> None:
        """Do this process's own work that needs no grade (the similarity report: it reads the
        submissions as handed in) while the workers run the first jobs, not after the last. What
        fails then is tried again after the grades (``last_chance``), where its error is raised:
        it never stops the grading."""
        tasks, self.meanwhile = self.meanwhile, []
        for task in tasks:
            if last_chance:
                task()
                continue
            try:
                task()
            except Exception:  # noqa: BLE001 - tried again at the end, after every grade is recorded
                self.meanwhile.append(task)

    def feedback_done(self, wait: bool = False) -> None:
        """Count the feedback pages the workers have written (``wait``: until all are)."""
        steps = self.feedback_steps
        while steps:
            done = [step for step in steps if step.done()]
            if not done and wait:
                done = list(concurrent.futures.wait(steps, return_when=concurrent.futures.FIRST_COMPLETED).done)
            if not done:
                return
            for step in done:
                pages = steps.pop(step)
                try:
                    step.result()
                except Exception:  # a lost worker or a busy gradebook: this process writes them later
                    continue
                self.bars["feedback"].update(pages)

    def outcome(self, future: Any) -> ExecutedSubmission:
        try:
            return future.result()
        except Exception as error:  # a lost worker: the writer grades the raw files
            student, assignment = self.owners[future]
            return ExecutedSubmission(student, assignment, {}, False, f"parallel phase failed: {error!r}")

    def drain(self, done_futures: Iterable[Any], pending_count: int) -> None:
        """Record what has finished, once a batch is full or nothing else is coming."""
        arrived = [self.outcome(f) for f in done_futures]
        self.finished.extend(arrived)
        self.bars["grade"].update(len(arrived))
        if not self.finished or (len(self.finished) < self.size and pending_count > 0):
            return
        written = list(self.finished)
        self.finished.clear()
        recorded = self.writer.record_many(written)
        self.results.extend(recorded)
        pairs = [(r.student, r.assignment) for r in recorded if r.ok]
        self.bars["record"].update(len(written))
        if self.pool is not None:  # feedback pages of this batch by the workers, between grading jobs
            course = self.course
            step = max(1, -(-len(pairs) // max(1, self.workers)))
            for chunk in (pairs[i:i + step] for i in range(0, len(pairs), step)):
                try:
                    step_done = self.pool.submit(feedback_submissions, str(course.root), course.db_url,
                                                 str(course.project), chunk)
                except Exception:  # noqa: BLE001 - a broken pool: the pages still missing are written at the end
                    break
                self.feedback_steps[step_done] = len(chunk)
        self.feedback_done()


class ClusterUnavailable(RuntimeError):
    """``--scheduler``: the Dask scheduler cannot be reached, has no workers, or a worker would
    not grade as this process does (no working sandbox, other checks). Raised before anything
    is graded; the message names the address and what to do."""


def _connect(scheduler: str, payloads: list[tuple[Any, ...]]) -> Any:
    """A Dask client of ``scheduler`` whose workers are ready to grade ``payloads``, or
    :class:`ClusterUnavailable`. Waits at most Dask's connection timeout
    (``distributed.comm.timeouts.connect``, 30 s unless configured, e.g. with
    ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=5s``) for the scheduler, then as long for a
    first worker. Every worker then says whether it grades in the sandbox and with which
    checks (:func:`.jobs.worker_report`): one that would not grade as this process does stops
    the run before anything is graded."""
    import dask
    from dask.distributed import Client
    from dask.utils import parse_timedelta

    seconds = parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), "s")
    advice = (f"start the scheduler (`dask scheduler`) and its workers (`dask worker {scheduler}`, see "
              "docs/scale-out.md), or grade on this machine without --scheduler; nothing was graded")
    try:
        client = Client(scheduler, timeout=seconds)
    except Exception as error:  # noqa: BLE001 - refused, timed out, a malformed address: one clear message
        raise ClusterUnavailable(f"cannot reach the Dask scheduler at {scheduler} ({error}): {advice}") from None
    try:
        try:
            client.wait_for_workers(1, timeout=seconds)
        except TimeoutError:
            raise ClusterUnavailable(f"the Dask scheduler at {scheduler} has no workers (none joined in {seconds:g} s): "
                                     f"{advice}") from None
        sources = {p[2]: p[5] for p in payloads}
        reports = client.run(jobs.worker_report, sources, on_error="return")
        expected = jobs.checks_fingerprints(sources)
        problems = []
        for address, report in sorted(reports.items()):
            if not isinstance(report, dict):  # cvkit not importable there, the worker lost: say what happened
                problems.append(f"the worker {address} could not report whether it can grade ({report!r})")
                continue
            worker = f"the worker {address} ({report['where']})"
            if report["sandbox"]:
                problems.append(f"{worker} cannot grade in the sandbox: {report['sandbox']}")
            differ = sorted(a for a in expected if report["checks"].get(a) != expected[a])
            if differ:
                problems.append(f"{worker} would grade {', '.join(differ)} with other checks than this machine "
                                "(another cvkit version, checks or course packages: install the same environment there)")
        if problems:
            raise ClusterUnavailable(f"the Dask cluster at {scheduler} cannot grade: " + "; ".join(problems)
                                     + "; nothing was graded")
    except BaseException:
        client.close()
        raise
    return client


def _on_dask(batches: _Batches, payloads: list[tuple[Any, ...]], client: Any) -> tuple[list[tuple[Any, ...]], str]:
    """The jobs on the workers of ``client`` (:func:`_connect`). A job whose worker dies is
    given to another worker by the scheduler; one that still fails (Dask's ``KilledWorker``
    after ``distributed.scheduler.allowed-failures``, a worker whose sandbox broke) is graded
    by this process in a worker process of its own (:meth:`.writer.Writer.record_many`).
    Returns the jobs left when the scheduler is lost, or when the cluster has had no worker for
    Dask's connection timeout (its jobs would wait for one for ever), and why; none otherwise."""
    import dask
    from dask.distributed import wait
    from dask.utils import parse_timedelta

    patience = parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), "s")
    with client:
        submitted = {client.submit(jobs.grade_on_worker, *p, pure=False): p for p in payloads}
        batches.owners.update({future: job[1:3] for future, job in submitted.items()})
        batches.while_jobs_run()
        pending = set(submitted)
        alone_since: float | None = None
        while pending:
            why = ""
            try:
                done = wait(pending, timeout=min(5.0, patience), return_when="FIRST_COMPLETED").done
            except TimeoutError:  # nothing finished meanwhile: is anyone still working?
                done = set()
                try:
                    workers = client.scheduler_info().get("workers", {})
                except Exception as error:  # noqa: BLE001 - the scheduler lost
                    why = " ".join(f"{type(error).__name__}: {error}".split())[:300]
                else:
                    alone_since = None if workers else (alone_since or time.monotonic())
                    if alone_since is not None and time.monotonic() - alone_since > patience:
                        why = f"no worker left in the cluster for {patience:g} s"
            except Exception as error:  # noqa: BLE001 - the scheduler lost: the rest is graded here
                why = " ".join(f"{type(error).__name__}: {error}".split())[:300]
            if why:
                batches.drain([], 0)  # what arrived is recorded first
                left = [future for future in submitted if future in pending]
                try:
                    client.cancel(left)  # a worker joining later must not grade them as well
                except Exception:  # noqa: BLE001 - a lost scheduler cancels nothing, and runs nothing
                    pass
                return [submitted[future] for future in left], why
            pending -= done
            batches.drain(done, len(pending))
    return [], ""


#: what every local worker imports before its first job (nbformat, nbconvert and nbgrader for the
#: cell-metadata check and the feedback pages: about 1.5 s of CPU per process; matplotlib's image
#: writer for the reports' image comparisons, 0.25 s); the workers are forked from a server
#: process that imported them once (:func:`worker_context`)
WORKER_PRELOAD = ("cvkit.course", "nbgrader.preprocessors", "nbgrader.apps", "nbconvert", "matplotlib.image")


def worker_context() -> Any:
    """The local workers' start method: ``forkserver``. Its server is a fresh interpreter (no
    inherited threads, memory or open files of this process, as with ``spawn``) that imports
    :data:`WORKER_PRELOAD` once; each worker is a fork of it, so a course graded in one process
    — several ``grade`` calls, two workers each — pays those imports once, not once per worker
    and call. Starting it here, before the instructor's own set-up, lets the imports run while
    this process loads the gradebook. A worker takes this process's environment as it is when
    its pool starts (:func:`_take_environment`), not the server's."""
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():  # Windows: each worker imports
        return multiprocessing.get_context("spawn")
    from multiprocessing import forkserver

    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(WORKER_PRELOAD))  # no effect once the server runs
    forkserver.ensure_running()
    return context


def _take_environment(environment: dict[str, str]) -> None:
    """A local worker's first step: the grading process's environment at the pool's start
    (``CVKIT_NO_SANDBOX``, the time limits, ...), which a worker forked from the server would
    otherwise take from the server's start."""
    os.environ.clear()
    os.environ.update(environment)


def _on_local_pool(batches: _Batches, payloads: list[tuple[Any, ...]], workers: int) -> None:
    pool = concurrent.futures.ProcessPoolExecutor(max_workers=max(1, workers), mp_context=worker_context(),
                                                  initializer=_take_environment, initargs=(dict(os.environ),))
    try:
        batches.pool = pool
        # the grading jobs are handed to the pool a few at a time (one waiting beyond the busy
        # workers, so that a worker never waits while the writer records), and the feedback pages
        # of each recorded batch (queued by drain) before the next ones: the pages are written
        # while grading goes on, and only the last batch's are left at the end
        waiting = list(payloads)
        pending: set[Future[ExecutedSubmission]] = set()

        def hand_out() -> None:
            while waiting and len(pending) < max(1, workers) + 1:
                job = waiting.pop(0)
                try:
                    future = pool.submit(grade_submission, *job)
                except Exception as error:  # noqa: BLE001 - a broken pool: the writer grades it (drain)
                    future = Future()
                    future.set_exception(error)
                batches.owners[future] = job[1:3]
                pending.add(future)

        hand_out()
        batches.while_jobs_run()
        while pending:
            done, _ = concurrent.futures.wait(pending, return_when=concurrent.futures.FIRST_COMPLETED)
            pending.difference_update(done)
            batches.drain(done, len(pending) + len(waiting))  # the batch's pages queued first
            hand_out()
        batches.feedback_done(wait=True)
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=False)  # nothing left to do: the workers exit while this process goes on


def _regrading(course: CourseState, jobs: list[tuple[str, str]], regrade: bool | Iterable[str]) -> list[tuple[str, str]]:
    """The submissions of ``jobs`` to grade now: new or changed ones, and those ``regrade`` names
    (True: all; else the assignments to regrade)."""
    if isinstance(regrade, (bool, type(None))):
        again: set[str] = {a for _, a in jobs} if regrade else set()
    else:
        again = {regrade} if isinstance(regrade, str) else set(regrade)
    return [(s, a) for s, a in jobs if a in again or not results.is_graded(course, s, a)]


def grade(course: CourseState, assignments: Iterable[str] | None = None, workers: int = 2, scheduler: str | None = None,
          progress_bar: bool = False, regrade: bool | Iterable[str] = False, batch: int | None = None,
          sandbox: bool = True) -> list[JobResult]:
    """See :meth:`Course.grade`. Each submission folder is read once in the run
    (:meth:`~.state.CourseState.one_read_per_submission`)."""
    with course.one_read_per_submission():
        return _grade(course, assignments, workers, scheduler, progress_bar, regrade, batch, sandbox)


def _grade(course: CourseState, assignments: Iterable[str] | None, workers: int, scheduler: str | None,
           progress_bar: bool, regrade: bool | Iterable[str], batch: int | None, sandbox: bool) -> list[JobResult]:
    from ..sandbox import isolation

    if sandbox:
        isolation.require()
        os.environ.pop("CVKIT_NO_SANDBOX", None)
        from ..sandbox.session import require_worker

        require_worker()  # the worker itself starts here: never a class of "ended early" zeros
    else:
        os.environ["CVKIT_NO_SANDBOX"] = "1"  # inherited by the grading workers
    course.claim_gradebook()  # before anything is written: never two courses in one gradebook
    found = course.submissions(assignments)
    outside = course.outside_plan(found)  # chapters not in the plan: listed as not graded, never a zero
    jobs = [(s, a) for s, a in found if f"{s}/{a}" not in outside]
    todo = _regrading(course, jobs, regrade)
    payloads = [payload(course, s, a) for s, a in todo]
    size = max(1, batch if batch is not None else max(2, workers))
    client = _connect(scheduler, payloads) if scheduler and payloads else None  # before anything is written
    if payloads:
        if client is None:
            worker_context()  # the workers' imports start now, beside this process's set-up
        try:
            course.nbgrader_api()  # load nbgrader and the configuration while the workers start
            course.sync_due_dates()
        except BaseException:
            if client is not None:
                client.close()
            raise
    bars = {"grade": Phase("grade", len(payloads), progress_bar and bool(payloads), unit="submission", position=0),
            "record": Phase("record", len(payloads), progress_bar and bool(payloads), unit="submission", position=1),
            "feedback": Phase("feedback", len(payloads), progress_bar and bool(payloads), unit="page", position=2)}
    batches = _Batches(course, size, workers, bars)
    batches.meanwhile.append(lambda: exports.export_similarity(course, None, progress_bar, position=3))
    if client is not None:
        left, why = _on_dask(batches, payloads, client)
        if left:  # never a lost submission: the local pool grades what the cluster did not
            print(f"cvkit: lost the Dask cluster at {scheduler} ({why}); grading the "
                  f"{len(left)} submission{'s' * (len(left) != 1)} left on this machine", file=sys.stderr, flush=True)
            _on_local_pool(batches, left, workers)
    elif payloads:
        _on_local_pool(batches, payloads, workers)
    bars["grade"].close()
    bars["record"].close()
    graded_now = batches.results
    missing = missing_before = results.audit(course, jobs)
    for student, assignment in progress(missing, "regrade (no grade recorded)", progress_bar and bool(missing),
                                        unit="submission"):
        # never lose a grade: one more, plain attempt
        graded_now = [r for r in graded_now if (r.student, r.assignment) != (student, assignment)]
        graded_now.append(batches.writer.record_many([grade_in_fresh_process(payload(course, student, assignment))])[0])
    missing = results.audit(course, jobs)
    graded_now += [JobResult(s, a, 1, 0, "no grade recorded after autograding") for s, a in missing]
    graded_now += [JobResult(s, a, 0, 1, f"not graded: {outside[f'{s}/{a}']}", executed=False,
                          not_graded=outside[f"{s}/{a}"]) for s, a in found if f"{s}/{a}" in outside]
    retried = [(r.student, r.assignment) for r in graded_now if r.ok and (r.student, r.assignment) in missing_before]
    not_graded = course.not_graded()
    graded = [(s, a) for s, a in jobs if f"{s}/{a}" not in not_graded]
    marked = marks.read(course, graded)  # once for the three uses below
    # pages missing, of a submission graded again, or whose hand marks changed since they were written
    pages = sorted({pair for pair in retried + [(s, a) for s, a in jobs if not (course.root / "feedback" / s / a).is_dir()]
                    if f"{pair[0]}/{pair[1]}" not in not_graded} | set(marks.stale_pages(course, graded, marked)))
    feedback = bars["feedback"]
    if pages and not feedback.enabled:
        feedback = Phase("feedback", 0, progress_bar, unit="page")
    feedback.set_total(feedback.done + len(pages))  # the estimate (a page per submission) made exact
    write_feedback(course, pages, feedback)
    feedback.close()
    marks.remember_pages(course, [(s, a) for s, a in graded if (course.root / "feedback" / s / a).is_dir()], marked)
    marks.log_changes(course, graded, marked)
    batches.while_jobs_run(last_chance=True)  # the similarity report, if no job ran or it failed then
    with course.scores_read_once():  # nothing is recorded from here on
        exports.export(course, progress_bar)
        item_analysis.export(course)  # exports/item_analysis.csv and .html
        class_notes.annotate_feedback(course)  # plan.toml [class_notes]: off by default
        leaderboard.publish(course)  # plan.toml [leaderboard]: off by default, opt-in by each student
    return sorted(graded_now, key=lambda r: (r.assignment, r.student))


def refresh(course: CourseState, progress_bar: bool = False) -> list[tuple[str, str]]:
    """See :meth:`Course.refresh`."""
    with course.one_read_per_submission():
        return _refresh(course, progress_bar)


def _refresh(course: CourseState, progress_bar: bool) -> list[tuple[str, str]]:
    not_graded = course.not_graded()
    graded = [(s, a) for s, a in course.submissions() if f"{s}/{a}" not in not_graded and results.is_graded(course, s, a)]
    marked = marks.read(course, graded)
    pages = marks.stale_pages(course, graded, marked)
    bar = Phase("feedback", len(pages), progress_bar and bool(pages), unit="page")
    write_feedback(course, pages, bar)
    bar.close()
    marks.remember_pages(course, [(s, a) for s, a in graded if (course.root / "feedback" / s / a).is_dir()], marked)
    marks.log_changes(course, graded, marked)
    with course.scores_read_once():
        exports.export(course, progress_bar)
        item_analysis.export(course)  # the marks changed the scores
        class_notes.annotate_feedback(course)  # the pages written again lost their notes
        leaderboard.publish(course)  # and their leaderboard
    return pages
