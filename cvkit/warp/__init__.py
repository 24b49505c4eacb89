"""Chapter 8, second half — image warping (§8.4 of the notes).

Warping moves pixels instead of changing their values. Every function here maps *backward*:
for each pixel of the output it computes where that pixel comes from in the input and reads
the input there by bilinear interpolation, so the output has neither holes nor folds.

==================================== ============================================ =========
function                              what                                         §
==================================== ============================================ =========
``bilinear_sample(image, x, y)``      the image at real-valued (x, y)              8.4.2
``warp_homography(image, H, shape)``  the image seen through a homography H        8.4.2
``undistort_image(image, A, k, p)``   the image a distortion-free camera sees      8.4.1
``rotation_homography(A, R)``         H = A·R·A⁻¹ of a virtual rotated camera      8.4.3
``birds_eye_homography(img, gnd, s)`` image → bird's-eye view of a plane (IPM)     8.4.3
==================================== ============================================ =========

Conventions: images are indexed ``[row, col]``, points are ``(x, y) = (col, row)``, a
homography maps *input* to *output* pixel coordinates and is used through its inverse; values
are computed in float64 and not rescaled; inputs are never modified.

>>> import numpy as np
>>> from cvkit import warp
>>> img = np.arange(16.0).reshape(4, 4)
>>> float(warp.bilinear_sample(img, 1.5, 2.0))
9.5
"""
from ._sampling import bilinear_sample, undistort_image, warp_homography
from ._views import birds_eye_homography, rotation_homography

__all__ = [
    "bilinear_sample",
    "warp_homography",
    "undistort_image",
    "rotation_homography",
    "birds_eye_homography",
]
