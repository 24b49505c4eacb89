"""Probes: what the hidden cases penalise that the visible cases do not show.

A visible test that passes should not hide a rule the hidden cases apply (an input dtype, a
shape, the precision of the result). After a *passing* visible evaluation, the engine runs the
candidate on a few variants of the public inputs shaped like the hidden cases (the same input
in the dtypes the hidden cases use, a single point or a single row where they give one) and
compares with the reference there. A difference is not a failure and costs nothing: the
visible report gets one line, "passes the shown cases, but …", naming what differs, so that a
student learns it before the deadline rather than from the grade.

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
    """What the hidden cases give at each argument (a position or a keyword name)."""

    #: key -> {dtype name: largest |value| met in that dtype}
    dtypes: dict = field(default_factory=dict)
    #: keys at which a hidden case gives a one-dimensional array
    vectors: set = field(default_factory=set)
    #: keys at which a hidden case gives an array of one row (shape ``(1, ...)``, ndim ≥ 2)
    rows: set = field(default_factory=set)


def _arguments(case: Case) -> Iterator[tuple[Any, Any]]:
    yield from enumerate(case.args)
    yield from case.kwargs.items()


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
            if not isinstance(value, np.ndarray) or value.dtype.kind not in "biuf" or value.size == 0:
                continue
            top = float(np.max(np.abs(value.astype(np.float64)))) if value.dtype.kind != "b" else 1.0
            kinds = found.dtypes.setdefault(key, {})
            kinds[value.dtype.name] = max(kinds.get(value.dtype.name, 0.0), top if np.isfinite(top) else 0.0)
            if value.ndim == 1:
                found.vectors.add(key)
            elif value.shape[0] == 1:
                found.rows.add(key)
    _PROFILES[id(spec)] = (spec, found)
    return found


def _to_dtype(values: list[np.ndarray], dtype: np.dtype, top: float) -> list[np.ndarray] | None:
    """``values`` (the arrays of one case that the hidden cases give in ``dtype``) in that
    dtype: cast as they are when they are integers that fit, else mapped together onto the
    range the hidden cases use (``[0, top]`` unsigned, ``[-top, top]`` signed)."""
    if dtype.kind == "f":
        return [v.astype(dtype) for v in values]
    if dtype.kind == "b":
        return None
    info = np.iinfo(dtype)
    floats = [v.astype(np.float64) for v in values]
    if not all(np.all(np.isfinite(f)) for f in floats):
        return None
    lo = min(float(f.min()) for f in floats)
    hi = max(float(f.max()) for f in floats)
    limit = min(float(top), float(info.max))
    integral = all(np.array_equal(f, np.round(f)) for f in floats)
    if integral and lo >= info.min and hi <= info.max and hi - lo >= 2:
        return [f.astype(dtype) for f in floats]
    if hi <= lo or limit < 1:
        return None
    if info.min == 0 or lo >= 0:
        return [np.round((f - lo) / (hi - lo) * limit).astype(dtype) for f in floats]
    scale = max(abs(lo), abs(hi))
    return [np.round(f / scale * limit).astype(dtype) for f in floats]


def _with(case: Case, replaced: dict, label: str) -> Case:
    args = list(case.args)
    kwargs = dict(case.kwargs)
    for key, value in replaced.items():
        if isinstance(key, int):
            args[key] = value
        else:
            kwargs[key] = value
    return Case(tuple(args), kwargs, label)


def variants(spec: Check, cases: list[Case]) -> Iterator[tuple[str, Case]]:
    """``(what, probe case)``: the public ``cases`` in the dtypes and shapes the hidden cases
    use and the public ones do not (what: "int16 input", "a single point (1-D input)"...)."""
    found = profile(spec)
    public_dtypes: dict = {}
    for case in cases:
        for key, value in _arguments(case):
            if isinstance(value, np.ndarray):
                public_dtypes.setdefault(key, set()).add(value.dtype.name)
    seen_dtypes: set = set()
    for case in cases:
        arrays = {key: value for key, value in _arguments(case)
                  if isinstance(value, np.ndarray) and value.dtype.kind in "biuf" and value.size}
        # dtypes: every array argument the hidden cases give in a dtype no public case uses
        wanted: dict = {}
        for key, value in arrays.items():
            for name, top in found.dtypes.get(key, {}).items():
                if name not in public_dtypes.get(key, set()) and name != value.dtype.name:
                    wanted.setdefault(name, {})[key] = top
        for name, keys in sorted(wanted.items()):
            if name in seen_dtypes:
                continue
            converted = _to_dtype([arrays[k] for k in keys], np.dtype(name), max(keys.values()))
            if converted is None:
                continue
            seen_dtypes.add(name)
            yield f"on the same input in {name}", _with(case, dict(zip(keys, converted)), f"{case.label} ({name})")
    for case in cases:
        arrays = {key: value for key, value in _arguments(case) if isinstance(value, np.ndarray)}
        points = {k: v for k, v in arrays.items() if k in found.vectors and v.ndim == 2 and v.shape[0] > 1}
        if points and len({v.shape[0] for v in points.values()}) == 1:
            yield ("on a single point of the same input, of shape (d,)" if all(v.shape[1] <= 4 for v in points.values())
                   else "on one row of the same input as a 1-D array"), _with(case, {k: v[0].copy() for k, v in points.items()}, f"{case.label} (1-D)")
            break
    for case in cases:
        arrays = {key: value for key, value in _arguments(case) if isinstance(value, np.ndarray)}
        rows = {k: v for k, v in arrays.items() if k in found.rows and v.ndim >= 2 and v.shape[0] > 1}
        if rows and len({v.shape[0] for v in rows.values()}) == 1:
            yield "on a single row of the same input", _with(case, {k: v[:1].copy() for k, v in rows.items()}, f"{case.label} (one row)")
            break


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
          reference: Callable[[Case], Any], headline: Callable[[str], str]) -> list[str]:
    """The one-line notes of a passing visible evaluation (see the module's docstring).

    ``outputs`` are the (candidate's, reference's) results of the passed public cases; ``run``
    runs the candidate on a case under the guard (an :class:`~cvkit.grading.runtime.guard.Outcome`);
    ``reference`` computes the reference's output (raising when it cannot); ``headline`` makes a
    failure message short.
    """
    found: list[str] = []
    if any(computes_in_float32(got, expected) for got, expected in outputs):
        found.append("passes the shown cases, but computes in float32 — the hidden cases compare in "
                     "float64: compute (and return) float64")
    runs = 0
    for what, probe in variants(spec, cases):
        if runs >= MAX_PROBES:
            break
        try:
            expected = reference(probe)
        except Exception:  # an input the reference refuses is no rule of the exercise
            continue
        runs += 1
        outcome = run(probe)
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
    return found


def copy_case(case: Case) -> Case:
    return Case(copy.deepcopy(case.args), copy.deepcopy(case.kwargs), case.label)
