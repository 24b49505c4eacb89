"""Scale space and blobs (§5.8–5.9): the scale-normalised LoG blob detector, SIFT's Gaussian and
difference-of-Gaussians pyramids, the extrema of the DoG over their 26 neighbours, and the
refinement and rejection tests applied to each extremum.

Pyramid levels are blurred incrementally with the registry's Gaussian; extrema are found with
whole-array comparisons (a separable 3×3 maximum and minimum per level, then the 26
neighbours of the few surviving candidates).
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_allocation, check_bool, check_padded, check_size, check_work
from ..registry import algorithm, implementation
from ._common import check_int, check_real, gray

__all__ = [
    "double_size", "gaussian_pyramid", "dog_pyramid", "log_blobs", "dog_extrema", "refine_extremum",
    "is_edge_like", "NEIGHBOURS_26", "MAX_SCALES", "max_octaves", "pyramid_arguments", "derivatives_3d",
]

#: the 26 offsets (ds, dr, dc) of a sample's neighbours in (scale, row, col)
NEIGHBOURS_26 = tuple((ds, dr, dc) for ds in (-1, 0, 1) for dr in (-1, 0, 1) for dc in (-1, 0, 1)
                      if (ds, dr, dc) != (0, 0, 0))
#: the most scales per octave of a pyramid (and σ's of :func:`log_blobs`): each one is a
#: whole-image Gaussian (or LoG) per octave, and SIFT uses 3
MAX_SCALES = 100


def double_size(image: ArrayLike) -> np.ndarray:
    """Double both sides: ``U[2i, 2j] = I[i, j]``, bilinear in between, replicate border."""
    img = np.asarray(image, dtype=np.float64)
    h, w = img.shape
    down = np.concatenate([img[1:], img[-1:]], axis=0)          # I[i + 1, j], replicated
    right = np.concatenate([img[:, 1:], img[:, -1:]], axis=1)   # I[i, j + 1]
    diagonal = np.concatenate([down[:, 1:], down[:, -1:]], axis=1)
    out = np.empty((2 * h, 2 * w))
    out[0::2, 0::2] = img
    out[1::2, 0::2] = 0.5 * (img + down)
    out[0::2, 1::2] = 0.5 * (img + right)
    out[1::2, 1::2] = 0.25 * (img + down + right + diagonal)
    return out


def _increments(sigma0: float, scales: int) -> list[float]:
    """The blurs taking level i − 1 of an octave to level i, i = 1 … s + 2: total blurs
    σ_i = σ0·2^(i/s) compose by adding variances."""
    totals = [sigma0 * 2.0 ** (i / scales) for i in range(scales + 3)]
    return [math.sqrt(totals[i] ** 2 - totals[i - 1] ** 2) for i in range(1, scales + 3)]


def _gaussian_radius(sigma: float) -> int:
    """The radius ``ceil(3σ − 1e-9)`` of the registry's Gaussian (``filters.gaussian_kernel``);
    2**60, beyond any allocation, for a σ that is huge (or whose square overflowed to inf/nan)."""
    reach = 3.0 * sigma
    return max(0, math.ceil(reach - 1e-9)) if reach < 2.0**60 else 2**60


def _separable_work(h: int, w: int, radius: int) -> int:
    """Elementary operations of a separable filter of ``radius`` on an h × w image (the padded
    copy and its two passes, as ``filters.gaussian`` counts them)."""
    return 3 * (radius + 1) * (2 * h + 2 * radius) * w


def max_octaves(shape: Sequence[int]) -> int:
    """Octaves an image of ``shape`` gives before the next one would repeat 1 × 1 (each octave
    takes every second row and column of the previous one)."""
    side, count = max(int(n) for n in shape[:2]), 1
    while side > 1:
        side, count = (side + 1) // 2, count + 1
    return count


def pyramid_arguments(shape: Sequence[int], sigma0: float, scales: int, octaves: int, upsample: bool,
                      assumed_blur: float) -> tuple[float, int, int, float]:
    """The arguments of :func:`gaussian_pyramid` for an image of ``shape``, checked (errors name
    the argument): ``(sigma0, scales, octaves, b)`` with ``b`` the blur the base already has.

    Bounds: ``scales`` up to :data:`MAX_SCALES`, ``octaves`` up to :func:`max_octaves` of the
    (upsampled) image, every Gaussian within the 2 GiB padded image and all of them within
    ``cvkit._validation.MAX_WORK`` (``sigma0``), each octave within 2 GiB (``image``).
    """
    sigma0 = check_real(sigma0, "sigma0", positive=True)
    scales = check_size(scales, "scales", minimum=1, maximum=MAX_SCALES)
    octaves = check_int(octaves, "octaves", minimum=1)
    check_bool(upsample, "upsample")
    assumed_blur = check_real(assumed_blur, "assumed_blur", nonnegative=True)
    blur = 2.0 * assumed_blur if upsample else assumed_blur
    if sigma0 <= blur:
        raise ValueError(
            f"sigma0 must exceed the blur the {'upsampled ' if upsample else ''}image already has "
            f"({'2·' if upsample else ''}assumed_blur = {blur:g}), got sigma0 = {sigma0:g}"
        )
    base = (2 * int(shape[0]), 2 * int(shape[1])) if upsample else (int(shape[0]), int(shape[1]))
    allowed = max_octaves(base)
    if octaves > allowed:
        size = f"{base[0]}×{base[1]}{' (upsampled)' if upsample else ''}"
        raise ValueError(f"octaves must be <= {allowed}: a {size} image halves to 1×1 in {allowed} octaves, "
                         f"got {octaves}")
    check_allocation((scales + 3,) + base, "image", what="an octave of scales + 3 levels")
    try:
        radii = [_gaussian_radius(step) for step in _increments(sigma0, scales)]
        first = _gaussian_radius(math.sqrt(sigma0 * sigma0 - blur * blur))
    except OverflowError:                     # σ0² beyond float64: no allocation could hold it
        radii, first = [], 2**60
    check_padded(base, max(radii + [first]), "sigma0")
    h, w = base
    work = _separable_work(h, w, first)
    for _ in range(octaves):
        work += sum(_separable_work(h, w, r) for r in radii)
        h, w = (h + 1) // 2, (w + 1) // 2
    check_work(work, "sigma0", what=f"a pyramid of {octaves} octaves of {scales + 3} levels with sigma0 = {sigma0:g}")
    return sigma0, scales, octaves, blur


# --------------------------------------------------------------------------------------------
# §5.8–5.9 pyramids
# --------------------------------------------------------------------------------------------
@algorithm("features.gaussian_pyramid", section="5.8–5.9", check="cvkit.features.checks:gaussian_pyramid")
def gaussian_pyramid(image: ArrayLike, sigma0: float = 1.6, scales: int = 3, octaves: int = 4, upsample: bool = True,
                     assumed_blur: float = 0.5) -> list[np.ndarray]:
    """SIFT's scale space: octaves of progressively blurred images, halved from one to the next.

    Parameters
    ----------
    image : (H, W) array_like
        Grayscale image, any real dtype, finite values.
    sigma0 : float
        Blur of level 0 of every octave, in that octave's pixels (1.6 in SIFT). Bounded by the
        work it causes: the (upsampled) image padded for the widest Gaussian of the pyramid
        may take at most 2 GiB, and all the Gaussians together at most
        ``cvkit._validation.MAX_WORK`` (2**36, about a minute) elementary operations
        (``ValueError`` naming ``sigma0`` otherwise).
    scales : int
        1 ≤ s ≤ 100 (:data:`MAX_SCALES`), the number of scales per octave at which extrema are
        sought (3 in SIFT); every octave has s + 3 levels, so that its s + 2 DoG levels have s
        interior ones. An octave may take at most 2 GiB (``ValueError`` naming ``image``).
    octaves : int
        Number of octaves, 1 ≤ octaves ≤ :func:`max_octaves` of the (upsampled) image: as
        many as halve it down to 1×1 (a 16×16 image allows 5), since further ones would only
        repeat that pixel (``ValueError`` saying how many the image allows).
    upsample : bool
        Double the image first (Lowe: it quadruples the number of stable keypoints).
    assumed_blur : float
        Blur the input is assumed to have already (0.5: a camera's anti-aliasing), ≥ 0.

    Returns
    -------
    list of ``octaves`` float64 ndarrays of shape (s + 3, H_o, W_o)

    Notes
    -----
    §5.8–5.9. Upsampling puts ``U[2i, 2j] = I[i, j]`` and interpolates bilinearly in between,
    replicating the last row and column; shape (2H, 2W). Level 0 is the (upsampled) image
    blurred by ``sqrt(σ0² − b²)`` with ``b = 2·assumed_blur`` when upsampling (the doubled image
    has twice the blur in its pixels) else ``assumed_blur``, so that its total blur is σ0.
    Level i has total blur ``σ_i = σ0·2^(i/s)``, reached *incrementally*: level i is level
    i − 1 blurred by ``sqrt(σ_i² − σ_{i−1}²)`` (Gaussians compose by adding variances), each
    with ``implementation("filters.gaussian")`` (reflect101 border). Octave o + 1 starts from
    level s of octave o (total blur 2σ0) taken ``[::2, ::2]``, whose blur in the new pixels is
    σ0 again; its further levels use the same increments. A point (x_o, y_o) of octave o lies
    at ``x_o·2^o`` (halved when upsampled) in the input. Small images simply give small
    octaves (down to 1×1, the last octave allowed).

    Examples
    --------
    >>> import numpy as np
    >>> pyramid = gaussian_pyramid(np.random.default_rng(0).random((32, 40)), octaves=3)
    >>> [level.shape for level in pyramid]
    [(6, 64, 80), (6, 32, 40), (6, 16, 20)]
    """
    img = gray(image)
    sigma0, scales, octaves, b = pyramid_arguments(img.shape, sigma0, scales, octaves, upsample, assumed_blur)
    gaussian = implementation("filters.gaussian")
    increments = _increments(sigma0, scales)
    base = double_size(img) if upsample else img
    base = np.asarray(gaussian(base, math.sqrt(sigma0 * sigma0 - b * b)), dtype=np.float64)
    pyramid: list[np.ndarray] = []
    for o in range(octaves):
        if o > 0:
            base = pyramid[-1][scales][::2, ::2]
        stack = np.empty((scales + 3,) + base.shape)
        stack[0] = base
        for i, step in enumerate(increments, start=1):
            stack[i] = gaussian(stack[i - 1], step)
        pyramid.append(stack)
    return pyramid


def _as_stacks(value: object, name: str) -> list[np.ndarray]:
    if isinstance(value, np.ndarray) and value.ndim == 3:
        value = [value]
    if not isinstance(value, (list, tuple)) or not value:
        raise TypeError(f"{name} must be a non-empty list of (levels, H, W) arrays, got {type(value).__name__}")
    stacks = [as_float_array(s, f"{name}[{i}]", ndim=3) for i, s in enumerate(value)]
    return stacks


@algorithm("features.dog_pyramid", section="5.9", check="cvkit.features.checks:dog_pyramid")
def dog_pyramid(gaussian_pyramid: Sequence[ArrayLike] | np.ndarray) -> list[np.ndarray]:
    """Differences of adjacent Gaussian levels, octave by octave.

    Parameters
    ----------
    gaussian_pyramid : list of (L, H_o, W_o) arrays
        As returned by :func:`gaussian_pyramid` (L = s + 3 ≥ 2).

    Returns
    -------
    list of float64 ndarrays of shape (L − 1, H_o, W_o)
        Level i is ``level i+1 − level i`` of the Gaussian octave.

    Notes
    -----
    §5.9. ``G(kσ) ∗ I − G(σ) ∗ I ≈ (k − 1)σ²∇²G ∗ I``: each DoG level approximates the
    scale-normalised LoG (times the constant k − 1), with its sign — bright blobs are minima.

    Examples
    --------
    >>> import numpy as np
    >>> dog_pyramid([np.arange(12.0).reshape(3, 2, 2)])[0][:, 0, 0]
    array([4., 4.])
    """
    stacks = _as_stacks(gaussian_pyramid, "gaussian_pyramid")
    for i, stack in enumerate(stacks):
        if stack.shape[0] < 2:
            raise ValueError(f"gaussian_pyramid[{i}] needs at least 2 levels, got shape {stack.shape}")
    return [stack[1:] - stack[:-1] for stack in stacks]


# --------------------------------------------------------------------------------------------
# §5.8 scale-normalised LoG blobs
# --------------------------------------------------------------------------------------------
def _strict_extrema(stack: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Masks of the samples strictly above (below) their 3×3×3 neighbours, clipped to the stack."""
    s, h, w = stack.shape
    high = np.full((s + 2, h + 2, w + 2), -np.inf)
    low = np.full((s + 2, h + 2, w + 2), np.inf)
    high[1:-1, 1:-1, 1:-1] = stack
    low[1:-1, 1:-1, 1:-1] = stack
    is_max = np.ones(stack.shape, dtype=bool)
    is_min = np.ones(stack.shape, dtype=bool)
    for ds, dr, dc in NEIGHBOURS_26:
        window = (slice(1 + ds, 1 + ds + s), slice(1 + dr, 1 + dr + h), slice(1 + dc, 1 + dc + w))
        is_max &= stack > high[window]
        is_min &= stack < low[window]
    return is_max, is_min


def _check_log_stack(shape: tuple[int, ...], sigmas: np.ndarray) -> None:
    """Refuse (naming ``sigmas``) a stack of LoG responses beyond the bounds of :func:`log_blobs`."""
    check_size(sigmas.size, "len(sigmas)", maximum=MAX_SCALES)
    check_allocation((sigmas.size,) + tuple(shape), "sigmas", what="the stack of LoG responses")
    work = 0
    for sigma in sigmas.tolist():
        radius = max(0, math.ceil(3.0 * sigma)) if sigma < 2.0**60 else 2**60      # edges.log's ceil(3σ)
        check_allocation((2 * radius + 1, 2 * radius + 1), "sigmas", what="a LoG kernel")
        padded = check_padded(shape, radius, "sigmas")
        pixels = padded[0] * padded[1]
        work += 15 * pixels * max(1, math.ceil(math.log2(pixels)))          # at most three FFTs of it
    check_work(work, "sigmas", what=f"{sigmas.size} LoG responses of a {shape[0]}×{shape[1]} image")


@algorithm("features.log_blobs", section="5.8", check="cvkit.features.checks:log_blobs")
def log_blobs(image: ArrayLike, sigmas: ArrayLike, threshold: float) -> np.ndarray:
    """Blobs: extrema in space and scale of the scale-normalised Laplacian of Gaussian.

    Parameters
    ----------
    image : (H, W) array_like
        Grayscale image, any real dtype, finite values.
    sigmas : sequence of float
        The scales σ > 0 to sample, in the order that defines the scale neighbours (usually
        increasing); at most 100 (:data:`MAX_SCALES`) of them. Bounded by the work they cause:
        the LoG kernel of the largest σ and the image padded by its radius ceil(3σ) may each
        take at most 2 GiB, the stack of responses too, and the LoGs together at most
        ``cvkit._validation.MAX_WORK`` elementary operations (``ValueError`` naming
        ``sigmas`` otherwise).
    threshold : float
        A blob needs ``|F| > threshold``, ≥ 0.

    Returns
    -------
    (N, 3) float64 ndarray
        ``(x, y, σ)`` of each blob, σ being the sampled value; ordered by scale index, then
        row, then column. Shape ``(0, 3)`` when there is none.

    Notes
    -----
    §5.8. ``F(x, y, σ) = σ²·∇²(G_σ ∗ I)`` with ``implementation("edges.log")`` (kernel radius
    ceil(3σ), reflect101 border). The σ² factor (Lindeberg's normalisation) undoes the decay of
    the derivatives with σ, so a disk of radius ρ answers most strongly at σ ≈ ρ/√2 at every
    size. A sample is kept when ``|F| > threshold`` and it is strictly greater — or strictly
    smaller — than all its neighbours in the 3×3×3 block of (scale, row, col) clipped to the
    stack. Bright blobs on a dark background are minima of F (the LoG is negative inside),
    dark blobs maxima. ``skimage.feature.blob_log`` finds the same blobs (it negates F, keeps
    maxima only, and prunes overlapping blobs).

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[0:41, 0:41]
    >>> img = np.exp(-((x - 20) ** 2 + (y - 17) ** 2) / (2 * 3.0 ** 2))   # bright blob, σ = 3
    >>> log_blobs(img, [1.5, 2.1, 3.0, 4.2, 6.0], 0.1)
    array([[20., 17.,  3.]])
    """
    img = gray(image)
    sigmas = as_float_array(sigmas, "sigmas", ndim=1)
    if np.any(sigmas <= 0):
        raise ValueError(f"sigmas must all be > 0, got {sigmas.tolist()}")
    threshold = check_real(threshold, "threshold", nonnegative=True)
    _check_log_stack(img.shape, sigmas)
    log = implementation("edges.log")
    stack = np.stack([s * s * np.asarray(log(img, float(s)), dtype=np.float64) for s in sigmas])
    is_max, is_min = _strict_extrema(stack)
    keep = (is_max | is_min) & (np.abs(stack) > threshold)
    index, rows, cols = np.nonzero(keep)
    return np.stack([cols, rows, sigmas[index]], axis=1).astype(np.float64).reshape(-1, 3)


# --------------------------------------------------------------------------------------------
# §5.9 DoG extrema, refinement and edge rejection
# --------------------------------------------------------------------------------------------
_BLOCK = 1 << 15  # samples of a block of rows: the comparisons' temporaries stay in cache


def _extrema_of_level(d: np.ndarray, s: int, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the strict 26-neighbour extrema of level ``s`` of the stack ``d``
    with ``|D| > threshold``, in raster order.

    A cascade: the threshold and the 4 neighbours in the level leave few candidates (whole
    blocks of rows at a time); the other 22 neighbours are compared on those only.
    """
    _, h, w = d.shape
    level = d[s]
    rows_per_block = max(1, _BLOCK // max(1, w))
    found_r, found_c = [], []
    for r0 in range(1, h - 1, rows_per_block):
        r1 = min(h - 1, r0 + rows_per_block)
        centre = level[r0:r1, 1:-1]
        left, right = level[r0:r1, :-2], level[r0:r1, 2:]
        up, down = level[r0 - 1:r1 - 1, 1:-1], level[r0 + 1:r1 + 1, 1:-1]
        strong = np.abs(centre) > threshold
        high = strong & (centre > left) & (centre > right) & (centre > up) & (centre > down)
        low = strong & (centre < left) & (centre < right) & (centre < up) & (centre < down)
        for mask, better in ((high, np.greater), (low, np.less)):
            rr, cc = np.nonzero(mask)
            if rr.size == 0:
                continue
            rr, cc = rr + r0, cc + 1
            value = level[rr, cc]
            keep = np.ones(rr.size, dtype=bool)
            for ds, dr, dc in NEIGHBOURS_26:
                if ds == 0 and (dr == 0 or dc == 0):
                    continue  # the four already compared
                keep &= better(value, d[s + ds, rr + dr, cc + dc])
            found_r.append(rr[keep])
            found_c.append(cc[keep])
    if not found_r:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    rr, cc = np.concatenate(found_r), np.concatenate(found_c)
    order = np.lexsort((cc, rr))
    return rr[order], cc[order]


@algorithm("features.dog_extrema", section="5.9", check="cvkit.features.checks:dog_extrema")
def dog_extrema(dog_pyramid: Sequence[ArrayLike] | np.ndarray, contrast_threshold: float = 0.03) -> np.ndarray:
    """Samples of the DoG pyramid that are extrema among their 26 neighbours.

    Parameters
    ----------
    dog_pyramid : list of (L, H_o, W_o) arrays
        As returned by :func:`dog_pyramid`.
    contrast_threshold : float
        A candidate needs ``|D| > contrast_threshold``, ≥ 0, in the units of D (raw: *not*
        divided by the number of scales).

    Returns
    -------
    (N, 4) int64 ndarray
        ``(octave, scale, row, col)`` of every extremum, sorted lexicographically.

    Notes
    -----
    §5.9. Every interior sample (1 ≤ scale ≤ L−2, 1 ≤ row ≤ H−2, 1 ≤ col ≤ W−2) is a
    candidate — no wider margin. It is kept when it is *strictly* greater than all 26
    neighbours (8 in its own level, 9 in the level above, 9 below) or strictly smaller than
    all of them. (OpenCV accepts ties, asks maxima to be positive and minima negative, and
    skips a 5-pixel border.) Vectorised as a cascade, by blocks of rows: the threshold and the
    four neighbours in the same level leave few candidates, which are then compared with the
    other 22 neighbours.

    Examples
    --------
    >>> import numpy as np
    >>> d = np.zeros((3, 5, 5)); d[1, 2, 3] = 0.5; d[1, 1, 1] = -0.2
    >>> dog_extrema([d], 0.1)
    array([[0, 1, 1, 1],
           [0, 1, 2, 3]])
    """
    stacks = _as_stacks(dog_pyramid, "dog_pyramid")
    threshold = check_real(contrast_threshold, "contrast_threshold", nonnegative=True)
    found = []
    for octave, d in enumerate(stacks):
        levels, h, w = d.shape
        if levels < 3 or h < 3 or w < 3:
            continue
        for s in range(1, levels - 1):
            rr, cc = _extrema_of_level(d, s, threshold)
            found.append(np.stack([np.full(rr.size, octave), np.full(rr.size, s), rr, cc], axis=1))
    if not found:
        return np.zeros((0, 4), dtype=np.int64)
    rows = np.concatenate(found).astype(np.int64).reshape(-1, 4)
    order = np.lexsort(rows.T[::-1])
    return rows[order]


def _position(value: int, name: str, size: int) -> int:
    index = check_int(value, name)
    if not 1 <= index <= size - 2:
        raise ValueError(f"{name} must be an interior index 1..{size - 2} (both neighbours needed), got {index}")
    return index


def derivatives_3d(d: np.ndarray, s: int | np.ndarray, r: int | np.ndarray,
                   c: int | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Central-difference gradient (..., 3) and Hessian (..., 3, 3) of a stack at (s, r, c), in the
    order (s, r, c); the indices may be integers or arrays of them."""
    v = d[s, r, c]
    g = 0.5 * np.stack([d[s + 1, r, c] - d[s - 1, r, c], d[s, r + 1, c] - d[s, r - 1, c], d[s, r, c + 1] - d[s, r, c - 1]], axis=-1)
    hss = d[s + 1, r, c] + d[s - 1, r, c] - 2.0 * v
    hrr = d[s, r + 1, c] + d[s, r - 1, c] - 2.0 * v
    hcc = d[s, r, c + 1] + d[s, r, c - 1] - 2.0 * v
    hsr = 0.25 * (d[s + 1, r + 1, c] - d[s + 1, r - 1, c] - d[s - 1, r + 1, c] + d[s - 1, r - 1, c])
    hsc = 0.25 * (d[s + 1, r, c + 1] - d[s + 1, r, c - 1] - d[s - 1, r, c + 1] + d[s - 1, r, c - 1])
    hrc = 0.25 * (d[s, r + 1, c + 1] - d[s, r + 1, c - 1] - d[s, r - 1, c + 1] + d[s, r - 1, c - 1])
    hessian = np.stack([np.stack([hss, hsr, hsc], axis=-1), np.stack([hsr, hrr, hrc], axis=-1),
                        np.stack([hsc, hrc, hcc], axis=-1)], axis=-2)
    return g, hessian


@algorithm("features.refine_extremum", section="5.9", check="cvkit.features.checks:refine_extremum")
def refine_extremum(dog_stack: ArrayLike, scale: int, row: int, col: int) -> tuple[np.ndarray, float]:
    """Sub-pixel, sub-scale position of an extremum: one Newton step on a 3-D quadratic.

    Parameters
    ----------
    dog_stack : (L, H, W) array_like
        One octave of the DoG pyramid.
    scale, row, col : int
        The sample to refine; interior (both neighbours must exist along each axis).

    Returns
    -------
    offset : (3,) float64 ndarray
        ``x̂ = −H⁻¹∇D``, as ``(ds, dr, dc)``.
    value : float
        The interpolated value ``D(x̂) = D + ½ ∇Dᵀ x̂``, used for the contrast test.

    Notes
    -----
    §5.9 (Brown and Lowe). The Taylor expansion ``D(x) ≈ D + ∇Dᵀx + ½ xᵀHx`` about the sample
    has its stationary point at ``x̂ = −H⁻¹∇D``. The gradient is by central differences
    ``(D[+1] − D[−1]) / 2`` and the Hessian by the second differences
    ``D[+1] + D[−1] − 2D`` and the mixed ``(D[+1,+1] − D[+1,−1] − D[−1,+1] + D[−1,−1]) / 4``,
    all in the order (scale, row, col). An |offset| > 0.5 along an axis means that the
    extremum is closer to another sample (SIFT then moves there and repeats; :func:`sift`
    moves only from 0.6 on, as Otero & Delbracio's IPOL SIFT and VLFeat do, so that an
    extremum half-way between two samples is not bounced between them).

    Raises
    ------
    ValueError
        At the border of the stack, or when the Hessian is singular.

    Examples
    --------
    >>> import numpy as np
    >>> s, r, c = np.mgrid[0:3, 0:5, 0:5]
    >>> d = -((s - 1.2) ** 2 + (r - 2.0) ** 2 + (c - 1.7) ** 2)     # a peak at (1.2, 2.0, 1.7)
    >>> offset, value = refine_extremum(d, 1, 2, 2)
    >>> offset.round(12), round(value, 12)
    (array([ 0.2,  0. , -0.3]), 0.0)
    """
    d = as_float_array(dog_stack, "dog_stack", ndim=3)
    s = _position(scale, "scale", d.shape[0])
    r = _position(row, "row", d.shape[1])
    c = _position(col, "col", d.shape[2])
    g, hessian = derivatives_3d(d, s, r, c)
    try:
        offset = -np.linalg.solve(hessian, g)
    except np.linalg.LinAlgError:
        raise ValueError(f"the Hessian at (scale, row, col) = ({s}, {r}, {c}) is singular") from None
    if not np.all(np.isfinite(offset)):
        raise ValueError(f"the Hessian at (scale, row, col) = ({s}, {r}, {c}) is singular")
    # the three products summed in a fixed order (the pipeline's batch version does the same)
    return offset, float(d[s, r, c] + 0.5 * (g[0] * offset[0] + g[1] * offset[1] + g[2] * offset[2]))


@algorithm("features.is_edge_like", section="5.9", check="cvkit.features.checks:is_edge_like")
def is_edge_like(dog_slice: ArrayLike, row: int, col: int, r: float = 10.0) -> bool:
    """Is a DoG extremum on an edge (principal curvatures too unequal)?

    Parameters
    ----------
    dog_slice : (H, W) array_like
        One level of the DoG pyramid.
    row, col : int
        The sample, interior (1..H−2, 1..W−2).
    r : float
        The largest accepted ratio of the two principal curvatures, > 0 (10 in SIFT).

    Returns
    -------
    bool
        True when ``det ≤ 0`` (curvatures of opposite signs: a saddle) or
        ``trace² / det ≥ (r + 1)² / r``.

    Notes
    -----
    §5.9. The 2×2 Hessian by central differences, ``Dxx = D[r, c+1] + D[r, c−1] − 2D``,
    ``Dyy`` likewise down the column, ``Dxy = (D[r+1, c+1] − D[r+1, c−1] − D[r−1, c+1] +
    D[r−1, c−1]) / 4``. With eigenvalues α = r·β, ``trace²/det = (r + 1)²/r`` grows with the
    ratio r: the test bounds the ratio without computing eigenvalues, as Harris' R does.

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[0:5, 0:5]
    >>> bool(is_edge_like(-(x - 2.0) ** 2 - (y - 2.0) ** 2, 2, 2)), bool(is_edge_like(-(x - 2.0) ** 2 + 0.0 * y, 2, 2))
    (False, True)
    """
    d = as_float_array(dog_slice, "dog_slice", ndim=2)
    i = _position(row, "row", d.shape[0])
    j = _position(col, "col", d.shape[1])
    ratio = check_real(r, "r", positive=True)
    trace, det = _hessian_trace_det(d, i, j)
    return bool(det <= 0 or trace * trace * ratio >= (ratio + 1.0) ** 2 * det)


def _hessian_trace_det(d: np.ndarray, r: "int | np.ndarray", c: "int | np.ndarray") -> tuple:
    """Trace and determinant of the 2×2 Hessian of ``d`` at ``(r, c)`` by central differences
    (scalars, or arrays for index arrays ``r``, ``c``; no check: the neighbours must exist)."""
    v = d[r, c]
    dxx = d[r, c + 1] + d[r, c - 1] - 2.0 * v
    dyy = d[r + 1, c] + d[r - 1, c] - 2.0 * v
    dxy = 0.25 * (d[r + 1, c + 1] - d[r + 1, c - 1] - d[r - 1, c + 1] + d[r - 1, c - 1])
    return dxx + dyy, dxx * dyy - dxy * dxy
