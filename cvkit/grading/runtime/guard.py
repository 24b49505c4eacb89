"""Run a candidate function under watch: copies of its inputs, a time limit, captured output, and a
watch on calls into libraries (or cvkit's own reference) that would do the exercise for it.

Nothing here writes to stderr: nbgrader gives zero to a test cell with any stderr output, so
warnings and prints from student code are captured into the report instead, and the guard's own
bookkeeping runs with warnings silenced.

Importing is not the candidate's time: while a module is being loaded (the first ``import`` of
it, wherever it comes from: an ``import`` statement, ``importlib.import_module``, a library's lazy
attribute) the clock is paused and the call watch is off, and the time limit never interrupts an
import, so a timed-out case leaves no half-initialised module behind.
"""
from __future__ import annotations

import ast
import contextlib
import copy
import importlib
import importlib.util  # noqa: F401  (its code is recognised as an import in progress)
import inspect
import io
import linecache
import signal
import textwrap
import sys
import threading
import time
import traceback
import types
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, cast

import numpy as np

from . import wire


class CandidateTimeout(BaseException):
    """Raised inside the candidate when its time is up (BaseException: ``except Exception``
    in student code does not swallow it)."""


#: (entries, characters of each) an outcome's lists keep when it crosses the sandbox boundary
_LIST_LIMITS = {"modified": (20, 200), "forbidden_calls": (20, 200), "warnings": (20, 500)}
#: characters of the end of the captured stdout/stderr that cross the boundary
_OUTPUT_TAIL = 2000
#: characters of an exception's one-line summary, of its traceback and of its type name that
#: cross the boundary (a 64 KB message must not make a 36 MB graded notebook)
_ERROR_CHARS, _TRACEBACK_CHARS, _NAME_CHARS = 500, 4000, 100
#: the exceptions a case may require (:attr:`cvkit.grading.Case.raises`), by name: an outcome
#: says which of them the candidate's exception is an instance of (a subclass counts)
ERROR_KINDS = {"ValueError": ValueError, "TypeError": TypeError}
#: the kinds of loop a timed-out candidate can be stopped in (:func:`loop_evidence`), and how
#: many of their header lines an outcome keeps
LOOP_KINDS = ("while", "for")
_LOOP_LINES = 5


def _capped(text: str | None, limit: int, keep_end: bool = False) -> str | None:
    """``text`` cut to ``limit`` characters, saying so (the end kept for a traceback)."""
    if text is None or len(text) <= limit:
        return text
    note = f" […{len(text) - limit} characters cut]"
    return note.strip() + "\n" + text[-limit:] if keep_end else text[:limit] + note


def _texts(items: Any, count: int, length: int) -> list[str]:
    """At most ``count`` strings of at most ``length`` characters (a single one for a value
    that is not a list, none for None)."""
    if items is None:
        return []
    if not isinstance(items, (list, tuple)):
        items = [items]
    return [str(item)[:length] for item in items[:count]]


@dataclass
class Outcome:
    """What happened during one guarded call.

    :meth:`to_json` and :meth:`from_json` are its form on the wire between the grading sandbox
    (which sends it) and the trusted grader (which reads it, trusting nothing in it).
    """

    value: Any = None
    error: str | None = None          # one-line summary of an exception
    traceback: str | None = None      # the candidate's part of the traceback
    exception: str | None = None      # exception type name
    #: the names of :data:`ERROR_KINDS` the exception is an instance of (``LinAlgError`` is a
    #: ``ValueError``): what a case that requires an error is judged by
    raised_as: list = field(default_factory=list)
    elapsed: float = 0.0
    timed_out: bool = False
    modified: list = field(default_factory=list)      # names of inputs the candidate changed
    forbidden_calls: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    stdout: str = ""
    stderr: str = ""
    #: where a timed-out candidate was stopped (:func:`loop_evidence`): ``"while"`` (inside a
    #: ``while`` loop: maybe one that never ends), ``"for"`` (inside ``for`` loops or a
    #: comprehension: a loop over pixels, merely slow) or None (no loop of the candidate's own
    #: code around the line, or not known); ``loop_lines`` the lines of those loops' headers
    loop: str | None = None
    loop_lines: list = field(default_factory=list)
    #: True for an outcome the trusted side wrote itself (a timeout measured outside, a worker
    #: that died): its texts are the grader's. Never read from the wire.
    from_grader: bool = False

    @property
    def ok(self) -> bool:
        return self.error is None and not self.modified and not self.forbidden_calls

    def to_json(self) -> dict[str, Any]:
        """The outcome as plain JSON data, its value in :mod:`.wire` encoding.

        Lists and captured output are cut to what crosses the sandbox boundary. A value that
        cannot be encoded (an object, a too large array) becomes the outcome's error.

        Returns
        -------
        dict
            What :meth:`from_json` reads back.
        """
        item: dict[str, Any] = {
            "error": _capped(self.error, _ERROR_CHARS), "traceback": _capped(self.traceback, _TRACEBACK_CHARS, True),
            "exception": _capped(self.exception, _NAME_CHARS),
            "raised_as": [name for name in ERROR_KINDS if name in self.raised_as],
            "elapsed": self.elapsed, "timed_out": self.timed_out,
            **{key: _texts(getattr(self, key), *limits) for key, limits in _LIST_LIMITS.items()},
            "stdout": self.stdout[-_OUTPUT_TAIL:], "stderr": self.stderr[-_OUTPUT_TAIL:],
            "loop": self.loop, "loop_lines": [int(n) for n in self.loop_lines[:_LOOP_LINES]],
        }
        if self.error is None:
            try:
                item["value"] = wire.encode(self.value)
            except wire.WireError as exc:
                item["error"] = f"returned something that cannot be graded: {exc}"
        return item

    @classmethod
    def from_json(cls, item: Mapping[str, Any]) -> "Outcome":
        """Read an outcome sent by the sandbox (:meth:`to_json`), trusting nothing in it.

        Parameters
        ----------
        item : mapping
            The decoded JSON object. Fields of the wrong type are read as text or dropped,
            lists and output are cut to their limits, and the value is decoded by
            :func:`.wire.decode` (never unpickled).

        Returns
        -------
        Outcome
            With ``error`` set when the value cannot be decoded or is missing.
        """
        def text(key: str, limit: int = _ERROR_CHARS, keep_end: bool = False) -> str | None:
            value = item.get(key)
            return _capped(value if value is None or isinstance(value, str) else str(value)[:limit], limit, keep_end)

        elapsed = item.get("elapsed", 0.0)
        outcome = cls(
            error=text("error"), traceback=text("traceback", _TRACEBACK_CHARS, True),
            exception=text("exception", _NAME_CHARS),
            elapsed=float(elapsed) if isinstance(elapsed, (int, float)) else 0.0,
            timed_out=bool(item.get("timed_out", False)),
            modified=_texts(item.get("modified"), *_LIST_LIMITS["modified"]),
            forbidden_calls=_texts(item.get("forbidden_calls"), *_LIST_LIMITS["forbidden_calls"]),
            warnings=_texts(item.get("warnings"), *_LIST_LIMITS["warnings"]),
            stdout=(text("stdout", 1 << 30) or "")[-_OUTPUT_TAIL:], stderr=(text("stderr", 1 << 30) or "")[-_OUTPUT_TAIL:],
        )
        raised_as = item.get("raised_as")
        if isinstance(raised_as, list):  # names of a fixed set: nothing else is read
            outcome.raised_as = [name for name in ERROR_KINDS if name in raised_as]
        loop, lines = item.get("loop"), item.get("loop_lines")
        if loop in LOOP_KINDS:  # a word of a fixed set and a few line numbers: nothing else is read
            outcome.loop = loop
            outcome.loop_lines = [n for n in (lines if isinstance(lines, list) else [])[:_LOOP_LINES]
                                  if type(n) is int and 0 < n < 10**7]
        if "value" in item and outcome.error is None:
            try:
                outcome.value = wire.decode(item["value"])
            except (wire.WireError, ValueError, TypeError, KeyError, AttributeError) as exc:
                outcome.error = f"returned something that cannot be graded ({exc})"
        elif outcome.error is None:
            outcome.error = "returned nothing the grader could read"
        return outcome


class _Sink(io.StringIO):
    """Captured output; code that closes ``sys.stdout``/``sys.stderr`` does not lose it."""

    def close(self) -> None:
        pass


@contextlib.contextmanager
def _quiet():
    """The guard's own bookkeeping: no warning and no print of it reaches the real stderr."""
    sink = _Sink()
    with warnings.catch_warnings(), contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        warnings.simplefilter("ignore")
        yield


#: a module's namespace without any attribute lookup on the module (``vars(module)`` goes
#: through ``__getattribute__``, which lazy modules override to load themselves)
_module_namespace: Callable[[types.ModuleType], dict] = cast(Any, types.ModuleType).__dict__["__dict__"].__get__


def _namespace_of(module) -> dict | None:
    if not issubclass(type(module), types.ModuleType):  # type(), not isinstance: no __class__ lookup
        return None
    namespace = _module_namespace(module)
    return namespace if type(namespace) is dict else None


def _module_name(owner) -> str:
    """``__module__`` as a string (some extensions store the module object itself there)."""
    if type(owner) is str:
        return owner
    namespace = _namespace_of(owner)
    name = namespace.get("__name__") if namespace is not None else None
    return name if type(name) is str else ""


_builtin_cache: dict = {}


def _forbidden_builtins(libraries: tuple) -> dict:
    """id → dotted name of the C functions exported by imported forbidden modules.

    Extension functions such as ``cv2.GaussianBlur`` have no ``__module__``, so they are
    recognised by identity instead (the table is rebuilt when new modules are imported).
    Nothing here runs a module's code: namespaces are read directly, never through
    ``getattr`` (a module-level ``__getattr__`` that warns about a deprecated name would write
    to stderr), and warnings are silenced all the same.
    """
    libraries = tuple(libraries)
    key = (libraries, len(sys.modules))
    if key in _builtin_cache:
        return _builtin_cache[key]
    table: dict[int, str] = {}  # id of a builtin function -> its name
    with _quiet():
        for name, module in list(sys.modules.items()):
            if type(name) is not str or not name.startswith(libraries):
                continue
            namespace = _namespace_of(module)
            if namespace is None:
                continue
            for attr, value in list(namespace.items()):
                if type(value) is not types.BuiltinFunctionType:
                    continue
                owner = _module_name(value.__module__)
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
        self.stop_code: types.CodeType | None = None
        self.exempt: types.CodeType | None = None  # the candidate's own code (grading the reference itself is fine)
        self.own_module: str | None = None  # module name of the candidate's code (``__main__`` in notebooks)
        self.enabled = True
        self.builtins = _forbidden_builtins(self.libraries) if self.libraries else {}
        # verdicts on what was seen and found harmless, by id, each entry holding its object
        # (so that an id is not reused while it is cached): Python code with the globals it
        # ran in, and C functions of modules (never bound methods, which hold their instance)
        self._harmless_code: dict[int, tuple] = {}
        self._harmless_c: dict[int, Any] = {}
        self.profile = self._profile_function()

    def refresh(self) -> None:
        """Recognise the C functions of forbidden modules imported since the watch began."""
        if self.libraries:
            self.builtins = _forbidden_builtins(self.libraries)
            self._harmless_c.clear()

    def _module_of(self, frame) -> str:
        name = frame.f_globals.get("__name__", "")
        return name if type(name) is str else ""

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

    def _profile_function(self) -> Callable:
        """The ``sys.setprofile`` function of this watch: the checks of :meth:`__call__`, in a
        plain function (cheaper to call than this object) that skips what it has already found
        harmless. It runs on every call and return of the candidate and of the libraries it
        uses, so its cost multiplies the candidate's running time."""
        harmless_code, harmless_c = self._harmless_code, self._harmless_c
        check = self.__call__
        module_type = types.ModuleType

        def profile(frame, event, arg):
            if event == "call":
                code = frame.f_code
                seen = harmless_code.get(id(code))
                if seen is not None and seen[0] is code and seen[1] is frame.f_globals:
                    return
                if check(frame, event, arg) is _HARMLESS:
                    harmless_code[id(code)] = (code, frame.f_globals)
            elif event == "c_call":
                if harmless_c.get(id(arg)) is arg:
                    return
                if check(frame, event, arg) is _HARMLESS:
                    owner = getattr(arg, "__self__", None)
                    if owner is None or type(owner) is module_type:
                        harmless_c[id(arg)] = arg

        return profile

    def __call__(self, frame, event, arg):
        """Check one profile event; returns :data:`_HARMLESS` for a call that is neither
        forbidden nor watched, whoever makes it (so that the same call need not be looked at
        again)."""
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
            watched = False
            for prefix, name in self.functions:
                if code.co_name == name and module.startswith(prefix):
                    watched = True
                    if not self._nested(frame):
                        self._record(f"{prefix}.{name}")
            return None if watched else _HARMLESS
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
            module = getattr(arg, "__module__", None)
            if type(module) is not str:  # None, or (some extensions) the module object itself
                module = _module_name(module) if module is not None else ""
            if self.libraries and module.startswith(self.libraries):
                if not self._nested(frame):
                    self._record(f"{module}.{getattr(arg, '__name__', '?')}")
                return
            return _HARMLESS


#: what :meth:`_CallWatcher.__call__` says of a call that is neither forbidden nor watched
_HARMLESS = object()


#: while the time is up but the candidate is inside an import (or inside the guard's own code),
#: how soon to look again whether it can be stopped (seconds)
_RETRY = 0.002
#: after stopping the candidate, how soon to stop it again if its code swallowed the exception
#: (a bare ``except:`` in a loop)
_AGAIN = 0.05


class _Clock:
    """The case's time limit: SIGALRM in the main thread (Unix only), paused while a module loads.

    Its handler raises :class:`CandidateTimeout` only where the candidate's own code (or a
    library it called) runs. Never inside an import: a module left half-initialised breaks
    every later use of it (``SystemError … bad call flags``, crashes at exit). Never inside the
    call watch: Python switches off a profile function that raises, which would read as the
    candidate switching off the watch. Never in the guard itself. There it looks again
    :data:`_RETRY` seconds later.
    """

    def __init__(self, seconds: float, base) -> None:
        self.seconds = float(seconds)
        self.base = base  # the guard's frame: the candidate's code runs above it
        self.running = False
        self.expired = False
        self.paused: float | None = None  # seconds that were left when a module began to load
        self._previous_handler: Any = None
        self._previous_timer = (0.0, 0.0)
        self._started = 0.0

    @staticmethod
    def usable(seconds) -> bool:
        return (
            bool(seconds) and seconds > 0
            and hasattr(signal, "setitimer")
            and threading.current_thread() is threading.main_thread()
        )

    def start(self) -> None:
        self._previous_handler = signal.signal(signal.SIGALRM, self._expire)
        self._started = time.monotonic()
        self.running = True
        self._previous_timer = signal.setitimer(signal.ITIMER_REAL, self.seconds)

    def stop(self) -> None:
        if not self.running:
            return
        self.running = False  # from here on a late signal is ignored
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, self._previous_handler)
        left, interval = self._previous_timer
        if left > 0:  # someone else's timer (pytest-timeout, an outer guard): what is left of it
            spent = time.monotonic() - self._started
            signal.setitimer(signal.ITIMER_REAL, max(left - spent, 1e-3), interval)

    def pause(self) -> None:
        if self.running and self.paused is None:
            left, _ = signal.setitimer(signal.ITIMER_REAL, 0)
            if left <= 0:
                self.expired = True  # it went off just now: the signal's handler will wait
            self.paused = left

    def resume(self) -> None:
        if self.running and self.paused is not None:
            left, self.paused = self.paused, None
            signal.setitimer(signal.ITIMER_REAL, _RETRY if self.expired else left)

    def _expire(self, signum, frame) -> None:
        if not self.running:
            return  # late: the candidate has finished
        self.expired = True
        if self.paused is not None:
            return  # a module is loading: resume() sets the clock going again
        if not self._interruptible(frame):
            signal.setitimer(signal.ITIMER_REAL, _RETRY)
            return
        signal.setitimer(signal.ITIMER_REAL, _AGAIN)
        raise CandidateTimeout()

    def _interruptible(self, frame) -> bool:
        """Is ``frame`` (and every frame between it and the guard) the candidate's or a library's
        ordinary code, with no import in progress?"""
        if frame is self.base:
            return False
        while frame is not None and frame is not self.base:
            code = frame.f_code
            if id(code) in _UNINTERRUPTIBLE or code.co_filename in _IMPORT_FILES:
                return False
            frame = frame.f_back
        return True


class _Session:
    """One guarded call in progress: its clock and its watch."""

    def __init__(self, clock: _Clock | None, watcher: _CallWatcher | None) -> None:
        self.clock = clock
        self.watcher = watcher
        self.thread = threading.get_ident()
        self.loading = False  # a module is being loaded (the clock is paused, the watch off)


_sessions: list[_Session] = []  # guarded calls in progress, innermost last
_bootstrap = getattr(importlib, "_bootstrap", None)
# what importlib._bootstrap._find_and_load was before the guard put _find_and_load in its place
_previous_find_and_load = getattr(_bootstrap, "_find_and_load", None)


def _session_here() -> _Session | None:
    ident = threading.get_ident()
    for session in reversed(_sessions):
        if session.thread == ident:
            return session
    return None


def _find_and_load(name, *args, **kwargs):
    """importlib's ``_find_and_load`` while a guarded call runs.

    importlib calls it for every module that is not loaded yet, whichever way the import
    came (``import``, ``importlib.import_module``, a lazy attribute, the sandbox's import gate),
    so a first import neither counts toward the time limit nor runs under the call watch, which
    makes it several times slower (and module code is not the candidate calling anything).
    """
    load = _previous_find_and_load
    session = _session_here()
    if session is None or session.loading:
        return load(name, *args, **kwargs)
    session.loading = True
    clock, watcher = session.clock, session.watcher
    if clock is not None:
        clock.pause()
    watching = watcher is not None and sys.getprofile() is watcher.profile
    if watching:
        sys.setprofile(None)
    before = set(sys.modules)
    try:
        return load(name, *args, **kwargs)
    except BaseException as exc:
        if not isinstance(exc, Exception):  # interrupted (Ctrl-C): leave no half-imported module
            _discard_partial(before)
        raise
    finally:
        try:
            if watching:
                if len(sys.modules) != len(before):
                    watcher.refresh()
                if sys.getprofile() is None:
                    sys.setprofile(watcher.profile)
        finally:
            session.loading = False
            if clock is not None:
                clock.resume()


def _discard_partial(before: set) -> list:
    """Remove from ``sys.modules`` what an interrupted import left: modules still being
    initialised, and modules whose package is gone (importing them again would run the
    package's code over their old state)."""
    removed = []
    with _quiet():
        for name in [n for n in list(sys.modules) if n not in before]:
            namespace = _namespace_of(sys.modules.get(name))
            spec = namespace.get("__spec__") if namespace is not None else None
            try:
                initialising = getattr(spec, "_initializing", False) is True
            except Exception:
                initialising = False
            if initialising:
                sys.modules.pop(name, None)
                removed.append(name)
        for name in [n for n in list(sys.modules) if n not in before]:
            parts = name.split(".") if type(name) is str else []
            parents = [".".join(parts[:i]) for i in range(1, len(parts))]
            if any(parent not in sys.modules for parent in parents):
                sys.modules.pop(name, None)
                removed.append(name)
    return removed


def _begin(session: _Session) -> None:
    """Put the import hook in place, start the clock, switch the watch on (in that order)."""
    global _previous_find_and_load
    if not _sessions and _bootstrap is not None:
        current = getattr(_bootstrap, "_find_and_load", None)
        if current is not None and current is not _find_and_load:
            _previous_find_and_load = current
            _bootstrap._find_and_load = _find_and_load
    _sessions.append(session)
    if session.clock is not None:
        session.clock.start()
    if session.watcher is not None:
        sys.setprofile(session.watcher.profile)


def _end(session: _Session, previous_profile) -> None:
    """Stop the clock, check and switch off the watch, take the import hook away."""
    try:
        if session.clock is not None:
            session.clock.stop()
    finally:
        watcher = session.watcher
        if watcher is not None:
            watcher.enabled = False
            if sys.getprofile() is not watcher.profile:
                watcher._record("sys.setprofile (switching off the grader's watch)")
        sys.setprofile(previous_profile)
        if session in _sessions:
            _sessions.remove(session)
        if not _sessions and _bootstrap is not None and getattr(_bootstrap, "_find_and_load", None) is _find_and_load:
            _bootstrap._find_and_load = _previous_find_and_load


def _code_ids(*objects) -> set:
    """The ids of the code of these functions and of the classes' methods, with the code of
    the functions defined inside them (such as the call watch's profile function)."""
    codes = set()

    def add(code) -> None:
        codes.add(id(code))
        for constant in code.co_consts:
            if isinstance(constant, types.CodeType):
                add(constant)

    for item in objects:
        members = vars(item).values() if isinstance(item, type) else (item,)
        for member in members:
            member = getattr(member, "__func__", member)
            member = getattr(member, "__wrapped__", member)
            code = getattr(member, "__code__", None)
            if code is not None:
                add(code)
    return codes


def _import_files() -> frozenset:
    """The file names of importlib's machinery (frozen in CPython: ``<frozen importlib._bootstrap>``)."""
    files = {"<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>", "<frozen importlib.util>"}
    for module_name, function in (("importlib._bootstrap", "_gcd_import"),
                                  ("importlib._bootstrap_external", "decode_source"),
                                  ("importlib.util", "resolve_name")):
        code = getattr(getattr(sys.modules.get(module_name), function, None), "__code__", None)
        if code is not None:
            files.add(code.co_filename)
    return frozenset(files)


#: where the guard learns cvkit's reference functions (code → id) when a caller gives none: set
#: by the grading engine (:func:`use_reference_functions`), which may know the registry; the
#: runtime itself never reaches for it (in the sandbox there is none)
_reference_source: Callable[[], dict] | None = None


def use_reference_functions(source: Callable[[], dict] | None) -> None:
    """Tell the guard how to list cvkit's reference functions (``registry.reference_functions``)."""
    global _reference_source
    _reference_source = source


def _reference_functions() -> dict:
    """cvkit's reference functions (code → id), or none where nobody said (the sandbox)."""
    return _reference_source() if _reference_source is not None else {}


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


def _own_module(function) -> str | None:
    """The module name of the candidate's own code (``__main__`` in a notebook and in the
    sandbox): its frames are those whose globals carry this ``__name__``."""
    inner = getattr(function, "__wrapped__", function)
    name = getattr(inner, "__module__", None) or getattr(function, "__module__", None)
    return name if type(name) is str else None


def _own_frames(exc: BaseException, module: str | None) -> list:
    """(frame, line) of the candidate's own code in the traceback of ``exc``, outermost first."""
    here = __file__.rsplit(".", 1)[0]
    frames = [(frame, line) for frame, line in traceback.walk_tb(exc.__traceback__)
              if not frame.f_code.co_filename.startswith(here)]
    if module is None:
        return frames
    return [(frame, line) for frame, line in frames if frame.f_globals.get("__name__") == module]


#: subpackages kept in a library function's name (``numpy.linalg.inv``, not ``numpy.inv``)
_SUBPACKAGES = ("linalg", "fft", "random", "ma", "polynomial", "testing", "strings", "char")


def _library_name(frame) -> str:
    """``numpy.pad`` for a frame of NumPy's ``pad`` (the name the student calls it by)."""
    module = frame.f_globals.get("__name__", "")
    parts = module.split(".") if type(module) is str and module else []
    kept = parts[:1] + [part for part in parts[1:] if part in _SUBPACKAGES]
    name = frame.f_code.co_name
    # a private helper (``x.sum()`` runs ``numpy._core._methods._sum``) is no name the student knows
    return ".".join(kept + ([] if name.startswith(("_", "<")) else [name])) or "a library"


def _candidate_traceback(exc: BaseException, module: str | None = None) -> str | None:
    """The traceback of the candidate's own code, ending in its own line.

    Only the frames of the candidate's module (:func:`_own_module`) are kept, the last few of
    them: the last one shown is always the student's line. When the exception came from inside
    a library the student's line called (NumPy's ``pad``, ``reshape``...), one line names that
    function instead of its frames. The exception follows on one line. None when no frame of
    the candidate's code is in the traceback (it was not called at all, e.g. wrong arguments)."""
    own = _own_frames(exc, module)
    if not own:
        return None
    lines = []
    for frame, number in own[-_TRACEBACK_FRAMES:]:
        code = frame.f_code
        lines.append(f'  File "{code.co_filename}", line {number}, in {code.co_name}')
        text = linecache.getline(code.co_filename, number, frame.f_globals).strip()
        if text:
            lines.append(f"    {text[:_CODE_CHARS]}")
    here = __file__.rsplit(".", 1)[0]
    every = [frame for frame, _ in traceback.walk_tb(exc.__traceback__)]
    after = [frame for frame in every[every.index(own[-1][0]) + 1:]
             if not frame.f_code.co_filename.startswith(here)]  # not the guard's own handler
    if after:
        what = "it was stopped" if isinstance(exc, CandidateTimeout) else "the error was raised"
        lines.append(f"  ({what} inside {_library_name(after[0])}, which this line called)")
    if isinstance(exc, CandidateTimeout):
        head = "stopped here: the time limit was reached"
    else:
        try:
            text = str(exc).strip()
        except Exception:  # an exception whose str() fails
            text = ""
        head = type(exc).__name__ + (f": {text.splitlines()[0]}" if text else "")
    if len(head) > _HEAD_CHARS:  # the frames above must survive the traceback's own cap
        head = head[:_HEAD_CHARS] + f" […{len(head) - _HEAD_CHARS} characters cut]"
    lines.append(head)
    return "\n".join(lines)


#: frames of the candidate's own code a traceback keeps (the innermost ones), characters of each
#: frame's code line and of the exception's line: together well within ``_TRACEBACK_CHARS``, so
#: that the cap at the boundary never cuts the student's frames away
_TRACEBACK_FRAMES, _CODE_CHARS, _HEAD_CHARS = 6, 200, 1500


def _loops_around(frame, number: int) -> list[tuple[str, int]]:
    """The loops of the function running in ``frame`` whose body holds line ``number``,
    outermost first, as ``(kind, line of the loop's header)`` with kind ``"while"`` or
    ``"for"``, read from the function's source (empty when it cannot be read)."""
    code = frame.f_code
    lines = linecache.getlines(code.co_filename, frame.f_globals)
    if not lines:
        return []
    try:
        block = inspect.getblock(lines[code.co_firstlineno - 1:])
        tree = ast.parse(textwrap.dedent("".join(block)))
    except (SyntaxError, IndexError, ValueError, TypeError):
        return []
    relative = number - code.co_firstlineno + 1
    found = sorted((node.lineno, "while" if isinstance(node, ast.While) else "for")
                   for node in ast.walk(tree) if isinstance(node, (ast.For, ast.AsyncFor, ast.While))
                   and node.lineno <= relative <= (node.end_lineno or node.lineno))
    return [(kind, line + code.co_firstlineno - 1) for line, kind in found]


def loop_evidence(exc: BaseException, module: str | None) -> tuple[str | None, list[int]]:
    """Where a candidate stopped by its time limit was running, as evidence for the advice.

    The candidate's own frames are read from the innermost outwards (a helper it called
    first): ``("while", [line])`` when the line it was stopped at is inside a ``while`` loop
    (the innermost one) — a loop that may never end, whose exit condition is the thing to look
    at; ``("for", [lines])`` when it is inside ``for`` loops only (or a comprehension) — they
    always end, so the code was merely slow, typically a Python loop over pixels; ``(None, [])``
    when no loop of the candidate's code is around it (a single huge computation, a sleep), or
    its source cannot be read."""
    for frame, number in reversed(_own_frames(exc, module)):
        name = frame.f_code.co_name
        if name in ("<listcomp>", "<dictcomp>", "<setcomp>", "<genexpr>"):
            return "for", [frame.f_code.co_firstlineno]
        loops = _loops_around(frame, number)
        whiles = [line for kind, line in loops if kind == "while"]
        if whiles:
            return "while", [whiles[-1]]
        if loops:
            return "for", [line for _, line in loops][:_LOOP_LINES]
    return None, []


def timeout_message(limit: float | None, loop: str | None = None, lines: list | tuple = ()) -> str:
    """What a student reads when a case did not return within its time limit, with the advice
    that fits the evidence (:func:`loop_evidence`).

    >>> timeout_message(20, "while", [7])
    "did not return within 20 s: look at your loop's exit condition (it was still in the `while` loop of line 7 when it was stopped)"
    """
    within = f"did not return within {limit:g} s" if limit else "did not return in time"
    numbers = [str(n) for n in lines]
    where = ", ".join(numbers[:-1]) + " and " + numbers[-1] if len(numbers) > 1 else "".join(numbers)
    if loop == "while":
        return (f"{within}: look at your loop's exit condition (it was still in the `while` loop of line {where} "
                "when it was stopped)")
    if loop == "for":
        loops = "`for` loops of lines" if len(lines) > 1 else "`for` loop of line"
        return (f"{within}: it was still in the {loops} {where} when it was stopped; a loop in Python (over "
                "pixels, say) is far too slow here: vectorize with NumPy (whole-array operations, shifted copies, "
                "sliding windows)")
    return (f"{within}: look at your loop's exit condition, or, if your code works pixel by pixel, vectorize it "
            "with NumPy (whole-array operations instead of loops)")


def run_guarded(
    function: Callable,
    args: tuple,
    kwargs: dict,
    *,
    arg_names: tuple = (),
    time_limit: float | None = wire.DEFAULT_TIME_LIMIT,
    forbidden_libraries: tuple = (),
    forbidden_functions: tuple = (),
    allowed_ids: tuple = (),
    watch_reference: bool = True,
    reference_codes: dict | None = None,
) -> Outcome:
    """Call ``function(*args, **kwargs)`` on copies of the inputs under the guard.

    ``time_limit`` is the candidate's own time: loading a module for the first time does not
    count (it runs without the call watch, too), and the limit never falls inside an import.
    ``Outcome.elapsed`` is the wall time of the whole call, imports included.
    """
    outcome = Outcome()
    with _quiet():  # the guard's own work: none of it reaches the real stdout/stderr
        _run(outcome, function, args, kwargs, arg_names, time_limit, forbidden_libraries,
             forbidden_functions, allowed_ids, watch_reference, reference_codes)
    return outcome


def _run(outcome, function, args, kwargs, arg_names, time_limit, forbidden_libraries,
         forbidden_functions, allowed_ids, watch_reference, reference_codes) -> None:
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
        watcher.stop_code = sys._getframe().f_code
    # the clock knows this frame (the candidate runs above it) until the call is over
    clock = _Clock(time_limit, sys._getframe()) if _Clock.usable(time_limit) else None
    session = _Session(clock, watcher)
    out, err = _Sink(), _Sink()
    previous_profile = sys.getprofile()
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        warnings.simplefilter("always")
        try:
            try:
                _begin(session)
                outcome.value = function(*call_args, **call_kwargs)
            finally:
                _end(session, previous_profile)
        except CandidateTimeout as exc:
            outcome.timed_out = True
            outcome.exception = "Timeout"
            try:
                outcome.loop, outcome.loop_lines = loop_evidence(exc, _own_module(function))
            except Exception:  # the evidence is a courtesy: never the grader's failure
                outcome.loop, outcome.loop_lines = None, []
            outcome.error = timeout_message(time_limit, outcome.loop, outcome.loop_lines)
            outcome.traceback = _capped(_candidate_traceback(exc, _own_module(function)), _TRACEBACK_CHARS, True)
        except KeyboardInterrupt:
            raise
        except BaseException as exc:  # the candidate's fault, never the grader's
            outcome.exception = type(exc).__name__
            outcome.raised_as = [name for name, kind in ERROR_KINDS.items() if isinstance(exc, kind)]
            if isinstance(exc, NotImplementedError):
                outcome.error = "not implemented yet (the function raises NotImplementedError)"
            else:
                try:
                    text = str(exc).strip()
                except Exception:  # an exception whose str() fails
                    text = ""
                message = text.splitlines()[0] if text else ""
                outcome.error = _capped(f"raised {type(exc).__name__}" + (f": {message}" if message else ""),
                                        _ERROR_CHARS)
            outcome.traceback = _capped(_candidate_traceback(exc, _own_module(function)), _TRACEBACK_CHARS, True)
        finally:
            if clock is not None:
                clock.base = None  # no reference cycle through the frame
        outcome.elapsed = time.perf_counter() - start
        outcome.stdout, outcome.stderr = out.getvalue(), err.getvalue()
        outcome.warnings = [_describe_warning(w) for w in caught]
    if watcher is not None:
        outcome.forbidden_calls = list(watcher.calls)
    names = list(arg_names) + [f"argument {i}" for i in range(len(arg_names), len(args))]
    for i, (original, used) in enumerate(zip(args, call_args)):
        if not _same(original, used):
            outcome.modified.append(names[i])
    for key in kwargs:
        if not _same(kwargs[key], call_kwargs[key]):
            outcome.modified.append(key)


def _describe_warning(w) -> str:
    try:
        return f"{w.category.__name__}: {w.message}"
    except Exception:  # a warning whose str() fails
        return f"{getattr(w.category, '__name__', 'Warning')}: ?"


#: code of the guard itself, where the time limit never interrupts
_UNINTERRUPTIBLE = _code_ids(
    _Clock, _Session, _CallWatcher, _find_and_load, _discard_partial, _begin, _end, _session_here,
    _forbidden_builtins, _namespace_of, _module_name, _quiet, _Sink, _run, run_guarded,
)
#: importlib's own code: an import in progress
_IMPORT_FILES = _import_files()
