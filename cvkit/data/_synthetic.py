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

from .._validation import check_int, check_real

__all__ = ["disk_image", "square_image", "oriented_step_image", "step_signal"]


def _shape(shape) -> tuple[int, int]:
    if not isinstance(shape, (tuple, list)) or len(shape) != 2:
        raise ValueError(f"shape must be a pair (rows, cols), got {shape!r}")
    return check_int(shape[0], "shape[0] (rows)", minimum=1), check_int(shape[1], "shape[1] (cols)", minimum=1)


def _centre(centre, rows: int, cols: int) -> tuple[float, float]:
    if centre is None:
        return (cols - 1) / 2.0, (rows - 1) / 2.0
    if not isinstance(centre, (tuple, list, np.ndarray)) or len(centre) != 2:
        raise ValueError(f"centre must be a pair (x, y) or None, got {centre!r}")
    return check_real(centre[0], "centre[0] (x)"), check_real(centre[1], "centre[1] (y)")


def _coverage(rows: int, cols: int, inside, supersample: int) -> np.ndarray:
    """Fraction of each pixel for which ``inside(x, y)`` holds, on an s × s grid of samples."""
    s = check_int(supersample, "supersample", minimum=1)
    offsets = (np.arange(s) + 0.5) / s - 0.5
    y = (np.arange(rows)[:, None] + offsets[None, :]).reshape(-1)
    x = (np.arange(cols)[:, None] + offsets[None, :]).reshape(-1)
    hit = inside(x[None, :], y[:, None])  # (rows·s, cols·s) bool
    return hit.reshape(rows, s, cols, s).mean(axis=(1, 3))


def _levels(coverage: np.ndarray, inside: float, outside: float) -> np.ndarray:
    inside = check_real(inside, "inside")
    outside = check_real(outside, "outside")
    return outside + (inside - outside) * coverage


def disk_image(shape=(64, 64), centre=None, radius=20.0, inside=1.0, outside=0.0, supersample=8):
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

    Returns
    -------
    (rows, cols) float64 ndarray

    Examples
    --------
    >>> img = disk_image((32, 40), centre=(20.3, 15.8), radius=9.5, inside=0.8, outside=0.2)
    >>> img.shape, round(float(img.max()), 3), round(float(img.min()), 3)
    ((32, 40), 0.8, 0.2)
    """
    rows, cols = _shape(shape)
    cx, cy = _centre(centre, rows, cols)
    radius = check_real(radius, "radius", positive=True)
    cover = _coverage(rows, cols, lambda x, y: (x - cx) ** 2 + (y - cy) ** 2 <= radius * radius, supersample)
    return _levels(cover, inside, outside)


def square_image(shape=(64, 64), centre=None, side=32.0, angle=0.0, inside=1.0, outside=0.0, supersample=8):
    """A filled square of side ``side`` rotated by ``angle`` radians, anti-aliased.

    Its four edges have the orientations ``angle + k·π/2``; its corners are where edge
    detectors break down.

    Examples
    --------
    >>> img = square_image((20, 20), side=10.0)
    >>> float(img[10, 10]), float(img[0, 0]), float(img.sum())
    (1.0, 0.0, 100.0)
    """
    rows, cols = _shape(shape)
    cx, cy = _centre(centre, rows, cols)
    side = check_real(side, "side", positive=True)
    angle = check_real(angle, "angle")
    c, s = math.cos(angle), math.sin(angle)
    half = side / 2.0

    def inside_square(x, y):
        u = (x - cx) * c + (y - cy) * s
        v = -(x - cx) * s + (y - cy) * c
        return (np.abs(u) <= half) & (np.abs(v) <= half)

    return _levels(_coverage(rows, cols, inside_square, supersample), inside, outside)


def oriented_step_image(shape=(64, 64), angle=0.0, offset=0.0, low=0.0, high=1.0, supersample=8):
    """A straight step edge whose normal points at ``angle`` radians, anti-aliased.

    The edge is the line ``(x − xc)·cos(angle) + (y − yc)·sin(angle) = offset`` through the
    image centre ``(xc, yc)`` shifted by ``offset`` pixels along the normal; intensity is
    ``high`` on the side the normal points to and ``low`` on the other. The gradient of the
    image therefore points at ``angle`` (y down).

    Examples
    --------
    >>> oriented_step_image((2, 6), angle=0.0, offset=0.25)[0]
    array([0.  , 0.  , 0.  , 0.75, 1.  , 1.  ])
    """
    rows, cols = _shape(shape)
    angle = check_real(angle, "angle")
    offset = check_real(offset, "offset")
    cx, cy = (cols - 1) / 2.0, (rows - 1) / 2.0
    c, s = math.cos(angle), math.sin(angle)
    cover = _coverage(rows, cols, lambda x, y: (x - cx) * c + (y - cy) * s >= offset, supersample)
    return _levels(cover, high, low)


def step_signal(n=101, position=50.3, width=3.0, low=0.2, high=0.8):
    """A 1-D blurred step: ``low + (high − low)·Φ((x − position)/width)`` at x = 0..n−1.

    Φ is the standard normal cumulative distribution, so the step is a perfect edge blurred by
    a Gaussian of standard deviation ``width`` (``width = 0`` gives a sharp step). Its first
    derivative peaks, and its second derivative crosses zero, exactly at ``position`` (the
    inflection point).

    Examples
    --------
    >>> f = step_signal(7, position=3.0, width=1.0, low=0.0, high=1.0)
    >>> float(f[3]), bool(f[0] < 0.01 and f[6] > 0.99)
    (0.5, True)
    """
    n = check_int(n, "n", minimum=1)
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
