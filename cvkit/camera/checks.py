"""Checks of Chapter 7's camera model: the cases, comparators and mistake banks the grader uses.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference
function (``cvkit.camera.checks:project`` grades ``camera.project``). Each check has

- ``public`` cases: a few points and a camera with unequal focal lengths, an off-centre
  principal point, a rotation about all three axes and, where it matters, skew, distortion
  with every coefficient non-zero, a scaled or negated P, integer input and points at
  infinity, so that every mistake of the bank already shows;
- ``hidden`` cases drawn from the grading seed: random cameras and point sets, single points,
  integer dtypes, huge and tiny scales, directions parallel to the image plane, points
  behind the camera, every number of radial coefficients (1–3), zero and non-zero tangential
  terms, t as a (3,) vector, a list or a (3, 1) column — and, for every mistake, inputs on
  which it is wrong;
- a comparator: :class:`FloatClose` (allclose that also requires a float result where a float
  is expected, so integer outputs are caught and their mistake named), or :class:`Parts`
  for the ``(A, R, t)`` of ``decompose_projection``;
- a bank of named mistakes, each a function computing the wrong variant and a hint saying
  how to fix it.

Point sets stay below 12 points, so loop versions finish instantly.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import numpy as np

from ..grading import Case, Check, Close, Comparator, Mismatch, Mistake, mistake
from ..grading.casekit import variant
from ..grading.casekit import size as _n
from ..grading.casekit import uniform as _u
from ..grading.compare import tuple_problem
from ._common import distortion_coefficients, radial_tangential
from ._distortion import distort as _distort
from ._distortion import undistort_points as _undistort_points
from ._projection import _rq
from ._projection import decompose_projection as _decompose_projection
from ._projection import extrinsic_matrix as _extrinsic_matrix
from ._projection import intrinsic_matrix as _intrinsic_matrix
from ._projection import project as _project
from ._projection import projection_matrix as _projection_matrix
from ._projection import rotation_matrix as _rotation_matrix

__all__ = [
    "FloatClose", "Parts",
    "to_homogeneous", "from_homogeneous", "intrinsic_matrix", "rotation_matrix", "extrinsic_matrix",
    "projection_matrix", "project", "decompose_projection", "distort", "undistort_points", "project_full",
]


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
@dataclass
class FloatClose(Close):
    """:class:`~cvkit.grading.Close` that also wants a float array wherever the expected
    output is one.

    Unlike ``close(kind="f")`` the dtype requirement follows the *expected* value: an integer
    candidate fails against the float reference, but matches an integer mistake (e.g.
    ``np.ones_like`` of integer points), so the grader can name that mistake.
    """

    def __call__(self, got, expected, case=None):
        if isinstance(expected, (tuple, list)) and not isinstance(expected, np.ndarray):
            return super().__call__(got, expected, case)
        exp_kind = np.asarray(expected).dtype.kind
        try:
            got_kind = np.asarray(got).dtype.kind
        except Exception:
            got_kind = None
        if exp_kind == "f" and got_kind in ("i", "u", "b"):
            return Mismatch(
                f"dtype mismatch: expected a float array, got {np.asarray(got).dtype} "
                "(integer input must give float64 output: convert with np.asarray(x, dtype=float))"
            )
        return super().__call__(got, expected, case)


@dataclass
class Parts(Comparator):
    """Several named results returned as one tuple (``A, R, t``), each compared by ``inner``."""

    names: tuple = ()
    inner: Comparator = field(default_factory=lambda: FloatClose())

    def describe(self) -> str:
        return f"({', '.join(self.names)}) each {self.inner.describe()}"

    def __call__(self, got, expected, case=None):
        problem = tuple_problem(got, self.names)
        if problem:
            return Mismatch(problem)
        for name, g, e in zip(self.names, got, expected):
            mismatch = self.inner(g, e, case)
            if mismatch is not None:
                mismatch.message = f"{name}: {mismatch.message}"
                return mismatch
        return None


# --------------------------------------------------------------------------------------------
# case helpers
# --------------------------------------------------------------------------------------------
def _angles(rng: np.random.Generator) -> tuple:
    """Three angles, each at least 0.2 rad away from 0 and ±π (no accidental symmetry)."""
    values = []
    for _ in range(3):
        a = _u(rng, 0.2, float(np.pi) - 0.2)
        values.append(a if rng.random() < 0.5 else -a)
    return tuple(values)


def _intrinsics(rng: np.random.Generator, skew: bool = False) -> np.ndarray:
    fu = _u(rng, 400, 1200, 1)
    fv = float(np.round(fu * rng.uniform(0.85, 0.95) if rng.random() < 0.5 else fu * rng.uniform(1.05, 1.15), 1))
    u0, v0 = _u(rng, 250, 400, 1), _u(rng, 150, 240, 1)
    s = _u(rng, 1.0, 6.0, 2) * (1 if rng.random() < 0.5 else -1) if skew else 0.0
    return _intrinsic_matrix(fu, fv, u0, v0, s)


def _pose(rng: np.random.Generator) -> tuple:
    R = _rotation_matrix(*_angles(rng))
    t = np.round(np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(4, 9)]), 3)
    return R, t


def _camera(rng: np.random.Generator, skew: bool = False) -> tuple:
    return (_intrinsics(rng, skew),) + _pose(rng)


def _points_in_front(rng: np.random.Generator, R: np.ndarray, t: np.ndarray, n: int,
                     depth=(2.0, 8.0), spread: float = 0.4) -> np.ndarray:
    """World points whose camera coordinates have z in ``depth`` and |x|, |y| ≤ spread·z."""
    z = rng.uniform(depth[0], depth[1], n)
    xy = rng.uniform(-spread, spread, (n, 2)) * z[:, None]
    camera = np.column_stack([xy, z])
    return np.round((camera - t) @ R, 4)  # Rᵀ(M_C − t), rounded: readable, still in front


def _coefficients(rng: np.random.Generator, count: int = 3, scale: float = 1.0, tangential: bool = True):
    drawn = [_u(rng, 0.1, 0.3, 4) * rng.choice([-1, 1]), _u(rng, 0.02, 0.1, 4) * rng.choice([-1, 1]),
             _u(rng, 0.005, 0.02, 4) * rng.choice([-1, 1])][:count]
    k = tuple(float(v) * scale for v in drawn)
    if not tangential:
        return k, (0.0, 0.0)
    p1 = _u(rng, 0.0005, 0.002, 5) * rng.choice([-1, 1])
    p2 = _u(rng, 0.0005, 0.002, 5) * rng.choice([-1, 1])
    return k, (float(p1), float(p2))


def _normalized(rng: np.random.Generator, n: int, half: float = 0.4) -> np.ndarray:
    return np.round(rng.uniform(-half, half, (n, 2)), 4)


# The public camera: unequal focal lengths, off-centre principal point, all three angles.
_A1 = _intrinsic_matrix(800.0, 790.0, 320.0, 240.0)
_R1 = _rotation_matrix(0.1, -0.2, 0.3)
_T1 = np.array([0.5, -0.3, 4.0])
_A2 = _intrinsic_matrix(600.0, 650.0, 310.5, 200.5, 1.5)
_R2 = _rotation_matrix(-0.7, 0.5, 2.0)
_T2 = np.array([[1.0], [2.0], [10.0]])
_WORLD = np.array([[0.0, 0.0, 0.0], [1.0, -0.5, 2.0], [-1.5, 0.8, 1.0], [0.3, 1.2, -1.0],
                   [2.0, 1.0, 3.5], [-0.8, -1.1, 0.6]])


# --------------------------------------------------------------------------------------------
# camera.to_homogeneous (§7.4.1)
# --------------------------------------------------------------------------------------------
@mistake("1 prepended instead of appended", "The homogeneous coordinate goes last: [x, y] → [x, y, 1]")
def _th_prepend(points):
    p = np.asarray(points, dtype=np.float64)
    return np.concatenate([np.ones(p.shape[:-1] + (1,)), p], axis=-1)


@mistake("0 appended (that makes a direction)",
         "Append a 1; [x, y, 0] is the point at infinity in the direction (x, y) (§7.4.2)")
def _th_zero(points):
    p = np.asarray(points, dtype=np.float64)
    return np.concatenate([p, np.zeros(p.shape[:-1] + (1,))], axis=-1)


@mistake("row of ones added (wrong axis)",
         "Points are rows: add a column, along the last axis (np.concatenate(..., axis=-1))")
def _th_row(points):
    p = np.asarray(points, dtype=np.float64)
    return np.vstack([p, np.ones(p.shape[-1])])


@mistake("integer dtype kept (np.ones_like)",
         "Return float64 even for integer points: np.asarray(points, dtype=float) first")
def _th_ones_like(points):
    p = np.asarray(points)
    return np.concatenate([p, np.ones_like(p[..., :1])], axis=-1)


def _th_hidden(rng):
    return [
        Case((np.round(rng.normal(0, 100, (_n(rng, 5, 9), 2)), 3),), {}, "image points (N, 2)"),
        Case((np.round(rng.normal(0, 10, (_n(rng, 4, 8), 3)), 3),), {}, "world points (N, 3)"),
        Case((rng.integers(-500, 500, (_n(rng, 4, 8), 2)),), {}, "int64 points (result float)"),
        Case((rng.integers(0, 256, (_n(rng, 3, 7), 2), dtype=np.uint8),), {}, "uint8 points"),
        Case((rng.integers(-50, 50, (_n(rng, 3, 6), 3), dtype=np.int32),), {}, "int32 world points"),
        Case((np.round(rng.normal(0, 5, 3), 3),), {}, "a single 3-D point of shape (3,)"),
        Case((rng.integers(0, 640, 2),), {}, "a single integer pixel of shape (2,)"),
        Case((np.round(rng.normal(0, 5, (1, 2)), 3),), {}, "one point, shape (1, 2)"),
        Case((rng.uniform(-1e6, 1e6, (_n(rng, 4, 7), 3)),), {}, "±1e6 coordinates"),
        Case((np.round(rng.normal(0, 3, (_n(rng, 4, 7), 1)), 3),), {}, "1-D points (N, 1)"),
        Case((np.round(rng.normal(0, 3, (_n(rng, 3, 6), 4)), 3),), {}, "4-D points (N, 4)"),
    ]


to_homogeneous = Check(
    rules=("integer", "single point"),
    public=[
        Case((np.array([[0.5, -1.25], [3.0, 4.0], [-2.0, 0.75], [10.0, -7.5]]),), {}, "4 image points (x, y)"),
        Case((np.array([[1, 2, 3], [-4, 0, 6], [7, -8, 9]]),), {}, "3 integer world points (x, y, z)"),
        Case((np.array([2.5, -1.0]),), {}, "a single point of shape (2,)"),
    ],
    hidden=_th_hidden,
    compare=FloatClose(rtol=0.0, atol=0.0),
    mistakes=[_th_prepend, _th_zero, _th_row, _th_ones_like],
)


# --------------------------------------------------------------------------------------------
# camera.from_homogeneous (§7.4.1)
# --------------------------------------------------------------------------------------------
@mistake("no division (last coordinate dropped)",
         "Divide by the last coordinate before dropping it: [x̃, ỹ, w] → [x̃/w, ỹ/w]")
def _fh_drop(points_h):
    return np.asarray(points_h, dtype=np.float64)[..., :-1].copy()


@mistake("divided by the third coordinate, not the last",
         "Divide by the LAST coordinate (index -1): for 3-D points (x, y, z, w) that is w, not z")
def _fh_third(points_h):
    p = np.asarray(points_h, dtype=np.float64)
    return p[..., :-1] / p[..., 2:3]


@mistake("last coordinate kept (x/w, y/w, 1)",
         "Drop the last coordinate after dividing: the result has one coordinate fewer")
def _fh_keep(points_h):
    p = np.asarray(points_h, dtype=np.float64)
    return p / p[..., -1:]


@mistake("floor division (//)", "Use true division `/` (float result); `//` rounds down")
def _fh_floor(points_h):
    p = np.asarray(points_h)
    return (p[..., :-1] // p[..., -1:]).astype(np.float64)


@mistake("points at infinity set to 0",
         "Do not skip w = 0: dividing gives ±inf (nan for 0/0), which says 'at infinity'")
def _fh_zero_at_infinity(points_h):
    p = np.asarray(points_h, dtype=np.float64)
    w = np.broadcast_to(p[..., -1:], p[..., :-1].shape)
    return np.divide(p[..., :-1], w, out=np.zeros(w.shape), where=w != 0)


def _w(rng, n):
    return np.round(rng.uniform(0.5, 3.0, n) * rng.choice([-1, 1], n), 3)


def _fh_hidden(rng):
    def pts(n, d, w=None):
        out = np.round(rng.normal(0, 5, (n, d)), 3)
        out[:, -1] = _w(rng, n) if w is None else w
        return out

    n = _n(rng, 4, 7)
    at_infinity = pts(n, 3)
    at_infinity[: n // 2, -1] = 0.0
    at_infinity[0, 0] = -abs(at_infinity[0, 0]) - 1.0
    at_infinity[1, :] = [0.0, 2.5, 0.0]
    ints = rng.integers(-60, 60, (_n(rng, 4, 7), 3))
    ints[:, -1] = rng.choice([-7, -3, 2, 4, 9], len(ints))
    small = rng.integers(1, 256, (_n(rng, 3, 6), 3), dtype=np.uint8)
    return [
        Case((pts(_n(rng, 5, 9), 3),), {}, "image points with various w (N, 3)"),
        Case((pts(_n(rng, 4, 8), 4),), {}, "3-D points (N, 4)"),
        Case((ints,), {}, "integer points, w does not divide the coordinates"),
        Case((small,), {}, "uint8 points"),
        Case((pts(1, 3)[0],), {}, "a single point of shape (3,)"),
        Case((pts(1, 4)[0],), {}, "a single 3-D point of shape (4,)"),
        Case((at_infinity,), {}, "points at infinity among finite points (±inf, nan for 0/0)"),
        Case((pts(_n(rng, 3, 6), 3, -np.round(rng.uniform(0.2, 4, 1), 3)),), {}, "negative w only"),
        Case((pts(_n(rng, 3, 6), 3, np.round(rng.uniform(1e-9, 1e-8), 12)),), {}, "tiny w (far points)"),
        Case((np.column_stack([rng.uniform(-1e6, 1e6, (5, 2)), rng.uniform(1, 5, 5)]),), {}, "±1e6 coordinates"),
        Case((pts(_n(rng, 3, 6), 2),), {}, "1-D homogeneous points (N, 2)"),
    ]


from_homogeneous = Check(
    rules=("no warnings", "single point"),
    public=[
        Case((np.array([[6.0, -4.0, 2.0], [3.0, 1.5, -3.0], [-1.0, 2.0, 0.5], [7.0, 5.0, 4.0]]),), {},
             "4 image points with w = 2, −3, 0.5, 4"),
        Case((np.array([[2.0, -1.0, 0.0], [0.0, 0.0, 0.0], [4.0, 6.0, 2.0], [0.0, 3.0, 0.0]]),), {},
             "points at infinity: w = 0 gives ±inf, and nan for 0/0"),
        Case((np.array([[7, 2, -9, 2], [5, 10, 3, 4], [-3, 1, 8, 5]]),), {}, "integer 3-D points (x, y, z, w)"),
    ],
    hidden=_fh_hidden,
    compare=FloatClose(rtol=1e-10, atol=1e-12),
    mistakes=[_fh_drop, _fh_third, _fh_keep, _fh_floor, _fh_zero_at_infinity],
)


# --------------------------------------------------------------------------------------------
# camera.intrinsic_matrix (§7.5.2)
# --------------------------------------------------------------------------------------------
@mistake("principal point in the bottom row (A transposed)",
         "A is upper triangular: [[fu, s, u0], [0, fv, v0], [0, 0, 1]] — u0, v0 in the last column")
def _im_transposed(fu, fv, u0, v0, skew=0.0):
    return _intrinsic_matrix(fu, fv, u0, v0, skew).T


@mistake("fu and fv swapped", "fu (horizontal pixels) scales x into u: A[0, 0] = fu, A[1, 1] = fv")
def _im_f_swapped(fu, fv, u0, v0, skew=0.0):
    return _intrinsic_matrix(fv, fu, u0, v0, skew)


@mistake("u0 and v0 swapped", "u0 is the column (x) of the principal point: A[0, 2] = u0, A[1, 2] = v0")
def _im_pp_swapped(fu, fv, u0, v0, skew=0.0):
    return _intrinsic_matrix(fu, fv, v0, u0, skew)


@mistake("skew at A[1, 0] instead of A[0, 1]", "The skew mixes y into u: it goes in the first row, A[0, 1]")
def _im_skew_below(fu, fv, u0, v0, skew=0.0):
    A = _intrinsic_matrix(fu, fv, u0, v0)
    A[1, 0] = float(skew)
    return A


@mistake("skew ignored", "Put the skew argument at A[0, 1]")
def _im_no_skew(fu, fv, u0, v0, skew=0.0):
    return _intrinsic_matrix(fu, fv, u0, v0)


def _im_hidden(rng):
    def f():
        return _u(rng, 300, 1500, 2)

    fu = f()
    return [
        Case((f(), f(), _u(rng, 200, 400, 2), _u(rng, 100, 300, 2)), {}, "no skew (default)"),
        Case((f(), f(), _u(rng, 200, 400, 2), _u(rng, 100, 300, 2), _u(rng, 0.5, 5, 3)), {}, "skew given"),
        Case((f(), f(), _u(rng, 200, 400, 2), _u(rng, 100, 300, 2)), {"skew": -_u(rng, 0.5, 5, 3)},
             "negative skew as keyword"),
        Case((_n(rng, 300, 900), _n(rng, 300, 900), _n(rng, 100, 400), _n(rng, 50, 300)), {}, "integer arguments"),
        Case((np.float64(f()), np.float64(f()), np.float64(_u(rng, 200, 400)), np.float64(_u(rng, 100, 300))), {},
             "NumPy float scalars"),
        Case((fu, fu, _u(rng, 200, 400, 2), _u(rng, 100, 300, 2), _u(rng, 0.5, 3, 3)), {}, "square pixels (fu = fv), skew"),
        Case((f(), f(), 256.0, 256.0), {}, "principal point on the diagonal (u0 = v0)"),
        Case((_u(rng, 5e3, 2e4, 1), _u(rng, 5e3, 2e4, 1), _u(rng, 1e3, 3e3, 1), _u(rng, 500, 2e3, 1)), {},
             "telephoto: large focal lengths"),
        Case((_u(rng, 1, 3), _u(rng, 1, 3), _u(rng, 0.2, 0.8), _u(rng, 0.2, 0.8), _u(rng, 0.01, 0.1)), {},
             "small values (metric units)"),
    ]


intrinsic_matrix = Check(
    public=[
        Case((800.0, 780.0, 320.5, 240.25), {}, "fu ≠ fv, no skew"),
        Case((500.0, 520.0, 300.0, 200.0, 2.5), {}, "skew = 2.5"),
    ],
    hidden=_im_hidden,
    compare=FloatClose(rtol=1e-12, atol=0.0),
    mistakes=[_im_transposed, _im_f_swapped, _im_pp_swapped, _im_skew_below, _im_no_skew],
)


# --------------------------------------------------------------------------------------------
# camera.rotation_matrix (§7.3)
# --------------------------------------------------------------------------------------------
def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@mistake("rotation order reversed (Rx·Ry·Rz)",
         "R = Rz(yaw) @ Ry(pitch) @ Rx(roll): the rightmost factor acts first, roll comes first")
def _rm_reversed(roll, pitch, yaw):
    return _rx(roll) @ _ry(pitch) @ _rz(yaw)


@mistake("roll and yaw swapped (roll about z)", "roll turns about x, pitch about y, yaw about z")
def _rm_roll_yaw_swapped(roll, pitch, yaw):
    return _rz(roll) @ _ry(pitch) @ _rx(yaw)


@mistake("passive rotations (each matrix transposed)",
         "Use the active matrices: Rz(a) = [[cos a, −sin a, 0], [sin a, cos a, 0], [0, 0, 1]], same pattern for Rx")
def _rm_passive(roll, pitch, yaw):
    return _rz(yaw).T @ _ry(pitch).T @ _rx(roll).T


@mistake("signs of sin in Ry swapped",
         "Ry(a) = [[cos a, 0, sin a], [0, 1, 0], [−sin a, 0, cos a]]: +sin in the first row")
def _rm_ry_sign(roll, pitch, yaw):
    return _rz(yaw) @ _ry(pitch).T @ _rx(roll)


@mistake("angles taken as degrees", "Angles are already in radians: no np.deg2rad / np.radians")
def _rm_degrees(roll, pitch, yaw):
    return _rotation_matrix(*np.deg2rad([float(roll), float(pitch), float(yaw)]))


def _rm_hidden(rng):
    return [
        Case(_angles(rng), {}, "three angles"),
        Case(_angles(rng), {}, "three other angles"),
        Case(_angles(rng), {}, "three more angles"),
        Case((_u(rng, 0.2, 1.0), np.pi / 2, _u(rng, -1.0, -0.2)), {}, "pitch = π/2 (gimbal lock)"),
        Case((_u(rng, 6.5, 9.0), -_u(rng, 6.5, 9.0), _u(rng, 10.0, 14.0)), {}, "angles beyond 2π"),
        Case((_u(rng, 0.01, 0.03, 4), -_u(rng, 0.01, 0.03, 4), _u(rng, 0.01, 0.03, 4)), {}, "small angles"),
        Case((_n(rng, 1, 3), -_n(rng, 1, 3), _n(rng, 1, 3)), {}, "integer angles"),
        Case((0.0, 0.0, _u(rng, 0.3, 2.5)), {}, "yaw only"),
        Case((_u(rng, 0.3, 2.5), _u(rng, 0.3, 1.2), 0.0), {}, "roll and pitch, no yaw"),
        Case((np.float64(_u(rng, -3, 3)), np.float64(_u(rng, -1.5, 1.5)), np.float64(_u(rng, -3, 3))), {},
             "NumPy float scalars"),
        Case((0.0, 0.0, 0.0), {}, "all zero (identity)"),
    ]


rotation_matrix = Check(
    public=[
        Case((0.3, -0.5, 1.1), {}, "roll 0.3, pitch −0.5, yaw 1.1"),
        Case((1.2, 0.4, -2.0), {}, "roll 1.2, pitch 0.4, yaw −2.0"),
        Case((0.0, 0.8, 0.0), {}, "pitch only"),
    ],
    hidden=_rm_hidden,
    compare=FloatClose(rtol=1e-9, atol=1e-12),
    mistakes=[_rm_reversed, _rm_roll_yaw_swapped, _rm_passive, _rm_ry_sign, _rm_degrees],
)


# --------------------------------------------------------------------------------------------
# camera.extrinsic_matrix (§7.5.3)
# --------------------------------------------------------------------------------------------
def _vec(t):
    return np.asarray(t, dtype=np.float64).reshape(3)


@mistake("t in the bottom row (transposed layout)",
         "G = [[R, t], [0, 0, 0, 1]]: t is the last column, the bottom row is [0, 0, 0, 1]")
def _em_transposed_layout(R, t):
    G = np.eye(4)
    G[:3, :3] = np.asarray(R, dtype=np.float64)
    G[3, :3] = _vec(t)
    return G


@mistake("R transposed", "Use R itself in the top-left block: M_C = R·M_W + t")
def _em_r_transposed(R, t):
    return _extrinsic_matrix(np.asarray(R, dtype=np.float64).T, t)


@mistake("inverse motion (camera → world)",
         "G maps world to camera coordinates: [[R, t], [0, 1]], not its inverse [[Rᵀ, −Rᵀt], [0, 1]]")
def _em_inverse(R, t):
    Rt = np.asarray(R, dtype=np.float64).T
    return _extrinsic_matrix(Rt, -Rt @ _vec(t))


@mistake("bottom-right 1 missing", "The bottom row of G is [0, 0, 0, 1]")
def _em_no_one(R, t):
    G = _extrinsic_matrix(R, t)
    G[3, 3] = 0.0
    return G


def _em_hidden(rng):
    def rot():
        return _rotation_matrix(*_angles(rng))

    def trans():
        return np.round(rng.uniform(-5, 5, 3), 3)

    return [
        Case((rot(), trans()), {}, "random pose"),
        Case((rot(), trans()), {}, "another random pose"),
        Case((rot(), trans().tolist()), {}, "t given as a list"),
        Case((rot(), trans().reshape(3, 1)), {}, "t given as a (3, 1) column"),
        Case((rot(), np.zeros(3)), {}, "t = 0"),
        Case((np.eye(3), trans()), {}, "R = I"),
        Case((rot(), rng.integers(-9, 10, 3)), {}, "integer t"),
        Case((rot(), np.round(rng.uniform(-1e4, 1e4, 3), 2)), {}, "large translation"),
        Case((_rotation_matrix(0.0, 0.0, np.pi), trans()), {}, "yaw = π"),
    ]


extrinsic_matrix = Check(
    public=[
        Case((_rotation_matrix(0.2, -0.4, 0.9), np.array([1.0, -2.0, 5.0])), {}, "rotation about 3 axes, t (3,)"),
        Case((_rotation_matrix(-1.0, 0.3, 0.5), np.array([[0.5], [0.25], [-3.0]])), {}, "t as a (3, 1) column"),
    ],
    hidden=_em_hidden,
    compare=FloatClose(rtol=1e-12, atol=1e-14),
    mistakes=[_em_transposed_layout, _em_r_transposed, _em_inverse, _em_no_one],
)


# --------------------------------------------------------------------------------------------
# camera.projection_matrix (§7.6)
# --------------------------------------------------------------------------------------------
@mistake("t not multiplied by A ([A·R | t])", "P = A·[R | t]: A multiplies the whole 3×4 matrix, the t column included")
def _pm_t_outside(A, R, t):
    return np.column_stack([np.asarray(A, dtype=np.float64) @ np.asarray(R, dtype=np.float64), _vec(t)])


@mistake("R transposed", "Use R itself: P = A·[R | t]")
def _pm_r_transposed(A, R, t):
    return np.asarray(A, dtype=np.float64) @ np.column_stack([np.asarray(R, dtype=np.float64).T, _vec(t)])


@mistake("t taken as the camera centre (A·[R | −R·t])",
         "t is the world origin seen from the camera, not the camera's position: P = A·[R | t]")
def _pm_centre(A, R, t):
    R = np.asarray(R, dtype=np.float64)
    return np.asarray(A, dtype=np.float64) @ np.column_stack([R, -R @ _vec(t)])


@mistake("camera → world pose used (A·[Rᵀ | −Rᵀt])",
         "R, t map world to camera coordinates already: P = A·[R | t], no inversion")
def _pm_inverse(A, R, t):
    Rt = np.asarray(R, dtype=np.float64).T
    return np.asarray(A, dtype=np.float64) @ np.column_stack([Rt, -Rt @ _vec(t)])


def _pm_hidden(rng):
    return [
        Case(_camera(rng), {}, "random camera"),
        Case(_camera(rng, skew=True), {}, "camera with skew"),
        Case(_camera(rng), {}, "another random camera"),
        Case((_intrinsics(rng), _rotation_matrix(*_angles(rng)), np.zeros(3)), {}, "t = 0"),
        Case((_intrinsics(rng), np.eye(3), np.round(rng.uniform(-2, 2, 3), 3)), {}, "R = I"),
        Case((_intrinsic_matrix(_n(rng, 400, 900), _n(rng, 400, 900), _n(rng, 200, 400), _n(rng, 100, 300)),
              _rotation_matrix(*_angles(rng)), rng.integers(-5, 6, 3)), {}, "integer A and t"),
        Case((_intrinsics(rng), _rotation_matrix(*_angles(rng)), np.round(rng.uniform(-1, 1, 3), 3).reshape(3, 1)), {},
             "t as a (3, 1) column"),
        Case((_intrinsics(rng), _rotation_matrix(*_angles(rng)), np.round(rng.uniform(-1, 1, 3), 3).tolist()), {},
             "t as a list"),
        Case((_intrinsic_matrix(_u(rng, 1.0, 3.0), _u(rng, 1.0, 3.0), _u(rng, 0.1, 0.5), _u(rng, 0.1, 0.5)),
              _rotation_matrix(*_angles(rng)), np.round(rng.uniform(-1e3, 1e3, 3), 2)), {},
             "metric intrinsics, large translation"),
    ]


projection_matrix = Check(
    public=[
        Case((_A1, _R1, _T1), {}, "fu ≠ fv, rotation about 3 axes, t (3,)"),
        Case((_A2, _R2, _T2), {}, "camera with skew, t as a (3, 1) column"),
    ],
    hidden=_pm_hidden,
    compare=FloatClose(rtol=1e-10, atol=1e-9),
    mistakes=[_pm_t_outside, _pm_r_transposed, _pm_centre, _pm_inverse],
    allowed=("camera.extrinsic_matrix",),
)


# --------------------------------------------------------------------------------------------
# camera.project (§7.6, §7.5.1)
# --------------------------------------------------------------------------------------------
def _homog(P, points_world):
    pts = np.asarray(points_world, dtype=np.float64)
    if pts.shape[1] == 3:
        pts = np.column_stack([pts, np.ones(len(pts))])
    return pts @ np.asarray(P, dtype=np.float64).T, pts


@mistake("forgot the division by z", "After k·m̃ = P·M̃ divide by the third coordinate k: u = m̃₁/m̃₃, v = m̃₂/m̃₃")
def _pr_no_division(P, points_world):
    return _homog(P, points_world)[0][:, :2].copy()


@mistake("w ignored (homogeneous input treated as w = 1)",
         "Use (x, y, z, w) as given; only (N, 3) points get a 1 appended. w = 0 is a direction")
def _pr_w_ignored(P, points_world):
    return _project(P, np.asarray(points_world, dtype=np.float64)[:, :3])


@mistake("divided by the world z, not by the projected third coordinate",
         "Divide by the third row of P·M̃ (the depth z_C in the camera frame), not by the point's world z")
def _pr_world_z(P, points_world):
    projected, pts = _homog(P, points_world)
    return projected[:, :2] / pts[:, 2:3]


@mistake("u and v swapped", "Return (u, v) = (x, y) = (column, row): the first row of P gives u")
def _pr_swapped(P, points_world):
    return _project(P, points_world)[:, ::-1].copy()


def _pr_hidden(rng):
    A, R, t = _camera(rng)
    P = _projection_matrix(A, R, t)
    A2, R2, t2 = _camera(rng, skew=True)
    P2 = _projection_matrix(A2, R2, t2)
    n = _n(rng, 4, 7)
    homogeneous = np.column_stack([_points_in_front(rng, R, t, n), np.ones(n)])
    w = _w(rng, n)
    homogeneous *= w[:, None]
    directions = np.vstack([np.eye(3), np.round(rng.normal(0, 1, (2, 3)), 3)])
    A3 = _intrinsics(rng)
    P3 = _projection_matrix(A3, np.eye(3), np.round(np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), 5.0]), 3))
    parallel = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
                         [_u(rng, 0.2, 1), _u(rng, 0.2, 1), _u(rng, 0.5, 1), 0.0]])
    behind = _points_in_front(rng, R, t, 5, depth=(1.0, 4.0))
    camera_behind = (behind @ R.T + t) * np.array([1.0, 1.0, -1.0])
    behind[:2] = np.round((camera_behind[:2] - t) @ R, 4)
    far = _points_in_front(rng, R, t, 4, depth=(1e5, 1e6))
    return [
        Case((P, _points_in_front(rng, R, t, _n(rng, 5, 9))), {}, "points in front of a random camera"),
        Case((P2 * float(np.exp(rng.uniform(-7, 7))), _points_in_front(rng, R2, t2, _n(rng, 4, 8))), {},
             "P scaled by a positive factor (skewed camera)"),
        Case((-_u(rng, 0.01, 100) * P, _points_in_front(rng, R, t, _n(rng, 4, 8))), {}, "P scaled by a negative factor"),
        Case((P, homogeneous), {}, "homogeneous points (N, 4) with various w"),
        Case((P2, np.column_stack([directions, np.zeros(len(directions))])), {},
             "directions (w = 0): vanishing points"),
        Case((P3, parallel), {}, "directions parallel to the image plane (±inf / nan)"),
        Case((np.round(P).astype(np.int64), np.round(_points_in_front(rng, R, t, 1)).astype(np.int64)), {},
             "one integer point, integer P"),
        Case((P, far), {}, "far points (near their vanishing points)"),
        Case((P, behind), {}, "two points behind the camera"),
        Case((P2, np.round(rng.uniform(-3, 3, (_n(rng, 4, 7), 3)), 2)), {}, "arbitrary world points"),
    ]


_P1 = _projection_matrix(_A1, _R1, _T1)
_P2 = _projection_matrix(_A2, _R2, _T2)

project = Check(
    rules=("no warnings",),
    public=[
        Case((_P1, _WORLD), {}, "6 world points (N, 3)"),
        Case((-0.01 * _P1, np.array([[2.0, -1.0, 4.0, 2.0], [0.5, 0.25, -0.5, 0.5], [1.0, 1.0, 1.0, 1.0],
                                     [0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0]])), {},
         "P × (−0.01), homogeneous points with w = 2, 0.5, 1 and two directions (w = 0)"),
        Case((_P2, np.array([[1, 2, 3], [-2, 0, 5], [4, -3, -1]])), {}, "skewed camera, integer points"),
    ],
    hidden=_pr_hidden,
    compare=FloatClose(rtol=1e-9, atol=1e-9),
    mistakes=[_pr_no_division, _pr_w_ignored, _pr_world_z, _pr_swapped],
    allowed=("camera.to_homogeneous", "camera.from_homogeneous"),
)


# --------------------------------------------------------------------------------------------
# camera.decompose_projection (§7.6.1)
# --------------------------------------------------------------------------------------------
def _dp_raw(P, rq):
    mat = np.asarray(P, dtype=np.float64)
    M, p4 = mat[:, :3], mat[:, 3]
    sign = np.sign(np.linalg.det(M))
    K, Q = rq(sign * M)
    return K, Q, sign * p4


@mistake("RQ sign fix missing (QR of the flipped matrix)",
         "RQ is unique only up to signs: with D = diag(sign(diag K)), use A ∝ K·D and R = D·Q")
def _dp_no_diag_fix_numpy(P):
    K, Q, p4 = _dp_raw(P, _rq)
    return K / K[2, 2], Q, np.linalg.solve(K, p4)


@mistake("RQ sign fix missing (scipy.linalg.rq)",
         "RQ is unique only up to signs: with D = diag(sign(diag K)), use A ∝ K·D and R = D·Q")
def _dp_no_diag_fix_scipy(P):
    import scipy.linalg  # here: importing it costs every grading process 0.4 s of CPU

    K, Q, p4 = _dp_raw(P, scipy.linalg.rq)
    return K / K[2, 2], Q, np.linalg.solve(K, p4)


@mistake("overall sign of P not fixed (det R = −1)",
         "P is known up to a scale λ that may be negative: multiply P by sign(det P[:, :3]) first, so det R = +1")
def _dp_no_det_fix(P):
    mat = np.asarray(P, dtype=np.float64)
    K, Q = _rq(mat[:, :3])
    D = np.sign(np.diag(K))
    K, Q = K * D, D[:, None] * Q
    return K / K[2, 2], Q, np.linalg.solve(K, mat[:, 3])


@mistake("A not normalised (A[2, 2] ≠ 1)", "Divide the triangular factor by its bottom-right entry: A = K / K[2, 2]")
def _dp_not_normalised(P):
    A, R, t = _decompose_projection(P)
    M = np.asarray(P, dtype=np.float64)[:, :3]
    scale = abs(np.linalg.det(M)) ** (1 / 3) / abs(np.linalg.det(A)) ** (1 / 3)  # |λ|: K = |λ|·A
    return A * scale, R, t


@mistake("t read off the last column (A⁻¹ not applied)",
         "The last column of P is λ·A·t: solve K·t = p₄ (np.linalg.solve), do not just divide by λ")
def _dp_last_column(P):
    A, R, t = _decompose_projection(P)
    mat = np.asarray(P, dtype=np.float64)
    lam = np.sign(np.linalg.det(mat[:, :3])) * abs(np.linalg.det(mat[:, :3])) ** (1 / 3) / np.linalg.det(A) ** (1 / 3)
    return A, R, mat[:, 3] / lam


@mistake("camera centre returned instead of t",
         "Return t = K⁻¹·p₄ (world origin in camera coordinates); the camera centre C = −Rᵀt is another thing")
def _dp_centre(P):
    A, R, t = _decompose_projection(P)
    return A, R, -R.T @ t


@mistake("QR instead of RQ",
         "M = A·R is upper-triangular × orthogonal: that is an RQ decomposition (QR gives orthogonal × upper)")
def _dp_qr(P):
    mat = np.asarray(P, dtype=np.float64)
    M, p4 = mat[:, :3], mat[:, 3]
    sign = np.sign(np.linalg.det(M))
    Q, K = np.linalg.qr(sign * M)   # M = Q·K: orthogonal times upper triangular
    D = np.sign(np.diag(K))
    K, Q = D[:, None] * K, Q * D
    return K / K[2, 2], Q, np.linalg.solve(K, sign * p4)


def _dp_hidden(rng):
    def P(camera, scale=1.0):
        return scale * _projection_matrix(*camera)

    def scale(lo=-3, hi=3):
        return float(np.exp(rng.uniform(lo, hi)))

    A_aniso = _intrinsic_matrix(_u(rng, 300, 500), _u(rng, 1500, 2500), -_u(rng, 50, 200), _u(rng, 600, 900))
    return [
        Case((P(_camera(rng)),), {}, "P = A[R|t] (λ = 1)"),
        Case((P(_camera(rng), scale()),), {}, "positive multiple of a PPM"),
        Case((P(_camera(rng), -scale()),), {}, "negative multiple of a PPM"),
        Case((P(_camera(rng, skew=True), scale() * rng.choice([-1, 1])),), {}, "camera with skew"),
        Case((P((_intrinsics(rng), np.eye(3), np.zeros(3)), scale(0.5, 2)),), {}, "R = I, t = 0, λ > 1"),
        Case((P(_camera(rng), scale(-17, -15)),), {}, "tiny scale (λ ≈ 1e-7)"),
        Case((P(_camera(rng), -scale(13, 14)),), {}, "huge negative scale (λ ≈ −1e6)"),
        Case((P((_intrinsics(rng), _rotation_matrix(_u(rng, 2.8, 3.1), _u(rng, -0.3, 0.3), _u(rng, 2.8, 3.1)),
                 np.round(rng.uniform(-2, 2, 3), 3))),), {}, "camera turned by about π about two axes"),
        Case((np.round(P(_camera(rng)) * 10).astype(np.int64),), {}, "integer P"),
        Case((P((A_aniso,) + _pose(rng), -1.0),), {}, "very anisotropic pixels, negative u0, λ = −1"),
    ]


decompose_projection = Check(
    public=[
        Case((_P1,), {}, "P = A[R|t] exactly (λ = 1)"),
        Case((0.0037 * _P2,), {}, "P = 0.0037·A[R|t], skewed camera"),
        Case((-2.0 * _projection_matrix(_intrinsic_matrix(700.0, 720.0, 330.0, 250.0), _rotation_matrix(2.5, -0.4, 0.8),
                                        np.array([-0.4, 0.2, 6.0])),), {},
             "P = −2·A[R|t] (negative multiple)"),
    ],
    hidden=_dp_hidden,
    refusals=[
        Case((np.array([[800.0, 0.0, 0.0, 10.0], [0.0, 800.0, 0.0, 20.0], [0.0, 0.0, 0.0, 1.0]]),), {},
             "a left 3×3 block with a zero column (singular)", raises="ValueError"),
    ],
    compare=Parts(names=("A", "R", "t"), inner=FloatClose(rtol=1e-7, atol=1e-8)),
    mistakes=[_dp_no_diag_fix_numpy, _dp_no_diag_fix_scipy, _dp_no_det_fix, _dp_not_normalised, _dp_last_column,
              _dp_centre, _dp_qr],
)


# --------------------------------------------------------------------------------------------
# camera.distort (§7.7.2)
# --------------------------------------------------------------------------------------------
#: the tangential mistake shared by distort, undistort_points and project_full, with OpenCV's order
_P_SWAPPED = "p1 and p2 swapped"
_P_ORDER = "Δx = 2·p1·x·y + p2·(r² + 2x²), Δy = p1·(r² + 2y²) + 2·p2·x·y (OpenCV's order)"


def _distort_variant(xy_normalized, k=(0.0, 0.0, 0.0), p=(0.0, 0.0), *, swap_p=False, r2_power=1,
                     radial_on_tangential=False, tangential_xy_swapped=False, drop_k3=False):
    xy = np.asarray(xy_normalized, dtype=np.float64)
    kk, pp = distortion_coefficients(k, p)
    if drop_k3:
        kk = np.array([kk[0], kk[1], 0.0])
    if swap_p:
        pp = pp[::-1]
    x, y = xy[:, 0], xy[:, 1]
    r2 = (x * x + y * y) ** r2_power
    radial = 1.0 + kk[0] * r2 + kk[1] * r2 ** 2 + kk[2] * r2 ** 3
    rr = x * x + y * y
    if tangential_xy_swapped:
        dx = 2 * pp[0] * x * y + pp[1] * (rr + 2 * y * y)
        dy = pp[0] * (rr + 2 * x * x) + 2 * pp[1] * x * y
    else:
        dx = 2 * pp[0] * x * y + pp[1] * (rr + 2 * x * x)
        dy = pp[0] * (rr + 2 * y * y) + 2 * pp[1] * x * y
    if radial_on_tangential:
        return np.column_stack([(x + dx) * radial, (y + dy) * radial])
    return np.column_stack([x * radial + dx, y * radial + dy])


_dist = partial(variant, _distort_variant)


def _distort_hidden(rng):
    def pts(n, half=0.4):
        return _normalized(rng, n, half)

    with_origin = pts(_n(rng, 4, 7))
    with_origin[0] = 0.0
    return [
        Case((pts(_n(rng, 5, 9)),) + _coefficients(rng, 3), {}, "k1, k2, k3 and p1, p2"),
        Case((pts(_n(rng, 5, 9)),) + _coefficients(rng, 3), {}, "other k1, k2, k3 and p1, p2"),
        Case((pts(_n(rng, 4, 8)),) + _coefficients(rng, 1), {}, "one radial coefficient (k1,)"),
        Case((pts(_n(rng, 4, 8)),) + _coefficients(rng, 2), {}, "two radial coefficients (k1, k2)"),
        Case((pts(_n(rng, 4, 8)),) + _coefficients(rng, 3, tangential=False), {}, "radial only (p = 0)"),
        Case((pts(_n(rng, 4, 8)), (0.0,), _coefficients(rng, 1)[1]), {}, "tangential only (k = (0,))"),
        Case((pts(_n(rng, 4, 8), 1.2),) + _coefficients(rng, 3, scale=0.3), {}, "wide angle: |x|, |y| ≤ 1.2"),
        Case((with_origin,) + _coefficients(rng, 3), {}, "the principal point (0, 0) among the points"),
        Case((pts(1),) + _coefficients(rng, 3), {}, "a single point"),
        Case((np.array([[0, 1], [1, 0], [-1, 1]]),) + _coefficients(rng, 3, scale=0.2), {}, "integer coordinates"),
        Case((pts(_n(rng, 4, 7)), np.array(_coefficients(rng, 3)[0]), list(_coefficients(rng, 3)[1])), {},
             "k as an array, p as a list"),
    ]


distort = Check(
    public=[
        Case((np.array([[0.1, 0.2], [-0.3, 0.15], [0.35, -0.25], [-0.05, -0.4], [0.25, 0.3]]),
              (-0.28, 0.09, -0.015), (0.0012, -0.0021)), {}, "barrel, k1, k2, k3 and p1 ≠ p2"),
        Case((np.array([[0.2, -0.1], [-0.4, 0.3], [0.05, 0.35]]), (0.2,), (-0.01, 0.004)), {},
             "pincushion, one radial coefficient, strong tangential"),
        Case((np.array([[0.8, -0.6], [-1.0, 0.5], [0.3, 0.9]]), (-0.3, 0.08, -0.01), (0.001, 0.002)), {},
             "wide angle: points far from the centre"),
    ],
    hidden=_distort_hidden,
    compare=FloatClose(rtol=1e-9, atol=1e-12),
    mistakes=[
        Mistake(_P_SWAPPED, _dist(swap_p=True), _P_ORDER),
        Mistake("r² squared again (k1·r⁴ + k2·r⁸ + k3·r¹²)", _dist(r2_power=2),
                "With r2 = x² + y² the radial factor is 1 + k1·r2 + k2·r2² + k3·r2³"),
        Mistake("radial factor applied to the tangential terms too", _dist(radial_on_tangential=True),
                "x_d = x·L(r) + Δx: the tangential shift is added after the radial scaling, not scaled by it"),
        Mistake("2x² and 2y² exchanged in the tangential terms", _dist(tangential_xy_swapped=True),
                "Δx uses r² + 2x², Δy uses r² + 2y²"),
        Mistake("k3 ignored", _dist(drop_k3=True), "Use all given radial coefficients: L = 1 + k1·r² + k2·r⁴ + k3·r⁶"),
    ],
)


# --------------------------------------------------------------------------------------------
# camera.undistort_points (§7.7)
# --------------------------------------------------------------------------------------------
@mistake("distortion applied instead of removed",
         "Invert the model: solve x_d = L(r)·x + Δ(x) for x; distort(x_d) goes the wrong way")
def _ud_distorts(xy_distorted, k, p, iterations=20):
    return _distort(xy_distorted, k, p)


@mistake("first-order inverse 2·x_d − distort(x_d)",
         "Subtracting the distortion once is only an approximation: iterate x ← (x_d − Δ(x)) / L(r(x))")
def _ud_first_order(xy_distorted, k, p, iterations=20):
    xd = np.asarray(xy_distorted, dtype=np.float64)
    return 2 * xd - _distort(xd, k, p)


@mistake("one step only", "Repeat the step `iterations` times, recomputing r, L and Δ from the current estimate")
def _ud_one_step(xy_distorted, k, p, iterations=20):
    return _undistort_points(xy_distorted, k, p, min(int(iterations), 1))


@mistake("tangential part not subtracted",
         "Each step is x ← (x_d − Δx(x)) / L, y ← (y_d − Δy(x)) / L: remove the tangential shift first")
def _ud_no_tangential(xy_distorted, k, p, iterations=20):
    xd = np.asarray(xy_distorted, dtype=np.float64)
    kk, _ = distortion_coefficients(k, p)
    x = xd.copy()
    for _ in range(int(iterations)):
        radial, _, _ = radial_tangential(x[:, 0], x[:, 1], kk, np.zeros(2))
        x = xd / radial[:, None]
    return x


@mistake(_P_SWAPPED, _P_ORDER)
def _ud_p_swapped(xy_distorted, k, p, iterations=20):
    return _undistort_points(xy_distorted, k, tuple(np.asarray(p, dtype=float)[::-1]), iterations)


@mistake("iterations ignored", "Do exactly `iterations` fixed-point steps, starting from x = x_d")
def _ud_iterations_ignored(xy_distorted, k, p, iterations=20):
    return _undistort_points(xy_distorted, k, p, 20)


def _ud_case(rng, n, count=3, half=0.4, tangential=True, scale=1.0):
    k, p = _coefficients(rng, count, scale=scale, tangential=tangential)
    return (np.round(_distort(_normalized(rng, n, half), k, p), 6), k, p)


def _ud_hidden(rng):
    origin = _ud_case(rng, _n(rng, 4, 6))
    origin[0][0] = 0.0
    return [
        Case(_ud_case(rng, _n(rng, 5, 9)), {}, "k1, k2, k3 and p1, p2 (usual range)"),
        Case(_ud_case(rng, _n(rng, 5, 9)), {}, "other k1, k2, k3 and p1, p2"),
        Case(_ud_case(rng, _n(rng, 4, 8), 1), {}, "one radial coefficient"),
        Case(_ud_case(rng, _n(rng, 4, 8), 2), {}, "two radial coefficients"),
        Case(_ud_case(rng, _n(rng, 4, 8), tangential=False), {}, "radial only (p = 0)"),
        Case(_ud_case(rng, _n(rng, 4, 8)), {"iterations": 1}, "iterations = 1"),
        Case(_ud_case(rng, _n(rng, 4, 8)), {"iterations": _n(rng, 2, 5)}, "a few iterations"),
        Case(_ud_case(rng, _n(rng, 4, 8), half=0.8, scale=0.2), {"iterations": 40}, "far from the centre, 40 iterations"),
        Case(origin, {}, "the principal point among the points"),
        Case(_ud_case(rng, 1), {}, "a single point"),
        Case((np.array([[0, 1], [1, 0], [-1, -1]]), (-0.05, 0.01), (0.001, -0.001)), {}, "integer coordinates, mild distortion"),
    ]


def _ud_public():
    k1, p1 = (-0.3, 0.1, -0.02), (0.002, -0.0015)
    ideal1 = np.array([[0.3, -0.2], [-0.35, 0.25], [0.1, 0.35], [-0.2, -0.3], [0.33, 0.31], [0.05, -0.05]])
    k2, p2 = (0.25,), (-0.001, 0.002)
    ideal2 = np.array([[0.2, 0.1], [-0.3, 0.3], [0.35, -0.15], [-0.1, -0.25], [0.0, 0.3]])
    k3, p3 = (0.2, 0.05), (0.001, 0.001)
    ideal3 = np.array([[0.3, 0.3], [-0.25, 0.1], [0.1, -0.35]])
    return [
        Case((np.round(_distort(ideal1, k1, p1), 8), k1, p1), {}, "barrel k1, k2, k3 and p1 ≠ p2, 20 iterations"),
        Case((np.round(_distort(ideal2, k2, p2), 8), k2, p2), {}, "pincushion, one radial coefficient"),
        Case((np.round(_distort(ideal3, k3, p3), 8), k3, p3), {"iterations": 3}, "only 3 iterations"),
    ]


undistort_points = Check(
    public=_ud_public,
    hidden=_ud_hidden,
    compare=FloatClose(rtol=1e-9, atol=1e-10),
    mistakes=[_ud_distorts, _ud_first_order, _ud_one_step, _ud_no_tangential, _ud_p_swapped, _ud_iterations_ignored],
)


# --------------------------------------------------------------------------------------------
# camera.project_full (§7.7.3)
# --------------------------------------------------------------------------------------------
def _pf_variant(points_world, A, R, t, k=(0.0, 0.0, 0.0), p=(0.0, 0.0), *, divide=True, pixel_distortion=False,
                swap_p=False, transpose_r=False, skew=True, distortion=True):
    X = np.asarray(points_world, dtype=np.float64)
    A = np.asarray(A, dtype=np.float64)
    R = np.asarray(R, dtype=np.float64)
    if transpose_r:
        R = R.T
    if swap_p:
        p = tuple(np.asarray(p, dtype=float)[::-1])
    cam = X @ R.T + _vec(t)
    xy = cam[:, :2] / cam[:, 2:] if divide else cam[:, :2]
    if distortion and not pixel_distortion:
        xy = _distort(xy, k, p)
    a = A / A[2, 2]
    s = a[0, 1] if skew else 0.0
    uv = np.column_stack([a[0, 0] * xy[:, 0] + s * xy[:, 1] + a[0, 2], a[1, 1] * xy[:, 1] + a[1, 2]])
    if pixel_distortion:
        uv = _distort(uv, k, p)
    return uv


_pf = partial(variant, _pf_variant)


def _pf_hidden(rng):
    def case(count=3, skew=False, tangential=True, n=None, depth=(2.0, 8.0), spread=0.4, t_form=None, scale=1.0):
        A, R, t = _camera(rng, skew)
        X = _points_in_front(rng, R, t, n or _n(rng, 5, 9), depth, spread)
        k, p = _coefficients(rng, count, scale=scale, tangential=tangential)
        if t_form == "list":
            t = t.tolist()
        elif t_form == "column":
            t = t.reshape(3, 1)
        return (X, A, R, t, k, p)

    no_distortion = case()[:4]
    ints = list(case(2))
    ints[0] = np.round(ints[0]).astype(np.int64)
    ints[0] = ints[0][(ints[0] @ ints[2].T + ints[3])[:, 2] > 0.5]  # keep points in front
    return [
        Case(case(), {}, "k1, k2, k3 and p1, p2"),
        Case(case(skew=True), {}, "camera with skew, full distortion"),
        Case(case(1), {}, "one radial coefficient"),
        Case(case(2, tangential=False), {}, "two radial coefficients, p = 0"),
        Case(no_distortion, {}, "no distortion (defaults)"),
        Case(case(t_form="list"), {}, "t as a list"),
        Case(case(skew=True, t_form="column"), {}, "t as a (3, 1) column, skew"),
        Case(case(n=1), {}, "a single point"),
        Case(tuple(ints), {}, "integer world points"),
        Case(case(depth=(50.0, 500.0)), {}, "far points"),
        Case(case(spread=0.9, scale=0.3), {}, "wide field of view (|x/z| up to 0.9)"),
    ]


project_full = Check(
    public=[
        Case((_WORLD, _A1, _R1, _T1, (-0.25, 0.08, -0.01), (0.001, -0.0008)), {}, "barrel k1, k2, k3 and p1 ≠ p2"),
        Case((_WORLD, _A2, _R2, _T2), {}, "skewed camera, no distortion (defaults)"),
        Case((_WORLD, _A2, _R2, _T2, (0.15, -0.05), (-0.002, 0.0015)), {}, "skewed camera, k1, k2 and p1, p2"),
    ],
    hidden=_pf_hidden,
    compare=FloatClose(rtol=1e-9, atol=1e-8),
    mistakes=[
        Mistake("forgot the division by z", _pf(divide=False),
                "Step 2 is the canonical projection: x = x_C / z_C, y = y_C / z_C"),
        Mistake("distortion applied in pixel instead of normalised coordinates", _pf(pixel_distortion=True),
                "Distort (x_C/z_C, y_C/z_C) BEFORE applying A; the coefficients are meant for normalised coordinates"),
        Mistake(_P_SWAPPED, _pf(swap_p=True), _P_ORDER),
        Mistake("R transposed", _pf(transpose_r=True), "Step 1 is M_C = R·M_W + t (for row vectors: X @ R.T + t)"),
        Mistake("skew ignored", _pf(skew=False), "Step 4 uses all of A: u = fu·x_d + s·y_d + u0"),
        Mistake("distortion left out", _pf(distortion=False),
                "Apply the lens distortion (k, p) between the canonical projection and A"),
    ],
    allowed=("camera.distort",),
)
