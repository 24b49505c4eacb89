"""Homographies between the pattern plane and the image (§8.3.1–8.3.4): the linear DLT estimate
and its refinement by minimising the reprojection error."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..camera import as_matrix, as_points
from ..registry import algorithm, implementation

__all__ = ["homography_dlt", "refine_homography"]


def _point_pairs(src: ArrayLike, dst: ArrayLike, minimum: int = 4) -> tuple[np.ndarray, np.ndarray]:
    s = as_points(src, "src", 2)
    d = as_points(dst, "dst", 2)
    if s.shape != d.shape:
        raise ValueError(f"src and dst must hold the same number of points, got shapes {s.shape} and {d.shape}")
    if len(s) < minimum:
        raise ValueError(f"a homography needs at least {minimum} point pairs, got {len(s)}")
    return s, d


def hartley_normalization(points: np.ndarray, name: str = "points") -> np.ndarray:
    """T (3×3) moving the centroid of ``points`` to the origin and scaling their mean distance
    from it to √2 (Hartley's normalisation)."""
    centroid = points.mean(axis=0)
    distance = float(np.mean(np.hypot(*(points - centroid).T)))
    if not distance > 0.0:
        raise ValueError(f"{name} must not all coincide")
    s = np.sqrt(2.0) / distance
    return np.array([[s, 0.0, -s * centroid[0]], [0.0, s, -s * centroid[1]], [0.0, 0.0, 1.0]])


def _apply(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ T[:2, :2].T + T[:2, 2]


def _dlt_matrix(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The 2N×9 matrix L of the DLT: rows 2i and 2i+1 are the first two components of
    m̃ × (H w̃) = 0 (up to sign) for the pair w = src[i], m = dst[i]."""
    x, y = src[:, 0], src[:, 1]
    u, v = dst[:, 0], dst[:, 1]
    one, zero = np.ones_like(x), np.zeros_like(x)
    L = np.empty((2 * len(src), 9))
    L[0::2] = np.column_stack([x, y, one, zero, zero, zero, -u * x, -u * y, -u])
    L[1::2] = np.column_stack([zero, zero, zero, x, y, one, -v * x, -v * y, -v])
    return L


def _null_vector(L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singular values and the right singular vector of the smallest one, of the full 9×9 Vᵀ.

    Zero rows are appended up to 9 (they change nothing) so that the economy SVD still has all
    nine right singular vectors: with four points L is 8×9 and the null vector is the 9th. (The
    economy SVD also avoids building the 2N×2N matrix U.)"""
    if L.shape[0] < L.shape[1]:
        L = np.vstack([L, np.zeros((L.shape[1] - L.shape[0], L.shape[1]))])
    _, singular, Vt = np.linalg.svd(L, full_matrices=False)
    return singular, Vt[-1]


def _scaled(H: np.ndarray) -> np.ndarray:
    if abs(H[2, 2]) <= 1e-14 * np.abs(H).max():
        raise ValueError("the homography sends the origin of src to infinity (H[2, 2] = 0): it cannot be "
                         "scaled to H[2, 2] = 1")
    return H / H[2, 2]


@algorithm("calibration.homography_dlt", section="8.3.2", check="cvkit.calibration.checks:homography_dlt")
def homography_dlt(src: ArrayLike, dst: ArrayLike, normalize: bool = True) -> np.ndarray:
    """The homography H with dst ≃ H·src, by the Direct Linear Transform.

    Parameters
    ----------
    src, dst : (N, 2) array_like
        Corresponding points (x, y), N ≥ 4, e.g. pattern coordinates (x_W, y_W) and pixels.
    normalize : bool
        Apply Hartley's normalisation (recommended): solve for the homography between the
        normalised point sets and undo the normalisation afterwards.

    Returns
    -------
    (3, 3) float64 ndarray
        H scaled so that H[2, 2] = 1.

    Raises
    ------
    ValueError
        Shapes that differ or are not (N, 2), fewer than 4 pairs, non-finite values, point sets
        in a degenerate configuration (all on a line, or three of four collinear), or an H
        with H[2, 2] = 0.

    Notes
    -----
    §8.3.2: λ m̃ = H w̃ says that H w̃ and m̃ are parallel, m̃ × H w̃ = 0. With
    w̃ = (x, y, 1), m̃ = (u, v, 1) and h the rows of H stacked (h = H.ravel()), the first two
    components of the cross product are linear in h (the third depends on them):

    .. math::

        \\begin{bmatrix} x & y & 1 & 0 & 0 & 0 & -ux & -uy & -u \\\\
                         0 & 0 & 0 & x & y & 1 & -vx & -vy & -v \\end{bmatrix} h = 0 .

    Stacked for the N pairs they form L (2N×9). The unit vector minimising ‖L h‖ is the
    right singular vector of the smallest singular value: the last row of ``Vt`` in
    ``np.linalg.svd(L)`` (with the full 9×9 ``Vt``, which matters when N = 4). This minimises
    an *algebraic* error, whose weighting depends on the coordinates: pixels in the hundreds
    make the entries of L range over ten orders of magnitude and the solution very sensitive to
    noise. Hartley's normalisation fixes this: T (and T′) translate each point set to its
    centroid and scale it to a mean distance √2 from it, separately; the DLT of the normalised
    pairs gives H̃, and H = T′⁻¹ H̃ T. The same as ``cv2.findHomography(src, dst, 0)`` up to
    scale on exact data (OpenCV then refines the algebraic solution by a few Levenberg–Marquardt
    steps on the reprojection error, as :func:`refine_homography` does).

    Examples
    --------
    >>> import numpy as np
    >>> square = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    >>> quad = np.array([[100.0, 100], [300, 120], [280, 310], [90, 290]])
    >>> H = homography_dlt(square, quad)
    >>> m = np.c_[square, np.ones(4)] @ H.T
    >>> np.round(m[:, :2] / m[:, 2:], 9)
    array([[100., 100.],
           [300., 120.],
           [280., 310.],
           [ 90., 290.]])
    """
    s, d = _point_pairs(src, dst)
    if not isinstance(normalize, (bool, np.bool_)):
        raise TypeError(f"normalize must be True or False, got {normalize!r}")
    Ts = hartley_normalization(s, "src")
    Td = hartley_normalization(d, "dst")
    singular, h = _null_vector(_dlt_matrix(_apply(Ts, s), _apply(Td, d)))
    if singular[7] <= 1e-9 * singular[0]:
        raise ValueError("src and dst are in a degenerate configuration (collinear points): the homography is "
                         "not determined")
    if normalize:
        H = np.linalg.solve(Td, h.reshape(3, 3) @ Ts)
    else:
        H = _null_vector(_dlt_matrix(s, d))[1].reshape(3, 3)
    return _scaled(H)


@algorithm("calibration.refine_homography", section="8.3.4", check="cvkit.calibration.checks:refine_homography")
def refine_homography(H: ArrayLike, src: ArrayLike, dst: ArrayLike) -> np.ndarray:
    """Refine a homography by minimising the reprojection error in the destination image.

    Parameters
    ----------
    H : (3, 3) array_like
        Initial homography (dst ≃ H·src), e.g. from :func:`homography_dlt`; any non-zero scale
        with H[2, 2] ≠ 0.
    src, dst : (N, 2) array_like
        Corresponding points, N ≥ 4.

    Returns
    -------
    (3, 3) float64 ndarray
        The refined H, scaled so that H[2, 2] = 1.

    Raises
    ------
    ValueError
        Malformed inputs, fewer than 4 pairs, or H[2, 2] = 0.

    Notes
    -----
    §8.3.4: the DLT minimises an algebraic quantity without physical meaning; what the noise
    of the measured points calls for is the *geometric* (reprojection) error, the sum of
    squared pixel distances between the measured points and the projected pattern points,

    .. math:: H^* = \\arg\\min_H \\sum_j \\lVert m_j - \\pi(H \\tilde w_j) \\rVert^2,
              \\qquad \\pi(x, y, w) = (x / w, y / w),

    one-sided (only the image points are noisy; the pattern is known). It is minimised over the
    eight entries of H other than H[2, 2] = 1 by Levenberg–Marquardt
    (``implementation("calibration.levenberg_marquardt")``) from the given H, with the
    analytic Jacobian. For conditioning the problem is solved between Hartley-normalised point
    sets; the normalisation of dst is a similarity (rotation-free scaling and shift), which
    scales the cost by a constant and leaves its minimiser unchanged.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> grid = np.array([[i, j] for j in range(4) for i in range(5)], dtype=float)
    >>> H_true = np.array([[80.0, 5, 100], [-3, 75, 60], [0.02, 0.01, 1]])
    >>> pixels = grid @ H_true[:2, :2].T + H_true[:2, 2]
    >>> pixels /= (grid @ H_true[2, :2] + 1)[:, None]
    >>> noisy = pixels + rng.normal(0, 0.5, pixels.shape)
    >>> def error(H):
    ...     m = np.c_[grid, np.ones(len(grid))] @ H.T
    ...     return float(np.sum((m[:, :2] / m[:, 2:] - noisy) ** 2))
    >>> H0 = homography_dlt(grid, noisy)
    >>> H1 = refine_homography(H0, grid, noisy)
    >>> error(H1) <= error(H0)
    True
    """
    H0 = as_matrix(H, "H", (3, 3))
    s, d = _point_pairs(src, dst)
    H0 = _scaled(H0)
    Ts = hartley_normalization(s, "src")
    Td = hartley_normalization(d, "dst")
    sn, dn = _apply(Ts, s), _apply(Td, d)
    start = Td @ H0 @ np.linalg.inv(Ts)
    start = _scaled(start)
    x, y = sn[:, 0], sn[:, 1]

    def project(h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        Hm = np.append(h, 1.0).reshape(3, 3)
        w = Hm[2, 0] * x + Hm[2, 1] * y + 1.0
        u = (Hm[0, 0] * x + Hm[0, 1] * y + Hm[0, 2]) / w
        v = (Hm[1, 0] * x + Hm[1, 1] * y + Hm[1, 2]) / w
        return u, v, w

    def residuals(h: np.ndarray) -> np.ndarray:
        u, v, _ = project(h)
        return np.column_stack([u - dn[:, 0], v - dn[:, 1]]).ravel()

    def jacobian(h: np.ndarray) -> np.ndarray:
        u, v, w = project(h)
        J = np.zeros((2 * len(x), 8))
        J[0::2, 0], J[0::2, 1], J[0::2, 2] = x / w, y / w, 1.0 / w
        J[1::2, 3], J[1::2, 4], J[1::2, 5] = x / w, y / w, 1.0 / w
        J[0::2, 6], J[0::2, 7] = -u * x / w, -u * y / w
        J[1::2, 6], J[1::2, 7] = -v * x / w, -v * y / w
        return J

    h, _ = implementation("calibration.levenberg_marquardt")(residuals, start.ravel()[:8], jacobian=jacobian)
    refined = np.append(h, 1.0).reshape(3, 3)
    return _scaled(np.linalg.solve(Td, refined @ Ts))
