"""The Chapter 3 checks are worth their points (the tests every chapter owes:
``checks_harness.ChapterChecks``; a mistake may call every Ch. 3 id), the cases use every border
and avoid σ = 1, and the guard catches what it should on the checks as registered."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.ndimage

import cvkit.filters
from cvkit.grading import evaluate

import alternatives_ch03 as alt
import checks_harness as harness
from checks_harness import SEEDS, check_of

CH03 = [
    "filters.pad", "filters.correlate", "filters.convolve", "filters.mean_kernel", "filters.mean",
    "filters.gaussian_kernel", "filters.gaussian", "filters.median", "filters.bilateral",
    "filters.nl_means", "filters.temporal_mean", "noise.add_gaussian", "noise.add_salt_and_pepper",
]
WITH_BORDER = [
    "filters.pad", "filters.correlate", "filters.convolve", "filters.mean", "filters.gaussian",
    "filters.median", "filters.bilateral", "filters.nl_means",
]


class TestChapter03(harness.ChapterChecks):
    IDS = CH03
    TRIVIAL = frozenset({"filters.mean_kernel"})
    ALTERNATIVES = alt.ALTERNATIVES
    EXTRA_ALTERNATIVES = list(alt.EXTRA_ALTERNATIVES.items())


# --------------------------------------------------------------------------------------------
# the cases
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("algorithm_id", WITH_BORDER)
def test_hidden_cases_use_every_border(algorithm_id):
    drawn = harness.assert_hidden_cases_use_every_border(check_of(algorithm_id), SEEDS)
    if algorithm_id in ("filters.correlate", "filters.convolve"):
        for cases in drawn.values():
            assert {case.kwargs.get("output", "same") for case in cases} == {"same", "valid"}
            shapes = [np.shape(case.args[1]) for case in cases]
            assert any(kh % 2 == 0 or kw % 2 == 0 for kh, kw in shapes)
            assert any(kh != kw for kh, kw in shapes)


@pytest.mark.parametrize("algorithm_id", ["filters.gaussian_kernel", "filters.gaussian", "filters.bilateral"])
def test_sigma_is_never_one(algorithm_id):
    """With σ = 1 "σ used as variance" would be right; the cases must avoid it."""
    for seed in SEEDS:
        for case in check_of(algorithm_id).hidden_cases(np.random.default_rng(seed)):
            sigma = case.args[0] if algorithm_id == "filters.gaussian_kernel" else case.args[1]
            assert abs(sigma - 1.0) > 0.01


# --------------------------------------------------------------------------------------------
# the guard on Chapter 3 checks (as registered)
# --------------------------------------------------------------------------------------------
def test_scipy_ndimage_is_forbidden_and_named():
    def gaussian(image, sigma, border="reflect101"):
        mode = {"zero": "constant", "replicate": "nearest", "reflect": "reflect", "reflect101": "mirror"}[border]
        radius = int(np.ceil(3 * sigma - 1e-9))
        image = np.asarray(image, dtype=np.float64)
        sigmas = (sigma, sigma, 0) if image.ndim == 3 else sigma
        return scipy.ndimage.gaussian_filter(image, sigmas, mode=mode, truncate=radius / sigma)

    harness.assert_only_the_library_fails("filters.gaussian", gaussian, "scipy.ndimage")


def test_calling_the_reference_is_forbidden_and_named():
    def gaussian(image, sigma, border="reflect101"):
        return cvkit.filters.gaussian(image, sigma, border)

    harness.assert_scores_zero("filters.gaussian", gaussian, "'filters.gaussian'", hidden=True, seed=SEEDS[0])


def test_allowed_building_blocks_may_be_called():
    def gaussian(image, sigma, border="reflect101"):
        g = cvkit.filters.gaussian_kernel(sigma)
        r = g.size // 2
        padded = cvkit.filters.pad(image, r, border)
        h, w = np.shape(image)[:2]
        rows = sum(g[k] * padded[:, k: k + w] for k in range(g.size))
        return sum(g[k] * rows[k: k + h] for k in range(g.size))

    harness.assert_passes_everywhere("filters.gaussian", gaussian, SEEDS)


def test_np_pad_is_caught_in_the_pad_exercise_only():
    modes = {"zero": "constant", "replicate": "edge", "reflect": "symmetric", "reflect101": "reflect"}

    def pad(image, radius, border="reflect101"):
        ry, rx = (radius, radius) if np.isscalar(radius) else radius
        image = np.asarray(image, dtype=np.float64)
        widths = ((ry, ry), (rx, rx)) + ((0, 0),) * (image.ndim - 2)
        return np.pad(image, widths, mode=modes[border])

    harness.assert_scores_zero("filters.pad", pad, "numpy.pad")

    def mean(image, size, border="reflect101"):
        r = size // 2
        padded = pad(image, r, border)
        h, w = np.shape(image)[:2]
        return sum(padded[i: i + h, j: j + w] for i in range(size) for j in range(size)) / size ** 2

    assert evaluate("filters.mean", mean, hidden=True, seed=SEEDS[0]).passed


def test_modifying_the_input_fails():
    def mean(image, size, border="reflect101"):
        result = alt.mean(image, size, border)
        image[0, 0] = image[0, 0] + 1  # then a correct result
        return result

    report = harness.assert_scores_zero("filters.mean", mean, "modified its input")
    assert "'image'" in report.cases[0].message


def test_warnings_and_prints_cost_nothing(capsys):
    def median(image, size, border="reflect101"):
        warnings.warn("this is only a test", UserWarning)
        print("debugging output")
        return alt.median(image, size, border)

    report = evaluate("filters.median", median, hidden=True, seed=SEEDS[0])
    assert report.passed, report.text()
    assert any("this is only a test" in w for w in report.cases[0].warnings)
    assert "debugging output" in report.cases[0].stdout
    assert "Warnings raised by your code" in report.text()
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""


def test_drawing_from_np_random_fails_the_seeded_check():
    def add_gaussian(image, sigma, rng=None):
        return np.asarray(image, dtype=np.float64) + sigma * np.random.standard_normal(np.shape(image))

    report = harness.assert_scores_zero("noise.add_gaussian", add_gaussian, "same rng seed")

    def add_salt_and_pepper(image, amount, rng=None, low=0.0, high=1.0):
        return alt.add_salt_and_pepper(image, amount, None, low, high)  # ignores rng

    report = evaluate("noise.add_salt_and_pepper", add_salt_and_pepper, hidden=True, seed=SEEDS[0])
    assert not report.passed
    assert any("same rng seed" in c.message for c in report.cases)


def test_integer_output_is_refused():
    """Filters return float64 (values are not rescaled, not cast back to uint8)."""
    def mean(image, size, border="reflect101"):
        out = alt.mean(image, size, border)
        return np.round(out).astype(np.asarray(image).dtype)

    report = evaluate("filters.mean", mean)
    assert not report.passed
    assert any("dtype" in c.message for c in report.cases if not c.passed)
