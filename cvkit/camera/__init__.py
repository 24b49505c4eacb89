"""Chapter 7 — the camera model (§7.1–7.7 of the notes).

From a 3-D point of the world to a pixel, in four steps (§7.7.3):

=============================== =========================================== ===================
step                            formula                                     function
=============================== =========================================== ===================
1. world → camera frame          M_C = R·M_W + t  (G = [[R, t], [0, 1]])      ``extrinsic_matrix``
2. canonical projection          (x, y) = (x_C / z_C, y_C / z_C)
3. lens distortion               (x_d, y_d) = L(r)·(x, y) + Δ(x, y)          ``distort``
4. intrinsics                    [u, v, 1]ᵀ ≃ A·[x_d, y_d, 1]ᵀ                 ``intrinsic_matrix``
=============================== =========================================== ===================

``project_full`` runs all four; without distortion the linear model P = A[R|t]
(``projection_matrix``, ``project``) does the same in homogeneous coordinates
(``to_homogeneous``, ``from_homogeneous``), also for points at infinity, whose images are
vanishing points. ``decompose_projection`` factorises P back into A, R, t, and
``undistort_points`` inverts the distortion (it warns with ``ConvergenceWarning`` where it
cannot). The argument checks ``as_points``, ``as_matrix``, ``as_rotation``, ``as_translation``,
``as_intrinsics`` and ``distortion_coefficients``, the lens model's arithmetic
``radial_tangential``, ``project_full``'s steps on checked arguments (``project_checked``) and
``rotation_matrix`` for arrays of angles (``rotation_matrices``)
are public for the topics built on the camera model (not algorithms of the catalog, so not in
``__all__``).

Conventions: pixels are (u, v) = (x, y) = (col, row) with the origin at the top-left pixel;
the camera frame has x to the right, y down and z along the optical axis (OpenCV's); angles
are radians; ``R, t`` map world to camera coordinates (the camera centre in the world is
C = −Rᵀt); the image plane is in front of the optical centre (no minus signs). Point sets are
``(N, 2)`` / ``(N, 3)`` arrays; every function returns float64 and never modifies its inputs.

>>> import numpy as np
>>> from cvkit import camera
>>> A = camera.intrinsic_matrix(800, 800, 320, 240)
>>> R, t = camera.rotation_matrix(0.0, 0.1, 0.0), np.array([0.0, 0.0, 5.0])
>>> camera.project(camera.projection_matrix(A, R, t), [[0.0, 0.0, 0.0]])
array([[320., 240.]])
"""
from . import _projection
from ._homogeneous import from_homogeneous, to_homogeneous
from ._projection import (
    decompose_projection,
    extrinsic_matrix,
    intrinsic_matrix,
    project,
    projection_matrix,
    rotation_matrices,
    rotation_matrix,
)
from ._distortion import ConvergenceWarning, distort, project_checked, project_full, undistort_points

# argument checks of the camera model, public for the topics built on it (calibration, warp, data)
from ._common import (
    as_intrinsics,
    as_matrix,
    as_points,
    as_rotation,
    as_translation,
    distortion_coefficients,
    radial_tangential,
)

__all__ = [
    "to_homogeneous",
    "from_homogeneous",
    *_projection.__all__,
    "distort",
    "undistort_points",
    "project_full",
]
