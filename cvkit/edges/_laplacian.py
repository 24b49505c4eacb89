"""Second derivatives (§4.11–4.12): the discrete Laplacian, the Laplacian of Gaussian (LoG),
its difference-of-Gaussians approximation (DoG) and the zero crossings that mark edges.

Linear operators accept grayscale ``(H, W)`` or colour ``(H, W, 3)`` images (per channel) of
any real dtype, compute in float64 without rescaling, read outside the image through
``border`` and never modify their inputs. Building blocks are looked up in the registry.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .._docstrings import IMAGE_BORDER, filler
from .._validation import (Border, as_float_array, as_image, check_allocation, check_border, check_int,
                           check_padded, check_real)
from ..registry import algorithm, implementation
from ._gradient import IMAGE_BORDER_PARAMETERS

__all__ = ["laplacian", "log_kernel", "log", "zero_crossings", "dog"]

_docs = filler({**IMAGE_BORDER, **IMAGE_BORDER_PARAMETERS})


@algorithm("edges.laplacian", section="4.12", check="cvkit.edges.checks:laplacian")
@_docs
def laplacian(image: ArrayLike, border: Border = "reflect101") -> np.ndarray:
    """The 4-neighbour discrete Laplacian ``Ixx + Iyy``.

    %(image_border_parameters)s

    Returns
    -------
    float64 ndarray, the shape of ``image``
        ``Ixx + Iyy`` at every pixel: 0 on flat areas and, away from the border, on linear ramps.

    Notes
    -----
    §4.12. The second differences ``Ixx ≈ I(x−1) − 2I(x) + I(x+1)`` (a forward difference of
    backward differences) and the same along y add up to the correlation with

    .. math:: \\nabla^2 = \\begin{bmatrix} 0 & 1 & 0 \\\\ 1 & -4 & 1 \\\\ 0 & 1 & 0 \\end{bmatrix}.

    Equals ``cv2.Laplacian(I, cv2.CV_64F, ksize=1)`` and ``scipy.ndimage.laplace`` with the
    corresponding border modes.

    Examples
    --------
    >>> import numpy as np
    >>> laplacian(np.array([[0, 0, 0], [0, 1, 0], [0, 0, 0]]), border="zero")
    array([[ 0.,  1.,  0.],
           [ 1., -4.,  1.],
           [ 0.,  1.,  0.]])
    """
    img = as_image(image)
    check_border(border)
    p = np.asarray(implementation("filters.pad")(img, 1, border=border), dtype=np.float64)
    centre = p[1:-1, 1:-1]
    out = p[:-2, 1:-1] + p[2:, 1:-1]
    out += p[1:-1, :-2]
    out += p[1:-1, 2:]
    out -= 4.0 * centre
    return out


def _radius(sigma: float) -> int:
    """``ceil(3σ)``, the default LoG radius (``2**62`` for a σ beyond any allocation)."""
    reach = 3.0 * sigma
    return max(0, int(math.ceil(reach))) if reach < 2.0**62 else 2**62


@algorithm("edges.log_kernel", section="4.12", check="cvkit.edges.checks:log_kernel")
def log_kernel(sigma: float, radius: int | None = None) -> np.ndarray:
    """The Laplacian of Gaussian sampled on a square, shifted to sum to zero.

    Parameters
    ----------
    sigma : float
        Standard deviation of the Gaussian, > 0. A σ so small that the samples overflow
        float64 (below about 1e-50) is refused (``ValueError`` naming ``sigma``): the LoG
        has no finite limit as σ → 0.
    radius : int, optional
        Half-width r >= 0; default ``ceil(3σ)``, literally as the catalog states (unlike
        :func:`cvkit.filters.gaussian_kernel`, no guard against round-off in 3σ). The kernel
        may take at most 2 GiB, r <= 8191 (``ValueError`` naming ``radius``, or ``sigma``
        for the default radius).

    Returns
    -------
    (2r + 1, 2r + 1) float64 ndarray
        Symmetric, summing to 0 (up to rounding), negative at the centre.

    Notes
    -----
    §4.12. With :math:`G = e^{-(x^2+y^2)/2\\sigma^2} / 2\\pi\\sigma^2`,

    .. math:: \\nabla^2 G(x, y) = \\frac{x^2 + y^2 - 2\\sigma^2}{2\\pi\\sigma^6}\\, e^{-(x^2+y^2)/2\\sigma^2}

    sampled at the integers ``-r .. r`` (row index y, column index x), minus the mean of the
    samples: the continuous LoG integrates to 0, the truncated samples do not quite, and a
    kernel that does not sum to 0 would respond to flat regions. Not scale-normalised (no σ²
    factor). ``scipy.ndimage.gaussian_laplace`` sums two separable second-derivative kernels
    instead and truncates at 4σ; the two agree to a few percent of the response.

    Examples
    --------
    >>> k = log_kernel(1.0)
    >>> k.shape, bool(abs(k.sum()) < 1e-15), bool(k[3, 3] == k.min()), bool(np.allclose(k, k.T))
    ((7, 7), True, True, True)
    """
    sigma = check_real(sigma, "sigma", positive=True)
    if radius is None:
        radius, name = _radius(sigma), "sigma"
    else:
        radius, name = check_int(radius, "radius", minimum=0), "radius"
    check_allocation((2 * radius + 1, 2 * radius + 1), name, what="a LoG kernel")
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    r2 = x[:, None] ** 2 + x[None, :] ** 2
    s2 = sigma * sigma
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        kernel = (r2 - 2.0 * s2) / (2.0 * math.pi * s2 ** 3) * np.exp(-r2 / (2.0 * s2))
        kernel -= kernel.mean()
    if not np.isfinite(kernel).all():
        raise ValueError(
            f"sigma={sigma!r} is too small for a sampled LoG of radius {radius}: its samples "
            f"(about r²/σ⁶) overflow float64; use a larger sigma (1e-50 or more)")
    return kernel


@algorithm("edges.log", section="4.12", check="cvkit.edges.checks:log")
@_docs
def log(image: ArrayLike, sigma: float, border: Border = "reflect101") -> np.ndarray:
    """Laplacian of Gaussian response: the image correlated with :func:`log_kernel`.

    Parameters
    ----------
    %(image)s
    sigma : float
        Standard deviation of the Gaussian, > 0; the kernel radius is ceil(3σ). The kernel and
        the image padded by the radius may each take at most 2 GiB (``ValueError`` naming
        ``sigma`` otherwise), which also bounds the time (at most one FFT of that size).
    %(border)s

    Returns
    -------
    float64 ndarray, the shape of ``image``
        Negative on the bright side of an edge, positive on the dark side; its zero crossings
        (:func:`zero_crossings`) mark the edges (Marr–Hildreth).

    Notes
    -----
    §4.12. By linearity ``∇²(G ∗ I) = (∇²G) ∗ I``: one correlation with the precomputed kernel
    replaces smoothing followed by differentiation (the kernel is symmetric, so correlation
    and convolution agree). The kernel and the correlation are looked up in the registry
    (``edges.log_kernel``, ``filters.correlate``). Agrees with
    ``scipy.ndimage.gaussian_laplace(I, σ)`` up to the truncation of the kernel (3σ here,
    4σ there), a few percent of the largest response.

    Examples
    --------
    >>> import numpy as np
    >>> step = np.zeros((9, 10)); step[:, 5:] = 1.0
    >>> response = log(step, 1.0)
    >>> bool(response[4, 4] > 0 > response[4, 5]), bool(np.allclose(response[:, 0], 0))
    (True, True)
    """
    img = as_image(image)
    sigma = check_real(sigma, "sigma", positive=True)
    check_border(border)
    radius = _radius(sigma)
    check_allocation((2 * radius + 1, 2 * radius + 1), "sigma", what="a LoG kernel")
    check_padded(img.shape, radius, "sigma")
    kernel = as_float_array(implementation("edges.log_kernel")(sigma), "the kernel returned by edges.log_kernel", ndim=2)
    return np.asarray(implementation("filters.correlate")(img, kernel, border=border), dtype=np.float64)


@algorithm("edges.zero_crossings", section="4.11", check="cvkit.edges.checks:zero_crossings")
def zero_crossings(response: ArrayLike, threshold: float = 0.0) -> np.ndarray:
    """Mark the zero crossings of a second-derivative response (LoG, DoG, Laplacian).

    Parameters
    ----------
    response : (H, W) array_like
        Real, finite values.
    threshold : float
        Minimal jump ``|a − b|`` across a crossing, >= 0 (0: every sign change).

    Returns
    -------
    (H, W) bool ndarray

    Notes
    -----
    §4.11–4.12. Every pair of horizontally or vertically adjacent pixels with values a and b
    of opposite signs (``a·b < 0``, tested on the signs so that tiny values cannot underflow;
    an exact 0 is never part of a crossing) and ``|a − b| > threshold`` is a crossing. The
    edge is put on the pixel of the pair whose value is closer to 0, the one nearer to the
    true zero; on a tie, on the upper (vertical pair) or left (horizontal pair) pixel. The
    notes list the other choices (the positive or the negative pixel): they shift the edge
    by half a pixel to one side.

    Examples
    --------
    >>> import numpy as np
    >>> zero_crossings(np.array([[3.0, 1.0, -2.0, -1.0, 0.0, 5.0]])).astype(int)
    array([[0, 1, 0, 0, 0, 0]])
    """
    r = as_float_array(response, "response", ndim=2)
    threshold = check_real(threshold, "threshold", nonnegative=True)
    positive, negative = r > 0, r < 0
    magnitude = np.abs(r)
    out = np.zeros(r.shape, dtype=bool)
    for first, second in (
        ((slice(None), slice(None, -1)), (slice(None), slice(1, None))),  # left, right
        ((slice(None, -1), slice(None)), (slice(1, None), slice(None))),  # upper, lower
    ):
        crossing = (positive[first] & negative[second]) | (negative[first] & positive[second])
        if threshold > 0:
            crossing &= np.abs(r[first] - r[second]) > threshold
        on_first = magnitude[first] <= magnitude[second]
        out[first] |= crossing & on_first
        out[second] |= crossing & ~on_first
    return out


@algorithm("edges.dog", section="4.12", check="cvkit.edges.checks:dog")
@_docs
def dog(image: ArrayLike, sigma: float, k: float = 1.6, border: Border = "reflect101") -> np.ndarray:
    """Difference of Gaussians ``G_{kσ} ∗ I − G_σ ∗ I``, an approximation of the LoG.

    Parameters
    ----------
    %(image)s
    sigma : float
        The smaller standard deviation, > 0.
    k : float
        Ratio of the two standard deviations, > 0 (1.6 in Marr–Hildreth, √2 or 2^(1/s) in
        SIFT's scale space). Both σ and kσ must be finite and > 0 in float64, and each
        smoothing is bounded as :func:`cvkit.filters.gaussian` (``ValueError`` naming
        ``sigma`` and ``k`` otherwise).
    %(border)s

    Returns
    -------
    float64 ndarray, the shape of ``image``
        The band-pass response: ≈ (k − 1)σ² times the Laplacian of the image smoothed by σ.

    Notes
    -----
    §4.12 (and §5.9). Since ``∂G/∂σ = σ∇²G``,
    ``G_{kσ} − G_σ ≈ (k − 1)σ · σ∇²G = (k − 1)σ²∇²G``: the DoG is a scaled LoG (with the
    same sign: negative on the bright side of an edge). Both smoothings use
    ``implementation("filters.gaussian")`` (radius ceil(3σ) each).

    Examples
    --------
    >>> import numpy as np
    >>> step = np.zeros((9, 10)); step[:, 5:] = 1.0
    >>> d = dog(step, 1.0)
    >>> bool(d[4, 4] > 0 > d[4, 5])
    True
    """
    img = as_image(image)
    sigma = check_real(sigma, "sigma", positive=True)
    k = check_real(k, "k", positive=True)
    check_border(border)
    wider = k * sigma
    if not 0.0 < wider < math.inf:
        raise ValueError(f"k·sigma must be finite and > 0 in float64, got k={k!r}, sigma={sigma!r}: {wider!r}")
    gaussian = implementation("filters.gaussian")
    try:
        wide = np.asarray(gaussian(img, wider, border=border), dtype=np.float64)
    except ValueError as error:  # said of filters.gaussian's sigma: here it is k·sigma
        raise ValueError(f"k·sigma = {wider!r} (k={k!r}, sigma={sigma!r}): {error}") from None
    return wide - np.asarray(gaussian(img, sigma, border=border), dtype=np.float64)
