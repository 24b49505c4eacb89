"""Run a student's code in a fresh, isolated worker process and bring back only its outputs.

The trusted grader (nbgrader's autograde process, see :mod:`cvkit.grading.nbgrader_plugins`)
never trusts anything computed in the student's kernel. For each notebook it starts one
worker (``python -I -m cvkit.grading.sandbox``) that

- gets its request on stdin and writes its answer to a private pipe (student prints go to a
  separate, bounded stream), all as JSON through :mod:`cvkit.grading.wire` (never pickle);
- runs with resource limits (address space, CPU time, file size), an empty scratch working
  directory, a scrubbed environment (no grading salt, no student id, no course paths), and,
  when the grader runs as root, as the unprivileged user ``nobody``;
- cannot import scikit-image, SciPy's ndimage/signal/spatial/optimize, OpenCV, scikit-learn,
  PyTorch or cvkit's reference modules (an import hook refuses them); the few reference
  building blocks a check allows are handed over as plain functions, watched per call;
- executes the notebook's answer cells (and cells the student added), then calls the graded
  functions on the cases under :func:`cvkit.grading.guard.run_guarded`.

Comparison with the reference happens back in the trusted process, so monkeypatching NumPy,
``cvkit.grading`` or ``check`` inside the student's code changes nothing.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import threading
from dataclasses import dataclass, field
from typing import Any

from . import wire
from .guard import Outcome

NOBODY = 65534
_privilege_probe: dict = {}


@dataclass
class SandboxResult:
    """Outcomes of the requested calls (``None`` where the worker never got to a call)."""

    outcomes: list
    cell_errors: list = field(default_factory=list)
    crashed: str | None = None
    output: str = ""
    started: bool = True  # the worker got through the notebook's cells


def _strip_magics(source: str) -> str:
    return "\n".join("pass  # magic" if line.lstrip().startswith(("%", "!")) else line for line in source.splitlines())


def _worker_env(scratch: str) -> dict:
    keep = {k: os.environ[k] for k in ("PATH", "LANG", "LC_ALL", "SYSTEMROOT") if k in os.environ}
    keep.update(HOME=scratch, TMPDIR=scratch, MPLBACKEND="Agg", OMP_NUM_THREADS="1",
                OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1", PYTHONDONTWRITEBYTECODE="1",
                MPLCONFIGDIR=os.path.join(scratch, ".mpl"))
    return keep


def _drop_privileges() -> None:  # runs in the child between fork and exec
    os.setgroups([])
    os.setgid(NOBODY)
    os.setuid(NOBODY)


def _can_drop_privileges() -> bool:
    """Root can run workers as ``nobody`` when that user can still import cvkit."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return False
    if "ok" not in _privilege_probe:
        try:
            done = subprocess.run(
                [sys.executable, "-I", "-c", "import cvkit.grading.sandbox"],
                preexec_fn=_drop_privileges, capture_output=True, timeout=60, cwd="/",
                env=_worker_env("/tmp"),
            )
            _privilege_probe["ok"] = done.returncode == 0
        except Exception:
            _privilege_probe["ok"] = False
    return _privilege_probe["ok"]


def run_calls(
    cells: list[str],
    calls: list[dict],
    *,
    allowed: dict[str, str] | None = None,
    blocked: tuple = (),
    memory_mb: int = 3072,
    extra_seconds: float = 60.0,
    max_restarts: int = 8,
) -> SandboxResult:
    """Execute ``cells`` in a worker, then each call ``{"function", "args", "kwargs", ...}``.

    ``allowed`` maps algorithm ids to ``"module:function"`` reference building blocks that
    some call may use (exposed to the student's code as ``cvkit.<module>.<name>``); each call
    lists the subset it may really use in ``"allowed"``. ``blocked`` are module prefixes the
    worker must refuse to import. If the student's code kills the worker (``os._exit``, a
    crash, the memory limit), the call that did it fails with the reason and the remaining
    calls run in a fresh worker, so one exercise cannot take the others down.
    """
    encoded = [dict(call, args=wire.encode(tuple(call["args"])), kwargs=wire.encode(dict(call["kwargs"])))
               for call in calls]
    outcomes: list = [None] * len(calls)
    cell_errors: list = []
    output = ""
    crashed = None
    deaths: dict[str, int] = {}
    pending = list(range(len(calls)))
    for _ in range(max_restarts + 1):
        part = _run_worker(cells, [encoded[i] for i in pending], allowed or {}, blocked, memory_mb, extra_seconds)
        cell_errors = cell_errors or part.cell_errors
        output = part.output
        finished = 0
        for item in part.outcomes:
            if item is None:
                break
            outcomes[pending[finished]] = item
            finished += 1
        if part.crashed is None:
            break
        crashed = part.crashed
        dead = pending[finished]  # the call that was running when the worker died
        died = Outcome(error=f"no result: {part.crashed}", exception="WorkerDied")
        outcomes[dead] = died
        remaining = pending[finished + 1:]
        if not part.started:  # the notebook's cells themselves kill the worker: no retry
            for index in remaining:
                outcomes[index] = died
            break
        function = calls[dead]["function"]
        deaths[function] = deaths.get(function, 0) + 1
        if deaths[function] >= 2:  # this function keeps killing the worker: stop calling it
            for index in remaining:
                if calls[index]["function"] == function:
                    outcomes[index] = died
            remaining = [i for i in remaining if calls[i]["function"] != function]
        pending = remaining
        if not pending:
            break
    for index, outcome in enumerate(outcomes):
        if outcome is None:
            outcomes[index] = Outcome(error=f"no result: {crashed} (too many restarts)", exception="WorkerDied")
    return SandboxResult(outcomes, cell_errors, crashed, output)


def _run_worker(cells, calls, allowed, blocked, memory_mb, extra_seconds) -> SandboxResult:
    """One worker process over ``calls``; stops early if the student's code kills it."""
    request = {
        "cells": [_strip_magics(c) for c in cells],
        "calls": calls,
        "allowed": allowed,
        "blocked": list(blocked),
        "memory_mb": memory_mb,
        "cpu_seconds": int(sum(c.get("time_limit", 20.0) for c in calls) + extra_seconds),
    }
    deadline = request["cpu_seconds"] + extra_seconds
    with tempfile.TemporaryDirectory(prefix="cvkit-worker-") as scratch:
        drop = _can_drop_privileges()
        if drop:
            os.chown(scratch, NOBODY, NOBODY)
        read_fd, write_fd = os.pipe()
        try:
            process = subprocess.Popen(
                [sys.executable, "-I", "-m", "cvkit.grading.sandbox", str(write_fd)],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                pass_fds=(write_fd,), cwd=scratch, env=_worker_env(scratch),
                preexec_fn=_drop_privileges if drop else None, start_new_session=True,
            )
        finally:
            os.close(write_fd)
        chunks: list[bytes] = []
        reader = threading.Thread(target=lambda: chunks.append(_read_all(read_fd)), daemon=True)
        reader.start()
        output = b""
        crashed = None
        try:
            output, _ = process.communicate(json.dumps(request).encode(), timeout=deadline)
        except subprocess.TimeoutExpired:
            _kill(process)
            output = (process.communicate()[0] or b"")
            crashed = f"the grading worker was stopped after {deadline:.0f} s"
        reader.join(timeout=30)
        os.close(read_fd)
        raw = chunks[0] if chunks else b""
    text_output = output[-20000:].decode("utf-8", "replace")
    outcomes: list = []
    cell_errors: list = []
    started = False
    # the worker streams one JSON line per finished call, so a crash loses only the call running
    for line in raw.decode("utf-8", "replace").splitlines():
        try:
            item = json.loads(line)
        except ValueError:
            break
        if not isinstance(item, dict):
            break
        if "cell_errors" in item:
            started = True
            cell_errors = [str(e) for e in item["cell_errors"]][:50]
        elif "outcome" in item and len(outcomes) < len(calls):
            outcomes.append(_outcome_from(item["outcome"]) if isinstance(item["outcome"], dict) else None)
    finished = len(outcomes) == len(calls)
    if not finished and crashed is None:
        crashed = (
            f"the grading worker ended early (exit status {process.returncode}): the code called exit(), "
            "crashed the interpreter or exhausted its memory"
        )
    outcomes += [None] * (len(calls) - len(outcomes))
    return SandboxResult(outcomes, cell_errors, None if finished else crashed, text_output, started)


def _read_all(fd: int) -> bytes:
    parts = []
    limit = 2 * wire.MAX_BYTES
    total = 0
    while True:
        block = os.read(fd, 1 << 20)
        if not block:
            break
        total += len(block)
        if total > limit:
            break
        parts.append(block)
    return b"".join(parts)


def _kill(process: subprocess.Popen) -> None:
    try:
        os.killpg(process.pid, 9)
    except (ProcessLookupError, PermissionError):
        process.kill()


def _outcome_from(item: dict) -> Outcome:
    outcome = Outcome()
    for key in ("error", "traceback", "exception", "stdout", "stderr"):
        value = item.get(key)
        outcome.__dict__[key] = value if value is None or isinstance(value, str) else str(value)
    outcome.elapsed = float(item.get("elapsed", 0.0))
    outcome.timed_out = bool(item.get("timed_out", False))
    outcome.modified = [str(x) for x in item.get("modified", [])]
    outcome.forbidden_calls = [str(x) for x in item.get("forbidden_calls", [])]
    outcome.warnings = [str(x) for x in item.get("warnings", [])][:20]
    if "value" in item and outcome.error is None:
        try:
            outcome.value = wire.decode(item["value"])
        except (wire.WireError, ValueError, TypeError, KeyError) as exc:
            outcome.error = f"returned something that cannot be graded ({exc})"
    return outcome


# ============================================================================ worker side
class _ImportBlocker:
    """A meta-path finder refusing modules the student's code must not use while graded."""

    def __init__(self, prefixes):
        self.prefixes = tuple(prefixes)

    def find_spec(self, fullname, path=None, target=None):
        if any(fullname == p or fullname.startswith(p + ".") for p in self.prefixes):
            raise ImportError(f"{fullname} cannot be imported while your code is graded: write it with NumPy")
        return None


_TOPICS = ("formation", "stereo", "filters", "noise", "edges", "features", "detection", "camera",
           "calibration", "warp", "learn", "nn", "train", "data")


def _stub_module(name: str, attributes: dict) -> Any:
    """A stand-in module holding only ``attributes``; anything else is explained, not found."""
    import types

    class StandIn(types.ModuleType):
        def __getattr__(self, attr):
            if attr.startswith("__"):
                raise AttributeError(attr)
            raise AttributeError(
                f"{name}.{attr} is not available while your code is graded "
                "(the reference implementations are off limits in exercises)"
            )

    module = StandIn(name, f"grading stand-in for {name}")
    module.__dict__.update(attributes)
    return module


def _worker_main(result_fd: int) -> None:  # pragma: no cover - runs in the worker process
    import resource

    request = json.loads(sys.stdin.read())
    sys.stdin.close()
    memory = int(request["memory_mb"]) * 1024 * 1024
    for limit, value in ((resource.RLIMIT_AS, memory), (resource.RLIMIT_CPU, int(request["cpu_seconds"])),
                         (resource.RLIMIT_FSIZE, 64 * 1024 * 1024), (resource.RLIMIT_CORE, 0)):
        try:
            resource.setrlimit(limit, (value, value))
        except (ValueError, OSError):
            pass

    import numpy as np  # noqa: F401  (loaded before the student's code)
    import importlib

    from cvkit.grading import guard as _guard

    # reference building blocks a check allows, taken before the reference modules are hidden
    allowed_functions: dict[str, Any] = {}
    for algorithm_id, target in request["allowed"].items():
        module_name, _, attr = target.partition(":")
        allowed_functions[algorithm_id] = getattr(importlib.import_module(module_name), attr)
    reference_codes = {fn.__code__: algorithm_id for algorithm_id, fn in allowed_functions.items()
                       if hasattr(fn, "__code__")}
    # how checks of classes call the candidate (Check.call), taken before cvkit is hidden
    adapters: dict[str, Any] = {}
    for call in request["calls"]:
        target = call.get("call")
        if target and target not in adapters:
            module_name, _, attr = target.partition(":")
            adapters[target] = getattr(importlib.import_module(module_name), attr)
    from cvkit.grading.checks import bind_call
    topics: dict[str, dict] = {}
    for algorithm_id, fn in allowed_functions.items():
        module, name = algorithm_id.split(".", 1)
        topics.setdefault(module, {})[name] = fn

    def student(algorithm_id):
        return lambda function: function

    def check(*args, **kwargs):
        return None

    stubs = {
        "cvkit": _stub_module("cvkit", {"student": student}),
        "cvkit.registry": _stub_module("cvkit.registry", {"student": student}),
        "cvkit.grading": _stub_module("cvkit.grading", {"check": check}),
    }
    stubs["cvkit"].registry = stubs["cvkit.registry"]
    stubs["cvkit"].grading = stubs["cvkit.grading"]
    for module in _TOPICS:
        stubs[f"cvkit.{module}"] = _stub_module(f"cvkit.{module}", topics.get(module, {}))
        setattr(stubs["cvkit"], module, stubs[f"cvkit.{module}"])
    blocked = tuple(request["blocked"])
    for name in list(sys.modules):
        if name == "cvkit" or name.startswith("cvkit.") or any(name == p or name.startswith(p + ".") for p in blocked):
            del sys.modules[name]
    sys.modules.update(stubs)
    # anything of cvkit beyond the stand-ins (cvkit.filters._linear, cvkit.course, ...) is refused
    internals = tuple(f"cvkit.{m}." for m in _TOPICS) + ("cvkit.grading.", "cvkit.registry.", "cvkit.course",
                                                          "cvkit.cli", "cvkit._validation")
    sys.meta_path.insert(0, _ImportBlocker(blocked + internals))

    namespace: dict = {"__name__": "__main__"}
    cell_errors = []
    for index, source in enumerate(request["cells"]):
        try:
            exec(compile(source, f"<cell {index}>", "exec"), namespace)
        except BaseException as exc:  # noqa: BLE001 - a broken cell is reported, not fatal
            if isinstance(exc, SystemExit):
                cell_errors.append(f"cell {index}: called exit()")
                continue
            cell_errors.append(f"cell {index}: {type(exc).__name__}: {str(exc)[:200]}")

    def emit(item) -> None:
        data = (json.dumps(item) + "\n").encode()
        view = memoryview(data)
        while view:
            written = os.write(result_fd, view)
            view = view[written:]

    emit({"cell_errors": cell_errors})
    timeouts: dict[str, int] = {}
    for call in request["calls"]:
        group = call.get("group", call["function"])
        if timeouts.get(group, 0) >= 2:
            emit({"outcome": {"error": "skipped: two earlier cases of this exercise ran out of time; "
                                       "vectorize with NumPy instead of looping over pixels",
                              "exception": "Timeout", "timed_out": True}})
            continue
        function = namespace.get(call["function"])
        if not callable(function):
            emit({"outcome": {"error": f"no function called {call['function']!r} is defined (did its cell run?)",
                              "exception": "NameError"}})
            continue
        try:
            args = wire.decode(call["args"])
            kwargs = wire.decode(call["kwargs"])
        except wire.WireError as exc:
            emit({"outcome": {"error": f"grader error decoding the case: {exc}"}})
            continue
        outcome = _guard.run_guarded(
            bind_call(adapters.get(call.get("call") or ""), function), args, kwargs,
            arg_names=tuple(call.get("arg_names", ())),
            time_limit=float(call.get("time_limit", 20.0)),
            forbidden_libraries=tuple(call.get("forbidden_libraries", ())),
            forbidden_functions=tuple(call.get("forbidden_functions", ())),
            allowed_ids=tuple(call.get("allowed", ())),
            reference_codes=reference_codes,
        )
        item = {
            "error": outcome.error, "traceback": outcome.traceback, "exception": outcome.exception,
            "elapsed": outcome.elapsed, "timed_out": outcome.timed_out, "modified": outcome.modified,
            "forbidden_calls": outcome.forbidden_calls, "warnings": outcome.warnings[:20],
            "stdout": outcome.stdout[-2000:], "stderr": outcome.stderr[-2000:],
        }
        if outcome.error is None:
            try:
                item["value"] = wire.encode(outcome.value)
            except wire.WireError as exc:
                item["error"] = f"returned something that cannot be graded: {exc}"
        if outcome.timed_out:
            timeouts[group] = timeouts.get(group, 0) + 1
        emit({"outcome": item})
    os.close(result_fd)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":  # pragma: no cover
    _worker_main(int(sys.argv[1]))
