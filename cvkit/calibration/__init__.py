"""Chapter 8 — camera calibration with Zhang's method (§8.1–8.3 of the notes).

Calibration estimates the camera model of Chapter 7 — intrinsic matrix A, lens distortion k
and the pose (R_i, t_i) of every view — from images of a planar chessboard whose geometry is
known. Zhang's method (§8.2.1), step by step:

=================================== ============================================= =========
step                                 function                                      §
=================================== ============================================= =========
pattern points and image corners     ``chessboard_points``, ``find_chessboard_corners`` 8.3
... saddle response, candidates      ``chessboard_response``, ``corner_candidates``   8.3
... grid, its order                  ``grow_grid``, ``order_grid_corners``          8.3
... sub-pixel position               ``refine_corners``                             8.3
homography of each view (linear)     ``homography_dlt``                            8.3.2
... refined on the reprojection      ``refine_homography`` (``levenberg_marquardt``) 8.3.4
intrinsics from B = A⁻ᵀA⁻¹           ``intrinsics_from_homographies``              8.3.5
extrinsics of each view              ``extrinsics_from_homography``                8.3.6
radial distortion, least squares     ``estimate_radial_distortion``                8.3.7
everything refined together          ``calibrate``                                 8.3.8
=================================== ============================================= =========

``calibrate`` runs the whole chain, calling each building block through the registry (so
``with cvkit.use("student"):`` runs it on a student's versions). Conventions: pixels are
``(x, y) = (col, row)``; the pattern's world frame has z = 0 on the board; ``R, t`` map world
to camera coordinates (Chapter 7); distortion follows OpenCV's model.

>>> from cvkit import calibration, data
>>> views = data.chessboard_views(n_views=4, render=False)
>>> result = calibration.calibrate(views.world_points, views.image_points)
>>> round(float(result.A[0, 0]), 6), round(float(result.A[1, 1]), 6)
(800.0, 820.0)
"""
from ._pattern import (
    chessboard_points,
    chessboard_response,
    corner_candidates,
    find_chessboard_corners,
    grow_grid,
    order_grid_corners,
    refine_corners,
)
from ._homography import homography_dlt, refine_homography
from ._optimize import levenberg_marquardt
from ._zhang import (
    CalibrationResult,
    calibrate,
    estimate_radial_distortion,
    extrinsics_from_homography,
    intrinsics_from_homographies,
)

__all__ = [
    "chessboard_points",
    "chessboard_response",
    "corner_candidates",
    "grow_grid",
    "order_grid_corners",
    "refine_corners",
    "find_chessboard_corners",
    "homography_dlt",
    "levenberg_marquardt",
    "refine_homography",
    "intrinsics_from_homographies",
    "extrinsics_from_homography",
    "estimate_radial_distortion",
    "calibrate",
]
