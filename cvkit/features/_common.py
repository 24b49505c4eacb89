"""Argument checks and small array helpers shared by the feature modules."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_int, check_real

__all__ = ["gray", "check_int", "check_real", "box_sum", "window_max"]


def gray(value: ArrayLike, name: str = "image") -> np.ndarray:
    """A grayscale ``(H, W)`` image as float64 (feature detectors take 2-D images only)."""
    array = as_float_array(value, name, ndim=(2, 3))
    if array.ndim == 3:
        raise ValueError(
            f"{name} must be a grayscale (H, W) image, got shape {array.shape} "
            "(convert a colour image to grey first)"
        )
    return array


def box_sum(values: np.ndarray, size: int) -> np.ndarray:
    """Sums over every ``size × size`` window of a 2-D array ("valid" output).

    Separable: ``size`` shifted adds along the rows, then ``size`` along the columns. No
    cumulative sums, so the round-off does not grow with the image.
    """
    h, w = values.shape
    rows = values[:, : w - size + 1].copy()
    for j in range(1, size):
        rows += values[:, j: j + w - size + 1]
    out = rows[: h - size + 1].copy()
    for i in range(1, size):
        out += rows[i: i + h - size + 1]
    return out


def window_max(values: np.ndarray, radius: int) -> np.ndarray:
    """The maximum of the ``(2r+1)²`` window about every pixel, the window clipped to the array."""
    if radius == 0:
        return values.copy()
    h, w = values.shape
    padded = np.full((h, w + 2 * radius), -np.inf)
    padded[:, radius: radius + w] = values
    rows = padded[:, : w].copy()
    for j in range(1, 2 * radius + 1):
        np.maximum(rows, padded[:, j: j + w], out=rows)
    padded = np.full((h + 2 * radius, w), -np.inf)
    padded[radius: radius + h] = rows
    out = padded[:h].copy()
    for i in range(1, 2 * radius + 1):
        np.maximum(out, padded[i: i + h], out=out)
    return out
