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
) -> SandboxResult:
    """Execute ``cells`` in a worker, then each call ``{"function", "args", "kwargs", ...}``.

    ``allowed`` maps algorithm ids to ``"module:function"`` reference building blocks that
    some call may use (exposed to the student's code as ``cvkit.<module>.<name>``); each call
    lists the subset it may really use in ``"allowed"``. ``blocked`` are module prefixes the
    worker must refuse to import.
    """
    request = {
        "cells": [_strip_magics(c) for c in cells],
        "calls": [dict(call, args=wire.encode(tuple(call["args"])), kwargs=wire.encode(dict(call["kwargs"])))
                  for call in calls],
        "allowed": allowed or {},
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
    try:
        answer = json.loads(raw.decode("utf-8")) if raw else None
    except ValueError:
        answer = None
    if not isinstance(answer, dict):
        reason = crashed or (
            f"the grading worker ended without an answer (exit status {process.returncode}): your code "
            "may have called exit(), crashed the interpreter or exhausted its memory"
        )
        return SandboxResult([None] * len(calls), [], reason, text_output)
    outcomes = []
    for item in answer.get("outcomes", []):
        outcomes.append(None if item is None else _outcome_from(item))
    outcomes += [None] * (len(calls) - len(outcomes))
    if crashed is None and any(o is None for o in outcomes):
        crashed = answer.get("crashed") or "the grading worker stopped before all cases ran"
    return SandboxResult(outcomes[: len(calls)], list(answer.get("cell_errors", [])), crashed, text_output)


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

    outcomes = []
    for call in request["calls"]:
        function = namespace.get(call["function"])
        if not callable(function):
            outcomes.append({"error": f"no function called {call['function']!r} is defined (did its cell run?)",
                             "exception": "NameError"})
            continue
        try:
            args = wire.decode(call["args"])
            kwargs = wire.decode(call["kwargs"])
        except wire.WireError as exc:
            outcomes.append({"error": f"grader error decoding the case: {exc}"})
            continue
        outcome = _guard.run_guarded(
            function, args, kwargs,
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
        outcomes.append(item)
    data = json.dumps({"outcomes": outcomes, "cell_errors": cell_errors}).encode()
    view = memoryview(data)
    while view:
        written = os.write(result_fd, view)
        view = view[written:]
    os.close(result_fd)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":  # pragma: no cover
    _worker_main(int(sys.argv[1]))
