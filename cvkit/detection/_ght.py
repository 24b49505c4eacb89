"""The Generalized Hough Transform (§6.0.6–6.0.7): detect an arbitrary shape by letting every
edge pixel vote for the position of the object's reference point.

Off-line, the R-table stores, for each quantised gradient direction φ, the vectors
``r = reference − p`` from the model's edge pixels p of that direction to the reference point.
On-line, each edge pixel x of the image with direction φ looks up the row of φ and votes at
``x + r`` for every vector of it; to allow a similarity transform the vectors are rotated and
scaled, ``r' = s·R(a)·r``, and the row is the one of ``φ − a``, which fills a 4-D accumulator
(scale, angle, y, x). Vectorised: one ``np.bincount`` over all the votes of a (scale, angle)
pair, built by broadcasting the image's edge pixels of each R-table row against its vectors.
"""
from __future__ import annotations

import math

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .._validation import MAX_ARRAY_BYTES, MAX_WORK, as_float_array, check_size
from ..registry import algorithm, implementation
from ._shape import _sobel

__all__ = ["ght_build", "ght_detect", "MAX_BINS"]

#: the most direction bins of an R-table (0.1° each)
MAX_BINS = 3600
_FLUSH = 1 << 24  # votes gathered before they are added to the accumulator (at least its size)


def _direction_bins(gx: np.ndarray, gy: np.ndarray, bins: int, angle: float = 0.0) -> np.ndarray:
    """round((atan2(gy, gx) − angle) / (2π / bins)) mod bins, rounding as np.round."""
    phi = np.arctan2(gy, gx) - angle
    return np.round(phi / (2 * math.pi / bins)).astype(np.int64) % bins


@algorithm("detection.ght_build", section="6.0.6", check="cvkit.detection.checks:ght_build")
def ght_build(template_edges: ArrayLike, template_image: ArrayLike, bins: int = 36,
              reference: Sequence[float] | np.ndarray | None = None) -> dict:
    """The R-table of a shape: displacement vectors to the reference point, by gradient direction.

    Parameters
    ----------
    template_edges : (h, w) array_like
        Edge map of the model (bool or numeric): its nonzero pixels are the border points.
    template_image : (h, w) array_like
        The model image, for the gradient directions (finite values).
    bins : int
        Number of direction bins over the full circle, ``1 <= bins <= 3600`` (:data:`MAX_BINS`;
        step Δφ = 2π / bins).
    reference : (x, y) or None
        The reference point; ``None``: the barycentre (mean x, mean y) of the edge pixels.

    Returns
    -------
    dict
        ``"bins"``: int; ``"reference"``: ``(x, y)`` as a tuple of two floats; ``"table"``: a
        list of ``bins`` float64 arrays, entry k of shape ``(n_k, 2)`` holding the vectors
        ``r = reference − p`` (x, y components) of the edge pixels p whose direction falls in
        bin k, in raster order of p (``(0, 2)`` for an empty bin).

    Raises
    ------
    ValueError
        No edge pixel, shapes that differ, bad arguments.

    Notes
    -----
    §6.0.6. The direction of p is ``φ = atan2(gy, gx)`` with ``(gx, gy) = edges.sobel(template_image)``
    (border ``reflect101``, from the registry), and its bin is ``round(φ / Δφ) mod bins``
    with ``round`` as ``np.round`` (exact halves to even: with 36 bins a 45° gradient,
    φ/Δφ = 4.5, goes to bin 4). Bin k therefore collects the directions within Δφ/2 of k·Δφ.
    The R-table is the whole model: the reference point need not lie on the shape.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.zeros((5, 6)); t[:, 3:] = 1.0            # a vertical step, gradient along +x
    >>> e = np.zeros((5, 6), bool); e[1:4, 3] = True
    >>> table = ght_build(e, t, bins=4)
    >>> table["reference"], [len(r) for r in table["table"]]
    ((3.0, 2.0), [3, 0, 0, 0])
    >>> table["table"][0]
    array([[ 0.,  1.],
           [ 0.,  0.],
           [ 0., -1.]])
    """
    edges = as_float_array(template_edges, "template_edges", ndim=2)
    img = as_float_array(template_image, "template_image", ndim=2)
    if edges.shape != img.shape:
        raise ValueError(f"template_edges and template_image must have the same shape, got {edges.shape} and {img.shape}")
    bins = check_size(bins, "bins", maximum=MAX_BINS)
    rows, cols = np.nonzero(edges)
    if rows.size == 0:
        raise ValueError("template_edges has no edge pixel: the R-table would be empty")
    points = np.stack([cols, rows], axis=1).astype(np.float64)
    if reference is None:
        ref = (float(points[:, 0].mean()), float(points[:, 1].mean()))
    else:
        if not isinstance(reference, (tuple, list, np.ndarray)) or len(reference) != 2:
            raise ValueError(f"reference must be a pair (x, y) or None, got {reference!r}")
        ref = (float(reference[0]), float(reference[1]))
        if not all(math.isfinite(v) for v in ref):
            raise ValueError(f"reference must be finite, got {reference!r}")
    gx, gy = _sobel(img)
    index = _direction_bins(gx[rows, cols], gy[rows, cols], bins)
    r = np.array(ref)[None, :] - points
    table = [r[index == k].copy() for k in range(bins)]
    return {"bins": bins, "reference": ref, "table": table}


def _check_rtable(rtable: object) -> tuple[int, list[np.ndarray]]:
    if not isinstance(rtable, dict):
        raise TypeError(f"rtable must be the dict made by ght_build, got {type(rtable).__name__}")
    if "bins" not in rtable or "table" not in rtable:
        raise ValueError("rtable must have the keys 'bins' and 'table'")
    bins = check_size(rtable["bins"], "rtable['bins']", maximum=MAX_BINS)
    table = rtable["table"]
    if not isinstance(table, (list, tuple)) or len(table) != bins:
        raise ValueError(f"rtable['table'] must be a list of rtable['bins'] = {bins} arrays")
    rows = []
    for k, entry in enumerate(table):
        a = as_float_array(entry, f"rtable['table'][{k}]", allow_empty=True)
        if a.size == 0:
            a = a.reshape(0, 2)
        if a.ndim != 2 or a.shape[1] != 2:
            raise ValueError(f"rtable['table'][{k}] must be an (n, 2) array, got shape {a.shape}")
        rows.append(a)
    return bins, rows


def _values(values: ArrayLike, name: str) -> np.ndarray:
    arr = as_float_array(values, name, ndim=1)
    return arr


@algorithm("detection.ght_detect", section="6.0.6–6.0.7", check="cvkit.detection.checks:ght_detect")
def ght_detect(image: ArrayLike, rtable: dict, scales: ArrayLike = (1.0,), angles: ArrayLike = (0.0,),
               edge_params: dict | None = None) -> tuple[np.ndarray, tuple[int, int, float, float]]:
    """Vote for the reference point of the R-table's shape over positions, scales and angles.

    Parameters
    ----------
    image : (H, W) array_like
        Target image, finite values.
    rtable : dict
        From :func:`ght_build` (``"bins"`` and ``"table"`` are used).
    scales : sequence of float
        Scales s to try (> 0).
    angles : sequence of float
        Rotations a to try, radians (y down: a positive angle turns clockwise on screen).
    edge_params : dict or None
        Keyword arguments of ``edges.canny`` (default: its defaults); an error of ``canny``
        about them is raised again naming ``edge_params``.

        Bounds: the accumulator, S·A·H·W floats, may take at most 2 GiB, and the voting
        — about ``10·S·A·n·m / bins`` operations for n edge pixels and an R-table of m
        vectors, plus a Python step per (angle, bin) — at most ``cvkit._validation.MAX_WORK``
        (2**36, about a minute); otherwise ``ValueError`` naming ``scales`` and ``angles``.

    Returns
    -------
    accumulator : (S, A, H, W) float64 ndarray
        ``accumulator[i, j, y, x]``: the votes for the reference point at ``(x, y)`` with scale
        ``scales[i]`` and angle ``angles[j]``.
    best : tuple ``(x, y, scale, angle)``
        The first maximum of the accumulator in C order (smallest scale index, then angle
        index, then y, then x), x and y as Python ints, scale and angle as floats.

    Notes
    -----
    §6.0.6–6.0.7. Edge pixels: ``edges.canny(image, **edge_params)``; directions:
    ``φ = atan2(gy, gx)`` with ``(gx, gy) = edges.sobel(image)`` (the same operator as the
    model's; both from the registry). For each scale s and angle a, an edge pixel
    ``x = (col, row)`` with direction φ reads the R-table row ``round((φ − a) / Δφ) mod bins``
    (a rotated object's gradients are turned by a) and votes at ``round(x + s·R(a)·r)`` for
    each vector r of the row, ``R(a) = [[cos a, −sin a], [sin a, cos a]]`` acting on (x, y);
    ``round`` is ``np.round`` (halves to even), like the R-table's bins. Votes that fall
    outside the image are dropped. Memory: S·A·H·W floats.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.zeros((13, 13)); t[3:10, 3:10] = 1.0                 # a bright square
    >>> from cvkit.edges import canny
    >>> table = ght_build(canny(t, 1.0), t, bins=8)
    >>> img = np.zeros((24, 30)); img[10:17, 17:24] = 1.0             # moved by (14, 7)
    >>> acc, best = ght_detect(img, table, edge_params={"sigma": 1.0})
    >>> table["reference"], acc.shape, best
    ((6.0, 6.0), (1, 1, 24, 30), (20, 13, 1.0, 0.0))
    """
    img = as_float_array(image, "image", ndim=2)
    bins, rows_of = _check_rtable(rtable)
    s_values = _values(scales, "scales")
    a_values = _values(angles, "angles")
    if np.any(s_values <= 0):
        raise ValueError(f"scales must be > 0, got {s_values}")
    if edge_params is None:
        edge_params = {}
    if not isinstance(edge_params, dict):
        raise TypeError(f"edge_params must be a dict of edges.canny keyword arguments or None, got {type(edge_params).__name__}")
    H, W = img.shape
    S, A = s_values.size, a_values.size
    size = S * A * H * W
    if 8 * size > MAX_ARRAY_BYTES:
        raise ValueError(
            f"scales and angles ask for an accumulator of shape {(S, A, H, W)} ({8 * size / 1024**3:.3g} GiB), more "
            f"than the {MAX_ARRAY_BYTES / 1024**3:g} GiB cvkit allows for one array; use fewer scales and angles")
    try:
        edge_map = np.asarray(implementation("edges.canny")(img, **edge_params), dtype=bool)
    except (TypeError, ValueError) as error:
        raise type(error)(f"edge_params: edges.canny refused them: {error}") from error
    gx, gy = _sobel(img)
    ey, ex = np.nonzero(edge_map)
    vectors = sum(r.shape[0] for r in rows_of)
    work = 10 * S * A * ey.size * vectors // bins + 2000 * A * bins + 5 * A * ey.size
    if work > MAX_WORK:
        raise ValueError(
            f"scales and angles: voting with {S} scales and {A} angles ({ey.size} edge pixels, {vectors} R-table "
            f"vectors) needs about {work:.2g} elementary operations, more than the {MAX_WORK:.2g} (about a minute "
            f"of work) cvkit allows for one call; use fewer scales and angles")
    counts = np.zeros(size, dtype=np.int64)
    if ey.size:
        px = ex.astype(np.float64)
        py = ey.astype(np.float64)
        gxe, gye = gx[ey, ex], gy[ey, ex]
        chunks: list[np.ndarray] = []
        pending = 0
        layer = np.arange(S, dtype=np.int64)[None, :, None] * (A * H * W)
        for j, a in enumerate(a_values):
            c, s_ = math.cos(a), math.sin(a)
            which = _direction_bins(gxe, gye, bins, a)
            order = np.argsort(which, kind="stable")
            starts = np.searchsorted(which[order], np.arange(bins + 1))
            for k in range(bins):
                r = rows_of[k]
                members = order[starts[k]:starts[k + 1]]
                if r.shape[0] == 0 or members.size == 0:
                    continue
                rx = c * r[:, 0] - s_ * r[:, 1]      # R(a)·r
                ry = s_ * r[:, 0] + c * r[:, 1]
                # votes of every member for every vector at every scale: (members, S, n_k)
                vx = np.round(px[members, None, None] + s_values[None, :, None] * rx[None, None, :]).astype(np.int64)
                vy = np.round(py[members, None, None] + s_values[None, :, None] * ry[None, None, :]).astype(np.int64)
                inside = (vx >= 0) & (vx < W) & (vy >= 0) & (vy < H)
                flat = layer + (j * H + vy) * W + vx
                chunks.append(flat[inside])
                pending += chunks[-1].size
                if pending >= max(_FLUSH, size):   # bounded memory; the counts are exact integers
                    counts += np.bincount(np.concatenate(chunks), minlength=size)
                    chunks, pending = [], 0
        if chunks:
            counts += np.bincount(np.concatenate(chunks), minlength=size)
    acc = counts.astype(np.float64).reshape(S, A, H, W)
    flat = int(np.argmax(acc))
    best = np.unravel_index(flat, acc.shape)
    return acc, (int(best[3]), int(best[2]), float(s_values[best[0]]), float(a_values[best[1]]))
