"""Lens distortion (§7.7): OpenCV's radial–tangential model, its inversion, and the complete
four-step image formation pipeline."""
from __future__ import annotations

import warnings
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike

from .._validation import check_bool, check_size
from ..registry import algorithm, implementation
from ._common import (
    as_intrinsics,
    as_points,
    as_rotation,
    as_translation,
    distortion_coefficients,
    radial_tangential,
)

__all__ = ["distort", "undistort_points", "project_full", "ConvergenceWarning", "TOLERANCE", "REPORT_TOLERANCE",
           "MAX_ITERATIONS"]

#: ``undistort_points(iterations=None)``: a point is undistorted when ``distort`` of the result is
#: within TOLERANCE·max(1, |x_d|, |y_d|) of x_d, in each coordinate
TOLERANCE = 1e-12
#: ``undistort_points(iterations=n)``: a result whose ``distort`` is farther than
#: REPORT_TOLERANCE·max(1, |x_d|, |y_d|) from x_d is reported (the n-step iterate is far from the
#: inverse: 1e-6 in normalised coordinates is about a thousandth of a pixel for f = 1000 px)
REPORT_TOLERANCE = 1e-6
#: the fixed-point steps taken before Newton's method (OpenCV's count, the notes' default)
DEFAULT_ITERATIONS = 20
#: the largest ``iterations`` accepted (each step is one pass over the points)
MAX_ITERATIONS = 1000
_NEWTON_STEPS = 50     # Newton converges quadratically: a handful of steps where it converges at all
_HALVINGS = 30         # step halvings tried before a point is left where it is


class ConvergenceWarning(RuntimeWarning):
    """:func:`undistort_points` could not invert the distortion at some points (the message
    names how many, and the worst)."""


@algorithm("camera.distort", section="7.7.2", check="cvkit.camera.checks:distort")
def distort(xy_normalized: ArrayLike, k: ArrayLike = (0.0, 0.0, 0.0), p: ArrayLike = (0.0, 0.0)) -> np.ndarray:
    """Apply radial and tangential lens distortion to normalised image coordinates.

    Parameters
    ----------
    xy_normalized : (N, 2) array_like
        Ideal (undistorted) normalised coordinates ``(x, y) = (x_C / z_C, y_C / z_C)``: the
        canonical projection, *before* the intrinsic matrix (not pixels). N = 0 is allowed.
    k : sequence of 1 to 3 floats
        Radial coefficients ``(k1[, k2[, k3]])``; missing ones are 0. A scalar is k1.
    p : sequence of 2 floats
        Tangential (decentring) coefficients ``(p1, p2)``.

    Returns
    -------
    (N, 2) float64 ndarray
        Distorted normalised coordinates.

    Raises
    ------
    ValueError
        Wrong shapes, non-finite values, k with 0 or more than 3 entries, p without exactly 2.
    TypeError
        Non-numeric or complex arguments.

    Notes
    -----
    §7.7.2, OpenCV's (Brown–Conrady) model with :math:`r^2 = x^2 + y^2`:

    .. math::

        x_d &= x\\,(1 + k_1 r^2 + k_2 r^4 + k_3 r^6) + 2 p_1 x y + p_2 (r^2 + 2 x^2) \\\\
        y_d &= y\\,(1 + k_1 r^2 + k_2 r^4 + k_3 r^6) + p_1 (r^2 + 2 y^2) + 2 p_2 x y

    :math:`k_1 < 0` gives barrel distortion (points pulled towards the centre, more so far
    from it), :math:`k_1 > 0` pincushion. The "tangential" term has a radial component too:
    along the radius it moves a point by :math:`3r(p_1 y + p_2 x)`, across it by
    :math:`r(p_1 x - p_2 y)`. Same as ``cv2.projectPoints`` with identity camera and
    ``distCoeffs = (k1, k2, p1, p2, k3)`` (note OpenCV's order).

    Examples
    --------
    >>> distort([[0.0, 0.0], [0.5, 0.0]], k=(-0.2,))          # barrel: the centre stays, 0.5 → 0.475
    array([[0.   , 0.   ],
           [0.475, 0.   ]])
    >>> distort([[0.5, 0.0]], k=(0.0,), p=(0.0, 0.01))         # p2 moves x by p2·(r² + 2x²)
    array([[0.5075, 0.    ]])
    """
    xy = as_points(xy_normalized, "xy_normalized", 2)
    kk, pp = distortion_coefficients(k, p)
    return _distorted(xy, kk, pp)


def _distorted(xy: np.ndarray, kk: np.ndarray, pp: np.ndarray) -> np.ndarray:
    """:func:`distort`'s arithmetic on checked arguments (``kk``, ``pp`` from
    :func:`distortion_coefficients`)."""
    x, y = xy[:, 0], xy[:, 1]
    radial, dx, dy = radial_tangential(x, y, kk, pp)
    return np.stack([x * radial + dx, y * radial + dy], axis=1)


@algorithm("camera.undistort_points", section="7.7", check="cvkit.camera.checks:undistort_points")
def undistort_points(xy_distorted: ArrayLike, k: ArrayLike, p: ArrayLike, iterations: int | None = DEFAULT_ITERATIONS, *,
                     strict: bool = False) -> np.ndarray:
    """Invert :func:`distort`: ideal normalised coordinates from distorted ones.

    Parameters
    ----------
    xy_distorted : (N, 2) array_like
        Distorted normalised coordinates (pixels mapped through A⁻¹). N = 0 is allowed.
    k : sequence of 1 to 3 floats
        Radial coefficients ``(k1[, k2[, k3]])``, as for :func:`distort`.
    p : sequence of 2 floats
        Tangential coefficients ``(p1, p2)``.
    iterations : int or None
        An int ``0 ≤ n ≤ 1000`` (:data:`MAX_ITERATIONS`; default 20, the catalog's and
        OpenCV's count): exactly ``n`` fixed-point steps — the iterate of the notes (0 returns
        the input as float64); points whose iterate ``distort`` maps farther than
        :data:`REPORT_TOLERANCE` from ``x_d`` are reported (see ``strict``). ``None``: the
        inverse to :data:`TOLERANCE` — 20 fixed-point steps, then Newton steps for the points
        not yet within it; points that still are not are reported.
    strict : bool, keyword-only
        What to do with the points reported. False (default): warn with
        :class:`ConvergenceWarning` (a ``RuntimeWarning``) and return the estimate. True: raise
        ``ValueError`` naming ``xy_distorted`` and the worst point.

    Returns
    -------
    (N, 2) float64 ndarray
        The undistorted normalised coordinates.

    Raises
    ------
    ValueError, TypeError
        As for :func:`distort`; a negative, non-integer or too large ``iterations``; with
        ``strict=True``, points that do not converge.

    Warns
    -----
    ConvergenceWarning
        ``strict=False`` and some points are reported: the ``n`` steps left them far from the
        inverse (strong distortion far from the centre: pass ``iterations=None``), or they have
        no inverse at all (beyond the fold of a strong barrel distortion, no x gives that x_d).

    Notes
    -----
    §7.7: the distortion has no closed-form inverse. Writing it as
    :math:`x_d = L(r)\\,x + \\Delta(x)` suggests the fixed-point iteration used by OpenCV's
    ``undistortPoints``, starting from :math:`x^{(0)} = x_d`:

    .. math:: x^{(n+1)} = \\frac{x_d - \\Delta_x(x^{(n)})}{L(r^{(n)})}, \\quad
              y^{(n+1)} = \\frac{y_d - \\Delta_y(x^{(n)})}{L(r^{(n)})}

    The error shrinks each step by the factor :math:`|r L'(r)/L(r)|` (about
    :math:`2|k_1| r^2`): the iteration converges linearly, fast near the centre and slowly
    for strong distortion far from it (it diverges where that factor exceeds 1). With
    :math:`|k_1| \\le 0.3`, :math:`|k_2| \\le 0.1`, :math:`|k_3| \\le 0.02`,
    :math:`|p_1|, |p_2| \\le 0.002` and ideal points with :math:`|x|, |y| \\le 0.4`, 20 steps
    recover them to better than 1e-12 (measured worst case 2.5e-13, i.e. 1e-9 px for focal
    lengths up to 4000 px). If instead the *distorted* points fill that square, strong
    barrel distortion (all :math:`k_i < 0`) moves the ideal corners out to
    :math:`r^2 \\approx 0.4`, the factor grows to 0.36 and 20 steps leave up to 1e-8.

    With ``iterations=None`` a point is done when ``distort`` of the estimate is within
    ``TOLERANCE·max(1, |x_d|, |y_d|)`` of ``x_d`` (each coordinate); the points the 20
    fixed-point steps leave farther (or at inf/nan) are solved by Newton's method on
    :math:`F(x) = \\text{distort}(x) - x_d` with the analytic 2×2 Jacobian, from the better of
    the fixed-point estimate and ``x_d``, each step halved until the residual decreases and
    the Jacobian stays orientation-preserving (det > 0: the branch of the inverse that
    contains the centre), at most 50 steps. Points the fixed-point steps already solved keep
    exactly their fixed-point value. A point still not within the tolerance has no inverse on
    that branch — ``x_d`` beyond the fold where ``d(r L(r))/dr = 0`` (for ``k = (−0.5,)``,
    distorted radii above 0.544) — and is reported; its value is the estimate with the
    smallest residual.

    ``iterations=n`` equals ``cv2.undistortPointsIter`` with an identity camera matrix,
    distCoeffs ``(k1, k2, p1, p2, k3)`` and the criteria ``(COUNT, n, 0)``.

    Examples
    --------
    >>> import numpy as np
    >>> xd = distort([[0.3, -0.2]], k=(-0.25, 0.05), p=(0.001, -0.002))
    >>> np.round(undistort_points(xd, k=(-0.25, 0.05), p=(0.001, -0.002)), 12)
    array([[ 0.3, -0.2]])
    >>> # beyond the fold of k1 = -0.5 (distorted radii above 0.544) there is no inverse
    >>> undistort_points([[0.6, 0.0]], k=(-0.5,), p=(0, 0), iterations=None, strict=True)   # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: xy_distorted: 1 of 1 points could not be undistorted to 1e-12 ...
    """
    xy = as_points(xy_distorted, "xy_distorted", 2)
    kk, pp = distortion_coefficients(k, p)
    converge = iterations is None
    steps = DEFAULT_ITERATIONS if iterations is None else check_size(
        iterations, "iterations", minimum=0, maximum=MAX_ITERATIONS)
    check_bool(strict, "strict")
    xd, yd = xy[:, 0], xy[:, 1]
    x, y = xd.copy(), yd.copy()
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for _ in range(steps):
            radial, dx, dy = radial_tangential(x, y, kk, pp)
            x, y = (xd - dx) / radial, (yd - dy) / radial
        if xy.shape[0] == 0:
            return np.stack([x, y], axis=1)
        scale = (TOLERANCE if converge else REPORT_TOLERANCE) * np.maximum(1.0, np.maximum(np.abs(xd), np.abs(yd)))
        error = _residual_norm(x, y, xd, yd, kk, pp)
        if converge:
            todo = np.flatnonzero(~(error <= scale))          # NaN counts as not converged
            if todo.size:
                nx, ny, n_error = _newton(xd[todo], yd[todo], x[todo], y[todo], error[todo], kk, pp)
                better = (n_error < error[todo]) | ~np.isfinite(error[todo])
                x[todo[better]], y[todo[better]], error[todo[better]] = nx[better], ny[better], n_error[better]
    failed = np.flatnonzero(~(error <= scale))
    if failed.size:
        worst = failed[int(np.argmax(np.where(np.isfinite(error[failed]), error[failed], np.inf)))]
        message = (
            f"xy_distorted: {failed.size} of {xy.shape[0]} points could not be undistorted to "
            f"{TOLERANCE if converge else REPORT_TOLERANCE:g} "
            f"(worst: row {worst}, x_d = ({xd[worst]:.6g}, {yd[worst]:.6g}), distort(result) is {error[worst]:.3g} "
            + ("away after the Newton steps; beyond the fold of the distortion model there is no inverse)"
               if converge else f"away after {steps} fixed-point steps; iterations=None adds Newton steps where an inverse exists)"))
        if strict:
            raise ValueError(message)
        warnings.warn(message, ConvergenceWarning, stacklevel=2)
    return np.stack([x, y], axis=1)


def _residual_norm(x: np.ndarray, y: np.ndarray, xd: np.ndarray, yd: np.ndarray, k: np.ndarray,
                   p: np.ndarray) -> np.ndarray:
    """max(|distort(x, y) − (x_d, y_d)|) per point (NaN where the estimate is not finite)."""
    radial, dx, dy = radial_tangential(x, y, k, p)
    return np.maximum(np.abs(x * radial + dx - xd), np.abs(y * radial + dy - yd))


def _jacobian(x: np.ndarray, y: np.ndarray, k: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Entries (a, b, d) of the symmetric Jacobian [[a, b], [b, d]] of distort at (x, y)."""
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[2]))
    slope = 2.0 * (k[0] + r2 * (2.0 * k[1] + 3.0 * k[2] * r2))      # 2·dL/d(r²)
    a = radial + slope * x * x + 2.0 * p[0] * y + 6.0 * p[1] * x
    b = slope * x * y + 2.0 * p[0] * x + 2.0 * p[1] * y
    d = radial + slope * y * y + 6.0 * p[0] * y + 2.0 * p[1] * x
    return a, b, d


def _newton(xd: np.ndarray, yd: np.ndarray, x: np.ndarray, y: np.ndarray, error: np.ndarray, k: np.ndarray,
            p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton's method on distort(x) = x_d for the given points, from the better of (x, y) and
    x_d; each step halved until the residual decreases with det J > 0. Returns x, y, residual."""
    a, b, d = _jacobian(xd, yd, k, p)
    from_xd = _residual_norm(xd, yd, xd, yd, k, p)
    a0, b0, d0 = _jacobian(x, y, k, p)
    keep = (error <= from_xd) & (a0 * d0 - b0 * b0 > 0)               # False for NaN
    x, y = np.where(keep, x, xd), np.where(keep, y, yd)
    error = np.where(keep, error, from_xd)
    usable = keep | (a * d - b * b > 0)
    active = np.flatnonzero(usable & (error > 0))
    for _ in range(_NEWTON_STEPS):
        if active.size == 0:
            break
        xa, ya = x[active], y[active]
        radial, dx, dy = radial_tangential(xa, ya, k, p)
        fx, fy = xa * radial + dx - xd[active], ya * radial + dy - yd[active]
        a, b, d = _jacobian(xa, ya, k, p)
        det = a * d - b * b
        sx, sy = (b * fy - d * fx) / det, (b * fx - a * fy) / det
        moved = np.zeros(active.size, dtype=bool)
        t = 1.0
        for _ in range(_HALVINGS):
            pending = np.flatnonzero(~moved)
            if pending.size == 0:
                break
            tx, ty = xa[pending] + t * sx[pending], ya[pending] + t * sy[pending]
            trial = _residual_norm(tx, ty, xd[active[pending]], yd[active[pending]], k, p)
            ta, tb, td = _jacobian(tx, ty, k, p)
            ok = (trial < error[active[pending]]) & (ta * td - tb * tb > 0)
            chosen = active[pending[ok]]
            x[chosen], y[chosen], error[chosen] = tx[ok], ty[ok], trial[ok]
            moved[pending[ok]] = True
            t *= 0.5
        active = active[moved & (error[active] > 0)]
    return x, y, error
@algorithm("camera.project_full", section="7.7.3", check="cvkit.camera.checks:project_full")
def project_full(points_world: ArrayLike, A: ArrayLike, R: ArrayLike, t: ArrayLike, k: ArrayLike = (0.0, 0.0, 0.0),
                 p: ArrayLike = (0.0, 0.0)) -> np.ndarray:
    """Project world points to pixels through the complete camera model, lens included.

    Parameters
    ----------
    points_world : (N, 3) array_like
        Points in the world reference frame. N = 0 is allowed.
    A : (3, 3) array_like
        Intrinsic matrix (upper triangular, non-zero diagonal; ``A[2, 2]`` is normally 1 and
        is divided out otherwise).
    R : (3, 3) array_like
        World → camera rotation (orthonormal within 1e-3, det +1; used as given).
    t : (3,) or (3, 1) array_like
        World → camera translation.
    k : sequence of 1 to 3 floats
        Radial distortion coefficients ``(k1[, k2[, k3]])``.
    p : sequence of 2 floats
        Tangential distortion coefficients ``(p1, p2)``.

    Returns
    -------
    (N, 2) float64 ndarray
        Pixel coordinates ``(u, v)`` = (x, y) = (col, row). A point with :math:`z_C = 0` gives
        ``±inf`` / ``nan`` (``np.divide`` semantics, no warnings); points behind the camera are
        projected by the same formulas, as in OpenCV.

    Raises
    ------
    ValueError
        Wrong shapes, non-finite values, a non-triangular ``A``, an ``R`` that is not a
        rotation, or bad distortion coefficients.
    TypeError
        Non-numeric or complex arguments.

    Notes
    -----
    §7.7.3, the four steps:

    1. extrinsics: :math:`M_C = R M_W + t`;
    2. canonical perspective projection: :math:`(x, y) = (x_C / z_C, y_C / z_C)`;
    3. lens distortion in these *normalised* coordinates, through
       ``implementation("camera.distort")``;
    4. intrinsics: :math:`[u, v, 1]^T \\simeq A [x_d, y_d, 1]^T`, i.e.
       :math:`u = f_u x_d + s\\, y_d + u_0`, :math:`v = f_v y_d + v_0`.

    With k = p = 0 this equals ``project(projection_matrix(A, R, t), points_world)``. For zero
    skew it equals ``cv2.projectPoints(points, cv2.Rodrigues(R)[0], t, A, (k1, k2, p1, p2, k3))``
    (OpenCV's projectPoints ignores a non-zero skew).

    Examples
    --------
    >>> import numpy as np
    >>> from cvkit.camera import intrinsic_matrix
    >>> A = intrinsic_matrix(500, 500, 320, 240)
    >>> project_full([[0.2, 0.1, 2.0]], A, np.eye(3), [0, 0, 0])
    array([[370., 265.]])
    >>> project_full([[0.2, 0.1, 2.0]], A, np.eye(3), [0, 0, 0], k=(-0.2,))   # barrel: pulled in
    array([[369.875 , 264.9375]])
    """
    pts = as_points(points_world, "points_world", 3)
    intr = as_intrinsics(A, "A")
    rot = as_rotation(R, "R")
    trans = as_translation(t, "t")
    kk, pp = distortion_coefficients(k, p)  # validate before any work
    distort_now = implementation("camera.distort")
    lens = None if distort_now is distort else (lambda xy: distort_now(xy, k, p))
    return project_checked(pts, intr, rot, trans, kk, pp, lens)


def project_checked(points: np.ndarray, A: np.ndarray, R: np.ndarray, t: np.ndarray, k: np.ndarray, p: np.ndarray,
                    lens: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """The four steps of :func:`project_full` on arguments already checked: float64 ``(N, 3)``
    points, ``A``, ``R`` and ``t`` as :func:`as_intrinsics`, :func:`as_rotation` and
    :func:`as_translation` return them, ``k`` and ``p`` as :func:`distortion_coefficients`
    returns them. ``lens`` maps ``(M, 2)`` normalised points to distorted ones (the active
    provider's ``camera.distort``); None: the reference's arithmetic. For the topics that
    project many times with arguments they made themselves (calibration's refinement, the
    chessboard pose sampler): the same numbers as :func:`project_full`, bit for bit."""
    camera = points @ R.T + t                                     # 1. world -> camera frame
    with np.errstate(divide="ignore", invalid="ignore"):
        normalized = camera[:, :2] / camera[:, 2:]                # 2. canonical projection
    finite = np.isfinite(normalized).all(axis=1)
    if lens is None and finite.all():                             # 3. lens distortion
        distorted = _distorted(normalized, k, p)
    else:                                                         # points at infinity stay there
        distorted = np.array(normalized)
        if finite.any():
            inside = normalized[finite]
            distorted[finite] = _distorted(inside, k, p) if lens is None else lens(inside)
    a = A / A[2, 2]                                               # 4. intrinsics
    with np.errstate(invalid="ignore"):  # a point at infinity: inf - inf is nan, without a warning
        u = a[0, 0] * distorted[:, 0] + a[0, 2]
        if a[0, 1] != 0.0:  # (skipped when 0: keeps 0·inf from turning a point at infinity into nan)
            u = u + a[0, 1] * distorted[:, 1]
        v = a[1, 1] * distorted[:, 1] + a[1, 2]
    return np.stack([u, v], axis=1)
