"""Border handling (§3.7): extend an image beyond its edges before filtering."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import Border, as_image, check_allocation, check_border, check_int
from ..registry import algorithm


def border_indices(n: int, radius: int, border: str) -> np.ndarray:
    """Source index, in ``0..n-1``, of each of the ``n + 2*radius`` padded positions.

    For ``border="zero"`` positions outside the image get index ``-1``.
    """
    idx = np.arange(-radius, n + radius)
    if border == "replicate":
        return np.clip(idx, 0, n - 1)
    if border == "reflect":  # dcb|abcd|cba: period 2n
        m = np.mod(idx, 2 * n)
        return np.where(m < n, m, 2 * n - 1 - m)
    if border == "reflect101":  # dc|abcd|cb: period 2(n-1); a single pixel repeats
        if n == 1:
            return np.zeros_like(idx)
        m = np.mod(idx, 2 * (n - 1))
        return np.where(m < n, m, 2 * (n - 1) - m)
    # zero
    return np.where((idx >= 0) & (idx < n), idx, -1)


def _radii(radius: int | tuple[int, int] | list[int] | np.ndarray) -> tuple[int, int]:
    if isinstance(radius, (tuple, list, np.ndarray)):
        if len(radius) != 2:
            raise ValueError(f"radius must be an int or a pair (ry, rx), got {radius!r}")
        return (check_int(radius[0], "radius[0] (ry)", minimum=0), check_int(radius[1], "radius[1] (rx)", minimum=0))
    r = check_int(radius, "radius", minimum=0)
    return r, r


@algorithm("filters.pad", section="3.7", check="cvkit.filters.checks:pad")
def pad(image: ArrayLike, radius: int | tuple[int, int], border: Border = "reflect101") -> np.ndarray:
    """Pad an image by ``radius`` pixels on every side.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array
        Grayscale or colour image, any real dtype.
    radius : int or (int, int)
        Pixels added above/below and left/right; a pair is ``(ry, rx)``. Bounded by memory:
        the padded image may take at most 2 GiB (``ValueError`` naming ``radius`` otherwise).
    border : {"reflect101", "reflect", "replicate", "zero"}
        How values outside the image are made up (§3.7). Radii larger than the image repeat
        the rule (reflections bounce back and forth, as in ``numpy.pad``).

    Returns
    -------
    (H + 2*ry, W + 2*rx[, 3]) float64 array

    Examples
    --------
    >>> import numpy as np
    >>> pad(np.array([[1, 2, 3, 4]]), (0, 2), border="reflect101")
    array([[3., 2., 1., 2., 3., 4., 3., 2.]])
    """
    img = as_image(image)
    check_border(border)
    ry, rx = _radii(radius)
    h, w = img.shape[:2]
    shape = check_allocation((h + 2 * ry, w + 2 * rx) + img.shape[2:], "radius", what="a padded image")
    out = np.empty(shape)
    out[ry : ry + h, rx : rx + w] = img
    if border == "zero":
        out[:ry] = 0.0
        out[ry + h :] = 0.0
        out[:, :rx] = 0.0
        out[:, rx + w :] = 0.0
        return out
    rows = border_indices(h, ry, border)
    cols = border_indices(w, rx, border)
    # top and bottom strips of the central band, then whole columns (corners included)
    out[:ry, rx : rx + w] = img[rows[:ry]]
    out[ry + h :, rx : rx + w] = img[rows[ry + h :]]
    out[:, :rx] = out[:, rx + cols[:rx]]
    out[:, rx + w :] = out[:, rx + cols[rx + w :]]
    return out
