"""The trusted side of a sandboxed run: a student's answer cells and their cases.

:func:`run_calls` starts the worker (:mod:`cvkit.grading.runtime.worker`) inside the
operating-system sandbox (:mod:`cvkit.sandbox.isolation`), with the Python standard library,
NumPy and :mod:`cvkit.grading.runtime` only — no cvkit reference, no SciPy, scikit-image,
OpenCV, Pillow, scikit-learn or torch. It then drives the conversation:

- the answer cells run one by one, each under a wall-clock limit kept *here*: a cell that
  sleeps is stopped, reported, and skipped on the next start, so only what it defined is lost;
- the cases are sent one at a time (the worker never sees a case before it runs), each under
  its check's time limit plus a small grace, measured here on the wall clock — the time this
  side spends serving the case's requests included, so that a student cannot ignore the limit
  nor hide slow work behind requests;
- a building block the current case allows (``filters.pad``, or a data loader that is not
  itself the exercise's answer: the call's ``allowed``, decided by :mod:`.trusted`) is
  computed on this side by the :class:`~cvkit.sandbox.reference_server.ReferenceServer` and
  sent back as data, at most :data:`MAX_REQUESTS` times per case; any other id is refused and
  reported as a forbidden call;
- the whole run has a deadline (``total_seconds``: every cell, case and restart of one
  notebook, cascades included when the caller passes the same deadline on); what has not run
  when it passes fails with the reason;
- messages are size-capped JSON, refused *before* they are parsed when they are too long or
  made of too many parts (:func:`parse_message`); anything malformed, too large or out of
  turn ends the sandbox, and the call that was running fails with the reason;
- if the student's code kills the worker, or a case runs out of time, the sandbox is killed
  (all its processes with it) and the remaining cases run in a fresh one — except the other
  cases of the check call (the call's ``group``) whose case did not return: they are not run at all
  (``"not run: …"``), so an endless loop costs one time limit per check call; two crashes of
  the worker end a call the same way.

Comparison with the reference happens back in the trusted process (:mod:`.trusted`).
"""
from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import registry
from . import isolation
from ..grading.served import DATA_LOADERS, DATA_SOURCES
from .reference_server import ReferenceServer
from ..grading.runtime import wire
from ..grading.runtime.guard import Outcome, timeout_message

RUNTIME_DIR = Path(__file__).resolve().parent.parent / "grading" / "runtime"
INSIDE = "/opt/cvkit"            # where the runtime and NumPy appear inside the sandbox
STARTUP_SECONDS = 60.0           # bubblewrap, Python and NumPy on a loaded machine
GRACE_SECONDS = 1.0              # a case's result may arrive this late (encoding, transfer)
KILL_GRACE_SECONDS = 3.0         # after this, the sandbox is killed
OUTPUT_TAIL = 20000              # characters of the worker's own stdout/stderr kept
MAX_LINE = 2 * wire.MAX_BYTES    # one protocol message (base64 is 4/3 of the data)
#: JSON parts (objects, arrays, members) of one message: an array travels as one base64 string,
#: so honest messages have few; a line of millions of tiny parts would cost the grader gigabytes
#: to parse (``[1,1,1,…]``: about 20 bytes of Python objects per 2 bytes of text)
MAX_PARTS = 200_000
MAX_REQUESTS = 1000              # building-block and data requests of one case


def answer_cell_seconds() -> float:
    """One answer cell's limit (answer cells define functions): ``CVKIT_ANSWER_CELL_TIMEOUT``,
    default 60 s. Read at each run, as every limit the caller's environment sets: a grading
    worker may have been forked from a process started before the caller set it."""
    return float(os.environ.get("CVKIT_ANSWER_CELL_TIMEOUT", "60"))


def notebook_seconds() -> float:
    """The deciding run of one notebook — its cells, cases and restarts, cascades included:
    ``CVKIT_NOTEBOOK_GRADING_SECONDS``, default 900 s (read at each run)."""
    return float(os.environ.get("CVKIT_NOTEBOOK_GRADING_SECONDS", "900"))


@dataclass
class SandboxResult:
    """Outcomes of the requested calls, and what happened to the notebook's cells."""

    outcomes: list
    cell_errors: list = field(default_factory=list)
    crashed: str | None = None
    output: str = ""
    started: bool = True
    refused: list = field(default_factory=list)   # imports the allow-list refused
    sandboxed: bool = True
    exhausted: bool = False   # the run's deadline passed before every call had run


class _Replace(Exception):
    """A case ran out of time inside the worker: go on in a fresh one (nothing half-done is kept)."""


class _Stopped(Exception):
    """The sandbox ended, broke the protocol or ran out of time (``reason`` says which)."""

    def __init__(self, reason: str, timed_out: bool = False, exhausted: bool = False):
        super().__init__(reason)
        self.reason = reason
        self.timed_out = timed_out
        self.exhausted = exhausted   # the whole run's deadline has passed: nothing more runs


def parse_message(line: bytes) -> tuple[str, object]:
    """One line of the worker's channel as ``("message", dict)`` or ``("bad", why)``.

    The size and the number of JSON parts are checked on the raw bytes *before* parsing, so a
    hostile line costs the grader at most its own length in memory."""
    if len(line) > MAX_LINE or not line.endswith(b"\n"):
        return "bad", f"sent a message larger than {MAX_LINE >> 20} MB"
    parts = line.count(b",") + line.count(b"{") + line.count(b"[")
    if parts > MAX_PARTS:
        return "bad", f"sent a message of {parts} parts (at most {MAX_PARTS}: return NumPy arrays, not long lists)"
    try:
        item = json.loads(line)
    except ValueError:
        return "bad", "sent a malformed message (the student's code wrote to the grader's channel)"
    return ("message", item) if isinstance(item, dict) else ("bad", "sent a malformed message")


def _runtime_paths(sandboxed: bool) -> tuple[list, str, str | None]:
    """Read-only mounts of the runtime and NumPy, the folder to put on ``sys.path`` inside,
    and (without a sandbox) a temporary folder of links standing in for those mounts."""
    import numpy

    numpy_dir = Path(numpy.__file__).resolve().parent
    pieces = [(RUNTIME_DIR, "cvkit_runtime"), (numpy_dir, "numpy")]
    libs = numpy_dir.parent / "numpy.libs"
    if libs.is_dir():
        pieces.append((libs, "numpy.libs"))
    if sandboxed:
        return [(str(source), f"{INSIDE}/{name}") for source, name in pieces], INSIDE, None
    links = tempfile.mkdtemp(prefix="cvkit-runtime-")
    for source, name in pieces:
        os.symlink(source, os.path.join(links, name))
    return [], links, links


def base_python() -> str:
    """The base installation's own interpreter (real path), which the worker runs: a virtual
    environment is not bound into the worker's sandbox, only the installation it was made from
    (:func:`cvkit.sandbox.isolation.system_mounts`). ``sys._base_executable`` names it from
    Python 3.11 on; before (3.10) it is the environment's own ``python``, a file of the
    environment in a ``--copies`` one (as ``scripts/_venv.py`` makes them): then the
    installation's ``bin/pythonX.Y``."""
    base = os.path.realpath(sys.base_prefix)
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    for candidate in (getattr(sys, "_base_executable", None), os.path.join(base, "bin", version),
                      os.path.join(base, "bin", f"python{sys.version_info.major}")):
        if candidate and os.path.isfile(candidate) and isolation.within(os.path.realpath(candidate), base):
            return os.path.realpath(candidate)
    return os.path.realpath(getattr(sys, "_base_executable", None) or sys.executable)


def worker_interpreter() -> tuple[str, list[tuple[str, str]], list[str]]:
    """The Python the grading worker runs, the read-only binds it needs besides the system's,
    and the package folders hidden from it (behind an empty tmpfs: only NumPy is bound, at
    :data:`INSIDE`).

    The base installation's interpreter (:func:`base_python`) brings no virtual
    environment's packages along. Where this user cannot reach it — a virtual environment made
    with ``--copies`` from a Python in another user's home — the environment's own interpreter
    runs instead, its folder bound read-only and its package folders hidden."""
    hidden = isolation.site_packages_of_the_system()
    base = base_python()
    if os.access(base, os.X_OK):
        return base, [], hidden
    prefix = os.path.realpath(sys.prefix)
    packages = [str(path) for pattern in ("lib/python*/site-packages", "lib64/python*/site-packages")
                for path in sorted(Path(prefix).glob(pattern)) if path.is_dir()]
    return os.path.realpath(sys.executable), [(prefix, prefix)], hidden + packages


_worker_checked: dict = {}


def require_worker() -> None:
    """Raise :class:`~cvkit.sandbox.isolation.SandboxUnavailable`, with what the sandbox said,
    unless the grading worker starts and answers a call in the sandbox on this machine (checked
    once per process). Grading refuses to start rather than record every answer as a worker
    that "ended early"."""
    if isolation.sandbox_disabled():
        return
    if "reason" not in _worker_checked:
        result = run_calls(["def _cvkit_probe(x):\n    return x + 1"],
                           [wire.BoxCall("_cvkit_probe", args=(1,), time_limit=60.0)],
                           max_restarts=0)
        outcome = result.outcomes[0]
        _worker_checked["reason"] = None if outcome.ok and outcome.value == 2 else (
            f"the grading worker cannot run in the sandbox on this machine ({outcome.error}); the sandbox said: "
            f"{result.output.strip()[-500:] or 'nothing'}")
    if _worker_checked["reason"]:
        raise isolation.SandboxUnavailable(_worker_checked["reason"])


class _Session:
    """One sandboxed worker and the threads that read its streams."""

    def __init__(self, memory_mb: int, sandboxed: bool, deadline: float = float("inf")):
        self.deadline = deadline
        mounts, path, self._links = _runtime_paths(sandboxed)
        read_fd, write_fd = os.pipe()
        python, binds, masked = worker_interpreter()
        bootstrap = f"import sys; sys.path.insert(0, {path!r}); from cvkit_runtime.worker import main; main()"
        env = {"CVKIT_PROTOCOL_FD": str(write_fd), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
               "MKL_NUM_THREADS": "1", "PYTHONDONTWRITEBYTECODE": "1", "LANG": "C.UTF-8"}
        limits = isolation.Limits(memory_mb=memory_mb, cpu_seconds=3600, processes=16, file_mb=16, tmpfs_mb=64)
        try:
            self.box = isolation.Sandbox(
                [python, "-I", "-S", "-B", "-c", bootstrap],
                mounts=isolation.Mounts(read_only=binds + mounts, with_environment=False, masked=masked),
                limits=limits, env=env, sandboxed=sandboxed,
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, pass_fds=(write_fd,),
            )
        finally:
            os.close(write_fd)
        self.messages: queue.Queue = queue.Queue()
        self.tail = bytearray()
        self._reader = threading.Thread(target=self._read_messages, args=(read_fd,), daemon=True)
        self._drain = threading.Thread(target=self._read_output, daemon=True)
        self._reader.start()
        self._drain.start()

    def _read_messages(self, fd: int) -> None:
        with os.fdopen(fd, "rb", buffering=1 << 16) as stream:
            while True:
                line = stream.readline(MAX_LINE + 1)
                if not line:
                    self.messages.put(("end", None))
                    return
                kind, item = parse_message(line)
                del line
                self.messages.put((kind, item))
                if kind == "bad":
                    return

    def _read_output(self) -> None:
        stream = self.box.process.stdout
        while stream is not None:
            block = stream.read1(1 << 16) if hasattr(stream, "read1") else stream.read(1 << 16)
            if not block:
                return
            self.tail += block
            if len(self.tail) > 2 * OUTPUT_TAIL:
                del self.tail[:-OUTPUT_TAIL]

    @property
    def output(self) -> str:
        return bytes(self.tail[-OUTPUT_TAIL:]).decode("utf-8", "replace")

    def send(self, item: dict) -> None:
        stdin = self.box.process.stdin
        try:
            if stdin is None:
                raise ValueError("the sandbox has no input")
            stdin.write((json.dumps(item) + "\n").encode())
            stdin.flush()
        except (OSError, ValueError):
            raise _Stopped(self._death()) from None

    def receive(self, timeout: float, what: str) -> dict:
        left = self.deadline - time.monotonic()
        try:
            kind, item = self.messages.get(timeout=max(0.0, min(timeout, left)))
        except queue.Empty:
            if left <= timeout:
                raise _Stopped(EXHAUSTED, timed_out=True, exhausted=True) from None
            raise _Stopped(f"{what} ran longer than its limit and was stopped", timed_out=True) from None
        if kind == "end":
            raise _Stopped(self._death())
        if kind == "bad":
            raise _Stopped(f"the graded code {item}")
        return item

    def _death(self) -> str:
        try:
            status = self.box.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            status = None
        if status is not None and status < 0:
            return f"the code was killed by signal {-status} (memory, CPU time or file-size limit, or a crash)"
        return (f"the grading worker ended early (exit status {status}): the code called exit(), "
                "crashed the interpreter or exhausted its memory")

    def close(self) -> None:
        """End the box; then everything it printed has been read (:attr:`output` is whole)."""
        self.box.close()
        self._reader.join(timeout=5)
        self._drain.join(timeout=5)  # every process of the box is dead: its output ends here
        if self._links:
            import shutil

            shutil.rmtree(self._links, ignore_errors=True)


def _not_run(calls: list, stalled: int | None) -> str:
    """Why a call was not run: an earlier case of its check did not return in time (``stalled``,
    the index of that call), or two crashed the worker."""
    if stalled is None:
        return "not run: two earlier cases of this check crashed the grading worker"
    limit = float(calls[stalled].time_limit)
    return (f"not run: an earlier case did not return within {limit:g} s, so the rest of this check was skipped "
            "(see that case)")


#: what a cell (not a case) may have computed outside: the data sources, never a building block
CELL_HELPERS = frozenset(f"data.{name}" for name in DATA_SOURCES)
EXHAUSTED = "the notebook's grading time ran out (every cell and case of one notebook, in all)"


def _blank(value: Any) -> Any:
    """``value`` with every array replaced by zeros of its shape and dtype (containers kept)."""
    if isinstance(value, np.ndarray):
        return np.zeros_like(value)
    if isinstance(value, (tuple, list)):
        return type(value)(_blank(v) for v in value)
    if isinstance(value, dict):
        return {k: _blank(v) for k, v in value.items()}
    return value


def _serve(session: _Session, message: dict, allowed: set | frozenset, budget: float, refused: list,
           count: int, blanked: frozenset = frozenset()) -> None:
    """Answer one building-block request (the ``count``-th of this case) within ``budget`` seconds;
    an id in ``blanked`` is answered with zeros of its value's shape."""
    identifier = str(message.get("rpc"))[:200]
    if count > MAX_REQUESTS:
        note = f"more than {MAX_REQUESTS} requests for cvkit's building blocks in one case"
        if note not in refused:
            refused.append(note)
        reply = {"error": f"{note}: compute what you need yourself"}
    elif identifier not in allowed:
        what = f"cvkit reference implementation of {identifier!r}"
        if what not in refused:
            refused.append(what)
        reply = {"error": f"{identifier} is not allowed in this exercise: write it yourself"}
    else:
        reply = ReferenceServer.shared().call(identifier, message.get("args"), message.get("kwargs"),
                                              timeout=max(0.1, budget))
        if identifier in blanked and "value" in reply:
            reply = {"value": wire.encode(_blank(wire.decode(reply["value"])))}
    session.send(reply)


def run_calls(
    cells: list[str],
    calls: list[wire.BoxCall],
    *,
    blocks: tuple = (),
    memory_mb: int = 3072,
    max_restarts: int = 8,
    sandboxed: bool | None = None,
    cell_seconds: float | None = None,
    deadline: float | None = None,
    blank_for_cells: frozenset | None = None,
) -> SandboxResult:
    """Execute ``cells`` in a sandboxed worker, then each of ``calls``
    (:class:`~cvkit.grading.runtime.wire.BoxCall`) in order; see the module docstring.

    ``blocks`` are the algorithm ids some call may use as building blocks; each call lists the
    ids it really may use in ``allowed`` (building blocks and ``"data.<loader>"``; a call
    whose ``allowed`` is None may use the data loaders only). A call's outcome is ``None`` only if it
    was never reached (it then fails with the reason). ``deadline`` (``time.monotonic()``
    seconds; default :func:`notebook_seconds` from now) ends the whole run, restarts included.
    ``cell_seconds`` is each answer cell's limit (default :func:`answer_cell_seconds`).
    ``sandboxed=False`` (``--no-sandbox``) runs the same worker with resource limits only.

    A cell may load the data sources (:data:`CELL_HELPERS`), and what it keeps in a global
    every case can read — as can a case of another exercise that may load it. When the cells or
    the cases loaded a source that some call may not use itself (the clean pictures
    ``filters.denoise`` is measured on), those calls run again in a fresh
    sandbox whose cells get that source blank (zeros of its shape and dtype:
    ``blank_for_cells``), and their outcomes are that run's: a lookup table filled at the top
    of the notebook then holds nothing, while the cells still run to their end, so a function
    that does not depend on the picture is graded as before.
    """
    deadline = time.monotonic() + notebook_seconds() if deadline is None else deadline
    cell_seconds = answer_cell_seconds() if cell_seconds is None else cell_seconds
    sandboxed = (not isolation.sandbox_disabled()) if sandboxed is None else sandboxed
    if sandboxed:
        isolation.require()
    run = _Run.prepare(cells, calls, blocks, sandboxed, cell_seconds, deadline, frozenset(blank_for_cells or ()))
    restarts = 0
    while restarts <= max_restarts and time.monotonic() < deadline:
        restarts += 1
        session = _Session(memory_mb, sandboxed, deadline)
        run.current = None
        stopped = False
        try:
            run.start_cells(session)
            run.take_ready(session)
            run.run_pending(session)
            session.send({"end": True})
            break
        except _Replace:
            restarts -= 1  # a timeout is not a crash: it does not use up the restarts
            continue
        except _Stopped as stop:
            stopped = True
            if not run.goes_on_after(stop):
                break
        finally:
            session.close()  # before its output is read: a box that died at once said why on its way out
            run.result.output = session.output if stopped else (run.result.output or session.output)
    run.settle_the_rest()
    if blank_for_cells is None:  # (a run again happens once: what the cells load is known then)
        _again_without_answering_data(run, cells, calls, blocks, memory_mb, max_restarts, sandboxed, cell_seconds,
                                      deadline)
    return run.result


def _again_without_answering_data(run: "_Run", cells: list[str], calls: list[wire.BoxCall], blocks: tuple,
                                  memory_mb: int, max_restarts: int, sandboxed: bool, cell_seconds: float,
                                  deadline: float) -> None:
    """The calls that may not use some data source the cells (or another exercise's cases) loaded,
    run again with cells that get it blank (see :func:`run_calls`); their outcomes replace the
    first ones. Only those calls run again: no other exercise's case can load it there."""
    loaded = run.loads & CELL_HELPERS
    denied_to = {i: loaded - set(call.allowed) for i, call in enumerate(calls)
                 if call.allowed is not None and loaded - set(call.allowed)}
    if not denied_to:
        return
    denied = frozenset().union(*denied_to.values())
    indices = sorted(denied_to)
    again = run_calls(cells, [calls[i] for i in indices], blocks=blocks, memory_mb=memory_mb, max_restarts=max_restarts,
                      sandboxed=sandboxed, cell_seconds=cell_seconds, deadline=deadline,
                      blank_for_cells=denied)
    for i, outcome in zip(indices, again.outcomes):
        run.result.outcomes[i] = outcome
    run.result.exhausted = run.result.exhausted or again.exhausted
    if again.crashed and not run.result.crashed:
        run.result.crashed = again.crashed


def _answer_requests(session: _Session, started: float, seconds: float, what: str, allowed: set | frozenset,
                     refused: list, asked: set | None = None, blanked: frozenset = frozenset()) -> dict:
    """Serve the box's requests until it sends another message (returned), ``seconds`` after ``started`` at most
    (the allowed ids requested are added to ``asked``; those in ``blanked`` are answered with zeros)."""
    requests = 0
    while True:  # the wall clock, serving included: the time is all of it
        message = session.receive(seconds - (time.monotonic() - started), what)
        if "rpc" not in message:
            return message
        requests += 1
        if asked is not None and str(message.get("rpc"))[:200] in allowed:
            asked.add(str(message.get("rpc"))[:200])
        _serve(session, message, allowed, seconds - (time.monotonic() - started), refused, requests, blanked)


@dataclass
class _Run:
    """One :func:`run_calls` under way: its calls, their outcomes, and what a fresh sandbox keeps."""

    cells: list[str]
    calls: list[wire.BoxCall]
    encoded: list[dict]                     # the calls as they are sent (encoded once, before any sandbox)
    opening: dict                           # the first message but its cells: building blocks, data, topics
    cell_seconds: float
    deadline: float                         # ``time.monotonic()`` seconds: the end of the whole run
    result: SandboxResult
    blank_for_cells: frozenset = frozenset()       # data the cells get as zeros
    loads: set = field(default_factory=set)        # the data ids served to the cells and the cases
    skipped_cells: set[int] = field(default_factory=set)
    strikes: dict[str, int] = field(default_factory=dict)   # group → cases that killed the worker
    stalled: dict[str, int] = field(default_factory=dict)   # group → its first call that did not return in time
    pending: list[int] = field(default_factory=list)
    current: int | None = None              # the call running now

    @classmethod
    def prepare(cls, cells: list[str], calls: list[wire.BoxCall], blocks: tuple, sandboxed: bool,
                cell_seconds: float, deadline: float, blank_for_cells: frozenset = frozenset()) -> "_Run":
        """The run before its first sandbox: the calls encoded, nothing decided yet."""
        wrong = next((call for call in calls if not isinstance(call, wire.BoxCall)), None)
        if wrong is not None:
            raise TypeError(f"calls: expected cvkit.grading.runtime.wire.BoxCall objects, got a {type(wrong).__name__}")
        encoded = [call.to_wire() for call in calls]
        result = SandboxResult([None] * len(calls), sandboxed=sandboxed, started=False)
        # the worker's stand-ins for cvkit's modules
        opening = {"blocks": sorted(blocks), "data": list(DATA_LOADERS), "topics": registry.topic_modules()}
        return cls(cells, calls, encoded, opening, cell_seconds, deadline, result, blank_for_cells=blank_for_cells,
                   pending=list(range(len(calls))))

    @property
    def outcomes(self) -> list:
        """The calls' outcomes so far (None: not decided yet)."""
        return self.result.outcomes

    def start_cells(self, session: _Session) -> None:
        """Send the cells (those stopped before left out) and see each of them run."""
        session.send({"cells": [("pass  # stopped: ran longer than its limit" if i in self.skipped_cells else c)
                                for i, c in enumerate(self.cells)], **self.opening})
        for index in range(len(self.cells)):
            if session.receive(STARTUP_SECONDS if index == 0 else self.cell_seconds,
                               "starting the sandbox").get("cell") != index:
                raise _Stopped("the graded code sent a message out of turn")
            self._run_cell(session, index)

    def _run_cell(self, session: _Session, index: int) -> None:
        """One cell under its wall-clock limit, serving its data requests; a cell stopped is skipped from now on."""
        try:
            # a cell may load data (a demo the student added): served like a case's
            message = _answer_requests(session, time.monotonic(), self.cell_seconds, f"cell {index}",
                                       CELL_HELPERS, [], self.loads, self.blank_for_cells)
            if message.get("cell_done") != index:
                raise _Stopped("the graded code sent a message out of turn")
        except _Stopped as stop:
            self.skipped_cells.add(index)
            note = (f"cell {index}: ran longer than {self.cell_seconds:g} s and was stopped (what it defines is "
                    "missing)" if stop.timed_out else f"cell {index}: {stop.reason}")
            self.result.cell_errors.append(note)
            raise

    def take_ready(self, session: _Session) -> None:
        """The worker's word that the cells ran: their errors and the imports it refused."""
        result = self.result
        ready = session.receive(STARTUP_SECONDS if not self.cells else self.cell_seconds, "starting the sandbox")
        if not ready.get("ready"):
            raise _Stopped("the graded code sent a message out of turn")
        result.cell_errors = [e for e in result.cell_errors if "was stopped" in e or "ended early" in e
                              or "killed" in e] + [str(e)[:400] for e in ready.get("cell_errors", [])][:50]
        result.refused = [str(r)[:200] for r in ready.get("refused", [])][:20]
        result.started = True

    def run_pending(self, session: _Session) -> None:
        """The calls not decided yet, in order, until one does not return in time (then: a fresh sandbox)."""
        while self.pending:
            current = self.current = self.pending[0]
            group = self.calls[current].check_group
            if group in self.stalled or self.strikes.get(group, 0) >= 2:
                # one case of this check did not return in time, or two crashed the worker: the
                # rest of the check is not run (an endless loop costs one time limit, not one per case)
                self.outcomes[current] = Outcome(error=_not_run(self.calls, self.stalled.get(group)),
                                                 exception="NotRun", from_grader=True)
                self.pending.pop(0)
                self.current = None
                continue
            outcome = self._run_call(session, current)
            self.outcomes[current] = outcome
            self.pending.pop(0)
            if outcome.timed_out:
                self._skip_the_rest_of(group, current)
            self.current = None
            if outcome.timed_out and self.pending:
                raise _Replace()

    def _run_call(self, session: _Session, index: int) -> Outcome:
        """One call under its time limit on the wall clock, serving included, with the building blocks it may use."""
        call = self.calls[index]
        limit = float(call.time_limit)
        allowed = set(call.allowed) if call.allowed is not None else {f"data.{name}" for name in DATA_SOURCES}
        refused: list = []
        session.send({"call": self.encoded[index]})
        started = time.monotonic()
        message = _answer_requests(session, started, limit + KILL_GRACE_SECONDS, "this case", allowed, refused,
                                   self.loads)
        if "outcome" not in message or not isinstance(message["outcome"], dict):
            raise _Stopped("the graded code sent a message out of turn")
        outcome = Outcome.from_json(message["outcome"])
        outcome.forbidden_calls += [r for r in refused if r not in outcome.forbidden_calls]
        used = time.monotonic() - started
        if used > limit + GRACE_SECONDS and not outcome.timed_out:
            outcome = Outcome(error=timeout_message(limit), exception="Timeout", timed_out=True, from_grader=True)
        return outcome

    def _skip_the_rest_of(self, group: str, stalled: int) -> None:
        """The pending calls of the check whose call ``stalled`` did not return: not run (no fresh sandbox for them)."""
        self.stalled.setdefault(group, stalled)
        for index in [i for i in self.pending if self.calls[i].check_group == group]:
            self.outcomes[index] = Outcome(error=_not_run(self.calls, stalled), exception="NotRun", from_grader=True)
            self.pending.remove(index)

    def goes_on_after(self, stop: _Stopped) -> bool:
        """Record why the sandbox stopped; whether a fresh one may take over the calls still pending."""
        result = self.result
        if stop.exhausted:
            result.exhausted = True
            result.crashed = stop.reason
            return False
        current = self.current
        if current is None:
            if not result.started and not self.skipped_cells:
                # the sandbox itself, or the cells, cannot get going: no retry helps
                result.crashed = stop.reason
                result.started = False
                return False
            return True  # a cell was stopped: start again without it
        call = self.calls[current]
        group = call.check_group
        if stop.timed_out:
            self.stalled.setdefault(group, current)
        else:
            self.strikes[group] = self.strikes.get(group, 0) + 1
        self.outcomes[current] = Outcome(error=timeout_message(float(call.time_limit)) if stop.timed_out
                                         else f"no result: {stop.reason}",
                                         exception="Timeout" if stop.timed_out else "WorkerDied",
                                         timed_out=stop.timed_out, from_grader=True)
        result.crashed = stop.reason
        self.pending.pop(0)
        return bool(self.pending)

    def settle_the_rest(self) -> None:
        """Every call never reached fails with the reason: the run's deadline, or too many restarts."""
        result = self.result
        if any(outcome is None for outcome in self.outcomes) and time.monotonic() >= self.deadline:
            result.exhausted = True
        for index, outcome in enumerate(self.outcomes):
            if outcome is None and result.exhausted:
                self.outcomes[index] = Outcome(error=f"not run: {EXHAUSTED}", exception="Timeout", timed_out=True,
                                               from_grader=True)
            elif outcome is None:
                self.outcomes[index] = Outcome(error=f"no result: {result.crashed or 'the grading worker stopped'} "
                                                     "(too many restarts)", exception="WorkerDied", from_grader=True)
