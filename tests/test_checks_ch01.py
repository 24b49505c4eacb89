"""Checks of the Chapter 1 warm-up exercises (``formation.image_memory_bits``,
``formation.quantize``): reference and alternatives pass, every mistake fails and is named,
a stub scores 0."""
from __future__ import annotations

import numpy as np
import pytest

from cvkit.grading import evaluate

try:
    from . import alternatives_ch02 as alt
    from . import checks_harness as harness
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    import alternatives_ch02 as alt
    import checks_harness as harness

SEEDS = (101, 202, 303)
CH01 = ["formation.image_memory_bits", "formation.quantize"]
MISTAKES = harness.mistakes_of(CH01)


@pytest.mark.parametrize("algorithm_id", CH01)
def test_check_is_complete(algorithm_id):
    harness.assert_check_is_complete(harness.check_of(algorithm_id), SEEDS, public=(1, 6), hidden=(8, 14),
                                     min_mistakes=3)


@pytest.mark.parametrize("algorithm_id", CH01)
def test_reference_and_alternative_pass(algorithm_id):
    for candidate in (harness.reference_of(algorithm_id), alt.ALTERNATIVES[algorithm_id]):
        harness.assert_passes_everywhere(algorithm_id, candidate, SEEDS)


@pytest.mark.parametrize("algorithm_id", CH01)
def test_stub_scores_zero(algorithm_id):
    harness.assert_stub_scores_zero(algorithm_id, SEEDS)


@pytest.mark.parametrize(("algorithm_id", "name"), MISTAKES, ids=harness.pair_ids(MISTAKES))
def test_mistake_fails_and_is_named(algorithm_id, name):
    harness.assert_mistake_fails_and_is_named(algorithm_id, name, SEEDS, allowed=CH01)


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
