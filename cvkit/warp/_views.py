"""New points of view from a calibrated camera (§8.4.3): the homography of a virtual rotated
camera, and the bird's-eye view of a plane (inverse perspective mapping)."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import check_real
from ..camera import as_intrinsics, as_points, as_rotation
from ..registry import algorithm, implementation

__all__ = ["rotation_homography", "birds_eye_homography"]


@algorithm("warp.rotation_homography", section="8.4.3", check="cvkit.warp.checks:rotation_homography")
def rotation_homography(A: ArrayLike, R: ArrayLike) -> np.ndarray:
    """The homography between the images of a camera and of the same camera rotated by R.

    Parameters
    ----------
    A : (3, 3) array_like
        Intrinsic matrix (upper triangular, non-zero diagonal; skew allowed).
    R : (3, 3) array_like
        Rotation from the original camera frame to the virtual camera's frame (orthonormal
        within 1e-3, det +1; used as given): a point M_C of the first frame has coordinates
        R·M_C in the second.

    Returns
    -------
    (3, 3) float64 ndarray
        H = A·R·A⁻¹ scaled so that H[2, 2] = 1: pixel m of the original image goes to H·m of
        the virtual one (``warp_homography(image, H, shape)`` renders the virtual view).

    Raises
    ------
    ValueError
        A malformed A or R, or a rotation of 90° or more that sends the principal point to
        infinity (H[2, 2] = 0 cannot be normalised).

    Notes
    -----
    §8.4.3: a camera that only rotates about its optical centre sees every point along the
    same ray; only the frame changes, :math:`M_C' = R M_C`, so with
    :math:`\\tilde m \\simeq A M_C`,

    .. math:: \\tilde m' \\simeq A R M_C \\simeq A R A^{-1} \\tilde m.

    The depth of the point drops out: the two images are related by a homography whatever
    the scene (after removing lens distortion). This is how panoramas are stitched, and how a
    camera mounted with a small pitch or yaw error is corrected to a straight-ahead view.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    >>> a = np.deg2rad(10)
    >>> R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])   # yaw by 10°
    >>> H = rotation_homography(A, R)
    >>> m = H @ [320, 240, 1]
    >>> np.round(m[:2] / m[2], 3)      # the principal point moves by f·tan(10°) = 88.163 px
    array([408.163, 240.   ])
    """
    intr = as_intrinsics(A, "A")
    rot = as_rotation(R, "R")
    H = intr @ rot @ np.linalg.inv(intr)
    if abs(H[2, 2]) <= 1e-12 * np.abs(H).max():
        raise ValueError("the rotation sends the principal point to infinity (H[2, 2] = 0): rotate by less than 90°")
    return H / H[2, 2]


@algorithm("warp.birds_eye_homography", section="8.4.3", check="cvkit.warp.checks:birds_eye_homography")
def birds_eye_homography(image_points: ArrayLike, ground_points: ArrayLike, pixels_per_unit: float) -> np.ndarray:
    """The homography from an image of a plane to its bird's-eye view (inverse perspective mapping).

    Parameters
    ----------
    image_points : (4, 2) array_like
        Four pixels (x, y) of the image, images of four points of the ground plane, no three of
        them collinear.
    ground_points : (4, 2) array_like
        The same four points in a metric frame of the ground plane (e.g. metres: x to the
        right, y forward), no three collinear.
    pixels_per_unit : float
        Scale of the bird's-eye image (> 0): one ground unit becomes this many pixels.

    Returns
    -------
    (3, 3) float64 ndarray
        H with H[2, 2] = 1 mapping each image point exactly to ``ground_point·pixels_per_unit``
        — no offset and no axis flip, so ground points with negative coordinates fall outside
        the bird's-eye image unless the caller composes H with a translation (and ground y
        pointing forward appears *down* the rows unless composed with a flip).

    Raises
    ------
    ValueError
        Shapes other than (4, 2), non-finite values, a non-positive scale, three collinear
        points in either set, or a pixel (0, 0) on the horizon of the ground plane (it would
        map to infinity: H[2, 2] = 0).

    Notes
    -----
    §8.4.3: the ground is a plane, and any two images of a plane are related by a
    homography; one of them can be a virtual camera looking straight down, whose image is the
    ground's metric map scaled by ``pixels_per_unit``. Four correspondences fix the eight
    degrees of freedom of H exactly: here by the (normalised) DLT
    (``implementation("calibration.homography_dlt")``), which is exact for four points. Warp
    the camera image with ``warp_homography(image, H, shape)`` to see the plane from above:
    lane markings become parallel, distances on the road become measurable — everything not
    on the plane (cars, posts) is smeared.

    Examples
    --------
    >>> import numpy as np
    >>> img = [[300, 400], [340, 400], [330, 300], [310, 300]]      # a trapezoid on the road...
    >>> ground = [[0, 0], [2, 0], [2, 10], [0, 10]]                   # ...is a 2 m × 10 m rectangle
    >>> H = birds_eye_homography(img, ground, 20.0)
    >>> m = H @ [330, 300, 1]
    >>> np.round(m[:2] / m[2], 6)
    array([ 40., 200.])
    """
    img = as_points(image_points, "image_points", 2)
    ground = as_points(ground_points, "ground_points", 2)
    for name, pts in (("image_points", img), ("ground_points", ground)):
        if pts.shape != (4, 2):
            raise ValueError(f"{name} must have shape (4, 2) (four points), got {pts.shape}")
        _no_three_collinear(pts, name)
    scale = check_real(pixels_per_unit, "pixels_per_unit", positive=True)
    try:
        return implementation("calibration.homography_dlt")(img, ground * scale, normalize=True)
    except ValueError as error:   # e.g. the pixel (0, 0) on the ground's horizon: H[2, 2] = 0
        raise ValueError(f"image_points and ground_points give no bird's-eye homography with H[2, 2] = 1 "
                         f"(homography_dlt: {error})") from error


def _no_three_collinear(points: np.ndarray, name: str) -> None:
    extent = float(np.ptp(points, axis=0).max())
    for drop in range(4):
        a, b, c = points[[i for i in range(4) if i != drop]]
        area = abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
        if extent == 0.0 or area <= 1e-9 * extent * extent:
            raise ValueError(f"{name} must not contain three collinear points (points {sorted(set(range(4)) - {drop})})")
