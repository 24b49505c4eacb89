"""The Chapter 2 checks are worth their points (the tests every chapter owes:
``checks_harness.ChapterChecks``), the cases cover the awkward inputs, the disparity comparator
accepts only genuine ties, and the guard catches what it should."""
from __future__ import annotations

import numpy as np
import pytest

import cvkit.formation
import cvkit.stereo
from cvkit.grading import evaluate
from cvkit.stereo.checks import DisparityMaps

import alternatives_ch02 as alt
import checks_harness as harness
from checks_harness import SEEDS, check_of

CH02 = [
    "formation.project_pinhole", "formation.depth_from_disparity", "stereo.block_matching",
    "formation.thin_lens_image_distance", "formation.blur_circle_diameter", "formation.snr_db",
    "formation.dynamic_range_db", "formation.bayer_mosaic", "formation.demosaic_bilinear",
]
ALL_IDS = CH02 + ["formation.quantize", "formation.image_memory_bits"]


def _values(case):
    """Every non-string argument of a case, as an array."""
    return tuple(np.asarray(x) for x in list(case.args) + list(case.kwargs.values()) if not isinstance(x, str))


class TestChapter02(harness.ChapterChecks):
    IDS = CH02
    MISTAKES_MAY_CALL = ALL_IDS
    MIN_MISTAKES = 3
    ALTERNATIVES = {aid: f for aid, f in alt.ALTERNATIVES.items() if aid in CH02}  # (the others: Chapter 1)
    EXTRA_ALTERNATIVES = list(alt.EXTRA_ALTERNATIVES.items())
    EQUAL_NAN = True

    def fingerprint(self, case):
        return (case.describe(), *_values(case))

    def varies(self, case):
        return _values(case)


def test_bayer_cases_use_every_pattern_and_odd_sizes():
    for name in ("formation.bayer_mosaic", "formation.demosaic_bilinear"):
        for seed in SEEDS:
            cases = check_of(name).hidden_cases(np.random.default_rng(seed))
            patterns = {c.kwargs.get("pattern", c.args[1] if len(c.args) > 1 else "RGGB") for c in cases}
            assert patterns == set(cvkit.formation.PATTERNS)
            assert any(np.shape(c.args[0])[0] % 2 and np.shape(c.args[0])[1] % 2 for c in cases)


def test_block_matching_cases_cover_every_cost_and_the_awkward_inputs():
    for seed in SEEDS:
        cases = check_of("stereo.block_matching").hidden_cases(np.random.default_rng(seed))
        costs = {c.kwargs.get("cost", "sad") for c in cases}
        assert costs == set(cvkit.stereo.COSTS)
        assert any(np.asarray(c.args[0]).dtype == np.uint8 for c in cases)
        assert any(c.kwargs.get("block_size", 7) == 1 for c in cases)
        assert any(c.args[2] == 0 for c in cases)
        assert any(c.args[2] >= np.shape(c.args[0])[1] for c in cases)
        assert any("block_size" not in c.kwargs and "cost" not in c.kwargs for c in cases)
        # flat windows: every candidate ties there, and only d = 0 is right
        assert any(np.ptp(np.asarray(c.args[0], dtype=float)[:3]) == 0 for c in cases)


def test_quantize_is_not_tested_on_ambiguous_half_way_values():
    """Only values whose position between two levels is exact in any order of arithmetic may
    sit exactly half-way (1 bit, x = vmax/2)."""
    spec = check_of("formation.quantize")
    for seed in SEEDS:
        for case in spec.hidden_cases(np.random.default_rng(seed)):
            x = np.asarray(case.args[0], dtype=np.float64)
            bits = case.args[1]
            vmax = float(case.kwargs.get("vmax", 1.0))
            t = np.clip(x, 0, vmax) * (2 ** bits - 1) / vmax
            frac = np.abs(t - np.floor(t) - 0.5)
            if bits == 1:
                continue
            assert frac.min() > 1e-7, case.label


# --------------------------------------------------------------------------------------------
# the disparity comparator
# --------------------------------------------------------------------------------------------
def _bm_case():
    return check_of("stereo.block_matching").public_cases()[0]


def test_disparity_comparator_accepts_only_genuine_ties():
    compare = DisparityMaps()
    left = np.array([[1.0, 2.0, 1.0, 2.0, 1.0, 2.0]])
    right = left.copy()
    from cvkit.grading import Case

    case = Case((left, right, 3), {"block_size": 1, "cost": "sad"}, "period 2")
    expected = cvkit.stereo.block_matching(left, right, 3, block_size=1)
    np.testing.assert_array_equal(expected, [[0, 0, 0, 0, 0, 0]])
    # d = 2 costs exactly as much as d = 0 here (period 2), but ties are exact on integer
    # images: the smallest d is the only right answer
    got = expected.copy()
    got[0, 4] = 2
    assert compare(got, expected, case) is not None
    # on a float image the same costs tie up to round-off: accepted
    case_f = Case((left + 0.1, right + 0.1, 3), {"block_size": 1, "cost": "sad"}, "period 2, float")
    assert compare(got, expected, case_f) is None
    # a d > x is never accepted, a float dtype neither
    bad = expected.copy()
    bad[0, 1] = 3
    mismatch = compare(bad, expected, case_f)
    assert mismatch is not None and "outside the image" in mismatch.message
    assert "integer" in compare(expected.astype(float), expected, case).message


def test_disparity_comparator_full_ties_need_the_smallest_d():
    from cvkit.grading import Case

    flat = np.full((3, 6), 0.3)
    case = Case((flat, flat, 4), {"block_size": 3, "cost": "zncc"}, "flat")
    expected = np.zeros((3, 6), dtype=np.int64)
    got = expected.copy()
    got[1, 5] = 4
    mismatch = DisparityMaps()(got, expected, case)
    assert mismatch is not None and "smallest d" in mismatch.message


# --------------------------------------------------------------------------------------------
# the guard on Chapter 2 checks (as registered)
# --------------------------------------------------------------------------------------------
def test_calling_the_reference_is_forbidden_and_named():
    def block_matching(left, right, max_disparity, block_size=7, cost="sad"):
        return cvkit.stereo.block_matching(left, right, max_disparity, block_size, cost)

    harness.assert_scores_zero("stereo.block_matching", block_matching, "'stereo.block_matching'", hidden=True,
                               seed=SEEDS[0])


def test_opencv_is_forbidden_in_demosaicking():
    cv2 = pytest.importorskip("cv2")
    codes = {p: getattr(cv2, f"COLOR_Bayer{n}2RGB") for p, n in cvkit.formation.OPENCV_BAYER_NAMES.items()}

    def demosaic_bilinear(raw, pattern="RGGB"):
        scaled = np.round(np.asarray(raw, dtype=np.float64) * 256).astype(np.uint16)  # OpenCV: 8/16-bit only
        return cv2.cvtColor(scaled, codes[pattern]).astype(np.float64) / 256

    harness.assert_scores_zero("formation.demosaic_bilinear", demosaic_bilinear, "cv2")


def test_modifying_the_input_fails():
    def quantize_in_place(frames):
        frames = np.asarray(frames)
        result = alt.snr_db(frames)
        frames[0] = frames[0]  # harmless
        if frames.dtype.kind == "f":
            frames[0, 0, 0] += 1
        return result

    report = evaluate("formation.snr_db", quantize_in_place)
    assert report.score < 1.0
    assert any("modified its input" in c.message for c in report.cases)


def test_integer_disparities_are_required():
    def block_matching(left, right, max_disparity, block_size=7, cost="sad"):
        return alt.block_matching(left, right, max_disparity, block_size, cost).astype(np.float64)

    harness.assert_scores_zero("stereo.block_matching", block_matching, "integer")

# --------------------------------------------------------------------------------------------
# the measured exercise: stereo.dense_disparity, graded by its share of good pixels
# --------------------------------------------------------------------------------------------
from cvkit.stereo import _measured as stereo_task  # noqa: E402
from cvkit.stereo.checks import DISPARITY_SCALE, good_pixels  # noqa: E402

try:
    from . import measured_harness as measured
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    import measured_harness as measured

DENSE = "stereo.dense_disparity"
GOOD = "share of good pixels (error ≤ 1 px)"


def test_dense_disparity_notebook_publishes_the_scale_and_budget():
    assert DISPARITY_SCALE.corners == stereo_task.GOOD_PIXEL_SCALE and check_of(DENSE).credit is not None
    measured.assert_notebook_publishes("ch02_image_formation", DENSE, "dense_disparity(left, right, max_disparity)",
                                       DISPARITY_SCALE, "share of good pixels in your pairs", stereo_task.BUDGET_SECONDS)


def test_the_reference_stays_well_below_the_top_on_forty_scenes():
    """The claim of the reference's docstring: over 40 scenes its worst bad-pixel rate keeps a
    margin of 3 points to the top of the scale."""
    rates = []
    for seed in range(40):
        left, right, truth = stereo_task.synthetic_pair(seed)
        rates.append(stereo_task.bad_pixel_rate(stereo_task.dense_disparity(left, right, 16), truth))
    assert 1 - max(rates) >= DISPARITY_SCALE.top + 0.03, max(rates)
    assert np.median(rates) <= 0.07


def test_dense_disparity_measures_what_it_should():
    measured.assert_measures_what_it_should(DENSE, SEEDS, good_pixels, DISPARITY_SCALE, GOOD,
                                            alternatives=(alt.dense_disparity,))


def _spoiled(left, right, max_disparity):
    """The reference's map with every fifth pixel of every row set to 0: about 80 % good."""
    disparity = stereo_task.match_pair(left, right, max_disparity)
    disparity[:, ::5] = -10.0
    return disparity


def test_dense_disparity_partial_credit_follows_the_scale():
    measured.assert_partial_credit_follows_the_scale(DENSE, _spoiled, SEEDS[0], good_pixels, DISPARITY_SCALE)


def test_dense_disparity_pairs_differ_per_student_and_the_truth_stays_with_the_grader():
    measured.assert_hidden_data_differ_and_truth_stays_outside(
        DENSE, lambda a, b: np.array_equal(a.args[0], b.args[0]) and np.array_equal(a.truth, b.truth, equal_nan=True))
    for case in check_of(DENSE).hidden_cases(np.random.default_rng(SEEDS[0])):
        left, right, max_disparity = case.args
        assert left.shape == right.shape == case.truth.shape == stereo_task.PAIR_SHAPE and max_disparity == 16
        known = np.isfinite(case.truth)
        assert 0.7 < known.mean() < 0.98                      # occluded pixels are left out
        assert np.nanmax(case.truth) <= max_disparity and np.nanmin(case.truth) >= 0


def test_synthetic_pair_truth_is_what_the_views_show():
    """Where the truth is known, the left pixel's grey level is the right view's at x − d
    (up to the gain, offset and noise), so a perfect matcher exists."""
    left, right, truth = stereo_task.synthetic_pair(7, noise=0.0, photometric=False)
    rows, cols = np.nonzero(np.isfinite(truth))
    x = cols - truth[rows, cols]
    i = np.floor(x).astype(int)
    t = x - i
    j = np.minimum(i + 1, right.shape[1] - 1)
    seen = (1 - t) * right[rows, i] + t * right[rows, j]
    assert np.median(np.abs(seen - left[rows, cols])) < 1e-9
    assert np.mean(np.abs(seen - left[rows, cols]) < 0.02) > 0.97


def test_a_map_of_the_wrong_shape_fails_with_a_message():
    report = evaluate(DENSE, lambda left, right, d: np.zeros((3, 3)))
    assert not report.passed and report.score == 0.0
    assert "one disparity per left pixel" in report.cases[0].message
