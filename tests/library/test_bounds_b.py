"""Bounded work and type hints of ``cvkit.features``, ``cvkit.detection``, ``cvkit.camera``,
``cvkit.calibration`` and ``cvkit.warp`` (issue #21).

- Every size-like or cost-driving parameter given an extreme value is refused up front with a
  ``ValueError``/``TypeError`` naming the caller's argument, before anything large is allocated
  (``bounds_harness.assert_refused``); errors of building blocks name the caller's argument.
- Where a bound is handled exactly instead (``peaks``' radius, the windows of ``orientations``
  and ``sift_descriptor`` cut to the image), the result is the one of the smaller value.
- ``camera.undistort_points`` converges where its fixed-point iteration does not, keeps the
  fixed-point result where that one already converged, and reports the points without an
  inverse (``ConvergenceWarning``, or ``ValueError`` with ``strict=True``).
- Every public function and method of the five topics is fully annotated, and importing them
  does not import SciPy.
"""
from __future__ import annotations

import importlib
import inspect
import pkgutil
import subprocess
import sys
import typing
import warnings

import numpy as np
import pytest

from cvkit import calibration, camera, data, detection, features, warp
from cvkit.camera import ConvergenceWarning

try:
    from .bounds_harness import assert_refused
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    from bounds_harness import assert_refused

TOPICS = ("features", "detection", "camera", "calibration", "warp")

RNG = np.random.default_rng(21)
IMG = RNG.random((32, 40))
SQUARE = np.zeros((21, 21))
SQUARE[5:16, 6:14] = 1.0
RTABLE = detection.ght_build(SQUARE > 0.5, SQUARE, bins=8)
VIEWS = data.chessboard_views(n_views=4, render=False)
XD = np.array([[0.1, -0.2], [0.3, 0.25]])


def _dense_model(side: int) -> dict:
    """A shape model with a control point at every pixel of a side × side template."""
    y, x = np.mgrid[0:side, 0:side]
    points = np.column_stack([x.ravel(), y.ravel()]).astype(float)
    return {"points": points, "directions": np.tile([1.0, 0.0], (side * side, 1)), "shape": (side, side)}


def _tree_of_duplicates() -> features.KDTree:
    """Half the points equal: one leaf holds them all, and every other leaf is padded to it."""
    points = np.vstack([np.zeros((2_500, 64)), RNG.random((2_500, 64))])
    return features.KDTree(points, leaf_size=1)


def _query_a_long_line(queries, k):
    """KDTree.query on a tree of 70,000 points on a line (built at the call, not at collection)."""
    return features.KDTree(np.arange(70_000.0)[:, None]).query(queries, k=k)


# (id, function, positional arguments, keyword arguments, names the error may give)
EXTREMES = [
    # ------------------------------------------------------------------------ features
    ("moravec window", features.moravec, (IMG,), {"window": 10**6 + 1}, "window"),
    ("moravec window work", features.moravec, (RNG.random((400, 400)),), {"window": 4001}, "window"),
    ("structure_tensor sigma", features.structure_tensor, (IMG,), {"sigma": 1e9}, "sigma"),
    ("harris sigma", features.harris, (IMG,), {"sigma": 1e9}, "sigma"),
    ("peaks radius work", features.peaks, (np.zeros((3000, 3000)), 0.5), {"radius": 10**9}, "radius"),
    ("gaussian_pyramid octaves", features.gaussian_pyramid, (IMG,), {"octaves": 200}, "octaves"),
    ("gaussian_pyramid scales", features.gaussian_pyramid, (IMG,), {"scales": 10**6}, "scales"),
    ("gaussian_pyramid sigma0", features.gaussian_pyramid, (IMG,), {"sigma0": 1e6}, "sigma0"),
    ("gaussian_pyramid sigma0 overflow", features.gaussian_pyramid, (IMG,), {"sigma0": 1e300}, "sigma0"),
    ("gaussian_pyramid sigma0 work", features.gaussian_pyramid, (np.zeros((512, 512)),), {"sigma0": 200.0, "scales": 100},
     "sigma0"),
    ("log_blobs sigma", features.log_blobs, (IMG, [1.0, 1e6], 0.1), {}, "sigmas"),
    ("log_blobs count", features.log_blobs, (IMG, np.linspace(1.0, 3.0, 1000), 0.1), {}, "sigmas"),
    ("orientations bins", features.orientations, (IMG, 10.0, 10.0, 2.0), {"bins": 10**9}, "bins"),
    ("orientations x", features.orientations, (IMG, 1e300, 10.0, 2.0), {}, "x"),
    ("orientations window", features.orientations, (IMG, -1e8, -1e8, 1e8), {}, "sigma"),
    ("sift_descriptor sigma", features.sift_descriptor, (IMG, 10.0, 10.0, 1e300, 0.0), {}, "sigma"),
    ("sift_descriptor y", features.sift_descriptor, (IMG, 10.0, -1e12, 2.0, 0.0), {}, "y"),
    ("sift octaves", features.sift, (IMG,), {"octaves": 200}, "octaves"),
    ("sift scales", features.sift, (IMG,), {"scales": 10**4}, "scales"),
    ("sift sigma0", features.sift, (IMG,), {"sigma0": 1e6}, "sigma0"),
    ("sift max_steps", features.sift, (IMG,), {"max_steps": 10**9}, "max_steps"),
    ("KDTree padded leaves", _tree_of_duplicates, (), {}, "points"),
    ("KDTree.query k", _query_a_long_line, (np.zeros((4_000, 1)),), {"k": 70_000}, "k"),
    # ------------------------------------------------------------------------ detection
    ("match_template sad", detection.match_template, (np.zeros((1000, 1000)), np.zeros((500, 500)), "sad"), {},
     "template"),
    ("shape_match model", detection.shape_match, (np.zeros((800, 800)), _dense_model(300)), {}, "model"),
    ("hough_lines theta_step", detection.hough_lines, (IMG > 0.5,), {"theta_step": 1e-9}, "theta_step"),
    ("hough_lines rho_step", detection.hough_lines, (IMG > 0.5,), {"rho_step": 1e-9}, "rho_step"),
    ("hough_lines votes", detection.hough_lines, (np.ones((1000, 1000)),), {"theta_step": 1e-4}, "theta_step"),
    ("ght_build bins", detection.ght_build, (SQUARE > 0.5, SQUARE), {"bins": 10**9}, "bins"),
    ("ght_detect accumulator", detection.ght_detect, (IMG, RTABLE),
     {"scales": np.linspace(0.5, 2.0, 3000), "angles": np.linspace(0.0, 6.0, 3000)}, ("scales", "angles")),
    ("ght_detect voting", detection.ght_detect, (RNG.random((100, 100)), {"bins": 1, "table": [RNG.random((5000, 2))]}),
     {"scales": np.linspace(0.5, 2.0, 100), "angles": np.linspace(0.0, 6.0, 100)}, ("scales", "angles")),
    ("ght_detect edge_params", detection.ght_detect, (IMG, RTABLE), {"edge_params": {"sigma": -1.0}}, "edge_params"),
    # ------------------------------------------------------------------------ camera
    ("undistort_points iterations", camera.undistort_points, (XD, (-0.2,), (0.0, 0.0)), {"iterations": 10**9},
     "iterations"),
    ("undistort_points strict", camera.undistort_points, ([[0.6, 0.0]], (-0.5,), (0.0, 0.0)), {"strict": True},
     "xy_distorted"),
    # ------------------------------------------------------------------------ calibration
    ("chessboard_points cols", calibration.chessboard_points, (10**6, 10**6, 1.0), {}, "cols"),
    ("chessboard_response sigma", calibration.chessboard_response, (IMG,), {"sigma": 1e9}, "sigma"),
    ("corner_candidates sigma", calibration.corner_candidates, (IMG, 4), {"sigma": 1e9}, "sigma"),
    ("refine_corners sigma", calibration.refine_corners, (IMG, [[10.0, 10.0]], 1e9), {}, "sigma"),
    ("grow_grid points", calibration.grow_grid, (RNG.random((100_000, 2)), np.zeros((100_000, 2, 2))), {}, "points"),
    ("levenberg_marquardt max_iter", calibration.levenberg_marquardt, (lambda x: x - 1.0, [0.0]),
     {"max_iter": 10**9}, "max_iter"),
    ("levenberg_marquardt jacobian", calibration.levenberg_marquardt, (lambda x: x - 1.0, np.zeros(20_000)), {}, "x0"),
    ("calibrate coinciding world_points", calibration.calibrate, (np.zeros((len(VIEWS.world_points), 3)),
                                                                  VIEWS.image_points), {}, "world_points"),
    ("calibrate collinear view", calibration.calibrate,
     (VIEWS.world_points, [VIEWS.image_points[0], np.tile(VIEWS.image_points[1][:, :1], (1, 2)),
                           VIEWS.image_points[2]]), {}, "image_points_list[1]"),
    # ------------------------------------------------------------------------ warp
    ("warp_homography output_shape", warp.warp_homography, (IMG, np.eye(3), (10**9, 12)), {}, "output_shape"),
    ("bilinear_sample x and y", warp.bilinear_sample, (IMG, np.zeros((100_000, 1)), np.zeros((1, 100_000))), {},
     ("x", "y")),
]


@pytest.mark.parametrize(("fn", "args", "kwargs", "names"), [pytest.param(*case[1:], id=case[0]) for case in EXTREMES])
def test_extreme_values_are_refused_naming_the_argument(fn, args, kwargs, names):
    assert_refused(fn, *args, names=names, **kwargs)


def test_gaussian_pyramid_says_how_many_octaves_the_image_allows():
    error = assert_refused(features.gaussian_pyramid, np.zeros((8, 8)), octaves=200, names="octaves")
    assert "octaves must be <= 5" in str(error) and "16×16 (upsampled)" in str(error)
    assert len(features.gaussian_pyramid(np.zeros((8, 8)), octaves=5)) == 5          # down to 1×1: allowed
    assert features.gaussian_pyramid(np.zeros((8, 8)), octaves=5)[-1].shape[1:] == (1, 1)
    assert len(features.gaussian_pyramid(np.zeros((8, 8)), sigma0=0.9, upsample=False, octaves=4)) == 4
    with pytest.raises(ValueError, match="octaves must be <= 4"):
        features.gaussian_pyramid(np.zeros((8, 8)), sigma0=0.9, upsample=False, octaves=5)


def test_calibrate_names_world_points_not_the_homography_helper():
    error = assert_refused(calibration.calibrate, np.zeros((12, 3)), VIEWS.image_points[:, :12], names="world_points")
    assert "src" not in str(error)
    same_view = [VIEWS.image_points[0]] * 3                        # three equal views: no camera
    error = assert_refused(calibration.calibrate, VIEWS.world_points, same_view, names="image_points_list")
    assert "do not determine the camera" in str(error)


def test_calibrate_bounds_the_jacobian_of_its_refinement():
    views = [RNG.random((15_000, 2)) * 600] * 100                   # 100 views of 15 000 points
    error = assert_refused(calibration.calibrate, calibration.chessboard_points(150, 100, 1.0), views,
                           names="image_points_list")
    assert "Jacobian of the refinement" in str(error)


def test_birds_eye_homography_names_its_arguments_when_the_origin_pixel_is_on_the_horizon():
    truth = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.001, 0.0, 0.0]])     # H[2, 2] = 0
    pixels = np.array([[100.0, 50.0], [200.0, 60.0], [180.0, 160.0], [110.0, 150.0]])
    mapped = np.c_[pixels, np.ones(4)] @ truth.T
    error = assert_refused(warp.birds_eye_homography, pixels, mapped[:, :2] / mapped[:, 2:], 1.0,
                           names="image_points")
    assert "ground_points" in str(error)


# ------------------------------------------------------------------ bounds handled exactly
def test_peaks_radius_beyond_the_map_is_the_whole_map():
    response = RNG.random((9, 13))
    whole = features.peaks(response, 0.1, radius=12)
    np.testing.assert_array_equal(whole, [[*np.unravel_index(response.argmax(), response.shape)][::-1]])
    np.testing.assert_array_equal(features.peaks(response, 0.1, radius=10**15), whole)


def test_keypoint_windows_cut_to_the_image_give_the_same_votes(monkeypatch):
    """Windows far larger than the image are cut to its pixels: the same samples in the same
    order, so the same histograms and descriptors as the whole square window, bit for bit."""
    import cvkit.features._sift as sift_module

    image = RNG.random((24, 30))
    cases = [(12.0, 11.0, 40.0, 0.4), (-20.0, 5.0, 9.0, 1.0), (28.5, 22.5, 6.0, 2.0), (60.0, 11.0, 3.0, 0.0)]
    cut = [(features.orientations(image, x, y, s), features.sift_descriptor(image, x, y, s, a)) for x, y, s, a in cases]
    monkeypatch.setattr(sift_module, "_window_radii", lambda cx, cy, radii, shape: radii)      # the whole square
    for (x, y, s, a), (angles, vector) in zip(cases, cut):
        np.testing.assert_array_equal(angles, features.orientations(image, x, y, s))
        np.testing.assert_array_equal(vector, features.sift_descriptor(image, x, y, s, a))
    monkeypatch.undo()
    for sigma in (1e6, 1e9):                            # any σ: the work is bounded by the image
        assert features.orientations(image, 12.0, 11.0, sigma).size >= 1
        assert np.isclose(np.linalg.norm(features.sift_descriptor(image, 12.0, 11.0, sigma, 0.4)), 1.0)
    assert features.orientations(image, 1e8, 1e8, 2.0).size == 0          # a window that misses the image
    assert not features.sift_descriptor(image, -1e8, 5.0, 3.0, 0.0).any()


def test_kd_tree_search_in_small_blocks_equals_one_block(monkeypatch):
    points, queries = RNG.random((500, 6)), RNG.random((100, 6))
    tree = features.KDTree(points, leaf_size=3)
    exact, approximate = tree.query(queries, k=4), tree.query_bbf(queries, k=2, max_checks=30)
    import cvkit.features._matching as matching

    monkeypatch.setattr(matching, "_ROWS_BUDGET", tree.leaves)          # one query per block
    for got, want in ((tree.query(queries, k=4), exact), (tree.query_bbf(queries, k=2, max_checks=30), approximate)):
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
    distances = np.sqrt(((queries[:, None] - points[None]) ** 2).sum(-1))
    np.testing.assert_allclose(exact[0], np.sort(distances, axis=1)[:, :4], rtol=1e-12)


def test_ght_votes_added_in_batches_equal_one_batch(monkeypatch):
    image = np.zeros((40, 50))
    image[12:23, 20:28] = 1.0
    kwargs = {"scales": (0.9, 1.0, 1.1), "angles": (0.0, 0.2), "edge_params": {"sigma": 1.0}}
    accumulator, best = detection.ght_detect(image, RTABLE, **kwargs)
    import cvkit.detection._ght as ght

    monkeypatch.setattr(ght, "_FLUSH", 1)                              # add the votes after every bin
    batched, best_batched = detection.ght_detect(image, RTABLE, **kwargs)
    np.testing.assert_array_equal(batched, accumulator)
    assert best_batched == best and accumulator.max() > 0


# ------------------------------------------------------------------ undistort_points
STRONG_K, STRONG_P = (-0.3, -0.1, -0.02), (-0.002, -0.002)


def _grid(half: float, n: int = 17) -> np.ndarray:
    g = np.linspace(-half, half, n)
    return np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)


def _residual(xy: np.ndarray, xd: np.ndarray, k, p) -> np.ndarray:
    return np.abs(camera.distort(xy, k, p) - xd).max(axis=1)


def test_undistort_points_converges_where_the_fixed_point_iteration_does_not():
    xd = _grid(0.4)                              # distorted points filling the square: strong barrel
    fixed = camera.undistort_points(xd, STRONG_K, STRONG_P, 20)
    assert _residual(fixed, xd, STRONG_K, STRONG_P).max() > 1e-12         # 20 steps are not enough here
    with warnings.catch_warnings():
        warnings.simplefilter("error")                                     # and no warning: all converge
        solved = camera.undistort_points(xd, STRONG_K, STRONG_P, iterations=None)
    assert _residual(solved, xd, STRONG_K, STRONG_P).max() <= 1e-12
    slow = _residual(fixed, xd, STRONG_K, STRONG_P) > 1e-12
    np.testing.assert_array_equal(solved[~slow], fixed[~slow])           # converged points: unchanged


def test_undistort_points_keeps_the_fixed_point_result_where_it_converged():
    ideal = RNG.uniform(-0.4, 0.4, (300, 2))
    for k, p in (((-0.3, 0.1, -0.02), (0.002, -0.001)), ((0.25,), (-0.001, 0.002)), ((0.0,), (0.0, 0.0))):
        xd = camera.distort(ideal, k, p)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            np.testing.assert_array_equal(camera.undistort_points(xd, k, p, iterations=None),
                                          camera.undistort_points(xd, k, p, 20))


def test_undistort_points_reports_points_without_an_inverse():
    """k1 = −0.5: r(1 − r²/2) is largest, 0.544, at r = 0.816; no ideal point distorts farther."""
    xd = np.array([[0.3, 0.1], [0.6, 0.0], [0.0, -0.7], [-0.2, 0.2]])
    with pytest.warns(ConvergenceWarning, match=r"xy_distorted: 2 of 4 points .* row 2"):
        got = camera.undistort_points(xd, (-0.5,), (0.0, 0.0), iterations=None)
    assert issubclass(ConvergenceWarning, RuntimeWarning)
    residual = _residual(got, xd, (-0.5,), (0.0, 0.0))
    assert residual[[0, 3]].max() <= 1e-12                               # the others are undistorted
    top = np.sqrt(2 / 3) * (1 - 1 / 3)                                   # the fold: the best there is
    np.testing.assert_allclose(residual[[1, 2]], [0.6 - top, 0.7 - top], atol=1e-9)
    with pytest.raises(ValueError, match="xy_distorted: 2 of 4"):
        camera.undistort_points(xd, (-0.5,), (0.0, 0.0), strict=True)


def test_undistort_points_by_default_reports_an_iterate_far_from_the_inverse():
    """The catalog's default, 20 fixed-point steps, is kept; a result that distort maps far
    from the input (here 0.108: beyond the fold of k1 = -0.5) is never returned without a word."""
    with pytest.warns(ConvergenceWarning, match=r"1 of 1 points .* 0\.108 away after 20 fixed-point steps"):
        camera.undistort_points([[0.6, 0.0]], (-0.5,), (0.0, 0.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")                       # converged to 1e-8: within the report tolerance
        camera.undistort_points(_grid(0.4), STRONG_K, STRONG_P)


def test_undistort_points_with_a_number_of_iterations_is_that_iterate():
    xd = _grid(0.4, 5)
    with pytest.warns(ConvergenceWarning, match="after 1 fixed-point steps"):  # far from the inverse: said
        one = camera.undistort_points(xd, STRONG_K, STRONG_P, 1)
    radial = 1 + (xd ** 2).sum(1) * (-0.3 + (xd ** 2).sum(1) * (-0.1 - 0.02 * (xd ** 2).sum(1)))
    x, y = xd.T
    shift = np.column_stack([-0.004 * x * y - 0.002 * (3 * x * x + y * y), -0.002 * (x * x + 3 * y * y) - 0.004 * x * y])
    np.testing.assert_allclose(one, (xd - shift) / radial[:, None], rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="after 1 fixed-point steps"):
        camera.undistort_points(xd, STRONG_K, STRONG_P, 1, strict=True)
    with pytest.raises(TypeError, match="strict"):
        camera.undistort_points(xd, STRONG_K, STRONG_P, strict="yes")
    assert camera.undistort_points(np.zeros((0, 2)), STRONG_K, STRONG_P, strict=True).shape == (0, 2)


# ------------------------------------------------------------------ lazy imports
def test_importing_the_topics_does_not_import_scipy():
    code = ("import sys\nimport cvkit." + ", cvkit.".join(TOPICS) +
            "\nprint(sorted(m for m in sys.modules if m == 'scipy' or m.startswith('scipy.')))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]", done.stdout


def test_match_template_still_takes_the_fft_route(monkeypatch):
    from cvkit.detection import _template

    routed = []
    monkeypatch.setattr(_template, "correlate_valid_fft",
                        lambda *a, fft=_template.correlate_valid_fft: routed.append(1) or fft(*a))
    image, template = RNG.random((60, 70)), RNG.random((19, 24))                   # many taps: FFT
    scores = detection.match_template(image, template, "ssd")
    windows = np.lib.stride_tricks.sliding_window_view(image, template.shape)
    np.testing.assert_allclose(scores, ((windows - template) ** 2).sum((-2, -1)), rtol=1e-9, atol=1e-9)
    assert routed and scores.shape == (42, 47)


# ------------------------------------------------------------------ type hints
def _public(topic: str) -> dict[str, typing.Callable]:
    """The public functions and methods of a topic: its ``__all__``, and what its modules
    (not ``checks``) define under public names, with the public methods of their classes."""
    package = importlib.import_module(f"cvkit.{topic}")
    modules = [importlib.import_module(f"{package.__name__}.{m.name}")
               for m in pkgutil.iter_modules(package.__path__) if m.name != "checks"]
    candidates = [getattr(package, name) for name in package.__all__]
    candidates += [obj for module in modules for name, obj in vars(module).items()
                   if not name.startswith("_") and getattr(obj, "__module__", None) == module.__name__]
    found: dict[str, typing.Callable] = {}
    for obj in candidates:
        if inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if inspect.isfunction(member) and (attr == "__init__" or not attr.startswith("_")):
                    found[f"{obj.__module__}.{member.__qualname__}"] = member
        elif inspect.isfunction(obj):
            found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return found


PUBLIC = {name: fn for topic in TOPICS for name, fn in _public(topic).items()}


def test_the_walk_sees_every_topic_function():
    for topic in TOPICS:
        package = importlib.import_module(f"cvkit.{topic}")
        for name in package.__all__:
            obj = getattr(package, name)
            assert not inspect.isfunction(obj) or f"{obj.__module__}.{obj.__qualname__}" in PUBLIC, name
    for expected in ("cvkit.features._matching.KDTree.query_bbf", "cvkit.features._matching.KDTree.__init__",
                     "cvkit.features._scale_space.derivatives_3d", "cvkit.calibration._zhang.rotation_to_vector",
                     "cvkit.detection._hough.theta_samples", "cvkit.camera._common.as_points"):
        assert expected in PUBLIC, expected


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_public_function_is_fully_annotated(name):
    fn = PUBLIC[name]
    hints = typing.get_type_hints(fn)                   # every annotation must also resolve
    unannotated = [p for p in inspect.signature(fn).parameters if p not in ("self", "cls") and p not in hints]
    assert not unannotated, f"{name}: parameters without a type hint: {unannotated}"
    assert "return" in hints, f"{name}: no return type"
