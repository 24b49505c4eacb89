"""The Chapter 8 checks are worth their points (the tests every chapter owes:
``checks_harness.ChapterChecks``), the corner steps are graded by what they are for, the
comparators say what is wrong, and the guard catches what it should on the checks as
registered."""
from __future__ import annotations

import copy

import numpy as np
import pytest

import cvkit.calibration
import cvkit.warp
from cvkit import registry
from cvkit.grading.runtime.problems import Jacobian, Residuals, rebuild
from cvkit.calibration.checks import CalibrationClose, CornersClose, HomographyClose, MinimumClose, PointsClose
from cvkit.grading import Case, evaluate
from cvkit.warp.checks import WarpClose

import alternatives_ch08 as alt
import checks_harness as harness
from checks_harness import SEEDS, check_of, hidden_cases, reference_of

CH08 = [f"calibration.{name}" for name in cvkit.calibration.__all__] + [f"warp.{name}" for name in cvkit.warp.__all__]
BLOCKS = tuple(CH08) + tuple(f"camera.{n}" for n in ("distort", "undistort_points", "project_full", "rotation_matrix")) + (
    "filters.gaussian",)


def _reprs(case):
    """The values of a case's arguments as text (dicts sorted by key; arrays, lists and tuples
    through ``tolist``)."""
    out = []
    for value in list(case.args) + list(case.kwargs.values()):
        if isinstance(value, dict):
            out.append(repr(sorted((k, np.asarray(v).tolist()) for k, v in value.items())))
        elif isinstance(value, (np.ndarray, list, tuple)):
            out.append(repr(np.asarray(value, dtype=object).tolist()))
        else:
            out.append(repr(value))
    return tuple(out)


class TestChapter08(harness.ChapterChecks):
    IDS = CH08
    MISTAKES_MAY_CALL = BLOCKS
    ALTERNATIVES = alt.ALTERNATIVES

    def fingerprint(self, case):
        return _reprs(case)

    def reference_check(self, algorithm_id):
        # graded through a Check.call adapter, the reference counts as calling itself
        spec = check_of(algorithm_id)
        return harness.allowing_itself(spec, algorithm_id) if spec.call else None


# --------------------------------------------------------------------------------------------
# the shape of every check
# --------------------------------------------------------------------------------------------
def test_every_catalog_id_of_the_chapter_is_registered_with_its_section():
    sections = {
        "calibration.chessboard_points": "8.3", "calibration.find_chessboard_corners": "8.3",
        "calibration.chessboard_response": "8.3", "calibration.corner_candidates": "8.3",
        "calibration.grow_grid": "8.3", "calibration.order_grid_corners": "8.3",
        "calibration.refine_corners": "8.3",
        "calibration.homography_dlt": "8.3.2", "calibration.levenberg_marquardt": "8.3.4",
        "calibration.refine_homography": "8.3.4", "calibration.intrinsics_from_homographies": "8.3.5",
        "calibration.extrinsics_from_homography": "8.3.6", "calibration.estimate_radial_distortion": "8.3.7",
        "calibration.calibrate": "8.2–8.3.8", "warp.bilinear_sample": "8.4.2", "warp.warp_homography": "8.4.2",
        "warp.undistort_image": "8.4.1", "warp.rotation_homography": "8.4.3", "warp.birds_eye_homography": "8.4.3",
    }
    assert set(CH08) == set(sections)
    for algorithm_id, section in sections.items():
        record = registry.get(algorithm_id)
        module, name = algorithm_id.split(".")
        assert record.section == section
        assert record.reference is getattr(getattr(cvkit, module), name)


def test_hidden_cases_are_small():
    """A student's plain version must finish fast: few views and points, small images."""
    for seed in SEEDS:
        for case in hidden_cases("calibration.calibrate", seed):
            world, images = case.args
            assert len(images) <= 5 and len(world) <= 24
        for case in hidden_cases("calibration.find_chessboard_corners", seed):
            assert np.asarray(case.args[0]).shape[0] * np.asarray(case.args[0]).shape[1] <= 130 * 170
        for algorithm_id in ("warp.warp_homography", "warp.undistort_image", "warp.bilinear_sample"):
            for case in hidden_cases(algorithm_id, seed):
                assert np.asarray(case.args[0]).size <= 30 * 30 * 3


def test_hidden_cases_separate_the_dlt_mistakes():
    """Noisy, clustered pixel coordinates in the thousands; four points; normalize=False."""
    for seed in SEEDS:
        cases = hidden_cases("calibration.homography_dlt", seed)
        assert any(np.asarray(c.args[1], dtype=float).min() > 1000 for c in cases)
        assert any(len(c.args[0]) == 4 for c in cases)
        assert any(c.kwargs.get("normalize") is False for c in cases)
        assert any(np.asarray(c.args[0]).dtype.kind == "i" for c in cases)


def test_hidden_cases_cover_the_awkward_inputs():
    for seed in SEEDS:
        rng_cases = hidden_cases("calibration.intrinsics_from_homographies", seed)
        assert any(len(c.args[0]) == 3 for c in rng_cases)                       # the minimum
        assert any(abs(np.asarray(c.args[0][0], dtype=float)).max() < 1e-3 for c in rng_cases)  # tiny scales
        eh = hidden_cases("calibration.extrinsics_from_homography", seed)
        dets = [np.linalg.det(np.asarray(c.args[1], dtype=float)) for c in eh]
        assert any(d < 0 for d in dets) and any(d > 0 for d in dets)             # both signs of H
        corners = hidden_cases("calibration.find_chessboard_corners", seed)
        expected = [reference_of("calibration.find_chessboard_corners")(*c.args) for c in corners]
        assert sum(e is None for e in expected) >= 3 and sum(e is not None for e in expected) >= 8
        kinds = {np.asarray(c.args[0]).dtype.kind for c in corners}
        assert {"u", "f"} <= kinds and any(np.ndim(c.args[0]) == 3 for c in corners)
        samples = hidden_cases("warp.bilinear_sample", seed)
        assert any(np.asarray(c.args[0]).dtype == np.uint8 for c in samples)
        assert any(np.isnan(np.asarray(c.args[1], dtype=float)).any() for c in samples)
        warps = hidden_cases("warp.undistort_image", seed)
        assert {len(np.atleast_1d(c.args[2])) for c in warps} == {1, 2, 3}


# --------------------------------------------------------------------------------------------
# the harness itself, and alternatives over many draws
# --------------------------------------------------------------------------------------------
def test_the_harness_keeps_a_draw_as_the_same_cases():
    """The tests reuse slow draws of hidden cases (checks_harness._Draws): a kept draw is the
    same cases as a fresh one, and each use gets its own copy."""
    import pickle

    spec = registry.get("calibration.find_chessboard_corners").check
    fresh = spec.hidden_cases(np.random.default_rng(101))
    with harness.reusing_known_outputs():
        first = spec.hidden_cases(np.random.default_rng(101))
        again = spec.hidden_cases(np.random.default_rng(101))
        other = spec.hidden_cases(np.random.default_rng(102))
    assert pickle.dumps(fresh) == pickle.dumps(first) == pickle.dumps(again) != pickle.dumps(other)
    assert again is not first and again[0].args[0] is not first[0].args[0]


def test_alternative_detector_passes_many_seeds():
    """The detector's cases are images: a different correct detector must pass on many draws."""
    for seed in range(4):
        report = evaluate("calibration.find_chessboard_corners", alt.find_chessboard_corners, hidden=True,
                          seed=1000 + seed)
        assert report.passed, report.text()


# --------------------------------------------------------------------------------------------
# the corner steps are graded by what they are for (issue #38): a correct method other than
# the reference's passes although its output differs; a wrong one fails
# --------------------------------------------------------------------------------------------
def _cases(algorithm_id, seed):
    spec = check_of(algorithm_id)
    return spec.public_cases() if seed is None else spec.hidden_cases(np.random.default_rng(seed))


def test_a_harris_corner_detector_passes_corner_candidates():
    """Harris peaks moved to the most X-like pixel and refined by a saddle fit: sub-pixel points,
    other pixels and another order than the reference's, yet every inner corner is found."""
    harness.assert_passes_everywhere("calibration.corner_candidates", alt.corner_candidates_harris, SEEDS)
    reference = reference_of("calibration.corner_candidates")
    compare = check_of("calibration.corner_candidates").compare
    differ = 0
    for seed in (None,) + SEEDS:
        for case in _cases("calibration.corner_candidates", seed):
            mine = alt.corner_candidates_harris(*case.args, **case.kwargs)
            theirs = reference(*case.args, **case.kwargs)
            if len(theirs[0]) == 0:
                continue
            assert not np.array_equal(mine[0], np.round(mine[0]))                  # not whole pixels
            differ += compare._same(mine, theirs) is not None                       # the former verdict
    assert differ >= 10


def test_a_detector_that_keeps_every_harris_peak_fails_corner_candidates():
    for seed in SEEDS:
        report = evaluate("calibration.corner_candidates", alt.corner_candidates_harris_no_x_test, hidden=True,
                          seed=seed)
        assert not report.passed
        assert any("not inner corners" in case.message for case in report.cases), report.text()


def test_corner_candidates_are_judged_against_the_rendered_corners():
    compare = check_of("calibration.corner_candidates").compare
    case = _cases("calibration.corner_candidates", None)[0]
    corners, lines = case.truth
    count = case.args[1]
    rng = np.random.default_rng(0)
    exact = (corners + rng.uniform(-1, 1, corners.shape), lines[:, ::-1] * -1)          # any order, any sign
    assert compare.judge(exact, case.truth, count) is None
    far = (corners + 2.0, lines)
    assert "no candidate within" in compare.judge(far, case.truth, count).message
    strays = (np.vstack([corners, rng.uniform(0, 60, (max(3, count // 4) + 1, 2))]),
              np.vstack([lines, np.tile(lines[:1], (max(3, count // 4) + 1, 1, 1))]))
    assert "not inner corners" in compare.judge(strays, case.truth, count).message
    stray_first = (np.vstack([[[1.0, 1.0]], corners]), np.vstack([lines[:1], lines]))
    assert "put the most corner-like candidates first" in compare.judge(stray_first, case.truth, count).message
    turned = (corners, lines @ np.array([[np.cos(0.4), -np.sin(0.4)], [np.sin(0.4), np.cos(0.4)]]))
    assert "Edge directions off" in compare.judge(turned, case.truth, count).message


def test_a_grid_grown_another_way_passes_grow_grid():
    """Another queue, averaged predictions, another acceptance radius and a test on the edge
    directions: the same board, so it passes, though its answers differ from the reference's
    where the seed is a stray (not graded)."""
    harness.assert_passes_everywhere("calibration.grow_grid", alt.grow_grid_wide, SEEDS)
    reference = reference_of("calibration.grow_grid")
    compare = check_of("calibration.grow_grid").compare
    differ = sum(compare._same(alt.grow_grid_wide(*case.args), reference(*case.args)) is not None
                 for seed in (None,) + SEEDS for case in _cases("calibration.grow_grid", seed))
    assert differ >= 1


def test_an_affine_lattice_fails_grow_grid():
    """Labels from one affine lattice ignore perspective: the far corners are mislabelled."""
    for seed in SEEDS:
        report = evaluate("calibration.grow_grid", alt.grow_grid_affine, hidden=True, seed=seed)
        assert not report.passed


def test_a_gradient_orthogonality_refinement_passes_refine_corners():
    """Förstner's / cornerSubPix's least squares instead of Newton's method: its corners differ
    from the reference's by more than the former tolerance (0.01 px on average), yet they are
    as close to the corners the renderer drew."""
    harness.assert_passes_everywhere("calibration.refine_corners", alt.refine_corners_subpix, SEEDS)
    reference = reference_of("calibration.refine_corners")
    compare = check_of("calibration.refine_corners").compare
    former = PointsClose(mean=0.01, maximum=0.05)
    differ = sum(former(alt.refine_corners_subpix(*case.args), reference(*case.args), case) is not None
                 for seed in (None,) + SEEDS for case in _cases("calibration.refine_corners", seed))
    assert differ >= 10
    case = _cases("calibration.refine_corners", None)[0]
    targets, moved = case.truth
    start = np.asarray(case.args[1], dtype=np.float64)
    exact = np.where(moved[:, None], targets, start)
    assert compare.judge(exact, case) is None
    assert "Corners differ" in compare.judge(np.where(moved[:, None], targets + 0.3, start), case).message
    assert "must come back unchanged" in compare.judge(np.where(moved[:, None], targets, start + 1.0), case).message


def test_find_chessboard_corners_is_judged_against_the_rendered_corners():
    compare = check_of("calibration.find_chessboard_corners").compare
    case = _cases("calibration.find_chessboard_corners", None)[0]
    truth = case.truth
    rng = np.random.default_rng(1)
    reference_like = truth - 0.1 + rng.normal(0, 0.02, truth.shape)     # a right answer, not the truth
    assert compare(truth.copy(), reference_like, case) is None
    assert compare(truth[::-1].copy(), reference_like, case) is None     # the 180° turn is accepted
    other_side = truth + 0.1                                             # 0.14 px from the truth, 0.28 from it
    assert compare(other_side, reference_like, case) is None
    assert CornersClose()(other_side, reference_like) is not None        # (judged against the reference: fails)
    assert compare(truth + 0.5, reference_like, case) is not None
    rounded = np.round(truth)                                            # a mistake's output is matched as it is
    assert compare(rounded, rounded, case) is None


def test_grow_grid_is_judged_by_the_board_not_the_reference():
    compare = check_of("calibration.grow_grid").compare
    case = next(c for c in _cases("calibration.grow_grid", None) if not isinstance(c.truth, str))
    labels, positions, step = case.truth
    points = np.asarray(case.args[0], dtype=np.float64)
    index = [int(np.argmin(np.hypot(*(points - p).T))) for p in positions]
    right = np.column_stack([labels, index])
    assert compare(right[::-1], right, case) is None                                   # any row order
    assert "not corners of the board" in compare(np.column_stack([labels + [5, 0], index]), right, case).message
    assert "missing" in compare(right[1:], right, case).message
    swapped = np.column_stack([labels[:, ::-1], index])
    assert compare(swapped, right, case) is not None
    assert compare(None, right, case).message.startswith("you returned None")
    stray = next(c for c in _cases("calibration.grow_grid", 303) if isinstance(c.truth, str) and c.truth == "any")
    assert compare(None, reference_grid(stray), stray) is None                         # a stray seed: not graded


def reference_grid(case):
    return reference_of("calibration.grow_grid")(*case.args)


# --------------------------------------------------------------------------------------------
# the comparators
# --------------------------------------------------------------------------------------------
def test_homography_close_judges_the_mapping_and_the_scale():
    H = np.array([[2.0, 0.1, 10.0], [0.2, 1.5, -4.0], [1e-3, 2e-3, 1.0]])
    case = Case((np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 100.0], [100.0, 100.0]]),), {}, "")
    compare = HomographyClose(atol=1e-4, rtol=1e-8)
    assert compare(H.copy(), H, case) is None
    message = compare(3 * H, H, case).message
    assert "H[2, 2] = 3" in message and "dividing it by H[2, 2]" in message
    assert compare(3 * H, 3 * H, case) is None                      # a mistake's unscaled H can be matched
    shifted = H.copy()
    shifted[0, 2] += 0.01
    mismatch = compare(shifted, H, case)
    assert mismatch is not None and "maps points elsewhere" in mismatch.message and mismatch.max_abs > 0.005
    assert "shape mismatch" in compare(np.eye(2), H, case).message
    assert "None" in compare(None, H, case).message


def test_corners_close_accepts_the_180_degree_rotation_and_none():
    expected = np.array([[10.0, 10.0], [20.0, 10.0], [30.0, 10.0], [10.0, 20.0], [20.0, 20.0], [30.0, 20.0]])
    compare = CornersClose(mean=0.2, maximum=0.6)
    assert compare(expected + 0.1, expected) is None
    assert compare(expected[::-1] + 0.05, expected) is None
    assert "Corners differ" in compare(expected[:, ::-1], expected).message
    assert "mean distance" in compare(expected + 0.45, expected).message
    assert "expected None" in compare(expected, None).message
    assert compare(None, None) is None
    assert "returned None" in compare(None, expected).message
    assert "shape mismatch" in compare(expected[:4], expected).message


def test_minimum_close_checks_x_cost_and_flags():
    problem = Residuals("linear", M=np.eye(2), b=np.array([1.0, 2.0]))
    case = Case((problem, np.zeros(2)), {}, "")
    expected = (np.array([1.0, 2.0]), {"iterations": 3, "cost": 0.0, "converged": True})
    compare = MinimumClose()
    assert compare((np.array([1.0, 2.0]), {"iterations": 7, "cost": 0.0, "converged": True}), expected, case) is None
    assert "tuple (x, info)" in compare(np.array([1.0, 2.0]), expected, case).message
    assert "lacks" in compare((np.array([1.0, 2.0]), {"cost": 0.0}), expected, case).message
    assert "converged" in compare((np.array([1.0, 2.0]), {"iterations": 3, "cost": 0.0, "converged": False}),
                                  expected, case).message
    assert "same minimum" in compare((np.array([1.0, 2.1]), {"iterations": 3, "cost": 0.0, "converged": True}),
                                     expected, case).message
    assert "diverged" in compare((np.array([np.nan, 2.0]), {"iterations": 3, "cost": 0.0, "converged": True}),
                                 expected, case).message
    assert "max_iter" in compare((np.array([1.0, 2.0]), {"iterations": 101, "cost": 0.0, "converged": True}),
                                 expected, case).message


def test_calibration_close_accepts_dicts_and_objects():
    expected = {"A": np.array([[800.0, 0, 320], [0, 820, 240], [0, 0, 1]]), "k": np.array([-0.2, 0.05]),
                "rotations": np.stack([np.eye(3)] * 3), "translations": np.ones((3, 3)) * 100, "rms": 0.3}
    compare = CalibrationClose()
    assert compare(copy.deepcopy(expected), expected) is None
    result = cvkit.calibration.CalibrationResult(copy.deepcopy(expected))
    assert compare(result, expected) is None and result.rms == 0.3
    wrong = dict(copy.deepcopy(expected), rms=0.3 / np.sqrt(2))
    assert compare(wrong, expected).message.startswith("rms")
    missing = {k: v for k, v in expected.items() if k != "k"}
    assert "no 'k'" in compare(missing, expected).message
    bent = copy.deepcopy(expected)
    bent["A"][0, 0] += 1.0
    assert compare(bent, expected).message.startswith("A: ")


def test_warp_close_ignores_only_sources_on_the_border():
    image = np.arange(12.0).reshape(3, 4)
    shift = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])     # sources of column 0: x = −1
    case = Case((image, shift, (3, 4)), {}, "")
    expected = cvkit.warp.warp_homography(image, shift, (3, 4))
    from cvkit.warp.checks import _warp_sources
    compare = WarpClose(sources=_warp_sources)
    assert compare(expected.copy(), expected, case) is None
    off_border = expected.copy()
    off_border[1, 2] += 1.0
    assert compare(off_border, expected, case) is not None
    nudged = np.array([[1.0, 0.0, 1.0 + 1e-9], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])   # column 3 source at 2 − 1e-9
    border_case = Case((image, nudged, (3, 5)), {}, "")
    exact = cvkit.warp.warp_homography(image, shift, (3, 5))
    assert compare(cvkit.warp.warp_homography(image, nudged, (3, 5)), exact, border_case) is None


# --------------------------------------------------------------------------------------------
# the data-only test problems of the optimiser
# --------------------------------------------------------------------------------------------
def test_optimiser_cases_cross_the_wire_as_plain_data():
    """The trusted grader sends cases to its worker as JSON: the residual functions go as plain
    dicts and the check's adapter rebuilds them there."""
    from cvkit.grading.runtime.problems import least_squares_call
    from cvkit.grading import wire

    spec = check_of("calibration.levenberg_marquardt")
    assert spec.call is least_squares_call
    for case in spec.public_cases() + hidden_cases("calibration.levenberg_marquardt", 11):
        args, kwargs = wire.loads(wire.dumps(case.args)), wire.loads(wire.dumps(case.kwargs))
        assert type(args[0]) is dict
        x, info = least_squares_call(cvkit.calibration.levenberg_marquardt, *args, **kwargs)
        want, want_info = least_squares_call(cvkit.calibration.levenberg_marquardt, *case.args, **case.kwargs)
        np.testing.assert_array_equal(x, want)
        assert info == want_info


def test_problems_are_data_copies_and_rebuild_from_plain_dicts():
    for case in hidden_cases("calibration.levenberg_marquardt", 5):
        problem = case.args[0]
        assert isinstance(problem, Residuals) and isinstance(problem, dict)
        x = np.asarray(case.args[1], dtype=float)
        clone = copy.deepcopy(problem)
        assert clone == problem and clone is not problem
        plain = {k: (np.asarray(v).tolist() if k != "kind" else v) for k, v in problem.items()}
        np.testing.assert_allclose(rebuild(plain)(x), problem(x))
        jac = case.kwargs.get("jacobian")
        if jac is not None:
            assert isinstance(jac, Jacobian)
            numeric = np.column_stack([(problem(x + h) - problem(x - h)) / 2e-6 for h in np.eye(x.size) * 1e-6])
            np.testing.assert_allclose(jac(x), numeric, rtol=1e-5, atol=1e-6)
            np.testing.assert_allclose(rebuild(dict(jac), jacobian=True)(x), jac(x))
    assert "Rosenbrock" in repr(Residuals("rosenbrock", a=10.0))
    with pytest.raises(ValueError, match="kind"):
        Residuals("quartic")


# --------------------------------------------------------------------------------------------
# the guard on Chapter 8 checks (as registered)
# --------------------------------------------------------------------------------------------
def test_opencv_is_forbidden_and_named():
    cv2 = pytest.importorskip("cv2")

    def homography_dlt(src, dst, normalize=True):
        H, _ = cv2.findHomography(np.asarray(src, dtype=float), np.asarray(dst, dtype=float), 0)
        return H / H[2, 2]

    harness.assert_scores_zero("calibration.homography_dlt", homography_dlt, "cv2", every_case=True)


def test_scipy_optimize_is_forbidden():
    import scipy.optimize

    def levenberg_marquardt(residuals, x0, jacobian=None, max_iter=100, tol=1e-10):
        result = scipy.optimize.least_squares(residuals, np.asarray(x0, dtype=float), method="lm")
        return result.x, {"iterations": int(result.nfev), "cost": float(result.cost), "converged": True}

    report = evaluate("calibration.levenberg_marquardt", levenberg_marquardt)
    assert report.score == 0.0 and all("scipy.optimize" in c.message for c in report.cases), report.text()


def test_calling_the_reference_is_forbidden_but_building_blocks_are_allowed():
    def refine_homography(H, src, dst):
        return cvkit.calibration.refine_homography(H, src, dst)

    report = evaluate("calibration.refine_homography", refine_homography)
    assert report.score == 0.0 and "'calibration.refine_homography'" in report.cases[0].message

    def warp_homography(image, H, output_shape, fill=0.0):                # bilinear_sample is allowed
        inv = np.linalg.inv(np.asarray(H, dtype=float))
        rows, cols = output_shape
        x, y = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
        w = inv[2, 0] * x + inv[2, 1] * y + inv[2, 2]
        return cvkit.warp.bilinear_sample(image, (inv[0, 0] * x + inv[0, 1] * y + inv[0, 2]) / w,
                                          (inv[1, 0] * x + inv[1, 1] * y + inv[1, 2]) / w, fill)

    harness.assert_passes_everywhere("warp.warp_homography", warp_homography, SEEDS)


def test_modifying_the_input_fails():
    def bilinear_sample(image, x, y, fill=0.0):
        x = np.asarray(x)
        if x.dtype.kind == "f":
            np.clip(x, 0, np.asarray(image).shape[1] - 1, out=x)           # in place: the caller's array
        return alt.bilinear_sample(image, x, y, fill)

    report = evaluate("warp.bilinear_sample", bilinear_sample)
    assert not report.passed
    assert any("modified its input" in c.message for c in report.cases if not c.passed)


def test_a_failing_report_names_the_mistake_and_hint():
    def homography_dlt(src, dst, normalize=True):   # forgets the normalisation
        src, dst = np.asarray(src, float), np.asarray(dst, float)
        rows = []
        for (x, y), (u, v) in zip(src, dst):
            rows += [[x, y, 1, 0, 0, 0, -u * x, -u * y, -u], [0, 0, 0, x, y, 1, -v * x, -v * y, -v]]
        L = np.array(rows, dtype=float)
        L = np.vstack([L, np.zeros((max(0, 9 - len(L)), 9))])
        H = np.linalg.svd(L)[2][-1].reshape(3, 3)
        return H / H[2, 2]

    report = evaluate("calibration.homography_dlt", homography_dlt)
    assert not report.passed and report.mistake == "no Hartley normalisation"
    assert "√2" in report.text()
