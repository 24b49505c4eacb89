"""The Chapter 4 checks are worth their points (the tests every chapter owes:
``checks_harness.ChapterChecks``), mistakes that hide on natural images are still caught, the
comparators say clearly how outputs differ, and the guard catches what it should."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import scipy.ndimage

import cvkit.edges
import cvkit.filters
from cvkit import data
from cvkit.edges.checks import Angles, EdgeF1, edge_f1
from cvkit.grading import evaluate

import alternatives_ch04 as alt
import checks_harness as harness
import measured_harness
from checks_harness import EVERY_ID, SEEDS, check_of

CH04 = [
    "edges.gradient", "edges.magnitude", "edges.direction", "edges.prewitt", "edges.sobel",
    "edges.non_max_suppression", "edges.hysteresis", "edges.canny", "edges.laplacian",
    "edges.log_kernel", "edges.log", "edges.zero_crossings", "edges.dog",
]
WITH_BORDER = ["edges.gradient", "edges.prewitt", "edges.sobel", "edges.laplacian", "edges.log", "edges.dog"]
#: the measured exercise (§4.10): graded by the F1 score it reaches against true outlines
OUTLINES = "edges.detect_outlines"


class TestChapter04(harness.WholeModuleChecks):
    IDS = CH04
    MEASURED = (OUTLINES,)
    MISTAKES_MAY_CALL = EVERY_ID
    ALTERNATIVES = alt.ALTERNATIVES


# --------------------------------------------------------------------------------------------
# the cases
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("algorithm_id", WITH_BORDER)
def test_hidden_cases_use_every_border(algorithm_id):
    harness.assert_hidden_cases_use_every_border(check_of(algorithm_id), SEEDS)


def _options(cases, name, index, default):
    return {c.kwargs.get(name, c.args[index] if len(c.args) > index else default) for c in cases}


def test_hidden_cases_use_every_option_value():
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        assert _options(check_of("edges.gradient").hidden_cases(rng), "scheme", 1, "central") == {"central", "forward", "backward"}
        assert _options(check_of("edges.magnitude").hidden_cases(rng), "norm", 2, "l2") == {"l2", "l1", "max"}
        assert _options(check_of("edges.non_max_suppression").hidden_cases(rng), "interpolate", 3, True) == {True, False}
        assert _options(check_of("edges.canny").hidden_cases(rng), "relative", 4, True) == {True, False}


def test_sigma_is_never_one():
    """σ = 1 would hide "σ used as variance"; k = 1.6 would hide "k ignored" (except once)."""
    for seed in SEEDS:
        for case in check_of("edges.log_kernel").hidden_cases(np.random.default_rng(seed)):
            assert abs(case.args[0] - 1.0) > 0.01
        dog_cases = check_of("edges.dog").hidden_cases(np.random.default_rng(seed))
        ks = [c.kwargs.get("k", c.args[2] if len(c.args) > 2 else 1.6) for c in dog_cases]
        assert sum(abs(k - 1.6) < 1e-9 for k in ks) == 1


def test_separating_inputs_are_in_the_hidden_cases():
    """The awkward inputs the mistakes need: integer plateaus (NMS ≥), magnitudes that are
    not hypot (NMS), diagonal chains and values equal to thresholds (hysteresis), ties and
    zeros (zero crossings), tight relative thresholds on a disk (Canny L1)."""
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        labels = " | ".join(c.label for c in check_of("edges.non_max_suppression").hidden_cases(rng))
        assert "plateaus" in labels and "not hypot" in labels
        hyst = check_of("edges.hysteresis").hidden_cases(rng)
        assert any(np.any(c.args[0] == c.args[1]) and np.any(c.args[0] == c.args[2]) for c in hyst)
        zc = check_of("edges.zero_crossings").hidden_cases(rng)
        assert any(np.any(c.args[0] == 0) for c in zc)
        canny_labels = " | ".join(c.label for c in check_of("edges.canny").hidden_cases(rng))
        assert "tight relative thresholds" in canny_labels and "constant image" in canny_labels


# --------------------------------------------------------------------------------------------
# mistakes that hide, alternatives built of the student's own pieces
# --------------------------------------------------------------------------------------------
def test_a_mistake_hidden_by_natural_images_is_still_caught():
    """Canny with an L1 magnitude agrees with the right edges on the camera image (F1 ≈ 0.98
    within 1 px), yet fails the check: the hidden disks with tight relative thresholds expose it."""
    camera = data.resize_half(data.camera())
    wrong = check_of("edges.canny").mistake("L1 magnitude instead of L2").function
    f1 = edge_f1(wrong(camera, 1.4), cvkit.edges.canny(camera, 1.4), radius=1)[0]
    assert 0.95 < f1 < 0.995
    allowing = dataclasses.replace(check_of("edges.canny"), allowed=EVERY_ID)
    for seed in SEEDS:
        report = evaluate("edges.canny", wrong, hidden=True, seed=seed, check=allowing)
        failed = [c.label for c in report.cases if not c.passed]
        assert any("disk" in label for label in failed)


def test_a_canny_built_from_the_students_own_pieces_passes():
    """What the notebook solution does: its own Gaussian, Sobel, NMS and hysteresis."""
    for report in harness.grade_everywhere("edges.canny", alt.canny, SEEDS):
        assert report.passed


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
def test_edge_f1_definition():
    a = np.zeros((6, 6), bool)
    a[2, 1:5] = True
    b = np.zeros((6, 6), bool)
    b[3, 1:5] = True
    b[0, 0] = True
    assert edge_f1(a, a, 0) == (1.0, 1.0, 1.0)
    assert edge_f1(a, b, 0)[0] == 0.0
    f1, precision, recall = edge_f1(a, b, 1)
    assert precision == 1.0 and recall == 0.8 and math.isclose(f1, 2 * 0.8 / 1.8)
    empty = np.zeros((6, 6), bool)
    assert edge_f1(empty, empty, 0) == (1.0, 1.0, 1.0)
    assert edge_f1(empty, a, 1)[0] == 0.0 and edge_f1(a, empty, 1)[0] == 0.0


def test_edge_f1_comparator_messages():
    compare = EdgeF1(radius=0, min_f1=0.97)
    expected = np.zeros((8, 8), bool)
    expected[3, :] = True
    assert compare(expected.copy(), expected) is None
    shifted = np.roll(expected, 1, axis=0)
    mismatch = compare(shifted, expected)
    assert "F1 = 0.000" in mismatch.message and "spurious: 8, missing: 8" in mismatch.message
    assert "First spurious edge pixel at [4, 0]" in mismatch.message
    assert EdgeF1(radius=1, min_f1=0.97)(shifted, expected) is None
    assert "bool" in compare(expected.astype(np.uint8), expected).message
    assert "shape mismatch" in compare(expected[:, :5], expected).message
    assert "None" in compare(None, expected).message
    one_off = expected.copy()
    one_off[3, 0] = False  # recall 7/8: F1 0.933
    assert compare(one_off, expected) is not None
    big = np.zeros((40, 40), bool)
    big[5:35, 20] = True
    almost = big.copy()
    almost[5, 20] = False  # F1 0.983 >= 0.97: a single tie does not fail a correct detector
    assert compare(almost, big) is None


def test_angles_comparator_wraps_around():
    compare = Angles(atol=1e-9)
    expected = np.array([np.pi, -np.pi / 2, 0.0, 3.0])
    assert compare(np.array([-np.pi, 3 * np.pi / 2, 2 * np.pi, 3.0 - 2 * np.pi]), expected) is None
    mismatch = compare(np.array([0.0, -np.pi / 2, 0.0, 3.0]), expected)
    assert "Mismatched elements: 1 / 4" in mismatch.message and "180°" in mismatch.message
    mismatch = compare(np.array([np.nan, -np.pi / 2, 0.0, 3.0]), expected)
    assert "NaN" in mismatch.message
    assert "float" in compare(np.array([3, 0, 0, 3]), expected).message


# --------------------------------------------------------------------------------------------
# the guard on Chapter 4 checks (as registered)
# --------------------------------------------------------------------------------------------
def test_scipy_ndimage_is_forbidden_and_named():
    def sobel(image, border="reflect101"):
        mode = {"zero": "constant", "replicate": "nearest", "reflect": "reflect", "reflect101": "mirror"}[border]
        image = np.asarray(image, dtype=np.float64)
        return scipy.ndimage.sobel(image, axis=1, mode=mode), scipy.ndimage.sobel(image, axis=0, mode=mode)

    harness.assert_only_the_library_fails("edges.sobel", sobel, "scipy.ndimage")


def test_calling_the_reference_is_forbidden_and_named():
    def hysteresis(magnitude, low, high):
        return cvkit.edges.hysteresis(magnitude, low, high)

    harness.assert_scores_zero("edges.hysteresis", hysteresis, "'edges.hysteresis'", hidden=True, seed=SEEDS[0])


def test_canny_may_call_the_allowed_building_blocks():
    def canny(image, sigma=1.4, low=0.1, high=0.2, relative=True):
        smooth = cvkit.filters.gaussian(image, sigma)
        gx, gy = cvkit.edges.sobel(smooth)
        strength = cvkit.edges.magnitude(gx, gy)
        top = strength.max()
        if top <= 1e-12 * max(1.0, np.abs(np.asarray(image, dtype=float)).max()):
            return np.zeros(np.shape(image), dtype=bool)
        if relative:
            low, high = low * top, high * top
        return cvkit.edges.hysteresis(cvkit.edges.non_max_suppression(strength, gx, gy), low, high)

    harness.assert_passes_everywhere("edges.canny", canny, SEEDS)

    def canny_cheat(image, sigma=1.4, low=0.1, high=0.2, relative=True):
        return cvkit.edges.canny(image, sigma, low, high, relative)

    assert evaluate("edges.canny", canny_cheat).score == 0.0


def test_log_may_call_its_kernel_and_correlate():
    def log(image, sigma, border="reflect101"):
        return cvkit.filters.correlate(image, cvkit.edges.log_kernel(sigma), border)

    harness.assert_passes_everywhere("edges.log", log, SEEDS)


def test_integer_output_is_refused():
    def magnitude(ix, iy, norm="l2"):
        return np.abs(np.asarray(ix)) + np.abs(np.asarray(iy)) if norm == "l1" else alt.magnitude(ix, iy, norm)

    report = evaluate("edges.magnitude", magnitude, hidden=True, seed=SEEDS[0])
    assert not report.passed
    assert any("dtype" in c.message for c in report.cases if not c.passed)


def test_canny_returning_0_1_integers_is_told_to_return_bool():
    def canny(image, sigma=1.4, low=0.1, high=0.2, relative=True):
        return alt.canny(image, sigma, low, high, relative).astype(np.uint8)

    harness.assert_scores_zero("edges.canny", canny, "bool")


# --------------------------------------------------------------------------------------------
# the measured exercise: edges.detect_outlines, graded by F1 against the true outlines
# --------------------------------------------------------------------------------------------
from cvkit.edges import checks as edges_checks  # noqa: E402

OUTLINE_SEEDS = (101, 202)
_f1 = edges_checks.OutlineF1.f1


def test_the_outline_scale_is_the_published_one():
    from cvkit.edges import _outlines

    assert tuple(edges_checks.OUTLINE_F1) == _outlines.F1_SCALE == ((0.60, 0.0), (0.75, 0.5), (0.85, 1.0))
    assert edges_checks.OUTLINE_RADIUS == 1
    measured_harness.assert_notebook_publishes("ch04_edges", OUTLINES, "detect_outlines(image)",
                                               edges_checks.OUTLINE_F1,
                                               "F1 against the true outlines (1 px tolerance)", _outlines.BUDGET_SECONDS)


def test_the_outline_check_measures_what_it_should():
    """The reference and a Canny tuned another way (relative thresholds) clear the top; default
    thresholds, no non-maximum suppression and no smoothing stay below it; a stub earns 0."""
    measured_harness.assert_measures_what_it_should(OUTLINES, OUTLINE_SEEDS, _f1, edges_checks.OUTLINE_F1, "F1",
                                                    alternatives=[alt.detect_outlines])
    measured_harness.assert_reports_advise(OUTLINES, {"Canny's default relative thresholds on a noisy picture": "noise edges",
                                                      "no non-maximum suppression": "non-maximum suppression"})


def _every_other_outline_pixel_missed(image):
    """The reference's map with its outline pixels dropped in a checkerboard of 3×3 blocks
    and noise edges added: between the corners of the scale."""
    found = cvkit.edges._outlines.outline_canny(image, 2.0, *edges_checks._noise_thresholds(image, 2.0))
    rows, cols = np.indices(found.shape)
    thinned = found & ((rows // 3 + cols // 3) % 2 == 0)
    return thinned | ((rows % 11 == 0) & (cols % 13 == 0))


def test_outline_partial_credit_follows_the_scale():
    measured_harness.assert_partial_credit_follows_the_scale(OUTLINES, _every_other_outline_pixel_missed, 101, _f1,
                                                             edges_checks.OUTLINE_F1)


def test_outline_pictures_differ_per_student_and_their_truth_stays_outside():
    measured_harness.assert_hidden_data_differ_and_truth_stays_outside(OUTLINES, measured_harness.same_input_and_truth)
    for case in harness.hidden_cases(OUTLINES, 5):
        (image,) = case.args
        assert image.shape == case.truth.shape == (112, 112) and case.truth.dtype == bool
        assert 200 < case.truth.sum() < 1200


def test_the_truth_is_where_the_shapes_end():
    """The true outline pixels are where the picture's smoothed gradient is strong: a shape's
    contrast, several times the gradient of the noise and the shading away from the outlines."""
    rng = np.random.default_rng(3)
    image, truth = edges_checks.outline_scene(rng)
    smooth = scipy.ndimage.gaussian_filter(image, 2.0)
    gx, gy = scipy.ndimage.sobel(smooth, axis=1), scipy.ndimage.sobel(smooth, axis=0)
    strength = np.hypot(gx, gy)
    assert np.median(strength[truth]) > 4 * np.median(strength[~scipy.ndimage.binary_dilation(truth, iterations=3)])
