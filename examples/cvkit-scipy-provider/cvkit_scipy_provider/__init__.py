"""A cvkit provider backed by scipy.ndimage (an example of writing one).

Each function keeps the catalog's signature and conventions (float64 output, ``border`` names,
inputs never modified), so that ``with cvkit.use("scipy"):`` can swap it into cvkit's own
pipelines. Algorithms it does not provide fall back to cvkit's reference.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

_MODES = {"zero": "constant", "replicate": "nearest", "reflect": "reflect", "reflect101": "mirror"}


def _per_channel(function, image, *args, **kwargs):
    image = np.asarray(image, dtype=np.float64)
    if image.ndim == 3:
        return np.stack([function(image[..., c], *args, **kwargs) for c in range(image.shape[2])], axis=-1)
    return function(image, *args, **kwargs)


def gaussian(image, sigma, border="reflect101"):
    """filters.gaussian through scipy.ndimage.gaussian_filter, with cvkit's kernel radius."""
    radius = max(0, math.ceil(3 * sigma - 1e-9))
    return _per_channel(ndimage.gaussian_filter, image, sigma, mode=_MODES[border], truncate=radius / sigma)


def median(image, size, border="reflect101"):
    """filters.median through scipy.ndimage.median_filter."""
    return _per_channel(ndimage.median_filter, image, size=size, mode=_MODES[border])


def correlate(image, kernel, border="reflect101", output="same"):
    """filters.correlate through scipy.ndimage.correlate ('same' output only)."""
    if output != "same":
        raise ValueError("this example provider only supports output='same'")
    kernel = np.asarray(kernel, dtype=np.float64)
    return _per_channel(ndimage.correlate, image, kernel, mode=_MODES[border])


def provides():
    """The entry point: algorithm id -> implementation."""
    return {"filters.gaussian": gaussian, "filters.median": median, "filters.correlate": correlate}
