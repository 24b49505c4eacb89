"""Checks of the Chapter 1 warm-up exercises (``formation.image_memory_bits``,
``formation.quantize``): reference and alternatives pass, every mistake fails and is named,
a stub scores 0."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cvkit import registry
from cvkit.grading import evaluate

try:
    from . import alternatives_ch02 as alt
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    import alternatives_ch02 as alt

SEEDS = (101, 202, 303)
CH01 = ["formation.image_memory_bits", "formation.quantize"]
MISTAKES = [(aid, m.name) for aid in CH01 for m in registry.get(aid).check.mistakes]


def _grade_everywhere(algorithm_id, candidate, check=None):
    reports = [evaluate(algorithm_id, candidate, check=check)]
    reports += [evaluate(algorithm_id, candidate, hidden=True, seed=s, check=check) for s in SEEDS]
    return reports


@pytest.mark.parametrize("algorithm_id", CH01)
def test_check_is_complete(algorithm_id):
    spec = registry.get(algorithm_id).check
    assert 1 <= len(spec.public_cases()) <= 6
    assert len(spec.mistakes) >= 3
    for seed in SEEDS:
        hidden = spec.hidden_cases(np.random.default_rng(seed))
        assert 8 <= len(hidden) <= 14 and all(c.label for c in hidden)


@pytest.mark.parametrize("algorithm_id", CH01)
def test_reference_and_alternative_pass(algorithm_id):
    for candidate in (registry.get(algorithm_id).reference, alt.ALTERNATIVES[algorithm_id]):
        for report in _grade_everywhere(algorithm_id, candidate):
            assert report.passed, report.text()


@pytest.mark.parametrize("algorithm_id", CH01)
def test_stub_scores_zero(algorithm_id):
    def stub(*args, **kwargs):
        raise NotImplementedError

    for report in _grade_everywhere(algorithm_id, stub):
        assert report.score == 0.0


@pytest.mark.parametrize(("algorithm_id", "name"), MISTAKES, ids=[f"{a}:{n}" for a, n in MISTAKES])
def test_mistake_fails_and_is_named(algorithm_id, name):
    spec = registry.get(algorithm_id).check
    mistake = spec.mistake(name)
    allowing = dataclasses.replace(spec, allowed=tuple(CH01))
    public = evaluate(algorithm_id, mistake.function, check=allowing)
    assert not public.passed and public.mistake == name
    for seed in SEEDS:
        report = evaluate(algorithm_id, mistake.function, hidden=True, seed=seed, check=allowing)
        assert not report.passed, f"hidden cases (seed {seed}) do not catch {name!r}"
        assert report.mistake == name, [(c.label, c.mistake) for c in report.cases if not c.passed]


def test_float_memory_is_refused():
    report = evaluate("formation.image_memory_bits", lambda width, height, bits_per_pixel: width * height * bits_per_pixel / 1)
    assert report.score == 0.0
    assert "dtype" in report.cases[0].message


def test_round_half_up_is_a_named_mistake():
    def quantize(image, bits, vmax=1.0):
        x = np.clip(np.asarray(image, dtype=float), 0, vmax) / vmax * (2 ** bits - 1)
        return np.floor(x + 0.5) / (2 ** bits - 1) * vmax

    report = evaluate("formation.quantize", quantize)
    assert not report.passed
    assert report.mistake == "halves rounded up, not as np.round"
