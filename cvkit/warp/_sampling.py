"""Resampling an image at real-valued positions (§8.4.2): bilinear interpolation, backward
warping through a homography, and undistortion of a whole image (§8.4.1)."""
from __future__ import annotations

import numbers

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, as_image, check_allocation, check_int
from ..camera import as_intrinsics, as_matrix, distortion_coefficients
from ..registry import algorithm, implementation

__all__ = ["bilinear_sample", "warp_homography", "undistort_image"]

_CHUNK = 8192  # positions per block in bilinear_sample (64 KiB temporaries)


def _fill_value(fill: object) -> float:
    if isinstance(fill, (bool, np.bool_)) or not isinstance(fill, (numbers.Real, np.integer, np.floating)):
        raise TypeError(f"fill must be a real number, got {type(fill).__name__} {fill!r}")
    return float(fill)  # NaN is allowed: it marks "outside" unmistakably


def _output_shape(output_shape: object) -> tuple[int, int]:
    if isinstance(output_shape, np.ndarray):
        output_shape = tuple(output_shape.tolist())
    if not isinstance(output_shape, (tuple, list)) or len(output_shape) != 2:
        raise ValueError(f"output_shape must be a pair (rows, cols), got {output_shape!r}")
    return (check_int(output_shape[0], "output_shape[0] (rows)", minimum=1),
            check_int(output_shape[1], "output_shape[1] (cols)", minimum=1))


@algorithm("warp.bilinear_sample", section="8.4.2", check="cvkit.warp.checks:bilinear_sample")
def bilinear_sample(image: ArrayLike, x: ArrayLike, y: ArrayLike, fill: float = 0.0) -> np.ndarray:
    """Values of an image at real-valued positions by bilinear interpolation.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Grey or colour image, any real dtype (computed in float64, not rescaled).
    x, y : array_like
        Positions ``(x, y) = (col, row)``, in pixels, of any (common, broadcastable) shape.
        Non-finite positions count as outside. The result, of their broadcast shape (× 3 for
        colour), may take at most 2 GiB (``ValueError`` naming ``x and y``).
    fill : float
        Value returned for positions outside the image.

    Returns
    -------
    float64 ndarray
        Shape ``np.broadcast(x, y).shape`` for a grey image, that shape + ``(3,)`` for a colour
        one.

    Raises
    ------
    ValueError, TypeError
        A malformed image, positions that do not broadcast, or a non-real ``fill``.

    Notes
    -----
    §8.4.2: with :math:`x_0 = \\lfloor x \\rfloor`, :math:`y_0 = \\lfloor y \\rfloor`,
    :math:`a = x - x_0`, :math:`b = y - y_0`,

    .. math::

        I(x, y) = (1-a)(1-b)\\,I[y_0, x_0] + a(1-b)\\,I[y_0, x_0+1]
                + (1-a)\\,b\\,I[y_0+1, x_0] + a\\,b\\,I[y_0+1, x_0+1]

    (each neighbour weighted by the area of the opposite sub-rectangle). A position is inside
    when :math:`0 \\le x \\le W-1` and :math:`0 \\le y \\le H-1` — the last row and column
    included, where the formula uses only the pixels it needs — and gets ``fill`` otherwise,
    as ``scipy.ndimage.map_coordinates(image, [y, x], order=1, mode="constant", cval=fill)``
    (note SciPy's (row, col) order).

    Examples
    --------
    >>> import numpy as np
    >>> img = np.array([[0.0, 10.0], [20.0, 30.0]])
    >>> bilinear_sample(img, [0.5, 1.0, 1.5], [0.5, 1.0, 0.0], fill=-1.0)
    array([15., 30., -1.])
    """
    img = as_image(image)
    xs = as_float_array(x, "x", finite=False, allow_empty=True)
    ys = as_float_array(y, "y", finite=False, allow_empty=True)
    fill = _fill_value(fill)
    try:
        xs, ys = np.broadcast_arrays(xs, ys)
    except ValueError:
        raise ValueError(f"x and y must have the same (or broadcastable) shapes, got {xs.shape} and {ys.shape}") from None
    check_allocation(xs.shape + img.shape[2:], "x and y", what="samples")
    H, W = img.shape[:2]
    flat = img.reshape(H * W, -1) if img.ndim == 3 else img.reshape(-1)
    dx, dy = (1 if W > 1 else 0), (W if H > 1 else 0)
    right, below, diagonal = flat[dx:], flat[dy:], flat[dy + dx:]    # shifted views: no index arithmetic
    x, y = xs.reshape(-1), ys.reshape(-1)
    out = np.empty(x.shape + img.shape[2:])
    for start in range(0, x.size, _CHUNK):          # blocks of positions: the temporaries stay in cache
        xc, yc = x[start:start + _CHUNK], y[start:start + _CHUNK]
        with np.errstate(invalid="ignore"):
            # outside: beyond [0, W − 1] × [0, H − 1], or NaN (every comparison with NaN is False)
            # (compared with 0 and W − 1 themselves: |x − c| ≤ c with c = (W − 1)/2 would let
            # a tiny negative x round to inside)
            outside = ~((xc >= 0) & (xc <= W - 1) & (yc >= 0) & (yc <= H - 1))
            # the left/top neighbour: truncation is the floor for the positions inside (≥ 0),
            # kept one pixel from the far edge so that x = W − 1 uses a = 1 (positions outside
            # get some index in the image, and `fill` below)
            x0 = np.clip(xc.astype(np.intp), 0, max(W - 2, 0))
            y0 = np.clip(yc.astype(np.intp), 0, max(H - 2, 0))
        a = xc - x0
        b = yc - y0
        index = y0 * W + x0
        if img.ndim == 3:
            a, b, outside = a[:, None], b[:, None], outside[:, None]
        with np.errstate(invalid="ignore"):
            top = flat[index]                          # (1 − a)·I[y0, x0] + a·I[y0, x0 + 1] ...
            top += a * (right[index] - top)
            bottom = below[index]
            bottom += a * (diagonal[index] - bottom)
            top += b * (bottom - top)                  # ... then the same between the two rows
        np.copyto(top, fill, where=np.broadcast_to(outside, top.shape))
        out[start:start + _CHUNK] = top
    return out.reshape(xs.shape + img.shape[2:])


def _pixel_grid(rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) of every pixel of a rows × cols image, each of shape (rows, cols)."""
    return np.meshgrid(np.arange(cols, dtype=np.float64), np.arange(rows, dtype=np.float64))


@algorithm("warp.warp_homography", section="8.4.2", check="cvkit.warp.checks:warp_homography")
def warp_homography(image: ArrayLike, H: ArrayLike, output_shape: Sequence[int] | np.ndarray,
                    fill: float = 0.0) -> np.ndarray:
    """Warp an image through a homography by backward mapping and bilinear interpolation.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Input image, any real dtype (computed in float64, not rescaled).
    H : (3, 3) array_like
        Homography mapping *input* pixel coordinates (x, y, 1) to *output* ones (any non-zero
        scale; it must be invertible).
    output_shape : (rows, cols)
        Size of the output image (positive integers); the output may take at most 2 GiB
        (``ValueError`` naming ``output_shape``, before anything is allocated).
    fill : float
        Value of output pixels whose source lies outside the input.

    Returns
    -------
    (rows, cols) or (rows, cols, 3) float64 ndarray

    Raises
    ------
    ValueError
        A singular ``H``, a malformed image or shape.

    Notes
    -----
    §8.4.2. *Forward* mapping — sending every input pixel to ``H·(x, y, 1)`` and rounding —
    leaves holes where the warp stretches the image and piles several pixels onto one where
    it shrinks it. *Backward* mapping visits every output pixel :math:`(x', y')` instead,
    finds where it comes from, :math:`(x, y, w)^T = H^{-1}(x', y', 1)^T`, divides by
    :math:`w` and reads the input there by bilinear interpolation
    (``implementation("warp.bilinear_sample")``). Output pixels whose source is outside the
    input (or at infinity, w = 0) get ``fill``. The same as
    ``skimage.transform.warp(image, ProjectiveTransform(H).inverse, order=1, cval=fill,
    output_shape=...)`` and, away from the border, ``cv2.warpPerspective(image, H, (cols,
    rows), flags=INTER_LINEAR)`` (OpenCV interpolates with 1/32-pixel fixed-point weights).

    Examples
    --------
    >>> import numpy as np
    >>> img = np.arange(12.0).reshape(3, 4)
    >>> shift = np.array([[1.0, 0, 1], [0, 1, 0], [0, 0, 1]])   # one pixel to the right
    >>> warp_homography(img, shift, (3, 4), fill=-1)
    array([[-1.,  0.,  1.,  2.],
           [-1.,  4.,  5.,  6.],
           [-1.,  8.,  9., 10.]])
    """
    img = as_image(image)
    M = as_matrix(H, "H", (3, 3))
    rows, cols = _output_shape(output_shape)
    check_allocation((rows, cols) + img.shape[2:], "output_shape", what="an output image")
    fill = _fill_value(fill)
    singular = np.linalg.svd(M, compute_uv=False)
    if singular[0] == 0.0 or singular[-1] <= 1e-13 * singular[0]:
        raise ValueError(f"H must be invertible, its singular values are {np.array2string(singular, precision=3)}")
    inverse = np.linalg.inv(M)
    xo = np.arange(cols, dtype=np.float64)[None, :]
    yo = np.arange(rows, dtype=np.float64)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        w = 1.0 / (inverse[2, 0] * xo + (inverse[2, 1] * yo + inverse[2, 2]))   # (rows, cols) by broadcasting
        x = (inverse[0, 0] * xo + (inverse[0, 1] * yo + inverse[0, 2])) * w
        y = (inverse[1, 0] * xo + (inverse[1, 1] * yo + inverse[1, 2])) * w
    return implementation("warp.bilinear_sample")(img, x, y, fill=fill)


@algorithm("warp.undistort_image", section="8.4.1", exercise="8.4.2", check="cvkit.warp.checks:undistort_image")
def undistort_image(image: ArrayLike, A: ArrayLike, k: ArrayLike, p: ArrayLike = (0.0, 0.0)) -> np.ndarray:
    """Remove lens distortion from an image: what a distortion-free camera would see.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Image taken by the camera (A, k, p), any real dtype.
    A : (3, 3) array_like
        Intrinsic matrix of the camera, kept for the undistorted image.
    k : sequence of 1 to 3 floats
        Radial distortion coefficients ``(k1[, k2[, k3]])``.
    p : sequence of 2 floats
        Tangential coefficients ``(p1, p2)``.

    Returns
    -------
    float64 ndarray of the shape of ``image``
        The undistorted image, 0 where its pixels see outside the input.

    Notes
    -----
    §8.4.1 as a backward warp (§8.4.2): for every pixel :math:`(u, v)` of the *undistorted*
    output, the ideal normalised coordinates are :math:`(x, y, 1)^T = A^{-1}(u, v, 1)^T`; the
    lens moves them to :math:`(x_d, y_d)` = ``distort((x, y), k, p)``
    (``implementation("camera.distort")``, no inversion needed), which the camera records at
    the pixel :math:`A (x_d, y_d, 1)^T` of the input; that is where the output pixel is read,
    bilinearly (``implementation("warp.bilinear_sample")``), with 0 outside. Same as
    ``cv2.undistort(image, A, (k1, k2, p1, p2, k3))`` (OpenCV's ``remap`` interpolates with
    1/32-pixel fixed-point weights, so the two differ by a few 1e-3 of the contrast at edges).

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[100.0, 0, 10], [0, 100, 10], [0, 0, 1]])
    >>> img = np.ones((21, 21))
    >>> out = undistort_image(img, A, k=(0.5,))       # pincushion: the corners see outside
    >>> float(out[10, 10]), float(out[0, 0])
    (1.0, 0.0)
    """
    img = as_image(image)
    intr = as_intrinsics(A, "A")
    intr = intr / intr[2, 2]
    distortion_coefficients(k, p)  # validate
    rows, cols = img.shape[:2]
    u, v = _pixel_grid(rows, cols)
    y = (v - intr[1, 2]) / intr[1, 1]
    x = (u - intr[0, 2] - intr[0, 1] * y) / intr[0, 0]
    xd = implementation("camera.distort")(np.column_stack([x.ravel(), y.ravel()]), k, p)
    src_u = intr[0, 0] * xd[:, 0] + intr[0, 1] * xd[:, 1] + intr[0, 2]
    src_v = intr[1, 1] * xd[:, 1] + intr[1, 2]
    return implementation("warp.bilinear_sample")(img, src_u.reshape(rows, cols), src_v.reshape(rows, cols), fill=0.0)
