"""Zhang's calibration (§8.3.5–8.3.8): intrinsics from the homographies, extrinsics of each
view, radial distortion by linear least squares, and the global refinement of everything."""
from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .. import camera
from .._validation import AttributeDict, as_float_array, check_allocation
from ..camera import as_intrinsics, as_matrix, as_points, as_rotation, as_translation
from ..registry import algorithm, implementation

__all__ = [
    "CalibrationResult",
    "intrinsics_from_homographies",
    "extrinsics_from_homography",
    "estimate_radial_distortion",
    "calibrate",
    "rotation_to_vector",
]


class CalibrationResult(AttributeDict):
    """The result of :func:`calibrate`: a dict whose keys are also attributes.

    Keys: ``A`` (3×3, skew 0), ``k`` (k1, k2), ``rotations`` (V, 3, 3), ``translations``
    (V, 3), ``rms`` (px), and for inspection ``residuals`` (V, N, 2: projected − measured,
    px), ``view_rms`` (V,), ``homographies`` (V, 3, 3, refined), ``initial`` (dict of the
    closed-form estimates before the global refinement: ``A`` with its skew, ``k``,
    ``rotations``, ``translations``, ``rms``) and ``info`` (of the final Levenberg–Marquardt).
    """


# --------------------------------------------------------------------------------------------
# rotations as 3-vectors (for the refinement)
# --------------------------------------------------------------------------------------------
def _rotations(W: np.ndarray) -> np.ndarray:
    """Rodrigues' formula for a stack of rotation vectors (V, 3) → (V, 3, 3)."""
    theta = np.linalg.norm(W, axis=1)
    small = theta < 1e-12
    axis = W / np.where(small, 1.0, theta)[:, None]
    K = np.zeros((len(W), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = axis[:, 2], -axis[:, 1], axis[:, 0]
    # for tiny angles K holds w itself and R ≈ I + [w]× (sin θ → 1, 1 − cos θ → 0)
    sin = np.where(small, 1.0, np.sin(theta))[:, None, None]
    one_minus_cos = np.where(small, 0.0, 1.0 - np.cos(theta))[:, None, None]
    return np.eye(3) + sin * K + one_minus_cos * (K @ K)


def rotation_to_vector(R: ArrayLike) -> np.ndarray:
    """The rotation vector w (angle·axis, angle in [0, π]) of a rotation matrix."""
    R = np.asarray(R, dtype=np.float64).reshape(3, 3)
    cosine = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    theta = float(np.arccos(cosine))
    skew = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    if theta < 1e-6:
        return skew                                   # sin θ ≈ θ
    if theta > np.pi - 1e-4:                          # near π the skew part vanishes: use R + I
        B = (R + np.eye(3)) / 2.0                     # = a·aᵀ for the unit axis a
        i = int(np.argmax(np.diag(B)))
        axis = B[:, i] / np.sqrt(max(B[i, i], 1e-300))
        if skew @ axis < 0:
            axis = -axis
        return theta * axis / np.linalg.norm(axis)
    return theta / np.sin(theta) * skew


# --------------------------------------------------------------------------------------------
# §8.3.5 intrinsics
# --------------------------------------------------------------------------------------------
def _homography_stack(homographies: object) -> np.ndarray:
    if isinstance(homographies, np.ndarray):
        Hs = as_float_array(homographies, "homographies", ndim=3)
    else:
        if not isinstance(homographies, (list, tuple)):
            raise TypeError(f"homographies must be a list of 3×3 matrices or an (n, 3, 3) array, "
                            f"got {type(homographies).__name__}")
        Hs = np.array([as_matrix(H, f"homographies[{i}]", (3, 3)) for i, H in enumerate(homographies)])
        if len(Hs) == 0:
            Hs = np.zeros((0, 3, 3))
    if Hs.ndim != 3 or Hs.shape[1:] != (3, 3):
        raise ValueError(f"homographies must be 3×3 matrices, got shape {Hs.shape}")
    return Hs


def _v(H: np.ndarray, i: int, j: int) -> np.ndarray:
    """Zhang's v_ij: h_iᵀ B h_j = v_ijᵀ b with b = (B11, B12, B22, B13, B23, B33), h_i = column i."""
    hi, hj = H[:, i], H[:, j]
    return np.array([hi[0] * hj[0], hi[0] * hj[1] + hi[1] * hj[0], hi[1] * hj[1],
                     hi[2] * hj[0] + hi[0] * hj[2], hi[2] * hj[1] + hi[1] * hj[2], hi[2] * hj[2]])


@algorithm("calibration.intrinsics_from_homographies", section="8.3.5",
           check="cvkit.calibration.checks:intrinsics_from_homographies")
def intrinsics_from_homographies(homographies: Sequence[ArrayLike] | np.ndarray) -> np.ndarray:
    """The intrinsic matrix A from three or more homographies of a plane (Zhang's closed form).

    Parameters
    ----------
    homographies : list of (3, 3) array_like, or (n, 3, 3) array
        Homographies H_i ≃ A [r1 r2 t] from the pattern plane (x_W, y_W, 1) to the pixels of
        n ≥ 3 views; each may have any non-zero scale and sign.

    Returns
    -------
    (3, 3) float64 ndarray
        A = [[α, γ, u0], [0, β, v0], [0, 0, 1]] with α, β > 0; the skew γ is estimated.

    Raises
    ------
    ValueError
        Fewer than 3 homographies, non-finite or zero matrices, or homographies inconsistent
        with any camera (B not positive definite, e.g. all views parallel to each other).

    Notes
    -----
    §8.3.5: H = λA[r1 r2 t], so r1 ∝ A⁻¹h1 and r2 ∝ A⁻¹h2; because r1 ⊥ r2 and ‖r1‖ = ‖r2‖,

    .. math:: h_1^T B h_2 = 0, \\qquad h_1^T B h_1 - h_2^T B h_2 = 0, \\qquad B = A^{-T} A^{-1}.

    B is symmetric: six unknowns b = (B11, B12, B22, B13, B23, B33), and
    :math:`h_i^T B h_j = v_{ij}^T b` with
    :math:`v_{ij} = (h_{1i}h_{1j},\\ h_{1i}h_{2j} + h_{2i}h_{1j},\\ h_{2i}h_{2j},\\
    h_{3i}h_{1j} + h_{1i}h_{3j},\\ h_{3i}h_{2j} + h_{2i}h_{3j},\\ h_{3i}h_{3j})` (h_i the
    *columns* of H). Each view gives the rows :math:`v_{12}^T` and
    :math:`(v_{11} - v_{22})^T` of V; b is the unit null vector of V (its last right singular
    vector; each H is first scaled to unit Frobenius norm, so that no view weighs more because of
    its arbitrary scale). Three views fix the five parameters and the skew. B is recovered
    up to a scale λ and sign (made positive definite), and A follows in closed form (Zhang,
    2000, appendix B; the same as the Cholesky factorisation B = LLᵀ, A ∝ L⁻ᵀ):

    .. math::

        v_0 = \\frac{B_{12}B_{13} - B_{11}B_{23}}{B_{11}B_{22} - B_{12}^2},\\quad
        \\lambda = B_{33} - \\frac{B_{13}^2 + v_0(B_{12}B_{13} - B_{11}B_{23})}{B_{11}},\\quad
        \\alpha = \\sqrt{\\lambda / B_{11}},

        \\beta = \\sqrt{\\frac{\\lambda B_{11}}{B_{11}B_{22} - B_{12}^2}},\\quad
        \\gamma = -\\frac{B_{12}\\alpha^2\\beta}{\\lambda},\\quad
        u_0 = \\frac{\\gamma v_0}{\\beta} - \\frac{B_{13}\\alpha^2}{\\lambda}.

    Examples
    --------
    >>> import numpy as np
    >>> from cvkit.camera import rotation_matrix
    >>> A = np.array([[800.0, 2.0, 320], [0, 820, 240], [0, 0, 1]])
    >>> Hs = [A @ np.column_stack([R[:, 0], R[:, 1], t]) for R, t in [
    ...     (rotation_matrix(0.3, 0.1, 0.0), [-50, -40, 500]), (rotation_matrix(-0.2, 0.4, 0.3), [-80, 20, 600]),
    ...     (rotation_matrix(0.1, -0.5, -0.2), [10, -60, 450])]]
    >>> np.round(intrinsics_from_homographies(Hs), 6)
    array([[800.,   2., 320.],
           [  0., 820., 240.],
           [  0.,   0.,   1.]])
    """
    Hs = _homography_stack(homographies)
    if len(Hs) < 3:
        raise ValueError(f"at least 3 homographies are needed to estimate A (5 parameters and the skew), got {len(Hs)}")
    norms = np.linalg.norm(Hs.reshape(len(Hs), -1), axis=1)
    if np.any(norms == 0):
        raise ValueError("homographies must not be zero matrices")
    rows = []
    for H in Hs / norms[:, None, None]:
        rows.append(_v(H, 0, 1))
        rows.append(_v(H, 0, 0) - _v(H, 1, 1))
    _, _, Vt = np.linalg.svd(np.array(rows), full_matrices=False)   # 2n ≥ 6 rows: Vt is 6×6
    b = Vt[-1]
    if b[0] < 0:
        b = -b
    B11, B12, B22, B13, B23, B33 = b
    denominator = B11 * B22 - B12 * B12
    if not (B11 > 0 and denominator > 0):
        raise ValueError("the homographies do not fit any camera (B = A⁻ᵀA⁻¹ is not positive definite): use "
                         "views with different orientations of the pattern")
    v0 = (B12 * B13 - B11 * B23) / denominator
    lam = B33 - (B13 * B13 + v0 * (B12 * B13 - B11 * B23)) / B11
    if not lam / B11 > 0:
        raise ValueError("the homographies do not fit any camera (B = A⁻ᵀA⁻¹ is not positive definite): use "
                         "views with different orientations of the pattern")
    alpha = np.sqrt(lam / B11)
    beta = np.sqrt(lam * B11 / denominator)
    gamma = -B12 * alpha * alpha * beta / lam
    u0 = gamma * v0 / beta - B13 * alpha * alpha / lam
    return np.array([[alpha, gamma, u0], [0.0, beta, v0], [0.0, 0.0, 1.0]])


# --------------------------------------------------------------------------------------------
# §8.3.6 extrinsics
# --------------------------------------------------------------------------------------------
@algorithm("calibration.extrinsics_from_homography", section="8.3.6",
           check="cvkit.calibration.checks:extrinsics_from_homography")
def extrinsics_from_homography(A: ArrayLike, H: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The pose (R, t) of the pattern in one view from its homography and the intrinsics.

    Parameters
    ----------
    A : (3, 3) array_like
        Intrinsic matrix (upper triangular, non-zero diagonal).
    H : (3, 3) array_like
        Homography of the view (pattern plane → pixels), any non-zero scale and sign.

    Returns
    -------
    R : (3, 3) float64 ndarray
        The rotation (orthonormal, det +1) closest to [r1 r2 r1×r2] in the Frobenius norm.
    t : (3,) float64 ndarray
        Translation, with t_z > 0 (the pattern in front of the camera).

    Raises
    ------
    ValueError
        Malformed A or H, or A⁻¹h1 = 0.

    Notes
    -----
    §8.3.6: with H = (1/λ)·A[r1 r2 t],

    .. math:: r_1 = \\lambda A^{-1} h_1,\\quad r_2 = \\lambda A^{-1} h_2,\\quad
              t = \\lambda A^{-1} h_3,\\quad r_3 = r_1 \\times r_2,\\quad
              \\lambda = \\pm 1 / \\lVert A^{-1} h_1 \\rVert,

    the sign of λ chosen so that t_z > 0 (H is known only up to sign). With noise,
    [r1 r2 r3] is not exactly a rotation: the closest one (Frobenius norm) is R = U Vᵀ from
    its SVD U D Vᵀ, i.e. D replaced by the identity. Since det[r1 r2 r1×r2] = ‖r1×r2‖² > 0,
    R has det +1. t is not changed by this step.

    Examples
    --------
    >>> import numpy as np
    >>> from cvkit.camera import rotation_matrix
    >>> A = np.array([[800.0, 0, 320], [0, 820, 240], [0, 0, 1]])
    >>> R0, t0 = rotation_matrix(0.3, -0.2, 0.1), np.array([-60.0, -40.0, 500.0])
    >>> H = -3.0 * A @ np.column_stack([R0[:, 0], R0[:, 1], t0])   # any scale, even negative
    >>> R, t = extrinsics_from_homography(A, H)
    >>> bool(np.allclose(R, R0) and np.allclose(t, t0))
    True
    """
    intr = as_intrinsics(A, "A")
    M = as_matrix(H, "H", (3, 3))
    columns = np.linalg.solve(intr, M)                     # A⁻¹[h1 h2 h3]
    norm = float(np.linalg.norm(columns[:, 0]))
    if norm == 0.0:
        raise ValueError("A⁻¹h1 is zero: H is not the homography of a plane seen by this camera")
    lam = 1.0 / norm
    if columns[2, 2] * lam < 0:
        lam = -lam
    r1, r2, t = lam * columns[:, 0], lam * columns[:, 1], lam * columns[:, 2]
    Q = np.column_stack([r1, r2, np.cross(r1, r2)])
    U, _, Vt = np.linalg.svd(Q)
    return U @ Vt, t


# --------------------------------------------------------------------------------------------
# §8.3.7 radial distortion
# --------------------------------------------------------------------------------------------
def _views(world_points: ArrayLike, image_points_list: object, rotations: object,
           translations: object) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    world = as_points(world_points, "world_points", 3)
    if len(world) == 0:
        raise ValueError("world_points must hold at least one point")
    images = _image_point_sets(image_points_list, len(world))
    if isinstance(rotations, np.ndarray) and rotations.ndim == 3:
        rotations = list(rotations)
    if isinstance(translations, np.ndarray) and translations.ndim == 2:
        translations = list(translations)
    if not isinstance(rotations, (list, tuple)) or not isinstance(translations, (list, tuple)):
        raise TypeError("rotations and translations must be lists (or stacked arrays) with one entry per view")
    if len(rotations) != len(images) or len(translations) != len(images):
        raise ValueError(f"one rotation and one translation per view are needed: {len(images)} views, "
                         f"{len(rotations)} rotations, {len(translations)} translations")
    Rs = [as_rotation(R, f"rotations[{i}]") for i, R in enumerate(rotations)]
    ts = [as_translation(t, f"translations[{i}]") for i, t in enumerate(translations)]
    return world, images, Rs, ts


def _image_point_sets(image_points_list: object, n_points: int) -> list[np.ndarray]:
    if isinstance(image_points_list, np.ndarray):
        if image_points_list.ndim != 3:
            raise ValueError(f"image_points_list must be a list of (N, 2) arrays or an (n_views, N, 2) array, "
                             f"got shape {image_points_list.shape}")
        image_points_list = list(image_points_list)
    if not isinstance(image_points_list, (list, tuple)) or len(image_points_list) == 0:
        raise TypeError("image_points_list must be a non-empty list of (N, 2) arrays (one per view)")
    images = [as_points(m, f"image_points_list[{i}]", 2) for i, m in enumerate(image_points_list)]
    for i, m in enumerate(images):
        if len(m) != n_points:
            raise ValueError(f"image_points_list[{i}] has {len(m)} points, world_points has {n_points}")
    return images


@algorithm("calibration.estimate_radial_distortion", section="8.3.7",
           check="cvkit.calibration.checks:estimate_radial_distortion")
def estimate_radial_distortion(A: ArrayLike, world_points: ArrayLike, image_points_list: Sequence[ArrayLike] | np.ndarray,
                               rotations: Sequence[ArrayLike] | np.ndarray,
                               translations: Sequence[ArrayLike] | np.ndarray) -> np.ndarray:
    """Radial distortion (k1, k2) by linear least squares, given the rest of the camera.

    Parameters
    ----------
    A : (3, 3) array_like
        Intrinsic matrix.
    world_points : (N, 3) array_like
        Pattern points in the world frame (the same in every view).
    image_points_list : list of (N, 2) array_like, or (n_views, N, 2) array
        Measured (distorted) pixels of the pattern points in each view.
    rotations, translations : lists of (3, 3) and (3,), or stacked arrays
        The pose of each view (world → camera).

    Returns
    -------
    (2,) float64 ndarray
        ``(k1, k2)``.

    Raises
    ------
    ValueError, TypeError
        Malformed or inconsistent inputs (numbers of views and points must match).

    Notes
    -----
    §8.3.7: project each pattern point without distortion: normalised coordinates
    (x, y) = (x_C/z_C, y_C/z_C), r² = x² + y², ideal pixel (u, v) = A·(x, y, 1). The lens moves
    (x, y) to (1 + k1 r² + k2 r⁴)·(x, y) *before* A, and A is linear, so the measured pixel is
    (ŭ, v̆) = (u, v) + (k1 r² + k2 r⁴)·(u − u0, v − v0) (also with skew). Two equations per
    point, linear in k:

    .. math::

        \\begin{bmatrix} (u-u_0) r^2 & (u-u_0) r^4 \\\\ (v-v_0) r^2 & (v-v_0) r^4 \\end{bmatrix}
        \\begin{bmatrix} k_1 \\\\ k_2 \\end{bmatrix} =
        \\begin{bmatrix} \\breve u - u \\\\ \\breve v - v \\end{bmatrix}

    stacked over all points of all views into D k = d (in pixels), solved in the least-squares
    sense, k = (DᵀD)⁻¹Dᵀd (``np.linalg.lstsq``). r is that of the *ideal* point.

    Examples
    --------
    >>> import numpy as np
    >>> from cvkit.camera import project_full, rotation_matrix
    >>> A = np.array([[800.0, 0, 320], [0, 820, 240], [0, 0, 1]])
    >>> world = np.array([[x, y, 0.0] for y in range(0, 150, 25) for x in range(0, 200, 25)])
    >>> R, t = rotation_matrix(0.2, -0.3, 0.1), np.array([-90.0, -60.0, 400.0])
    >>> pixels = project_full(world, A, R, t, k=(-0.2, 0.05))
    >>> np.round(estimate_radial_distortion(A, world, [pixels], [R], [t]), 10)
    array([-0.2 ,  0.05])
    """
    intr = as_intrinsics(A, "A")
    intr = intr / intr[2, 2]
    world, images, Rs, ts = _views(world_points, image_points_list, rotations, translations)
    D_rows, d_rows = [], []
    for m, R, t in zip(images, Rs, ts):
        cam = world @ R.T + t
        x, y = cam[:, 0] / cam[:, 2], cam[:, 1] / cam[:, 2]
        r2 = x * x + y * y
        du = intr[0, 0] * x + intr[0, 1] * y                  # u − u0
        dv = intr[1, 1] * y                                     # v − v0
        D_rows.append(np.column_stack([du * r2, du * r2 * r2]))
        D_rows.append(np.column_stack([dv * r2, dv * r2 * r2]))
        d_rows.append(m[:, 0] - (du + intr[0, 2]))
        d_rows.append(m[:, 1] - (dv + intr[1, 2]))
    k, *_ = np.linalg.lstsq(np.concatenate(D_rows), np.concatenate(d_rows), rcond=None)
    return k


# --------------------------------------------------------------------------------------------
# §8.2–8.3.8 the whole calibration
# --------------------------------------------------------------------------------------------
def _camera_of(x: np.ndarray, layout: tuple[str, ...], fixed_k: np.ndarray) -> tuple[np.ndarray, tuple[float, ...]]:
    """``A`` and ``k`` from the head of the parameter vector (see :func:`_unpack`)."""
    head = dict(zip(layout, x[:len(layout)]))
    A = np.array([[head["fu"], head.get("skew", 0.0), head["u0"]], [0.0, head["fv"], head["v0"]], [0.0, 0.0, 1.0]])
    k = (head["k1"], head["k2"]) if "k1" in head else tuple(fixed_k)
    return A, k


def _unpack(x: np.ndarray, n_views: int, layout: tuple[str, ...],
            fixed_k: np.ndarray) -> tuple[np.ndarray, tuple[float, ...], np.ndarray, np.ndarray]:
    """Camera and poses from the parameter vector: ``layout`` names its head (intrinsics and,
    when refined, distortion), then 6 numbers per view (rotation vector, translation)."""
    A, k = _camera_of(x, layout, fixed_k)
    poses = x[len(layout):].reshape(n_views, 6)
    return A, k, _rotations(poses[:, :3]), poses[:, 3:]


@contextlib.contextmanager
def _blame(name: str, what: str) -> Iterator[None]:
    """Raise a ``ValueError`` of a building block again, prefixed with the caller's argument
    (``name``) and what failed, so that it does not speak of the block's own arguments only."""
    try:
        yield
    except ValueError as error:
        raise ValueError(f"{name}: {what}: {error}") from error


def _check_spread(points: np.ndarray, name: str) -> None:
    """Points of a plane that determine a homography: not all equal, not all on one line."""
    singular = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    if not singular[0] > 0:
        raise ValueError(f"{name} must not all coincide: a homography needs points spread over the plane")
    if singular[1] <= 1e-9 * singular[0]:
        raise ValueError(f"{name} must not all lie on one line: a homography needs points spread over the plane")


def _calibrate(world_points: ArrayLike, image_points_list: Sequence[ArrayLike] | np.ndarray, refine: bool = True,
               refine_distortion: bool = True, free_skew: bool = False) -> CalibrationResult:
    """Zhang's method; the switches exist for the mistake bank of the check."""
    world = as_points(world_points, "world_points", 3)
    if len(world) < 4:
        raise ValueError(f"world_points must hold at least 4 points, got {len(world)}")
    extent = max(float(np.ptp(world[:, :2], axis=0).max()), 1e-300)
    if np.abs(world[:, 2]).max() > 1e-9 * extent:
        raise ValueError("world_points must lie on the plane z = 0 (a planar pattern in its own frame)")
    images = _image_point_sets(image_points_list, len(world))
    n_views = len(images)
    if n_views < 3:
        raise ValueError(f"Zhang's method needs at least 3 views of the pattern, got {n_views}")
    plane = world[:, :2]
    _check_spread(plane, "world_points")
    for i, m in enumerate(images):
        _check_spread(m, f"image_points_list[{i}]")
    layout = ("fu", "fv", "u0", "v0") + (("skew",) if free_skew else ()) + (("k1", "k2") if refine_distortion else ())
    check_allocation((2 * n_views * len(world), len(layout) + 6 * n_views), "image_points_list",
                     what="the Jacobian of the refinement (2·views·points, parameters)")

    # 1.-4. closed-form start
    dlt = implementation("calibration.homography_dlt")
    refine_h = implementation("calibration.refine_homography")
    Hs = []
    for i, m in enumerate(images):
        with _blame(f"image_points_list[{i}]", "no homography from the pattern to this view"):
            Hs.append(refine_h(dlt(plane, m), plane, m))
    with _blame("image_points_list", f"the {n_views} views do not determine the camera"):
        A0 = implementation("calibration.intrinsics_from_homographies")(Hs)
        poses = [implementation("calibration.extrinsics_from_homography")(A0, H) for H in Hs]
        Rs0, ts0 = [p[0] for p in poses], [p[1] for p in poses]
        A_start = A0.copy()
        if not free_skew:
            A_start[0, 1] = 0.0
        k0 = np.asarray(implementation("calibration.estimate_radial_distortion")(A_start, world, images, Rs0, ts0),
                        dtype=np.float64).ravel()[:2]

    # 5. global refinement
    values = {"fu": A_start[0, 0], "fv": A_start[1, 1], "u0": A_start[0, 2], "v0": A_start[1, 2],
              "skew": A_start[0, 1], "k1": k0[0], "k2": k0[1]}
    observed = np.stack(images)                                  # (V, N, 2)
    project = implementation("camera.project_full")
    identity, origin = np.eye(3), np.zeros(3)
    n_points, n_head = len(world), len(layout)

    def in_cameras(poses):
        """The pattern points in every camera frame, (V·N, 3), for poses (V, 6)."""
        Rs = _rotations(poses[:, :3])
        return (np.einsum("vij,nj->vni", Rs, world) + poses[:, None, 3:]).reshape(-1, 3)

    reference_lens = project is camera.project_full and implementation("camera.distort") is camera.distort

    def lens(camera_points, k):
        """Distorted normalised coordinates: project_full with A = I (steps 2-3 of §7.7.3);
        with the reference camera model, its arithmetic without the argument checks (the
        refinement projects hundreds of times; the same numbers)."""
        if reference_lens:
            kk, pp = camera.distortion_coefficients(k, (0.0, 0.0))
            return camera.project_checked(camera_points, identity, identity, origin, kk, pp)
        return project(camera_points, identity, identity, origin, k)

    def pixels(A, xy):
        """Step 4, the affine intrinsics (linear in fu, fv, u0, v0 and the skew)."""
        return np.column_stack([A[0, 0] * xy[:, 0] + A[0, 1] * xy[:, 1] + A[0, 2], A[1, 1] * xy[:, 1] + A[1, 2]])

    def split(x):
        A, k = _camera_of(x, layout, k0)
        return A, k, x[n_head:].reshape(n_views, 6)

    def predict(x):
        A, k, poses = split(x)
        return pixels(A, lens(in_cameras(poses), k)).reshape(n_views, n_points, 2)

    def residuals(x):
        return (predict(x) - observed).ravel()

    def jacobian(x):
        A, k, poses = split(x)
        cameras = in_cameras(poses)
        xy = lens(cameras, k)
        base = (pixels(A, xy) - observed.reshape(-1, 2)).ravel()
        J = np.zeros((base.size, x.size))
        eps = np.sqrt(np.finfo(float).eps)
        for j, name in enumerate(layout):                        # the intrinsics enter linearly: exact columns
            column = np.zeros((len(xy), 2))
            if name == "fu":
                column[:, 0] = xy[:, 0]
            elif name == "fv":
                column[:, 1] = xy[:, 1]
            elif name == "u0":
                column[:, 0] = 1.0
            elif name == "v0":
                column[:, 1] = 1.0
            elif name == "skew":
                column[:, 0] = xy[:, 1]
            else:                                                # k1, k2: forward differences through the lens
                step = x.copy()
                step[j] += eps * max(1.0, abs(x[j]))
                _, k_step, _ = split(step)
                column = (pixels(A, lens(cameras, k_step)) - pixels(A, xy)) / (step[j] - x[j])
            J[:, j] = column.ravel()
        # pose parameter j of all views at once, the six perturbed copies projected in one call
        h = eps * np.maximum(1.0, np.abs(poses))                 # (V, 6)
        shifted = [in_cameras(poses + np.eye(6)[j] * h) for j in range(6)]
        moved = pixels(A, lens(np.concatenate(shifted), k)).reshape(6, n_views, n_points, 2)
        change = (moved - pixels(A, xy).reshape(1, n_views, n_points, 2)).reshape(6, n_views, 2 * n_points)
        per_view = 2 * n_points
        rows = np.arange(base.size).reshape(n_views, per_view)
        for j in range(6):
            actual = (poses[:, j] + h[:, j]) - poses[:, j]
            J[rows, (n_head + 6 * np.arange(n_views) + j)[:, None]] = change[j] / actual[:, None]   # block diagonal
        return J

    x0 = np.concatenate([np.array([values[name] for name in layout])]
                        + [np.concatenate([rotation_to_vector(R), t]) for R, t in zip(Rs0, ts0)])
    start_errors = predict(x0) - observed
    start_rms = float(np.sqrt(np.mean(np.sum(start_errors ** 2, axis=-1))))
    if refine:
        with _blame("image_points_list", "the refinement of the closed-form estimate failed"):
            x, info = implementation("calibration.levenberg_marquardt")(residuals, x0, jacobian=jacobian)
    else:
        x, info = x0, {"iterations": 0, "cost": 0.5 * float(np.sum(start_errors ** 2)), "converged": False}
    A, k, Rs, ts = _unpack(x, n_views, layout, k0)
    errors = predict(x) - observed
    squared = np.sum(errors ** 2, axis=-1)                       # (V, N)
    return CalibrationResult(
        A=A, k=np.array(k, dtype=np.float64), rotations=np.array(Rs), translations=np.array(ts),
        rms=float(np.sqrt(squared.mean())), residuals=errors, view_rms=np.sqrt(squared.mean(axis=1)),
        homographies=np.array(Hs),
        initial={"A": A0, "k": k0, "rotations": np.array(Rs0), "translations": np.array(ts0), "rms": start_rms},
        info=info,
    )


@algorithm("calibration.calibrate", section="8.2–8.3.8", check="cvkit.calibration.checks:calibrate")
def calibrate(world_points: ArrayLike, image_points_list: Sequence[ArrayLike] | np.ndarray) -> CalibrationResult:
    """Calibrate a camera from views of a planar pattern (Zhang's method, §8.2–8.3.8).

    Parameters
    ----------
    world_points : (N, 3) array_like
        The pattern's points in its own frame, all with z = 0 (e.g. :func:`chessboard_points`),
        N ≥ 4, not all equal and not all on one line.
    image_points_list : list of (N, 2) array_like, or (n_views, N, 2) array
        The measured pixels of those points in each of n ≥ 3 views (e.g. from
        :func:`find_chessboard_corners`), in each view not all equal nor on one line. The
        Jacobian of the refinement, (2·n·N, 6 + 6n) floats, may take at most 2 GiB
        (``ValueError`` naming ``image_points_list``). An error of a building block is raised
        again naming the argument it comes from (``image_points_list[i]`` for the homography
        of view i, ``image_points_list`` for the camera the views determine).

    Returns
    -------
    CalibrationResult
        A dict with attribute access: ``A`` (3×3, skew 0), ``k`` (k1, k2) as a (2,) array,
        ``rotations`` (n, 3, 3), ``translations`` (n, 3), ``rms`` (px), plus ``residuals``,
        ``view_rms``, ``homographies``, ``initial`` and ``info`` (see
        :class:`CalibrationResult`).

    Raises
    ------
    ValueError
        Fewer than 3 views or 4 points, a pattern that is not planar (z ≠ 0), mismatched numbers
        of points, or views that do not determine the camera.

    Notes
    -----
    The steps of §8.2.1, each through the registry (so a provider's building blocks are used):

    1. per view, ``homography_dlt`` (normalised) of the pattern plane (x_W, y_W) to the pixels,
       refined by ``refine_homography`` (reprojection error);
    2. ``intrinsics_from_homographies`` (closed form, skew estimated);
    3. ``extrinsics_from_homography`` for each view;
    4. ``estimate_radial_distortion`` (k1, k2) with the skew of A set to 0;
    5. global refinement by ``levenberg_marquardt`` of (fu, fv, u0, v0, k1, k2) and of every
       pose (rotation vector, Rodrigues' formula, and t) minimising the total reprojection error
       Σ‖m_ij − m̂(A, k, R_i, t_i, M_j)‖² (points moved to each camera frame, then through the
       lens by ``camera.project_full`` with A = I in one call for all views, then A) — the maximum
       likelihood estimate for i.i.d. Gaussian noise on the measured corners. The skew stays 0
       and k3 = p1 = p2 = 0 (OpenCV's ``CALIB_FIX_K3`` with zero tangential distortion).
       The Jacobian columns of fu, fv, u0, v0 are exact (the intrinsics are affine in them);
       those of k1, k2 and of the poses are forward differences, perturbing one pose
       parameter of *all* views at once (a view's residuals depend only on its own pose) and
       projecting the six perturbed copies in one call: four projections per Jacobian whatever
       the number of views.

    ``rms`` = √(Σ‖e‖² / number of points), e the reprojection error vectors after refinement,
    as ``cv2.calibrateCamera`` reports it. With the same points and model OpenCV reaches the
    same minimum (see the tests and ``benchmarks/bench_ch08.py``).

    Examples
    --------
    >>> import numpy as np
    >>> from cvkit.data import chessboard_views
    >>> views = chessboard_views(n_views=5, render=False)          # exact corners, k1 = -0.2, k2 = 0.05
    >>> result = calibrate(views.world_points, views.image_points)
    >>> np.round(result.A, 6)
    array([[800.,   0., 320.],
           [  0., 820., 240.],
           [  0.,   0.,   1.]])
    >>> np.round(result.k, 8), result.rms < 1e-6
    (array([-0.2 ,  0.05]), True)
    """
    return _calibrate(world_points, image_points_list)
