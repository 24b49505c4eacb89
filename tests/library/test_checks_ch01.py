"""Checks of the Chapter 1 warm-up exercises (``formation.image_memory_bits``,
``formation.quantize``): reference and alternatives pass, every mistake fails and is named,
a stub scores 0."""
from __future__ import annotations

import numpy as np
import pytest

from cvkit.grading import evaluate

import alternatives_ch02 as alt
import checks_harness as harness
from checks_harness import SEEDS

CH01 = ["formation.image_memory_bits", "formation.quantize"]


class TestChapter01(harness.MistakeBankChecks):
    IDS = CH01
    MIN_MISTAKES = 3


@pytest.mark.parametrize("algorithm_id", CH01)
def test_reference_and_alternative_pass(algorithm_id):
    for candidate in (harness.reference_of(algorithm_id), alt.ALTERNATIVES[algorithm_id]):
        harness.assert_passes_everywhere(algorithm_id, candidate, SEEDS)


def test_float_memory_is_refused():
    harness.assert_scores_zero("formation.image_memory_bits",
                               lambda width, height, bits_per_pixel: width * height * bits_per_pixel / 1, "dtype")


def test_round_half_up_is_a_named_mistake():
    def quantize(image, bits, vmax=1.0):
        x = np.clip(np.asarray(image, dtype=float), 0, vmax) / vmax * (2 ** bits - 1)
        return np.floor(x + 0.5) / (2 ** bits - 1) * vmax

    report = evaluate("formation.quantize", quantize)
    assert not report.passed
    assert report.mistake == "halves rounded up, not as np.round"
