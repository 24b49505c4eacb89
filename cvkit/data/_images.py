"""Images and data sets for the notebooks: made by code or shipped with installed packages.

Every loader returns float64 arrays in [0, 1] (grayscale ``(H, W)`` or RGB ``(H, W, 3)``);
nothing is downloaded. Standard images wrap the ones bundled with scikit-image, an optional
extra: without it they raise ``ImportError`` saying ``pip install "cvkit[data]"``.

>>> camera().shape
(512, 512)
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_image, as_rng, check_allocation, check_int, check_real
from ._common import image_shape, skimage_data

__all__ = [
    "camera", "astronaut", "coins", "moon", "text", "brick", "coffee", "chelsea", "image",
    "resize_half", "noisy_stack", "with_gaussian_noise", "with_impulse_noise", "step_edge",
    "psnr",
]

_NAMES = ("camera", "astronaut", "coins", "moon", "text", "brick", "coffee", "chelsea", "grass", "gravel")


def image(name: str) -> np.ndarray:
    """One of scikit-image's bundled images by name, as float64 in [0, 1]."""
    if not isinstance(name, str) or name not in _NAMES:
        raise ValueError(f"name must be one of {', '.join(_NAMES)}, got {name!r}")
    return _bundled_pixels(name).astype(np.float64) / 255.0


def _bundled_pixels(name: str) -> np.ndarray:
    """The uint8 pixels of the bundled image ``name``: its PNG file in scikit-image's data
    folder read with Pillow (scikit-image's own loader goes through ``skimage.io``, whose first
    import costs about 0.3 s in every notebook that shows a picture), or scikit-image's loader
    where the file is not there or not plain grey or RGB."""
    module = skimage_data()
    try:
        from PIL import Image

        with Image.open(Path(str(module.__file__)).parent / f"{name}.png") as picture:
            if picture.mode in ("L", "RGB"):
                return np.asarray(picture)
    except (ImportError, OSError):
        pass
    return getattr(module, name)()


def _bundled(name: str, description: str) -> Callable[[], np.ndarray]:
    """A loader ``name()`` of the bundled image ``name`` (see :func:`image`)."""

    def load() -> np.ndarray:
        return image(name)

    load.__name__ = load.__qualname__ = name
    load.__doc__ = description
    return load


camera = _bundled("camera", "The 512×512 grayscale 'cameraman' image.")
astronaut = _bundled("astronaut", "A 512×512 RGB portrait (Eileen Collins).")
coins = _bundled("coins", "303×384 grayscale coins on a textured background.")
moon = _bundled("moon", "512×512 grayscale lunar surface.")
text = _bundled("text", "172×448 grayscale handwritten text.")
brick = _bundled("brick", "512×512 grayscale brick wall texture.")
coffee = _bundled("coffee", "400×600 RGB cup of coffee.")
chelsea = _bundled("chelsea", "300×451 RGB cat.")


def resize_half(img: ArrayLike) -> np.ndarray:
    """Halve both sides by averaging 2×2 blocks (odd last rows/columns are dropped); ``img``
    must be at least 2×2."""
    arr = as_image(img, "img")
    if arr.shape[0] < 2 or arr.shape[1] < 2:
        raise ValueError(f"img must be at least 2×2 to be halved, got shape {arr.shape}")
    h, w = arr.shape[0] // 2 * 2, arr.shape[1] // 2 * 2
    arr = arr[:h, :w]
    return 0.25 * (arr[0::2, 0::2] + arr[1::2, 0::2] + arr[0::2, 1::2] + arr[1::2, 1::2])


def with_gaussian_noise(img: ArrayLike, sigma: float, rng: np.random.Generator | int | None = None) -> np.ndarray:
    """``img`` plus N(0, σ²) noise (not clipped)."""
    arr = as_image(img, "img")
    sigma = check_real(sigma, "sigma", nonnegative=True)
    return arr + as_rng(rng).normal(0.0, sigma, size=arr.shape)


def with_impulse_noise(img: ArrayLike, amount: float, rng: np.random.Generator | int | None = None) -> np.ndarray:
    """``img`` with a fraction ``amount`` of its pixels set to 0 or 1."""
    arr = as_image(img, "img").copy()
    amount = check_real(amount, "amount", nonnegative=True)
    if amount > 1:
        raise ValueError(f"amount must be in [0, 1], got {amount}")
    gen = as_rng(rng)
    flat = arr.reshape(arr.shape[0] * arr.shape[1], -1)
    chosen = gen.choice(flat.shape[0], size=int(round(amount * flat.shape[0])), replace=False)
    flat[chosen] = (gen.random(chosen.size) < 0.5)[:, None].astype(np.float64)
    return arr


def noisy_stack(img: ArrayLike, frames: int, sigma: float, rng: np.random.Generator | int | None = None) -> np.ndarray:
    """``frames`` noisy shots of the same scene, ``(T, H, W[, 3])``: I_t = I + n_t (§3.1).

    ``frames`` >= 1; the stack may take at most 2 GiB (``ValueError`` naming ``frames``).
    """
    arr = as_image(img, "img")
    frames = check_int(frames, "frames", minimum=1)
    check_allocation((frames,) + arr.shape, "frames", what="a stack of frames")
    sigma = check_real(sigma, "sigma", nonnegative=True)
    return arr[None] + as_rng(rng).normal(0.0, sigma, size=(frames,) + arr.shape)


def step_edge(shape: tuple[int, int] = (64, 64), low: float = 0.2, high: float = 0.8,
              angle: float = 0.0) -> np.ndarray:
    """A synthetic step edge through the centre, normal at ``angle`` radians from the x axis.

    ``shape`` is a pair of integers >= 1 whose image fits in 2 GiB; ``low``, ``high`` (the
    levels on either side) and ``angle`` are finite reals.
    """
    rows, cols = image_shape(shape)
    low = check_real(low, "low")
    high = check_real(high, "high")
    angle = check_real(angle, "angle")
    y, x = np.mgrid[0:rows, 0:cols].astype(np.float64)
    s = (x - (cols - 1) / 2) * np.cos(angle) + (y - (rows - 1) / 2) * np.sin(angle)
    return np.where(s >= 0, high, low)


def psnr(reference: ArrayLike, test: ArrayLike, data_range: float = 1.0) -> float:
    """Peak signal-to-noise ratio in dB: 10·log10(range² / MSE).

    ``data_range`` is the span of the values (1 for [0, 1] images, 255 for 0..255), > 0.
    Identical images give ``inf``.
    """
    ref = as_image(reference, "reference")
    out = as_image(test, "test")
    if ref.shape != out.shape:
        raise ValueError(f"reference and test must have the same shape, got {ref.shape} and {out.shape}")
    data_range = check_real(data_range, "data_range", positive=True)
    mse = float(np.mean((ref - out) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(data_range ** 2 / mse)

