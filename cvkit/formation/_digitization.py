"""Digitization and sensor figures of merit (§2.11–2.15): quantization, memory, SNR, dynamic range."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_int, check_real
from ..registry import algorithm
from ._common import Values, as_values, scalar_or_array

__all__ = ["quantize", "image_memory_bits", "snr_db", "dynamic_range_db"]

#: 2**53 - 1 is the largest number of levels float64 still represents exactly
MAX_BITS = 53


@algorithm("formation.quantize", section="2.11", check="cvkit.formation.checks:quantize")
def quantize(image: ArrayLike, bits: int, vmax: float = 1.0) -> np.ndarray:
    """Quantize intensities to ``2**bits`` equally spaced levels between 0 and ``vmax``.

    Parameters
    ----------
    image : array_like
        Intensities of any shape (grayscale, colour, a 1-D ramp...) and any real dtype,
        finite values, in the units of ``vmax``.
    bits : int
        Bits per sample, 1 <= bits <= 53: there are :math:`L + 1 = 2^{bits}` levels.
    vmax : float
        The largest representable value (> 0): 1.0 for images in [0, 1], 255 for 0..255.

    Returns
    -------
    float64 ndarray, same shape as ``image``
        Each value replaced by its level :math:`k\\, v_{max} / L`, :math:`L = 2^{bits} - 1`,
        in the units of the input (not the integer code k).

    Raises
    ------
    ValueError
        Non-finite ``image``, ``bits`` outside 1..53, ``vmax`` not finite and > 0.
    TypeError
        ``bits`` not an integer, non-numeric ``image``.

    Notes
    -----
    §2.11. Values are first clipped to :math:`[0, v_{max}]` (what an analogue-to-digital
    converter does with under- and over-exposure), then

    .. math:: k = \\mathrm{round}\\!\\left(\\frac{x\\, L}{v_{max}}\\right), \\qquad
              Q(x) = \\frac{k\\, v_{max}}{L},

    with ``np.round`` (a value exactly half-way between two levels goes to the even k). Both
    0 and :math:`v_{max}` are levels, so the step is :math:`v_{max} / (2^{bits} - 1)` and the
    quantization error is at most half a step. bits = 8, vmax = 255 leaves integer images
    unchanged.

    Examples
    --------
    >>> quantize([0.0, 0.2, 0.5, 0.7, 1.3], bits=2)
    array([0.        , 0.33333333, 0.66666667, 0.66666667, 1.        ])
    >>> quantize([[10.4, 300.0, -3.0]], bits=8, vmax=255)
    array([[ 10., 255.,   0.]])
    """
    values = as_float_array(image, "image", allow_empty=True)
    bits = check_int(bits, "bits", minimum=1)
    if bits > MAX_BITS:
        raise ValueError(f"bits must be <= {MAX_BITS} (levels beyond 2**53 are not exact in float64), got {bits}")
    vmax = check_real(vmax, "vmax", positive=True)
    levels = float(2 ** bits - 1)
    clipped = np.clip(values, 0.0, vmax)
    with np.errstate(over="ignore"):
        scaled = clipped * levels
        # v·levels can overflow for vmax near the largest float: divide first there
        k = np.round(np.where(np.isfinite(scaled), scaled / vmax, clipped / vmax * levels))
        out = k * vmax / levels
        return np.where(np.isfinite(out), out, k / levels * vmax)


@algorithm("formation.image_memory_bits", section="2.11", check="cvkit.formation.checks:image_memory_bits")
def image_memory_bits(width: int, height: int, bits_per_pixel: int) -> int:
    """Memory needed by an uncompressed digital image, in bits.

    Parameters
    ----------
    width, height : int
        Image size N × M in pixels, >= 1.
    bits_per_pixel : int
        m, >= 1: 8 for a grayscale image with 256 grey levels, 24 for an RGB image with 8 bits
        per channel.

    Returns
    -------
    int
        :math:`B = N \\cdot M \\cdot m` (a Python int: exact for any size). Divide by 8 for
        bytes.

    Notes
    -----
    §2.11. The number of grey levels is :math:`2^m`, the memory grows only with m: doubling
    the levels costs one more bit per pixel, doubling the resolution four times the memory.

    Examples
    --------
    >>> image_memory_bits(640, 480, 8)
    2457600
    >>> image_memory_bits(1920, 1080, 24) // 8     # bytes of a full-HD RGB frame
    6220800
    """
    width = check_int(width, "width", minimum=1)
    height = check_int(height, "height", minimum=1)
    bits_per_pixel = check_int(bits_per_pixel, "bits_per_pixel", minimum=1)
    return width * height * bits_per_pixel


@algorithm("formation.snr_db", section="2.14", check="cvkit.formation.checks:snr_db")
def snr_db(frames: ArrayLike) -> np.ndarray:
    """Per-pixel signal-to-noise ratio, in decibels, of a stack of frames of a static scene.

    Parameters
    ----------
    frames : (T, H, W) or (T, H, W, 3) array_like
        T >= 2 shots of the same static scene, any real dtype, finite values.

    Returns
    -------
    (H, W) or (H, W, 3) float64 ndarray
        :math:`20 \\log_{10}(\\mu / \\sigma)` with :math:`\\mu` the mean and :math:`\\sigma`
        the standard deviation (``ddof=0``) of each pixel over the T frames; ``nan`` where
        :math:`\\mu \\le 0`, ``inf`` where :math:`\\mu > 0` and :math:`\\sigma = 0`.

    Raises
    ------
    ValueError
        Other shapes, T < 2, non-finite values.

    Notes
    -----
    §2.14. A pixel's value is a random variable: the mean over many frames estimates the
    signal, the standard deviation the noise. :math:`\\mu/\\sigma` is an amplitude ratio, hence
    the factor 20 (a power ratio :math:`\\mu^2/\\sigma^2` in dB is the same number with
    10·log10). In bits, :math:`\\log_2(\\mu/\\sigma) \\approx` dB / 6.02. :math:`\\sigma = 0` is
    taken exactly where all T values of a pixel are equal (so round-off in the standard
    deviation cannot turn a noise-free pixel into a finite SNR).

    Examples
    --------
    >>> snr_db([[[10.0, 5.0, 0.0]], [[10.0, 7.0, 0.0]]])
    array([[        inf, 15.56302501,         nan]])
    """
    stack = as_float_array(frames, "frames", ndim=(3, 4))
    if stack.ndim == 4 and stack.shape[3] != 3:
        raise ValueError(f"frames must be (T, H, W) or (T, H, W, 3), got shape {stack.shape}")
    if stack.shape[0] < 2:
        raise ValueError(f"frames must hold T >= 2 frames to estimate the noise, got T = {stack.shape[0]}")
    # mean/std does not change when every frame of a pixel is scaled by the same power of
    # two, which is exact: scaled to [−1, 1), the squares can neither overflow nor underflow
    _, exponent = np.frexp(np.abs(stack).max(axis=0))
    scaled = np.ldexp(stack, -exponent)
    mean = scaled.mean(axis=0)
    std = scaled.std(axis=0)
    std[np.all(stack == stack[0], axis=0)] = 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        snr = 20.0 * np.log10(mean / std)
    return np.where(mean > 0, snr, np.nan)


@algorithm("formation.dynamic_range_db", section="2.15", check="cvkit.formation.checks:dynamic_range_db")
def dynamic_range_db(e_max: ArrayLike, e_min: ArrayLike) -> Values:
    """Dynamic range of a sensor in decibels.

    Parameters
    ----------
    e_max : float or array_like
        Saturation level :math:`E_{max}` > 0 (the most light the sensor can measure).
    e_min : float or array_like
        Smallest detectable level :math:`E_{min}` > 0 (just above the noise floor), in the
        same unit; broadcasts with ``e_max``.

    Returns
    -------
    float64 ndarray of the broadcast shape (a NumPy float for scalars)
        :math:`20 \\log_{10}(E_{max} / E_{min})`.

    Notes
    -----
    §2.15: :math:`DR = E_{max}/E_{min}`, an amplitude ratio, expressed in dB as
    :math:`20\\log_{10} DR` or in bits as :math:`\\log_2 DR`; one bit is
    :math:`20 \\log_{10} 2 \\approx 6.02` dB.

    Examples
    --------
    >>> float(dynamic_range_db(1000.0, 1.0))
    60.0
    >>> dynamic_range_db([255.0, 4095.0], 1.0).round(2)
    array([48.13, 72.25])
    """
    high = as_values(e_max, "e_max")
    low = as_values(e_min, "e_min")
    if np.any(high <= 0):
        raise ValueError("e_max must be > 0")
    if np.any(low <= 0):
        raise ValueError("e_min must be > 0")
    try:
        with np.errstate(over="ignore", under="ignore"):
            ratio = high / low
    except ValueError:
        raise ValueError(f"e_max and e_min must broadcast together, got shapes {high.shape} and {low.shape}") from None
    with np.errstate(over="ignore", under="ignore", divide="ignore"):
        decibels = 20.0 * np.log10(ratio)
        # a ratio beyond the float range (1e300 / 1e-300): the difference of the logarithms
        decibels = np.where(np.isfinite(ratio) & (ratio > 0), decibels, 20.0 * (np.log10(high) - np.log10(low)))
    return scalar_or_array(decibels)
