"""Regression tests of the guard (issue 18, bullet 7): a first import inside the candidate does
not count toward the time limit and is never interrupted by it, a timed-out case leaves no
half-initialised module behind, and nothing the guard itself does writes to stderr.

No assertion here is about how fast something was: the slow modules sleep for longer than the
limit, so a guard that counted them would time out, whatever the machine.
"""
from __future__ import annotations

import builtins
import importlib
import json
import signal
import sys
import textwrap
import time
import types
import warnings

import numpy as np
import pytest

from cvkit.grading.checks import FORBIDDEN_LIBRARIES
from cvkit.grading.runtime import guard
from cvkit.grading.runtime.guard import Outcome, run_guarded

#: a loop "forever" that still ends if the guard failed to stop it (the test then fails, not hangs)
FOREVER = 30.0


@pytest.fixture
def modules(tmp_path, monkeypatch):
    """Write synthetic modules into ``tmp_path`` (on ``sys.path``); forgotten afterwards."""
    monkeypatch.syspath_prepend(str(tmp_path))
    written: list[str] = []

    def write(name: str, source: str, package: bool = False) -> None:
        parts = name.split(".")
        folder = tmp_path.joinpath(*parts[:-1])
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / parts[-1] / "__init__.py" if package else folder / f"{parts[-1]}.py"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(source))
        written.append(parts[0])
        importlib.invalidate_caches()

    yield write
    for name in list(sys.modules):
        if name.partition(".")[0] in written:
            del sys.modules[name]


def _state():
    """Everything the guard changes while it runs and must give back."""
    return (sys.stdout, sys.stderr, sys.getprofile(), signal.getsignal(signal.SIGALRM), list(warnings.filters),
            importlib._bootstrap._find_and_load, builtins.__import__)


def _complete(name: str) -> bool:
    module = sys.modules.get(name)
    return module is not None and module.__spec__ is not None and not getattr(module.__spec__, "_initializing", False)


def _no_half_imports(prefix: str) -> None:
    """``sys.modules`` either lacks the modules or has them complete, parents included."""
    for name in [n for n in sys.modules if n.partition(".")[0] == prefix]:
        assert _complete(name), f"{name} is half-initialised"
        parts = name.split(".")
        for i in range(1, len(parts)):
            assert ".".join(parts[:i]) in sys.modules, f"{name} is left without its package"


# ------------------------------------------------------------------ (a) a first import is not the candidate's time
def test_first_import_of_a_slow_module_does_not_count_toward_the_limit(modules):
    modules("guardslow_a", """
        import time
        time.sleep(1.5)
        READY = True
    """)

    def candidate():
        import guardslow_a

        return guardslow_a.READY

    before = _state()
    outcome = run_guarded(candidate, (), {}, time_limit=0.5, forbidden_libraries=FORBIDDEN_LIBRARIES,
                          watch_reference=False)
    assert not outcome.timed_out and outcome.error is None, outcome.error
    assert outcome.value is True
    assert _complete("guardslow_a") and sys.modules["guardslow_a"].READY is True
    assert _state() == before


def test_first_import_through_importlib_and_through_a_sandbox_import_gate(modules):
    """``importlib.import_module`` and the worker's own ``__import__`` in the namespace's builtins
    (see runtime/worker.py ``_ImportGate``) reach the same pause."""
    modules("guardslow_b", "import time\ntime.sleep(1.5)\nREADY = 'b'\n")
    modules("guardslow_c", "import time\ntime.sleep(1.5)\nREADY = 'c'\n")
    seen = []
    real_import = builtins.__import__

    def gate(name, globals=None, locals=None, fromlist=(), level=0):
        seen.append(name)
        return real_import(name, globals, locals, fromlist, level)

    namespace = {"__name__": "__main__", "__builtins__": dict(vars(builtins), __import__=gate)}
    exec(textwrap.dedent("""
        import importlib

        def candidate():
            import guardslow_c
            return importlib.import_module("guardslow_b").READY + guardslow_c.READY
    """), namespace)
    outcome = run_guarded(namespace["candidate"], (), {}, time_limit=0.5, forbidden_libraries=("scipy.ndimage",),
                          watch_reference=False)
    assert not outcome.timed_out and outcome.error is None, outcome.error
    assert outcome.value == "bc"
    assert "guardslow_c" in seen  # the gate was asked, and composes with the guard
    assert _complete("guardslow_b") and _complete("guardslow_c")


def test_imports_run_without_the_call_watch_and_forbidden_calls_are_still_seen(modules):
    """Module code is not the candidate calling: a module that uses a forbidden library while it
    loads is not reported, the candidate's own call into it is (also for C functions of a
    module imported during the call)."""
    modules("guardwatch_lib", """
        import numpy as np
        from scipy import ndimage
        SMOOTH = ndimage.maximum_filter(np.ones((3, 3)), 3)
    """)

    def candidate():
        import guardwatch_lib
        from scipy import ndimage

        return ndimage.uniform_filter(guardwatch_lib.SMOOTH, 3)

    outcome = run_guarded(candidate, (), {}, time_limit=60, forbidden_libraries=FORBIDDEN_LIBRARIES,
                          watch_reference=False)
    assert outcome.error is None, outcome.error
    assert outcome.forbidden_calls == ["scipy.ndimage.uniform_filter"]


def test_c_functions_of_a_library_imported_during_the_call_are_recognised(modules):
    """C functions without ``__module__`` (OpenCV's) are known by identity: the table of them is
    brought up to date when the candidate imports the library itself."""
    modules("guardwatch_c", "_shelf = []\nput = _shelf.append\n")

    def candidate():
        import guardwatch_c

        guardwatch_c.put(1)

    outcome = run_guarded(candidate, (), {}, time_limit=60, forbidden_libraries=("guardwatch_c",),
                          watch_reference=False)
    assert outcome.error is None, outcome.error
    assert outcome.forbidden_calls == ["guardwatch_c.put"]


# ------------------------------------------------------------------ (b) a loop is still stopped at the limit
def test_a_loop_forever_is_stopped():
    def candidate():
        end = time.monotonic() + FOREVER
        while time.monotonic() < end:
            pass
        return "not stopped"

    before = _state()
    outcome = run_guarded(candidate, (), {}, time_limit=0.3, watch_reference=False)
    assert outcome.timed_out and outcome.exception == "Timeout" and "did not return within 0.3 s" in outcome.error
    # it was stopped in a `while` loop: the advice is its exit condition, with the loop's line
    line = candidate.__code__.co_firstlineno + 2
    assert outcome.loop == "while" and outcome.loop_lines == [line], (outcome.loop, outcome.loop_lines)
    assert "exit condition" in outcome.error and f"line {line}" in outcome.error and "vectorize" not in outcome.error
    assert outcome.value is None
    assert _state() == before


def test_a_loop_under_the_call_watch_is_stopped_without_a_false_tampering_report():
    """A timeout raised inside the profile function used to make Python switch the watch off,
    which was then reported as the candidate calling ``sys.setprofile``."""
    def step(x):
        return x + 1

    def candidate():
        x, end = 0, time.monotonic() + FOREVER
        while time.monotonic() < end:
            x = step(x)
            len("abc")
        return "not stopped"

    for _ in range(5):
        outcome = run_guarded(candidate, (), {}, time_limit=0.1, forbidden_libraries=FORBIDDEN_LIBRARIES,
                              watch_reference=False)
        assert outcome.timed_out
        assert outcome.forbidden_calls == []


def test_a_candidate_that_swallows_the_timeout_is_stopped_again():
    def candidate():
        end = time.monotonic() + FOREVER
        try:
            while time.monotonic() < end:
                pass
        except BaseException:  # noqa: BLE001 - what a careless student writes
            pass
        while time.monotonic() < end:
            pass
        return "not stopped"

    outcome = run_guarded(candidate, (), {}, time_limit=0.2, watch_reference=False)
    assert outcome.timed_out and outcome.value is None


def test_a_timer_set_before_the_guard_is_given_back():
    """Someone else's SIGALRM timer (pytest-timeout's, an outer guard's) survives a guarded call."""
    previous = signal.signal(signal.SIGALRM, lambda *a: None)
    signal.setitimer(signal.ITIMER_REAL, 500)
    try:
        run_guarded(lambda: 1, (), {}, time_limit=5, watch_reference=False)
        left, _ = signal.getitimer(signal.ITIMER_REAL)
        assert left > 0
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


# ------------------------------------------------------------------ (c) no half-initialised module after a timeout
@pytest.mark.parametrize("how", ["import", "import_module"])
def test_the_limit_falling_during_an_import_leaves_no_half_initialised_module(modules, how):
    modules("guardhalf", """
        import time
        from . import part
        time.sleep(1.0)
        READY = part.VALUE
    """, package=True)
    modules("guardhalf.part", "VALUE = 42\n")

    def candidate():
        time.sleep(0.5)  # the limit falls during the import that follows
        if how == "import":
            import guardhalf
        else:
            guardhalf = importlib.import_module("guardhalf")
        return guardhalf.READY

    outcome = run_guarded(candidate, (), {}, time_limit=1.0, forbidden_libraries=FORBIDDEN_LIBRARIES,
                          watch_reference=False)
    _no_half_imports("guardhalf")
    assert not outcome.timed_out and outcome.value == 42, outcome.error
    again = run_guarded(candidate, (), {}, time_limit=5, watch_reference=False)
    assert again.error is None and again.value == 42


def test_a_timeout_after_an_import_leaves_the_module_complete(modules):
    modules("guardafter", "import time\ntime.sleep(1.0)\nREADY = True\n")

    def candidate():
        time.sleep(0.5)
        import guardafter  # noqa: F401

        end = time.monotonic() + FOREVER
        while time.monotonic() < end:
            pass
        return "not stopped"

    outcome = run_guarded(candidate, (), {}, time_limit=1.0, watch_reference=False)
    assert outcome.timed_out
    assert _complete("guardafter") and sys.modules["guardafter"].READY is True
    again = run_guarded(lambda: importlib.import_module("guardafter").READY, (), {}, time_limit=5,
                        watch_reference=False)
    assert again.error is None and again.value is True


def test_an_interrupted_import_is_taken_out_of_sys_modules(modules):
    """Ctrl-C in the student's kernel while a package loads: neither the package nor the
    submodules it had already loaded stay behind (importing them again must run them afresh)."""
    modules("guardbroken", """
        from . import done
        raise KeyboardInterrupt
    """, package=True)
    modules("guardbroken.done", "VALUE = 1\n")

    def candidate():
        import guardbroken  # noqa: F401

    before = _state()
    with pytest.raises(KeyboardInterrupt):
        run_guarded(candidate, (), {}, time_limit=5, watch_reference=False)
    assert [name for name in sys.modules if name.startswith("guardbroken")] == []
    assert _state() == before


# ------------------------------------------------------------------ (d) building the table of forbidden callables is silent
class _LoudClass(type):
    def __getattribute__(cls, name):
        if name == "__class__":
            warnings.warn("reading __class__ is deprecated", FutureWarning)
            sys.stderr.write("loud class\n")
        return super().__getattribute__(name)


class _LoudModule(types.ModuleType):
    def __getattribute__(self, name):
        warnings.warn(f"{name} is deprecated", FutureWarning, stacklevel=2)
        sys.stderr.write(f"loud attribute {name}\n")
        return super().__getattribute__(name)


class _LoudObject:
    @property
    def __dict__(self):
        warnings.warn("deprecated", FutureWarning)
        sys.stderr.write("loud object\n")
        return {}

    @property
    def __class__(self):
        warnings.warn("deprecated", FutureWarning)
        sys.stderr.write("loud __class__\n")
        return _LoudObject


@pytest.fixture
def loud_library(monkeypatch):
    """A library like torch: deprecated module attributes (module ``__getattr__`` that warns),
    a module subclass with properties, odd objects in sys.modules and in namespaces."""
    top = types.ModuleType("guardloud")
    exec(textwrap.dedent("""
        import sys, warnings

        def __getattr__(name):
            warnings.warn(f"guardloud.{name} is deprecated", FutureWarning)
            sys.stderr.write(f"deprecated {name}\\n")
            raise AttributeError(name)
    """), top.__dict__)
    shelf: list = []
    top.put = shelf.append  # a C function of the library (its __module__ is None)
    top.odd = _LoudObject()
    top.odd_class = _LoudClass("Odd", (), {})
    foreign = [].append
    foreign.__module__ = top  # some extensions store the module object, not its name
    top.foreign = foreign
    sub = _LoudModule("guardloud.sub")
    object.__setattr__(sub, "count", [].count)
    for name, module in {"guardloud": top, "guardloud.sub": sub, "guardloud.obj": _LoudObject()}.items():
        monkeypatch.setitem(sys.modules, name, module)
    guard._builtin_cache.clear()
    yield top
    guard._builtin_cache.clear()


def test_forbidden_table_with_deprecated_module_attributes_writes_nothing(loud_library, capfd):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = guard._forbidden_builtins(("guardloud",))
    out, err = capfd.readouterr()
    assert err == "" and out == ""
    assert caught == []
    assert table[id(loud_library.put)] == "guardloud.put"
    assert table[id(loud_library.foreign)] == "guardloud.foreign"
    assert "guardloud.sub.count" in table.values()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning would be an exception here
        guard._builtin_cache.clear()
        guard._forbidden_builtins(("guardloud",))


def test_watching_a_library_with_deprecated_attributes_writes_nothing(loud_library, capfd):
    def candidate():
        loud_library.put(1)
        loud_library.foreign(2)
        return "done"

    outcome = run_guarded(candidate, (), {}, time_limit=5, forbidden_libraries=("guardloud",) + FORBIDDEN_LIBRARIES)
    out, err = capfd.readouterr()
    assert err == "" and out == ""
    assert outcome.error is None and outcome.value == "done"
    assert outcome.warnings == []
    assert outcome.forbidden_calls == ["guardloud.put", "guardloud.foreign"]


# ------------------------------------------------------------------ (e) nothing reaches the real stderr
def _raises():
    print("about to fail", file=sys.stderr)
    raise ValueError("broken on purpose")


def _times_out():
    sys.stderr.write("still going\n")
    warnings.warn("slow", RuntimeWarning)
    end = time.monotonic() + FOREVER
    while time.monotonic() < end:
        pass


def _noisy():
    print("to stdout")
    print("to stderr", file=sys.stderr)
    warnings.warn("careful", UserWarning)
    warnings.simplefilter("error")  # the candidate changes the warning filters ...
    sys.stderr.close()  # ... and closes the stream it was given
    return 3


class _BadMessage(Exception):
    def __str__(self):
        raise RuntimeError("no message")


def _bad_exception():
    raise _BadMessage()


@pytest.mark.parametrize("candidate, check", [
    (_raises, lambda o: o.error == "raised ValueError: broken on purpose" and "about to fail" in o.stderr),
    (_times_out, lambda o: o.timed_out and "still going" in o.stderr and o.warnings == ["RuntimeWarning: slow"]),
    (_noisy, lambda o: o.value == 3 and o.stdout == "to stdout\n" and o.stderr == "to stderr\n"
     and o.warnings == ["UserWarning: careful"]),
    (_bad_exception, lambda o: o.exception == "_BadMessage" and o.error == "raised _BadMessage"),
])
def test_nothing_reaches_the_real_stderr(candidate, check, capfd):
    before = _state()
    outcome = run_guarded(candidate, (), {}, time_limit=0.3, forbidden_libraries=FORBIDDEN_LIBRARIES)
    out, err = capfd.readouterr()
    assert err == "" and out == ""
    assert check(outcome), outcome
    assert _state() == before  # streams, profile, SIGALRM handler, warning filters, import hooks


def test_an_outcome_crosses_the_sandbox_boundary_as_json():
    """Outcome.to_json (the worker) and Outcome.from_json (the trusted side) are one pair: a
    round trip keeps the outcome within the boundary's limits, and the trusted side reads a
    tampered message without raising."""
    sent = Outcome(value=(np.arange(3.0), {"k": 1}), elapsed=0.5, modified=["image"], warnings=["w"] * 30,
                   stdout="x" * 5000 + "end")
    back = Outcome.from_json(json.loads(json.dumps(sent.to_json())))
    assert np.array_equal(back.value[0], np.arange(3.0)) and back.value[1] == {"k": 1} and back.error is None
    assert back.elapsed == 0.5 and back.modified == ["image"] and len(back.warnings) == 20
    assert len(back.stdout) == 2000 and back.stdout.endswith("end") and back.stderr == ""
    assert sent.stdout.endswith("end") and len(sent.warnings) == 30  # the outcome sent is unchanged
    assert "cannot be graded" in Outcome.from_json(Outcome(value=object()).to_json()).error
    error = Outcome(error="ValueError: no", exception="ValueError")
    assert Outcome.from_json(error.to_json()) == error
    tampered = Outcome.from_json({"error": 3, "modified": 5, "forbidden_calls": ["x" * 999] * 50,
                                  "elapsed": "soon", "stdout": None})
    assert tampered.error == "3" and tampered.modified == ["5"] and tampered.elapsed == 0.0 and tampered.stdout == ""
    assert len(tampered.forbidden_calls) == 20 and all(len(c) == 200 for c in tampered.forbidden_calls)
    assert Outcome.from_json({}).error == "returned nothing the grader could read"
    object_array = {"value": {"t": "nd", "dtype": "|O", "shape": [1], "data": ""}}
    assert "cannot be graded" in Outcome.from_json(object_array).error
