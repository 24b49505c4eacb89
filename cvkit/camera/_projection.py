"""The pinhole camera as matrices (§7.2–7.6): intrinsics A, rotation R, extrinsics G, the
perspective projection matrix P = A[R|t], projecting with it, and factorising it back."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import check_real
from ..registry import algorithm, implementation
from ._common import as_intrinsics, as_matrix, as_points, as_rotation, as_translation

__all__ = [
    "intrinsic_matrix",
    "rotation_matrix",
    "extrinsic_matrix",
    "projection_matrix",
    "project",
    "decompose_projection",
]

#: a left 3×3 block of P whose smallest/largest singular value is below this is singular
_SINGULAR = 1e-12


# --------------------------------------------------------------------------------------------
# §7.2, §7.5.2 intrinsic parameters
# --------------------------------------------------------------------------------------------
@algorithm("camera.intrinsic_matrix", section="7.5.2", check="cvkit.camera.checks:intrinsic_matrix")
def intrinsic_matrix(fu: float, fv: float, u0: float, v0: float, skew: float = 0.0) -> np.ndarray:
    """The intrinsic parameter matrix A of a pinhole camera.

    Parameters
    ----------
    fu, fv : float
        Focal length in horizontal and vertical pixels, fu = f/Δu and fv = f/Δv (> 0).
    u0, v0 : float
        Principal point (piercing point of the optical axis) in pixels, (x, y) = (col, row).
    skew : float
        Skew coefficient s, 0 for orthogonal sensor axes (the usual assumption).

    Returns
    -------
    (3, 3) float64 ndarray
        ``[[fu, skew, u0], [0, fv, v0], [0, 0, 1]]``.

    Raises
    ------
    ValueError
        Non-finite values, or ``fu`` / ``fv`` not positive.
    TypeError
        Arguments that are not real numbers.

    Notes
    -----
    §7.2.3 and §7.5.2: a point :math:`(x_C, y_C, z_C)` of the camera reference frame lands on
    the pixel :math:`u = f_u x_C/z_C + s\\, y_C/z_C + u_0`, :math:`v = f_v y_C/z_C + v_0`, i.e.
    :math:`z_C [u, v, 1]^T = A [x_C, y_C, z_C]^T`. The image plane is taken in front of the
    optical centre (no minus signs), as in OpenCV's camera matrix; the mirrored plane behind it
    (:math:`u = -f x/z`) is the same camera rotated by π about its optical axis, which is why
    negative focal lengths are refused. The skew sits at ``A[0, 1]`` (OpenCV's position; its
    ``projectPoints`` ignores it, cvkit does not).

    Examples
    --------
    >>> intrinsic_matrix(800, 780, 320, 240)
    array([[800.,   0., 320.],
           [  0., 780., 240.],
           [  0.,   0.,   1.]])
    """
    fu = check_real(fu, "fu", positive=True)
    fv = check_real(fv, "fv", positive=True)
    u0 = check_real(u0, "u0")
    v0 = check_real(v0, "v0")
    skew = check_real(skew, "skew")
    return np.array([[fu, skew, u0], [0.0, fv, v0], [0.0, 0.0, 1.0]])


# --------------------------------------------------------------------------------------------
# §7.3 extrinsic parameters
# --------------------------------------------------------------------------------------------
@algorithm("camera.rotation_matrix", section="7.3", check="cvkit.camera.checks:rotation_matrix")
def rotation_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation matrix from roll, pitch and yaw angles: R = Rz(yaw)·Ry(pitch)·Rx(roll).

    Parameters
    ----------
    roll, pitch, yaw : float
        Angles in radians about the x, y and z axes (any finite value; they wrap around).

    Returns
    -------
    (3, 3) float64 ndarray
        The rotation matrix: orthonormal (RᵀR = I) with det R = +1.

    Raises
    ------
    ValueError, TypeError
        Non-finite or non-real angles (the message names the angle).

    Notes
    -----
    §7.3: a rotation has 9 entries but 3 degrees of freedom. With the *active* elementary
    rotations (a vector is turned by the angle, counter-clockwise seen from the tip of the axis)

    .. math::

        R_x(a) = \\begin{bmatrix}1&0&0\\\\0&\\cos a&-\\sin a\\\\0&\\sin a&\\cos a\\end{bmatrix},\\
        R_y(a) = \\begin{bmatrix}\\cos a&0&\\sin a\\\\0&1&0\\\\-\\sin a&0&\\cos a\\end{bmatrix},\\
        R_z(a) = \\begin{bmatrix}\\cos a&-\\sin a&0\\\\\\sin a&\\cos a&0\\\\0&0&1\\end{bmatrix}

    the result is :math:`R = R_z(\\text{yaw}) R_y(\\text{pitch}) R_x(\\text{roll})`: roll is applied
    first, about the fixed x axis, then pitch about the fixed y axis, then yaw about the fixed z
    axis (extrinsic x-y-z, the same as intrinsic z-y'-x''). This is
    ``scipy.spatial.transform.Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()``.
    Rotations do not commute: the order matters except for special angles.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(rotation_matrix(0.0, 0.0, np.pi / 2), 12)  # yaw: x axis turns into y axis
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    return rotation_matrices(check_real(roll, "roll"), check_real(pitch, "pitch"), check_real(yaw, "yaw"))[0]


def rotation_matrices(roll: ArrayLike, pitch: ArrayLike, yaw: ArrayLike) -> np.ndarray:
    """:func:`rotation_matrix` for arrays of K angles each, ``(K, 3, 3)``, without argument checks
    (for topics that build many rotations of their own, such as the chessboard pose sampler).
    For one angle each, exactly :func:`rotation_matrix`'s numbers; NumPy may round the sines of
    arrays differently from those of single values, by an ulp."""
    ca, sa = np.cos(roll), np.sin(roll)
    cb, sb = np.cos(pitch), np.sin(pitch)
    cc, sc = np.cos(yaw), np.sin(yaw)
    # Rz(yaw) @ Ry(pitch) @ Rx(roll), multiplied out
    return np.stack([
        cc * cb, cc * sb * sa - sc * ca, cc * sb * ca + sc * sa,
        sc * cb, sc * sb * sa + cc * ca, sc * sb * ca - cc * sa,
        0.0 - sb, cb * sa, cb * ca,  # 0.0 - sb: +0.0, not -0.0, when pitch = 0
    ], axis=-1).reshape(-1, 3, 3)


@algorithm("camera.extrinsic_matrix", section="7.5.3", check="cvkit.camera.checks:extrinsic_matrix")
def extrinsic_matrix(R: ArrayLike, t: ArrayLike) -> np.ndarray:
    """The 4×4 extrinsic matrix G = [[R, t], [0ᵀ, 1]] (world → camera reference frame).

    Parameters
    ----------
    R : (3, 3) array_like
        Rotation from the world to the camera frame (orthonormal within 1e-3, det +1; used as given).
    t : (3,) or (3, 1) array_like
        Translation: the world origin expressed in the camera frame (*not* the camera's
        position in the world, which is C = −Rᵀt).

    Returns
    -------
    (4, 4) float64 ndarray
        G, with ``G[:3, :3] = R``, ``G[:3, 3] = t`` and bottom row ``[0, 0, 0, 1]``.

    Raises
    ------
    ValueError
        Wrong shapes, non-finite values, or an ``R`` that is not a rotation matrix.
    TypeError
        Non-numeric or complex arguments.

    Notes
    -----
    §7.3 and §7.5.3: :math:`M_C = R M_W + t`, in homogeneous coordinates
    :math:`\\tilde M_C = G \\tilde M_W`. G is a rigid motion; its inverse is
    ``[[Rᵀ, −Rᵀt], [0ᵀ, 1]]`` (camera → world).

    Examples
    --------
    >>> import numpy as np
    >>> extrinsic_matrix(np.eye(3), [1, 2, 3])
    array([[1., 0., 0., 1.],
           [0., 1., 0., 2.],
           [0., 0., 1., 3.],
           [0., 0., 0., 1.]])
    """
    rot = as_rotation(R, "R")
    trans = as_translation(t, "t")
    G = np.eye(4)
    G[:3, :3] = rot
    G[:3, 3] = trans
    return G


# --------------------------------------------------------------------------------------------
# §7.6 the perspective projection matrix
# --------------------------------------------------------------------------------------------
@algorithm("camera.projection_matrix", section="7.6", check="cvkit.camera.checks:projection_matrix")
def projection_matrix(A: ArrayLike, R: ArrayLike, t: ArrayLike) -> np.ndarray:
    """The perspective projection matrix P = A[R|t] (3×4).

    Parameters
    ----------
    A : (3, 3) array_like
        Intrinsic matrix (upper triangular, non-zero diagonal; see :func:`intrinsic_matrix`).
    R : (3, 3) array_like
        World → camera rotation (orthonormal within 1e-3, det +1; used as given).
    t : (3,) or (3, 1) array_like
        World → camera translation (see :func:`extrinsic_matrix`).

    Returns
    -------
    (3, 4) float64 ndarray
        P, mapping homogeneous world points to homogeneous pixels: ``m̃ ≡ P·M̃_W``.

    Raises
    ------
    ValueError
        Wrong shapes, non-finite values, an ``A`` that is not upper triangular (e.g. the
        principal point written in the bottom row) or an ``R`` that is not a rotation.
    TypeError
        Non-numeric or complex arguments.

    Notes
    -----
    §7.6–7.6.1: :math:`P = A [I | 0] G = A [R | t]` — change of frame (G), canonical
    perspective projection :math:`[I|0]`, intrinsics (A). Computed exactly that way, with the
    extrinsic matrix from ``implementation("camera.extrinsic_matrix")`` (so inside
    ``with cvkit.use("student"):`` the student's G is used). P is defined up to a non-zero
    scale: every multiple projects the same way.

    Examples
    --------
    >>> import numpy as np
    >>> projection_matrix(intrinsic_matrix(100, 100, 50, 40), np.eye(3), [0, 0, 2])
    array([[100.,   0.,  50., 100.],
           [  0., 100.,  40.,  80.],
           [  0.,   0.,   1.,   2.]])
    """
    intr = as_intrinsics(A, "A")
    rot = as_rotation(R, "R")
    trans = as_translation(t, "t")
    G = np.asarray(implementation("camera.extrinsic_matrix")(rot, trans), dtype=np.float64)
    canonical = np.eye(3, 4)  # [I | 0]
    return intr @ canonical @ G


@algorithm("camera.project", section="7.6", check="cvkit.camera.checks:project")
def project(P: ArrayLike, points_world: ArrayLike) -> np.ndarray:
    """Project world points (or directions) to pixels with a perspective projection matrix.

    Parameters
    ----------
    P : (3, 4) array_like
        Perspective projection matrix (any non-zero multiple works the same).
    points_world : (N, 3) or (N, 4) array_like
        Euclidean world points ``(x, y, z)``, or homogeneous ones ``(x, y, z, w)``; ``w = 0``
        is the point at infinity in the direction ``(x, y, z)``. N = 0 is allowed.

    Returns
    -------
    (N, 2) float64 ndarray
        Pixel coordinates ``(u, v)`` = (x, y) = (col, row). A direction projects to its
        vanishing point. Where the third homogeneous coordinate of ``P·M̃`` is 0 (a point on
        the camera's focal plane, or a direction parallel to the image plane) the result has
        ``np.divide`` semantics: ``±inf``, or ``nan`` for 0/0, without warnings.

    Raises
    ------
    ValueError
        Wrong shapes, non-finite values, or P = 0.
    TypeError
        Non-numeric or complex arguments.

    Notes
    -----
    §7.6: :math:`k \\tilde m = P \\tilde M_W`, then divide by the third coordinate
    :math:`k` (= :math:`z_C` when P = A[R|t]). §7.5.1: for a direction
    :math:`[a, b, c, 0]^T` the same formula gives the vanishing point shared by all lines of
    that direction. Points behind the camera (:math:`z_C < 0`) are projected too, as the
    linear model does (a real camera does not see them). The building blocks are called
    through the registry: ``to_homogeneous`` for (N, 3) input and ``from_homogeneous`` for
    the division.

    Examples
    --------
    >>> import numpy as np
    >>> P = projection_matrix(intrinsic_matrix(100, 100, 50, 40), np.eye(3), [0, 0, 0])
    >>> project(P, [[1, 2, 4], [2, 4, 8]])          # twice as far, twice the coordinates: same pixel
    array([[75., 90.],
           [75., 90.]])
    >>> project(P, [[0, 0, 1, 0]])                   # the direction of the optical axis
    array([[50., 40.]])
    """
    mat = as_matrix(P, "P", (3, 4))
    if not np.any(mat):
        raise ValueError("P must not be the zero matrix")
    pts = as_points(points_world, "points_world", (3, 4))
    if pts.shape[1] == 3:
        pts = np.asarray(implementation("camera.to_homogeneous")(pts), dtype=np.float64)
    projected = pts @ mat.T
    return np.asarray(implementation("camera.from_homogeneous")(projected), dtype=np.float64)


# --------------------------------------------------------------------------------------------
# §7.6.1 factorisation of the PPM
# --------------------------------------------------------------------------------------------
def _rq(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M = K·Q with K upper triangular and Q orthogonal (no sign normalisation), from the QR
    decomposition of the row-reversed transpose: if (J·M)ᵀ = Q̃·R̃ with J the exchange matrix,
    then M = (J·R̃ᵀ·J)·(J·Q̃ᵀ)."""
    q, r = np.linalg.qr(M[::-1].T)
    K = r.T[::-1, ::-1]
    Q = q.T[::-1]
    return K, Q


@algorithm("camera.decompose_projection", section="7.6.1", check="cvkit.camera.checks:decompose_projection")
def decompose_projection(P: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Factorise a perspective projection matrix into intrinsics and pose: P ≃ A[R|t].

    Parameters
    ----------
    P : (3, 4) array_like
        Any non-zero multiple λ·A[R|t] (λ positive or negative) of a projection matrix
        whose left 3×3 block is invertible.

    Returns
    -------
    A : (3, 3) float64 ndarray
        Upper-triangular intrinsic matrix with ``A[2, 2] = 1`` and a positive diagonal (the
        skew ``A[0, 1]`` is whatever P implies).
    R : (3, 3) float64 ndarray
        World → camera rotation, orthonormal with det R = +1.
    t : (3,) float64 ndarray
        World → camera translation; the camera centre is ``C = −Rᵀt``.

    Raises
    ------
    ValueError
        Non-finite values, wrong shape, or a singular left 3×3 block (smallest singular value
        ≤ 1e-12 × largest): such a P is not a finite pinhole camera.
    TypeError
        Non-numeric or complex ``P``.

    Notes
    -----
    §7.6.1: write :math:`P = [M | p_4]` with :math:`M = \\lambda A R` and
    :math:`p_4 = \\lambda A t`.

    1. **Sign of λ.** :math:`\\det M = \\lambda^3 \\det A \\det R` with :math:`\\det A > 0`
       and :math:`\\det R = 1`, so multiplying P by :math:`\\operatorname{sign}(\\det M)`
       makes λ positive.
    2. **RQ decomposition** :math:`M = K Q` (upper triangular times orthogonal), computed from
       NumPy's QR of the row-reversed transpose. It is unique only up to the signs
       :math:`D = \\operatorname{diag}(\\pm 1)`: :math:`K Q = (K D)(D Q)`. Choosing D so that the
       diagonal of :math:`K D` is positive makes the factors unique, and then
       :math:`\\det(DQ) = +1` because of step 1.
    3. **Scale.** :math:`A = K / K_{33}` and :math:`R = DQ`; the translation is
       :math:`t = K^{-1} p_4` (not :math:`p_4` itself).

    ``cv2.decomposeProjectionMatrix`` agrees (for λ > 0) on A and R; it returns the camera
    centre :math:`C` as a homogeneous 4-vector instead of t.

    Examples
    --------
    >>> import numpy as np
    >>> A0, R0, t0 = intrinsic_matrix(800, 780, 320, 240), rotation_matrix(0.1, -0.2, 0.3), np.array([0.5, -1, 6])
    >>> A, R, t = decompose_projection(-2.5 * projection_matrix(A0, R0, t0))
    >>> bool(np.allclose(A, A0) and np.allclose(R, R0) and np.allclose(t, t0))
    True
    """
    mat = as_matrix(P, "P", (3, 4))
    M, p4 = mat[:, :3], mat[:, 3]
    singular = np.linalg.svd(M, compute_uv=False)
    if singular[0] == 0.0 or singular[-1] <= _SINGULAR * singular[0]:
        raise ValueError(
            "P must have an invertible left 3×3 block (a finite pinhole camera); its singular values "
            f"are {np.array2string(singular, precision=3)}"
        )
    sign = np.sign(np.linalg.det(M))
    M, p4 = sign * M, sign * p4
    K, Q = _rq(M)
    D = np.sign(np.diag(K))
    K = K * D            # K·D: flips the columns with a negative diagonal entry
    R = D[:, None] * Q   # D·Q: flips the matching rows of Q
    t = np.linalg.solve(K, p4)
    A = K / K[2, 2]
    A[np.tril_indices(3, -1)] = 0.0  # exact zeros below the diagonal
    return A, R, t
