"""Large correlations through NumPy's FFT, shared by the references that need one
(:func:`cvkit.filters.correlate` with a large kernel, :func:`cvkit.detection.match_template`
with a large template).

Why NumPy's and not ``scipy.fft``: both are PocketFFT, but ``numpy.fft`` comes with NumPy while
importing ``scipy.fft`` costs about 0.3 s of CPU (it loads ``scipy.special``) — paid by every
student's kernel and every grading process that ran one large correlation. The results are the
same bits: the forward transforms are identical, and the inverse is scaled as ``scipy.fft``
scales it (an unscaled transform, then times ``1/n``), which ``tests/library/test_fft.py``
checks against SciPy.
"""
from __future__ import annotations

import math

import numpy as np


def fft_pays(taps: int, out_shape: tuple[int, int], fft_shape: tuple[int, int]) -> bool:
    """Whether one FFT correlation over ``fft_shape`` beats ``taps`` whole-image multiply-adds
    producing ``out_shape`` (the measured crossover, NumPy 2.4: a tap costs ~1 ns per output
    pixel, the FFT route ~2.5 ns per transformed pixel and log2 level; below ~30 taps the
    direct loop always wins).

    >>> fft_pays(9, (11, 17), (13, 19)), fft_pays(81, (40, 52), (48, 60))
    (False, True)
    """
    n_out = out_shape[0] * out_shape[1]
    n_fft = fft_shape[0] * fft_shape[1]
    return taps > 30 and taps * n_out > 2.5 * n_fft * math.log2(max(n_fft, 2))


def fast_length(n: int) -> int:
    """The smallest 5-smooth number (``2**a * 3**b * 5**c``) that is at least ``n``: a length
    PocketFFT transforms quickly (what ``scipy.fft.next_fast_len(n, real=True)`` returns).

    >>> [fast_length(n) for n in (1, 7, 11, 97, 1000)]
    [1, 8, 12, 100, 1000]
    """
    n = int(n)
    if n < 1:
        raise ValueError(f"n must be a positive length, got {n}")
    best = None
    five = 1
    while True:
        three = five
        while True:
            candidate = three
            while candidate < n:
                candidate *= 2
            best = candidate if best is None else min(best, candidate)
            if three >= n:
                break
            three *= 3
        if five >= n:
            break
        five *= 5
    return best


def correlate_valid(image: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """``out[i, j] = sum_{m,n} kernel[m, n] * image[i + m, j + n]`` over the placements where
    the 2-D ``kernel`` lies inside ``image`` (float arrays; ``image`` (H, W) or (H, W, C), each
    channel alone), through the FFT: the linear convolution with the flipped kernel, at sizes
    where its circular wrap-around only reaches the rows and columns dropped. Agrees with direct
    summation to about ``1e-15 * max|image| * sum|kernel|``.

    >>> import numpy as np
    >>> correlate_valid(np.arange(5.0).reshape(1, 5), np.array([[1.0, 1.0]])).round(12)
    array([[1., 3., 5., 7.]])
    """
    kh, kw = kernel.shape
    rows, cols = image.shape[0] - kh + 1, image.shape[1] - kw + 1
    shape = (fast_length(image.shape[0]), fast_length(image.shape[1]))
    spectrum = np.fft.rfft2(image, shape, axes=(0, 1))
    kernel_spectrum = np.fft.rfft2(kernel[::-1, ::-1], shape)
    if image.ndim == 3:
        kernel_spectrum = kernel_spectrum[:, :, None]
    spectrum *= kernel_spectrum
    full = np.fft.irfft2(spectrum, shape, axes=(0, 1), norm="forward") * (1.0 / (shape[0] * shape[1]))
    return np.ascontiguousarray(full[kh - 1 : kh - 1 + rows, kw - 1 : kw - 1 + cols])
