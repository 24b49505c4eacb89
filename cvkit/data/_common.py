"""Argument checks and the supersampling grid shared by the data makers (no public names).

Images made by code are bounded like every cvkit array: the image, and the grid of
``supersample²`` samples per pixel that anti-aliases it, may each take at most 2 GiB, and the
shapes drawn over the grid at most 2**36 operations (:data:`cvkit._validation.MAX_WORK`).
"""
from __future__ import annotations

from types import ModuleType
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike

from .._validation import check_allocation, check_int, check_real, check_work

__all__: list[str] = []

#: ``inside(x, y)``: which sample points ``x (1, n)``, ``y (m, 1)`` lie inside a shape
Inside = Callable[[np.ndarray, np.ndarray], np.ndarray]


def skimage_data() -> ModuleType:
    """``skimage.data``, or an ``ImportError`` that says which extra installs it."""
    try:
        import skimage.data
    except ImportError as exc:
        raise ImportError(
            'cvkit.data loads its sample images from scikit-image, which is not installed: '
            'pip install "cvkit[data]"') from exc
    return skimage.data


def image_shape(shape: object, name: str = "shape") -> tuple[int, int]:
    """``(rows, cols)``: a pair of integers >= 1 whose float64 image fits in 2 GiB."""
    if not isinstance(shape, (tuple, list, np.ndarray)) or len(shape) != 2:
        raise ValueError(f"{name} must be a pair (rows, cols) of integers, got {shape!r}")
    rows = check_int(shape[0], f"{name}[0] (rows)", minimum=1)
    cols = check_int(shape[1], f"{name}[1] (cols)", minimum=1)
    check_allocation((rows, cols), name, what="an image")
    return rows, cols


def centre_point(centre: object, rows: int, cols: int) -> tuple[float, float]:
    """``(x, y)`` of ``centre`` (finite reals), the middle of the image for ``None``."""
    if centre is None:
        return (cols - 1) / 2.0, (rows - 1) / 2.0
    if not isinstance(centre, (tuple, list, np.ndarray)) or len(centre) != 2:
        raise ValueError(f"centre must be a pair (x, y) or None, got {centre!r}")
    return check_real(centre[0], "centre[0] (x)"), check_real(centre[1], "centre[1] (y)")


def grid_side(rows: int, cols: int, supersample: int) -> int:
    """``supersample`` (an int >= 1), refused if the ``(rows·s, cols·s)`` grid of samples
    would take more than 2 GiB."""
    s = check_int(supersample, "supersample", minimum=1)
    check_allocation((rows * s, cols * s), "supersample", what="a grid of samples")
    return s


def samples(rows: int, cols: int, supersample: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample points ``x (1, cols·s)`` and ``y (rows·s, 1)``: ``s × s`` per pixel, centred in
    their sub-squares (``supersample`` checked by :func:`grid_side`)."""
    s = grid_side(rows, cols, supersample)
    offsets = (np.arange(s) + 0.5) / s - 0.5
    y = (np.arange(rows)[:, None] + offsets[None, :]).reshape(-1)
    x = (np.arange(cols)[:, None] + offsets[None, :]).reshape(-1)
    return x[None, :], y[:, None]


def coverage(rows: int, cols: int, inside: Inside, supersample: int) -> np.ndarray:
    """Fraction of each pixel for which ``inside(x, y)`` holds, on an s × s grid of samples."""
    x, y = samples(rows, cols, supersample)
    s = x.shape[1] // cols
    hit = inside(x, y)  # (rows·s, cols·s) bool
    return hit.reshape(rows, s, cols, s).mean(axis=(1, 3))


def check_drawing(rows: int, cols: int, supersample: int, pieces: int, name: str, what: str) -> None:
    """Refuse (naming ``name``) drawing ``pieces`` polygon edges or segments, about ten
    operations each per sample, when that exceeds 2**36 operations (after the grid's own
    check, :func:`grid_side`)."""
    s = grid_side(rows, cols, supersample)
    check_work(10 * pieces * rows * s * cols * s, name, what=f"{what} on a {rows}×{cols} grid of {s}×{s} samples")


def as_points(values: ArrayLike, name: str, width: int) -> np.ndarray:
    """``values`` as a finite float64 ``(N, width)`` array (any array whose size is a multiple
    of ``width``, read row by row)."""
    if isinstance(values, (str, bytes)) or values is None:
        raise TypeError(f"{name} must be numeric rows of {width} values, got {type(values).__name__}")
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be numeric rows of {width} values, got {values!r}") from None
    if array.size % width:
        raise ValueError(f"{name} must hold rows of {width} values, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must contain only finite values (found NaN or inf)")
    return array.reshape(-1, width)
