"""The Chapter 3 checks are worth their points: the reference and correct alternatives pass,
every mistake of every bank fails and is named, and the guard catches what it should.

Mistake functions of the banks are built on the reference implementations (they run under
the reference provider when the grader compares outputs). To grade a mistake *as a candidate*
the tests therefore allow every reference building block (``allowed=`` all Ch. 3 ids); the
guard itself is tested separately below on the checks as registered.
"""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
import scipy.ndimage

import cvkit.filters
from cvkit.grading import evaluate

try:
    from . import alternatives_ch03 as alt
    from . import checks_harness as harness
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    import alternatives_ch03 as alt
    import checks_harness as harness

SEEDS = (101, 202, 303)
BORDERS = {"zero", "replicate", "reflect", "reflect101"}
CH03 = [
    "filters.pad", "filters.correlate", "filters.convolve", "filters.mean_kernel", "filters.mean",
    "filters.gaussian_kernel", "filters.gaussian", "filters.median", "filters.bilateral",
    "filters.nl_means", "filters.temporal_mean", "noise.add_gaussian", "noise.add_salt_and_pepper",
]
WITH_BORDER = [
    "filters.pad", "filters.correlate", "filters.convolve", "filters.mean", "filters.gaussian",
    "filters.median", "filters.bilateral", "filters.nl_means",
]
_check = harness.check_of
MISTAKES = harness.mistakes_of(CH03)


# --------------------------------------------------------------------------------------------
# the shape of every check
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("algorithm_id", CH03)
def test_check_is_complete(algorithm_id):
    nontrivial = algorithm_id != "filters.mean_kernel"
    harness.assert_check_is_complete(_check(algorithm_id), SEEDS, public=(1, 6), hidden=(8, 14),
                                     min_mistakes=4 if nontrivial else 3)


@pytest.mark.parametrize("algorithm_id", CH03)
def test_hidden_cases_are_reproducible(algorithm_id):
    harness.assert_hidden_cases_reproducible(_check(algorithm_id), harness.describe_and_array_args)


@pytest.mark.parametrize("algorithm_id", WITH_BORDER)
def test_hidden_cases_use_every_border(algorithm_id):
    drawn = harness.assert_hidden_cases_use_every_border(_check(algorithm_id), SEEDS, BORDERS, default="reflect101")
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
        for case in _check(algorithm_id).hidden_cases(np.random.default_rng(seed)):
            sigma = case.args[0] if algorithm_id == "filters.gaussian_kernel" else case.args[1]
            assert abs(sigma - 1.0) > 0.01


# --------------------------------------------------------------------------------------------
# right answers pass, wrong ones fail and are named
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("algorithm_id", CH03)
def test_reference_passes(algorithm_id):
    harness.assert_reference_passes(algorithm_id, SEEDS)


@pytest.mark.parametrize("algorithm_id", CH03)
def test_stub_scores_zero(algorithm_id):
    harness.assert_stub_scores_zero(algorithm_id, SEEDS)


@pytest.mark.parametrize(("algorithm_id", "name"), MISTAKES, ids=harness.pair_ids(MISTAKES))
def test_mistake_fails_and_is_named(algorithm_id, name):
    harness.assert_mistake_fails_and_is_named(algorithm_id, name, SEEDS, allowed=CH03)


ALTERNATIVE_IDS = [(aid, f) for aid, f in alt.ALTERNATIVES.items()] + list(alt.EXTRA_ALTERNATIVES.items())


@pytest.mark.parametrize(("algorithm_id", "function"), ALTERNATIVE_IDS, ids=harness.function_ids(ALTERNATIVE_IDS))
def test_correct_alternative_passes(algorithm_id, function):
    harness.assert_passes_everywhere(algorithm_id, function, SEEDS)


def test_every_algorithm_has_an_alternative():
    assert set(alt.ALTERNATIVES) == set(CH03)


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

    report = evaluate("filters.gaussian", gaussian)
    assert report.score == 0.0
    assert all("scipy.ndimage" in c.message for c in report.cases), report.text()
    # the same function is right: only the forbidden call fails it
    open_check = dataclasses.replace(_check("filters.gaussian"), allowed_libraries=("scipy.ndimage",))
    assert evaluate("filters.gaussian", gaussian, check=open_check).passed


def test_calling_the_reference_is_forbidden_and_named():
    def gaussian(image, sigma, border="reflect101"):
        return cvkit.filters.gaussian(image, sigma, border)

    report = evaluate("filters.gaussian", gaussian, hidden=True, seed=SEEDS[0])
    assert report.score == 0.0
    assert "'filters.gaussian'" in report.cases[0].message


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

    report = evaluate("filters.pad", pad)
    assert report.score == 0.0
    assert "numpy.pad" in report.cases[0].message

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

    report = evaluate("filters.mean", mean)
    assert report.score == 0.0
    assert "modified its input" in report.cases[0].message
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

    report = evaluate("noise.add_gaussian", add_gaussian)
    assert report.score == 0.0
    assert "same rng seed" in report.cases[0].message

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
