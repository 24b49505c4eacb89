"""No helper the grader computes for a student is, by itself, the answer (issue 32).

Graded code may call some of cvkit's functions, computed outside the sandbox by the trusted
side: the building blocks a check lists (``filters.pad`` in the correlation exercise) and the
data sources (``data.camera()``). For every check, each helper it is served is tried here as
the whole answer — ``def answer(*args, **kwargs): return helper(*args, **kwargs)`` — on the
public cases and the hidden cases of two seeds, and must pass none of them. The data loaders
that compute from an image (``data.with_gaussian_noise`` *is* ``noise.add_gaussian``) are
never served, and are watched in the student's own kernel too.
"""
import inspect
import warnings

import numpy as np
import pytest

from cvkit import data, registry
from cvkit.grading import evaluate
from cvkit.grading.checks import bind_call
from cvkit.grading.engine import _reference_output
from cvkit.grading.served import DATA_LOADERS, DATA_SOURCES, DATA_TRANSFORMS, served_helpers
from cvkit.sandbox.reference_server import _function
from cvkit.grading.runtime.guard import run_guarded

ALGORITHMS = [record.id for record in registry.algorithms() if record.check is not None]


def _cases(spec):
    return spec.public_cases() + [case for seed in (7, 8) for case in spec.hidden_cases(np.random.default_rng(seed))]


def _callable_with(function, case) -> bool:
    """Whether ``function`` accepts the case's arguments at all (if not, calling it raises
    TypeError: it cannot pass)."""
    try:
        inspect.signature(function).bind(*case.args, **case.kwargs)
    except TypeError:
        return False
    return True


@pytest.mark.parametrize("algorithm_id", ALGORITHMS)
def test_no_served_helper_is_the_whole_answer(algorithm_id):
    record = registry.get(algorithm_id)
    spec = record.check
    helpers = served_helpers(algorithm_id, tuple(spec.allowed))
    assert algorithm_id not in helpers
    assert not any(h == f"data.{name}" for h in helpers for name in DATA_TRANSFORMS)
    cases = []
    for case in _cases(spec):
        try:
            cases.append((case, _reference_output(record.reference, case, spec.call)))
        except Exception:  # noqa: BLE001 - a case the reference cannot compute is never scored
            continue
    assert cases
    passed = []
    for helper_id in helpers:
        function = _function(helper_id)
        for case, expected in cases:
            if spec.call is None and not _callable_with(function, case):
                continue  # a TypeError at the call: fails
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                outcome = run_guarded(bind_call(spec.call, function), case.args, case.kwargs,
                                      time_limit=spec.time_limit, watch_reference=False)
            if outcome.error is not None:
                continue
            with np.errstate(all="ignore"):
                if spec.compare(outcome.value, expected, case) is None:
                    passed.append(f"{helper_id} passes {case.label or case.describe(())}")
    assert not passed, passed


def test_every_loader_is_a_source_or_a_transform():
    assert set(DATA_SOURCES).isdisjoint(DATA_TRANSFORMS)
    assert set(DATA_LOADERS) == set(DATA_SOURCES) | set(DATA_TRANSFORMS)
    for name in DATA_LOADERS:
        assert callable(getattr(data, name)), name
    # a transform takes the student's image; a source makes data from numbers alone
    for name in DATA_TRANSFORMS:
        first = next(iter(inspect.signature(getattr(data, name)).parameters))
        assert first in ("img", "reference"), (name, first)


def test_a_noise_loader_as_the_noise_answer_is_refused_in_the_kernel_too():
    """While the student works, the visible test already says what grading will say."""
    def add_gaussian(image, sigma, rng=None):
        return data.with_gaussian_noise(image, sigma, rng)

    def add_salt_and_pepper(image, amount, rng=None, low=0.0, high=1.0):
        return data.with_impulse_noise(image, amount, rng)

    for algorithm_id, answer, loader in (("noise.add_gaussian", add_gaussian, "with_gaussian_noise"),
                                         ("noise.add_salt_and_pepper", add_salt_and_pepper, "with_impulse_noise")):
        for hidden in (False, True):
            report = evaluate(algorithm_id, answer, hidden=hidden, seed=11)
            assert report.score == 0, (algorithm_id, hidden)
            assert all(loader in case.message for case in report.cases), report.cases[0].message
