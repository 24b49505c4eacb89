"""Run a candidate function under watch: copies of its inputs, a time limit, captured output, and a
watch on calls into libraries (or cvkit's own reference) that would do the exercise for it.

Nothing here writes to stderr: nbgrader gives zero to a test cell with any stderr output, so
warnings and prints from student code are captured into the report instead.
"""
from __future__ import annotations

import contextlib
import copy
import io
import signal
import sys
import threading
import time
import traceback
import types
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np


class CandidateTimeout(BaseException):
    """Raised inside the candidate when its time is up (BaseException: ``except Exception``
    in student code does not swallow it)."""


@dataclass
class Outcome:
    """What happened during one guarded call."""

    value: Any = None
    error: str | None = None          # one-line summary of an exception
    traceback: str | None = None      # the candidate's part of the traceback
    exception: str | None = None      # exception type name
    elapsed: float = 0.0
    timed_out: bool = False
    modified: list = field(default_factory=list)      # names of inputs the candidate changed
    forbidden_calls: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    stdout: str = ""
    stderr: str = ""

    @property
    def ok(self) -> bool:
        return self.error is None and not self.modified and not self.forbidden_calls


_builtin_cache: dict = {}


def _forbidden_builtins(libraries: tuple) -> dict:
    """id → dotted name of the C functions exported by imported forbidden modules.

    Extension functions such as ``cv2.GaussianBlur`` have no ``__module__``, so they are
    recognised by identity instead (the table is rebuilt when new modules are imported).
    """
    key = (libraries, len(sys.modules))
    if key in _builtin_cache:
        return _builtin_cache[key]
    table = {}
    for name, module in list(sys.modules.items()):
        if module is None or not name.startswith(libraries):
            continue
        try:
            items = list(vars(module).items())
        except TypeError:
            continue
        for attr, value in items:
            if not isinstance(value, types.BuiltinFunctionType):
                continue
            owner = getattr(value, "__module__", None) or ""
            # re-exports such as scipy.signal.arange (= numpy.arange) are not the library's own
            if owner and not owner.startswith(libraries):
                continue
            table.setdefault(id(value), f"{name}.{attr}")
    _builtin_cache.clear()
    _builtin_cache[key] = table
    return table


class _CallWatcher:
    """A ``sys.setprofile`` hook recording the outermost calls into forbidden code."""

    #: C functions that let code switch off or reach around the watch; flagged when the
    #: candidate's own code calls them (libraries such as ``warnings`` may use them freely)
    TAMPERING = {
        id(sys.setprofile): "sys.setprofile (switching off the grader's watch)",
        id(sys.getprofile): "sys.getprofile (reaching into the grader's watch)",
        id(sys.settrace): "sys.settrace",
        id(sys._getframe): "sys._getframe (reading the grader's frames)",
    }

    def __init__(self, libraries: tuple, functions: tuple, reference_codes: dict, allowed_ids: tuple):
        self.libraries = tuple(libraries)
        self.functions = tuple(tuple(f.rsplit(".", 1)) for f in functions)
        self.reference_codes = reference_codes
        self.allowed_ids = set(allowed_ids)
        self.calls: list[str] = []
        self.stop_code = None
        self.exempt = None  # the candidate's own code (grading the reference itself is fine)
        self.own_module = None  # module name of the candidate's code (``__main__`` in notebooks)
        self.enabled = True
        self.builtins = _forbidden_builtins(self.libraries) if self.libraries else {}

    def _module_of(self, frame) -> str:
        return frame.f_globals.get("__name__", "") or ""

    def _is_watched_frame(self, frame) -> bool:
        if frame.f_code in self.reference_codes:
            return True
        module = self._module_of(frame)
        return bool(self.libraries) and module.startswith(self.libraries)

    def _nested(self, frame) -> bool:
        """Is this call made from inside reference or library code (not by the candidate)?"""
        parent = frame.f_back
        while parent is not None and parent.f_code is not self.stop_code:
            if self._is_watched_frame(parent):
                return True
            parent = parent.f_back
        return False

    def _record(self, what: str) -> None:
        # public spelling: scipy.ndimage._filters.uniform_filter -> scipy.ndimage.uniform_filter
        what = ".".join(part for part in what.split(".") if not part.startswith("_") or part.startswith("__"))
        if what not in self.calls:
            self.calls.append(what)

    def __call__(self, frame, event, arg):
        if not self.enabled:
            return
        if event == "call":
            code = frame.f_code
            if code is self.exempt or code.co_name == "<module>":  # importing is not calling
                return
            algorithm_id = self.reference_codes.get(code)
            if algorithm_id is not None:
                if algorithm_id not in self.allowed_ids and not self._nested(frame):
                    self._record(f"cvkit reference implementation of {algorithm_id!r}")
                return
            module = self._module_of(frame)
            if self.libraries and module.startswith(self.libraries):
                if not self._nested(frame):
                    self._record(f"{module}.{code.co_name}")
                return
            for prefix, name in self.functions:
                if code.co_name == name and module.startswith(prefix) and not self._nested(frame):
                    self._record(f"{prefix}.{name}")
        elif event == "c_call":
            tampering = self.TAMPERING.get(id(arg))
            if tampering is not None:
                if self._module_of(frame) == self.own_module:
                    self._record(tampering)
                return
            known = self.builtins.get(id(arg))
            if known is not None:
                if not self._nested(frame):
                    self._record(known)
                return
            module = getattr(arg, "__module__", None) or ""
            if self.libraries and module.startswith(self.libraries) and not self._nested(frame):
                self._record(f"{module}.{getattr(arg, '__name__', '?')}")


@contextlib.contextmanager
def _time_limit(seconds: float | None):
    """Raise :class:`CandidateTimeout` in the main thread after ``seconds`` (Unix only)."""
    usable = (
        seconds
        and hasattr(signal, "setitimer")
        and threading.current_thread() is threading.main_thread()
    )
    if not usable:
        yield
        return

    def _expire(signum, frame):
        raise CandidateTimeout()

    previous = signal.signal(signal.SIGALRM, _expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _reference_functions() -> dict:
    """cvkit's reference functions (code → id), or none where cvkit is absent (the sandbox)."""
    try:
        import importlib

        return importlib.import_module("cvkit.registry").reference_functions()
    except ImportError:
        return {}


def _copy_inputs(value):
    return copy.deepcopy(value)


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        try:
            return (
                isinstance(a, np.ndarray) and isinstance(b, np.ndarray)
                and a.shape == b.shape and a.dtype == b.dtype
                and bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))
            )
        except Exception:
            return False
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.random.Generator):
        return True  # drawing from the rng is expected
    if isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return True  # NaN arguments (e.g. fill=nan) are unchanged
    try:
        return bool(a == b)
    except Exception:
        return True


def _candidate_traceback(exc: BaseException) -> str:
    """The traceback without the grader's own frames."""
    frames = traceback.extract_tb(exc.__traceback__)
    here = __file__.rsplit(".", 1)[0]
    kept = [f for f in frames if not f.filename.startswith(here)]
    lines = traceback.format_list(kept) + traceback.format_exception_only(type(exc), exc)
    return "".join(lines).rstrip()


def run_guarded(
    function: Callable,
    args: tuple,
    kwargs: dict,
    *,
    arg_names: tuple = (),
    time_limit: float | None = 20.0,
    forbidden_libraries: tuple = (),
    forbidden_functions: tuple = (),
    allowed_ids: tuple = (),
    watch_reference: bool = True,
    reference_codes: dict | None = None,
) -> Outcome:
    """Call ``function(*args, **kwargs)`` on copies of the inputs under the guard."""
    outcome = Outcome()
    call_args = _copy_inputs(args)
    call_kwargs = _copy_inputs(kwargs)
    watcher = None
    if forbidden_libraries or forbidden_functions or watch_reference or reference_codes:
        if reference_codes is None:
            reference_codes = _reference_functions() if watch_reference else {}
        watcher = _CallWatcher(forbidden_libraries, forbidden_functions, reference_codes, allowed_ids)
        # the candidate's own code; through a Check.call adapter, the wrapped candidate's
        inner = getattr(function, "__wrapped__", function)
        watcher.exempt = getattr(inner, "__code__", None)
        watcher.own_module = getattr(function, "__module__", None)
    out, err = io.StringIO(), io.StringIO()
    previous_profile = sys.getprofile()
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        warnings.simplefilter("always")
        try:
            with _time_limit(time_limit):
                if watcher is not None:
                    watcher.stop_code = sys._getframe().f_code
                    sys.setprofile(watcher)
                try:
                    outcome.value = function(*call_args, **call_kwargs)
                finally:
                    if watcher is not None:
                        watcher.enabled = False
                        if sys.getprofile() is not watcher:
                            watcher._record("sys.setprofile (switching off the grader's watch)")
                    sys.setprofile(previous_profile)
        except CandidateTimeout:
            outcome.timed_out = True
            outcome.exception = "Timeout"
            outcome.error = (
                f"stopped after {time_limit:g} s: this is far slower than needed; vectorize with "
                "NumPy (whole-array operations, shifted copies, sliding windows) instead of "
                "looping over pixels"
            )
        except KeyboardInterrupt:
            raise
        except BaseException as exc:  # the candidate's fault, never the grader's
            outcome.exception = type(exc).__name__
            if isinstance(exc, NotImplementedError):
                outcome.error = "not implemented yet (the function raises NotImplementedError)"
            else:
                message = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
                outcome.error = f"raised {type(exc).__name__}" + (f": {message}" if message else "")
            outcome.traceback = _candidate_traceback(exc)
    outcome.elapsed = time.perf_counter() - start
    outcome.stdout, outcome.stderr = out.getvalue(), err.getvalue()
    outcome.warnings = [f"{w.category.__name__}: {w.message}" for w in caught]
    if watcher is not None:
        outcome.forbidden_calls = list(watcher.calls)
    names = list(arg_names) + [f"argument {i}" for i in range(len(arg_names), len(args))]
    for i, (original, used) in enumerate(zip(args, call_args)):
        if not _same(original, used):
            outcome.modified.append(names[i])
    for key in kwargs:
        if not _same(kwargs[key], call_kwargs[key]):
            outcome.modified.append(key)
    return outcome
