"""Nothing the hidden cases penalise passes the visible test silently (issue #35, item 2).

For every check, variants of the reference that differ from it only in dtype or shape handling
— computing in float32, refusing integer input, rescaling uint8 input, turning a single point
``(d,)`` into ``(1, d)`` — are graded on hidden cases; each one the hidden cases penalise must
fail the visible test or pass it with a note ("passes the shown cases, but …") from the probes
of :mod:`cvkit.grading.probes`. Correct answers get no note.
"""
from __future__ import annotations

import functools
import inspect

import numpy as np
import pytest

from cvkit import registry
from cvkit.grading import engine, evaluate
from cvkit.grading.checks import bind_call
from cvkit.grading.probes import computes_in_float32

try:
    from . import checks_harness as harness
except ImportError:  # pragma: no cover
    import checks_harness as harness

CHECKED = [r.id for r in registry.algorithms() if r.check is not None]
HIDDEN_SEED = 35


def _map(value, change):
    if isinstance(value, np.ndarray):
        return change(value)
    if isinstance(value, tuple):
        return tuple(_map(v, change) for v in value)
    if isinstance(value, list):
        return [_map(v, change) for v in value]
    if isinstance(value, dict):
        return {k: _map(v, change) for k, v in value.items()}
    return value


def _float32(a):
    return a.astype(np.float32) if a.dtype == np.float64 else a


def in_float32(reference):
    """Computes in float32: float64 inputs and results become float32."""
    @functools.wraps(reference)
    def wrong(*args, **kwargs):
        return _map(reference(*_map(args, _float32), **_map(kwargs, _float32)), _float32)
    return wrong


def refuses_integers(reference):
    @functools.wraps(reference)
    def wrong(*args, **kwargs):
        if any(isinstance(v, np.ndarray) and v.dtype.kind in "iu" for v in list(args) + list(kwargs.values())):
            raise TypeError("expected floats")
        return reference(*args, **kwargs)
    return wrong


def rescales_uint8(reference):
    def scale(a):
        return a / 255.0 if a.dtype == np.uint8 else a

    @functools.wraps(reference)
    def wrong(*args, **kwargs):
        return reference(*_map(args, scale), **_map(kwargs, scale))
    return wrong


def single_point_as_row(reference):
    """Treats a 1-D array as one row: the result keeps the leading axis of length 1."""
    def row(a):
        return a[None] if a.ndim == 1 else a

    @functools.wraps(reference)
    def wrong(*args, **kwargs):
        return reference(*[row(a) if isinstance(a, np.ndarray) else a for a in args], **kwargs)
    return wrong


def as_class(reference, change):
    """A class graded through :func:`~cvkit.grading.instance_call` changed like a function: its
    constructor and every method it is asked for go through ``change``."""
    class Wrong:
        def __init__(self, *args, **kwargs):
            self.inner = change(reference)(*args, **kwargs)

        def __getattr__(self, name):
            return change(getattr(self.inner, name))

    Wrong.__name__ = reference.__name__
    return Wrong


VARIANTS = {"float32": in_float32, "integers refused": refuses_integers, "uint8 rescaled": rescales_uint8,
            "single point as a row": single_point_as_row}
PAIRS = [(aid, name) for aid in CHECKED for name in VARIANTS]


def penalised(algorithm_id, wrong):
    """Some hidden case (seed :data:`HIDDEN_SEED`) tells ``wrong`` from the reference."""
    record = registry.get(algorithm_id)
    spec = record.check
    for case in spec.hidden_cases(np.random.default_rng(HIDDEN_SEED)):
        try:
            expected = engine._reference_output(record.reference, case, spec.call)
        except Exception:
            continue
        try:
            with np.errstate(all="ignore"):
                got = bind_call(spec.call, wrong)(*case.args, **case.kwargs)
        except Exception:
            return True
        with np.errstate(all="ignore"):
            if spec.compare(got, expected, case) is not None:
                return True
    return False


@pytest.mark.parametrize("algorithm_id,variant", PAIRS, ids=[f"{a}:{v}" for a, v in PAIRS])
def test_a_variant_the_hidden_cases_penalise_is_flagged_in_the_visible_test(algorithm_id, variant):
    record = registry.get(algorithm_id)
    wrong = as_class(record.reference, VARIANTS[variant]) if inspect.isclass(record.reference) \
        else VARIANTS[variant](record.reference)
    if not penalised(algorithm_id, wrong):
        return  # nothing to announce
    report = evaluate(algorithm_id, wrong, check=harness.allowing_itself(record.check, algorithm_id))
    assert not report.passed or report.notes, (
        f"{variant}: penalised by the hidden cases, but passes the visible test without a note")


@pytest.mark.parametrize("algorithm_id", CHECKED)
def test_the_reference_gets_no_note(algorithm_id):
    record = registry.get(algorithm_id)
    report = evaluate(algorithm_id, record.reference, check=harness.allowing_itself(record.check, algorithm_id))
    assert report.passed and report.notes == []


def test_float32_is_recognised_even_when_cast_back():
    expected = np.array([0.1, 0.2, 1 / 3])
    assert computes_in_float32(expected.astype(np.float32), expected)
    assert computes_in_float32(expected.astype(np.float32).astype(np.float64), expected)
    assert not computes_in_float32(expected + 0.0, expected)
    assert not computes_in_float32(np.array([1.0, 2.0]), np.array([1.0, 2.0]))  # exact in both: no telling


def test_the_magnitude_in_int16_is_flagged():
    def magnitude(ix, iy, norm="l2"):
        ix, iy = np.asarray(ix), np.asarray(iy)
        return np.sqrt(ix * ix + iy * iy).astype(np.float64) if norm == "l2" else \
            (np.abs(ix) + np.abs(iy) if norm == "l1" else np.maximum(np.abs(ix), np.abs(iy))).astype(np.float64)
    report = evaluate("edges.magnitude", magnitude)
    assert report.passed
    assert report.notes == [note for note in report.notes if "int16" in note] and report.notes
    assert "Note: passes the shown cases, but not on the same input in int16" in report.text()


def _alternatives():
    import importlib

    found = []
    for name in ("ch02", "ch03", "ch04", "ch05", "ch06", "ch07", "ch08", "ch09", "ch12", "nn"):
        module = importlib.import_module(f"alternatives_{name}")
        for table in (getattr(module, "ALTERNATIVES", {}), getattr(module, "EXTRA_ALTERNATIVES", {})):
            found += list(table.items()) if isinstance(table, dict) else list(table)
    return [(aid, f) for aid, f in found if aid in CHECKED]


ALTERNATIVES = _alternatives()


@pytest.mark.parametrize("algorithm_id,function", ALTERNATIVES,
                         ids=[f"{a}:{getattr(f, '__name__', 'alt')}" for a, f in ALTERNATIVES])
def test_a_correct_alternative_gets_no_note(algorithm_id, function):
    """Correct answers written differently (loops, other formulations) pass without a note."""
    spec = registry.get(algorithm_id).check
    report = evaluate(algorithm_id, function, check=harness.allowing(spec, tuple(spec.allowed) + (algorithm_id,)))
    assert report.passed and report.notes == []
