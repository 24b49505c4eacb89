"""Geometry of image formation (§2.3–2.5): perspective projection and depth from disparity."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_real
from ..registry import algorithm
from ._common import Values, as_values, scalar_or_array

__all__ = ["project_pinhole", "depth_from_disparity"]


@algorithm("formation.project_pinhole", section="2.3", check="cvkit.formation.checks:project_pinhole")
def project_pinhole(points_cam: ArrayLike, f: float) -> np.ndarray:
    """Perspective projection of 3-D points given in the camera reference system.

    Parameters
    ----------
    points_cam : (N, 3) array_like
        Points ``(x, y, z)`` in the camera frame: origin at the optical centre, z along the
        optical axis, x to the right and y downwards (so that u, v grow like image columns
        and rows). Finite values; ``z`` must not be 0. N may be 0.
    f : float
        Focal length, > 0, in the unit wanted for ``(u, v)`` (the same unit as x, y, z gives
        coordinates on the image plane; pixels give pixel offsets from the image centre c).

    Returns
    -------
    (N, 2) float64 ndarray
        Image points ``(u, v)`` relative to the image centre (piercing point).

    Raises
    ------
    ValueError
        ``points_cam`` not (N, 3), not finite, or with a point at z = 0 (in the focal plane
        F, which has no image); ``f`` not finite and > 0.
    TypeError
        Non-numeric ``points_cam`` or ``f``.

    Notes
    -----
    §2.3, with the image plane moved in front of the pinhole so that the image is upright:

    .. math:: u = f\\,\\frac{x}{z}, \\qquad v = f\\,\\frac{y}{z}

    (the physical image behind the pinhole is :math:`(-u, -v)`). Image sizes scale as
    :math:`1/z`: a segment of length L parallel to the image plane at depth z has an image
    of length :math:`L f / z` (§2.7). Points with z < 0 lie behind the camera; the formula
    is applied to them as well (a real camera does not see them).

    Examples
    --------
    >>> project_pinhole([[1.0, 2.0, 4.0], [-3.0, 0.0, 6.0]], f=2.0)
    array([[ 0.5,  1. ],
           [-1. ,  0. ]])
    """
    points = as_float_array(points_cam, "points_cam", ndim=2, allow_empty=True)
    if points.shape[1] != 3:
        raise ValueError(f"points_cam must have shape (N, 3), got {points.shape}")
    f = check_real(f, "f", positive=True)
    z = points[:, 2]
    if np.any(z == 0):
        raise ValueError(
            "points_cam contains points with z = 0 (in the focal plane): they have no image"
        )
    with np.errstate(over="ignore"):
        uv = f * points[:, :2] / z[:, None]
        # f·x can overflow where the image f·(x/z) is finite: divide first there
        return np.where(np.isfinite(uv), uv, f * (points[:, :2] / z[:, None]))


@algorithm("formation.depth_from_disparity", section="2.5.1", check="cvkit.formation.checks:depth_from_disparity")
def depth_from_disparity(disparity: ArrayLike, baseline: float, focal: float) -> Values:
    """Depth of points seen by a rectified stereo pair, from their disparity.

    Parameters
    ----------
    disparity : float or array_like
        Disparities :math:`d = u_L - u_R` in pixels, any shape and real dtype. NaN (unknown
        disparity) is allowed and gives NaN; +inf gives depth 0.
    baseline : float
        Distance b between the two optical centres, > 0 (any length unit).
    focal : float
        Focal length f in pixels, > 0.

    Returns
    -------
    float64 ndarray of the shape of ``disparity`` (a NumPy float for a scalar)
        Depth :math:`z = b f / d` in the unit of ``baseline``; ``inf`` where d = 0 (a point
        at infinity), ``nan`` where d < 0 (no point in front of both cameras) or d is NaN.

    Notes
    -----
    §2.5.1: with parallel optical axes, the same focal length and baseline b, a point at
    depth z appears in the two images on the same row with horizontal coordinates differing
    by :math:`d = u_L - u_R = b f / z`. Depth is inversely proportional to disparity, so a
    disparity error of one pixel costs :math:`\\Delta z \\approx z^2 / (b f)`: depth
    resolution degrades quadratically with distance.

    Examples
    --------
    >>> depth_from_disparity([[10.0, 0.0, -2.0]], baseline=0.2, focal=500.0)
    array([[10., inf, nan]])
    """
    d = as_values(disparity, "disparity", allow_nan=True, allow_inf=True)
    b = check_real(baseline, "baseline", positive=True)
    f = check_real(focal, "focal", positive=True)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # a tiny d: z = inf, as it should
        z = (b * f) / d
    z = np.where(d == 0, np.inf, z)
    z = np.where(d < 0, np.nan, z)
    return scalar_or_array(z)
