"""The main program of the grading sandbox: the student's answer cells, then one case at a time.

It runs inside bubblewrap (:mod:`cvkit.sandbox.isolation`) with NumPy, the standard library
and this package only. The conversation with the trusted side is JSON lines: requests on
stdin, messages on file descriptor 3 (the student's prints go to stdout/stderr, which the
trusted side drains and bounds):

====================================  =====================================================
trusted side → worker                 worker → trusted side
====================================  =====================================================
``{"cells": [...], "blocks": ...}``    ``{"cell": i}`` before and ``{"cell_done": i, "error":
                                      ...}`` after each cell, then ``{"ready": ...}``
``{"call": BoxCall}``                 any number of ``{"rpc": id, "args", "kwargs"}`` (the
                                      trusted side answers each with ``{"value"}`` or
                                      ``{"error"}``), then ``{"outcome": {...}}``
``{"end": true}``                     (exits)
====================================  =====================================================

Building blocks an exercise may use (``filters.pad`` in the correlation exercise) and the
data loaders (``cvkit.data``) are *proxies*: the trusted side computes them with the reference
and sends back the value, for the ids the current case allows. The reference code itself is
not in the sandbox. The first request names them (``"blocks"``, ``"data"``) and cvkit's
algorithm modules (``"topics"``, from :func:`cvkit.registry.topic_modules`): each of those
modules is a stand-in that holds the proxies and refuses every other name.

Every answer-cell ``import`` goes through an allow-list (:data:`ALLOWED_MODULES`); anything
else is refused with a message that names it. The libraries themselves are not in the
sandbox either: the allow-list only makes the refusal explicit.
"""
from __future__ import annotations

import builtins
import json
import linecache
import os
import sys
import threading
import types

from . import wire
from . import adapters
from .adapters import bind_call
from .guard import Outcome, run_guarded

#: modules (top-level names) an answer cell may import
ALLOWED_MODULES = frozenset({
    "numpy", "math", "cmath", "functools", "itertools", "collections", "dataclasses", "typing", "heapq",
    "bisect", "operator", "statistics", "fractions", "decimal", "numbers", "random", "copy", "enum", "abc",
    "re", "string", "time", "warnings", "contextlib", "types", "__future__", "textwrap", "array",
})
#: modules of the notebooks' setup cell that are replaced by harmless stand-ins
_SETUP_STAND_INS = ("matplotlib", "matplotlib.pyplot", "IPython", "IPython.display")
PROTOCOL_FD = int(os.environ.get("CVKIT_PROTOCOL_FD", "3"))


class _Channel:
    """JSON lines in (stdin) and out (fd 3); one conversation at a time."""

    def __init__(self):
        self.lock = threading.RLock()
        self.incoming = os.fdopen(0, "rb", buffering=1 << 16, closefd=False)

    def send(self, item: dict) -> None:
        data = (json.dumps(item) + "\n").encode()
        view = memoryview(data)
        with self.lock:
            while view:
                view = view[os.write(PROTOCOL_FD, view):]

    def receive(self) -> dict:
        line = self.incoming.readline()
        if not line:
            os._exit(0)  # the trusted side has gone: nothing left to do
        return json.loads(line)

    def ask(self, item: dict) -> dict:
        with self.lock:
            self.send(item)
            return self.receive()


class _Nothing:
    """A stand-in that accepts any attribute access or call and does nothing (plots)."""

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return self

    def __call__(self, *args, **kwargs):
        return self

    def __iter__(self):
        return iter((self, self))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def _stand_in(name: str, attributes: dict, explain: bool) -> types.ModuleType:
    class StandIn(types.ModuleType):
        def __getattr__(self, attr):
            if attr.startswith("__"):
                raise AttributeError(attr)
            if not explain:
                return _Nothing()
            raise AttributeError(f"{name}.{attr} is not available while your code is graded "
                                 "(cvkit's reference implementations are off limits in exercises)")

    module = StandIn(name, f"grading stand-in for {name}")
    module.__dict__.update(attributes)
    return module


def _proxy(channel: _Channel, algorithm_id: str):
    def building_block(*args, **kwargs):
        try:
            request = {"rpc": algorithm_id, "args": wire.encode(args), "kwargs": wire.encode(kwargs)}
        except wire.WireError as exc:
            raise TypeError(f"cvkit.{algorithm_id}: {exc}") from None
        answer = channel.ask(request)
        if "error" in answer:
            raise RuntimeError(f"cvkit.{algorithm_id}: {answer['error']}")
        return wire.decode(answer["value"])

    module, _, name = algorithm_id.partition(".")
    building_block.__name__ = building_block.__qualname__ = name
    building_block.__module__ = f"cvkit.{module}"
    building_block.__doc__ = f"cvkit.{algorithm_id}, computed by the grader (a building block this exercise allows)"
    return building_block


def _install_stand_ins(channel: _Channel, blocks: list[str], data_names: list[str], topics: list[str]) -> dict:
    """Stand-ins for cvkit in ``sys.modules``: the grading functions, a module for each of
    ``topics`` (cvkit's algorithm modules, :func:`cvkit.registry.topic_modules`, sent by the
    trusted side) and for ``cvkit.data``, holding proxies of the building blocks and data
    loaders the trusted side serves; any other name of them is refused when used."""
    def student(algorithm_id=None):
        return lambda function: function

    def check(*args, **kwargs):
        return None

    class AnswersUnavailable(RuntimeError):
        pass

    def load_answers(*args, **kwargs):
        raise AnswersUnavailable("answers of other notebooks are not available while your code is graded")

    class needs_answer:  # noqa: N801 - the name the notebooks import
        def __init__(self, exercise=""):
            self.exercise = exercise

        def __enter__(self):
            return self

        def __exit__(self, kind, error, traceback):
            return kind is not None and issubclass(kind, NotImplementedError)

    grading = {"check": check, "needs_answer": needs_answer, "load_answers": load_answers,
               "AnswersUnavailable": AnswersUnavailable}
    served: dict[str, dict] = {}  # module -> its proxies
    proxies = {}
    for algorithm_id in list(blocks) + [f"data.{name}" for name in data_names]:
        module, _, name = algorithm_id.partition(".")
        served.setdefault(module, {})[name] = proxies[algorithm_id] = _proxy(channel, algorithm_id)
    modules = {
        "cvkit": _stand_in("cvkit", {"student": student}, True),
        "cvkit.registry": _stand_in("cvkit.registry", {"student": student}, True),
        "cvkit.grading": _stand_in("cvkit.grading", grading, True),
        "cvkit.grading.answers": _stand_in("cvkit.grading.answers", grading, True),
    }
    for topic in [*topics, "data"]:
        modules[f"cvkit.{topic}"] = _stand_in(f"cvkit.{topic}", served.get(topic, {}), True)
    for name in _SETUP_STAND_INS:
        modules[name] = _stand_in(name, {}, False)
    for name, stand_in in modules.items():  # each submodule is an attribute of its parent, as after an import
        parent, _, child = name.rpartition(".")
        if parent:
            setattr(modules[parent], child, stand_in)
    sys.modules.update(modules)
    return proxies


class _ImportGate:
    """``__import__`` for the student's namespace: the allow-list, with refusals recorded."""

    def __init__(self) -> None:
        self.real = builtins.__import__
        self.refused: list[str] = []

    def __call__(self, name, globals=None, locals=None, fromlist=(), level=0):
        top = name.partition(".")[0]
        if level == 0 and top not in ALLOWED_MODULES and top not in ("cvkit",) + _SETUP_STAND_INS:
            if name not in self.refused:
                self.refused.append(name)
            raise ImportError(f"{name} is not allowed in graded code: write the exercise with NumPy "
                              f"(allowed: {', '.join(sorted(ALLOWED_MODULES))})", name=name)
        return self.real(name, globals, locals, fromlist, level)


def _strip_magics(source: str) -> str:
    return "\n".join("pass  # magic" if line.lstrip().startswith(("%", "!")) else line
                     for line in source.splitlines())


def _refusal(name: str) -> str:
    return f"import {name} (not allowed in graded code)"


def main() -> None:  # pragma: no cover - runs inside the sandbox
    import resource

    processes = int(os.environ.get("CVKIT_SANDBOX_NPROC", "0") or 0)
    if processes:  # counted per sandbox: the limit is set inside the sandbox's user namespace
        resource.setrlimit(resource.RLIMIT_NPROC, (processes, processes))
    import numpy  # noqa: F401  (loaded before the student's code)

    channel = _Channel()
    request = channel.receive()
    proxies = _install_stand_ins(channel, list(request.get("blocks", [])), list(request.get("data", [])),
                                 list(request.get("topics", [])))
    gate = _ImportGate()
    safe_builtins = dict(vars(builtins))
    safe_builtins["__import__"] = gate
    namespace: dict = {"__name__": "__main__", "__builtins__": safe_builtins}
    cell_errors = []
    for index, source in enumerate(request["cells"]):
        channel.send({"cell": index})
        error = None
        try:
            code = _strip_magics(source)
            # the cell's lines for tracebacks and for where a timed-out case was stopped (the guard)
            linecache.cache[f"<cell {index}>"] = (len(code), None, code.splitlines(True), f"<cell {index}>")
            exec(compile(code, f"<cell {index}>", "exec"), namespace)
        except SystemExit:
            error = f"cell {index}: called exit()"
        except BaseException as exc:  # noqa: BLE001 - a broken cell is reported, not fatal
            error = f"cell {index}: {type(exc).__name__}: {str(exc)[:300]}"
        if error:
            cell_errors.append(error)
        channel.send({"cell_done": index, "error": error})
    channel.send({"ready": True, "cell_errors": cell_errors,
                  "refused": [_refusal(name) for name in gate.refused]})
    while True:
        message = channel.receive()
        if "call" not in message:
            break
        before = len(gate.refused)
        try:
            call = wire.BoxCall.from_wire(message["call"])
        except wire.WireError as exc:
            channel.send({"outcome": Outcome(error=f"grader error decoding the case: {exc}").to_json()})
            continue
        function = namespace.get(call.function)
        if not callable(function):
            why = "; ".join(e for e in cell_errors if "not allowed" in e or "Error" in e)[:400]
            channel.send({"outcome": Outcome(
                error=f"no function called {call.function!r} is defined"
                      + (f" (its cell stopped: {why})" if why else " (did its cell run?)"),
                exception="NameError").to_json()})
            continue
        adapter = getattr(adapters, call.adapter) if call.adapter else None
        # a cascade: the student's own building block (their `pad`) replaced by the grader's
        substitute = {name: proxies[block] for name, block in call.substitute.items() if block in proxies}
        saved = {name: namespace.get(name) for name in substitute}
        namespace.update(substitute)
        try:
            outcome = run_guarded(
                bind_call(adapter, function), call.args, call.kwargs,
                arg_names=call.arg_names, time_limit=call.time_limit,
                forbidden_libraries=call.forbidden_libraries,
                forbidden_functions=call.forbidden_functions,
                watch_reference=False, reference_codes={},
            )
        finally:
            namespace.update(saved)
        outcome.forbidden_calls += [_refusal(name) for name in gate.refused[before:]]
        channel.send({"outcome": outcome.to_json()})
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":  # pragma: no cover
    main()
