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


# --------------------------------------------------------------------------------------------
# the measured exercise: filters.denoise, graded by its PSNR against the reference's
# --------------------------------------------------------------------------------------------
from cvkit.filters import _denoise as denoise_task  # noqa: E402
from cvkit.filters.checks import DENOISE_SCALE  # noqa: E402

try:
    from . import measured_harness as measured
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    import measured_harness as measured

DENOISE = "filters.denoise"


def _gap(output, case):
    noisy, sigma = case.args
    return denoise_task.psnr_gap(output, noisy, sigma, case.truth)


def test_denoise_notebook_publishes_the_scale_and_budget():
    assert DENOISE_SCALE.corners == denoise_task.PSNR_GAP_SCALE and check_of(DENOISE).credit is not None
    measured.assert_notebook_publishes("ch03_filtering", DENOISE, "denoise(noisy, sigma)", DENOISE_SCALE,
                                       "your PSNR minus the reference's (dB), per crop", denoise_task.BUDGET_SECONDS)


def test_the_reference_denoises_every_crop_and_a_correct_variant_stays_near_it():
    """Over 30 crops the reference gains at least 4 dB over the noisy input, and the
    alternative (same method, other border and code) stays within 1 dB of it: the top of the
    scale (−2 dB) leaves room for other reasonable settings."""
    gains, gaps = [], []
    for seed in range(30):
        noisy, sigma, clean, _ = denoise_task.noisy_crop(seed)
        reference = denoise_task.psnr(clean, denoise_task.denoise(noisy, sigma))
        gains.append(reference - denoise_task.psnr(clean, noisy))
        gaps.append(denoise_task.psnr(clean, alt.denoise(noisy, sigma)) - reference)
    assert min(gains) > 4.0, min(gains)
    assert min(gaps) > -1.0, min(gaps)


def test_denoise_measures_what_it_should():
    measured.assert_measures_what_it_should(DENOISE, SEEDS, _gap, DENOISE_SCALE, "your PSNR minus the reference's (dB)",
                                            alternatives=(alt.denoise,))


def _half_denoised(noisy, sigma):
    """The reference's output with 42 % of the noisy input mixed back: between the corners."""
    image = np.asarray(noisy, dtype=np.float64)
    return 0.58 * denoise_task.denoise_unregistered(image, sigma) + 0.42 * image


def test_denoise_partial_credit_follows_the_scale():
    measured.assert_partial_credit_follows_the_scale(DENOISE, _half_denoised, SEEDS[0], _gap, DENOISE_SCALE)


def test_denoise_crops_differ_per_student_and_the_clean_image_stays_with_the_grader():
    measured.assert_hidden_data_differ_and_truth_stays_outside(DENOISE, measured.same_input_and_truth)
    for case in check_of(DENOISE).hidden_cases(np.random.default_rng(SEEDS[0])):
        noisy, sigma = case.args
        assert noisy.shape == case.truth.shape == (denoise_task.CROP, denoise_task.CROP)
        assert denoise_task.SIGMA_RANGE[0] <= sigma <= denoise_task.SIGMA_RANGE[1]
        assert abs(np.std(noisy - case.truth) - sigma) < 0.1 * sigma      # the noise is what sigma says
        assert case.truth.std() >= denoise_task.MIN_CONTRAST


def test_a_denoised_image_of_the_wrong_shape_fails_with_a_message():
    report = evaluate(DENOISE, lambda noisy, sigma: np.zeros((3, 3)))
    assert not report.passed and report.score == 0.0
    assert "the shape of the noisy image" in report.cases[0].message


def test_the_clean_pictures_are_not_served_to_a_graded_denoiser():
    """The crops come from cvkit.data images: a graded answer that could load them might look
    the crop up instead of denoising it, so the sandbox serves none of them to this exercise."""
    from cvkit.grading.served import served_helpers

    served = served_helpers(DENOISE)
    assert not {f"data.{name}" for name in denoise_task.IMAGES} & set(served)
    assert "data.camera" in served_helpers("filters.nl_means")
