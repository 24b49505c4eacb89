"""Chapter 4 — edge detection (§4.1–4.12 of the notes).

First derivatives (finite differences, Prewitt, Sobel), the gradient magnitude in three norms
and its direction; non-maximum suppression, hysteresis and the Canny detector; second
derivatives (Laplacian, Laplacian of Gaussian, difference of Gaussians) and their zero
crossings; and the chapter's measured exercise, ``detect_outlines`` (Canny tuned to the noise
of a picture, graded by its F1 score against true outlines). Conventions (see ``docs/catalog.md``): images are indexed ``[row, col]``, x runs along
the columns and y *down* the rows, derivative kernels are correlated (not flipped), angles
are radians, and pixels outside the image are read through ``border`` (default
``"reflect101"``). Pipelines (``canny``, ``log``, ``dog``, and the derivative filters'
padding) call their building blocks through the registry, so ``with cvkit.use("student"):``
runs them on a student's own pieces.

>>> import numpy as np
>>> from cvkit import edges
>>> img = np.zeros((8, 8)); img[:, 4:] = 1.0
>>> gx, gy = edges.sobel(img)
>>> float(gx[3, 3]), float(gy.max())
(4.0, 0.0)
"""
from ._gradient import gradient, magnitude, direction, prewitt, sobel
from ._canny import non_max_suppression, hysteresis, canny
from ._laplacian import laplacian, log_kernel, log, zero_crossings, dog
from ._outlines import detect_outlines

__all__ = [
    "gradient",
    "magnitude",
    "direction",
    "prewitt",
    "sobel",
    "non_max_suppression",
    "hysteresis",
    "canny",
    "laplacian",
    "log_kernel",
    "log",
    "zero_crossings",
    "dog",
    "detect_outlines",
]
