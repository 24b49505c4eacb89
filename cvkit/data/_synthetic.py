"""Synthetic test images with known geometry: disks, rotated squares and straight step edges.

They are made by code (no files), anti-aliased by supersampling: a pixel on the boundary gets
the fraction of its area that lies inside the shape, as a camera would record it. The exact
boundary is known, which lets the notebooks and the checks measure how well an edge detector
localises edges and how its response depends on the edge orientation.

Coordinates follow the catalog: pixel ``[row, col]`` is the unit square centred on the point
``(x, y) = (col, row)``; angles are radians from the x axis with y pointing down the rows.

>>> img = disk_image((9, 9), radius=3.0)
>>> img.shape, float(img[4, 4]), float(img[0, 0])
((9, 9), 1.0, 0.0)
"""
from __future__ import annotations

import math

import numpy as np

from .._validation import check_real, check_size
from ._common import centre_point, coverage, image_shape

__all__ = ["disk_image", "square_image", "oriented_step_image", "step_signal"]

#: the most samples :func:`step_signal` makes (one ``math.erf`` call each)
MAX_SIGNAL = 10**7


def _levels(inside: float, outside: float, names: tuple[str, str] = ("inside", "outside")) -> tuple[float, float]:
    return check_real(inside, names[0]), check_real(outside, names[1])


def disk_image(shape: tuple[int, int] = (64, 64), centre: tuple[float, float] | None = None, radius: float = 20.0,
               inside: float = 1.0, outside: float = 0.0, supersample: int = 8) -> np.ndarray:
    """A filled disk, anti-aliased: its boundary contains every edge orientation.

    Parameters
    ----------
    shape : (rows, cols)
        Image size.
    centre : (x, y), optional
        Centre in pixel coordinates (x = column); default the middle of the image. Off-grid
        centres (e.g. ``(31.3, 30.8)``) avoid the exact symmetries of a centred disk.
    radius : float
        Radius in pixels, > 0.
    inside, outside : float
        Intensities inside and outside the disk.
    supersample : int
        Samples per pixel side for the anti-aliasing (1: a hard, aliased disk).

    The image and its grid of ``supersample²`` samples per pixel may each take at most
    2 GiB (``ValueError`` naming ``shape`` or ``supersample``).

    Returns
    -------
    (rows, cols) float64 ndarray

    Examples
    --------
    >>> img = disk_image((32, 40), centre=(20.3, 15.8), radius=9.5, inside=0.8, outside=0.2)
    >>> img.shape, round(float(img.max()), 3), round(float(img.min()), 3)
    ((32, 40), 0.8, 0.2)
    """
    rows, cols = image_shape(shape)
    cx, cy = centre_point(centre, rows, cols)
    radius = check_real(radius, "radius", positive=True)
    inside, outside = _levels(inside, outside)
    cover = coverage(rows, cols, lambda x, y: (x - cx) ** 2 + (y - cy) ** 2 <= radius * radius, supersample)
    return outside + (inside - outside) * cover


def square_image(shape: tuple[int, int] = (64, 64), centre: tuple[float, float] | None = None, side: float = 32.0,
                 angle: float = 0.0, inside: float = 1.0, outside: float = 0.0, supersample: int = 8) -> np.ndarray:
    """A filled square of side ``side`` rotated by ``angle`` radians, anti-aliased.

    Its four edges have the orientations ``angle + k·π/2``; its corners are where edge
    detectors break down. The other arguments, and the bounds on ``shape`` and
    ``supersample``, are those of :func:`disk_image`.

    Examples
    --------
    >>> img = square_image((20, 20), side=10.0)
    >>> float(img[10, 10]), float(img[0, 0]), float(img.sum())
    (1.0, 0.0, 100.0)
    """
    rows, cols = image_shape(shape)
    cx, cy = centre_point(centre, rows, cols)
    side = check_real(side, "side", positive=True)
    angle = check_real(angle, "angle")
    inside, outside = _levels(inside, outside)
    c, s = math.cos(angle), math.sin(angle)
    half = side / 2.0

    def inside_square(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        u = (x - cx) * c + (y - cy) * s
        v = -(x - cx) * s + (y - cy) * c
        return (np.abs(u) <= half) & (np.abs(v) <= half)

    return outside + (inside - outside) * coverage(rows, cols, inside_square, supersample)


def oriented_step_image(shape: tuple[int, int] = (64, 64), angle: float = 0.0, offset: float = 0.0,
                        low: float = 0.0, high: float = 1.0, supersample: int = 8) -> np.ndarray:
    """A straight step edge whose normal points at ``angle`` radians, anti-aliased.

    The edge is the line ``(x − xc)·cos(angle) + (y − yc)·sin(angle) = offset`` through the
    image centre ``(xc, yc)`` shifted by ``offset`` pixels along the normal; intensity is
    ``high`` on the side the normal points to and ``low`` on the other. The gradient of the
    image therefore points at ``angle`` (y down). ``shape`` and ``supersample`` are bounded
    as for :func:`disk_image`.

    Examples
    --------
    >>> oriented_step_image((2, 6), angle=0.0, offset=0.25)[0]
    array([0.  , 0.  , 0.  , 0.75, 1.  , 1.  ])
    """
    rows, cols = image_shape(shape)
    angle = check_real(angle, "angle")
    offset = check_real(offset, "offset")
    high, low = _levels(high, low, ("high", "low"))
    cx, cy = (cols - 1) / 2.0, (rows - 1) / 2.0
    c, s = math.cos(angle), math.sin(angle)
    cover = coverage(rows, cols, lambda x, y: (x - cx) * c + (y - cy) * s >= offset, supersample)
    return low + (high - low) * cover


def step_signal(n: int = 101, position: float = 50.3, width: float = 3.0, low: float = 0.2,
                high: float = 0.8) -> np.ndarray:
    """A 1-D blurred step: ``low + (high − low)·Φ((x − position)/width)`` at x = 0..n−1.

    Φ is the standard normal cumulative distribution, so the step is a perfect edge blurred by
    a Gaussian of standard deviation ``width`` (``width = 0`` gives a sharp step). Its first
    derivative peaks, and its second derivative crosses zero, exactly at ``position`` (the
    inflection point). ``n`` is the number of samples, 1 <= n <= 10**7 (:data:`MAX_SIGNAL`).

    Examples
    --------
    >>> f = step_signal(7, position=3.0, width=1.0, low=0.0, high=1.0)
    >>> float(f[3]), bool(f[0] < 0.01 and f[6] > 0.99)
    (0.5, True)
    """
    n = check_size(n, "n", maximum=MAX_SIGNAL)
    position = check_real(position, "position")
    width = check_real(width, "width", nonnegative=True)
    low = check_real(low, "low")
    high = check_real(high, "high")
    x = np.arange(n, dtype=np.float64)
    if width == 0.0:
        return np.where(x >= position, high, low)
    z = (x - position) / (width * math.sqrt(2.0))
    erf = np.vectorize(math.erf, otypes=[np.float64])
    return low + (high - low) * 0.5 * (1.0 + erf(z))
