"""Probes: what the hidden cases penalise that the visible cases do not show.

A visible test that passes should not hide a rule the hidden cases apply (an input dtype, a
shape, the precision of the result). After a *passing* visible evaluation, the engine runs the
candidate on a few variants of the public inputs shaped like the hidden cases (the same input
in the dtypes the hidden cases use, a single point or a single row where they give one) and
compares with the reference there. A difference is not a failure and costs nothing: the
visible report gets one line, "passes the shown cases, but …", naming what differs, so that a
student learns it before the deadline rather than from the grade. The check's refusals (bad
inputs the hidden test gives, where the function must raise) are tried the same way.

What the hidden cases use is read from one draw of them with a fixed seed (:data:`PROBE_SEED`):
its input dtypes, value ranges and shapes (:func:`profile`). The grading seed stays unknown.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator

import numpy as np

from .checks import Case, Check

#: the seed of the draw of hidden cases whose dtypes and shapes the probes imitate
PROBE_SEED = 20_240_035
#: at most this many probe runs per visible evaluation (each one is a call of the candidate)
MAX_PROBES = 8

_PROFILES: dict[int, tuple[Check, "Profile"]] = {}


@dataclass
class Profile:
    """What the hidden cases give at each argument (a position or a keyword name; the elements
    of a list of arrays as ``(key, "[]")``)."""

    #: key -> {dtype name: (smallest, largest) value met in that dtype}
    dtypes: dict = field(default_factory=dict)
    #: keys at which a hidden case gives a one-dimensional array
    vectors: set = field(default_factory=set)
    #: keys at which a hidden case gives an array of one row (shape ``(1, ...)``, ndim ≥ 2)
    rows: set = field(default_factory=set)
    #: keys at which a hidden case gives a NumPy array
    arrays: set = field(default_factory=set)
    #: keys at which a hidden case gives a list or tuple of numbers
    sequences: set = field(default_factory=set)


def _arguments(case: Case) -> Iterator[tuple[Any, Any]]:
    yield from enumerate(case.args)
    yield from case.kwargs.items()


def _numeric(value: Any) -> bool:
    return isinstance(value, np.ndarray) and value.dtype.kind in "biuf" and value.size > 0


def _slots(case: Case) -> Iterator[tuple[Any, np.ndarray]]:
    """``(slot, array)`` of every numeric array of a case: an argument (slot = its key) or an
    element of an argument that is a list or tuple of arrays (slot = ``(key, index)``)."""
    for key, value in _arguments(case):
        if _numeric(value):
            yield key, value
        elif isinstance(value, (list, tuple)) and value and all(isinstance(v, np.ndarray) for v in value):
            for i, item in enumerate(value):
                if _numeric(item):
                    yield (key, i), item


def _family(slot: Any) -> Any:
    return (slot[0], "[]") if isinstance(slot, tuple) else slot


def _number_sequence(value: Any) -> bool:
    if not isinstance(value, (list, tuple)) or not value:
        return False
    try:
        array = np.asarray(value)
    except Exception:
        return False
    return array.dtype.kind in "iuf" and array.size > 0


def profile(spec: Check) -> Profile:
    """The dtypes, ranges and shapes of ``spec``'s hidden cases drawn from :data:`PROBE_SEED`
    (kept for the life of the process)."""
    kept = _PROFILES.get(id(spec))
    if kept is not None and kept[0] is spec:
        return kept[1]
    found = Profile()
    try:
        cases = spec.hidden_cases(np.random.default_rng(PROBE_SEED))
    except Exception:  # a check whose cases cannot be drawn here: nothing to imitate
        cases = []
    for case in cases:
        for key, value in _arguments(case):
            if isinstance(value, np.ndarray):
                found.arrays.add(key)
            elif _number_sequence(value):
                found.sequences.add(key)
        for slot, value in _slots(case):
            floats = value.astype(np.float64)
            finite = floats[np.isfinite(floats)]
            if not finite.size:
                continue
            kinds = found.dtypes.setdefault(_family(slot), {})
            lo, hi = kinds.get(value.dtype.name, (np.inf, -np.inf))
            kinds[value.dtype.name] = (min(lo, float(finite.min())), max(hi, float(finite.max())))
            if not isinstance(slot, tuple):
                if value.ndim == 1:
                    found.vectors.add(slot)
                elif value.shape[0] == 1:
                    found.rows.add(slot)
    _PROFILES[id(spec)] = (spec, found)
    return found


def _to_dtype(values: list[np.ndarray], dtype: np.dtype, low: float, high: float) -> Iterator[list[np.ndarray]]:
    """``values`` (the arrays of one case that the hidden cases give in ``dtype``) in that
    dtype, in the ways that keep most of them, best first: cast as they are (integers that
    fit), rounded (large values), or mapped together onto the range the hidden cases use
    (``[low, high]``; an unsigned range starts at a fifth of its top, so that a rescaled input
    shows)."""
    if dtype.kind == "f":
        yield [v.astype(dtype) for v in values]
        return
    if dtype.kind not in "iu":
        return
    info = np.iinfo(dtype)
    # an integer has no inf or NaN: the largest value the hidden cases use stands for them
    floats = [np.where(np.isfinite(f), f, float(high)) for f in (v.astype(np.float64) for v in values)]
    lo = min(float(f.min()) for f in floats)
    hi = max(float(f.max()) for f in floats)
    fits = lo >= info.min and hi <= info.max
    if fits and hi - lo >= 2 and all(np.array_equal(f, np.round(f)) for f in floats):
        yield [f.astype(dtype) for f in floats]
    if fits and hi - lo >= 20:
        yield [np.round(f).astype(dtype) for f in floats]
    top = min(max(abs(low), abs(high)), float(info.max))
    if hi <= lo or top < 1:
        return
    if info.min == 0 or lo >= 0:
        bottom = max(float(low), 0.0, float(np.floor(top / 5)))
        if top - bottom < 1:
            bottom = 0.0
        yield [np.round(bottom + (f - lo) / (hi - lo) * (top - bottom)).astype(dtype) for f in floats]
    else:
        scale = max(abs(lo), abs(hi))
        yield [np.round(f / scale * top).astype(dtype) for f in floats]


def _with(case: Case, replaced: dict, label: str) -> Case:
    args = list(case.args)
    kwargs = dict(case.kwargs)

    def put(key, value):
        if isinstance(key, int):
            args[key] = value
        else:
            kwargs[key] = value

    def get(key):
        return args[key] if isinstance(key, int) else kwargs[key]

    for slot, value in replaced.items():
        if isinstance(slot, tuple):
            key, index = slot
            items = list(get(key))
            items[index] = value
            put(key, type(get(key))(items) if isinstance(get(key), tuple) else items)
        else:
            put(slot, value)
    return Case(tuple(args), kwargs, label)


def _sliced(case: Case, keys: dict, cut: Callable[[np.ndarray], np.ndarray], label: str) -> Case:
    """``case`` with the arrays at ``keys`` cut (one point, one row), and the arrays of the same
    shape inside its dict arguments (a layer's cache) cut alike."""
    replaced = {k: cut(v).copy() for k, v in keys.items()}
    shapes = {v.shape for v in keys.values()}
    for key, value in _arguments(case):
        if isinstance(value, dict) and key not in keys:
            inner = copy.copy(value)
            for name, item in value.items():
                if isinstance(item, np.ndarray) and item.shape in shapes:
                    inner[name] = cut(item).copy()
            replaced[key] = inner
    return _with(case, replaced, label)


def variants(spec: Check, cases: list[Case]) -> Iterator[tuple[str, Case]]:
    """``(what, probe case)``: the public ``cases`` in the dtypes, containers and shapes the
    hidden cases use and the public ones do not (what: "on the same input in int16", "on a
    single row of the same input"...). Several probes may share a ``what``: the first one the
    reference computes stands for it."""
    found = profile(spec)
    public_dtypes: dict = {}
    public_arrays: set = set()
    public_sequences: set = set()
    for case in cases:
        for slot, value in _slots(case):
            public_dtypes.setdefault(_family(slot), set()).add(value.dtype.name)
        for key, value in _arguments(case):
            if isinstance(value, np.ndarray):
                public_arrays.add(key)
            elif _number_sequence(value):
                public_sequences.add(key)
    for case in cases:
        arrays = dict(_slots(case))
        # dtypes: every array the hidden cases give in a dtype no public case uses there
        wanted: dict = {}
        for slot, value in arrays.items():
            for name, (low, high) in found.dtypes.get(_family(slot), {}).items():
                if name not in public_dtypes.get(_family(slot), set()) and name != value.dtype.name:
                    wanted.setdefault(name, {})[slot] = (low, high)
        for name, slots in sorted(wanted.items()):
            low = min(r[0] for r in slots.values())
            high = max(r[1] for r in slots.values())
            for converted in _to_dtype([arrays[k] for k in slots], np.dtype(name), low, high):
                yield f"on the same input in {name}", _with(case, dict(zip(slots, converted)), f"{case.label} ({name})")
        # containers: an array where the public cases give a list, and the other way round
        for key, value in _arguments(case):
            if key in found.arrays and key not in public_arrays and _number_sequence(value):
                yield ("on the same input given as a NumPy array",
                       _with(case, {key: np.asarray(value)}, f"{case.label} (NumPy array)"))
            elif key in found.sequences and key not in public_sequences and isinstance(value, np.ndarray) \
                    and value.ndim >= 1 and value.dtype.kind in "iuf":
                yield ("on the same input given as a list",
                       _with(case, {key: value.tolist()}, f"{case.label} (list)"))
    for case in cases:
        arrays = {key: value for key, value in _arguments(case) if isinstance(value, np.ndarray)}
        points = {k: v for k, v in arrays.items() if k in found.vectors and v.ndim == 2 and v.shape[0] > 1}
        if points and len({v.shape[0] for v in points.values()}) == 1:
            yield ("on a single point of the same input, of shape (d,)" if all(v.shape[1] <= 4 for v in points.values())
                   else "on one row of the same input as a 1-D array"), \
                _sliced(case, points, lambda v: v[0], f"{case.label} (1-D)")
    for case in cases:
        arrays = {key: value for key, value in _arguments(case) if isinstance(value, np.ndarray)}
        rows = {k: v for k, v in arrays.items() if k in found.rows and v.ndim >= 2 and v.shape[0] > 1}
        if rows and len({v.shape[0] for v in rows.values()}) == 1:
            yield "on a single row of the same input", _sliced(case, rows, lambda v: v[:1], f"{case.label} (one row)")


def _floats(value: Any) -> Iterator[np.ndarray]:
    if isinstance(value, dict):
        for item in value.values():
            yield from _floats(item)
    elif isinstance(value, (tuple, list)):
        for item in value:
            yield from _floats(item)
    elif isinstance(value, (np.ndarray, np.floating)):
        array = np.asarray(value)
        if array.dtype.kind == "f":
            yield array


def computes_in_float32(got: Any, expected: Any) -> bool:
    """The candidate's result carries float32 precision where the reference's does not: it
    returns float32 arrays where the reference returns float64 ones, or every float it returns
    is a float32 number while some of the reference's are not (computed in float32, cast back)."""
    mine, theirs = list(_floats(got)), list(_floats(expected))
    if not mine or len(mine) != len(theirs):
        return False
    if any(a.dtype == np.float32 and b.dtype == np.float64 for a, b in zip(mine, theirs)):
        return True

    def float32_exact(a: np.ndarray) -> bool:
        finite = a[np.isfinite(a)].astype(np.float64)
        return bool(np.array_equal(finite.astype(np.float32).astype(np.float64), finite))

    return (all(float32_exact(a) for a in mine)
            and any(b.dtype == np.float64 and not float32_exact(b) for b in theirs))


def notes(spec: Check, cases: list[Case], outputs: list[tuple[Any, Any]], run: Callable[[Case], Any],
          reference: Callable[[Case], Any], headline: Callable[[str], str], budget: float = 5.0) -> list[str]:
    """The one-line notes of a passing visible evaluation (see the module's docstring).

    ``outputs`` are the (candidate's, reference's) results of the passed public cases; ``run``
    runs the candidate on a case under the guard (an :class:`~cvkit.grading.runtime.guard.Outcome`);
    ``reference`` computes the reference's output (raising when it cannot); ``headline`` makes a
    failure message short; the probes stop once the candidate has run ``budget`` seconds on them.
    """
    found: list[str] = []
    if any(computes_in_float32(got, expected) for got, expected in outputs):
        found.append("passes the shown cases, but computes in float32 — the hidden cases compare in "
                     "float64: compute (and return) float64")
    runs, spent = 0, 0.0
    for refusal in spec.refusals:  # the bad inputs the hidden test gives (Check.refusals)
        if runs >= MAX_PROBES or spent >= budget:
            break
        runs += 1
        outcome = run(refusal)
        spent += getattr(outcome, "elapsed", 0.0) or 0.0
        if outcome is None or outcome.timed_out or refusal.raises in outcome.raised_as:
            continue
        did = "returns a result" if outcome.error is None else f"raises {outcome.exception}"
        found.append(f"passes the shown cases, but the hidden test also gives {refusal.label}, where your "
                     f"function must raise {refusal.raises}; it {did}")
        if len(found) >= 3:
            return found
    tried: set = set()
    for what, probe in variants(spec, cases):
        if runs >= MAX_PROBES or spent >= budget:
            break
        if what in tried:
            continue
        try:
            expected = reference(probe)
        except Exception:  # an input the reference refuses is no rule of the exercise
            continue
        runs += 1
        tried.add(what)
        outcome = run(probe)
        spent += getattr(outcome, "elapsed", 0.0) or 0.0
        if outcome is None or outcome.timed_out:
            continue
        if outcome.error is not None:
            problem = headline(outcome.error)
        else:
            with np.errstate(all="ignore"):
                mismatch = spec.compare(outcome.value, expected, probe)
            if mismatch is None:
                if computes_in_float32(outcome.value, expected) and not found:
                    found.append("passes the shown cases, but computes in float32 — the hidden cases compare "
                                 "in float64: compute (and return) float64")
                continue
            problem = headline(mismatch.message or "the values differ")
        found.append(f"passes the shown cases, but not {what}, as the hidden cases give it: "
                     f"{problem}")
        if len(found) >= 3:
            break
    return found
