"""Exercise mycourse.gamma_correction: its reference implementation and its check.

Gamma correction maps an intensity I in [0, vmax] to vmax·(I / vmax)^γ: γ < 1 brightens the
dark tones, γ > 1 darkens them, and 0 and vmax stay where they are.
"""
from __future__ import annotations

import numpy as np

import cvkit
from cvkit.grading import Case, Check, close, mistake


def _public() -> list[Case]:
    """Two small images students see: a ramp in [0, 1] and a uint8 image in [0, 255]."""
    ramp = np.array([[0.0, 0.25], [0.5, 1.0]])
    dark = np.array([[0, 16, 64], [128, 192, 255]], dtype=np.uint8)
    return [Case((ramp, 2.0), {}, "ramp in [0, 1], gamma 2"),
            Case((dark, 0.5), {"vmax": 255.0}, "uint8 image in [0, 255], gamma 0.5")]


def _hidden(rng: np.random.Generator) -> list[Case]:
    """Random images and exponents on both sides of 1, in [0, 1] and in [0, 255]."""
    cases = []
    for i, gamma in enumerate((rng.uniform(0.3, 0.8), rng.uniform(1.5, 3.0))):
        shape = (int(rng.integers(3, 9)), int(rng.integers(3, 9)))
        cases.append(Case((rng.random(shape), gamma), {}, f"random image in [0, 1], gamma {gamma:.2f}"))
        image = rng.integers(0, 256, size=shape + (3,)).astype(np.uint8)
        cases.append(Case((image, gamma), {"vmax": 255.0}, f"colour uint8 image, gamma {gamma:.2f}"))
    return cases


@mistake("1/gamma instead of gamma",
         "The exponent is gamma itself: (I / vmax) ** gamma; 1 / gamma undoes the correction")
def _inverse_gamma(image, gamma, vmax=1.0):
    return vmax * (np.asarray(image, dtype=np.float64) / vmax) ** (1.0 / gamma)


@mistake("gamma applied as multiplication", "Gamma is an exponent, not a gain: raise I / vmax to the power gamma")
def _times_gamma(image, gamma, vmax=1.0):
    return np.asarray(image, dtype=np.float64) * gamma


@mistake("vmax ignored", "Divide by vmax before raising to the power gamma, and multiply by vmax after")
def _not_normalised(image, gamma, vmax=1.0):
    return np.asarray(image, dtype=np.float64) ** gamma


CHECK = Check(
    public=_public,
    hidden=_hidden,
    compare=close(rtol=1e-9, atol=1e-12),
    mistakes=[_inverse_gamma, _times_gamma, _not_normalised],
)


@cvkit.algorithm("mycourse.gamma_correction", section="2.12", check=CHECK)
def gamma_correction(image, gamma, vmax=1.0):
    """Gamma correction ``vmax · (image / vmax) ** gamma``, computed in float64.

    Parameters
    ----------
    image : array_like
        Grayscale ``(H, W)`` or colour ``(H, W, 3)`` image, any real dtype, values in
        ``[0, vmax]``. It is not modified.
    gamma : float
        The exponent, > 0 (< 1 brightens the dark tones, > 1 darkens them).
    vmax : float, optional
        The largest intensity (1 for images in [0, 1], 255 for uint8 images), > 0.

    Returns
    -------
    numpy.ndarray
        float64 array of the image's shape, values in ``[0, vmax]``.

    Raises
    ------
    TypeError
        When ``gamma`` or ``vmax`` is not a number, or ``image`` not real.
    ValueError
        When ``gamma`` or ``vmax`` is not positive and finite, or ``image`` has values outside
        ``[0, vmax]``.
    """
    for name, value in (("gamma", gamma), ("vmax", vmax)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise TypeError(f"{name} must be a number, got {type(value).__name__}")
        if not np.isfinite(value) or value <= 0:
            raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    image = np.asarray(image)
    if image.dtype.kind not in "biuf":
        raise TypeError(f"image must be an array of real numbers, got dtype {image.dtype}")
    image = image.astype(np.float64)
    if image.size and (image.min() < 0 or image.max() > vmax):
        raise ValueError(f"image values must lie in [0, vmax] = [0, {vmax:g}], got [{image.min():g}, {image.max():g}]")
    return vmax * (image / vmax) ** gamma
