"""Stereo pairs with ground truth (Chapter 2), from the images bundled with scikit-image.

>>> left, right, disparity = stereo_motorcycle()
>>> left.shape, right.shape, disparity.shape
((500, 741, 3), (500, 741, 3), (500, 741))
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ._common import skimage_data

__all__ = ["stereo_motorcycle", "MOTORCYCLE_CALIBRATION"]

#: Calibration of the (4× down-sampled) motorcycle pair, from scikit-image's documentation:
#: focal length and principal points in pixels, baseline in millimetres. ``doffs`` is the
#: difference of the two principal points' x coordinates (right − left is negative here):
#: depth is ``baseline · focal / (d + doffs)``.
MOTORCYCLE_CALIBRATION = {
    "focal": 994.978,
    "cx": 311.193,
    "cy": 254.877,
    "doffs": 31.086,
    "baseline": 193.001,
}

#: ITU-R BT.601 luma weights (those of ``cv2.cvtColor(..., COLOR_RGB2GRAY)``)
_LUMA = np.array([0.299, 0.587, 0.114])


def _to_gray(rgb: ArrayLike) -> np.ndarray:
    """Luma ``0.299 R + 0.587 G + 0.114 B`` of an ``(H, W, 3)`` image (float64, not rescaled)."""
    arr = np.asarray(rgb, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"rgb must be an (H, W, 3) colour image, got shape {arr.shape}")
    return arr @ _LUMA


def stereo_motorcycle(gray: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rectified 'motorcycle' stereo pair of Middlebury 2014 with its ground truth.

    Parameters
    ----------
    gray : bool
        Return the two images as grayscale luma (``0.299 R + 0.587 G + 0.114 B``) instead of
        RGB.

    Returns
    -------
    left, right : (500, 741, 3) or (500, 741) float64 ndarray
        The two views in [0, 1] (scikit-image's uint8 images divided by 255).
    disparity : (500, 741) float64 ndarray
        Ground-truth disparity of every left pixel, in pixels (sub-pixel precision, about
        7 to 60): the pixel ``(x, y)`` of the left image shows the same scene point as
        ``(x − disparity[y, x], y)`` of the right image. **Pixels without ground truth
        (occluded in the right view, or not measured) are NaN** — scikit-image's file stores
        them as +inf, which is converted here; about 7.3% of the pixels.

    Notes
    -----
    Part of the Middlebury 2014 stereo benchmark (Scharstein et al., GCPR 2014), down-sampled
    4× by scikit-image, which ships it (``skimage.data.stereo_motorcycle``): nothing is
    downloaded. :data:`MOTORCYCLE_CALIBRATION` holds the focal length (994.978 px), the
    baseline (193.001 mm) and ``doffs`` (31.086 px): the depth of a pixel is
    ``baseline · focal / (disparity + doffs)`` because the principal points of the two
    cameras are not at the same column. The exposures of the two views differ slightly,
    which costs SAD and SSD matching accuracy but not ZNCC. Needs scikit-image, an optional
    extra (``pip install "cvkit[data]"``; ``ImportError`` saying so otherwise).
    """
    left, right, disparity = skimage_data().stereo_motorcycle()
    left = left.astype(np.float64) / 255.0
    right = right.astype(np.float64) / 255.0
    disparity = np.asarray(disparity, dtype=np.float64)
    disparity = np.where(np.isfinite(disparity), disparity, np.nan)
    if gray:
        left, right = _to_gray(left), _to_gray(right)
    return left, right, disparity
