"""Checks of Chapter 8's calibration algorithms: cases, comparators and mistake banks.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference function
(``cvkit.calibration.checks:homography_dlt`` grades ``calibration.homography_dlt``).

- ``public`` cases are few and small but already separate every mistake of the bank (noisy,
  clustered pixel coordinates in the thousands for the un-normalised DLT; four points for the
  economy SVD; a skewed camera and three views for the intrinsics; a perturbed homography for
  the missing re-orthonormalisation; a board of the wrong size for the detector; ...).
- ``hidden`` cases are drawn from the grading seed: random cameras, poses, point counts and
  noise levels, integer and list inputs, negative and tiny/huge scales of homogeneous inputs —
  and for every mistake inputs on which it is wrong. They stay small: at most 5 views of at
  most 20 points for a calibration, images of about 100×140 pixels for the detector, so that a
  student's plain version finishes in well under a second per case.

Comparators (subclasses of :class:`cvkit.grading.Comparator`, numpy.testing-style messages):

- :class:`HomographyClose` — a 3×3 H with H[2, 2] = 1 that maps the case's points where the
  reference does, within a tolerance in pixels (so entries of very different magnitudes are
  judged by their effect, and an unscaled H is told to divide by H[2, 2]);
- :class:`GridEqual` — the nodes ``(i, j, candidate)`` of a grown grid, exactly (any row order),
  or None where the seed grows no grid;
- :class:`CornersClose` — a corner list in the catalog's order (or its 180° rotation) within a
  mean and a maximal distance, or None where no board is expected;
- :class:`MinimumClose` — the ``(x, info)`` of an optimiser: the same minimum, a truthful
  ``info["cost"]``, ``converged`` as expected, and, when the iteration budget is too small
  for anybody, at least no worse than the start;
- :class:`CalibrationClose` — the fields of a calibration result (a dict or an object).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .. import registry
from ..camera import project_full as _project_full
from ..camera import rotation_matrix as _rotation_matrix
from ..camera.checks import FloatClose, Parts
from ..grading import Case, Check, Comparator, Mismatch, Mistake, mistake
from ..grading.casekit import variant
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ..grading.compare import FloatArrayComparator, as_float_array, tuple_problem
from ._homography import _apply, _dlt_matrix, _null_vector, _scaled, hartley_normalization
from ._homography import homography_dlt as _homography_dlt
from ._homography import refine_homography as _refine_homography
from ._optimize import levenberg_marquardt as _levenberg_marquardt
from ._pattern import chessboard_points as _chessboard_points
from ._pattern import find_chessboard_corners as _find_chessboard_corners
from ._pattern import chessboard_response as _chessboard_response
from ._pattern import corner_candidates as _corner_candidates
from ._pattern import order_grid_corners as _order_grid_corners
from ._pattern import grow_grid as _grow_grid_reference
from ._pattern import refine_corners as _refine_corners_reference
from ._pattern import _grid_rows, _grow_grid
from ._pattern import _LUMA, _derivatives, _edge_directions, _grey01, _hessian_map, _strongest_peaks
from ..filters import gaussian as _gaussian
from ..warp import bilinear_sample as _bilinear
from ..grading.runtime.problems import Jacobian, Residuals, least_squares_call
from ._zhang import _calibrate, _v
from ._zhang import extrinsics_from_homography as _extrinsics_from_homography
from ._zhang import intrinsics_from_homographies as _intrinsics_from_homographies

__all__ = [
    "HomographyClose", "CornersClose", "MinimumClose", "CalibrationClose",
    "MapClose", "CandidatesClose", "PointsClose", "GridEqual",
    "chessboard_points", "chessboard_response", "corner_candidates", "grow_grid", "order_grid_corners",
    "refine_corners",
    "find_chessboard_corners", "homography_dlt", "levenberg_marquardt",
    "refine_homography", "intrinsics_from_homographies", "extrinsics_from_homography",
    "estimate_radial_distortion", "calibrate",
]

CAMERA_BLOCKS = ("camera.to_homogeneous", "camera.from_homogeneous", "camera.intrinsic_matrix",
                 "camera.rotation_matrix", "camera.projection_matrix", "camera.project", "camera.distort",
                 "camera.undistort_points", "camera.project_full")


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
def _as_matrix(got, shape=(3, 3)) -> tuple[np.ndarray | None, str | None]:
    return as_float_array(got, shape=shape)


def _map(H: np.ndarray, points: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):
        m = points @ H[:, :2].T + H[:, 2]
        return m[:, :2] / m[:, 2:]


@dataclass
class HomographyClose(Comparator):
    """A homography judged by what it does: H[2, 2] as expected (1) and the probe points mapped within
    ``atol + rtol·max|mapped|`` pixels of where the expected H maps them.

    ``probes(case)`` gives the (N, 2) points to map (default: the case's first argument); with
    ``corners`` the corners of their bounding box are added.
    """

    atol: float = 1e-4
    rtol: float = 1e-8
    probes: Callable[[Any], Any] | None = None
    corners: bool = True
    elementwise = True  # a normalised H is compared entry by entry by the diagnosis

    def describe(self) -> str:
        return f"H[2,2] = 1 and mapped points within {self.atol:g} px + {self.rtol:g}·|value|"

    def _probe_points(self, case) -> np.ndarray:
        if self.probes is not None:
            pts = np.asarray(self.probes(case), dtype=np.float64)
        else:
            pts = np.asarray(case.args[0], dtype=np.float64)
        if not self.corners:
            return pts
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return np.vstack([pts, [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]])

    def normalise(self, value):
        """H scaled so that H[2, 2] = 1 (what the check asks for), for matching mistakes up to
        scale: A⁻¹·R·A is named whether or not the candidate divided by H[2, 2]."""
        H, problem = _as_matrix(value)
        if problem or not np.all(np.isfinite(H)):
            return value
        if abs(H[2, 2]) > 1e-12 * max(1e-300, float(np.abs(H).max())):
            return H / H[2, 2]
        return value

    def __call__(self, got, expected, case=None):
        H, problem = _as_matrix(got)
        if problem:
            return Mismatch(problem)
        E = np.asarray(expected, dtype=np.float64)
        if not np.all(np.isfinite(H)):
            return Mismatch("your H contains NaN or inf")
        scale_wrong = abs(H[2, 2] - E[2, 2]) > 1e-9 * max(1.0, abs(E[2, 2]))
        if case is None:
            points = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
        else:
            points = self._probe_points(case)
        # what H does does not depend on its scale: judge that first, so that the advice about
        # the scale is given only when the scale is the one thing wrong
        mine, theirs = _map(H, points), _map(E, points)
        scale = float(np.abs(theirs[np.isfinite(theirs)]).max()) if np.isfinite(theirs).any() else 1.0
        tolerance = self.atol + self.rtol * max(1.0, scale)
        with np.errstate(invalid="ignore"):
            distance = np.hypot(*(mine - theirs).T)
        distance = np.where(np.isfinite(distance), distance, np.inf)
        worst = int(np.argmax(distance))
        if distance[worst] <= tolerance:
            if not scale_wrong:
                return None
            advice = (": your H maps every point right and only its scale is off; "
                      "normalise it by dividing it by H[2, 2]" if E[2, 2] == 1.0 else "")
            return Mismatch(f"H[2, 2] = {H[2, 2]:.6g}, expected {E[2, 2]:.6g}{advice}",
                            max_abs=abs(H[2, 2] - E[2, 2]), worst=(2, 2))
        bad = int(np.count_nonzero(distance > tolerance))
        x, y = points[worst]
        note = (f"\n(its scale differs too: H[2, 2] = {H[2, 2]:.6g}, expected {E[2, 2]:.6g}; fix what H does first)"
                if scale_wrong else "")
        return Mismatch(
            f"Your H maps points elsewhere: {bad} of {len(points)} test points land more than {tolerance:.3g} px "
            f"from where they should\n"
            f"Max distance {distance[worst]:.6g} px for the point ({x:.6g}, {y:.6g}): yours goes to "
            f"({mine[worst, 0]:.6g}, {mine[worst, 1]:.6g}), expected ({theirs[worst, 0]:.6g}, {theirs[worst, 1]:.6g})"
            + note,
            max_abs=float(distance[worst]), worst=(worst,), mismatched=bad, total=len(points))


def _distances_mismatch(d, pts, exp, mean, maximum, words, counted):
    """None when the distances ``d`` between ``pts`` and ``exp`` are within ``mean`` on average
    and ``maximum`` each, else the mismatch at the farthest point; ``words`` = (what differs,
    what one is called, significant digits of the coordinates); ``mismatched`` counts the
    distances above ``counted``."""
    if d.mean() <= mean and d.max() <= maximum:
        return None
    what, one, digits = words
    worst = int(np.argmax(d))
    return Mismatch(
        f"{what} differ: mean distance {d.mean():.4g} px (at most {mean:g}), max {d.max():.4g} px "
        f"(at most {maximum:g}) at {one} {worst}: yours ({pts[worst, 0]:.{digits}g}, {pts[worst, 1]:.{digits}g}), "
        f"expected ({exp[worst, 0]:.{digits}g}, {exp[worst, 1]:.{digits}g})",
        max_abs=float(d.max()), worst=(worst,), mismatched=int(np.count_nonzero(d > counted)), total=len(d))


@dataclass
class CornersClose(FloatArrayComparator):
    """Chessboard corners in the catalog's order (or its 180° rotation, ``expected[::-1]``)
    within ``mean`` px on average and ``maximum`` px for every corner; None where the
    reference finds no board."""

    mean: float = 0.2
    maximum: float = 0.6
    layout = " (cols·rows corners, (x, y) each)"
    nonfinite = "your corners contain NaN or inf"

    def describe(self) -> str:
        return f"corners in order within {self.mean:g} px on average and {self.maximum:g} px each"

    def __call__(self, got, expected, case=None):
        if expected is None:
            if got is None:
                return None
            return Mismatch("expected None: the image has no complete board of this size (return None when the "
                            "grid you find is not exactly cols × rows corners)")
        if got is None:
            return Mismatch(f"you returned None, but the image has a {len(expected)}-corner board of this size")
        return super().__call__(got, self._true_positions(expected, case), case)

    def _true_positions(self, expected, case):
        """On a rendered board (a :class:`TruthCase` holding the corners the renderer drew), the
        true corners in the order of ``expected`` — when ``expected`` is itself a right answer
        (within the tolerances of them): then an answer is judged by where the corners really
        are, not by where the reference put them. Otherwise (a mistake's output, to recognise
        it) ``expected`` as it is."""
        truth = getattr(case, "truth", None)
        exp = np.asarray(expected, dtype=np.float64)
        if truth is None or exp.ndim != 2 or exp.shape != np.shape(truth):
            return expected
        d = np.hypot(*(exp[:, None, :] - truth[None]).transpose(2, 0, 1))
        match = d.argmin(axis=1)
        ordered = truth[match]
        if len(set(match.tolist())) != len(match) or self.judge_array(exp, ordered, case) is not None:
            return expected
        return ordered

    def judge_array(self, pts, exp, case=None):
        best = None
        for order, name in ((exp, "as expected"), (exp[::-1], "rotated by 180°")):
            d = np.hypot(*(pts - order).T)
            if best is None or d.mean() < best[0].mean():
                best = (d, order, name)
        d, order, name = best
        return _distances_mismatch(d, pts, order, self.mean, self.maximum, ("Corners", "corner", 4), self.mean)


@dataclass
class MinimumClose(Comparator):
    """``(x, info)`` of a least-squares optimiser.

    - ``info`` is a mapping with ``iterations`` (0..max_iter), ``cost`` and ``converged``;
    - ``converged`` as the reference's, x within ``xtol·max(1, |x_i|)`` and the cost within
      ``ctol`` (relative) of the reference's. (Only problems with a unique minimum that every
      correct method reaches well within the budget are used — and ``max_iter = 0``, where
      everybody must return x0.)
    """

    xtol: float = 1e-5
    ctol: float = 1e-7

    def describe(self) -> str:
        return f"same minimum (x within {self.xtol:g}·max(1,|x|), cost within {self.ctol:g} relative)"

    def __call__(self, got, expected, case=None):
        problem = tuple_problem(got, ("x", "info"))
        if problem:
            return Mismatch(problem)
        x, info = got
        x_exp, info_exp = expected
        try:
            x = np.asarray(x, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            return Mismatch(f"x could not be turned into a float array ({exc})")
        x_exp = np.asarray(x_exp, dtype=np.float64)
        if x.shape != x_exp.shape:
            return Mismatch(f"x: shape mismatch, expected {x_exp.shape}, got {x.shape}")
        if not isinstance(info, Mapping):
            return Mismatch(f"info must be a dict with 'iterations', 'cost' and 'converged', got {type(info).__name__}")
        missing = [k for k in ("iterations", "cost", "converged") if k not in info]
        if missing:
            return Mismatch(f"info lacks the key(s) {', '.join(map(repr, missing))}")
        if not np.all(np.isfinite(x)):
            return Mismatch("x contains NaN or inf: the iteration diverged (damp the steps and refuse those that "
                            "raise the cost)")
        try:
            cost = float(info["cost"])
            iterations = int(info["iterations"])
        except (TypeError, ValueError):
            return Mismatch("info['cost'] must be a number and info['iterations'] an integer")
        converged = info["converged"]
        if not isinstance(converged, (bool, np.bool_)):
            return Mismatch(f"info['converged'] must be True or False, got {converged!r}")
        max_iter = (case.kwargs.get("max_iter", case.args[3] if len(case.args) > 3 else 100)) if case is not None else None
        if max_iter is not None and not 0 <= iterations <= max_iter:
            return Mismatch(f"info['iterations'] = {iterations} is not between 0 and max_iter = {max_iter}")
        if bool(converged) != bool(info_exp["converged"]):
            if converged:
                return Mismatch("info['converged'] is True, but no stopping test can be met within max_iter iterations")
            return Mismatch("info['converged'] is False, but the problem can be solved within max_iter iterations")
        tolerance = self.xtol * np.maximum(1.0, np.abs(x_exp))
        error = np.abs(x - x_exp)
        if np.any(error > tolerance):
            i = int(np.argmax(error - tolerance))
            return Mismatch(
                f"Not the same minimum: x[{i}] = {x[i]:.10g}, expected {x_exp[i]:.10g} "
                f"(tolerance {tolerance[i]:.3g}); your cost {cost:.8g}, expected {info_exp['cost']:.8g}",
                max_abs=float(error.max()), worst=(i,), mismatched=int(np.count_nonzero(error > tolerance)),
                total=x.size)
        if not abs(cost - info_exp["cost"]) <= self.ctol * abs(info_exp["cost"]) + 1e-12:
            return Mismatch(f"info['cost'] = {cost:.10g}, expected {info_exp['cost']:.10g}")
        return None


def _field(result, name):
    if isinstance(result, Mapping):
        if name not in result:
            raise KeyError(name)
        return result[name]
    if not hasattr(result, name):
        raise KeyError(name)
    return getattr(result, name)


@dataclass
class CalibrationClose(Comparator):
    """A calibration result (dict or object) with ``A``, ``k``, ``rotations``,
    ``translations`` and ``rms`` close to the reference's (the same minimum of the
    reprojection error, reached by another implementation of the same steps)."""

    rtol: float = 1e-5
    rms_rtol: float = 1e-6
    inner: Comparator = field(default_factory=lambda: FloatClose(rtol=1e-5, atol=1e-6))

    def describe(self) -> str:
        return f"A, k, rotations, translations within {self.rtol:g} (relative), rms within {self.rms_rtol:g}"

    def __call__(self, got, expected, case=None):
        if got is None:
            return Mismatch("your output is None: did you forget to `return` the result?")
        values = {}
        for name in ("A", "k", "rotations", "translations", "rms"):
            try:
                values[name] = _field(got, name)
            except KeyError:
                return Mismatch(f"your result has no {name!r}: return a dict with the keys A, k, rotations, "
                                "translations and rms")
        A = np.asarray(values["A"], dtype=np.float64) if values["A"] is not None else None
        if A is None or A.shape != (3, 3):
            return Mismatch(f"A: expected a 3×3 matrix, got {None if A is None else A.shape}")
        scale = float(np.abs(expected["A"]).max())
        checks = [
            ("A", A, np.asarray(expected["A"]), FloatClose(rtol=self.rtol, atol=self.rtol * scale)),
            ("k", np.asarray(values["k"], dtype=np.float64).ravel(), np.asarray(expected["k"]),
             FloatClose(rtol=self.rtol * 100, atol=1e-4)),
            ("rotations", np.asarray(values["rotations"], dtype=np.float64), np.asarray(expected["rotations"]),
             FloatClose(rtol=0.0, atol=self.rtol)),
            ("translations", np.asarray(values["translations"], dtype=np.float64),
             np.asarray(expected["translations"]),
             FloatClose(rtol=self.rtol, atol=self.rtol * float(np.abs(expected["translations"]).max()))),
        ]
        for name, mine, theirs, compare in checks:
            mismatch = compare(mine, theirs, case)
            if mismatch is not None:
                mismatch.message = f"{name}: {mismatch.message}"
                return mismatch
        try:
            rms = float(values["rms"])
        except (TypeError, ValueError):
            return Mismatch(f"rms must be a number, got {type(values['rms']).__name__}")
        expected_rms = float(expected["rms"])
        if not abs(rms - expected_rms) <= self.rms_rtol * expected_rms + 1e-6:
            return Mismatch(f"rms: yours {rms:.8g} px, expected {expected_rms:.8g} px "
                            "(√(Σ‖e‖² / number of points) after the refinement)")
        return None


# --------------------------------------------------------------------------------------------
# case helpers
# --------------------------------------------------------------------------------------------
def _camera(rng, skew=False, size=(480, 640)):
    rows, cols = size
    fu = _u(rng, 0.9, 1.4, 3) * cols
    fv = fu * _u(rng, 0.93, 1.07, 3)
    u0 = cols / 2 + _u(rng, -0.06, 0.06) * cols
    v0 = rows / 2 + _u(rng, -0.06, 0.06) * rows
    s = _u(rng, 1.0, 4.0, 2) * rng.choice([-1.0, 1.0]) if skew else 0.0
    return np.array([[fu, s, u0], [0.0, fv, v0], [0.0, 0.0, 1.0]])


def _pose(rng, cols, rows, square, depth, tilt=0.6, spin=0.4):
    """A pose that looks at the centre of a cols × rows board from about ``depth``."""
    R = _rotation_matrix(rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt), rng.uniform(-spin, spin))
    centre = np.array([(cols - 1) * square / 2, (rows - 1) * square / 2, 0.0])
    target = np.array([rng.uniform(-0.12, 0.12) * depth, rng.uniform(-0.1, 0.1) * depth, depth])
    return R, target - R @ centre


def _views(rng, A, cols, rows, square, n_views, k=(0.0, 0.0), noise=0.0, size=(480, 640)):
    """Poses and image points of a board whose corners all stay inside the image."""
    world = _chessboard_points(cols, rows, square)
    width = max(cols, rows) * square
    Rs, ts, images = [], [], []
    while len(Rs) < n_views:
        depth = A[0, 0] * width / (size[1] * rng.uniform(0.45, 0.75))
        R, t = _pose(rng, cols, rows, square, depth)
        m = _project_full(world, A, R, t, k)
        if np.all(m >= 10) and np.all(m[:, 0] <= size[1] - 10) and np.all(m[:, 1] <= size[0] - 10):
            Rs.append(R)
            ts.append(t)
            images.append(m + rng.normal(0.0, noise, m.shape) if noise else m)
    return world, Rs, ts, images


def _perspective_homography(rng, scale=1.0, offset=(0.0, 0.0)):
    """A homography with a real perspective part, mapping [0, 200]² to around ``offset``."""
    a = scale * rng.uniform(1.5, 3.0)
    angle = rng.uniform(-0.6, 0.6)
    H = np.array([[a * np.cos(angle), -a * np.sin(angle) + rng.normal(0, 0.2) * scale, offset[0] + rng.uniform(50, 150)],
                  [a * np.sin(angle) + rng.normal(0, 0.2) * scale, a * np.cos(angle) * rng.uniform(0.8, 1.2),
                   offset[1] + rng.uniform(50, 150)],
                  [rng.uniform(-1.5e-3, 1.5e-3), rng.uniform(-1.5e-3, 1.5e-3), 1.0]])
    return H


def _pairs(rng, n, H, noise, spread=200.0):
    src = rng.uniform(0.0, spread, (n, 2))
    dst = _map(H, src)
    return np.round(src, 3), dst + rng.normal(0.0, noise, dst.shape)


# --------------------------------------------------------------------------------------------
# calibration.chessboard_points (§8.3)
# --------------------------------------------------------------------------------------------
@mistake("column by column (x varies slowest)",
         "Point r·cols + c is (c·s, r·s, 0): go row by row, x (c) varying fastest, like "
         "np.mgrid[0:cols, 0:rows].T.reshape(-1, 2)")
def _cp_column_major(cols, rows, square_size):
    P = _chessboard_points(cols, rows, square_size)
    return P.reshape(rows, cols, 3).transpose(1, 0, 2).reshape(-1, 3)


@mistake("x and y swapped", "x goes along a row of the board (the cols corners), y along a column: (c·s, r·s, 0)")
def _cp_xy_swapped(cols, rows, square_size):
    return _chessboard_points(cols, rows, square_size)[:, [1, 0, 2]]


@mistake("square size ignored (unit squares)",
         "Multiply the grid indices by square_size: the world unit is the unit of the squares")
def _cp_unit_squares(cols, rows, square_size):
    return _chessboard_points(cols, rows, 1.0)


@mistake("grid starts one square from the origin",
         "The origin is the first inner corner itself: indices start at 0, (0, 0, 0) is a point")
def _cp_from_one(cols, rows, square_size):
    P = _chessboard_points(cols, rows, square_size)
    P[:, :2] += float(square_size)
    return P


@mistake("2-D points (z column missing)", "Return 3-D world points (N, 3) with z = 0: the board is the plane z_W = 0")
def _cp_2d(cols, rows, square_size):
    return _chessboard_points(cols, rows, square_size)[:, :2]


@mistake("squares counted instead of inner corners",
         "cols × rows count the inner corners (where four squares meet), not the squares")
def _cp_squares(cols, rows, square_size):
    return _chessboard_points(cols + 1, rows + 1, square_size)


def _cp_hidden(rng):
    def n(lo, hi):
        return _size(rng, lo, hi)

    c = n(4, 9)
    r = c - n(1, 3)
    square = n(3, 12)
    return [
        Case((c, r, _u(rng, 15, 40, 1)), {}, "cols > rows, square size in mm"),
        Case((r, c, _u(rng, 0.01, 0.05, 4)), {}, "rows > cols, square size in metres"),
        Case((square, square, _u(rng, 2, 30, 2)), {}, "square board (cols = rows)"),
        Case((n(5, 8), n(2, 4), n(10, 40)), {}, "integer square size (result float)"),
        Case((np.int64(n(3, 6)), np.int64(n(7, 9)), np.float64(_u(rng, 5, 25, 2))), {}, "NumPy integer counts"),
        Case((n(2, 3), n(6, 9), _u(rng, 20, 30, 1)), {}, "tall board (2 or 3 columns)"),
        Case((n(15, 22), n(10, 14), _u(rng, 0.5, 2, 3)), {}, "large board"),
        Case((1, n(3, 6), _u(rng, 10, 20, 1)), {}, "a single column of corners"),
        Case((n(3, 6), 1, _u(rng, 10, 20, 1)), {}, "a single row of corners"),
        Case((n(4, 7), n(2, 3), 1.0), {}, "unit squares"),
    ]


chessboard_points = Check(
    public=[
        Case((4, 3, 25.0), {}, "4 × 3 inner corners, 25 mm squares"),
        Case((3, 5, 0.5), {}, "3 × 5 inner corners (taller than wide), 0.5 units"),
    ],
    hidden=_cp_hidden,
    compare=FloatClose(rtol=1e-12, atol=1e-12),
    mistakes=[_cp_column_major, _cp_xy_swapped, _cp_unit_squares, _cp_from_one, _cp_2d, _cp_squares],
)


# --------------------------------------------------------------------------------------------
# calibration.find_chessboard_corners (§8.3)
# --------------------------------------------------------------------------------------------
def _board_image(rng, cols, rows, size=(100, 136), tilt=0.5, spin=0.3, flip=False, noise=0.008, color=False,
                 dtype="float", k=None, square_fill=(0.6, 0.8), truth=False):
    """A rendered view of a random board for the detection checks.

    Rendered with 4 × 4 samples per edge pixel rather than the default 8 × 8: the area
    quantisation (1/16 of the contrast, about the size of the added sensor noise) does not
    matter to a check that compares a student's answer with the reference's on the same
    pixels, and drawing is 2.5 times faster; grading draws these images for every student.

    With ``truth=True`` it returns ``(image, corners, directions)``: where the renderer put the
    inner corners, ``(cols·rows, 2)`` pixel positions ``(x, y)``, and the two unit directions of
    the board's lines through each, ``(cols·rows, 2, 2)`` (along a row, down a column; lens
    distortion included). No random number is drawn for them: the image is the same either way.
    """
    from ..data import random_board_poses, render_chessboard

    H, W = size
    f = _u(rng, 0.9, 1.2) * W
    A = np.array([[f, 0.0, W / 2 + _u(rng, -3, 3)], [0.0, f * _u(rng, 0.97, 1.03), H / 2 + _u(rng, -3, 3)],
                  [0.0, 0.0, 1.0]])
    k = (_u(rng, -0.25, 0.05), _u(rng, 0.0, 0.05)) if k is None else k
    R, t = random_board_poses(1, A, size, cols, rows, 10.0, k, rng=rng, tilt=tilt, spin=spin, fill=square_fill,
                              border=4.0, flip=flip)
    image = render_chessboard(A, R[0], t[0], cols, rows, 10.0, size, k, noise=noise, rng=rng, color=color,
                              supersample=4)
    if dtype == "uint8":
        image = np.round(image * 255).astype(np.uint8)
    elif dtype == "scaled":
        image = image * 1000.0 - 200.0
    if not truth:
        return image
    board = _chessboard_points(cols, rows, 10.0)
    corners = _project_full(board, A, R[0], t[0], k)
    lines = []
    for axis in (0, 1):                                   # a small step along the board's x, then y
        step = np.zeros(3)
        step[axis] = 0.01
        d = _project_full(board + step, A, R[0], t[0], k) - _project_full(board - step, A, R[0], t[0], k)
        lines.append(d / np.linalg.norm(d, axis=1, keepdims=True))
    return image, corners, np.stack(lines, axis=1)


@mistake("(row, col) returned instead of (x, y)",
         "Points are (x, y) = (col, row): np.nonzero gives (rows, cols), swap them before returning")
def _fc_swapped_xy(image, cols, rows):
    corners = _find_chessboard_corners(image, cols, rows)
    return None if corners is None else corners[:, ::-1].copy()


@mistake("no sub-pixel refinement (integer pixels)",
         "Refine each corner below the pixel: e.g. Newton steps to the saddle point of the smoothed image, "
         "q ← q − H⁻¹∇I with derivatives interpolated at q")
def _fc_integer(image, cols, rows):
    corners = _find_chessboard_corners(image, cols, rows)
    return None if corners is None else np.round(corners)


@mistake("column by column (x and y of the board swapped)",
         "Corner r·cols + c: go along the side with `cols` corners first (x), then down the `rows` side")
def _fc_column_major(image, cols, rows):
    corners = _find_chessboard_corners(image, cols, rows)
    if corners is None:
        return None
    return corners.reshape(rows, cols, 2).transpose(1, 0, 2).reshape(-1, 2)


@mistake("left-handed order (mirror image of the board)",
         "The board's x and y axes must turn like the image's (x right, y down): choose the origin and the "
         "directions so that cross(x direction, y direction) > 0")
def _fc_left_handed(image, cols, rows):
    corners = _find_chessboard_corners(image, cols, rows)
    if corners is None:
        return None
    return corners.reshape(rows, cols, 2)[::-1].reshape(-1, 2)


@mistake("a larger board accepted (grid size not checked)",
         "Return None unless the grid you grow is exactly cols × rows corners: a board with more corners is "
         "another board")
def _fc_bigger_board(image, cols, rows):
    corners = _find_chessboard_corners(image, cols, rows)
    if corners is not None:
        return corners
    for c, r in ((cols + 1, rows), (cols, rows + 1), (cols + 1, rows + 1), (cols + 2, rows), (cols, rows + 2)):
        bigger = _find_chessboard_corners(image, c, r)
        if bigger is not None:
            return bigger.reshape(r, c, 2)[:rows, :cols].reshape(-1, 2)
    return None


#: the boards the hidden cases of both corner detectors (find_chessboard_corners,
#: corner_candidates) start with: label, cols, rows, how the board is rendered
_BOARDS = (
    ("grey 5 × 4 board", 5, 4, {"spin": 0.5}),
    ("6 × 4 board, strong tilt", 6, 4, {"size": (110, 150), "tilt": 0.6}),
    ("4 × 3 board upside down", 4, 3, {"flip": True}),
    ("RGB float image", 5, 4, {"color": True}),
    ("uint8 image, rotated board", 4, 3, {"dtype": "uint8", "spin": 0.6}),
)


def _fc_case(rng, label, cols, rows, ask=None, **board):
    """A rendered board; the truth (the corners the renderer drew) when the size asked is the
    board's, so that answers are judged against the true corners."""
    image, corners, _ = _board_image(rng, cols, rows, truth=True, **board)
    asked = (cols, rows) if ask is None else ask
    return TruthCase((image,) + tuple(asked), {}, label, truth=corners if ask is None else None)


def _fc_public():
    rng = np.random.default_rng(80301)
    return [
        _fc_case(rng, "grey 100×136, 5 × 4 board, tilted", 5, 4, spin=0.4),
        _fc_case(rng, "RGB uint8, 4 × 3 board upside down", 4, 3, size=(96, 128), spin=0.3, flip=True, color=True,
                 dtype="uint8"),
        _fc_case(rng, "a 5 × 3 board, asked for 4 × 3: None", 5, 3, ask=(4, 3), size=(90, 120)),
    ]


def _fc_hidden(rng):
    partial = _board_image(rng, 5, 4)
    partial = partial[:, : partial.shape[1] // 2].copy()
    return [
        *(_fc_case(rng, label, cols, rows, **board) for label, cols, rows, board in _BOARDS),
        _fc_case(rng, "square 4 × 4 board", 4, 4, spin=0.3),
        _fc_case(rng, "3 × 5 board in a tall image", 3, 5, size=(120, 110)),
        _fc_case(rng, "values in [-200, 800], more noise", 5, 4, dtype="scaled", noise=0.015),
        _fc_case(rng, "strong barrel distortion", 5, 4, k=(-0.3, 0.05)),
        _fc_case(rng, "a 5 × 4 board, asked for 4 × 4: None", 5, 4, ask=(4, 4)),
        _fc_case(rng, "a 4 × 3 board, asked for 4 × 4: None", 4, 3, ask=(4, 4)),
        Case((partial, 5, 4), {}, "half of the board cut off: None"),
        Case((np.full((60, 80), 0.5) + rng.normal(0, 0.01, (60, 80)), 4, 3), {}, "no board at all: None"),
    ]


find_chessboard_corners = Check(
    public=_fc_public,
    hidden=_fc_hidden,
    compare=CornersClose(mean=0.2, maximum=0.6),
    mistakes=[_fc_swapped_xy, _fc_integer, _fc_column_major, _fc_left_handed, _fc_bigger_board],
    allowed=("calibration.chessboard_response", "calibration.corner_candidates", "calibration.grow_grid",
             "calibration.order_grid_corners",
             "calibration.refine_corners", "filters.gaussian", "filters.correlate", "filters.convolve",
             "warp.bilinear_sample"),
    time_limit=30.0,
)


# --------------------------------------------------------------------------------------------
# the four steps of the detector (§8.3): response, candidates, grid order, sub-pixel position
# --------------------------------------------------------------------------------------------
@dataclass
class MapClose(FloatArrayComparator):
    """A float image within ``rtol·max|expected|`` (+ 1e-12) of the expected one, pixel by pixel."""

    rtol: float = 1e-6
    elementwise = True
    layout = " (one value per pixel)"

    def describe(self) -> str:
        return f"every pixel within {self.rtol:g}·max|expected|"

    def judge_array(self, arr, exp, case=None):
        scale = float(np.abs(exp).max())
        tolerance = self.rtol * scale + 1e-12
        error = np.abs(arr - exp)
        if error.max() <= tolerance:
            return None
        worst = np.unravel_index(int(np.argmax(error)), error.shape)
        bad = int(np.count_nonzero(error > tolerance))
        return Mismatch(
            f"{bad} of {error.size} pixels differ by more than {tolerance:.3g} ({self.rtol:g} of the largest "
            f"expected value, {scale:.4g}); worst at [row, col] = {tuple(int(i) for i in worst)}: yours "
            f"{arr[worst]:.6g}, expected {exp[worst]:.6g}",
            max_abs=float(error.max()), worst=tuple(int(i) for i in worst), mismatched=bad, total=error.size)


def _line_angles(got_dirs, exp_dirs):
    """Largest angle (degrees) between the lines of two direction pairs, best pairing."""
    def unit(d):
        with np.errstate(all="ignore"):
            return d / np.linalg.norm(d, axis=-1, keepdims=True)
    g, e = unit(got_dirs), unit(exp_dirs)
    cos = np.abs(np.einsum("kid,kjd->kij", e, g)).clip(0.0, 1.0)        # [k, expected i, got j]
    straight = np.maximum(np.arccos(cos[:, 0, 0]), np.arccos(cos[:, 1, 1]))
    crossed = np.maximum(np.arccos(cos[:, 0, 1]), np.arccos(cos[:, 1, 0]))
    return np.degrees(np.where(np.isfinite(straight), np.fmin(straight, crossed), np.inf))


@dataclass
class CandidatesClose(Comparator):
    """``(points, directions)`` of corner candidates.

    On a rendered board whose corners are known (a :class:`TruthCase`), by what the candidates
    are for: every inner corner has a candidate within ``radius`` px, whose two edge directions
    are within ``degrees`` of the board's lines through that corner (either order, either sign);
    at most ``max(3, count // 4)`` candidates are not inner corners, and the first ``lead`` are
    inner corners (the grid step takes its seeds from the front). Any correct detector passes,
    whichever pixels it settles on. Against an output that is itself wrong (a mistake of the
    bank, to recognise it) and on cases without a truth: the same pixels as that output (within
    0.5 px, ``slack`` more or fewer), in the same order, directions within 3°."""

    radius: float = 1.5
    degrees: float = 15.0
    lead: int = 3
    slack: int = 1

    def describe(self) -> str:
        return (f"every inner corner found within {self.radius:g} px, its edge directions within "
                f"{self.degrees:g}°, few false candidates, inner corners first")

    def _arrays(self, got):
        problem = tuple_problem(got, ("points", "directions"))
        if problem:
            return None, None, Mismatch(problem)
        try:
            pts = np.asarray(got[0], dtype=np.float64).reshape(-1, 2)
            dirs = np.asarray(got[1], dtype=np.float64)
        except (TypeError, ValueError) as exc:
            return None, None, Mismatch(f"points must be (K, 2) and directions (K, 2, 2) float arrays ({exc})")
        if dirs.shape != (len(pts), 2, 2):
            return None, None, Mismatch(f"directions must be (K, 2, 2) for K = {len(pts)} points, got shape {dirs.shape}")
        if not (np.all(np.isfinite(pts)) and np.all(np.isfinite(dirs))):
            return None, None, Mismatch("your points or directions contain NaN or inf")
        return pts, dirs, None

    def judge(self, got, truth, count):
        """The verdict on ``got`` from the corners the renderer drew."""
        pts, dirs, problem = self._arrays(got)
        if problem is not None:
            return problem
        corners, lines = truth
        allowed = max(3, int(count) // 4)
        if len(corners) == 0:
            if len(pts) <= allowed:
                return None
            return Mismatch(f"There is no board in this image, yet you found {len(pts)} candidates "
                            f"(at most {allowed} false ones are tolerated)", mismatched=len(pts), total=allowed)
        if len(pts) == 0:
            return Mismatch(f"you found no candidates; the board has {len(corners)} inner corners")
        d = np.hypot(*(corners[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))     # [corner, candidate]
        nearest = d.argmin(axis=1)
        found = d[np.arange(len(corners)), nearest] <= self.radius
        if not found.all():
            miss = corners[~found]
            return Mismatch(f"{len(miss)} of the {len(corners)} inner corners have no candidate within "
                            f"{self.radius:g} px, e.g. the corner at (x, y) = ({miss[0, 0]:.4g}, {miss[0, 1]:.4g})",
                            mismatched=len(miss), total=len(corners))
        true_ones = (d <= self.radius).any(axis=0)
        false = np.flatnonzero(~true_ones)
        if len(false) > allowed:
            p = pts[false[0]]
            return Mismatch(f"{len(false)} of your {len(pts)} candidates are not inner corners of the board (at most "
                            f"{allowed} are tolerated), e.g. (x, y) = ({p[0]:.4g}, {p[1]:.4g}): an L-corner of the "
                            "outline, an edge or noise", mismatched=len(false), total=len(pts))
        lead = min(self.lead, len(pts))
        if not true_ones[:lead].all():
            k = int(np.argmin(true_ones[:lead]))
            return Mismatch(f"your candidate number {k + 1}, at ({pts[k, 0]:.4g}, {pts[k, 1]:.4g}), is not an inner "
                            "corner: put the most corner-like candidates first (the grid step tries them as seeds)")
        angles = _line_angles(dirs[nearest], lines)
        worst = int(np.argmax(angles))
        if angles[worst] > self.degrees:
            p = corners[worst]
            return Mismatch(f"Edge directions off by {angles[worst]:.3g}° (at most {self.degrees:g}°) at the corner "
                            f"({p[0]:.4g}, {p[1]:.4g}): yours {np.round(dirs[nearest][worst], 3).tolist()}, the board's "
                            f"lines {np.round(lines[worst], 3).tolist()}",
                            max_abs=float(angles[worst]), worst=(worst,),
                            mismatched=int(np.count_nonzero(angles > self.degrees)), total=len(angles))
        return None

    def __call__(self, got, expected, case=None):
        truth = getattr(case, "truth", None)
        if truth is not None:
            count = case.args[1] if len(case.args) > 1 else case.kwargs.get("count", len(truth[0]))
            if self.judge(expected, truth, count) is None:
                return self.judge(got, truth, count)
        return self._same(got, expected)

    def _same(self, got, expected):
        pts, dirs, problem = self._arrays(got)
        if problem is not None:
            return problem
        exp_pts, exp_dirs = (np.asarray(v, dtype=np.float64) for v in expected)
        exp_pts = exp_pts.reshape(-1, 2)
        if len(exp_pts) == 0 or len(pts) == 0:
            if len(exp_pts) == len(pts):
                return None
            return Mismatch(f"you found {len(pts)} candidates, expected {len(exp_pts)}")
        d = np.hypot(*(exp_pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))
        nearest = d.argmin(axis=1)
        matched = d[np.arange(len(exp_pts)), nearest] <= 0.5
        missing = exp_pts[~matched]
        used = np.zeros(len(pts), dtype=bool)
        used[nearest[matched]] = True
        extra = pts[~used]
        if len(missing) + len(extra) > self.slack:
            return Mismatch(f"Not the same candidates ({len(pts)} yours, {len(exp_pts)} expected)",
                            mismatched=len(missing) + len(extra), total=len(exp_pts))
        order = nearest[matched]
        if np.any(np.diff(order) < 0):
            return Mismatch("The candidates are not in the same order")
        angles = _line_angles(dirs[order], exp_dirs[matched])
        if angles.max() > 3.0:
            return Mismatch(f"Edge directions off by {angles.max():.3g}°")
        return None


@dataclass
class PointsClose(FloatArrayComparator):
    """(N, 2) points in the expected order within ``mean`` px on average and ``maximum`` px each."""

    mean: float = 0.01
    maximum: float = 0.05
    layout = " (one (x, y) per corner)"
    nonfinite = "your points contain NaN or inf"

    def describe(self) -> str:
        return f"points within {self.mean:g} px on average and {self.maximum:g} px each"

    def judge_array(self, pts, exp, case=None):
        if len(exp) == 0:
            return None
        d = np.hypot(*(pts - exp).T)
        return _distances_mismatch(d, pts, exp, self.mean, self.maximum, ("Points", "point", 5), self.maximum)


# calibration.chessboard_response -------------------------------------------------------------
def _cr_parts(image, sigma, rescale=True, mean_grey=False, smooth=True):
    img = np.asarray(image, dtype=np.float64)
    grey = (img.mean(axis=2) if mean_grey else img @ _LUMA) if img.ndim == 3 else img
    if rescale:
        grey = _grey01(grey)
    return _gaussian(grey, float(sigma)) if smooth else grey


def _cr_from(S, gxx=None, gxy=None, gyy=None):
    hxx, hxy, hyy = _hessian_map(S)
    gxx, gxy, gyy = (hxx if gxx is None else gxx), (hxy if gxy is None else gxy), (hyy if gyy is None else gyy)
    return gxy * gxy - gxx * gyy


@mistake("det of the Hessian (sign flipped)",
         "The response is I_xy² − I_xx·I_yy = −det(Hessian): positive at a saddle (an X-junction)")
def _cr_det(image, sigma=1.5):
    return -_chessboard_response(image, sigma)


def _cr_variant(image, sigma=1.5, *, rescale=True, mean_grey=False, smooth=True):
    """The response on the grey image :func:`_cr_parts` makes with these settings."""
    return _cr_from(_cr_parts(image, sigma, rescale=rescale, mean_grey=mean_grey, smooth=smooth))


@mistake("I_xy without the factor 1/4",
         "The mixed difference spans two pixels in x and two in y: I_xy = (S[y+1,x+1] − S[y+1,x−1] − "
         "S[y−1,x+1] + S[y−1,x−1]) / 4")
def _cr_no_quarter(image, sigma=1.5):
    S = _cr_parts(image, sigma)
    return _cr_from(S, gxy=4.0 * _hessian_map(S)[1])


@mistake("second derivatives by np.gradient twice (step 2)",
         "np.gradient of np.gradient spans 5 pixels: use the 3-pixel second difference "
         "S[y, x+1] − 2 S[y, x] + S[y, x−1] (and likewise in y)")
def _cr_gradient_twice(image, sigma=1.5):
    S = _cr_parts(image, sigma)
    Iy, Ix = np.gradient(S)
    Ixy, Ixx = np.gradient(Ix)
    Iyy = np.gradient(Iy)[0]
    R = Ixy * Ixy - Ixx * Iyy
    R[[0, -1]] = 0.0
    R[:, [0, -1]] = 0.0
    return R


def _cr_public():
    rng = np.random.default_rng(80310)
    return [
        Case((_board_image(rng, 5, 4, size=(60, 80), spin=0.4),), {}, "grey 60×80, 5 × 4 board, default sigma"),
        Case((_board_image(rng, 4, 3, size=(48, 64), color=True, dtype="uint8"),), {"sigma": 1.0},
             "RGB uint8 48×64, sigma = 1"),
    ]


def _cr_hidden(rng):
    flat = np.full((30, 40), _u(rng, 0.1, 0.9))
    return [
        Case((_board_image(rng, 5, 4, size=(60, 80)),), {}, "grey board, default sigma"),
        Case((_board_image(rng, 4, 3, size=(50, 70)), _u(rng, 1.0, 1.3, 2)), {}, "small sigma (positional)"),
        Case((_board_image(rng, 4, 4, size=(60, 80)),), {"sigma": _u(rng, 2.0, 2.5, 2)}, "large sigma"),
        Case((_board_image(rng, 5, 3, size=(50, 70), color=True),), {}, "RGB float image"),
        Case((_board_image(rng, 4, 3, size=(50, 70), color=True, dtype="uint8"),), {"sigma": 1.5}, "RGB uint8"),
        Case((_board_image(rng, 4, 3, size=(50, 70), dtype="uint8"),), {}, "grey uint8"),
        Case((_board_image(rng, 5, 4, size=(60, 80), dtype="scaled"),), {}, "values in [-200, 800]"),
        Case((rng.normal(0.5, 0.2, (24, 30)),), {"sigma": 1.0}, "noise only"),
        Case((flat,), {}, "constant image: all zeros"),
        Case((_board_image(rng, 3, 3, size=(40, 44), k=(-0.3, 0.05)),), {"sigma": 1.2}, "barrel distortion"),
    ]


chessboard_response = Check(
    public=_cr_public,
    hidden=_cr_hidden,
    compare=MapClose(rtol=1e-6),
    mistakes=[
        _cr_det,
        Mistake("image not smoothed (sigma ignored)", variant(_cr_variant, smooth=False),
                "Smooth the grey image with filters.gaussian(grey, sigma) before taking the second differences"),
        Mistake("intensities not rescaled to [0, 1]", variant(_cr_variant, rescale=False),
                "Rescale the grey image to [0, 1] first, (grey − min) / (max − min): then the response does not "
                "depend on the dtype or the range of the input"),
        Mistake("grey = mean of R, G, B", variant(_cr_variant, mean_grey=True),
                "Grey is the luma 0.299 R + 0.587 G + 0.114 B, not the plain mean of the channels"),
        _cr_no_quarter,
        _cr_gradient_twice,
    ],
    allowed=("filters.gaussian", "filters.correlate", "filters.convolve", "filters.gaussian_kernel"),
)


# calibration.corner_candidates ---------------------------------------------------------------
@mistake("(row, col) returned instead of (x, y)",
         "Points and directions are (x, y) = (col, row): np.nonzero gives (rows, cols), swap them")
def _cc_swapped(image, count, sigma=1.5):
    points, directions = _corner_candidates(image, count, sigma)
    return points[:, ::-1].copy(), directions[..., ::-1].copy()


@mistake("no ring test (L-corners and edges kept)",
         "Keep only X-junctions: an L-corner of the board's outline or a noisy edge also gives a saddle-like "
         "response. Test the neighbourhood: e.g. a small circle around an X-junction crosses its mean "
         "intensity four times, around an L-corner twice")
def _cc_no_ring_test(image, count, sigma=1.5):
    img = np.asarray(image, dtype=np.float64)
    response = _chessboard_response(img, sigma)
    S = _cr_parts(img, sigma)
    xs, ys = _strongest_peaks(response, count)
    if xs.size == 0:
        return np.zeros((0, 2)), np.zeros((0, 2, 2))
    gxx, gxy, gyy = _hessian_map(S)
    return np.column_stack([xs, ys]).astype(np.float64), _edge_directions(gxx[ys, xs], gxy[ys, xs], gyy[ys, xs])


@mistake("Hessian eigenvectors instead of the edge directions",
         "The Hessian's eigenvectors bisect the angles between the edges; the edges are the two "
         "directions d along which the quadratic form dᵀ H d vanishes")
def _cc_eigenvectors(image, count, sigma=1.5):
    points, _ = _corner_candidates(image, count, sigma)
    S = _cr_parts(image, sigma)
    gxx, gxy, gyy = _hessian_map(S)
    xs, ys = points[:, 0].astype(int), points[:, 1].astype(int)
    H = np.stack([np.stack([gxx[ys, xs], gxy[ys, xs]], -1), np.stack([gxy[ys, xs], gyy[ys, xs]], -1)], -2)
    return points, np.linalg.eigh(H)[1].transpose(0, 2, 1).copy()


@mistake("maxima at the corner of their 5 × 5 window (2 px off)",
         "A window's maximum belongs to the window's centre pixel: with np.lib.stride_tricks.sliding_window_view "
         "(or shifted copies of a padded array) the index of a window is 2 px up and left of its centre")
def _cc_window_corner(image, count, sigma=1.5):
    points, directions = _corner_candidates(image, count, sigma)
    return points - 2.0, directions


def _cc_case(rng, label, cols, rows, count=None, kwargs=None, **board):
    image, corners, lines = _board_image(rng, cols, rows, truth=True, **board)
    return TruthCase((image, cols * rows if count is None else count), dict(kwargs or {}), label,
                     truth=(corners, lines))


def _cc_public():
    rng = np.random.default_rng(80311)
    return [
        _cc_case(rng, "grey 80×108, 5 × 4 board, tilted", 5, 4, size=(80, 108), spin=0.4),
        _cc_case(rng, "RGB uint8, 4 × 3 board, sigma = 1.2", 4, 3, kwargs={"sigma": 1.2}, size=(72, 96), color=True,
                 dtype="uint8"),
    ]


def _cc_hidden(rng):
    nothing = np.full((40, 50), 0.5) + rng.normal(0, 0.01, (40, 50))
    return [
        *(_cc_case(rng, label, cols, rows, **board) for label, cols, rows, board in _BOARDS),
        _cc_case(rng, "square 4 × 4 board, sigma = 1.2", 4, 4, kwargs={"sigma": 1.2}, spin=0.3),
        _cc_case(rng, "values in [-200, 800], more noise", 5, 4, dtype="scaled", noise=0.015),
        _cc_case(rng, "strong barrel distortion", 5, 4, k=(-0.3, 0.05)),
        _cc_case(rng, "count smaller than the board", 4, 3, count=int(rng.integers(6, 10))),
        TruthCase((nothing, 12), {}, "no board at all (noise)", truth=(np.zeros((0, 2)), np.zeros((0, 2, 2)))),
    ]


corner_candidates = Check(
    public=_cc_public,
    hidden=_cc_hidden,
    compare=CandidatesClose(radius=1.5, degrees=15.0, lead=3),
    mistakes=[_cc_swapped, _cc_no_ring_test, _cc_eigenvectors, _cc_window_corner],
    allowed=("calibration.chessboard_response", "filters.gaussian", "filters.correlate", "filters.convolve",
             "warp.bilinear_sample"),
)


@dataclass
class TruthCase(Case):
    """A case that also carries what it was drawn from (``truth``): the comparator judges an
    answer by what it is for, not by the reference's way of finding it. The truth never
    reaches the candidate, which is called with ``args`` and ``kwargs`` only."""

    truth: Any = None


# calibration.order_grid_corners --------------------------------------------------------------
def _grid_points(rng, board, noise=0.03, spin=0.5):
    """Image points (rows, cols, 2) of a board seen by a random camera, and their edge directions."""
    bc, br = board
    A = _camera(rng, size=(120, 160))
    for _ in range(100):
        R = _rotation_matrix(rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-spin, spin))
        depth = A[0, 0] * max(bc, br) * 10.0 / (160 * rng.uniform(0.5, 0.75))
        centre = np.array([(bc - 1) * 5.0, (br - 1) * 5.0, 0.0])
        t = np.array([rng.uniform(-0.08, 0.08) * depth, rng.uniform(-0.06, 0.06) * depth, depth]) - R @ centre
        m = _project_full(_chessboard_points(bc, br, 10.0), A, R, t, (0.0, 0.0)).reshape(br, bc, 2)
        if m.min() >= 6 and m[..., 0].max() <= 154 and m[..., 1].max() <= 114:
            break
    along = np.gradient(m, axis=1)
    down = np.gradient(m, axis=0)
    dirs = np.stack([along, down], axis=2)                                # (rows, cols, 2, 2)
    dirs = dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)
    m = m + rng.normal(0.0, noise, m.shape)
    return np.round(m, 3), dirs


def _grid_case(rng, label, board, ask=None, strays=3, stuck=False, missing=False, square=False, flip_seed=False,
               truth=False):
    """A case for order_grid_corners: a board's corners (shuffled, their two directions in either
    order and sign) with stray points. With ``truth=True`` it also returns, for every point of
    the case, its board position ``(row, col)``, or ``(-1, -1)`` for a stray, and the board's
    two unit directions ``(along a row, down a column)`` at each point."""
    m, dirs = _grid_points(rng, board, spin=2.0 if square else 0.5)
    br, bc = m.shape[:2]
    pts, ds = m.reshape(-1, 2), dirs.reshape(-1, 2, 2)
    where = np.stack(np.meshgrid(np.arange(br), np.arange(bc), indexing="ij"), -1).reshape(-1, 2)
    if missing:
        k = int((br // 2) * bc + bc // 2)                                 # an interior corner
        pts, ds = np.delete(pts, k, axis=0), np.delete(ds, k, axis=0)
        where = np.delete(where, k, axis=0)
    true_dirs = ds.copy()
    extra_pts, extra_dirs = [], []
    lo, hi = pts.min(axis=0) - 8, pts.max(axis=0) + 8
    # strays keep at least 0.45 of a step away from the board's corners and from the lattice's
    # next ring around it: nearer, which point is the corner would be a matter of taste
    wide = np.concatenate([2 * m[:, :1] - m[:, 1:2], m, 2 * m[:, -1:] - m[:, -2:-1]], axis=1)
    ahead = np.concatenate([2 * wide[:1] - wide[1:2], wide, 2 * wide[-1:] - wide[-2:-1]], axis=0).reshape(-1, 2)
    step = float(np.median(np.hypot(*np.diff(m, axis=1).reshape(-1, 2).T)))
    for _ in range(strays):
        for _ in range(50):
            point = rng.uniform(lo, hi)
            if np.hypot(*(ahead - point).T).min() >= 0.45 * step:
                break
        extra_pts.append(point)
        a = rng.uniform(0, np.pi)
        extra_dirs.append([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    if stuck:                                                             # one step beyond the end of a row
        r = int(rng.integers(0, br))
        extra_pts.append(2 * m[r, -1] - m[r, -2] + rng.normal(0, 0.2, 2))
        extra_dirs.append(dirs[r, -1])
    order = rng.permutation(len(pts))
    pts, ds, where, true_dirs = pts[order], ds[order], where[order], true_dirs[order]
    signs = rng.choice([-1.0, 1.0], (len(ds), 2, 1))
    ds = np.where(rng.random(len(ds))[:, None, None] < 0.5, ds, ds[:, ::-1]) * signs
    if extra_pts:
        stray_where = np.full((len(extra_pts), 2), -1)
        stray_dirs = np.asarray(extra_dirs, dtype=np.float64)
        if flip_seed:
            pts, ds = np.vstack([pts[:5], extra_pts, pts[5:]]), np.vstack([ds[:5], extra_dirs, ds[5:]])
            where = np.vstack([where[:5], stray_where, where[5:]])
            true_dirs = np.vstack([true_dirs[:5], stray_dirs, true_dirs[5:]])
        else:
            pts, ds = np.vstack([pts, extra_pts]), np.vstack([ds, extra_dirs])
            where, true_dirs = np.vstack([where, stray_where]), np.vstack([true_dirs, stray_dirs])
    cols, rows = ask if ask is not None else board
    case = Case((np.round(pts, 3), np.round(ds, 6), cols, rows), {}, label)
    return (case, where, true_dirs) if truth else case


# calibration.grow_grid -----------------------------------------------------------------------
@dataclass
class GridEqual(Comparator):
    """The nodes ``(i, j, k)`` of a grid grown from a seed.

    On a case drawn from a known board (a :class:`TruthCase`), by what the grid is for: the
    labels ``(i, j)`` are exactly the board's corners, counted in steps from the seed along
    ``d1`` and ``d2``, and each node's candidate ``k`` lies within ``tolerance`` × the board's
    step of the corner its label names (a stray dropped on top of a corner may stand for it);
    None for a lone seed; anything well formed for a seed that is not a corner of the board.
    Any correct method passes, whatever its thresholds. Against an output that is itself wrong
    (a mistake of the bank, to recognise it) and on cases without a truth: the same rows as that
    output, exactly."""

    tolerance: float = 0.25

    def describe(self) -> str:
        return "the board's corners, each labelled (i, j) by its steps from the seed along d1 and d2"

    def _rows(self, got):
        """(rows as a set, None) or (None, Mismatch) for a malformed output."""
        try:
            arr = np.asarray(got)
            rows = arr.astype(np.int64)
        except (TypeError, ValueError) as exc:
            return None, Mismatch(f"your output could not be turned into an integer array ({exc})")
        if arr.ndim != 2 or arr.shape[1:] != (3,):
            return None, Mismatch(f"expected an (N, 3) array of rows (i, j, candidate index), got shape {arr.shape}")
        if arr.dtype.kind == "f" and not np.array_equal(arr, rows):
            return None, Mismatch("your rows (i, j, candidate index) are not whole numbers")
        mine = {tuple(int(v) for v in r) for r in rows}
        if len(mine) != len(rows):
            return None, Mismatch("some of your rows appear twice")
        return mine, None

    def judge(self, got, truth, case):
        """The verdict on ``got`` from the board the case was drawn from."""
        if isinstance(truth, str) and truth == "none":
            if got is None:
                return None
            return Mismatch("expected None: the seed is a lone point, with no other candidate anywhere near "
                            "its two edge directions")
        if got is None:
            if isinstance(truth, str):
                return None
            return Mismatch(f"you returned None, but the seed is a corner of a board of {len(truth[0])} corners")
        mine, problem = self._rows(got)
        if problem is not None or isinstance(truth, str):
            return problem
        labels, positions, step = truth
        points = np.asarray(case.args[0], dtype=np.float64).reshape(-1, 2)
        wanted = {(int(i), int(j)): p for (i, j), p in zip(labels, positions)}
        have = {(i, j) for i, j, _ in mine}
        missing, extra = sorted(set(wanted) - have), sorted(have - set(wanted))
        if missing or extra:
            parts = []
            if missing:
                parts.append(f"{len(missing)} corner(s) of the board missing, e.g. (i, j) = {missing[0]}")
            if extra:
                parts.append(f"{len(extra)} label(s) that are not corners of the board, e.g. (i, j) = {extra[0]}")
            return Mismatch(f"Not the board's grid ({len(mine)} nodes yours, {len(wanted)} corners): "
                            + "; ".join(parts), mismatched=len(missing) + len(extra), total=len(wanted))
        if len({k for _, _, k in mine}) != len(mine):
            return Mismatch("one candidate appears under two labels")
        for i, j, k in sorted(mine):
            if not 0 <= k < len(points):
                return Mismatch(f"node ({i}, {j}) names candidate {k}, but there are {len(points)} candidates")
            gap = float(np.hypot(*(points[k] - wanted[(i, j)])))
            if gap > self.tolerance * step:
                return Mismatch(f"node (i, j) = ({i}, {j}) is candidate {k} at ({points[k][0]:.4g}, {points[k][1]:.4g}), "
                                f"but the corner {i} steps along d1 and {j} along d2 from the seed is at "
                                f"({wanted[(i, j)][0]:.4g}, {wanted[(i, j)][1]:.4g}) ({gap / step:.2g} of a step away)",
                                mismatched=1, total=len(wanted))
        return None

    def __call__(self, got, expected, case=None):
        truth = getattr(case, "truth", None)
        if truth is not None and self.judge(expected, truth, case) is None:
            return self.judge(got, truth, case)
        return self._same(got, expected)

    def _same(self, got, expected):
        if expected is None:
            if got is None:
                return None
            return Mismatch("expected None: this seed has no first neighbour along one of its two directions")
        exp = np.asarray(expected, dtype=np.int64).reshape(-1, 3)
        if got is None:
            return Mismatch(f"you returned None, but this seed grows a grid of {len(exp)} nodes")
        mine, problem = self._rows(got)
        if problem is not None:
            return problem
        theirs = {tuple(int(v) for v in r) for r in exp}
        if mine == theirs:
            return None
        missing, extra = sorted(theirs - mine), sorted(mine - theirs)
        parts = []
        if missing:
            parts.append(f"{len(missing)} expected node(s) missing, e.g. (i, j, k) = {missing[0]}")
        if extra:
            parts.append(f"{len(extra)} node(s) not expected, e.g. (i, j, k) = {extra[0]}")
        return Mismatch(f"Not the same grid ({len(mine)} nodes yours, {len(theirs)} expected): " + "; ".join(parts),
                        mismatched=len(missing) + len(extra), total=len(theirs))


def _gg_relabelled(points, directions, seed=0, swap=False, negate=False):
    rows = _grow_grid_reference(points, directions, seed)
    if rows is None:
        return None
    rows = rows.copy()
    if swap:
        rows[:, [0, 1]] = rows[:, [1, 0]]
    if negate:
        rows[:, :2] *= -1
    return rows[np.lexsort((rows[:, 1], rows[:, 0]))]


def _gg_variant(points, directions, seed=0, **options):
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    dirs = np.asarray(directions, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        dirs = dirs / np.linalg.norm(dirs, axis=2, keepdims=True)
    grid = _grow_grid(int(seed), pts, dirs, **options)
    return None if grid is None else _grid_rows(grid)


_gg_swapped = variant(_gg_relabelled, swap=True)
_gg_negated = variant(_gg_relabelled, negate=True)
_gg_no_pruning = variant(_gg_variant, prune=False)
_gg_lines_only = variant(_gg_variant, parallelogram=False)


def _gg_case(rng, label, board, seed="board", scale=False, as_list=False, **options):
    """:func:`_gg_draw`, drawn again (up to 30 times) until the grid does not depend on the order
    in which the nodes are visited (last-in-first-out, first-in-first-out and random orders of
    growth agree) and the reference finds the board (a stray dropped next to a corner can make
    a case ambiguous or mislead a greedy growth: such draws are not used)."""
    for _ in range(30):
        case = _gg_draw(rng, label, board, seed, scale, as_list, **options)
        if _gg_order_free(*case.args) and GridEqual().judge(_grow_grid_reference(*case.args), case.truth, case) is None:
            break
    return case


def _gg_order_free(points, directions, seed):
    pts = np.asarray(points, dtype=np.float64)
    dirs = np.asarray(directions, dtype=np.float64)
    dirs = dirs / np.linalg.norm(dirs, axis=2, keepdims=True)
    shuffle = np.random.default_rng(8)
    orders = [lambda n: 0] + [lambda n: int(shuffle.integers(n)) for _ in range(4)]
    grid = _grow_grid(seed, pts, dirs)
    return all(_grow_grid(seed, pts, dirs, visit=order) == grid for order in orders)


def _gg_draw(rng, label, board, seed="board", scale=False, as_list=False, **options):
    """A case of :func:`_grid_case` with a seed (a candidate's index): a random board corner
    ('board'), the board corner farthest from the centre ('edge'), the first stray ('stray') or a
    lone point added away from the board, which has no neighbours ('far')."""
    case, where, true_dirs = _grid_case(rng, label, board, truth=True, **options)
    points, directions, _, _ = case.args
    n_board = board[0] * board[1] - (1 if options.get("missing") else 0)
    n_extra = len(points) - n_board
    first = 5 if options.get("flip_seed") else n_board                   # where the strays start
    on_board = [k for k in range(len(points)) if not first <= k < first + n_extra]
    if seed == "stray":
        index = first
    elif seed == "edge":                                                  # the board point farthest out
        centre = points[on_board].mean(axis=0)
        index = max(on_board, key=lambda k: float(np.hypot(*(points[k] - centre))))
    else:
        index = int(rng.choice(on_board))
    if seed == "far":                    # a lone point below-right of the board, edges at ±45°: None
        corner = points.max(axis=0) + rng.uniform(35.0, 45.0, 2)
        points = np.vstack([points, np.round(corner, 3)])
        directions = np.vstack([directions, np.round([[[0.7071068, 0.7071068], [0.7071068, -0.7071068]]], 6)])
        index = len(points) - 1
    if scale:
        directions = np.round(directions * rng.uniform(0.2, 5.0, (len(directions), 2, 1)), 6)
    truth = _true_grid(points, directions, int(index), where, true_dirs)
    if as_list:
        points, directions = points.tolist(), directions.tolist()
    return TruthCase((points, directions, int(index)), {}, label, truth=truth)


def _true_grid(points, directions, seed, where, true_dirs):
    """What grow_grid is for, from what the case was drawn from: ``(labels (N, 2), positions
    (N, 2), step)`` — every corner of the board labelled by its steps ``(i, j)`` from the seed
    along the seed's two directions, the corner's position and the smallest distance between
    neighbouring corners; ``"none"`` for a lone point (no neighbours: the answer is None) and
    ``"any"`` for a seed that is not a corner of the board (a stray: not graded)."""
    if seed >= len(where):
        return "none"
    if where[seed][0] < 0:
        return "any"
    d1, d2 = np.asarray(directions[seed], dtype=np.float64)
    along, down = true_dirs[seed]
    if abs(d1 @ along) > abs(d1 @ down):                                 # i counts columns, j rows
        axes, signs = (1, 0), (np.sign(d1 @ along), np.sign(d2 @ down))
    else:
        axes, signs = (0, 1), (np.sign(d1 @ down), np.sign(d2 @ along))
    board = [k for k, rc in enumerate(where) if rc[0] >= 0]
    labels = np.array([[signs[0] * (where[k][axes[0]] - where[seed][axes[0]]),
                        signs[1] * (where[k][axes[1]] - where[seed][axes[1]])] for k in board], dtype=np.int64)
    positions = np.asarray(points, dtype=np.float64)[board]
    gaps = np.hypot(*(positions[:, None] - positions[None]).transpose(2, 0, 1))
    steps = [gaps[a, b] for a in range(len(board)) for b in range(len(board))
             if np.abs(labels[a] - labels[b]).sum() == 1]
    return labels, positions, float(min(steps))


def _gg_public():
    rng = np.random.default_rng(80314)
    return [
        _gg_case(rng, "a 5 × 4 grid with strays (one stuck to a row's end), seed on the board", (5, 4),
                 strays=3, stuck=True),
        _gg_case(rng, "a square 4 × 4 grid turned by up to 115°, seed at an outer corner, directions not unit",
                 (4, 4), square=True, seed="edge", scale=True),
        _gg_case(rng, "seed on a stray point among the board's corners", (4, 3), strays=2, seed="stray"),
        _gg_case(rng, "seed on a lone point away from the board: None", (4, 3), strays=0, seed="far"),
    ]


def _gg_hidden(rng):
    return [
        _gg_case(rng, "5 × 4 grid with strays", (5, 4)),
        _gg_case(rng, "6 × 4 grid, a stray stuck to a row", (6, 4), stuck=True),
        _gg_case(rng, "4 × 3 grid, no strays, seed at an outer corner", (4, 3), strays=0, seed="edge"),
        _gg_case(rng, "3 × 5 grid, a stray stuck to a row, directions not unit", (3, 5), stuck=True, scale=True),
        _gg_case(rng, "square 4 × 4 grid, any turn", (4, 4), square=True),
        _gg_case(rng, "square 3 × 3 grid, strays first, lists", (3, 3), square=True, flip_seed=True,
                 as_list=True),
        _gg_case(rng, "an interior corner missing", (5, 4), missing=True, stuck=True),
        _gg_case(rng, "7 × 5 grid, many strays", (7, 5), strays=8, stuck=True),
        _gg_case(rng, "seed on a stray point", (5, 4), strays=3, seed="stray"),
        _gg_case(rng, "6 × 5 grid, seed at an outer corner", (6, 5), seed="edge", stuck=True),
        _gg_case(rng, "a lone point away from the board: None", (5, 3), seed="far"),
    ]


grow_grid = Check(
    public=_gg_public,
    hidden=_gg_hidden,
    compare=GridEqual(),
    mistakes=[
        Mistake("i and j swapped (i along the second direction)", _gg_swapped,
                "i counts steps along directions[seed][0], j along directions[seed][1]: the first neighbour along "
                "+d1 is node (1, 0)"),
        Mistake("steps counted against the directions (signs flipped)", _gg_negated,
                "Node (1, 0) is the neighbour on the side directions[seed][0] points to (positive projection), "
                "node (-1, 0) the one on the other side"),
        Mistake("no pruning of nodes with a single neighbour", _gg_no_pruning,
                "After growing, remove the nodes with at most one neighbour in the grid, repeatedly: a stray "
                "candidate stuck to the end of a row is not a corner of the board"),
        Mistake("lines only (no parallelogram completion)", _gg_lines_only,
                "Where no node lies behind `here`, predict the next node by completing a parallelogram: "
                "here + diagonal − side; continuing lines alone only grows the cross through the seed"),
    ],
)


@mistake("column by column (x and y of the board swapped)",
         "Corner r·cols + c: go along the side with `cols` corners first (x), then down the `rows` side")
def _og_column_major(points, directions, cols, rows):
    corners = _order_grid_corners(points, directions, cols, rows)
    return None if corners is None else corners.reshape(rows, cols, 2).transpose(1, 0, 2).reshape(-1, 2)


@mistake("left-handed order (mirror image of the board)",
         "The board's x and y axes must turn like the image's (x right, y down): choose the origin and the "
         "directions so that cross(x direction, y direction) > 0")
def _og_left_handed(points, directions, cols, rows):
    corners = _order_grid_corners(points, directions, cols, rows)
    return None if corners is None else corners.reshape(rows, cols, 2)[::-1].reshape(-1, 2)


@mistake("a larger board accepted (grid size not checked)",
         "Return None unless the grid you grow is exactly cols × rows corners: a board with more corners is "
         "another board")
def _og_bigger_board(points, directions, cols, rows):
    corners = _order_grid_corners(points, directions, cols, rows)
    if corners is not None:
        return corners
    for c, r in ((cols + 1, rows), (cols, rows + 1), (cols + 1, rows + 1), (cols + 2, rows), (cols, rows + 2)):
        bigger = _order_grid_corners(points, directions, c, r)
        if bigger is not None:
            return bigger.reshape(r, c, 2)[:rows, :cols].reshape(-1, 2)
    return None


@mistake("x along the side with `rows` corners",
         "The board's x axis runs along the side that has `cols` corners (corner r·cols + c is in row r): "
         "count the corners of each side of your grid and pick the base accordingly")
def _og_sides_swapped(points, directions, cols, rows):
    return _order_grid_corners(points, directions, rows, cols)


@mistake("origin not the corner nearest the top-left",
         "Of the admissible orders (x along `cols`, right-handed), take the one whose first corner is "
         "nearest the pixel (0, 0): on a square board the four 90° turns are all admissible")
def _og_first_origin(points, directions, cols, rows):
    corners = _order_grid_corners(points, directions, cols, rows)
    if corners is None or cols != rows:
        return corners
    G = corners.reshape(rows, cols, 2)
    return G.transpose(1, 0, 2)[::-1].reshape(-1, 2)                    # a right-handed 90° turn of it


def _og_public():
    rng = np.random.default_rng(80312)
    return [
        _grid_case(rng, "a 5 × 4 grid, shuffled, with stray points (one stuck to a row's end)", (5, 4),
                   strays=3, stuck=True),
        _grid_case(rng, "a square 4 × 4 grid turned by up to 115°, a stray among the first points", (4, 4), square=True,
                   flip_seed=True),
        _grid_case(rng, "a 6 × 4 grid, asked for 5 × 4: None", (6, 4), ask=(5, 4)),
    ]


def _og_hidden(rng):
    return [
        _grid_case(rng, "5 × 4 grid with strays", (5, 4)),
        _grid_case(rng, "6 × 4 grid, a stray stuck to a row", (6, 4), stuck=True),
        _grid_case(rng, "4 × 3 grid, no strays", (4, 3), strays=0),
        _grid_case(rng, "3 × 5 grid (taller than wide)", (3, 5)),
        _grid_case(rng, "square 4 × 4 grid, any turn", (4, 4), square=True),
        _grid_case(rng, "square 3 × 3 grid, any turn, strays first", (3, 3), square=True, flip_seed=True),
        _grid_case(rng, "5 × 4 grid asked as 4 × 5", (5, 4), ask=(4, 5)),
        _grid_case(rng, "6 × 5 grid asked for 5 × 5: None", (6, 5), ask=(5, 5)),
        _grid_case(rng, "5 × 4 grid asked for 4 × 4: None", (5, 4), ask=(4, 4), stuck=True),
        _grid_case(rng, "an interior corner missing: None", (5, 4), missing=True),
        _grid_case(rng, "7 × 5 grid, many strays", (7, 5), strays=8, stuck=True),
    ]


order_grid_corners = Check(
    public=_og_public,
    hidden=_og_hidden,
    compare=CornersClose(mean=1e-6, maximum=1e-6),
    mistakes=[_og_column_major, _og_left_handed, _og_bigger_board, _og_sides_swapped,
              _og_first_origin],    allowed=("calibration.grow_grid",),
)


# calibration.refine_corners ------------------------------------------------------------------
def _rc_newton(image, corners, sigma, iterations=10, damp=0.5, max_shift=1.5, smooth=True):
    img = np.asarray(image, dtype=np.float64)
    grey = _grey01(img @ _LUMA if img.ndim == 3 else img)
    S = _gaussian(grey, float(sigma)) if smooth else grey
    first, second = _derivatives(S)
    start = np.asarray(corners, dtype=np.float64)
    q = start.copy()
    ok = np.ones(len(q), dtype=bool)
    for _ in range(iterations):
        g = _bilinear(first, q[:, 0], q[:, 1], fill=np.nan)
        h = _bilinear(second, q[:, 0], q[:, 1], fill=np.nan)
        a, b, c = h[:, 0], h[:, 1], h[:, 2]
        det = a * c - b * b
        saddle = det < 0
        with np.errstate(divide="ignore", invalid="ignore"):
            dx = np.where(saddle, (c * g[:, 0] - b * g[:, 1]) / det, 0.0)
            dy = np.where(saddle, (a * g[:, 1] - b * g[:, 0]) / det, 0.0)
        step = np.hypot(dx, dy)
        scale = np.where(step > damp, damp / np.maximum(step, 1e-300), 1.0) if damp else 1.0
        q[:, 0] -= dx * scale
        q[:, 1] -= dy * scale
        ok &= saddle
    if max_shift:
        ok &= np.hypot(*(q - start).T) <= max_shift
    return np.where(ok[:, None], q, start)


@mistake("no refinement (the start returned)",
         "Move each point to the saddle of the smoothed image: Newton steps q ← q − H⁻¹∇S with the "
         "derivatives interpolated at q")
def _rc_identity(image, corners, sigma):
    return np.array(corners, dtype=np.float64)


_rc_one_step = variant(_rc_newton, iterations=1)
_rc_not_smoothed = variant(_rc_newton, smooth=False)
_rc_no_shift_limit = variant(_rc_newton, max_shift=None)


def _rc_case(rng, label, cols, rows, sigma, offset=0.6, odd=0, **board):
    """A rendered board, starts near its corners (and ``odd`` starts 2.2 px from a corner along an
    edge), and the truth: for every start, the corner the renderer drew there, or the start
    itself for the far ones (they must come back unchanged)."""
    image, corners, _ = _board_image(rng, cols, rows, truth=True, **board)
    points, directions = _corner_candidates(image, cols * rows)
    points = points[:cols * rows]
    for _ in range(10):              # starts from which the reference reaches every corner (nearly always the first)
        start = np.round(points + rng.uniform(-offset, offset, points.shape), 2)
        reached = _refine_corners_reference(image, start, sigma)
        if np.hypot(*(reached - corners[np.hypot(*(points[:, None, :] - corners[None]).transpose(2, 0, 1))
                                        .argmin(axis=1)]).T).max() <= 0.2:
            break
    nearest = np.hypot(*(points[:, None, :] - corners[None]).transpose(2, 0, 1)).argmin(axis=1)
    targets, moved = corners[nearest], np.ones(len(start), dtype=bool)
    if odd:                          # points 2.2 px from a corner along an edge: they converge too far to count
        far = points[:odd] + 2.2 * directions[:odd, 0] * rng.choice([-1.0, 1.0], (odd, 1))
        start = np.vstack([start, np.round(far, 2)])
        targets, moved = np.vstack([targets, start[-odd:]]), np.concatenate([moved, np.zeros(odd, dtype=bool)])
    return TruthCase((image, start, sigma), {}, label, truth=(targets, moved))


@dataclass
class RefinedClose(PointsClose):
    """Refined corners. On a rendered board (a :class:`TruthCase`), by what they are for: the
    starts near a corner end within ``true_mean`` px of the corners the renderer drew on average
    and ``true_max`` px each; the starts too far from a corner come back unchanged. Any correct
    sub-pixel method passes. Against an output that is itself wrong (a mistake of the bank, to
    recognise it) and without a truth: within ``mean`` / ``maximum`` px of that output."""

    true_mean: float = 0.15
    true_max: float = 0.4

    def describe(self) -> str:
        return (f"within {self.true_mean:g} px of the true corners on average and {self.true_max:g} px each; "
                "far starts unchanged")

    def judge(self, got, case):
        pts, problem = as_float_array(got, shape=np.shape(case.args[1]), layout=self.layout, nonfinite=self.nonfinite)
        if problem is not None:
            return Mismatch(problem)
        targets, moved = case.truth
        start = np.asarray(case.args[1], dtype=np.float64)
        stay = np.flatnonzero(~moved)
        if len(stay):
            shift = np.hypot(*(pts[stay] - start[stay]).T)
            if shift.max() > 1e-6:
                k = int(stay[np.argmax(shift)])
                return Mismatch(f"the start ({start[k, 0]:.4g}, {start[k, 1]:.4g}) lies 2.2 px from a corner along an "
                                f"edge: it does not start at a corner and must come back unchanged, yours moved it "
                                f"{shift.max():.3g} px", mismatched=int(np.count_nonzero(shift > 1e-6)), total=len(stay))
        d = np.hypot(*(pts[moved] - targets[moved]).T)
        return _distances_mismatch(d, pts[moved], targets[moved], self.true_mean, self.true_max,
                                   ("Corners", "corner", 5), self.true_max)

    def __call__(self, got, expected, case=None):
        if getattr(case, "truth", None) is not None and self.judge(expected, case) is None:
            return self.judge(got, case)
        return super().__call__(got, expected, case)


def _rc_public():
    rng = np.random.default_rng(80313)
    return [
        _rc_case(rng, "grey 5 × 4 board, corners up to 0.6 px off, 4 points 2.2 px away, sigma = 1.5", 5, 4, 1.5,
                 odd=4),
        _rc_case(rng, "RGB uint8 4 × 3 board, sigma = 1.0", 4, 3, 1.0, color=True, dtype="uint8"),
    ]


def _rc_hidden(rng):
    return [
        _rc_case(rng, "grey board, sigma = 1.5", 5, 4, 1.5),
        _rc_case(rng, "sigma = 1", 4, 3, 1.0, offset=0.4),
        _rc_case(rng, "large sigma", 4, 4, _u(rng, 2.0, 2.5, 2), size=(120, 160), square_fill=(0.8, 0.9)),
        _rc_case(rng, "RGB float image", 5, 4, 1.5, color=True),
        _rc_case(rng, "uint8 image", 4, 3, 1.25, dtype="uint8"),
        _rc_case(rng, "values in [-200, 800]", 5, 4, 1.5, dtype="scaled"),
        _rc_case(rng, "points 2.2 px from a corner (too far: kept)", 5, 4, 1.5, odd=3),
        _rc_case(rng, "barrel distortion, strong tilt", 5, 4, 1.5, k=(-0.3, 0.05), tilt=0.6),
        _rc_case(rng, "starts up to 0.8 px off, points 2.2 px away", 4, 3, 1.5, offset=0.8, odd=3),
    ]


refine_corners = Check(
    public=_rc_public,
    hidden=_rc_hidden,
    compare=RefinedClose(mean=0.01, maximum=0.05, true_mean=0.15, true_max=0.4),
    mistakes=[
        _rc_identity,
        Mistake("a single Newton step", _rc_one_step,
                "One step is not enough from a pixel away (and steps are shortened to 0.5 px): iterate 10 times"),
        Mistake("derivatives of the unsmoothed image", _rc_not_smoothed,
                "Take the derivatives of S = filters.gaussian(grey, sigma): on the raw image the saddle is "
                "not defined between the pixels of an edge"),
        Mistake("no 1.5 px limit (a far start may end on the corner)", _rc_no_shift_limit,
                "A point that ends more than 1.5 px from its start (or leaves the saddle) did not start at a corner: "
                "return its start unchanged"),
    ],
    allowed=("filters.gaussian", "filters.correlate", "filters.convolve", "warp.bilinear_sample"),
)


# --------------------------------------------------------------------------------------------
# calibration.homography_dlt (§8.3.2)
# --------------------------------------------------------------------------------------------
def _dlt_parts(src, dst):
    s = np.asarray(src, dtype=np.float64)
    d = np.asarray(dst, dtype=np.float64)
    return s, d, hartley_normalization(s), hartley_normalization(d)


@mistake("no Hartley normalisation",
         "With normalize=True translate each point set to its centroid and scale it to mean distance √2 "
         "(T, T′), solve the DLT there and return T′⁻¹·H̃·T: raw pixels in the thousands make L "
         "ill-conditioned")
def _hd_not_normalized(src, dst, normalize=True):
    return _homography_dlt(src, dst, normalize=False)


@mistake("normalize=False ignored (always normalised)", "With normalize=False solve the DLT on the raw coordinates")
def _hd_always_normalized(src, dst, normalize=True):
    return _homography_dlt(src, dst, normalize=True)


@mistake("H inverted (maps dst to src)",
         "Build the equations of m̃ × H w̃ = 0 with w = src and m = dst: H maps src to dst")
def _hd_inverted(src, dst, normalize=True):
    return _homography_dlt(dst, src, normalize=normalize)


def _hd_normalized_solve(src, dst, normalize, undo, one_normalization=False):
    """The DLT solved between the Hartley-normalised sets (``dst`` normalised with the ``src``'s
    T when ``one_normalization``), H̃ mapped back by ``undo(H̃, Ts, Td)``; the plain DLT
    when not ``normalize``."""
    s, d, Ts, Td = _dlt_parts(src, dst)
    if not normalize:
        return _homography_dlt(src, dst, normalize=False)
    if one_normalization:
        Td = Ts
    h = _null_vector(_dlt_matrix(_apply(Ts, s), _apply(Td, d)))[1]
    return _scaled(undo(h.reshape(3, 3), Ts, Td))


@mistake("normalisation not undone (H̃ returned)",
         "The SVD gives the homography between the *normalised* sets: return T′⁻¹·H̃·T")
def _hd_not_denormalized(src, dst, normalize=True):
    return _hd_normalized_solve(src, dst, normalize, lambda H, Ts, Td: H)


@mistake("normalisation undone the wrong way (T′·H̃·T⁻¹)", "dst_n = T′·dst and src_n = T·src, so H = T′⁻¹·H̃·T")
def _hd_denormalized_backwards(src, dst, normalize=True):
    return _hd_normalized_solve(src, dst, normalize, lambda H, Ts, Td: Td @ H @ np.linalg.inv(Ts))


@mistake("one normalisation used for both point sets",
         "Normalise src and dst separately (each with its own centroid and scale)")
def _hd_one_normalization(src, dst, normalize=True):
    return _hd_normalized_solve(src, dst, normalize, lambda H, Ts, Td: np.linalg.inv(Td) @ H @ Ts,
                                one_normalization=True)


def _hd_svd_variant(src, dst, normalize, pick):
    s, d, Ts, Td = _dlt_parts(src, dst)
    if normalize:
        L = _dlt_matrix(_apply(Ts, s), _apply(Td, d))
    else:
        L = _dlt_matrix(s, d)
    _, _, Vt = np.linalg.svd(L, full_matrices=pick == "vt_column")
    h = {"first": Vt[0], "vt_column": Vt[:, -1], "economy": Vt[-1]}[pick]
    H = h.reshape(3, 3)
    if normalize:
        H = np.linalg.inv(Td) @ H @ Ts
    return _scaled(H)


@mistake("largest singular vector (Vt[0]) taken",
         "The solution is the right singular vector of the *smallest* singular value: the last row Vt[-1]")
def _hd_largest(src, dst, normalize=True):
    return _hd_svd_variant(src, dst, normalize, "first")


@mistake("column of Vᵀ taken (Vt[:, -1])",
         "np.linalg.svd returns Vᵀ: its rows are the singular vectors, so take the row Vt[-1], not a column")
def _hd_vt_column(src, dst, normalize=True):
    return _hd_svd_variant(src, dst, normalize, "vt_column")


@mistake("economy SVD with 4 points (null vector missing)",
         "With 4 points L is 8×9: np.linalg.svd(L, full_matrices=False) returns only 8 rows of Vᵀ; use the "
         "full SVD (or pad L with a row of zeros) and take the 9th")
def _hd_economy(src, dst, normalize=True):
    return _hd_svd_variant(src, dst, normalize, "economy")


@mistake("not scaled to H[2, 2] = 1", "The SVD gives ‖h‖ = 1; divide H by H[2, 2] before returning it")
def _hd_unit_norm(src, dst, normalize=True):
    H = _homography_dlt(src, dst, normalize=normalize)
    return H / np.linalg.norm(H)


def _hd_public():
    rng = np.random.default_rng(80302)
    square = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 80.0], [0.0, 80.0]])
    quad = np.array([[210.0, 140.0], [520.0, 180.0], [490.0, 420.0], [180.0, 390.0]])
    H_far = _perspective_homography(rng, scale=1.0, offset=(4000.0, 3000.0))
    src_far, dst_far = _pairs(rng, 8, H_far, noise=2.0, spread=60.0)
    H_mid = _perspective_homography(rng)
    src_mid, dst_mid = _pairs(rng, 7, H_mid, noise=3.0)
    return [
        Case((square, quad), {}, "4 exact pairs (a rectangle to a quadrilateral)"),
        Case((src_far, dst_far), {}, "8 noisy pairs, pixels clustered around (4000, 3000)"),
        Case((src_mid, dst_mid), {"normalize": False}, "7 noisy pairs, normalize=False"),
    ]


def _hd_hidden(rng):
    def far_case(n, noise, label, **kwargs):
        H = _perspective_homography(rng, scale=_u(rng, 0.5, 2.0), offset=(_u(rng, 2000, 9000), _u(rng, 2000, 9000)))
        src, dst = _pairs(rng, n, H, noise=noise, spread=_u(rng, 40, 80))
        return Case((src, dst), kwargs, label)

    H1 = _perspective_homography(rng)
    src4, dst4 = _pairs(rng, 4, H1, 0.0)
    H2 = _perspective_homography(rng)
    src_n, dst_n = _pairs(rng, int(rng.integers(10, 16)), H2, 0.0)
    H3 = _perspective_homography(rng)
    src_i, dst_i = _pairs(rng, 9, H3, 0.0)
    H4 = _perspective_homography(rng)
    src_u, dst_u = _pairs(rng, int(rng.integers(6, 10)), H4, _u(rng, 2.0, 4.0))
    H5 = _perspective_homography(rng)
    src_l, dst_l = _pairs(rng, 5, H5, 0.5)
    H6 = _perspective_homography(rng, scale=0.01)
    src_s, dst_s = _pairs(rng, 6, H6, 0.0, spread=1.0)
    return [
        Case((src4, dst4), {}, "4 exact pairs"),
        Case((src4 + _u(rng, -50, 50), dst4), {"normalize": False}, "4 exact pairs, normalize=False"),
        Case((src_n, dst_n), {}, "10-15 exact pairs"),
        far_case(int(rng.integers(6, 10)), _u(rng, 1.5, 3.0), "noisy pairs, pixels clustered in the thousands"),
        far_case(int(rng.integers(10, 20)), _u(rng, 1.0, 2.0), "more noisy clustered pairs, normalize=True",
                 normalize=True),
        far_case(int(rng.integers(5, 8)), _u(rng, 2.0, 4.0), "few noisy clustered pairs"),
        Case((src_u, dst_u), {"normalize": False}, "noisy pairs, normalize=False"),
        Case((np.round(src_i).astype(np.int64), np.round(dst_i).astype(np.int64)), {}, "integer coordinates"),
        Case((src_l.tolist(), dst_l.tolist()), {}, "lists of 5 noisy pairs"),
        Case((src_s, dst_s * 100.0), {}, "pattern coordinates below 1 (metres)"),
        Case((-src_n, dst_n), {}, "negative pattern coordinates"),
    ]


homography_dlt = Check(
    rules=("integer",),
    public=_hd_public,
    hidden=_hd_hidden,
    compare=HomographyClose(atol=1e-4, rtol=1e-8),
    mistakes=[_hd_not_normalized, _hd_always_normalized, _hd_inverted, _hd_not_denormalized, _hd_denormalized_backwards,
              _hd_one_normalization, _hd_largest, _hd_vt_column, _hd_economy, _hd_unit_norm],
)


# --------------------------------------------------------------------------------------------
# calibration.levenberg_marquardt (§8.3.4)
# --------------------------------------------------------------------------------------------
def _lm_core(residuals, x0, jacobian=None, max_iter=100, tol=1e-10, damping=True, accept_uphill=False,
             inverted=False, sign=1.0, jacobian_once=False, full_cost=False):
    """The reference algorithm with switches that turn it into the bank's mistakes."""
    from ._optimize import _damped_step, _forward_jacobian, _normal_equations, _residual_vector, _trial_step

    x = np.asarray(x0, dtype=np.float64).ravel().copy()
    r = _residual_vector(residuals, x, "x0")

    def jac(point, res):
        return _forward_jacobian(residuals, point, res) if jacobian is None else np.asarray(jacobian(point.copy()), float)

    cost = 0.5 * float(r @ r)
    J = jac(x, r)
    g, JTJ = _normal_equations(J, r)
    mu = 1e-3 if damping else 0.0
    iterations = 0
    converged = bool(np.max(np.abs(g)) <= tol)
    with np.errstate(all="ignore"):
        while not converged and iterations < max_iter and mu <= 1e16:
            iterations += 1
            try:
                step = sign * _damped_step(JTJ, g, mu)
            except np.linalg.LinAlgError:
                if not damping:
                    break
                mu *= 10.0
                continue
            if not np.all(np.isfinite(step)):
                break
            tiny, trial, r_trial, cost_trial = _trial_step(residuals, x, step, r.size, tol)
            better = np.isfinite(cost_trial) and cost_trial < cost
            if better or accept_uphill or not damping:
                decrease = (cost - cost_trial) / cost if cost > 0 else 0.0
                x, r, cost = trial, r_trial, cost_trial
                if damping:
                    mu = mu * 10.0 if (inverted or not better) else max(mu / 10.0, 1e-15)
                if not np.isfinite(cost):
                    break
                if (better and decrease < tol) or tiny:
                    converged = True
                    break
                if not jacobian_once:
                    J = jac(x, r)
                g, JTJ = _normal_equations(J, r)
                if np.max(np.abs(g)) <= tol:
                    converged = True
            else:
                mu = mu / 10.0 if inverted else mu * 10.0
                if tiny:
                    converged = True
    if full_cost:
        cost = 2.0 * cost
    return x, {"iterations": iterations, "cost": float(cost), "converged": bool(converged)}


_lm_gauss_newton = variant(_lm_core, damping=False)
_lm_uphill = variant(_lm_core, accept_uphill=True)
_lm_inverted = variant(_lm_core, inverted=True)
_lm_wrong_sign = variant(_lm_core, sign=-1.0)
_lm_jacobian_once = variant(_lm_core, jacobian_once=True)
_lm_full_cost = variant(_lm_core, full_cost=True)


def _circle_problem(rng, n=None, noise=None):
    n = int(rng.integers(8, 14)) if n is None else n
    centre = rng.uniform(-5, 5, 2)
    radius = _u(rng, 2, 6)
    angle = rng.uniform(0, 2 * np.pi) + np.linspace(0, rng.uniform(3.5, 5.5), n)   # most of the circle
    noise = _u(rng, 0.05, 0.2) if noise is None else noise
    points = centre + radius * np.column_stack([np.cos(angle), np.sin(angle)]) + rng.normal(0, noise, (n, 2))
    start = np.concatenate([centre + rng.uniform(-0.3, 0.3, 2) * radius, [radius * _u(rng, 0.7, 1.3)]])
    return Residuals("circle", points=np.round(points, 4)), Jacobian("circle", points=np.round(points, 4)), np.round(start, 3)


def _exponential_problem(rng, far=False):
    t = np.linspace(0, 2, int(rng.integers(10, 16)))
    a, b, c = _u(rng, 1.5, 3.0), -_u(rng, 0.8, 2.0), _u(rng, 0.2, 1.0)
    y = a * np.exp(b * t) + c + rng.normal(0, 0.02, t.size)
    start = np.array([a, b, c]) * (np.array([2.5, 3.0, -1.0]) if far else 1 + rng.normal(0, 0.2, 3))
    return Residuals("exponential", t=t, y=np.round(y, 5)), Jacobian("exponential", t=t, y=np.round(y, 5)), np.round(start, 3)


def _arctan_problem(rng, n=3, distance=(2.0, 4.0)):
    c = np.round(rng.uniform(-2, 2, n), 3)
    start = c + rng.choice([-1.0, 1.0], n) * rng.uniform(*distance, n)
    return Residuals("arctan", c=c), Jacobian("arctan", c=c), np.round(start, 3)


def _projective_problem(rng):
    H = _perspective_homography(rng)
    H = H / H[2, 2]
    src = rng.uniform(0, 1, (int(rng.integers(6, 10)), 2))
    dst = _map(H, src * 200.0) + rng.normal(0, 1.0, (len(src), 2))
    Hn = H @ np.diag([200.0, 200.0, 1.0])                         # pattern coordinates in [0, 1]
    start = (Hn / Hn[2, 2]).ravel()[:8] * (1 + rng.normal(0, 0.02, 8))
    return (Residuals("projective", src=src, dst=dst), Jacobian("projective", src=src, dst=dst), start)


def _lm_public():
    rng = np.random.default_rng(80304)
    r_a, j_a, x_a = _arctan_problem(rng, 1, distance=(2.5, 3.0))
    r_c, j_c, x_c = _circle_problem(rng, 10, 0.15)
    r_e, j_e, x_e = _exponential_problem(rng, far=True)
    return [
        Case((Residuals("rosenbrock", a=10.0), np.array([-1.2, 1.0])), {}, "Rosenbrock from (−1.2, 1), no Jacobian"),
        Case((r_a, x_a), {"jacobian": j_a}, "arctan(x − c) from 2.5-3 away (Gauss–Newton diverges)"),
        Case((r_c, x_c), {}, "circle through 10 noisy points (residuals remain)"),
        Case((r_e, x_e), {"jacobian": j_e}, "exponential fit from far away"),
    ]


def _lm_hidden(rng):
    r_c1, j_c1, x_c1 = _circle_problem(rng)
    r_c2, _, x_c2 = _circle_problem(rng)
    r_a, j_a, x_a = _arctan_problem(rng, 1, distance=(2.0, 4.0))
    r_a2, _, x_a2 = _arctan_problem(rng, 1, distance=(1.6, 2.5))
    r_e, j_e, x_e = _exponential_problem(rng)
    r_f, j_f, x_f = _exponential_problem(rng, far=True)
    r_p, j_p, x_p = _projective_problem(rng)
    M = np.round(rng.normal(0, 1, (int(rng.integers(6, 10)), 3)), 3)
    b = np.round(rng.normal(0, 1, len(M)), 3)
    exact_x = np.round(rng.normal(0, 1, 3), 3)
    start = np.round(rng.uniform(-2.0, 0.0, 2), 2)
    a = _u(rng, 5, 20, 1)
    return [
        Case((Residuals("rosenbrock", a=10.0), start), {"max_iter": 1000}, "Rosenbrock, random start, no Jacobian"),
        Case((Residuals("rosenbrock", a=a), start), {"jacobian": Jacobian("rosenbrock", a=a), "max_iter": 1000},
             "Rosenbrock with another a, with the Jacobian"),
        Case((Residuals("linear", M=M, b=b), np.zeros(3)), {}, "linear least squares (one step)"),
        Case((Residuals("linear", M=M, b=M @ exact_x), exact_x), {}, "starts at the exact solution (cost 0)"),
        Case((r_c1, x_c1), {"jacobian": j_c1}, "circle fit with the Jacobian"),
        Case((r_c2, [int(v) for v in np.round(x_c2)]), {}, "circle fit, x0 a list of integers"),
        Case((r_a, x_a), {"jacobian": j_a}, "arctan, 2-4 away (Gauss–Newton diverges)"),
        Case((r_a2, x_a2), {}, "arctan, 1.6-2.5 away, no Jacobian"),
        Case((r_e, x_e), {"jacobian": j_e}, "exponential fit"),
        Case((r_f, x_f), {"jacobian": j_f}, "exponential fit, far start"),
        Case((r_f, x_f), {"jacobian": j_f, "max_iter": 0}, "max_iter = 0: x0 returned, not converged"),
        Case((r_p, x_p), {"jacobian": j_p}, "homography fit (8 parameters) to noisy points"),
        Case((r_c1, x_c1), {"tol": 1e-13}, "circle fit, tol = 1e-13"),
    ]


levenberg_marquardt = Check(
    public=_lm_public,
    hidden=_lm_hidden,
    compare=MinimumClose(xtol=1e-5, ctol=1e-7),
    call=least_squares_call,
    mistakes=[
        Mistake("Gauss–Newton steps (no damping, every step taken)", _lm_gauss_newton,
                "Solve (JᵀJ + μ·diag(JᵀJ))δ = −Jᵀr and keep a step only if it lowers the cost; adapt μ"),
        Mistake("steps that raise the cost are accepted", _lm_uphill,
                "Compute the cost at x + δ first: if it is not lower, refuse the step (keep x) and multiply μ by 10"),
        Mistake("damping changed the wrong way", _lm_inverted,
                "After a successful step divide μ by 10 (trust the linear model more); after a failed one multiply "
                "it by 10"),
        Mistake("step taken against the gradient's descent (x − δ)", _lm_wrong_sign,
                "The step solves (JᵀJ + μD)δ = −Jᵀr and the new point is x + δ"),
        Mistake("Jacobian computed only once, at x0", _lm_jacobian_once,
                "Recompute J (and JᵀJ, Jᵀr) after every accepted step: the linearisation changes with x"),
        Mistake("cost reported as ‖r‖² (no ½)", _lm_full_cost, "info['cost'] is ½‖r(x)‖², half the sum of squares"),
    ],
)


# --------------------------------------------------------------------------------------------
# calibration.refine_homography (§8.3.4)
# --------------------------------------------------------------------------------------------
@mistake("initial H returned (not refined)",
         "Minimise Σ‖dst − π(H·src)‖² over the 8 free entries of H with your levenberg_marquardt")
def _rh_unrefined(H, src, dst):
    H = np.asarray(H, dtype=np.float64)
    return H / H[2, 2]


def _rh_refit(H, src, dst, residual):
    """A wrong refinement: Levenberg–Marquardt from H (scaled to H[2, 2] = 1) over its first 8
    entries, minimising ``residual(Hm, src, dst)`` instead of the transfer error."""
    s = np.asarray(src, dtype=np.float64)
    d = np.asarray(dst, dtype=np.float64)
    H0 = np.asarray(H, dtype=np.float64)
    H0 = H0 / H0[2, 2]

    def residuals(h):
        return residual(np.append(h, 1.0).reshape(3, 3), s, d).ravel()

    h, _ = _levenberg_marquardt(residuals, H0.ravel()[:8])
    return np.append(h, 1.0).reshape(3, 3)


@mistake("no division by the third coordinate",
         "The predicted pixel is π(H·(x, y, 1)) = (u/w, v/w): divide by w in the residuals")
def _rh_no_division(H, src, dst):
    return _rh_refit(H, src, dst, lambda Hm, s, d: s @ Hm[:2, :2].T + Hm[:2, 2] - d)


@mistake("error measured in the pattern plane (H⁻¹·dst)",
         "Only the image points are measured (noisy): compare dst with H·src in the image, not src with H⁻¹·dst")
def _rh_source_side(H, src, dst):
    return _rh_refit(H, src, dst, lambda Hm, s, d: _map(np.linalg.inv(Hm), d) - s)


@mistake("not scaled to H[2, 2] = 1", "Return H divided by H[2, 2]")
def _rh_unit_norm(H, src, dst):
    refined = _refine_homography(H, src, dst)
    return refined / np.linalg.norm(refined)


def _rh_case(rng, n, noise, label, scale=1.0, start="dlt", offset=(0.0, 0.0), integer=False):
    H = _perspective_homography(rng, offset=offset)
    src, dst = _pairs(rng, n, H, noise)
    if integer:
        dst = np.round(dst).astype(np.int64)
    if start == "dlt":
        H0 = _homography_dlt(src, dst)
    else:
        H0 = (H / H[2, 2]) @ np.array([[1 + rng.normal(0, 0.01), rng.normal(0, 0.01), rng.normal(0, 2)],
                                       [rng.normal(0, 0.01), 1 + rng.normal(0, 0.01), rng.normal(0, 2)],
                                       [0.0, 0.0, 1.0]])
    return Case((H0 * scale, src, dst), {}, label)


def _rh_public():
    rng = np.random.default_rng(80305)
    return [
        _rh_case(rng, 10, 1.5, "10 noisy pairs, H from the DLT"),
        _rh_case(rng, 8, 2.0, "8 noisy pairs, H given with scale −3", scale=-3.0),
    ]


def _rh_hidden(rng):
    return [
        _rh_case(rng, int(rng.integers(8, 14)), _u(rng, 1.0, 2.5), "noisy pairs, DLT start"),
        _rh_case(rng, int(rng.integers(6, 9)), _u(rng, 1.5, 3.0), "few noisy pairs"),
        _rh_case(rng, int(rng.integers(10, 16)), _u(rng, 0.5, 1.5), "perturbed start (not the DLT)", start="perturbed"),
        _rh_case(rng, 9, _u(rng, 1.0, 2.0), "H with scale 1e-3", scale=1e-3),
        _rh_case(rng, 9, _u(rng, 1.0, 2.0), "H with a negative scale", scale=-_u(rng, 0.5, 5.0)),
        _rh_case(rng, int(rng.integers(6, 12)), _u(rng, 1.0, 2.0), "pixels around 1000",
                 offset=(_u(rng, 600, 1200), _u(rng, 600, 1200))),
        _rh_case(rng, 12, 0.0, "integer (rounded) pixels", integer=True),
        _rh_case(rng, 4, 0.0, "4 exact pairs (already optimal)"),
        _rh_case(rng, int(rng.integers(15, 20)), _u(rng, 2.0, 4.0), "many very noisy pairs"),
        _rh_case(rng, 7, _u(rng, 1.0, 2.0), "perturbed start, few pairs", start="perturbed"),
    ]


def _refine_probes(case):
    return np.asarray(case.args[1], dtype=np.float64)


refine_homography = Check(
    public=_rh_public,
    hidden=_rh_hidden,
    # 2e-3 px: far below what the mistakes change (≥ 1e-2 px on noisy cases) and above what a
    # forward-difference Jacobian with a crude step moves the minimum
    # (at the data points only: with few pairs the minimum is flat in directions that move
    # points far outside them)
    compare=HomographyClose(atol=2e-3, rtol=1e-8, probes=_refine_probes, corners=False),
    mistakes=[_rh_unrefined, _rh_no_division, _rh_source_side, _rh_unit_norm],
    allowed=("calibration.levenberg_marquardt", "calibration.homography_dlt"),
)


# --------------------------------------------------------------------------------------------
# calibration.intrinsics_from_homographies (§8.3.5)
# --------------------------------------------------------------------------------------------
def _homographies(rng, A, n, scales=True):
    Hs = []
    for _ in range(n):
        R, t = _pose(rng, 8, 6, 25.0, A[0, 0] * 200 / 500.0, tilt=0.7, spin=0.5)
        H = A @ np.column_stack([R[:, 0], R[:, 1], t])
        if scales:
            H = H * rng.choice([-1.0, 1.0]) * np.exp(rng.uniform(-3, 3))
        Hs.append(H)
    return Hs


def _zhang_b(Hs, rows_of=None, orthogonality_only=False, plus=False):
    rows = []
    for H in Hs:
        H = np.asarray(H, dtype=np.float64)
        H = H / np.linalg.norm(H)
        if rows_of is not None:
            H = H.T
        rows.append(_v(H, 0, 1))
        if not orthogonality_only:
            rows.append(_v(H, 0, 0) + _v(H, 1, 1) if plus else _v(H, 0, 0) - _v(H, 1, 1))
    V = np.array(rows)
    if V.shape[0] < 6:
        V = np.vstack([V, np.zeros((6 - V.shape[0], 6))])
    b = np.linalg.svd(V)[2][-1]
    return b if b[0] > 0 else -b


def _closed_form(b, order=(0, 1, 2, 3, 4, 5), skew=True):
    B11, B12, B22, B13, B23, B33 = (b[i] for i in order)
    den = B11 * B22 - B12 * B12
    v0 = (B12 * B13 - B11 * B23) / den
    lam = B33 - (B13 * B13 + v0 * (B12 * B13 - B11 * B23)) / B11
    with np.errstate(invalid="ignore"):
        alpha = np.sqrt(lam / B11)
        beta = np.sqrt(lam * B11 / den)
    gamma = -B12 * alpha * alpha * beta / lam if skew else 0.0
    u0 = gamma * v0 / beta - B13 * alpha * alpha / lam
    return np.array([[alpha, gamma, u0], [0.0, beta, v0], [0.0, 0.0, 1.0]])


@mistake("b unpacked in the wrong order (B13 and B22 swapped)",
         "v_ij follows b = (B11, B12, B22, B13, B23, B33): read B back in that same order")
def _ih_wrong_order(homographies):
    return _closed_form(_zhang_b(homographies), order=(0, 1, 3, 2, 4, 5))


@mistake("rows of H used instead of columns", "h1, h2 are the COLUMNS of H = λA[r1 r2 t]: use H[:, 0] and H[:, 1]")
def _ih_rows(homographies):
    return _closed_form(_zhang_b(homographies, rows_of=True))


@mistake("skew forced to zero", "Estimate the skew too: A[0, 1] = γ = −B12·α²·β/λ")
def _ih_no_skew(homographies):
    A = _intrinsics_from_homographies(homographies)
    A[0, 1] = 0.0
    return A


@mistake("only the orthogonality constraint (one row per view)",
         "Each view gives two rows: v12ᵀ (r1 ⊥ r2) and (v11 − v22)ᵀ (‖r1‖ = ‖r2‖)")
def _ih_orthogonality(homographies):
    return _closed_form(_zhang_b(homographies, orthogonality_only=True))


@mistake("second row v11 + v22 instead of v11 − v22", "‖r1‖ = ‖r2‖ means h1ᵀBh1 − h2ᵀBh2 = 0: the row is (v11 − v22)ᵀ")
def _ih_plus(homographies):
    return _closed_form(_zhang_b(homographies, plus=True))


@mistake("Cholesky factor used as A (not inverted)",
         "B = LLᵀ with L = A⁻ᵀ (up to scale): A is the inverse of Lᵀ, normalised so that A[2, 2] = 1")
def _ih_cholesky_not_inverted(homographies):
    b = _zhang_b(homographies)
    B = np.array([[b[0], b[1], b[3]], [b[1], b[2], b[4]], [b[3], b[4], b[5]]])
    L = np.linalg.cholesky(B)
    K = L.T
    return K / K[2, 2]


def _ih_public():
    rng = np.random.default_rng(80306)
    A1 = np.array([[820.0, 3.5, 330.0], [0.0, 790.0, 250.0], [0.0, 0.0, 1.0]])
    A2 = np.array([[1100.0, 0.0, 610.0], [0.0, 1150.0, 350.0], [0.0, 0.0, 1.0]])
    return [
        Case((_homographies(rng, A1, 3),), {}, "3 exact homographies (any scale), skewed camera"),
        Case((np.array(_homographies(rng, A2, 4)),), {}, "4 homographies as a (4, 3, 3) array, no skew"),
    ]


def _ih_hidden(rng):
    cases = []
    for n, skew, label in ((3, True, "3 views, skewed camera"), (4, True, "4 views, skewed camera"),
                           (3, False, "3 views, no skew"), (int(rng.integers(5, 9)), True, "5-8 views, skew"),
                           (int(rng.integers(5, 9)), False, "5-8 views, no skew")):
        cases.append(Case((_homographies(rng, _camera(rng, skew=skew), n),), {}, label))
    A = _camera(rng, skew=True, size=(720, 1280))
    cases.append(Case((np.array(_homographies(rng, A, 4)),), {}, "(4, 3, 3) array, 1280×720 camera"))
    A = _camera(rng, skew=False)
    cases.append(Case(([H.tolist() for H in _homographies(rng, A, 3)],), {}, "nested lists"))
    A = _camera(rng, skew=True)
    cases.append(Case((_homographies(rng, A, 3, scales=False),), {}, "homographies with their natural scale"))
    A = _camera(rng, skew=True)
    cases.append(Case(([H * 1e-9 for H in _homographies(rng, A, 4, scales=False)],), {}, "tiny scales (1e-9)"))
    A = _camera(rng, skew=False, size=(240, 320))
    cases.append(Case((_homographies(rng, A, 3),), {}, "small 320×240 camera"))
    return cases


intrinsics_from_homographies = Check(
    public=_ih_public,
    hidden=_ih_hidden,
    refusals=[
        Case(([np.array([[1.0, 0.1, 5.0], [0.05, 1.0, 3.0], [0.001, 0.002, 1.0]]),
               np.array([[0.9, -0.2, 2.0], [0.1, 1.1, -4.0], [-0.002, 0.001, 1.0]])],), {},
             "two homographies: fewer than the 3 needed", raises="ValueError"),
    ],
    compare=FloatClose(rtol=1e-6, atol=1e-6),
    mistakes=[_ih_wrong_order, _ih_rows, _ih_no_skew, _ih_orthogonality, _ih_plus, _ih_cholesky_not_inverted],
)


# --------------------------------------------------------------------------------------------
# calibration.extrinsics_from_homography (§8.3.6)
# --------------------------------------------------------------------------------------------
def _eh_parts(A, H, mean_norm=False):
    A = np.asarray(A, dtype=np.float64)
    M = np.linalg.solve(A, np.asarray(H, dtype=np.float64))
    lam = 2.0 / (np.linalg.norm(M[:, 0]) + np.linalg.norm(M[:, 1])) if mean_norm else 1.0 / np.linalg.norm(M[:, 0])
    if M[2, 2] * lam < 0:
        lam = -lam
    return lam * M[:, 0], lam * M[:, 1], lam * M[:, 2]


@mistake("R not re-orthonormalised", "With noise [r1 r2 r1×r2] is not a rotation: take its SVD UDVᵀ and return R = UVᵀ")
def _eh_no_svd(A, H):
    r1, r2, t = _eh_parts(A, H)
    return np.column_stack([r1, r2, np.cross(r1, r2)]), t


@mistake("sign of λ not fixed (t_z may be negative)",
         "H is known up to sign: choose the sign of λ that puts the pattern in front (t_z > 0)")
def _eh_sign(A, H):
    A = np.asarray(A, dtype=np.float64)
    M = np.linalg.solve(A, np.asarray(H, dtype=np.float64))
    lam = 1.0 / np.linalg.norm(M[:, 0])
    r1, r2, t = lam * M[:, 0], lam * M[:, 1], lam * M[:, 2]
    U, _, Vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    return U @ Vt, t


@mistake("A⁻¹ not applied to the columns of H",
         "r1 = λA⁻¹h1, r2 = λA⁻¹h2, t = λA⁻¹h3: solve with A first (np.linalg.solve(A, H))")
def _eh_no_inverse(A, H):
    return _extrinsics_from_homography(np.eye(3), H)


@mistake("r3 = r2 × r1 (left-handed, det R = −1)", "r3 = r1 × r2, in this order, for a right-handed frame (det R = +1)")
def _eh_left_handed(A, H):
    r1, r2, t = _eh_parts(A, H)
    U, _, Vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r2, r1)]))
    return U @ Vt, t


@mistake("Gram–Schmidt instead of the SVD",
         "Gram–Schmidt keeps r1 and bends r2; the closest rotation (§8.3.6) is UVᵀ from the SVD of "
         "[r1 r2 r3]")
def _eh_gram_schmidt(A, H):
    r1, r2, t = _eh_parts(A, H)
    e1 = r1 / np.linalg.norm(r1)
    e2 = r2 - (e1 @ r2) * e1
    e2 /= np.linalg.norm(e2)
    return np.column_stack([e1, e2, np.cross(e1, e2)]), t


@mistake("λ from the mean of ‖A⁻¹h1‖ and ‖A⁻¹h2‖",
         "As in §8.3.6, λ = 1/‖A⁻¹h1‖ (the SVD then takes care of the small difference in norms)")
def _eh_mean_norm(A, H):
    r1, r2, t = _eh_parts(A, H, mean_norm=True)
    U, _, Vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    return U @ Vt, t


def _eh_case(rng, label, skew=False, noise=0.0, scale=None, as_list=False):
    A = _camera(rng, skew=skew)
    R, t = _pose(rng, 8, 6, 25.0, _u(rng, 400, 900), tilt=0.8, spin=np.pi)
    H = A @ np.column_stack([R[:, 0], R[:, 1], t])
    if noise:
        H = H * (1.0 + rng.normal(0, noise, (3, 3)))
    s = (rng.choice([-1.0, 1.0]) * np.exp(rng.uniform(-2, 2))) if scale is None else scale
    H = H * s
    return Case((A.tolist() if as_list else A, H.tolist() if as_list else H), {}, label)


def _eh_public():
    rng = np.random.default_rng(80307)
    return [
        _eh_case(rng, "exact homography with a negative scale", scale=-2.5),
        _eh_case(rng, "perturbed homography (0.5 % noise), skewed camera", skew=True, noise=0.005, scale=1.7),
    ]


def _eh_hidden(rng):
    return [
        _eh_case(rng, "exact, positive scale", scale=_u(rng, 0.5, 3.0)),
        _eh_case(rng, "exact, negative scale", scale=-_u(rng, 0.5, 3.0)),
        _eh_case(rng, "perturbed (1 % noise)", noise=0.01),
        _eh_case(rng, "perturbed (0.3 % noise), negative scale", noise=0.003, scale=-_u(rng, 1, 5)),
        _eh_case(rng, "perturbed, skewed camera", skew=True, noise=0.005),
        _eh_case(rng, "exact, skewed camera", skew=True),
        _eh_case(rng, "tiny scale (1e-7)", scale=1e-7 * rng.choice([-1.0, 1.0]), noise=0.002),
        _eh_case(rng, "huge scale (1e7)", scale=1e7 * rng.choice([-1.0, 1.0]), noise=0.002),
        _eh_case(rng, "nested lists", as_list=True, noise=0.004),
        _eh_case(rng, "strongly perturbed (3 % noise)", noise=0.03, scale=-1.0),
    ]


extrinsics_from_homography = Check(
    public=_eh_public,
    hidden=_eh_hidden,
    compare=Parts(names=("R", "t"), inner=FloatClose(rtol=1e-8, atol=1e-9)),
    mistakes=[_eh_no_svd, _eh_sign, _eh_no_inverse, _eh_left_handed, _eh_gram_schmidt, _eh_mean_norm],
)


# --------------------------------------------------------------------------------------------
# calibration.estimate_radial_distortion (§8.3.7)
# --------------------------------------------------------------------------------------------
def _rd_system(A, world, images, Rs, ts, pixels_r=False, swapped=False, no_centre=False, distorted_r=False):
    A = np.asarray(A, dtype=np.float64)
    A = A / A[2, 2]
    world = np.asarray(world, dtype=np.float64)
    D, d = [], []
    for m, R, t in zip(images, Rs, ts):
        m = np.asarray(m, dtype=np.float64)
        cam = world @ np.asarray(R, dtype=np.float64).T + np.asarray(t, dtype=np.float64).reshape(3)
        x, y = cam[:, 0] / cam[:, 2], cam[:, 1] / cam[:, 2]
        u = A[0, 0] * x + A[0, 1] * y + A[0, 2]
        v = A[1, 1] * y + A[1, 2]
        if pixels_r:
            r2 = u * u + v * v
        elif distorted_r:
            yd = (m[:, 1] - A[1, 2]) / A[1, 1]
            xd = (m[:, 0] - A[0, 2] - A[0, 1] * yd) / A[0, 0]
            r2 = xd * xd + yd * yd
        else:
            r2 = x * x + y * y
        du = u if no_centre else u - A[0, 2]
        dv = v if no_centre else v - A[1, 2]
        D += [np.column_stack([du * r2, du * r2 * r2]), np.column_stack([dv * r2, dv * r2 * r2])]
        if swapped:
            d += [u - m[:, 0], v - m[:, 1]]
        else:
            d += [m[:, 0] - u, m[:, 1] - v]
    return np.concatenate(D), np.concatenate(d)


def _rd_solve(*args, **kwargs):
    D, d = _rd_system(*args, **kwargs)
    return np.linalg.lstsq(D, d, rcond=None)[0]


_rd_pixels = variant(_rd_solve, pixels_r=True)
_rd_swapped = variant(_rd_solve, swapped=True)
_rd_no_centre = variant(_rd_solve, no_centre=True)


@mistake("only k1 estimated (k2 = 0)",
         "Two unknowns: each row of D has a r² and a r⁴ column, solve for (k1, k2) together")
def _rd_k1_only(A, world_points, image_points_list, rotations, translations):
    D, d = _rd_system(A, world_points, image_points_list, rotations, translations)
    k1 = float(np.linalg.lstsq(D[:, :1], d, rcond=None)[0][0])
    return np.array([k1, 0.0])


_rd_distorted_r = variant(_rd_solve, distorted_r=True)


def _rd_case(rng, label, n_views, k, noise=0.0, skew=False, form="list", board=(6, 4)):
    A = _camera(rng, skew=skew)
    world, Rs, ts, images = _views(rng, A, board[0], board[1], 25.0, n_views, k=k, noise=noise)
    if form == "array":
        return Case((A, world, np.array(images), np.array(Rs), np.array(ts)), {}, label)
    if form == "columns":
        return Case((A, world, images, Rs, [t.reshape(3, 1) for t in ts]), {}, label)
    return Case((A, world, images, Rs, ts), {}, label)


def _k(rng):
    return (-_u(rng, 0.15, 0.35, 4), _u(rng, 0.03, 0.12, 4))


def _rd_public():
    rng = np.random.default_rng(80308)
    return [
        _rd_case(rng, "2 views, exact points, k = (−0.3, 0.08)", 2, (-0.3, 0.08)),
        _rd_case(rng, "3 views, 0.3 px noise, skewed camera", 3, (-0.2, 0.05), noise=0.3, skew=True),
    ]


def _rd_hidden(rng):
    return [
        _rd_case(rng, "1 view, exact points", 1, _k(rng)),
        _rd_case(rng, "3 views, exact points", 3, _k(rng)),
        _rd_case(rng, "2 views, 0.2 px noise", 2, _k(rng), noise=0.2),
        _rd_case(rng, "pincushion (k1 > 0)", 2, (_u(rng, 0.1, 0.3, 4), -_u(rng, 0.01, 0.05, 4))),
        _rd_case(rng, "skewed camera", 2, _k(rng), skew=True),
        _rd_case(rng, "stacked arrays (views, N, 2)", 3, _k(rng), form="array"),
        _rd_case(rng, "translations as (3, 1) columns", 2, _k(rng), form="columns"),
        _rd_case(rng, "strong noise (1 px)", 4, _k(rng), noise=1.0),
        _rd_case(rng, "only k1 in the lens", 2, (-_u(rng, 0.1, 0.3, 4), 0.0)),
        _rd_case(rng, "9 × 6 board, 2 views", 2, _k(rng), board=(9, 6)),
    ]


estimate_radial_distortion = Check(
    public=_rd_public,
    hidden=_rd_hidden,
    compare=FloatClose(rtol=1e-6, atol=1e-9),
    mistakes=[
        Mistake("r² in pixels (not normalised coordinates)", _rd_pixels,
                "r² = x² + y² with the NORMALISED coordinates x = x_C/z_C, y = y_C/z_C, before A"),
        Mistake("ideal and measured swapped (d = u − ŭ)", _rd_swapped,
                "The right-hand side is measured − ideal: ŭ − u and v̆ − v"),
        Mistake("principal point not subtracted (u instead of u − u0)", _rd_no_centre,
                "Distortion is about the principal point: the columns of D are (u − u0)·r², (u − u0)·r⁴ "
                "and (v − v0)·r², (v − v0)·r⁴"),
        _rd_k1_only,
        Mistake("r from the measured (distorted) points", _rd_distorted_r,
                "r belongs to the IDEAL point (projected without distortion), not to the measured one"),
    ],
    allowed=CAMERA_BLOCKS,
)


# --------------------------------------------------------------------------------------------
# calibration.calibrate (§8.2–8.3.8)
# --------------------------------------------------------------------------------------------
_cal_no_refinement = variant(_calibrate, refine=False)


@mistake("rms = mean error (not the root of the mean square)",
         "rms = √(Σ‖e‖² / number of points): square the error lengths, average, then take the root")
def _cal_mean_error(world_points, image_points_list):
    result = _calibrate(world_points, image_points_list)
    result["rms"] = float(np.mean(np.sqrt(np.sum(result["residuals"] ** 2, axis=-1))))
    return result


@mistake("rms over coordinates (divided by 2 per point)",
         "Divide Σ‖e‖² by the number of POINTS (each has two coordinates), as OpenCV does")
def _cal_per_coordinate(world_points, image_points_list):
    result = _calibrate(world_points, image_points_list)
    result["rms"] = float(np.sqrt(np.mean(result["residuals"] ** 2)))
    return result


_cal_k_fixed = variant(_calibrate, refine_distortion=False)
_cal_free_skew = variant(_calibrate, free_skew=True)


def _closed_form_fits(A, world, images, tolerance=0.3) -> bool:
    """The closed-form start of ``calibrate`` (steps 1–2: refined DLT homographies, then
    ``intrinsics_from_homographies``) finds a camera, with fu and fv within ``tolerance``
    (relative) of the true ones. Views whose patterns are nearly parallel leave B = A⁻ᵀA⁻¹
    undetermined; with lens distortion and noise it is then not positive definite (the
    reference raises, rightly) or barely so (a start so far off that correct versions may
    end in different minima)."""
    plane = world[:, :2]
    try:
        with registry.use("reference"):
            Hs = [_refine_homography(_homography_dlt(plane, m), plane, m) for m in images]
            A0 = _intrinsics_from_homographies(Hs)
    except (ValueError, np.linalg.LinAlgError):
        return False
    return bool(abs(A0[0, 0] / A[0, 0] - 1) <= tolerance and abs(A0[1, 1] / A[1, 1] - 1) <= tolerance)


def _cal_case(rng, label, n_views, board, noise, k=None, form="list", skew=False, square=25.0):
    A = _camera(rng)
    k = _k(rng) if k is None else k
    for _ in range(200):  # views that determine the camera (≈ 4 % of draws do not): draw again
        world, _, _, images = _views(rng, A, board[0], board[1], square, n_views, k=k, noise=noise)
        if _closed_form_fits(A, world, images):
            break
    else:  # pragma: no cover - about 0.04 ** 200
        raise RuntimeError(f"no view set of {label!r} determines the camera")
    if form == "array":
        images = np.array(images)
    return Case((world, images), {}, label)


def _cal_public():
    rng = np.random.default_rng(80309)
    return [
        _cal_case(rng, "4 views of a 5 × 4 board, 0.3 px noise", 4, (5, 4), 0.3, k=(-0.25, 0.06)),
    ]


def _cal_hidden(rng):
    return [
        _cal_case(rng, "3 views, 5 × 4 board, 0.2 px noise", 3, (5, 4), 0.2),
        _cal_case(rng, "4 views, 4 × 3 board, 0.5 px noise", 4, (4, 3), 0.5),
        _cal_case(rng, "5 views, 5 × 4 board, 0.1 px noise", 5, (5, 4), 0.1),
        _cal_case(rng, "3 views, exact points", 3, (5, 4), 0.0),
        _cal_case(rng, "(views, N, 2) array", 4, (4, 4), 0.3, form="array"),
        _cal_case(rng, "no distortion in the lens", 4, (5, 3), 0.3, k=(0.0, 0.0)),
        _cal_case(rng, "pincushion lens", 4, (5, 4), 0.2, k=(_u(rng, 0.1, 0.25), -_u(rng, 0.0, 0.03))),
        _cal_case(rng, "squares of 0.03 m", 4, (5, 4), 0.3, square=0.03),
        _cal_case(rng, "4 views, 1 px noise", 4, (6, 4), 1.0),
    ]


calibrate = Check(
    public=_cal_public,
    hidden=_cal_hidden,
    compare=CalibrationClose(rtol=1e-5, rms_rtol=1e-6),
    mistakes=[
        Mistake("no global refinement (closed-form estimates)", _cal_no_refinement,
                "Finish with levenberg_marquardt over (fu, fv, u0, v0, k1, k2) and every pose, minimising the "
                "total reprojection error"),
        _cal_mean_error,
        _cal_per_coordinate,
        Mistake("distortion not refined (linear k kept)", _cal_k_fixed,
                "k1, k2 belong to the parameters of the final refinement too"),
        Mistake("skew left free in the refinement", _cal_free_skew,
                "Fix the skew at 0 in the final refinement (it is estimated only in the closed-form start)"),
    ],
    allowed=("calibration.homography_dlt", "calibration.refine_homography", "calibration.levenberg_marquardt",
             "calibration.intrinsics_from_homographies", "calibration.extrinsics_from_homography",
             "calibration.estimate_radial_distortion") + CAMERA_BLOCKS,
    time_limit=60.0,
)
