"""Argument checks shared by the camera-model functions (points, matrices, coefficients).

Every helper raises ``TypeError`` (wrong kind of object) or ``ValueError`` (right kind, wrong
value) with a message that names the argument, like :mod:`cvkit._validation`.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array

#: how far from orthonormal (max |RᵀR − I|) a rotation matrix may be: a rotation typed with
#: three decimals (cos 30° as 0.866, cos 45° as 0.707: 4e-5, 2e-4) passes, and is used as
#: given; any matrix that is not a rotation (a scale, a shear, A in R's place) is far beyond
ROTATION_TOLERANCE = 1e-3


def as_points(points: ArrayLike, name: str, dims: int | Sequence[int] | None = None, *, min_dim: int = 1,
              allow_single: bool = False) -> np.ndarray:
    """``points`` as a float64 ``(N, d)`` array (N = 0 allowed), with ``d`` in ``dims`` or, when
    ``dims`` is None, ``d >= min_dim``. With ``allow_single`` a single point of shape ``(d,)``
    is accepted too (and kept 1-D)."""
    ndim = (1, 2) if allow_single else 2
    array = as_float_array(points, name, ndim=ndim, allow_empty=True)
    d = array.shape[-1]
    if dims is not None:
        dims = (dims,) if isinstance(dims, int) else tuple(dims)
        if d not in dims:
            want = " or ".join(str(x) for x in dims)
            shape = f"({want},) or (N, {want})" if allow_single else f"(N, {want})"
            raise ValueError(f"{name} must have shape {shape}, got {array.shape}")
    elif d < min_dim:
        what = "a single point (d,) or (N, d)" if allow_single else "(N, d)"
        raise ValueError(f"{name} must have shape {what} with d >= {min_dim} coordinates, got {array.shape}")
    return array


def as_matrix(value: ArrayLike, name: str, shape: tuple[int, int]) -> np.ndarray:
    """A finite float64 matrix of exactly ``shape``."""
    array = as_float_array(value, name)
    if array.shape != shape:
        raise ValueError(f"{name} must be a {shape[0]}×{shape[1]} matrix, got shape {array.shape}")
    return array


def as_rotation(value: ArrayLike, name: str = "R") -> np.ndarray:
    """A 3×3 rotation matrix: RᵀR = I within :data:`ROTATION_TOLERANCE` and det R = +1."""
    R = as_matrix(value, name, (3, 3))
    error = float(np.abs(R.T @ R - np.eye(3)).max())
    if error > ROTATION_TOLERANCE:
        raise ValueError(
            f"{name} must be a rotation matrix (orthonormal, RᵀR = I), but max |RᵀR − I| = {error:.3g}"
        )
    if np.linalg.det(R) < 0:
        raise ValueError(f"{name} must be a rotation matrix with det = +1, got a reflection (det = −1)")
    return R


def as_translation(value: ArrayLike, name: str = "t") -> np.ndarray:
    """A translation vector of shape (3,) (a (3, 1) column or (1, 3) row is flattened)."""
    array = as_float_array(value, name)
    if array.size != 3 or array.ndim > 2 or (array.ndim == 2 and 1 not in array.shape):
        raise ValueError(f"{name} must be a 3-vector of shape (3,) or (3, 1), got shape {array.shape}")
    return array.reshape(3)


def as_intrinsics(value: ArrayLike, name: str = "A") -> np.ndarray:
    """A 3×3 intrinsic matrix: upper triangular with a non-zero diagonal."""
    A = as_matrix(value, name, (3, 3))
    scale = float(np.abs(A).max())
    lower = np.abs(A[np.tril_indices(3, -1)])
    if scale == 0.0 or lower.max() > 1e-12 * scale:
        raise ValueError(
            f"{name} must be an upper-triangular intrinsic matrix [[fu, s, u0], [0, fv, v0], [0, 0, 1]], "
            f"got {np.array2string(A, precision=4, separator=', ')} (principal point in the bottom row?)"
        )
    if np.any(np.diag(A) == 0):
        raise ValueError(f"{name} must have a non-zero diagonal (fu, fv, 1), got diagonal {np.diag(A)}")
    return A


def distortion_coefficients(k: ArrayLike, p: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """``k`` as (k1, k2, k3) (1–3 entries given, the rest 0) and ``p`` as (p1, p2)."""
    k_arr = as_float_array(k, "k", ndim=(0, 1))
    k_arr = k_arr.reshape(-1)
    if not 1 <= k_arr.size <= 3:
        raise ValueError(f"k must hold 1 to 3 radial coefficients (k1[, k2[, k3]]), got {k_arr.size}")
    p_arr = as_float_array(p, "p", ndim=1)
    if p_arr.size != 2:
        raise ValueError(f"p must hold the 2 tangential coefficients (p1, p2), got {p_arr.size}")
    return np.concatenate([k_arr, np.zeros(3 - k_arr.size)]), p_arr


def radial_tangential(x: np.ndarray, y: np.ndarray, k: np.ndarray,
                      p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Radial factor L(r) = 1 + k1 r² + k2 r⁴ + k3 r⁶ and tangential shifts (dx, dy) of OpenCV's
    model at normalised coordinates (x, y)."""
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[2]))
    xy2 = 2.0 * x * y
    dx = p[0] * xy2 + p[1] * (r2 + 2.0 * x * x)
    dy = p[0] * (r2 + 2.0 * y * y) + p[1] * xy2
    return radial, dx, dy
