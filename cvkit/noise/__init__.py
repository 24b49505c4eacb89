"""Noise models of Chapter 3: additive Gaussian noise (§3.1) and impulse noise (§3.10).

Both take a grayscale ``(H, W)`` or colour ``(H, W, 3)`` image of any real dtype, return a new
float64 image (never modifying the input, never rescaling or clipping) and draw from ``rng``:
a ``numpy.random.Generator``, an int seed or ``None``. The same seed gives the same output.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_image, as_rng, check_real
from ..registry import algorithm

__all__ = ["add_gaussian", "add_salt_and_pepper"]


@algorithm("noise.add_gaussian", section="3.1", check="cvkit.noise.checks:add_gaussian")
def add_gaussian(image: ArrayLike, sigma: float, rng: np.random.Generator | int | None = None) -> np.ndarray:
    """Add independent zero-mean Gaussian noise to every pixel (and channel).

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Grayscale or colour image, any real dtype, finite values.
    sigma : float
        Standard deviation of the noise, >= 0, in the units of ``image`` (e.g. 20 for a
        0..255 image, 0.08 for a 0..1 image). ``sigma=0`` returns an exact float64 copy.
    rng : numpy.random.Generator, int or None
        Source of randomness (an int is a seed; ``None`` draws fresh entropy).

    Returns
    -------
    float64 ndarray, same shape as ``image``
        ``image + noise``, not clipped to any range.

    Notes
    -----
    §3.1: :math:`I_t(p) = I(p) + n_t(p)` with :math:`n_t(p) \\sim \\mathcal{N}(0, \\sigma^2)`
    independent for every pixel. The noise is ``sigma * rng.standard_normal(image.shape)``.

    Examples
    --------
    >>> import numpy as np
    >>> noisy = add_gaussian(np.full((200, 200), 0.5), 0.1, rng=0)
    >>> noisy.dtype, round(float(noisy.mean()), 2), round(float(noisy.std()), 2)
    (dtype('float64'), 0.5, 0.1)
    >>> bool(np.array_equal(add_gaussian(noisy, 0.1, rng=7), add_gaussian(noisy, 0.1, rng=7)))
    True
    """
    img = as_image(image)
    sigma = check_real(sigma, "sigma", nonnegative=True)
    generator = as_rng(rng)
    noise = generator.standard_normal(img.shape)
    noise *= sigma
    noise += img
    return noise


@algorithm("noise.add_salt_and_pepper", section="3.10", check="cvkit.noise.checks:add_salt_and_pepper")
def add_salt_and_pepper(image: ArrayLike, amount: float, rng: np.random.Generator | int | None = None,
                        low: float = 0.0, high: float = 1.0) -> np.ndarray:
    """Impulse (salt-and-pepper) noise: replace a fraction of the pixels by ``low`` or ``high``.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Grayscale or colour image, any real dtype, finite values.
    amount : float
        Fraction of the pixels to replace, in [0, 1]. Exactly
        ``round(amount * H * W)`` pixels change (Python's ``round``: halves go to even).
    rng : numpy.random.Generator, int or None
        Source of randomness (an int is a seed; ``None`` draws fresh entropy).
    low, high : float
        The "pepper" and "salt" values (use 0 and 255 for a 0..255 image). Finite.

    Returns
    -------
    float64 ndarray, same shape as ``image``
        A copy of ``image`` in which the chosen pixels hold ``low`` or ``high``; all other
        pixels keep their values exactly.

    Notes
    -----
    §3.10: impulse noise turns random pixels black or white. The pixels are drawn without
    replacement (``rng.choice``), then each gets ``high`` or ``low`` with probability 1/2
    (an independent coin per pixel). In a colour image a *pixel* is replaced in all three
    channels, so the noise is black or white, not coloured.

    Examples
    --------
    >>> import numpy as np
    >>> noisy = add_salt_and_pepper(np.full((10, 10), 0.5), 0.2, rng=0)
    >>> int(np.sum(noisy != 0.5)), sorted(set(noisy[noisy != 0.5].tolist()))
    (20, [0.0, 1.0])
    """
    img = as_image(image)
    amount = check_real(amount, "amount")
    if not 0.0 <= amount <= 1.0:
        raise ValueError(f"amount must be in [0, 1] (a fraction of the pixels), got {amount}")
    low = check_real(low, "low")
    high = check_real(high, "high")
    generator = as_rng(rng)
    n_pixels = img.shape[0] * img.shape[1]
    count = min(n_pixels, int(round(amount * n_pixels)))
    chosen = generator.choice(n_pixels, size=count, replace=False)
    values = np.where(generator.random(count) < 0.5, high, low)
    out = np.array(img, dtype=np.float64, copy=True, order="C")
    flat = out.reshape(n_pixels, -1)  # a view: one row per pixel, one column per channel
    flat[chosen] = values[:, None]
    return out
