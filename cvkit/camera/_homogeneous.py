"""Homogeneous coordinates (§7.4.1–7.4.2): from Euclidean points to projective ones and back."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..registry import algorithm
from ._common import as_points

__all__ = ["to_homogeneous", "from_homogeneous"]


@algorithm("camera.to_homogeneous", section="7.4.1", check="cvkit.camera.checks:to_homogeneous")
def to_homogeneous(points: ArrayLike) -> np.ndarray:
    """Append a homogeneous coordinate equal to 1 to every point.

    Parameters
    ----------
    points : (N, d) or (d,) array_like
        N Euclidean points of dimension d >= 1 (``(x, y)`` image points, ``(x, y, z)`` world
        points, ...), or a single point; any real dtype, finite values. N = 0 is allowed.

    Returns
    -------
    (N, d + 1) or (d + 1,) float64 ndarray
        ``[x, y, ..., 1]`` for every point (a new array, also for integer input).

    Raises
    ------
    ValueError
        ``points`` with more than 2 dimensions, no coordinate, or non-finite values.
    TypeError
        Non-numeric or complex ``points``.

    Notes
    -----
    §7.4.1: the Euclidean point :math:`m = [u, v]^T` of the plane becomes the projective point
    :math:`\\tilde m = [u, v, 1]^T`, the representative with last coordinate 1 of the
    equivalence class :math:`[ku, kv, k]^T,\\ k \\neq 0` (a ray through the origin). The same
    holds in 3-D: :math:`[x, y, z]^T \\mapsto [x, y, z, 1]^T`. Points at infinity (last
    coordinate 0, §7.4.2) have no Euclidean counterpart and are never produced here.
    Equals ``cv2.convertPointsToHomogeneous`` (without its extra axis).

    Examples
    --------
    >>> to_homogeneous([[3, 4], [-1, 0.5]])
    array([[ 3. ,  4. ,  1. ],
           [-1. ,  0.5,  1. ]])
    >>> to_homogeneous([1.0, 2.0, 3.0])
    array([1., 2., 3., 1.])
    """
    pts = as_points(points, "points", min_dim=1, allow_single=True)
    out = np.empty(pts.shape[:-1] + (pts.shape[-1] + 1,))
    out[..., :-1] = pts
    out[..., -1] = 1.0
    return out


@algorithm("camera.from_homogeneous", section="7.4.1", check="cvkit.camera.checks:from_homogeneous")
def from_homogeneous(points_h: ArrayLike) -> np.ndarray:
    """Divide every homogeneous point by its last coordinate and drop it.

    Parameters
    ----------
    points_h : (N, d + 1) or (d + 1,) array_like
        N homogeneous points (or one), d >= 1; any real dtype, finite values. The last
        coordinate may be 0 (a point at infinity). N = 0 is allowed.

    Returns
    -------
    (N, d) or (d,) float64 ndarray
        ``[x / w, y / w, ...]`` with ``w`` the last coordinate, computed with ``np.divide``
        semantics and without warnings: a point at infinity (``w = 0``) gives ``±inf`` where
        its coordinate is non-zero (signed as the coordinate, and as ``w`` if it is ``-0.0``)
        and ``nan`` where the coordinate is 0 as well.

    Raises
    ------
    ValueError
        ``points_h`` with more than 2 dimensions, fewer than 2 coordinates, or non-finite values.
    TypeError
        Non-numeric or complex ``points_h``.

    Notes
    -----
    §7.4.1: :math:`[\\tilde x, \\tilde y, w]^T \\equiv [\\tilde x / w, \\tilde y / w, 1]^T`
    for :math:`w \\neq 0`, so every representative of the equivalence class gives the same
    Euclidean point. §7.4.2: :math:`[a, b, 0]^T` is the point at infinity in the direction
    :math:`(a, b)`; it has no finite Euclidean coordinates. Equals
    ``cv2.convertPointsFromHomogeneous`` except at infinity, where OpenCV leaves the
    coordinates undivided instead.

    Examples
    --------
    >>> from_homogeneous([[6, -4, 2], [1, 1, -0.5]])
    array([[ 3., -2.],
           [-2., -2.]])
    >>> from_homogeneous([[1.0, 0.0, 0.0]])
    array([[inf, nan]])
    """
    pts = as_points(points_h, "points_h", min_dim=2, allow_single=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return pts[..., :-1] / pts[..., -1:]
