"""Chapter 3's measured exercise: a denoiser graded by its PSNR on noise it has not seen.

The student's ``denoise(noisy, sigma)`` removes Gaussian noise of known standard deviation
``sigma`` from a grey image, with parameters of their choosing. It is graded on 128×128 crops
of the images shipped with cvkit (:data:`IMAGES`, colour ones converted to grey), the crop,
the noise level and the noise itself drawn per student (:func:`noisy_crop`). The measure is the
PSNR of the answer against the clean crop **minus** the PSNR the reference denoiser reaches on
the same noisy crop (:func:`psnr_gap`), put through the published scale :data:`PSNR_GAP_SCALE`
(in dB): what the image makes easy or hard cancels out, what the denoiser adds does not.

The reference (:func:`denoise`): non-local means (§3.13) with 5×5 patches, a 13×13 search
window and ``h = 1.1·sigma``, the best of the non-local means settings tried. Measured on the
crops of seeds 0–39 (``tests/library/test_checks_ch03.py`` re-measures 30): it gains 4.2 dB over the
noisy input on the worst crop, 8.8 dB on the median one, in about 0.02 s per crop. Against it,
on the median and the worst crop: non-local means with the notebook's 7×7/21×21 and h = σ
−0.6 and −1.1 dB, a bilateral filter (σs = 2, σr = 3σ) −1.6 and −4.3 dB, a Gaussian (σ = 1 px)
−2.0 and −6.1 dB, a 5×5 mean filter −3.9 and −7.2 dB; the top of the scale is −2 dB.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_image, as_rng, check_real
from ..registry import algorithm
from ._nonlinear import _nl_means

__all__ = ["denoise", "noisy_crop", "psnr", "psnr_gap", "denoise_unregistered", "PSNR_GAP_SCALE", "BUDGET_SECONDS", "IMAGES", "CROP",
           "SIGMA_RANGE"]

#: the published scale: (PSNR of the answer − PSNR of the reference, in dB; share of the points)
#: corners from worst to best, linear in between, flat outside
PSNR_GAP_SCALE: tuple[tuple[float, float], ...] = ((-6.0, 0.0), (-3.5, 0.5), (-2.0, 1.0))
#: seconds one call of ``denoise`` may take on the grader (its case time limit)
BUDGET_SECONDS = 10.0
#: the images of ``cvkit.data`` the crops come from (colour ones converted to grey)
IMAGES = ("camera", "coins", "astronaut", "coffee", "chelsea", "text", "brick")
#: the side of a crop, in pixels
CROP = 128
#: the range of the noise's standard deviation
SIGMA_RANGE = (0.06, 0.12)
#: a crop whose grey levels vary less than this (standard deviation) is drawn again: a nearly
#: flat crop rewards blurring whatever the denoiser
MIN_CONTRAST = 0.08


def _grey(name: str) -> np.ndarray:
    from .. import data

    image = getattr(data, name)()
    return image if image.ndim == 2 else image @ np.array([0.2125, 0.7154, 0.0721])


def noisy_crop(rng: np.random.Generator | int | None = None) -> tuple[np.ndarray, float, np.ndarray, str]:
    """One graded input: ``(noisy, sigma, clean, label)``.

    A :data:`CROP`-square crop of one of :data:`IMAGES` at a random place (drawn again until its
    standard deviation is at least :data:`MIN_CONTRAST`), ``sigma`` uniform in
    :data:`SIGMA_RANGE` (rounded to 3 decimals), ``noisy = clean + N(0, sigma²)`` (not
    clipped); ``label`` names the image and the crop's top-left corner.
    """
    generator = as_rng(rng)
    while True:
        name = IMAGES[int(generator.integers(len(IMAGES)))]
        image = _grey(name)
        top = int(generator.integers(0, image.shape[0] - CROP + 1))
        left = int(generator.integers(0, image.shape[1] - CROP + 1))
        clean = image[top:top + CROP, left:left + CROP]
        if clean.std() >= MIN_CONTRAST:
            break
    sigma = round(float(generator.uniform(*SIGMA_RANGE)), 3)
    noisy = clean + generator.normal(0.0, sigma, clean.shape)
    return noisy, sigma, clean, f"{name}, crop at row {top}, column {left}"


def psnr(clean: np.ndarray, image: np.ndarray) -> float:
    """PSNR in dB of ``image`` against ``clean``, for images in [0, 1] (peak 1)."""
    mse = float(np.mean((clean - image) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


def psnr_gap(output: ArrayLike, noisy: ArrayLike, sigma: float, clean: ArrayLike) -> float:
    """PSNR(clean, output) − PSNR(clean, reference denoiser's output on ``noisy``), in dB
    (images in [0, 1], so a peak of 1); −inf when ``output`` has another shape or non-finite
    values."""
    clean_arr = np.asarray(clean, dtype=np.float64)
    try:
        out = np.asarray(output, dtype=np.float64)
    except (TypeError, ValueError):
        return float("-inf")
    if out.shape != clean_arr.shape or not np.all(np.isfinite(out)):
        return float("-inf")
    reference = denoise_unregistered(np.asarray(noisy, dtype=np.float64), sigma)
    return psnr(clean_arr, out) - psnr(clean_arr, reference)


def denoise_unregistered(noisy: np.ndarray, sigma: float, *, h_factor: float = 1.1, patch_size: int = 5,
                         search_size: int = 13, summed: bool = False) -> np.ndarray:
    """The reference recipe with its settings as options (the check's mistakes change them):
    non-local means with ``h = h_factor·sigma``; ``summed`` compares patches by the sum of
    squared differences instead of the mean (as if h were ``patch_size`` times smaller)."""
    h = h_factor * sigma / (patch_size if summed else 1.0)
    return _nl_means(noisy, h, patch_size, search_size, "reflect101")


@algorithm("filters.denoise", section="3.14", check="cvkit.filters.checks:denoise")
def denoise(noisy: ArrayLike, sigma: float) -> np.ndarray:
    """Remove Gaussian noise of known standard deviation from a grey image (reference recipe).

    Parameters
    ----------
    noisy : (H, W) array_like
        A grey image in [0, 1] plus Gaussian noise (not clipped).
    sigma : float
        The noise's standard deviation, > 0.

    Returns
    -------
    (H, W) float64 ndarray
        The denoised image.

    Notes
    -----
    Non-local means with 5×5 patches, a 13×13 search window and ``h = 1.1·sigma`` (the
    course's patch distance is a mean over the patch, so two noisy copies of one patch are at
    about 2σ²). Graded like a student's answer, by its PSNR gap to itself it is at 0 dB, the top
    of :data:`PSNR_GAP_SCALE` being −2 dB.

    Examples
    --------
    >>> noisy, sigma, clean, _ = noisy_crop(0)
    >>> bool(psnr(clean, denoise(noisy, sigma)) > psnr(clean, noisy) + 5)
    True
    """
    image = as_image(noisy, "noisy", color=False)
    sigma = check_real(sigma, "sigma", positive=True)
    return denoise_unregistered(image, sigma)
