"""Linear filters of Chapter 3: temporal and spatial means, correlation, convolution, Gaussian.

All functions take a grayscale ``(H, W)`` or colour ``(H, W, 3)`` image of any real dtype,
compute in float64 without rescaling, never modify their inputs, and filter colour images
channel by channel with the same kernel. Pixels are never visited one by one: each kernel tap
is one whole-image multiply-add (large kernels go through the FFT instead).
"""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from .._docstrings import IMAGE_BORDER, filler
from .._fft import correlate_valid as correlate_valid_fft
from .._fft import fft_pays
from .._validation import (Border, as_float_array, as_image, check_allocation, check_border, check_padded,
                           check_int, check_real, check_work)
from ..registry import algorithm, implementation

__all__ = ["temporal_mean", "correlate", "convolve", "mean_kernel", "mean", "gaussian_kernel", "gaussian"]

_docs = filler({
    **IMAGE_BORDER,
    "image_per_kernel": ("image : (H, W) or (H, W, 3) array_like\n"
                         "        Grayscale or colour image, any real dtype, finite values. Colour images are filtered\n"
                         "        channel by channel with the same kernel."),
    "filtered": "float64 ndarray\n        The filtered image (colour stays colour).",
})

_OUTPUTS = ("same", "valid")
# Rows per block in the tap loops: a block of the image and its scratch buffer stay in cache.
_BLOCK_ELEMENTS = 1 << 15


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _check_output(output: str) -> str:
    if not isinstance(output, str) or output not in _OUTPUTS:
        raise ValueError(f"output must be one of {', '.join(map(repr, _OUTPUTS))}, got {output!r}")
    return output


def _image_and_kernel(image: ArrayLike, kernel: ArrayLike, border: str, output: str) -> tuple[np.ndarray, np.ndarray]:
    """The checked arguments of :func:`correlate` and :func:`convolve`: the image and the
    kernel as float64 arrays (``border`` and ``output`` are checked by name)."""
    img = as_image(image)
    k = as_float_array(kernel, "kernel", ndim=2)
    check_border(border)
    _check_output(output)
    return img, k


def _block_rows(row_elements: int) -> int:
    return max(8, _BLOCK_ELEMENTS // max(1, row_elements))


def _padded(img: np.ndarray, before: tuple[int, int], after: tuple[int, int], border: str) -> np.ndarray:
    """``img`` padded by ``before = (top, left)`` and ``after = (bottom, right)`` pixels."""
    ry, rx = max(before[0], after[0]), max(before[1], after[1])
    padded = implementation("filters.pad")(img, (ry, rx), border=border)
    rows = slice(ry - before[0], padded.shape[0] - (ry - after[0]))
    cols = slice(rx - before[1], padded.shape[1] - (rx - after[1]))
    return padded[rows, cols]


def gaussian_radius(sigma: float) -> int:
    """The default half-width ``ceil(3σ − 1e-9)`` of :func:`gaussian_kernel` (the notes' k = 3σ).

    A σ so large that the radius would not fit in an int64 gives ``2**62``: any allocation
    check refuses it.
    """
    reach = 3.0 * sigma - 1e-9
    return max(0, int(math.ceil(reach))) if reach < 2.0**62 else 2**62


def _correlate_direct(padded: np.ndarray, kernel: np.ndarray, out_shape: tuple[int, int]) -> np.ndarray:
    """``O[i, j] = sum K[m, n] P[i + m, j + n]`` by a loop over the kernel's non-zero taps."""
    ho, wo = out_shape
    out = np.zeros((ho, wo) + padded.shape[2:])
    taps = [(m, n, kernel[m, n]) for m, n in zip(*np.nonzero(kernel))]
    if not taps:
        return out
    block = _block_rows(out[0].size)
    scratch = np.empty((min(block, ho),) + out.shape[1:])
    for start in range(0, ho, block):
        stop = min(start + block, ho)
        acc, tmp = out[start:stop], scratch[: stop - start]
        m, n, k = taps[0]
        np.multiply(padded[start + m : stop + m, n : n + wo], k, out=acc)
        for m, n, k in taps[1:]:
            np.multiply(padded[start + m : stop + m, n : n + wo], k, out=tmp)
            acc += tmp
    return out


def _correlate(img: np.ndarray, kernel: np.ndarray, anchor: tuple[int, int], border: str, output: str) -> np.ndarray:
    """Correlation with the kernel tap ``anchor`` placed on the output pixel."""
    kh, kw = kernel.shape
    h, w = img.shape[:2]
    if output == "same":
        check_allocation((h + kh - 1, w + kw - 1) + img.shape[2:], "kernel", what="a padded image")
    if output == "valid":
        if kh > h or kw > w:
            raise ValueError(
                f"kernel of shape {kernel.shape} is larger than the image ({h}, {w}); "
                f"output='valid' needs the kernel to fit inside the image"
            )
        padded = img
        out_shape = (h - kh + 1, w - kw + 1)
    else:
        padded = _padded(img, anchor, (kh - 1 - anchor[0], kw - 1 - anchor[1]), border)
        out_shape = (h, w)
    taps = int(np.count_nonzero(kernel))
    if fft_pays(taps, out_shape, padded.shape[:2]):
        return correlate_valid_fft(padded, kernel)
    return _correlate_direct(padded, kernel, out_shape)


def _filter_1d(padded: np.ndarray, weights: np.ndarray, axis: int, out: np.ndarray, tmp: np.ndarray) -> None:
    """``out = sum_k w[k] * padded[..., k : k + n, ...]`` along ``axis`` (0 or 1), in place.

    A symmetric kernel adds the mirrored taps first, halving the multiplies.
    """
    n = out.shape[axis]

    def tap(k: int) -> np.ndarray:
        return padded[k : k + n] if axis == 0 else padded[:, k : k + n]

    length = weights.size
    r = length // 2
    if length % 2 == 1 and np.array_equal(weights, weights[::-1]):
        np.multiply(tap(r), weights[r], out=out)
        for k in range(1, r + 1):
            if weights[r + k] == 0.0:
                continue
            np.add(tap(r - k), tap(r + k), out=tmp)
            tmp *= weights[r + k]
            out += tmp
    else:
        np.multiply(tap(0), weights[0], out=out)
        for k in range(1, length):
            np.multiply(tap(k), weights[k], out=tmp)
            out += tmp


# --------------------------------------------------------------------------------------------
# §3.1 temporal mean
# --------------------------------------------------------------------------------------------
@algorithm("filters.temporal_mean", section="3.1", check="cvkit.filters.checks:temporal_mean")
def temporal_mean(frames: ArrayLike) -> np.ndarray:
    """Average of T frames of the same static scene.

    Parameters
    ----------
    frames : (T, H, W) or (T, H, W, 3) array_like
        T >= 1 grayscale or colour frames, any real dtype, finite values.

    Returns
    -------
    (H, W) or (H, W, 3) float64 ndarray
        The per-pixel mean over the frames (no rescaling).

    Notes
    -----
    §3.1: with frames :math:`I_t(p) = I(p) + n_t(p)` and zero-mean noise,

    .. math:: O(p) = \\frac{1}{T} \\sum_{t=1}^{T} I_t(p) \\approx I(p),

    the noise variance drops by a factor T.

    Examples
    --------
    >>> import numpy as np
    >>> temporal_mean(np.array([[[0, 2]], [[4, 6]]]))
    array([[2., 4.]])
    """
    stack = as_float_array(frames, "frames", ndim=(3, 4))
    if stack.ndim == 4 and stack.shape[3] != 3:
        raise ValueError(f"frames must be (T, H, W) or (T, H, W, 3), got shape {stack.shape}")
    return stack.mean(axis=0)


# --------------------------------------------------------------------------------------------
# §3.6–3.7 correlation and convolution
# --------------------------------------------------------------------------------------------
@algorithm("filters.correlate", section="3.6", exercise="3.7", check="cvkit.filters.checks:correlate")
@_docs
def correlate(image: ArrayLike, kernel: ArrayLike, border: Border = "reflect101",
              output: Literal["same", "valid"] = "same") -> np.ndarray:
    """Correlate an image with a 2-D kernel (the kernel is *not* flipped).

    Parameters
    ----------
    %(image_per_kernel)s
    kernel : (kh, kw) array_like
        Finite real kernel of any size, odd or even. Its anchor (the tap placed on the
        output pixel) is ``(kh // 2, kw // 2)``. With ``output="same"`` the image padded by
        the kernel, ``(H + kh - 1, W + kw - 1)``, may take at most 2 GiB (``ValueError``
        naming ``kernel`` otherwise); this also bounds the time (at most one FFT of that size).
    border : {"reflect101", "reflect", "replicate", "zero"}
        How pixels outside the image are made up (§3.7, see :func:`cvkit.filters.pad`). Any
        kernel size works, also one larger than the image. Ignored for ``output="valid"``.
    output : {"same", "valid"}
        ``"same"`` returns an (H, W) image; ``"valid"`` (the notes' CROP) only the positions
        where the kernel lies entirely inside the image, shape (H - kh + 1, W - kw + 1).

    Returns
    -------
    %(filtered)s

    Raises
    ------
    ValueError
        Bad shapes or values (``image``, ``kernel``, ``border``, ``output``), or a kernel
        larger than the image with ``output="valid"``.
    TypeError
        Non-numeric or complex ``image``/``kernel``.

    Notes
    -----
    §3.6, discrete, with the anchor :math:`(a, b) = (k_h // 2, k_w // 2)`:

    .. math:: O(i, j) = \\sum_{m=0}^{k_h-1} \\sum_{n=0}^{k_w-1} K(m, n)\\, I(i + m - a, j + n - b)

    This is OpenCV's ``filter2D`` with its default anchor and
    ``scipy.ndimage.correlate(..., origin=0)``; with ``output="valid"`` it is
    ``scipy.signal.correlate2d(..., mode="valid")``. Correlation is not commutative, and it
    equals convolution only for kernels with :math:`K(m, n) = K(-m, -n)`.

    Small kernels are applied tap by tap (one whole-image multiply-add per non-zero tap,
    exact up to summation order). Kernels with more than 30 non-zero taps on images where it
    is measurably faster go through the FFT (NumPy's, :mod:`cvkit._fft`) instead; the result then agrees
    with direct summation to about 1e-15 · max|I| · Σ|K|.

    Examples
    --------
    >>> import numpy as np
    >>> correlate(np.array([[0, 0, 1, 0, 0]]), np.array([[1, 2, 3]]), border="zero")
    array([[0., 3., 2., 1., 0.]])
    >>> correlate(np.array([[0, 1, 2, 3]]), np.array([[1, 1]]), output="valid")
    array([[1., 3., 5.]])
    """
    img, k = _image_and_kernel(image, kernel, border, output)
    kh, kw = k.shape
    return _correlate(img, k, (kh // 2, kw // 2), border, output)


@algorithm("filters.convolve", section="3.7", check="cvkit.filters.checks:convolve")
@_docs
def convolve(image: ArrayLike, kernel: ArrayLike, border: Border = "reflect101",
             output: Literal["same", "valid"] = "same") -> np.ndarray:
    """Convolve an image with a 2-D kernel (correlation with the kernel flipped).

    Parameters
    ----------
    %(image_per_kernel)s
    kernel : (kh, kw) array_like
        Finite real kernel of any size, odd or even; its centre is ``(kh // 2, kw // 2)``.
        Bounded as for :func:`correlate`.
    border : {"reflect101", "reflect", "replicate", "zero"}
        How pixels outside the image are made up (§3.7). Ignored for ``output="valid"``.
    output : {"same", "valid"}
        ``"same"`` returns an (H, W) image; ``"valid"`` (CROP) only the positions where the
        flipped kernel lies entirely inside the image, shape (H - kh + 1, W - kw + 1).

    Returns
    -------
    %(filtered)s

    Raises
    ------
    ValueError, TypeError
        As for :func:`correlate`.

    Notes
    -----
    §3.4–3.7, with :math:`(a, b) = (k_h // 2, k_w // 2)`:

    .. math:: O(i, j) = \\sum_{m} \\sum_{n} K(m, n)\\, I(i - (m - a), j - (n - b))

    It is computed as a correlation with the flipped kernel ``K[::-1, ::-1]``, whose anchor
    moves to ``(kh - 1 - a, kw - 1 - b)`` (the same tap for odd sizes, one tap earlier for
    even sizes). This equals ``scipy.ndimage.convolve(..., origin=0)`` for odd and even
    kernels, and ``scipy.signal.convolve2d(..., mode="valid")`` for ``output="valid"``.
    Convolving an impulse returns the kernel (the impulse response, §3.4).

    Examples
    --------
    >>> import numpy as np
    >>> convolve(np.array([[0, 0, 1, 0, 0]]), np.array([[1, 2, 3]]), border="zero")
    array([[0., 1., 2., 3., 0.]])
    """
    img, k = _image_and_kernel(image, kernel, border, output)
    kh, kw = k.shape
    anchor = (kh - 1 - kh // 2, kw - 1 - kw // 2)
    return _correlate(img, np.ascontiguousarray(k[::-1, ::-1]), anchor, border, output)


# --------------------------------------------------------------------------------------------
# §3.8 mean filter
# --------------------------------------------------------------------------------------------
@algorithm("filters.mean_kernel", section="3.8", check="cvkit.filters.checks:mean_kernel")
def mean_kernel(size: int) -> np.ndarray:
    """The ``size`` x ``size`` box kernel: every tap equals ``1 / size**2``.

    Parameters
    ----------
    size : int
        Side of the square kernel, >= 1 (even sizes are allowed here); the kernel may take at
        most 2 GiB (``size`` <= 16384).

    Returns
    -------
    (size, size) float64 ndarray
        A constant kernel summing to 1.

    Notes
    -----
    §3.8: :math:`K(m, n) = 1 / |S|` with :math:`|S| = \\text{size}^2`, so that correlating
    with it averages the neighbourhood, :math:`O(p) = \\frac{1}{|S|}\\sum_{q \\in S} I(q)` (§3.2).

    Examples
    --------
    >>> mean_kernel(2)
    array([[0.25, 0.25],
           [0.25, 0.25]])
    """
    size = check_int(size, "size", minimum=1)
    shape = check_allocation((size, size), "size", what="a box kernel")
    return np.full(shape, 1.0 / (size * size))


@algorithm("filters.mean", section="3.8", check="cvkit.filters.checks:mean")
@_docs
def mean(image: ArrayLike, size: int, border: Border = "reflect101") -> np.ndarray:
    """Box (mean) filter: each pixel becomes the average of its ``size`` x ``size`` window.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Grayscale or colour image, any real dtype, finite values.
    size : int
        Odd window side, >= 1. The kernel and the image padded by ``size // 2`` may each take
        at most 2 GiB (``ValueError`` naming ``size`` otherwise).
    %(border)s

    Returns
    -------
    float64 ndarray, same shape as ``image``

    Notes
    -----
    §3.8: the correlation of the image with :func:`mean_kernel`,

    .. math:: O(i, j) = \\frac{1}{s^2} \\sum_{|m|, |n| \\le s // 2} I(i + m, j + n).

    Both building blocks are called through the registry
    (``implementation("filters.mean_kernel")`` and ``implementation("filters.correlate")``),
    so inside ``with cvkit.use("student"):`` the student's versions are used. Equals
    ``cv2.blur(image, (size, size))`` and ``scipy.ndimage.uniform_filter(image, size)``
    (per channel) with the corresponding border modes.

    Examples
    --------
    >>> import numpy as np
    >>> mean(np.array([[0, 0, 9, 0, 0]] * 3), 3, border="zero")
    array([[0., 2., 2., 2., 0.],
           [0., 3., 3., 3., 0.],
           [0., 2., 2., 2., 0.]])
    """
    img = as_image(image)
    size = check_int(size, "size", minimum=1, odd=True)
    check_border(border)
    check_allocation((size, size), "size", what="a box kernel")
    check_padded(img.shape, size // 2, "size")
    kernel = implementation("filters.mean_kernel")(size)
    return implementation("filters.correlate")(img, kernel, border=border)


# --------------------------------------------------------------------------------------------
# §3.9 Gaussian filter
# --------------------------------------------------------------------------------------------
@algorithm("filters.gaussian_kernel", section="3.9", check="cvkit.filters.checks:gaussian_kernel")
def gaussian_kernel(sigma: float, radius: int | None = None) -> np.ndarray:
    """Sampled, normalised 1-D Gaussian kernel.

    Parameters
    ----------
    sigma : float
        Standard deviation in pixels, > 0. A σ so small that ``2σ²`` underflows to 0
        (σ < about 1e-162) gives the exact limit, the unit impulse (1 at offset 0).
    radius : int, optional
        Half-width r >= 0 of the kernel. Default ``ceil(3 * sigma - 1e-9)``, the notes'
        k = 3σ (the tiny guard keeps e.g. 3 · 0.1 · 10 from rounding up a whole pixel).
        The kernel may take at most 2 GiB, r < 2**27 (``ValueError`` naming ``radius``, or
        ``sigma`` for the default radius).

    Returns
    -------
    (2r + 1,) float64 ndarray
        Weights for offsets ``-r .. r``, symmetric, summing to 1.

    Notes
    -----
    §3.9: :math:`G(x) \\propto e^{-x^2 / 2\\sigma^2}` sampled at integers
    :math:`x = -r, \\dots, r` and divided by its sum (so the constant
    :math:`1/\\sigma\\sqrt{2\\pi}` drops out). The 2-D Gaussian is the outer product
    ``np.outer(g, g)`` (§3.9.1). Equals ``cv2.getGaussianKernel(2 * r + 1, sigma)``.
    σ = 1 gives r = 3, σ = 0.5 gives r = 2, σ = 2 gives r = 6.

    Examples
    --------
    >>> g = gaussian_kernel(1.0)
    >>> g.shape, round(float(g.sum()), 12), bool(g[3] == g.max())
    ((7,), 1.0, True)
    >>> gaussian_kernel(0.5, radius=1).round(4)
    array([0.1065, 0.787 , 0.1065])
    """
    sigma = check_real(sigma, "sigma", positive=True)
    if radius is None:
        radius, name = gaussian_radius(sigma), "sigma"
    else:
        radius, name = check_int(radius, "radius", minimum=0), "radius"
    check_allocation((2 * radius + 1,), name, what="a Gaussian kernel")
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    spread = 2.0 * sigma * sigma
    if spread == 0.0:  # σ² underflows: exp(-x²/2σ²) is 1 at x = 0 and 0 elsewhere, exactly
        return (x == 0.0).astype(np.float64)
    with np.errstate(over="ignore"):  # x²/2σ² beyond float64 (a subnormal σ²): weight exp(-inf) = 0
        weights = np.exp(-(x * x) / spread)
    weights /= weights.sum()
    return weights


def _check_separable(shape: tuple[int, ...], radius: int, name: str) -> None:
    """Refuse (naming ``name``) a separable filter of half-width ``radius`` on an image of
    ``shape`` whose padded copy or whose two passes would exceed cvkit's bounds."""
    check_padded(shape, radius, name)
    h, w = shape[0], shape[1]
    channels = shape[2] if len(shape) > 2 else 1
    work = 3 * (radius + 1) * (2 * h + 2 * radius) * w * channels
    check_work(work, name, what=f"a separable filter of radius {radius} on a {h}×{w} image")


@algorithm("filters.gaussian", section="3.9.1", check="cvkit.filters.checks:gaussian")
@_docs
def gaussian(image: ArrayLike, sigma: float, border: Border = "reflect101") -> np.ndarray:
    """Gaussian smoothing, computed separably (rows, then columns).

    Parameters
    ----------
    %(image)s
    sigma : float
        Standard deviation in pixels, > 0. The kernel radius is that of
        :func:`gaussian_kernel`, ``ceil(3σ − 1e-9)``. Bounded: the image padded by r may
        take at most 2 GiB and the two passes, about ``3(r + 1)(2H + 2r)·W·C`` operations,
        at most 2**36 (about a minute); otherwise ``ValueError`` naming ``sigma``.
    %(border)s

    Returns
    -------
    float64 ndarray, same shape as ``image``

    Notes
    -----
    §3.9.1: :math:`G(x, y) = G(x)\\,G(y)`, so the 2-D correlation with ``np.outer(g, g)``
    is a 1-D pass along every row followed by a 1-D pass along every column:
    O(2k+1) instead of O((2k+1)²) operations per pixel. The image is padded once by r
    and both passes are "valid" 1-D filters (a symmetric kernel adds the two mirrored taps
    before multiplying). The padded copy has (H + 2r)(W + 2r) pixels, so a σ much larger
    than the image costs memory accordingly.

    The 1-D kernel comes from ``implementation("filters.gaussian_kernel")(sigma)``, so
    ``with cvkit.use("student"):`` runs this on the student's kernel (a 1-D array of odd
    length; a non-symmetric one is applied as a correlation, anchor at its centre).
    Equals ``scipy.ndimage.gaussian_filter(image, sigma, truncate=r / sigma)`` and
    ``cv2.GaussianBlur(image, (2r+1, 2r+1), sigma)`` with the corresponding border modes.

    Examples
    --------
    >>> import numpy as np
    >>> impulse = np.zeros((9, 9)); impulse[4, 4] = 1
    >>> out = gaussian(impulse, 1.0)
    >>> g = gaussian_kernel(1.0)
    >>> bool(np.allclose(out[1:8, 1:8], np.outer(g, g)))
    True
    """
    img = as_image(image)
    sigma = check_real(sigma, "sigma", positive=True)
    check_border(border)
    _check_separable(img.shape, gaussian_radius(sigma), "sigma")
    weights = implementation("filters.gaussian_kernel")(sigma)
    weights = as_float_array(weights, "the kernel returned by filters.gaussian_kernel", ndim=1)
    if weights.size % 2 == 0:
        raise ValueError(
            f"the kernel returned by filters.gaussian_kernel must have odd length 2r+1, "
            f"got length {weights.size}"
        )
    r = weights.size // 2
    _check_separable(img.shape, r, "the kernel returned by filters.gaussian_kernel")
    padded = implementation("filters.pad")(img, r, border=border)  # (H + 2r, W + 2r[, 3])
    h, w = img.shape[:2]
    out = np.empty(img.shape)
    # Blocks of output rows: the row pass of a block and the column pass over it run while the
    # block is still in cache. rows_buf holds the row-filtered padded rows start .. stop+2r;
    # its last 2r rows are carried over to the next block instead of being filtered again.
    block = min(h, _block_rows(padded[0].size))
    rows_buf = np.empty((block + 2 * r, w) + img.shape[2:])
    scratch = np.empty_like(rows_buf)
    done = 0  # row-filtered rows already at the top of rows_buf
    for start in range(0, h, block):
        stop = min(start + block, h)
        n = stop - start
        rows = rows_buf[: n + 2 * r]
        _filter_1d(padded[start + done : stop + 2 * r], weights, 1, rows[done:], scratch[: n + 2 * r - done])
        _filter_1d(rows, weights, 0, out[start:stop], scratch[:n])
        if 2 * r:
            rows_buf[: 2 * r] = rows[n : n + 2 * r]
        done = 2 * r
    return out
