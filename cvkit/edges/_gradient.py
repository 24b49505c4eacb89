"""First derivatives of an image (§4.3–4.7): finite differences, Prewitt and Sobel, gradient
magnitude and direction.

Derivative filters are correlations (the kernel is not flipped), so that a kernel
``[-1, 0, 1]`` along x gives a positive response where the intensity increases to the right;
y points *down* the rows, as in OpenCV and scikit-image. Images may be grayscale ``(H, W)`` or
colour ``(H, W, 3)`` (filtered channel by channel), of any real dtype; computation is in
float64 without rescaling and the inputs are never modified. Pixels outside the image are read
through ``border`` (see :func:`cvkit.filters.pad`), which the filters obtain from the registry
(``implementation("filters.pad")``).
"""
from __future__ import annotations

from typing import Callable, Literal, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from .._docstrings import IMAGE_BORDER, filler
from .._validation import Border, as_float_array, as_image, check_border
from ..registry import algorithm, implementation

__all__ = ["gradient", "magnitude", "direction", "prewitt", "sobel"]

_docs = filler(IMAGE_BORDER)

#: the whole ``Parameters`` section of an operator that takes only ``(image, border)``: the
#: smoothed differences here and :func:`cvkit.edges.laplacian`
IMAGE_BORDER_PARAMETERS = {
    "image_border_parameters": "\n    ".join(("Parameters", "----------", IMAGE_BORDER["image"], IMAGE_BORDER["border"])),
}

_F = TypeVar("_F", bound=Callable[..., object])

SCHEMES = ("central", "forward", "backward")
NORMS = ("l2", "l1", "max")


def _pair(ix: ArrayLike, iy: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    gx = as_float_array(ix, "ix")
    gy = as_float_array(iy, "iy")
    if gx.shape != gy.shape:
        raise ValueError(f"ix and iy must have the same shape, got {gx.shape} and {gy.shape}")
    return gx, gy


def _padded(img: np.ndarray, radius: int | tuple[int, int], border: str) -> np.ndarray:
    return np.asarray(implementation("filters.pad")(img, radius, border=border), dtype=np.float64)


def _hypot(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """``sqrt(gx² + gy²)`` without overflow or underflow, as fast as the plain formula."""
    with np.errstate(over="ignore", under="ignore"):
        out = np.sqrt(gx * gx + gy * gy)
    unsafe = ~(out < 1e150) | ((out < 1e-150) & ((gx != 0) | (gy != 0)))
    if unsafe.any():
        out[unsafe] = np.hypot(gx[unsafe], gy[unsafe])
    return out


# --------------------------------------------------------------------------------------------
# §4.5 finite differences
# --------------------------------------------------------------------------------------------
@algorithm("edges.gradient", section="4.5", check="cvkit.edges.checks:gradient")
@_docs
def gradient(image: ArrayLike, scheme: Literal["central", "forward", "backward"] = "central",
             border: Border = "reflect101") -> tuple[np.ndarray, np.ndarray]:
    """Image gradient ``(Ix, Iy)`` by finite differences.

    Parameters
    ----------
    %(image)s
    scheme : {"central", "forward", "backward"}
        ``central``: ``Ix(x) = (I(x+1) − I(x−1)) / 2``, the correlation with ``[-1, 0, 1] / 2``;
        ``forward``: ``Ix(x) = I(x+1) − I(x)``; ``backward``: ``Ix(x) = I(x) − I(x−1)``
        (both the kernel ``[-1, 1]``, anchored on the first or on the second tap). The same
        along y, with y increasing down the rows.
    border : {"reflect101", "reflect", "replicate", "zero"}
        How the missing neighbours of border pixels are made up (§3.7).

    Returns
    -------
    (ix, iy) : tuple of two float64 ndarrays, each the shape of ``image``

    Notes
    -----
    §4.5. The forward and backward differences estimate the derivative half a pixel to the
    right (below) and to the left (above) of the pixel; the central difference is centred on
    it, and is the mean of the two. With ``reflect101`` the central difference of the first
    and last column is 0 (the mirror is symmetric about the border pixel), with ``replicate``
    it is a one-sided difference halved. This differs from ``numpy.gradient``, which switches
    to one-sided differences (not halved) at the border. Equals ``cv2.filter2D`` with the
    kernels above (anchor on the centre tap for central, on tap 0 for forward, on tap 1 for
    backward) and the corresponding border mode.

    Examples
    --------
    >>> import numpy as np
    >>> ix, iy = gradient(np.array([[0, 1, 4, 9]] * 2))
    >>> ix
    array([[0., 2., 4., 0.],
           [0., 2., 4., 0.]])
    >>> gradient(np.array([[0, 1, 4, 9]]), scheme="forward", border="replicate")[0]
    array([[1., 3., 5., 0.]])
    """
    img = as_image(image)
    if not isinstance(scheme, str) or scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {', '.join(map(repr, SCHEMES))}, got {scheme!r}")
    check_border(border)
    px = _padded(img, (0, 1), border)  # (H, W + 2)
    py = _padded(img, (1, 0), border)  # (H + 2, W)
    if scheme == "central":
        ix = (px[:, 2:] - px[:, :-2]) * 0.5
        iy = (py[2:] - py[:-2]) * 0.5
    elif scheme == "forward":
        ix = px[:, 2:] - px[:, 1:-1]
        iy = py[2:] - py[1:-1]
    else:
        ix = px[:, 1:-1] - px[:, :-2]
        iy = py[1:-1] - py[:-2]
    return ix, iy


# --------------------------------------------------------------------------------------------
# §4.4–4.5 magnitude and direction
# --------------------------------------------------------------------------------------------
@algorithm("edges.magnitude", section="4.5", exercise="4.4", check="cvkit.edges.checks:magnitude")
def magnitude(ix: ArrayLike, iy: ArrayLike, norm: Literal["l2", "l1", "max"] = "l2") -> np.ndarray:
    """Gradient magnitude ``|∇I|`` in one of three norms.

    Parameters
    ----------
    ix, iy : array_like
        The two derivatives, real arrays of the same shape (any shape), finite values.
    norm : {"l2", "l1", "max"}
        ``l2``: ``sqrt(Ix² + Iy²)`` (exact, the same in every direction);
        ``l1``: ``|Ix| + |Iy|`` (no square root; up to √2 too large on diagonal edges);
        ``max``: ``max(|Ix|, |Iy|)`` (cheapest; up to √2 too small on diagonal edges).

    Returns
    -------
    float64 ndarray, the shape of ``ix``

    Notes
    -----
    §4.5. For a gradient of length g pointing at angle θ, ``l1`` gives
    ``g·(|cos θ| + |sin θ|)`` and ``max`` gives ``g·max(|cos θ|, |sin θ|)``: only ``l2`` does
    not depend on the orientation of the edge. ``l2`` is ``sqrt(Ix² + Iy²)``, recomputed with
    ``numpy.hypot`` (8× slower here) only where the squares would overflow or underflow.

    Examples
    --------
    >>> magnitude([3.0, -1.0], [-4.0, 1.0])
    array([5.        , 1.41421356])
    >>> magnitude([3.0, -1.0], [-4.0, 1.0], norm="l1"), magnitude([3.0, -1.0], [-4.0, 1.0], norm="max")
    (array([7., 2.]), array([4., 1.]))
    """
    gx, gy = _pair(ix, iy)
    if not isinstance(norm, str) or norm not in NORMS:
        raise ValueError(f"norm must be one of {', '.join(map(repr, NORMS))}, got {norm!r}")
    if norm == "l2":
        return _hypot(gx, gy)
    if norm == "l1":
        return np.abs(gx) + np.abs(gy)
    return np.maximum(np.abs(gx), np.abs(gy))


@algorithm("edges.direction", section="4.3", check="cvkit.edges.checks:direction")
def direction(ix: ArrayLike, iy: ArrayLike) -> np.ndarray:
    """Gradient direction ``atan2(Iy, Ix)`` in radians, in (−π, π].

    Parameters
    ----------
    ix, iy : array_like
        The two derivatives, real arrays of the same shape, finite values.

    Returns
    -------
    float64 ndarray, the shape of ``ix``
        The angle of the gradient vector from the x axis, y pointing down the rows (so a
        positive angle turns clockwise on screen). Where both derivatives are 0 the direction
        is undefined and ``numpy.arctan2`` returns 0 (or ±π for negative zeros).

    Notes
    -----
    §4.3. ``arctan(Iy / Ix)`` only returns angles in (−π/2, π/2): it cannot tell a gradient
    from its opposite (a dark-to-bright edge from a bright-to-dark one), and it divides by zero
    on horizontal edges. ``atan2`` looks at both signs and covers the whole circle. (The notes
    quote the range [0, 2π]; NumPy's and C's ``atan2`` return (−π, π], which describes the same
    directions: the checks compare angles modulo 2π.)

    Examples
    --------
    >>> import numpy as np
    >>> np.degrees(direction([1.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, -1.0]))
    array([  0.,  90., 180., -90.])
    """
    gx, gy = _pair(ix, iy)
    return np.arctan2(gy, gx)


# --------------------------------------------------------------------------------------------
# §4.7 Prewitt and Sobel
# --------------------------------------------------------------------------------------------
def _smoothed_differences(image: ArrayLike, border: Border, centre_weight: float) -> tuple[np.ndarray, np.ndarray]:
    """Correlation with ``[1, c, 1]ᵀ ⊗ [-1, 0, 1]`` (gx) and its transpose (gy), separably."""
    img = as_image(image)
    check_border(border)
    p = _padded(img, 1, border)  # (H + 2, W + 2[, 3])
    # gx: smooth down the columns, then difference along the rows
    s = p[:-2] + p[2:]
    if centre_weight == 1.0:
        s += p[1:-1]
    else:
        s += centre_weight * p[1:-1]
    gx = s[:, 2:] - s[:, :-2]
    # gy: smooth along the rows, then difference down the columns
    t = p[:, :-2] + p[:, 2:]
    if centre_weight == 1.0:
        t += p[:, 1:-1]
    else:
        t += centre_weight * p[:, 1:-1]
    gy = t[2:] - t[:-2]
    return gx, gy


#: the docstring of a smoothed-difference filter, whose kernels are ``[1, c, 1]ᵀ ⊗ [-1, 0, 1]``
#: and their transpose: ``%(c)s`` is the centre weight, ``%(ramp)s`` the response to a ramp
#: rising by 1 per pixel, ``%(step)s`` that to a unit step; the summary, the remarks that follow
#: the kernels and the examples after the first are each filter's own.
_SMOOTHED_DIFFERENCES_DOC = """%(summary)s

    %(image_border_parameters)s

    Returns
    -------
    (gx, gy) : tuple of two float64 ndarrays, each the shape of ``image``
        Unnormalised: a ramp rising by 1 per pixel gives %(ramp)s (divide by %(ramp)s for the slope).

    Notes
    -----
    §4.7. Correlation (⋆) with

    .. math:: g_x = I \\star \\begin{bmatrix} -1 & 0 & 1 \\\\ -%(c)s & 0 & %(c)s \\\\ -1 & 0 & 1 \\end{bmatrix}, \\qquad
              g_y = I \\star \\begin{bmatrix} -1 & -%(c)s & -1 \\\\ 0 & 0 & 0 \\\\ 1 & %(c)s & 1 \\end{bmatrix},

    %(remarks)s

    Examples
    --------
    >>> import numpy as np
    >>> gx, gy = %(name)s(np.array([[0, 0, 1, 1]] * 3))
    >>> gx
    array([[0., %(step)s., %(step)s., 0.],
           [0., %(step)s., %(step)s., 0.],
           [0., %(step)s., %(step)s., 0.]])
    %(examples)s"""


def _smoothed_differences_doc(centre_weight: int, summary: str, remarks: str, examples: str = "") -> Callable[[_F], _F]:
    """The docstring of the smoothed-difference filter with centre weight ``centre_weight``
    (:data:`_SMOOTHED_DIFFERENCES_DOC`), given its own summary, remarks and further examples
    (each written with the indentation of a module-level function's docstring)."""
    step = 2 + centre_weight

    def fill(function: _F) -> _F:
        function.__doc__ = _SMOOTHED_DIFFERENCES_DOC
        return filler({**IMAGE_BORDER_PARAMETERS, "summary": summary, "remarks": remarks, "examples": examples,
                       "name": function.__name__, "c": str(centre_weight), "ramp": str(2 * step),
                       "step": str(step)})(function)

    return fill


@algorithm("edges.prewitt", section="4.7", check="cvkit.edges.checks:prewitt")
@_smoothed_differences_doc(
    1, "Prewitt derivatives ``(gx, gy)``: central differences smoothed by a box across them.",
    """unscaled (a unit step gives 3), with the signs of :func:`sobel`: y points down, so ``gy``
    is positive where the image gets brighter downwards. (The notes' listing uses the
    opposite ``gy`` kernel, y pointing up.) Computed separably: ``[1, 1, 1]`` across the
    derivative, then ``[-1, 0, 1]`` along it. Equals ``cv2.filter2D`` with these kernels.""",
    """>>> bool(np.all(gy == 0))
    True
    """)
def prewitt(image: ArrayLike, border: Border = "reflect101") -> tuple[np.ndarray, np.ndarray]:
    return _smoothed_differences(image, border, 1.0)


@algorithm("edges.sobel", section="4.7", check="cvkit.edges.checks:sobel")
@_smoothed_differences_doc(
    2, "Sobel derivatives ``(gx, gy)`` with OpenCV's signs and scale.",
    """i.e. central differences ``[-1, 0, 1]`` along the derivative smoothed by ``[1, 2, 1]``
    across it, computed separably; not normalised (a unit step gives 4). This is
    ``cv2.Sobel(I, cv2.CV_64F, 1, 0, ksize=3)`` (``0, 1`` for gy) and
    ``scipy.ndimage.sobel(I, axis=1)`` (``axis=0``), with the corresponding border modes.

    The padded image comes from ``implementation("filters.pad")``, so
    ``with cvkit.use("student"):`` runs this on the student's padding.""")
def sobel(image: ArrayLike, border: Border = "reflect101") -> tuple[np.ndarray, np.ndarray]:
    return _smoothed_differences(image, border, 2.0)
