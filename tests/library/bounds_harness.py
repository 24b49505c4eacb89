"""Bounded work: a public function given an extreme value refuses it up front.

``assert_refused(fn, *args, names="radius", **kwargs)`` calls ``fn`` and requires

- a ``ValueError`` or ``TypeError`` whose message names the caller's argument (``names``: one
  name or several, any of which may appear);
- raised before the function allocated more than :data:`ALLOCATION_BUDGET` bytes (NumPy reports
  its allocations to :mod:`tracemalloc`, so this is measured, not timed);
- and without taking the machine down: during the call the address space is capped at its size
  before the call plus :data:`ADDRESS_SPACE_MARGIN` (an allocation beyond it is a ``MemoryError``,
  reported as a failure, rather than the kernel's OOM killer ending the test run);
- and not after a hang: a guard interrupts a call still running after :data:`HANG_GUARD` seconds
  (a generous stop for a runaway loop, not a speed assertion).
"""
from __future__ import annotations

import resource
import signal
import tracemalloc

import pytest

ALLOCATION_BUDGET = 64 * 1024**2
HANG_GUARD = 60
ADDRESS_SPACE_MARGIN = 2 * 1024**3


def _address_space() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[0]) * resource.getpagesize()


class _Hung(Exception):
    pass


def _interrupt(signum, frame):
    raise _Hung


def assert_refused(fn, *args, names, **kwargs) -> Exception:
    """Call ``fn(*args, **kwargs)``; return the clear error it raised (see the module doc)."""
    names = (names,) if isinstance(names, str) else tuple(names)
    previous = signal.signal(signal.SIGALRM, _interrupt)
    limits = resource.getrlimit(resource.RLIMIT_AS)
    cap = _address_space() + ADDRESS_SPACE_MARGIN
    if limits[1] == resource.RLIM_INFINITY or cap < limits[1]:
        resource.setrlimit(resource.RLIMIT_AS, (cap, limits[1]))
    signal.alarm(HANG_GUARD)
    tracemalloc.start()
    try:
        fn(*args, **kwargs)
    except _Hung:
        pytest.fail(f"{fn.__qualname__} was still running after {HANG_GUARD} s instead of refusing the input")
    except (ValueError, TypeError) as error:
        peak = tracemalloc.get_traced_memory()[1]
        message = str(error)
        assert any(name in message for name in names), (
            f"{fn.__qualname__} raised {type(error).__name__}({message!r}), which names none of {names}")
        assert peak <= ALLOCATION_BUDGET, (
            f"{fn.__qualname__} allocated {peak / 1024**2:.0f} MiB before refusing (budget "
            f"{ALLOCATION_BUDGET / 1024**2:.0f} MiB): check the argument before allocating")
        return error
    except MemoryError:
        pytest.fail(f"{fn.__qualname__} ran out of memory instead of refusing {names}")
    else:
        pytest.fail(f"{fn.__qualname__} accepted the extreme value instead of refusing {names}")
    finally:
        tracemalloc.stop()
        resource.setrlimit(resource.RLIMIT_AS, limits)
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    raise AssertionError("unreachable")
