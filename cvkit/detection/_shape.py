"""Shape-based matching (§6.0.3): compare gradient *directions* at the model's edge points
with those of the image under every placement, instead of raw intensities.

The model is a set of control points (pixels of strong gradient in the template) and the unit
gradient direction at each. The similarity of a placement is the mean cosine of the angle
between each model direction and the image gradient at the corresponding pixel; taking the
absolute value of the sum (global) or of each term (local) makes it invariant to a global or a
local inversion of contrast polarity. Vectorised with a loop over the control points (each a
whole-map multiply-add of two shifted views of the unit image gradient).
"""
from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_real, check_work
from ..registry import algorithm, implementation

__all__ = ["shape_model", "shape_match"]

POLARITIES = ("none", "global", "local")
#: an image gradient of magnitude at most NO_GRADIENT·max|image| has no direction (cos = 0)
NO_GRADIENT = 1e-10


def _sobel(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    gx, gy = implementation("edges.sobel")(img)
    return np.asarray(gx, dtype=np.float64), np.asarray(gy, dtype=np.float64)


@algorithm("detection.shape_model", section="6.0.3", check="cvkit.detection.checks:shape_model")
def shape_model(template: ArrayLike, threshold: float) -> dict:
    """The model of shape-based matching: control points and their gradient directions.

    Parameters
    ----------
    template : (h, w) array_like
        The model image, any real dtype, finite values.
    threshold : float
        Control points are the pixels whose L2 Sobel magnitude is **strictly greater** than
        ``threshold``, in raw magnitude units (a unit step gives 4), ``>= 0``.

    Returns
    -------
    dict
        ``"points"``: ``(N, 2)`` float64 ``(x, y)`` of the control points, measured from the
        template's top-left pixel, in raster order (row by row); ``"directions"``: ``(N, 2)``
        float64 unit vectors ``(gx, gy) / |g|``; ``"shape"``: ``(h, w)`` as Python ints.

    Raises
    ------
    ValueError
        No pixel exceeds ``threshold`` (an empty model matches nothing), bad arguments.

    Notes
    -----
    §6.0.3. The gradient is ``edges.sobel(template)`` (border ``reflect101``), looked up in
    the registry. The notes extract the control points with an edge detector; a threshold on
    the gradient magnitude keeps the model simple and every point's direction well defined
    (use a higher threshold, or thin the mask, for fewer points).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.zeros((4, 5)); t[:, 3:] = 1.0          # a vertical step, bright on the right
    >>> model = shape_model(t, 2.0)
    >>> model["points"][:3], model["directions"][0], model["shape"]
    (array([[2., 0.],
           [3., 0.],
           [2., 1.]]), array([1., 0.]), (4, 5))
    """
    tpl = as_float_array(template, "template", ndim=2)
    threshold = check_real(threshold, "threshold", nonnegative=True)
    gx, gy = _sobel(tpl)
    mag = np.hypot(gx, gy)
    rows, cols = np.nonzero(mag > threshold)
    if rows.size == 0:
        raise ValueError(
            f"threshold={threshold:g} leaves no control point (largest Sobel magnitude of the template "
            f"is {float(mag.max()):.6g}): lower it"
        )
    m = mag[rows, cols]
    points = np.stack([cols, rows], axis=1).astype(np.float64)
    directions = np.stack([gx[rows, cols] / m, gy[rows, cols] / m], axis=1)
    return {"points": points, "directions": directions, "shape": (int(tpl.shape[0]), int(tpl.shape[1]))}


def _check_model(model: object) -> tuple[np.ndarray, np.ndarray, int, int]:
    if not isinstance(model, dict):
        raise TypeError(f"model must be the dict made by shape_model, got {type(model).__name__}")
    missing = [k for k in ("points", "directions", "shape") if k not in model]
    if missing:
        raise ValueError(f"model must have the keys 'points', 'directions' and 'shape', missing {missing}")
    points = as_float_array(model["points"], "model['points']", ndim=2)
    directions = as_float_array(model["directions"], "model['directions']", ndim=2)
    if points.shape[1] != 2 or directions.shape != points.shape:
        raise ValueError(
            f"model['points'] and model['directions'] must both be (N, 2), got {points.shape} and {directions.shape}"
        )
    shape = model["shape"]
    if not isinstance(shape, (tuple, list, np.ndarray)) or len(shape) != 2:
        raise ValueError(f"model['shape'] must be (h, w), got {shape!r}")
    h, w = (int(v) for v in shape)
    if h < 1 or w < 1:
        raise ValueError(f"model['shape'] must be positive, got {shape!r}")
    if np.any(points != np.round(points)):
        raise ValueError("model['points'] must be whole pixel positions (integers)")
    if np.any(points[:, 0] < 0) or np.any(points[:, 0] >= w) or np.any(points[:, 1] < 0) or np.any(points[:, 1] >= h):
        raise ValueError(f"model['points'] must lie inside the template of shape {(h, w)}")
    return points.astype(np.int64), directions, h, w


@algorithm("detection.shape_match", section="6.0.3", check="cvkit.detection.checks:shape_match")
def shape_match(image: ArrayLike, model: dict, polarity: Literal["none", "global", "local"] = "none") -> np.ndarray:
    """Similarity of the shape model at every placement over ``image``.

    Parameters
    ----------
    image : (H, W) array_like
        Target image, any real dtype, finite values, at least the model's ``shape``.
    model : dict
        From :func:`shape_model`: ``points`` (x, y), unit ``directions``, ``shape`` (h, w).
        Each of its N points is a pass over the placements: ``4·N·(H − h + 1)(W − w + 1)``
        may be at most ``cvkit._validation.MAX_WORK`` (2**36, about a minute; ``ValueError``
        naming ``model``).
    polarity : {"none", "global", "local"}
        ``none``: ``S = (1/n) Σ cos θk`` in [−1, 1]; ``global``: ``|Σ cos θk| / n``, invariant
        to inverting the contrast of the whole object; ``local``: ``Σ |cos θk| / n``, invariant
        to inversions along parts of its contour.

    Returns
    -------
    (H − h + 1, W − w + 1) float64 ndarray
        ``S[i, j]`` with the model's origin (its top-left pixel) at ``(x = j, y = i)``.

    Notes
    -----
    §6.0.3. θk is the angle between the model direction ``dk`` and the image gradient ``g`` at
    ``(j + xk, i + yk)``: ``cos θk = dk · g / |g|``, and 0 where ``g = 0`` (no direction:
    ``|g| <= 1e-10·max|image|``, so that the rounding residue of a Sobel sum over a flat
    region, which depends on the order of the additions, does not count as a direction). The
    image gradient is ``edges.sobel(image)`` (border ``reflect101``) from the registry, so
    only directions matter, not the gradient magnitude: the score does not depend on the
    image's contrast.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.zeros((4, 4)); t[:, 2:] = 1.0
    >>> model = shape_model(t, 2.0)
    >>> img = np.zeros((4, 8)); img[:, 5:] = 1.0
    >>> s = shape_match(img, model)
    >>> s.shape, int(np.argmax(s[0])), float(s.max())
    ((1, 5), 3, 1.0)
    >>> float(shape_match(1 - img, model).min()), float(shape_match(1 - img, model, "global").max())
    (-1.0, 1.0)
    """
    img = as_float_array(image, "image", ndim=2)
    points, directions, h, w = _check_model(model)
    if not isinstance(polarity, str) or polarity not in POLARITIES:
        raise ValueError(f"polarity must be one of {', '.join(map(repr, POLARITIES))}, got {polarity!r}")
    H, W = img.shape
    if h > H or w > W:
        raise ValueError(f"the model's shape {(h, w)} must fit in the image {img.shape}")
    n = points.shape[0]
    ho, wo = H - h + 1, W - w + 1
    if n == 0:
        return np.zeros((ho, wo))
    check_work(4 * n * ho * wo, "model", what=f"{n} control points at {ho}×{wo} placements")
    gx, gy = _sobel(img)
    mag = np.hypot(gx, gy)
    # "no gradient": zero up to the rounding of the Sobel sums (which depends on their order)
    some = mag > NO_GRADIENT * float(np.abs(img).max())
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = np.where(some, gx / mag, 0.0)
        uy = np.where(some, gy / mag, 0.0)
    total = np.zeros((ho, wo))
    term = np.empty((ho, wo))
    for (x, y), (dx, dy) in zip(points, directions):
        np.multiply(ux[y:y + ho, x:x + wo], dx, out=term)
        term += dy * uy[y:y + ho, x:x + wo]
        if polarity == "local":
            np.abs(term, out=term)
        total += term
    if polarity == "global":
        np.abs(total, out=total)
    return total / n
