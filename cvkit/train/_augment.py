"""Data augmentation of Chapter 12 (§12.4): random resized crop (multi-scale training),
cutout, mixup and cutmix.

Every function draws from ``rng`` (a ``numpy.random.Generator``, an int seed or ``None``;
the same seed gives the same result), returns new float64 arrays and never modifies its
inputs. Images are ``(H, W)`` grayscale or ``(H, W, 3)`` colour; mixup and cutmix work on a
batch whose first axis is the sample.
"""
from __future__ import annotations

import numbers
from collections.abc import Sequence
from typing import cast

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, as_image, as_rng, check_allocation, check_int, check_real
from ..registry import algorithm

__all__ = ["random_resized_crop", "cutout", "mixup", "cutmix"]

#: candidate boxes drawn at once by random_resized_crop (torchvision tries 10, one by one)
_ATTEMPTS = 100


def _pair(value: Sequence[float], name: str, *, positive: bool = True) -> tuple[float, float]:
    """A pair ``(lo, hi)`` of finite reals with lo <= hi."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise TypeError(f"{name} must be a pair (low, high), got {value!r}")
    lo = check_real(value[0], f"{name}[0]", positive=positive)
    hi = check_real(value[1], f"{name}[1]", positive=positive)
    if lo > hi:
        raise ValueError(f"{name} must be (low, high) with low <= high, got {value!r}")
    return lo, hi


def _output_size(value: int | Sequence[int]) -> tuple[int, int]:
    if isinstance(value, (numbers.Integral, np.integer)) and not isinstance(value, (bool, np.bool_)):
        size = check_int(value, "output_size", minimum=1)
        return size, size
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise TypeError(f"output_size must be an int or a pair (height, width), got {value!r}")
    pair = cast(Sequence[int], value)
    return check_int(pair[0], "output_size[0]", minimum=1), check_int(pair[1], "output_size[1]", minimum=1)


# --------------------------------------------------------------------------------------------
# random resized crop: box sampling and bilinear resampling (shared with the teaching model)
# --------------------------------------------------------------------------------------------
def _crop_boxes(n: int, height: int, width: int, scale: tuple[float, float], ratio: tuple[float, float],
                generator: np.random.Generator,
                attempts: int = _ATTEMPTS) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``n`` crop boxes ``(top, left, h, w)`` (int arrays) of area fraction in ``scale`` and
    aspect ratio w/h in ``ratio`` (log-uniform), as torchvision's ``RandomResizedCrop`` draws
    them: for each box, the first of ``attempts`` candidates that fits in the image; if none
    fits, the central crop of the whole image clamped to the ratio range."""
    area = height * width
    fractions = generator.uniform(scale[0], scale[1], (n, attempts))
    log_ratio = generator.uniform(np.log(ratio[0]), np.log(ratio[1]), (n, attempts))
    aspect = np.exp(log_ratio)
    target = fractions * area
    # sides beyond the image never fit: clipped to one more pixel, extreme ratios cast cleanly
    with np.errstate(over="ignore"):
        ws = np.round(np.minimum(np.sqrt(target * aspect), width + 1)).astype(np.int64)
        hs = np.round(np.minimum(np.sqrt(target / aspect), height + 1)).astype(np.int64)
    fits = (ws >= 1) & (ws <= width) & (hs >= 1) & (hs <= height)
    first = np.argmax(fits, axis=1)
    rows = np.arange(n)
    h, w = hs[rows, first], ws[rows, first]
    found = fits[rows, first]
    if not found.all():  # torchvision's fallback: a central crop, as large as the ratio allows
        in_ratio = width / height
        if in_ratio < ratio[0]:
            fw, fh = width, int(round(width / ratio[0]))
        elif in_ratio > ratio[1]:
            fh, fw = height, int(round(height * ratio[1]))
        else:
            fw, fh = width, height
        h = np.where(found, h, max(1, min(fh, height)))
        w = np.where(found, w, max(1, min(fw, width)))
    top = generator.integers(0, height - h + 1)
    left = generator.integers(0, width - w + 1)
    top = np.where(found, top, (height - h) // 2)
    left = np.where(found, left, (width - w) // 2)
    return top, left, h, w


def _sample_positions(start: np.ndarray, length: np.ndarray,
                      out_length: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Source coordinates (N, out) of a half-pixel-centred resize of ``length`` pixels starting
    at ``start`` to ``out_length`` pixels, clamped to the crop: the two neighbours to blend and
    the weight of the second."""
    u = np.arange(out_length, dtype=np.float64)
    size = length.astype(np.float64)[:, None]
    src = (u[None, :] + 0.5) * (size / out_length) - 0.5
    src = np.clip(src, 0.0, size - 1.0)
    floor = np.floor(src)
    frac = src - floor
    lower = floor.astype(np.int64)
    upper = np.minimum(lower + 1, size.astype(np.int64) - 1)
    return start[:, None] + lower, start[:, None] + upper, frac


def _resample_boxes(images: np.ndarray, top: np.ndarray, left: np.ndarray, h: np.ndarray, w: np.ndarray,
                    out_h: int, out_w: int) -> np.ndarray:
    """Bilinear resize of box ``n`` of image ``n`` to ``(out_h, out_w)`` for a batch
    ``images`` (N, H, W[, C]): OpenCV's ``INTER_LINEAR`` (half-pixel centres, the crop's edge
    pixels repeated, no anti-aliasing)."""
    r0, r1, fr = _sample_positions(top, h, out_h)
    c0, c1, fc = _sample_positions(left, w, out_w)
    idx = np.arange(images.shape[0])[:, None, None]
    extra = (None,) * (images.ndim - 3)
    fr = fr[:, :, None][(...,) + extra]
    fc = fc[:, None, :][(...,) + extra]
    top_row = images[idx, r0[:, :, None], c0[:, None, :]] * (1.0 - fc) + images[idx, r0[:, :, None], c1[:, None, :]] * fc
    bottom_row = images[idx, r1[:, :, None], c0[:, None, :]] * (1.0 - fc) + images[idx, r1[:, :, None], c1[:, None, :]] * fc
    return top_row * (1.0 - fr) + bottom_row * fr


@algorithm("train.random_resized_crop", section="12.4", check="cvkit.train.checks:random_resized_crop")
def random_resized_crop(image: ArrayLike, output_size: int | Sequence[int],
                        scale: Sequence[float] = (0.08, 1.0), ratio: Sequence[float] = (3 / 4, 4 / 3),
                        rng: np.random.Generator | int | None = None) -> np.ndarray:
    r"""Random crop of random size and shape, resized to ``output_size`` (multi-scale training).

    The crop's area is a fraction s ~ U(scale) of the image's, its aspect ratio
    w/h = r with log r ~ U(log ratio), its size ``w = round(√(s·H·W·r))``,
    ``h = round(√(s·H·W/r))``, its position uniform among those inside the image; it is then
    resized bilinearly to ``output_size``.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Any real dtype; values are not rescaled.
    output_size : int or (int, int)
        ``(height, width)`` of the result (an int gives a square), each ≥ 1; the result must
        fit in 2 GiB (cvkit's limit for one array), else ``ValueError`` naming ``output_size``.
    scale : (float, float)
        Range of the area fraction, ``0 < low <= high <= 1``.
    ratio : (float, float)
        Range of the aspect ratio width/height, ``0 < low <= high``.
    rng : numpy.random.Generator, int or None
        Source of randomness.

    Returns
    -------
    float64 ndarray, shape ``output_size`` (+ ``(3,)`` for colour)

    Notes
    -----
    §12.4 (multi-scale training); the sampling of torchvision's ``RandomResizedCrop``: up to
    100 candidates ``(s, r)`` are drawn at once and the first whose rounded box fits inside the
    image is used (torchvision tries 10); if none fits (only for ranges the image cannot
    satisfy) the central crop of the whole image, clamped to the ratio range, is used. The
    resize is OpenCV's ``INTER_LINEAR`` (= PyTorch ``align_corners=False`` without
    anti-aliasing): output pixel u samples the crop at ``(u + 0.5)·h/out_h − 0.5``, clamped to
    the crop, blending the two nearest pixels on each axis.

    Examples
    --------
    >>> import numpy as np
    >>> image = np.arange(64 * 80, dtype=float).reshape(64, 80)
    >>> out = random_resized_crop(image, (16, 20), scale=(0.25, 0.5), rng=0)
    >>> out.shape, bool(out.min() >= 0 and out.max() <= image.max())
    ((16, 20), True)
    """
    img = as_image(image)
    out_h, out_w = _output_size(output_size)
    check_allocation((out_h, out_w) + img.shape[2:], "output_size", what="the resized crop")
    scales = _pair(scale, "scale")
    if scales[1] > 1.0:
        raise ValueError(f"scale must lie in (0, 1] (a fraction of the image's area), got {scales!r}")
    ratios = _pair(ratio, "ratio")
    generator = as_rng(rng)
    height, width = img.shape[:2]
    top, left, h, w = _crop_boxes(1, height, width, scales, ratios, generator)
    return _resample_boxes(img[None], top, left, h, w, out_h, out_w)[0]


# --------------------------------------------------------------------------------------------
# cutout
# --------------------------------------------------------------------------------------------
@algorithm("train.cutout", section="12.4", check="cvkit.train.checks:cutout")
def cutout(image: ArrayLike, size: int, rng: np.random.Generator | int | None = None) -> np.ndarray:
    r"""Cutout (random erasing): set one ``size × size`` square of the image to 0.

    The square's centre (cy, cx) is uniform over the pixels of the image; it covers rows
    ``cy − size//2 … cy − size//2 + size − 1`` (and the same for columns), clipped to the
    image, so a square near the border is only partly inside.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Any real dtype (a colour pixel is erased in all channels).
    size : int
        Side of the square, >= 1.
    rng : numpy.random.Generator, int or None
        Source of randomness: ``cy = rng.integers(0, H)``, then ``cx = rng.integers(0, W)``.

    Returns
    -------
    float64 ndarray, shape of ``image``
        A copy with the square set to 0.

    Notes
    -----
    §12.4; DeVries & Taylor (2017), "dropout in the input space". Because the centre may lie
    anywhere, squares are clipped near the border as often as the geometry implies (the
    authors found this better than keeping the square inside). For odd sizes the square is
    centred on (cy, cx); for even sizes (cy, cx) is the pixel just below and right of its
    centre.

    Examples
    --------
    >>> import numpy as np
    >>> out = cutout(np.ones((8, 8)), 4, rng=0)
    >>> int((out == 0).sum()) <= 16, out.dtype
    (True, dtype('float64'))
    """
    img = as_image(image)
    size = check_int(size, "size", minimum=1)
    generator = as_rng(rng)
    height, width = img.shape[:2]
    cy = int(generator.integers(0, height))
    cx = int(generator.integers(0, width))
    top, left = cy - size // 2, cx - size // 2
    out = np.array(img, dtype=np.float64, copy=True)
    out[max(0, top): max(0, top + size), max(0, left): max(0, left + size)] = 0.0
    return out


# --------------------------------------------------------------------------------------------
# mixup and cutmix
# --------------------------------------------------------------------------------------------
def _batch(x: ArrayLike, y_onehot: ArrayLike, min_ndim: int) -> tuple[np.ndarray, np.ndarray]:
    data = as_float_array(x, "x")
    if data.ndim < min_ndim:
        want = "(N, ..., H, W)" if min_ndim == 3 else "(N, ...)"
        raise ValueError(f"x must be a batch {want} with at least {min_ndim} dimensions, got shape {data.shape}")
    labels = as_float_array(y_onehot, "y_onehot", ndim=2)
    if labels.shape[0] != data.shape[0]:
        raise ValueError(f"y_onehot must have one row per sample of x ({data.shape[0]}), got shape {labels.shape}")
    return data, labels


@algorithm("train.mixup", section="12.4", check="cvkit.train.checks:mixup")
def mixup(x: ArrayLike, y_onehot: ArrayLike, alpha: float = 0.2,
          rng: np.random.Generator | int | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    r"""Mixup: blend every sample (and its label) with a partner from the same batch.

    .. math:: \tilde x_n = \lambda x_n + (1 - \lambda) x_{\pi(n)}, \qquad
              \tilde y_n = \lambda y_n + (1 - \lambda) y_{\pi(n)}

    with one :math:`\lambda \sim \mathrm{Beta}(\alpha, \alpha)` for the whole batch and a
    random permutation π of the batch.

    Parameters
    ----------
    x : (N, ...) array_like
        A batch of N samples (images, feature vectors, ...).
    y_onehot : (N, C) array_like
        Their (one-hot or already soft) targets.
    alpha : float
        α > 0 of the Beta distribution (small α: λ mostly near 0 or 1).
    rng : numpy.random.Generator, int or None
        Source of randomness: λ is drawn first, then the permutation.

    Returns
    -------
    x_mixed : float64 ndarray, shape of ``x``
    y_mixed : (N, C) float64 ndarray
    lam : float
        The λ used.

    Notes
    -----
    §12.4 (Zhang et al., 2018). Pairing the batch with a permutation of itself (rather than a
    second batch) is the common implementation; a sample may be paired with itself.

    Examples
    --------
    >>> import numpy as np
    >>> x, y = np.arange(8.0).reshape(4, 2), np.eye(4)
    >>> xm, ym, lam = mixup(x, y, alpha=0.4, rng=0)
    >>> bool(np.allclose(ym.sum(axis=1), 1.0)), 0.0 <= lam <= 1.0
    (True, True)
    """
    data, labels = _batch(x, y_onehot, 1)
    alpha = check_real(alpha, "alpha", positive=True)
    generator = as_rng(rng)
    lam = float(generator.beta(alpha, alpha))
    perm = generator.permutation(data.shape[0])
    return lam * data + (1.0 - lam) * data[perm], lam * labels + (1.0 - lam) * labels[perm], lam


@algorithm("train.cutmix", section="12.4", check="cvkit.train.checks:cutmix")
def cutmix(x: ArrayLike, y_onehot: ArrayLike, alpha: float = 1.0,
           rng: np.random.Generator | int | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    r"""CutMix: paste one box from a permuted batch into every sample; mix labels by area.

    A :math:`\lambda_0 \sim \mathrm{Beta}(\alpha, \alpha)` sets the box size
    ``cut_h = int(H·√(1 − λ0))``, ``cut_w = int(W·√(1 − λ0))``; its centre (cy, cx) is
    uniform over the H × W grid; the box covers rows ``cy − cut_h//2 … cy + cut_h//2 − 1`` and
    columns ``cx − cut_w//2 … cx + cut_w//2 − 1``, clipped to the image. Every sample n gets
    the box's content from sample π(n), and

    .. math:: \lambda = 1 - \frac{\text{box area after clipping}}{H W}, \qquad
              \tilde y_n = \lambda y_n + (1 - \lambda) y_{\pi(n)}.

    Parameters
    ----------
    x : (N, ..., H, W) array_like
        A batch of images, the last two axes rows and columns (e.g. ``(N, H, W)`` or
        ``(N, C, H, W)``; every channel gets the same box).
    y_onehot : (N, C) array_like
        Their targets.
    alpha : float
        α > 0 of the Beta distribution (1: λ0 uniform).
    rng : numpy.random.Generator, int or None
        Source of randomness, drawn in the order λ0, permutation, cy, cx.

    Returns
    -------
    x_mixed : float64 ndarray, shape of ``x``
    y_mixed : (N, C) float64 ndarray
    lam : float
        The label weight λ of the *pasted-into* samples, from the clipped box.

    Notes
    -----
    §12.4 (Yun et al., 2019); the box follows the authors' code (``cy ± cut_h // 2``, so an odd
    ``cut_h`` loses a row). Labels are mixed by the *area actually pasted*, after clipping at
    the border, not by λ0.

    Examples
    --------
    >>> import numpy as np
    >>> x, y = np.random.default_rng(0).random((6, 8, 8)), np.eye(6)
    >>> xm, ym, lam = cutmix(x, y, rng=1)
    >>> pasted = (xm != x).any(axis=0)          # the box (every sample gets it from a partner)
    >>> bool(np.isclose(1 - lam, pasted.sum() / 64)), bool(np.allclose(ym.sum(axis=1), 1))
    (True, True)
    """
    data, labels = _batch(x, y_onehot, 3)
    alpha = check_real(alpha, "alpha", positive=True)
    generator = as_rng(rng)
    height, width = data.shape[-2:]
    lam0 = float(generator.beta(alpha, alpha))
    perm = generator.permutation(data.shape[0])
    cut = np.sqrt(1.0 - lam0)
    cut_h, cut_w = int(height * cut), int(width * cut)
    cy = int(generator.integers(0, height))
    cx = int(generator.integers(0, width))
    y1, y2 = np.clip([cy - cut_h // 2, cy + cut_h // 2], 0, height)
    x1, x2 = np.clip([cx - cut_w // 2, cx + cut_w // 2], 0, width)
    mixed = np.array(data, dtype=np.float64, copy=True)
    mixed[..., y1:y2, x1:x2] = data[perm][..., y1:y2, x1:x2]
    lam = 1.0 - float((y2 - y1) * (x2 - x1)) / (height * width)
    return mixed, lam * labels + (1.0 - lam) * labels[perm], lam
