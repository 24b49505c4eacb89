"""Corner detectors (§5.6–5.7): Moravec's cornerness, the structure tensor, Harris' response and
the peaks (thresholded local maxima) that turn a response map into points.

Everything is vectorised: the Moravec SSDs are eight shifted squared differences summed over the
window separably; the structure tensor smooths the three products of the Sobel derivatives with
the registry's Gaussian; peaks compare each pixel with a separable running maximum.
"""
from __future__ import annotations

from typing import cast

import numpy as np
from numpy.typing import ArrayLike

from .._docstrings import IMAGE_BORDER, filler
from .._validation import Border, as_float_array, check_border, check_padded, check_work
from ..registry import algorithm, implementation
from ._common import box_sum, check_int, check_real, gray, window_max

__all__ = ["moravec", "structure_tensor", "harris", "peaks"]

_docs = filler(IMAGE_BORDER)

#: the eight unit shifts (dy, dx) of Moravec's detector
SHIFTS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


# --------------------------------------------------------------------------------------------
# §5.6 Moravec
# --------------------------------------------------------------------------------------------
@algorithm("features.moravec", section="5.6", check="cvkit.features.checks:moravec")
@_docs
def moravec(image: ArrayLike, window: int = 7, border: Border = "reflect101") -> np.ndarray:
    """Moravec's cornerness: the smallest SSD between the window at p and its 8 shifted copies.

    Parameters
    ----------
    image : (H, W) array_like
        Grayscale image, any real dtype, finite values (not rescaled).
    window : int
        Side of the square window, odd, ≥ 3 (the notes use 7×7). Bounded by the work it
        causes: the image padded by ``window // 2 + 1`` may take at most 2 GiB and the 8
        shifted window sums, about ``8·(2·window + 3)`` operations per padded pixel, at most
        ``cvkit._validation.MAX_WORK`` (``ValueError`` naming ``window`` otherwise).
    %(border)s

    Returns
    -------
    (H, W) float64 ndarray
        :math:`C(p) = \\min_{s} \\sum_{o} \\big(I(p + s + o) - I(p + o)\\big)^2` over the 8 unit
        shifts ``s`` and the window offsets ``|o_x|, |o_y| ≤ window // 2``.

    Notes
    -----
    §5.6. The window compares *pixel by pixel* (a sum of squared differences, not the
    difference of two window sums). A flat region gives C ≈ 0, an edge too (the shift along
    the edge changes nothing), a corner a large C. The image is padded once by
    ``window // 2 + 1`` pixels (``implementation("filters.pad")``), enough for the shifted
    windows of the border pixels; then each shift's squared differences are summed over the
    window separably.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.zeros((9, 9)); img[4:, 4:] = 1.0          # a corner at (4, 4)
    >>> c = moravec(img, window=3)
    >>> float(c[4, 4]), float(c[6, 4]), float(c[2, 2])   # corner, edge, flat
    (2.0, 0.0, 0.0)
    """
    img = gray(image)
    window = check_int(window, "window", minimum=3, odd=True)
    check_border(border)
    r = window // 2
    grown = check_padded(img.shape, r + 1, "window")
    check_work(8 * (2 * window + 3) * grown[0] * grown[1], "window",
               what=f"Moravec's {window}×{window} window sums on a {img.shape[0]}×{img.shape[1]} image")
    padded = np.asarray(implementation("filters.pad")(img, r + 1, border=border), dtype=np.float64)
    h, w = img.shape
    # the window pixels of every output pixel, one pixel more for the shift
    centre = padded[1: h + 2 * r + 1, 1: w + 2 * r + 1]
    best: np.ndarray | None = None
    for dy, dx in SHIFTS:
        shifted = padded[1 + dy: h + 2 * r + 1 + dy, 1 + dx: w + 2 * r + 1 + dx]
        ssd = box_sum((shifted - centre) ** 2, window)
        best = ssd if best is None else np.minimum(best, ssd, out=best)
    return cast(np.ndarray, best)          # 8 shifts: never None


# --------------------------------------------------------------------------------------------
# §5.7 structure tensor and Harris
# --------------------------------------------------------------------------------------------
@algorithm("features.structure_tensor", section="5.7", check="cvkit.features.checks:structure_tensor")
def structure_tensor(image: ArrayLike, sigma: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The second-moment matrix M of every pixel: Gaussian-weighted products of the derivatives.

    Parameters
    ----------
    image : (H, W) array_like
        Grayscale image, any real dtype, finite values.
    sigma : float
        Standard deviation of the Gaussian window w(x, y), > 0.

    Returns
    -------
    (mxx, mxy, myy) : tuple of three (H, W) float64 ndarrays
        The entries of :math:`M = \\sum w \\begin{bmatrix} I_x^2 & I_x I_y \\\\ I_x I_y & I_y^2 \\end{bmatrix}`.

    Notes
    -----
    §5.7. ``(Ix, Iy) = edges.sobel(image)`` (OpenCV's scale: a unit step gives 4) and the
    window is ``filters.gaussian(·, sigma)``, a normalised kernel of radius ceil(3σ), both with
    the default ``reflect101`` border and both looked up in the registry. The eigenvalues of M
    say flat (both small), edge (one large) or corner (both large).
    ``skimage.feature.structure_tensor`` computes the same three maps with other derivative
    filters and borders.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.zeros((9, 9)); img[:, 5:] = 1.0        # a vertical edge: only Ix
    >>> mxx, mxy, myy = structure_tensor(img)
    >>> bool(mxx[4, 4] > 0), float(abs(mxy).max()), float(abs(myy).max())
    (True, 0.0, 0.0)
    """
    img = gray(image)
    sigma = check_real(sigma, "sigma", positive=True)
    ix, iy = implementation("edges.sobel")(img)
    ix = np.asarray(ix, dtype=np.float64)
    iy = np.asarray(iy, dtype=np.float64)
    smooth = implementation("filters.gaussian")
    mxx = np.asarray(smooth(ix * ix, sigma), dtype=np.float64)
    mxy = np.asarray(smooth(ix * iy, sigma), dtype=np.float64)
    myy = np.asarray(smooth(iy * iy, sigma), dtype=np.float64)
    return mxx, mxy, myy


@algorithm("features.harris", section="5.7", check="cvkit.features.checks:harris")
def harris(image: ArrayLike, k: float = 0.04, sigma: float = 1.0) -> np.ndarray:
    """Harris' corner response R = det(M) − k·trace(M)².

    Parameters
    ----------
    image : (H, W) array_like
        Grayscale image, any real dtype, finite values (not rescaled: R scales with the
        fourth power of the intensities).
    k : float
        The Harris constant, typically 0.04–0.06.
    sigma : float
        Standard deviation of the Gaussian window of the structure tensor, > 0.

    Returns
    -------
    (H, W) float64 ndarray
        Positive at corners, negative along edges, near 0 in flat regions.

    Notes
    -----
    §5.7. With λ1, λ2 the eigenvalues of M, det M = λ1λ2 and trace M = λ1 + λ2, so R needs no
    eigen-decomposition. M comes from ``implementation("features.structure_tensor")``. Agrees
    with ``skimage.feature.corner_harris(image, method="k", k=k, sigma=sigma)`` up to the
    derivative filter and border (the positions of the strongest corners coincide).

    Examples
    --------
    >>> import numpy as np
    >>> img = np.zeros((21, 21)); img[10:, 10:] = 1.0
    >>> r = harris(img)
    >>> int(np.argmax(r) // 21), int(np.argmax(r) % 21), bool(r[15, 10] < 0)
    (10, 10, True)
    """
    k = check_real(k, "k")
    sigma = check_real(sigma, "sigma", positive=True)
    img = gray(image)
    mxx, mxy, myy = (np.asarray(m, dtype=np.float64) for m in implementation("features.structure_tensor")(img, sigma))
    trace = mxx + myy
    return mxx * myy - mxy * mxy - k * trace * trace


# --------------------------------------------------------------------------------------------
# §5.6–5.7 thresholding and non-maximum suppression
# --------------------------------------------------------------------------------------------
@algorithm("features.peaks", section="5.7", check="cvkit.features.checks:peaks")
def peaks(response: ArrayLike, threshold: float, radius: int = 1) -> np.ndarray:
    """Points where a response map is above a threshold and the maximum of its neighbourhood.

    Parameters
    ----------
    response : (H, W) array_like
        Real, finite values (e.g. :func:`harris` or :func:`moravec`).
    threshold : float
        A peak must be strictly greater than this.
    radius : int
        Half-side of the square neighbourhood, ≥ 0 (1: the 3×3 window). A radius of
        ``max(H, W) − 1`` or more reaches the whole map from every pixel, and is computed as
        that one (same result, whatever the radius); the running maxima, about
        ``2(2r + 1)·H·W`` operations, may take at most ``cvkit._validation.MAX_WORK``
        (``ValueError`` naming ``radius`` otherwise).

    Returns
    -------
    (N, 2) float64 ndarray
        ``(x, y) = (col, row)`` of the peaks, strongest first; equal values in raster order
        (row by row). Shape ``(0, 2)`` when there is none.

    Notes
    -----
    §5.6–5.7 (thresholding, then non-maximum suppression). A pixel is a peak when its value is
    ``> threshold`` and ``≥`` every value of its ``(2r+1)²`` window; the window is clipped to the
    image, so border pixels can be peaks, and all pixels of a plateau are kept.
    ``skimage.feature.peak_local_max(response, min_distance=r, threshold_abs=threshold,
    exclude_border=False)`` uses the same window but keeps only one pixel of a plateau.

    Examples
    --------
    >>> import numpy as np
    >>> r = np.array([[0., 5., 0., 0.], [0., 0., 0., 7.], [3., 0., 0., 0.]])
    >>> peaks(r, 1.0)
    array([[3., 1.],
           [1., 0.],
           [0., 2.]])
    """
    values = as_float_array(response, "response", ndim=2)
    threshold = check_real(threshold, "threshold")
    radius = min(check_int(radius, "radius", minimum=0), max(values.shape) - 1)   # the whole map at most
    check_work(2 * (2 * radius + 1) * values.size, "radius",
               what=f"the {2 * radius + 1}×{2 * radius + 1} running maxima of a {values.shape[0]}×{values.shape[1]} map")
    keep = (values > threshold) & (values >= window_max(values, radius))
    rows, cols = np.nonzero(keep)  # raster order
    order = np.argsort(-values[rows, cols], kind="stable")
    return np.stack([cols[order], rows[order]], axis=1).astype(np.float64).reshape(-1, 2)
