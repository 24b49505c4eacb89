"""SIFT (§5.10–5.14.1): canonical orientations, the 128-D descriptor and the whole pipeline.

The single-keypoint functions of the catalog (:func:`orientations`, :func:`sift_descriptor`)
and the pipeline (:func:`sift`) share one batch implementation: the samples of many keypoints'
windows are gathered at once and their votes accumulated with ``np.bincount``, in the same order
for one keypoint as for many, so both give bit-identical results. :func:`sift` calls its building
blocks through the registry; when a block is cvkit's own, the batch path replaces the per-keypoint
calls (same results, much faster), otherwise the provider's function is called keypoint by
keypoint — ``with cvkit.use("student"):`` runs the pipeline on a student's pieces.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_allocation, check_bool, check_size, check_work
from ..registry import algorithm, get, implementation
from ._common import check_int, check_real, gray
from ._scale_space import _hessian_trace_det, derivatives_3d, pyramid_arguments

__all__ = ["orientations", "sift_descriptor", "sift", "DESCRIPTOR_RADIUS_FACTOR", "OFFSET_LIMIT", "MAX_BINS",
           "MAX_COORDINATE", "MAX_STEPS", "orientation_histograms", "histogram_peaks", "descriptors_batch"]

#: descriptor window: cells of 3σ, 4×4 cells (+1 for the interpolation), radius 3σ·√2·5/2
DESCRIPTOR_RADIUS_FACTOR = 3.0 * math.sqrt(2.0) * 2.5
_CELLS = 4
_ORIENTATION_BINS = 8
_CLIP = 0.2
_CHUNK = 1 << 16  # grid samples per batch: the temporaries stay in cache (8x faster than 2^21)
#: a refined extremum has converged when every |offset| < 0.6 — Otero & Delbracio, "Anatomy of
#: the SIFT method" (IPOL 2014), as scikit-image; VLFeat also moves only beyond 0.6. With 0.5
#: (OpenCV) an extremum about half-way between two samples is sent back and forth between them
#: until the steps run out, and lost (9 % of the candidates of the astronaut image)
OFFSET_LIMIT = 0.6
#: the most orientation bins (0.1° each)
MAX_BINS = 3600
#: the largest |x|, |y| and σ (pixels) of a keypoint: the window's integer offsets stay exact
MAX_COORDINATE = 1e9
#: the most Newton steps :func:`sift` allows an extremum (each one a pass over the candidates)
MAX_STEPS = 100


def _round(value: ArrayLike) -> np.ndarray:
    """Round to the nearest integer, halves to even: the catalog's ``round`` read as Python's
    ``round`` and ``np.rint`` (and OpenCV's ``cvRound``): round(4.5) = 4, round(13.5) = 14."""
    return np.rint(np.asarray(value, dtype=np.float64)).astype(np.int64)


def _differences(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``dx = L[r, c+1] − L[r, c−1]``, ``dy = L[r+1, c] − L[r−1, c]`` (y down); 0 on the border,
    where the central difference does not exist (those pixels never vote)."""
    dx = np.zeros(image.shape)
    dy = np.zeros(image.shape)
    dx[:, 1:-1] = image[:, 2:] - image[:, :-2]
    dy[1:-1, :] = image[2:, :] - image[:-2, :]
    return dx, dy


def _window_radii(cx: np.ndarray, cy: np.ndarray, radii: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Each window's radius cut to the pixels that can vote (1 ≤ row ≤ H−2, 1 ≤ col ≤ W−2):
    the grid of the smaller radius holds the same samples in the same order (0 when the window
    misses them all), so the work is bounded by the image whatever σ."""
    h, w = shape[0], shape[1]
    lo_x, hi_x = np.maximum(cx - radii, 1), np.minimum(cx + radii, w - 2)
    lo_y, hi_y = np.maximum(cy - radii, 1), np.minimum(cy + radii, h - 2)
    reach = np.maximum(np.maximum(cx - lo_x, hi_x - cx), np.maximum(cy - lo_y, hi_y - cy))
    empty = (lo_x > hi_x) | (lo_y > hi_y)
    return np.where(empty, 0, np.minimum(radii, reach))


def _check_keypoint(x: float, y: float, sigma: float, radius: float, shape: tuple[int, ...]) -> None:
    """Refuse, naming the argument, a keypoint beyond :data:`MAX_COORDINATE` or whose window
    (radius ``radius`` before it is cut to the image) would exceed cvkit's bounds."""
    for value, name in ((x, "x"), (y, "y"), (sigma, "sigma")):
        if abs(value) > MAX_COORDINATE:
            raise ValueError(f"{name} must be at most {MAX_COORDINATE:g} pixels in size, got {value:g}")
    reach = int(_window_radii(_round([x]), _round([y]), _round([radius]), shape)[0])
    samples = (2 * reach + 1) ** 2
    check_allocation((samples,), "sigma", what="the samples of the keypoint's window")
    check_work(40 * samples, "sigma", what=f"a window of radius {reach}")


def _samples(cx: np.ndarray, cy: np.ndarray, radii: np.ndarray, radius: int, shape: tuple[int, ...],
             keep: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pixels of the (2r+1)² squares about the centres (r = each centre's own radius),
    as flat lists ``k, rows, cols`` in raster order per centre, restricted to the pixels where
    both central differences exist (1 ≤ row ≤ H−2, 1 ≤ col ≤ W−2).

    ``keep(k_grid, rows_grid, cols_grid)`` may drop more samples while they are still a
    (K, n) grid (it returns a boolean mask of that shape, or None for no further condition).
    """
    offsets = np.arange(-radius, radius + 1)
    di = np.repeat(offsets, offsets.size)          # row offsets of the (2R+1)² grid, raster order
    dj = np.tile(offsets, offsets.size)
    rows = cy[:, None] + di[None, :]
    cols = cx[:, None] + dj[None, :]
    mask = (rows >= 1) & (rows <= shape[0] - 2) & (cols >= 1) & (cols <= shape[1] - 2)
    if radius > int(radii.min()):
        mask &= (np.abs(di)[None, :] <= radii[:, None]) & (np.abs(dj)[None, :] <= radii[:, None])
    if keep is not None:
        mask &= keep(rows, cols)
    k, n = np.nonzero(mask)
    return k, rows[k, n], cols[k, n]


def _chunks(count: int, per_item: int) -> Iterator[tuple[int, int]]:
    step = max(1, _CHUNK // max(1, per_item))
    for start in range(0, count, step):
        yield start, min(count, start + step)


# --------------------------------------------------------------------------------------------
# §5.11 canonical orientation
# --------------------------------------------------------------------------------------------
def orientation_histograms(dx: np.ndarray, dy: np.ndarray, x: ArrayLike, y: ArrayLike, sigma: ArrayLike,
                           bins: int) -> np.ndarray:
    """(K, bins) histograms of gradient directions, votes = magnitude × Gaussian(1.5σ)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    sigma = np.asarray(sigma, dtype=np.float64)
    count = x.size
    out = np.zeros((count, bins))
    if count == 0:
        return out
    cx, cy = _round(x), _round(y)
    radii = _window_radii(cx, cy, _round(4.5 * sigma), dx.shape)
    big = int(radii.max())
    for start, stop in _chunks(count, (2 * big + 1) ** 2):
        part = slice(start, stop)
        k, r, c = _samples(cx[part], cy[part], radii[part], int(radii[part].max()), dx.shape)
        gx, gy = dx[r, c], dy[r, c]
        ox = c - x[part][k]
        oy = r - y[part][k]
        s_w = 1.5 * sigma[part][k]
        weight = np.sqrt(gx * gx + gy * gy) * np.exp(-(ox * ox + oy * oy) / (2.0 * s_w * s_w))
        index = _round(np.arctan2(gy, gx) * (bins / (2.0 * math.pi))) % bins
        out[part] = np.bincount(k * bins + index, weights=weight, minlength=(stop - start) * bins).reshape(-1, bins)
    return out


def histogram_peaks(histograms: np.ndarray, peak_ratio: float) -> list[np.ndarray]:
    """Orientations of each histogram (a row of ``histograms``): its strict circular maxima
    ≥ peak_ratio·max, refined by the parabola through each and its neighbours, strongest first
    (equal heights: lower bin first). A list of (n_k,) arrays, empty for a flat histogram."""
    h = np.asarray(histograms, dtype=np.float64)
    count, bins = h.shape
    top = h.max(axis=1, initial=0.0)
    left = np.concatenate([h[:, -1:], h[:, :-1]], axis=1)
    right = np.concatenate([h[:, 1:], h[:, :1]], axis=1)
    mask = (h > left) & (h > right) & (h >= peak_ratio * top[:, None]) & (top[:, None] > 0)
    k, b = np.nonzero(mask)
    order = np.lexsort((b, -h[k, b], k))
    k, b = k[order], b[order]
    l, c, r = left[k, b], h[k, b], right[k, b]
    offset = 0.5 * (l - r) / (l - 2.0 * c + r)
    angles = np.mod((b + offset) * (2.0 * math.pi / bins), 2.0 * math.pi)
    angles[angles >= 2.0 * math.pi] = 0.0  # np.mod(−1e-17, 2π) rounds to 2π itself: keep [0, 2π)
    return np.split(angles, np.cumsum(np.bincount(k, minlength=count))[:-1])


@algorithm("features.orientations", section="5.11", check="cvkit.features.checks:orientations")
def orientations(gaussian_image: ArrayLike, x: float, y: float, sigma: float, bins: int = 36,
                 peak_ratio: float = 0.8) -> np.ndarray:
    """Canonical orientations of a keypoint: the peaks of its histogram of gradient directions.

    Parameters
    ----------
    gaussian_image : (H, W) array_like
        The Gaussian-blurred image L of the keypoint's scale (a level of the pyramid).
    x, y : float
        Keypoint position in that image's pixels (x along the columns, y down the rows),
        ``|x|, |y| ≤ 1e9`` (:data:`MAX_COORDINATE`).
    sigma : float
        Keypoint scale in that image's pixels, ``0 < σ ≤ 1e9``. The window is cut to the
        image's pixels (the same votes), and its samples may take at most 2 GiB and
        ``cvkit._validation.MAX_WORK`` operations (``ValueError`` naming ``sigma``).
    bins : int
        Histogram bins over the full circle, 3 ≤ bins ≤ 3600 (:data:`MAX_BINS`; 36: 10° each).
    peak_ratio : float
        Secondary peaks at least this fraction of the highest one also give an orientation.

    Returns
    -------
    (n,) float64 ndarray
        Orientations in [0, 2π), strongest first; empty when the patch is flat.

    Notes
    -----
    §5.11. The window is the (2R+1)² square of pixels about ``(round x, round y)`` with
    ``R = round(4.5σ)`` (OpenCV's 3 × 1.5σ); pixels where a central difference would leave the
    image (the outermost rows and columns) do not vote. Each pixel votes with
    ``m = sqrt(dx² + dy²)``, ``dx = L[r, c+1] − L[r, c−1]``, ``dy = L[r+1, c] − L[r−1, c]``
    (y down), times a Gaussian of σ_w = 1.5σ centred on the *real* (x, y), into the bin
    ``round(θ·bins/2π) mod bins`` of θ = atan2(dy, dx) (bin k is centred on k·2π/bins; no
    splitting between bins and no smoothing of the histogram). Every bin that is a strict
    circular maximum (above both neighbours) and ≥ peak_ratio × the highest bin gives one
    orientation, refined by the parabola through it and its neighbours:
    ``k + ½(h[k−1] − h[k+1]) / (h[k−1] − 2h[k] + h[k+1])`` bins. Every round takes halves to
    even (Python's ``round``, ``np.rint``, OpenCV's ``cvRound``): σ = 1 gives the radius
    round(4.5) = 4. OpenCV's ``calcOrientationHist`` centres the Gaussian
    on the rounded position and smooths the histogram; its angles are measured with y up.

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[0:31, 0:31]
    >>> a = 0.52                                  # a ramp brighter towards 0.52 rad (29.8°)
    >>> ramp = 0.01 * (np.cos(a) * x + np.sin(a) * y)
    >>> np.degrees(orientations(ramp, 15.2, 14.9, 2.0)).round(6)   # one bin: its centre
    array([30.])
    >>> orientations(np.zeros((31, 31)), 15.2, 14.9, 2.0)         # flat: no orientation
    array([], dtype=float64)
    """
    img = gray(gaussian_image, "gaussian_image")
    x = check_real(x, "x")
    y = check_real(y, "y")
    sigma = check_real(sigma, "sigma", positive=True)
    bins = check_size(bins, "bins", minimum=3, maximum=MAX_BINS)
    peak_ratio = check_real(peak_ratio, "peak_ratio", nonnegative=True)
    _check_keypoint(x, y, sigma, 4.5 * sigma, img.shape)
    dx, dy = _differences(img)
    return histogram_peaks(orientation_histograms(dx, dy, [x], [y], [sigma], bins), peak_ratio)[0]


# --------------------------------------------------------------------------------------------
# §5.12 the descriptor
# --------------------------------------------------------------------------------------------
def descriptors_batch(dx: np.ndarray, dy: np.ndarray, x: ArrayLike, y: ArrayLike, sigma: ArrayLike,
                      angle: ArrayLike) -> np.ndarray:
    """(K, 128) SIFT descriptors of keypoints on one image (see :func:`sift_descriptor`)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    sigma = np.asarray(sigma, dtype=np.float64)
    angle = np.asarray(angle, dtype=np.float64)
    count = x.size
    d, n_o = _CELLS, _ORIENTATION_BINS
    out = np.zeros((count, d * d * n_o))
    if count == 0:
        return out
    cx, cy = _round(x), _round(y)
    radii = _window_radii(cx, cy, _round(DESCRIPTOR_RADIUS_FACTOR * sigma), dx.shape)
    cos_t, sin_t = np.cos(angle), np.sin(angle)
    big = int(radii.max())
    size = (d + 2) * (d + 2) * (n_o + 2)  # room for the bins −1 and d (and o + 1) while voting
    h, w = dx.shape
    by_radius = np.argsort(radii, kind="stable")  # chunks of similar windows waste less
    for start, stop in _chunks(count, (2 * big + 1) ** 2):
        part = by_radius[start:stop]
        radius = int(radii[part].max())
        offsets = np.arange(-radius, radius + 1, dtype=np.float64)
        di = np.repeat(offsets, offsets.size)[None, :]   # the (2R+1)² grid in raster order
        dj = np.tile(offsets, offsets.size)[None, :]
        ox = dj + (cx[part] - x[part])[:, None]         # offsets from the real (x, y)
        oy = di + (cy[part] - y[part])[:, None]
        ct, st, width = cos_t[part, None], sin_t[part, None], 3.0 * sigma[part, None]
        c_rot = (ox * ct + oy * st) / width
        r_rot = (oy * ct - ox * st) / width
        del ox, oy
        half = d / 2 - 0.5
        slack = 1e-9  # a little wider than the square: the exact test follows on the samples
        mask = (r_rot > -1 - half - slack) & (r_rot < d - half + slack) & (c_rot > -1 - half - slack) \
            & (c_rot < d - half + slack)
        rows = cy[part, None] + di.astype(np.int64)
        cols = cx[part, None] + dj.astype(np.int64)
        mask &= (rows >= 1) & (rows <= h - 2) & (cols >= 1) & (cols <= w - 2)
        if radius > int(radii[part].min()):
            mask &= (np.abs(di) <= radii[part, None]) & (np.abs(dj) <= radii[part, None])
        k, n = np.nonzero(mask)
        r, c = rows[k, n], cols[k, n]
        c_rot, r_rot = c_rot[k, n], r_rot[k, n]
        rbin = r_rot + half
        cbin = c_rot + half
        inside = (rbin > -1) & (rbin < d) & (cbin > -1) & (cbin < d)
        if not inside.all():
            k, r, c, c_rot, r_rot, rbin, cbin = (v[inside] for v in (k, r, c, c_rot, r_rot, rbin, cbin))
        gx, gy = dx[r, c], dy[r, c]
        magnitude = np.sqrt(gx * gx + gy * gy) * np.exp(-(c_rot * c_rot + r_rot * r_rot) / (2.0 * (d / 2) ** 2))
        obin = np.mod((np.arctan2(gy, gx) - angle[part][k]) * (n_o / (2.0 * math.pi)), n_o)
        r0, c0, o0 = np.floor(rbin), np.floor(cbin), np.floor(obin)
        fr, fc, fo = rbin - r0, cbin - c0, obin - o0
        # bins shifted by one: bin −1 is row 0 of the padded histogram
        base = ((k * (d + 2) + (r0.astype(np.int64) + 1)) * (d + 2) + (c0.astype(np.int64) + 1)) * (n_o + 2) \
            + o0.astype(np.int64) % n_o
        votes_n = k.size
        index = np.empty(8 * votes_n, dtype=np.int64)
        weight = np.empty(8 * votes_n)
        slot = 0
        for a, wa in ((0, 1.0 - fr), (1, fr)):
            v_r = magnitude * wa
            for b, wb in ((0, 1.0 - fc), (1, fc)):
                v_rc = v_r * wb
                for e, we in ((0, 1.0 - fo), (1, fo)):
                    index[slot:slot + votes_n] = base + ((a * (d + 2) + b) * (n_o + 2) + e)
                    np.multiply(v_rc, we, out=weight[slot:slot + votes_n])
                    slot += votes_n
        votes = np.bincount(index, weights=weight, minlength=len(part) * size)
        hist = votes.reshape(len(part), d + 2, d + 2, n_o + 2)
        hist[..., 0] += hist[..., n_o]  # orientation bin n_o is bin 0 (the circle wraps)
        out[part] = hist[:, 1:d + 1, 1:d + 1, :n_o].reshape(len(part), -1)
    norms = np.sqrt(np.einsum("ij,ij->i", out, out))
    flat = norms == 0
    out[~flat] /= norms[~flat, None]
    np.minimum(out, _CLIP, out=out)
    norms = np.sqrt(np.einsum("ij,ij->i", out, out))
    out[~flat] /= norms[~flat, None]
    return out


@algorithm("features.sift_descriptor", section="5.12", check="cvkit.features.checks:sift_descriptor")
def sift_descriptor(gaussian_image: ArrayLike, x: float, y: float, sigma: float, angle: float) -> np.ndarray:
    """The 128-D SIFT descriptor: 4×4 cells × 8 orientation bins of the rotated patch.

    Parameters
    ----------
    gaussian_image : (H, W) array_like
        The Gaussian-blurred image L of the keypoint's scale.
    x, y : float
        Keypoint position in that image's pixels, ``|x|, |y| ≤ 1e9`` (:data:`MAX_COORDINATE`).
    sigma : float
        Keypoint scale in that image's pixels, ``0 < σ ≤ 1e9``. The window is cut to the
        image's pixels (the same votes), and its samples may take at most 2 GiB and
        ``cvkit._validation.MAX_WORK`` operations (``ValueError`` naming ``sigma``).
    angle : float
        The keypoint's canonical orientation in radians (y down, as :func:`orientations`).

    Returns
    -------
    (128,) float64 ndarray
        Unit length (the zero vector when the patch is flat), entries ≥ 0, laid out as
        (cell row, cell column, orientation): index ``(i·4 + j)·8 + o``.

    Notes
    -----
    §5.12–5.12.1 (OpenCV's ``calcSIFTDescriptor``). The patch is read in the keypoint's frame:
    a pixel at offset ``(ox, oy)`` from the *real* (x, y) has frame coordinates
    ``u = (ox cos a + oy sin a) / 3σ`` and ``v = (−ox sin a + oy cos a) / 3σ`` in cells of 3σ
    pixels, and bin coordinates ``col = u + 1.5``, ``row = v + 1.5`` (cell centres at
    0, 1, 2, 3). Samples are the pixels of the square of radius
    ``R = round(3σ·√2·5/2)`` about ``(round x, round y)`` with
    −1 < row, col < 4 whose central differences exist. Each votes ``m·exp(−(u² + v²)/8)``
    (a Gaussian of σ_w = 2 cells), m and θ as in :func:`orientations`, **trilinearly**: split
    between the two nearest cell rows, the two nearest cell columns (bins outside 0..3 are
    dropped) and the two nearest of 8 orientation bins of ``(θ − a)`` (bin o centred on
    o·45°, wrapping around). The vector is normalised to unit length, clipped at 0.2 (so that
    a few large gradients — non-linear lighting — cannot dominate) and normalised again.

    ``θ − a`` is the gradient's direction in the keypoint's frame with this library's angles
    (y down the rows). OpenCV measures its angles with y up, so its bins run the other way:
    its descriptor is this one with each cell's bins reordered ``o → (8 − o) mod 8``
    (after that, median cosine 0.99 between the two on keypoints both find).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> patch = rng.random((41, 41))
    >>> v = sift_descriptor(patch, 20.3, 19.8, 2.0, 0.7)
    >>> v.shape, round(float(np.linalg.norm(v)), 12), bool(v.min() >= 0)
    ((128,), 1.0, True)
    """
    img = gray(gaussian_image, "gaussian_image")
    x = check_real(x, "x")
    y = check_real(y, "y")
    sigma = check_real(sigma, "sigma", positive=True)
    angle = check_real(angle, "angle")
    _check_keypoint(x, y, sigma, DESCRIPTOR_RADIUS_FACTOR * sigma, img.shape)
    dx, dy = _differences(img)
    return descriptors_batch(dx, dy, [x], [y], [sigma], [angle])[0]


# --------------------------------------------------------------------------------------------
# §5.14.1 the pipeline
# --------------------------------------------------------------------------------------------
def _is_reference(algorithm_id: str):
    function = implementation(algorithm_id)
    return function, function is get(algorithm_id).reference


def _refine_all(dog, candidates, scales, border, max_steps, refine):
    """Iterate the Newton step: returns (octave, layer, row, col, offset (3,), value) of every
    candidate that converges inside the octave (|offset| < OFFSET_LIMIT on every axis)."""
    kept = []
    if refine is None:  # the reference: the same arithmetic, vectorised over the candidates
        octaves = candidates[:, 0]
        for o in np.unique(octaves):
            d = dog[o]
            _, h, w = d.shape
            s, r, c = (candidates[octaves == o, i].copy() for i in (1, 2, 3))
            alive = np.ones(s.size, dtype=bool)
            done = np.zeros(s.size, dtype=bool)
            offsets = np.zeros((s.size, 3))
            values = np.zeros(s.size)
            for _ in range(max_steps):
                todo = np.flatnonzero(alive & ~done)
                if todo.size == 0:
                    break
                g, hessian = derivatives_3d(d, s[todo], r[todo], c[todo])
                det = np.linalg.det(hessian)
                singular = ~(det != 0)
                alive[todo[singular]] = False
                todo, g, hessian = todo[~singular], g[~singular], hessian[~singular]
                if todo.size == 0:
                    continue
                x = -np.linalg.solve(hessian, g[..., None])[..., 0]
                finite = np.all(np.isfinite(x), axis=1)
                alive[todo[~finite]] = False
                todo, g, x = todo[finite], g[finite], x[finite]
                small = np.all(np.abs(x) < OFFSET_LIMIT, axis=1)
                offsets[todo] = x
                values[todo] = d[s[todo], r[todo], c[todo]] + 0.5 * (g[:, 0] * x[:, 0] + g[:, 1] * x[:, 1] + g[:, 2] * x[:, 2])
                done[todo[small]] = True
                move = todo[~small]
                step = np.rint(x[~small]).astype(np.int64)
                s[move] += step[:, 0]
                r[move] += step[:, 1]
                c[move] += step[:, 2]
                outside = (s[move] < 1) | (s[move] > scales) | (r[move] < border) | (r[move] >= h - border) \
                    | (c[move] < border) | (c[move] >= w - border)
                alive[move[outside]] = False
            ok = np.flatnonzero(alive & done)
            for i in ok:
                kept.append((int(o), int(s[i]), int(r[i]), int(c[i]), offsets[i], float(values[i])))
        return kept
    for o, s, r, c in candidates.tolist():
        _, h, w = dog[o].shape
        for _ in range(max_steps):
            try:
                x, value = refine(dog[o], s, r, c)
            except ValueError:
                break
            x = np.asarray(x, dtype=np.float64).reshape(3)
            if not np.all(np.isfinite(x)):
                break
            if np.all(np.abs(x) < OFFSET_LIMIT):
                kept.append((o, s, r, c, x, float(value)))
                break
            step = np.rint(x).astype(np.int64)
            s, r, c = s + int(step[0]), r + int(step[1]), c + int(step[2])
            if not (1 <= s <= scales and border <= r < h - border and border <= c < w - border):
                break
    return kept


def _edge_like_batch(d: np.ndarray, r: np.ndarray, c: np.ndarray, ratio: float) -> np.ndarray:
    trace, det = _hessian_trace_det(d, r, c)
    return (det <= 0) | (trace * trace * ratio >= (ratio + 1.0) ** 2 * det)


def _default_octaves(shape: tuple[int, ...]) -> int:
    """As many octaves as keep the smallest octave's shorter side at 8 pixels or more."""
    side = min(shape)
    return max(1, int(math.floor(math.log2(side / 8.0))) + 1) if side >= 8 else 1


@algorithm("features.sift", section="5.14.1", check="cvkit.features.checks:sift")
def sift(image: ArrayLike, sigma0: float = 1.6, scales: int = 3, octaves: int | None = None, upsample: bool = True,
         contrast_threshold: float = 0.04, edge_ratio: float = 10.0, assumed_blur: float = 0.5, border: int = 5,
         max_steps: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """SIFT keypoints and descriptors (Lowe 2004), with OpenCV's defaults.

    Parameters
    ----------
    image : (H, W) array_like
        Grayscale image with values in [0, 1] (the thresholds assume that range).
    sigma0, scales, upsample, assumed_blur
        The scale space, as :func:`gaussian_pyramid` (1.6, 3, True, 0.5), with its bounds
        (checked here, whoever provides the pyramid).
    octaves : int, optional
        Default: as many as keep the smallest octave's shorter side ≥ 8 pixels; at most as
        many as :func:`gaussian_pyramid` allows.
    contrast_threshold : float
        Keypoints need ``|D(x̂)| ≥ contrast_threshold / scales`` (OpenCV's 0.04); candidates
        need ``|D| > 0.5 · contrast_threshold / scales`` first.
    edge_ratio : float
        Largest accepted ratio of principal curvatures (:func:`is_edge_like`, 10).
    border : int
        Extrema closer than this to the border of their octave are ignored (OpenCV's 5).
    max_steps : int
        Newton steps allowed for an extremum to converge (OpenCV's and IPOL's 5), at most 100
        (:data:`MAX_STEPS`).

    Returns
    -------
    keypoints : (N, 4) float64 ndarray
        ``x, y, σ, angle`` in input pixels and radians (angle in [0, 2π), y down); one row
        per orientation.
    descriptors : (N, 128) float64 ndarray
        Unit vectors (:func:`sift_descriptor`).

    Notes
    -----
    §5.14.1, step by step (each through ``implementation(...)``):

    1. ``features.gaussian_pyramid`` and ``features.dog_pyramid``;
    2. ``features.dog_extrema`` with threshold ``0.5·contrast_threshold/scales``, keeping the
       extrema at least ``border`` pixels inside their octave;
    3. ``features.refine_extremum`` repeated: while some |offset| ≥ 0.6 (``OFFSET_LIMIT``),
       move to the sample ``(scale, row, col) + rint(offset)`` and refine again, at most
       ``max_steps`` times; an extremum that leaves scales 1..s or the border, has a singular
       Hessian or does not converge is dropped; two that converge to the same sample are one
       keypoint;
    4. contrast: drop it when ``|D(x̂)| < contrast_threshold / scales``;
    5. edges: drop it when ``features.is_edge_like(dog[o][scale], row, col, edge_ratio)``;
    6. position ``(col + dc, row + dr)`` and scale ``σ0·2^((scale + ds)/s)`` in octave pixels;
       ``features.orientations`` on Gaussian level ``scale`` of the octave;
    7. one ``features.sift_descriptor`` per orientation, on the same level;
    8. back to the input: coordinates and σ times 2^o, halved when upsampled.

    Keypoints are listed by octave, scale, row and column of the converged sample, each
    keypoint's orientations strongest first. OpenCV's ``cv2.SIFT`` follows the same steps on
    a differently interpolated upsampled image (and smooths its orientation histograms), so the
    two find mostly the same keypoints, not exactly the same ones; its descriptors order each
    cell's orientation bins the other way (see :func:`sift_descriptor`).

    Step 3 accepts offsets up to 0.6, not 0.5 (Lowe's "closer to another sample"), as
    Otero & Delbracio's *Anatomy of the SIFT Method* (IPOL 2014) and scikit-image do (VLFeat
    also moves only beyond 0.6): the quadratic fitted at a sample is only an approximation, and
    an extremum about half-way between two samples can look closer to the other one from both
    of them. With 0.5 (OpenCV) such candidates bounce between the two samples until
    ``max_steps`` runs out and are lost — 9 % of the candidates on the astronaut image, and
    repeatable ones: matching it against its 30°, ×0.8 view gives 697 correct matches instead
    of 605 (``benchmarks/bench_ch05.py``).

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[0:48, 0:48]
    >>> img = 0.2 + 0.6 * np.exp(-((x - 23.6) ** 2 + (y - 24.3) ** 2) / (2 * 3.0 ** 2))
    >>> keypoints, descriptors = sift(img)
    >>> keypoints.shape[1], descriptors.shape[1]
    (4, 128)
    >>> best = keypoints[np.argmax(keypoints[:, 2])]      # the blob itself
    >>> best[:2].round(1), round(float(best[2]), 2)       # σ of DoG level i: between σ_i and σ_i+1
    (array([23.6, 24.3]), 2.65)
    """
    img = gray(image)
    contrast = check_real(contrast_threshold, "contrast_threshold", nonnegative=True)
    ratio = check_real(edge_ratio, "edge_ratio", positive=True)
    border = check_int(border, "border", minimum=1)
    max_steps = check_size(max_steps, "max_steps", minimum=1, maximum=MAX_STEPS)
    check_bool(upsample, "upsample")
    if octaves is None:
        octaves = _default_octaves((2 * img.shape[0], 2 * img.shape[1]) if upsample else img.shape)
    sigma0, scales, octaves, _ = pyramid_arguments(img.shape, sigma0, scales, octaves, upsample, assumed_blur)

    pyramid = implementation("features.gaussian_pyramid")(img, sigma0, scales, octaves, upsample, assumed_blur)
    pyramid = [as_float_array(level, "a Gaussian octave", ndim=3) for level in pyramid]
    dog = implementation("features.dog_pyramid")(pyramid)
    dog = [as_float_array(level, "a DoG octave", ndim=3) for level in dog]
    candidates = np.asarray(implementation("features.dog_extrema")(dog, 0.5 * contrast / scales), dtype=np.int64).reshape(-1, 4)
    if candidates.size:
        shapes = np.array([d.shape[1:] for d in dog])[candidates[:, 0]]
        inside = (candidates[:, 2] >= border) & (candidates[:, 2] < shapes[:, 0] - border) \
            & (candidates[:, 3] >= border) & (candidates[:, 3] < shapes[:, 1] - border)
        candidates = candidates[inside]

    refine, reference = _is_reference("features.refine_extremum")
    converged = _refine_all(dog, candidates, scales, border, max_steps, None if reference else refine)
    seen = set()
    points = []
    for o, s, r, c, x, value in sorted(converged, key=lambda item: item[:4]):
        if (o, s, r, c) in seen or abs(value) * scales < contrast:
            continue
        seen.add((o, s, r, c))
        points.append((o, s, r, c, x))

    edge_like, reference = _is_reference("features.is_edge_like")
    if points:
        if reference:
            table = np.array([p[:4] for p in points])
            batch = np.zeros(len(points), dtype=bool)
            for key in {(o, s) for o, s, _, _, _ in points}:
                rows = np.flatnonzero((table[:, 0] == key[0]) & (table[:, 1] == key[1]))
                batch[rows] = _edge_like_batch(dog[key[0]][key[1]], table[rows, 2], table[rows, 3], ratio)
            flags = batch.tolist()
        else:
            flags = [bool(edge_like(dog[o][s], r, c, ratio)) for o, s, r, c, _ in points]
        points = [p for p, flag in zip(points, flags) if not flag]

    orient, orient_reference = _is_reference("features.orientations")
    describe, describe_reference = _is_reference("features.sift_descriptor")
    keypoints, descriptors = [], []
    groups: dict = {}
    for o, s, r, c, x in points:
        groups.setdefault((o, s), []).append((c + x[2], r + x[1], sigma0 * 2.0 ** ((s + x[0]) / scales)))
    factor_of = {o: 2.0 ** o / (2.0 if upsample else 1.0) for o in range(len(pyramid))}
    for (o, s), members in sorted(groups.items()):
        level = pyramid[o][s]
        xs, ys, sigmas = (np.array(v) for v in zip(*members))
        dx, dy = _differences(level)       # (used by the batch paths of cvkit's own blocks)
        if orient_reference:
            angles = histogram_peaks(orientation_histograms(dx, dy, xs, ys, sigmas, 36), 0.8)
        else:
            angles = [np.asarray(orient(level, float(a), float(b), float(sg)), dtype=np.float64).reshape(-1)
                      for a, b, sg in zip(xs, ys, sigmas)]
        counts = np.array([len(a) for a in angles], dtype=np.int64)
        ex, ey, es = (np.repeat(v, counts) for v in (xs, ys, sigmas))
        ea = np.concatenate(angles) if angles else np.zeros(0)
        if describe_reference:
            vectors = descriptors_batch(dx, dy, ex, ey, es, ea)
        else:
            vectors = np.array([np.asarray(describe(level, float(a), float(b), float(sg), float(t)), dtype=np.float64).reshape(128)
                                for a, b, sg, t in zip(ex, ey, es, ea)]).reshape(-1, 128)
        f = factor_of[o]
        keypoints.append(np.stack([ex * f, ey * f, es * f, np.mod(ea, 2.0 * math.pi)], axis=1))
        descriptors.append(vectors)
    if not keypoints:
        return np.zeros((0, 4)), np.zeros((0, 128))
    return np.concatenate(keypoints).reshape(-1, 4), np.concatenate(descriptors).reshape(-1, 128)
