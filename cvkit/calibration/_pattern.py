"""The calibration pattern (§8.3): the chessboard's world points and its inner corners found
in an image, to sub-pixel accuracy and in the order of the world points."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from .._docstrings import filler
from .._validation import as_float_array, as_image, check_allocation, check_int, check_real, check_work
from ..registry import algorithm, implementation

__all__ = ["chessboard_points", "chessboard_response", "corner_candidates", "grow_grid", "order_grid_corners",
           "refine_corners", "find_chessboard_corners"]

# the start of the doctests: a camera A that sees a 4 × 3 board face on, rendered at 96 × 128
_BOARD_CAMERA = (">>> import numpy as np\n"
                 "    >>> from cvkit.data import render_chessboard\n"
                 "    >>> A = np.array([[200.0, 0, 64], [0, 200, 48], [0, 0, 1]])")
_docs = filler({
    "board_camera": _BOARD_CAMERA,
    "board": _BOARD_CAMERA + ("\n    >>> img = render_chessboard(A, np.eye(3), [-15.0, -10.0, 200.0], cols=4, rows=3, "
                              "square_size=10.0,\n    ...                         image_size=(96, 128))"),
})

_LUMA = np.array([0.299, 0.587, 0.114])


@algorithm("calibration.chessboard_points", section="8.3", check="cvkit.calibration.checks:chessboard_points")
def chessboard_points(cols: int, rows: int, square_size: float) -> np.ndarray:
    """World coordinates of the inner corners of a chessboard, in its own reference frame.

    Parameters
    ----------
    cols : int
        Inner corners along a row of the board (the board has ``cols + 1`` squares across), ≥ 1.
    rows : int
        Inner corners along a column (``rows + 1`` squares down), ≥ 1. The result, (cols·rows, 3)
        floats, may take at most 2 GiB (``ValueError`` naming ``cols × rows``).
    square_size : float
        Side of a square (> 0), in the unit the calibration should use (mm, m, ...).

    Returns
    -------
    (cols·rows, 3) float64 ndarray
        Point ``r·cols + c`` is ``(c·square_size, r·square_size, 0)``: row by row from the
        origin corner, x varying fastest.

    Raises
    ------
    ValueError, TypeError
        Non-integer or non-positive counts, a non-positive or non-finite square size.

    Notes
    -----
    §8.3: the world reference frame is attached to the pattern — origin at a corner, x and y
    along the sides of the squares, and the board is the plane z_W = 0 — so the world
    coordinates of every corner follow from the square size alone. This is OpenCV's order
    (``np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square_size``), the order in which
    :func:`find_chessboard_corners` returns the image points.

    Examples
    --------
    >>> chessboard_points(3, 2, 25.0)
    array([[ 0.,  0.,  0.],
           [25.,  0.,  0.],
           [50.,  0.,  0.],
           [ 0., 25.,  0.],
           [25., 25.,  0.],
           [50., 25.,  0.]])
    """
    cols = check_int(cols, "cols", minimum=1)
    rows = check_int(rows, "rows", minimum=1)
    size = check_real(square_size, "square_size", positive=True)
    check_allocation((cols * rows, 3), "cols × rows", what="the corners")
    j, i = np.mgrid[0:rows, 0:cols]
    return np.column_stack([i.ravel() * size, j.ravel() * size, np.zeros(cols * rows)])


# --------------------------------------------------------------------------------------------
# corner detection
# --------------------------------------------------------------------------------------------
def _derivatives(S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Central differences of a smoothed image, 0 on the outer ring of pixels, as two
    3-channel images: (gx, gy, 0) and (gxx, gxy, gyy)."""
    H, W = S.shape
    first = np.zeros((H, W, 3))
    second = np.zeros((H, W, 3))
    np.subtract(S[:, 2:], S[:, :-2], out=first[:, 1:-1, 0])
    np.subtract(S[2:, :], S[:-2, :], out=first[1:-1, :, 1])
    first[..., :2] *= 0.5
    second[:, 1:-1, 0] = S[:, 2:] + S[:, :-2] - 2.0 * S[:, 1:-1]
    second[1:-1, 1:-1, 1] = 0.25 * (S[2:, 2:] - S[2:, :-2] - S[:-2, 2:] + S[:-2, :-2])
    second[1:-1, :, 2] = S[2:, :] + S[:-2, :] - 2.0 * S[1:-1, :]
    return first, second


def _local_maxima(response: np.ndarray, radius: int) -> np.ndarray:
    """Mask of pixels that are the maximum of their (2r+1)² window (ties kept) and > 0."""
    H, W = response.shape
    padded = np.full((H, W + 2 * radius), -np.inf)
    padded[:, radius:radius + W] = response
    rows = padded[:, 0:W].copy()
    for dx in range(1, 2 * radius + 1):       # separable maximum: loops over offsets, not pixels
        np.maximum(rows, padded[:, dx:dx + W], out=rows)
    padded = np.full((H + 2 * radius, W), -np.inf)
    padded[radius:radius + H] = rows
    best = padded[0:H].copy()
    for dy in range(1, 2 * radius + 1):
        np.maximum(best, padded[dy:dy + H], out=best)
    return (response >= best) & (response > 0)


def _saddle_refine(points: np.ndarray, derivatives: tuple[np.ndarray, np.ndarray], iterations: int, max_shift: float,
                   offset: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Newton's method for the saddle point (zero gradient) of the smoothed image near each point.

    ``derivatives`` are those of :func:`_derivatives`, possibly of a crop whose top-left pixel
    is at ``offset`` (x, y) of the image. Returns the refined points and a mask of those that
    stayed on a saddle within ``max_shift`` pixels of where they started.
    """
    sample = implementation("warp.bilinear_sample")
    first, second = derivatives
    q = points - np.asarray(offset, dtype=np.float64)
    start = q.copy()
    ok = np.ones(len(q), dtype=bool)
    for _ in range(iterations):
        x, y = q[:, 0], q[:, 1]
        g = sample(first, x, y, fill=np.nan)
        h = sample(second, x, y, fill=np.nan)
        a, b, c = h[:, 0], h[:, 1], h[:, 2]
        det = a * c - b * b
        saddle = det < 0                      # NaN (outside) is not a saddle
        with np.errstate(divide="ignore", invalid="ignore"):
            dx = np.where(saddle, (c * g[:, 0] - b * g[:, 1]) / det, 0.0)
            dy = np.where(saddle, (a * g[:, 1] - b * g[:, 0]) / det, 0.0)
        step = np.hypot(dx, dy)
        scale = np.where(step > 0.5, 0.5 / np.maximum(step, 1e-300), 1.0)   # damped: at most ½ px a step
        q[:, 0] -= dx * scale
        q[:, 1] -= dy * scale
        ok &= saddle
    ok &= np.hypot(*(q - start).T) <= max_shift
    return q + np.asarray(offset, dtype=np.float64), ok


def _edge_directions(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The two directions along which the quadratic form [[a, b], [b, c]] (a saddle) vanishes:
    the edges of the X-junction. Shape (n, 2, 2): [point, direction, (x, y)]."""
    H = np.stack([np.stack([a, b], -1), np.stack([b, c], -1)], -2)
    values, vectors = np.linalg.eigh(H)            # ascending: values[:, 0] < 0 < values[:, 1]
    ratio = np.sqrt(np.clip(values[:, 1] / np.maximum(-values[:, 0], 1e-300), 0.0, 1e12))
    directions = []
    for sign in (1.0, -1.0):
        d = vectors[:, :, 1] + sign * ratio[:, None] * vectors[:, :, 0]   # λ1·1² + λ0·ratio² = 0
        directions.append(d / np.linalg.norm(d, axis=1, keepdims=True))
    return np.stack(directions, axis=1)


def _ring_sign_changes(S: np.ndarray, points: np.ndarray, radius: float,
                       samples: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """How often the smoothed image crosses its ring mean on a circle around each point, and
    the ring's contrast. An X-junction crosses 4 times, an L-corner or an edge twice."""
    angles = 2 * np.pi * np.arange(samples) / samples
    x = points[:, 0:1] + radius * np.cos(angles)
    y = points[:, 1:2] + radius * np.sin(angles)
    ring = implementation("warp.bilinear_sample")(S, x, y, fill=np.nan)
    deviation = ring - np.nanmean(ring, axis=1, keepdims=True)
    contrast = np.nanmax(ring, axis=1) - np.nanmin(ring, axis=1)
    strong = np.abs(deviation) >= 0.2 * np.nanmax(np.abs(deviation), axis=1, keepdims=True)
    signs = np.where(strong, np.sign(deviation), 0.0)
    changes = np.zeros(len(points), dtype=int)
    for i in range(len(points)):              # a loop over candidates (tens), not pixels
        s = signs[i][signs[i] != 0]
        if s.size:
            changes[i] = int(np.count_nonzero(s != np.roll(s, 1)))
    valid = ~np.any(np.isnan(ring), axis=1)
    return np.where(valid, changes, 0), np.where(valid, contrast, 0.0)


def _grow_grid(seed: int, points: np.ndarray, directions: np.ndarray, prune: bool = True,
               parallelogram: bool = True,
               visit: Callable[[int], int] | None = None) -> dict[tuple[int, int], int] | None:
    """Assign grid indices (i, j) to candidates, growing from ``seed`` along the (unit) edge
    directions. The keyword arguments exist for the check only: its mistakes, and ``visit``
    (the position in the queue of the next node to visit; default the last) to draw cases whose
    grid does not depend on the order in which the nodes are visited."""
    d = points - points[seed]
    dist = np.hypot(d[:, 0], d[:, 1])
    dist[seed] = np.inf
    grid = {(0, 0): seed}
    used = {seed}
    for axis in range(2):
        for sign in (1, -1):
            u = sign * directions[seed, axis]
            with np.errstate(invalid="ignore", divide="ignore"):
                cosine = (d @ u) / dist
            ok = (cosine > np.cos(np.deg2rad(20))) & np.isfinite(dist)
            if ok.any():
                best = int(np.argmin(np.where(ok, dist, np.inf)))
                key = (sign, 0) if axis == 0 else (0, sign)
                if best not in used:
                    grid[key] = best
                    used.add(best)
    if not any(k in grid for k in ((1, 0), (-1, 0))) or not any(k in grid for k in ((0, 1), (0, -1))):
        return None
    steps = ((1, 0), (-1, 0), (0, 1), (0, -1))
    queue = list(grid)
    # the nodes' positions as Python floats and a mask of the used candidates: the same
    # arithmetic as with rows of `points`, without a NumPy call per coordinate
    xy = points.tolist()
    xs, ys = points[:, 0], points[:, 1]
    taken = np.zeros(len(points), dtype=bool)
    taken[list(used)] = True
    while queue:                                  # a loop over grid nodes (tens), not pixels
        i, j = queue.pop() if visit is None else queue.pop(visit(len(queue)))
        for di, dj in steps:
            target = (i + di, j + dj)
            if target in grid:
                continue
            hx, hy = xy[grid[(i, j)]]
            if (i - di, j - dj) in grid:                       # continue the line
                bx, by = xy[grid[(i - di, j - dj)]]
                px, py, step = 2 * hx - bx, 2 * hy - by, np.hypot(hx - bx, hy - by)
            elif not parallelogram:
                continue
            else:                                              # complete a parallelogram
                found = False
                for ei, ej in ((dj, di), (-dj, -di)):
                    side, diagonal = (i + ei, j + ej), (i + di + ei, j + dj + ej)
                    if side in grid and diagonal in grid:
                        (sx, sy), (gx, gy) = xy[grid[side]], xy[grid[diagonal]]
                        px, py, step = hx + gx - sx, hy + gy - sy, np.hypot(gx - sx, gy - sy)
                        found = True
                        break
                if not found:
                    continue
            gap = np.hypot(xs - px, ys - py)
            gap[taken] = np.inf
            best = int(gap.argmin())
            if gap[best] <= 0.35 * step:
                grid[target] = best
                used.add(best)
                taken[best] = True
                ti, tj = target
                queue.append(target)
                queue.extend(k for k in ((ti + 1, tj), (ti - 1, tj), (ti, tj + 1), (ti, tj - 1)) if k in grid)
    # a stray candidate stuck to the side of the board has a single neighbour: drop such
    # nodes (a true extra row of corners keeps two or more and is not dropped)
    while prune:
        lonely = [(i, j) for i, j in grid
                  if ((i + 1, j) in grid) + ((i - 1, j) in grid) + ((i, j + 1) in grid) + ((i, j - 1) in grid) <= 1]
        if not lonely or len(lonely) == len(grid):
            break
        for key in lonely:
            del grid[key]
    return grid


def _ordered(grid: dict[tuple[int, int], int], points: np.ndarray, cols: int, rows: int) -> np.ndarray | None:
    """The grid as (rows, cols, 2) in the catalog's order, or None if it is not cols × rows."""
    keys = np.array(list(grid))
    i0, j0 = keys.min(axis=0)
    ni, nj = keys.max(axis=0) - keys.min(axis=0) + 1
    if ni * nj != len(grid) or sorted((int(ni), int(nj))) != sorted((cols, rows)):
        return None
    G = np.empty((ni, nj, 2))
    for (i, j), index in grid.items():
        G[i - i0, j - j0] = points[index]
    options = []
    for base in ((G.transpose(1, 0, 2),) if ni == cols else ()) + ((G,) if nj == cols else ()):
        # base[r, c]: c along the axis with `cols` corners
        for flip_r in (False, True):
            for flip_c in (False, True):
                P = base[::-1 if flip_r else 1, ::-1 if flip_c else 1]
                dx, dy = P[0, -1] - P[0, 0], P[-1, 0] - P[0, 0]
                if dx[0] * dy[1] - dx[1] * dy[0] > 0:               # right-handed in the image
                    options.append(P)
    if not options:
        return None
    best = min(options, key=lambda P: float(np.hypot(*P[0, 0])))   # origin nearest the top-left
    return best.reshape(-1, 2)




def _grey01(img: np.ndarray) -> np.ndarray:
    """Grey (luma) image rescaled to [0, 1]; zeros for a constant image."""
    grey = img @ _LUMA if img.ndim == 3 else img
    low, high = float(grey.min()), float(grey.max())
    if high - low <= 1e-12 * max(1.0, abs(high)):
        return np.zeros(grey.shape)
    return (grey - low) / (high - low)


def _hessian_map(S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Second differences of S (I_xx, I_xy, I_yy), 0 where a neighbour is missing."""
    gxx = np.zeros_like(S)
    gyy = np.zeros_like(S)
    gxy = np.zeros_like(S)
    gxx[:, 1:-1] = S[:, 2:] + S[:, :-2] - 2.0 * S[:, 1:-1]
    gyy[1:-1, :] = S[2:, :] + S[:-2, :] - 2.0 * S[1:-1, :]
    gxy[1:-1, 1:-1] = 0.25 * (S[2:, 2:] - S[2:, :-2] - S[:-2, 2:] + S[:-2, :-2])
    return gxx, gxy, gyy


@algorithm("calibration.chessboard_response", section="8.3",
           check="cvkit.calibration.checks:chessboard_response")
def chessboard_response(image: ArrayLike, sigma: float = 1.5) -> np.ndarray:
    """Saddle response of an image: large and positive at the X-junctions of a chessboard.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Grey or RGB image, any real dtype and intensity range.
    sigma : float, optional
        Standard deviation (pixels, > 0) of the Gaussian smoothing.

    Returns
    -------
    (H, W) float64 ndarray
        :math:`s = I_{xy}^2 - I_{xx} I_{yy}` (minus the determinant of the Hessian) of
        ``S = filters.gaussian(grey, sigma)``, where grey = 0.299 R + 0.587 G + 0.114 B rescaled
        to [0, 1] (all zeros for a constant image). The second derivatives are the central
        differences ``I_xx = S[y, x+1] − 2 S[y, x] + S[y, x−1]``, ``I_yy`` likewise along the
        rows, ``I_xy = (S[y+1, x+1] − S[y+1, x−1] − S[y−1, x+1] + S[y−1, x−1]) / 4``; the response
        is 0 on the outermost rows and columns, where a neighbour is missing.

    Raises
    ------
    ValueError, TypeError
        A malformed image or a non-positive sigma.

    Notes
    -----
    §8.3: around an X-junction the smoothed intensity curves up along one direction and down
    along the other (a saddle: Hessian eigenvalues of opposite signs), so ``s`` is positive
    there; at an L-shaped corner of the board's outline it is about 4 times smaller, on an
    edge or a flat area about 0.

    Examples
    --------
    >>> import numpy as np
    >>> board = np.kron([[0, 1], [1, 0]], np.ones((8, 8)))     # one X-junction at (7.5, 7.5)
    >>> s = chessboard_response(board, 1.5)
    >>> tuple(int(v) for v in np.unravel_index(np.argmax(s), s.shape))
    (7, 7)
    """
    img = as_image(image)
    sigma = check_real(sigma, "sigma", positive=True)
    grey = _grey01(img)
    S = implementation("filters.gaussian")(grey, sigma)
    gxx, gxy, gyy = _hessian_map(S)
    return gxy * gxy - gxx * gyy


@algorithm("calibration.corner_candidates", section="8.3",
           check="cvkit.calibration.checks:corner_candidates")
@_docs
def corner_candidates(image: ArrayLike, count: int, sigma: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
    """Candidate X-junctions of an image (integer pixels), with their two edge directions.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Grey or RGB image, any real dtype and intensity range.
    count : int
        The number of corners expected (cols·rows of the board, ≥ 1): it sets the typical
        response of a corner, to which the weak maxima are compared.
    sigma : float, optional
        The smoothing of :func:`chessboard_response`.

    Returns
    -------
    points : (K, 2) float64 ndarray
        Pixel positions ``(x, y)`` (integer values) of the candidates, strongest response first.
    directions : (K, 2, 2) float64 ndarray
        ``directions[i]`` holds the two unit vectors ``(dx, dy)`` of the edges crossing at
        candidate i: the directions along which the Hessian's quadratic form vanishes.

    Raises
    ------
    ValueError, TypeError
        A malformed image, count or sigma.

    Notes
    -----
    1. The local maxima of ``chessboard_response(image, sigma)`` in 5 × 5 windows (ties
       kept), with the 5 outermost rows and columns of the response set to 0 first, and above
       1e-3 of the maximal response.
    2. The typical corner response is the median of the ``count`` strongest maxima; maxima
       weaker than 5 % of it are dropped, and at most ``4·count + 50`` strongest are kept.
    3. The ring test: the smoothed grey image S is read (bilinearly) at 32 points of a circle
       of radius 3 px around each candidate; samples deviating from the ring's mean by at least
       20 % of the largest deviation vote with their sign. An X-junction gives exactly 4 sign
       changes around the ring (an L-corner or an edge 2) and a ring contrast (max − min) of at
       least 0.15; a ring reaching outside the image fails.
    4. With the Hessian [[a, b], [b, c]] of S at the candidate (eigenvalues λ0 < 0 < λ1,
       eigenvectors e0, e1), the edge directions are e1 ± √(λ1/−λ0)·e0, normalised.

    Examples
    --------
    %(board)s
    >>> points, directions = corner_candidates(img, 12)
    >>> len(points), points[0]                       # the 12 inner corners, on whole pixels here
    (12, array([59., 38.]))
    >>> np.abs(directions[0])                        # the board is seen face on: edges along y and x
    array([[0., 1.],
           [1., 0.]])
    """
    img = as_image(image)
    count = check_int(count, "count", minimum=1)
    sigma = check_real(sigma, "sigma", positive=True)
    response = np.array(implementation("calibration.chessboard_response")(img, sigma), dtype=np.float64)
    S = implementation("filters.gaussian")(_grey01(img), sigma)
    empty = np.zeros((0, 2)), np.zeros((0, 2, 2))
    xs, ys = _strongest_peaks(response, count)
    if xs.size == 0:
        return empty
    changes, contrast = _ring_sign_changes(S, np.column_stack([xs, ys]).astype(np.float64), 3.0)
    junction = (changes == 4) & (contrast >= 0.15)
    xs, ys = xs[junction], ys[junction]
    if xs.size == 0:
        return empty
    a = S[ys, xs + 1] + S[ys, xs - 1] - 2.0 * S[ys, xs]
    c = S[ys + 1, xs] + S[ys - 1, xs] - 2.0 * S[ys, xs]
    b = 0.25 * (S[ys + 1, xs + 1] - S[ys + 1, xs - 1] - S[ys - 1, xs + 1] + S[ys - 1, xs - 1])
    return np.column_stack([xs, ys]).astype(np.float64), _edge_directions(a, b, c)


def _strongest_peaks(response: np.ndarray, count: int, border: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Columns and rows of the local maxima of ``response`` (changed in place: a ``border``-pixel
    frame is zeroed) above 1e-3 of its maximum and 5 % of the typical strength of the ``count``
    strongest, strongest first, at most ``4 count + 50`` of them."""
    response[:border] = response[-border:] = 0.0
    response[:, :border] = response[:, -border:] = 0.0
    if response.max() <= 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    ys, xs = np.nonzero(_local_maxima(response, 2) & (response > 1e-3 * response.max()))
    strength = response[ys, xs]
    order = np.argsort(-strength, kind="stable")
    typical = float(np.median(strength[order[:count]]))
    keep = order[strength[order] > 0.05 * typical][: 4 * count + 50]
    return xs[keep], ys[keep]


def _candidate_arrays(points: ArrayLike, directions: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Validated (K, 2) points and (K, 2, 2) directions as float64 arrays (directions as given)."""
    pts = as_float_array(points, "points", ndim=2, allow_empty=True)
    if pts.size and pts.shape[1:] != (2,):
        raise ValueError(f"points must be (K, 2), got shape {pts.shape}")
    pts = pts.reshape(-1, 2)
    dirs = as_float_array(directions, "directions", ndim=3, allow_empty=True)
    if pts.shape[0] != np.asarray(points).shape[0] or dirs.shape != (len(pts), 2, 2):
        raise ValueError(f"points must be (K, 2) and directions (K, 2, 2), got {np.shape(points)} and {dirs.shape}")
    return pts, dirs


@algorithm("calibration.grow_grid", section="8.3", check="cvkit.calibration.checks:grow_grid")
def grow_grid(points: ArrayLike, directions: ArrayLike, seed: int = 0) -> np.ndarray | None:
    """Grow the lattice of chessboard corners that contains candidate ``seed``.

    Parameters
    ----------
    points : (K, 2) array_like
        Candidate corners ``(x, y)``. Each node of the grid compares its prediction with all
        K candidates: ``24·K²`` may be at most ``cvkit._validation.MAX_WORK`` (2**36, about a
        minute; ``ValueError`` naming ``points``), i.e. K up to about 53 000.
    directions : (K, 2, 2) array_like
        The two edge directions (unit or not, any sign) at each candidate:
        ``directions[k, 0]`` and ``directions[k, 1]``.
    seed : int, optional
        Index of the candidate the growth starts from (``0 ≤ seed < K``).

    Returns
    -------
    (N, 3) int64 ndarray or None
        One row ``(i, j, k)`` per node of the grid: candidate ``k`` sits ``i`` steps along
        ``directions[seed, 0]`` and ``j`` steps along ``directions[seed, 1]`` from the seed (in
        the sense of those vectors: a node at ``i = 1`` lies on the side the vector points to).
        The seed is ``(0, 0, seed)`` (unless it was pruned). Rows are sorted by ``i``, then ``j``.
        None when the seed has no first neighbour along one of its two directions.

    Raises
    ------
    ValueError, TypeError
        Malformed points or directions, a seed that is not an index of a candidate.

    Notes
    -----
    §8.3, the grid of the detector. With unit directions ``u``:

    1. First neighbours: along each of ``±u1`` (node ``(±1, 0)``) and ``±u2`` (``(0, ±1)``), the
       nearest other candidate whose direction from the seed is within 20° of it. At least one
       neighbour along ``u1`` and one along ``u2`` are needed, else None.
    2. Growth, node by node (tens of nodes: a Python loop): the node next to ``here`` is
       predicted by continuing a line (``2·here − back``, step ``|here − back|``) or, if no
       ``back`` node exists, by completing a parallelogram with a side node and the diagonal
       node (``here + diagonal − side``, step ``|diagonal − side|``). The nearest unused candidate
       joins the grid if it is within 0.35 × step of the prediction, and its neighbours are
       revisited. The most recently added node is visited first (a stack). On a clean board
       the order of the visits does not matter; with stray candidates near a prediction it can
       (the check's cases avoid such draws).
    3. Pruning: nodes with at most one neighbour in the grid are removed, repeatedly (a stray
       candidate stuck to the side of the board), unless every node would go.

    Examples
    --------
    >>> import numpy as np
    >>> x, y = np.meshgrid([10.0, 20.0, 30.0], [50.0, 40.0])           # a 3 × 2 grid
    >>> points = np.column_stack([x.ravel(), y.ravel()])
    >>> directions = np.tile([[1.0, 0.0], [0.0, 1.0]], (6, 1, 1))
    >>> grow_grid(points, directions, seed=0)               # j = -1: the row above (y = 40)
    array([[ 0, -1,  3],
           [ 0,  0,  0],
           [ 1, -1,  4],
           [ 1,  0,  1],
           [ 2, -1,  5],
           [ 2,  0,  2]])
    >>> grow_grid(points[:3], directions[:3], 0) is None    # a single row: no neighbour along y
    True
    """
    pts, dirs = _candidate_arrays(points, directions)
    check_work(24 * len(pts) ** 2, "points", what=f"growing a grid among {len(pts)} candidates")
    seed = check_int(seed, "seed", minimum=0)
    if seed >= len(pts):
        raise ValueError(f"seed must be the index of a candidate (0 ≤ seed < {len(pts)}), got {seed}")
    with np.errstate(invalid="ignore", divide="ignore"):
        dirs = dirs / np.linalg.norm(dirs, axis=2, keepdims=True)
    grid = _grow_grid(seed, pts, dirs)
    return None if grid is None else _grid_rows(grid)


def _grid_rows(grid: dict[tuple[int, int], int]) -> np.ndarray:
    """A grid dict {(i, j): k} as the (N, 3) int64 rows (i, j, k) sorted by i, then j."""
    rows = np.array([(i, j, k) for (i, j), k in grid.items()], dtype=np.int64).reshape(-1, 3)
    return rows[np.lexsort((rows[:, 1], rows[:, 0]))]


@algorithm("calibration.order_grid_corners", section="8.3",
           check="cvkit.calibration.checks:order_grid_corners")
def order_grid_corners(points: ArrayLike, directions: ArrayLike, cols: int, rows: int) -> np.ndarray | None:
    """Pick a complete ``cols × rows`` grid out of candidate corners and put it in board order.

    Parameters
    ----------
    points : (K, 2) array_like
        Candidate corners ``(x, y)``, the most reliable first (the first 8 serve as seeds).
    directions : (K, 2, 2) array_like
        The two edge directions (unit or not, any sign) at each candidate.
    cols, rows : int
        Inner corners along a row and along a column of the board (≥ 2).

    Returns
    -------
    (cols·rows, 2) float64 ndarray or None
        The grid's points in the order of :func:`chessboard_points` (see
        :func:`find_chessboard_corners` for the axes and the origin), or None when no seed
        grows into exactly ``cols × rows`` corners.

    Raises
    ------
    ValueError, TypeError
        Malformed points, directions or counts.

    Notes
    -----
    The candidates ``0 … 7`` are tried as seeds in turn; each seed's lattice comes from
    :func:`grow_grid` (called through the registry). From a seed, the first neighbour along each of the ± edge directions is the nearest
    candidate within 20° of it. The grid then grows node by node: the next corner is predicted
    by continuing a line (2·here − back) or by completing a parallelogram
    (here + diagonal − side), and the nearest unused candidate is taken if it is within 35 % of
    the step from the prediction. Nodes with a single neighbour (stray points stuck to the
    board) are then dropped, repeatedly. A grid of exactly ``cols × rows`` nodes (either way
    round) is put in order: x along the side with ``cols`` corners, right-handed in the image
    (``cross(x_dir, y_dir) > 0``), origin the admissible corner nearest the pixel (0, 0).

    Examples
    --------
    >>> import numpy as np
    >>> x, y = np.meshgrid([10.0, 20.0, 30.0], [50.0, 40.0])           # a 3 × 2 grid, y up
    >>> points = np.column_stack([x.ravel(), y.ravel()])
    >>> directions = np.tile([[1.0, 0.0], [0.0, 1.0]], (6, 1, 1))
    >>> order_grid_corners(points, directions, 3, 2)
    array([[10., 40.],
           [20., 40.],
           [30., 40.],
           [10., 50.],
           [20., 50.],
           [30., 50.]])
    """
    cols = check_int(cols, "cols", minimum=2)
    rows = check_int(rows, "rows", minimum=2)
    pts, dirs = _candidate_arrays(points, directions)
    if len(pts) < cols * rows:
        return None
    grow = implementation("calibration.grow_grid")
    for seed in range(min(8, len(pts))):
        nodes = grow(pts, dirs, seed)
        if nodes is None or len(nodes) != cols * rows:
            continue
        grid = {(int(i), int(j)): int(k) for i, j, k in np.asarray(nodes).reshape(-1, 3)}
        if len(grid) == cols * rows:
            corners = _ordered(grid, pts, cols, rows)
            if corners is not None:
                return corners
    return None


@algorithm("calibration.refine_corners", section="8.3",
           check="cvkit.calibration.checks:refine_corners")
@_docs
def refine_corners(image: ArrayLike, corners: ArrayLike, sigma: float) -> np.ndarray:
    """Move each corner to the saddle point of the smoothed image next to it (sub-pixel).

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Grey or RGB image, any real dtype and intensity range.
    corners : (N, 2) array_like
        Approximate corners ``(x, y)`` (e.g. integer pixels).
    sigma : float
        Standard deviation (pixels, > 0) of the Gaussian smoothing.

    Returns
    -------
    (N, 2) float64 ndarray
        The refined corners; a corner whose iteration leaves the saddle, or ends more than
        1.5 px from its start, is returned unchanged.

    Raises
    ------
    ValueError, TypeError
        A malformed image or corners, a non-positive sigma.

    Notes
    -----
    S = ``filters.gaussian(grey, sigma)`` of the grey image rescaled to [0, 1] (as in
    :func:`chessboard_response`); its gradient (central differences ``(S[y, x+1] − S[y, x−1]) / 2``,
    ...) and Hessian (those of :func:`chessboard_response`) are interpolated bilinearly at the
    current point q. 10 Newton steps ``q ← q − H⁻¹ ∇S`` follow, each shortened to at most 0.5 px;
    a point where det H ≥ 0 (not a saddle) or outside the image does not move and counts as
    having left the saddle. Around an X-junction of two straight edges the smoothed image is
    point-symmetric about the crossing, so its gradient vanishes exactly there: the saddle
    point is an unbiased estimate of the corner. (For speed the image is smoothed only on the
    bounding box of the corners plus a margin of ``ceil(4σ) + 6`` px.)

    Examples
    --------
    %(board_camera)s
    >>> img = render_chessboard(A, np.eye(3), [-14.5, -9.7, 200.0], cols=4, rows=3, square_size=10.0,
    ...                         image_size=(96, 128))  # corners at (49.5 + 10 c, 38.3 + 10 r)
    >>> np.round(refine_corners(img, [[49.0, 38.0], [60.0, 38.0]], 1.25), 1)
    array([[49.5, 38.3],
           [59.5, 38.3]])
    """
    img = as_image(image)
    sigma = check_real(sigma, "sigma", positive=True)
    start = as_float_array(corners, "corners", ndim=2, allow_empty=True)
    if start.shape[1:] != (2,):
        raise ValueError(f"corners must be (N, 2), got shape {start.shape}")
    if len(start) == 0:
        return np.zeros((0, 2))
    grey = _grey01(img)
    H, W = grey.shape
    margin = int(np.ceil(4 * sigma)) + 6          # the crop's border does not reach the corners
    x0, y0 = (min(max(int(np.floor(v)) - margin, 0), n - 1) for v, n in zip(start.min(axis=0), (W, H)))
    x1, y1 = (max(int(np.ceil(v)) + margin + 1, 1) for v in start.max(axis=0))
    crop = grey[y0:min(y1, H), x0:min(x1, W)]
    if crop.size == 0:
        return start.copy()
    refined, ok = _saddle_refine(start, _derivatives(implementation("filters.gaussian")(crop, sigma)), 10, 1.5,
                                 offset=(x0, y0))
    return np.where(ok[:, None], refined, start)


@algorithm("calibration.find_chessboard_corners", section="8.3",
           check="cvkit.calibration.checks:find_chessboard_corners")
@_docs
def find_chessboard_corners(image: ArrayLike, cols: int, rows: int) -> np.ndarray | None:
    """Find the inner corners of a chessboard in an image, to sub-pixel accuracy.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Grey or RGB image, any real dtype (uint8 or float; the intensity range does not matter).
    cols, rows : int
        Inner corners along a row and along a column of the board (≥ 2).

    Returns
    -------
    (cols·rows, 2) float64 ndarray or None
        Corner ``r·cols + c`` (the order of :func:`chessboard_points`), as (x, y) pixels. The
        board's x axis follows the side with ``cols`` corners, its y axis the other, the pair
        is right-handed in the image (x to y turns like the image's x to y), and the origin is
        the one of the admissible corners nearest the image's top-left pixel (when cols ≠ rows
        the only other admissible order is its 180° rotation, ``corners[::-1]``). None when no
        complete ``cols × rows`` board is found.

    Raises
    ------
    ValueError, TypeError
        A malformed image or counts.

    Notes
    -----
    §8.3: chessboard corners are X-junctions — two edges crossing, alternating dark and light
    around the point — which can be located far more precisely than a pixel. The detector is
    the composition of four steps, each a function of its own (called through the registry):
    :func:`corner_candidates` (which uses :func:`chessboard_response`), :func:`order_grid_corners`
    and :func:`refine_corners`.

    1. **Candidates.** Grey = 0.299 R + 0.587 G + 0.114 B, rescaled to [0, 1]. After Gaussian
       smoothing (σ = 1.5, ``implementation("filters.gaussian")``) an X-junction is a *saddle*
       of the intensity: the Hessian has one positive and one negative curvature, so
       :math:`-\\det H = I_{xy}^2 - I_{xx} I_{yy}` is large and positive there (4× more than at
       an L-shaped corner of the outer border). Candidates are its local maxima (5×5) above
       5 % of the typical corner response.
    2. **Verification.** Around a true X-junction the smoothed intensity, read on a circle of
       radius 3 px, crosses its mean four times (twice for an L-corner or an edge), with a
       contrast of at least 0.15.
    3. **Sub-pixel position.** The pattern of two straight edges through a point q is
       symmetric about q, so after smoothing q is exactly a stationary point: Newton's method
       on the gradient, :math:`q \\leftarrow q - H^{-1} \\nabla I`, with the derivatives
       interpolated bilinearly (``implementation("warp.bilinear_sample")``), converges to it
       (and is unbiased, unlike a gradient-orthogonality fit on the raw image).
    4. **Grid.** From a seed, neighbours are the nearest candidates along the two edge
       directions (the null directions of the Hessian); the grid grows by predicting the next
       corner (continuing a line, or completing a parallelogram) and taking the candidate
       within 35 % of a step from the prediction; nodes left with a single neighbour (stray
       points stuck to the board) are dropped. The board is found if the grid is then exactly
       cols × rows (either way round); several seeds are tried.
    5. **Order and final position.** Of the grid's corners admissible as origin (x along the
       ``cols`` side, right-handed), the nearest to the top-left is taken; the corners are
       then refined again on an image smoothed in proportion to the square size
       (σ = spacing/8, between 1 and 3 px).

    On the rendered views of ``cvkit.data.chessboard_views`` (640×480, sensor noise 0.01) the
    corners are within about 0.02 px of the truth on average — OpenCV's
    ``findChessboardCorners`` + ``cornerSubPix`` about 0.06 px (see the tests). Unlike
    OpenCV, no corner order disambiguation by square colour is done.

    Examples
    --------
    %(board)s
    >>> corners = find_chessboard_corners(img, 4, 3)
    >>> np.round(corners[:2], 2)                     # (0, 0, 0) at 64 − 200·15/200 = 49
    array([[49., 38.],
           [59., 38.]])
    >>> find_chessboard_corners(img, 5, 3) is None   # there is no 5 × 3 board in the image
    True
    """
    img = as_image(image)
    cols = check_int(cols, "cols", minimum=2)
    rows = check_int(rows, "rows", minimum=2)
    grey = img @ _LUMA if img.ndim == 3 else img
    high = float(grey.max())
    if high - float(grey.min()) <= 1e-12 * max(1.0, abs(high)) or min(grey.shape) < 8:
        return None
    points, directions = implementation("calibration.corner_candidates")(img, cols * rows, 1.5)
    corners = implementation("calibration.order_grid_corners")(points, directions, cols, rows)
    if corners is None:
        return None
    grid = np.asarray(corners, dtype=np.float64).reshape(rows, cols, 2)
    spacing = np.median(np.concatenate([np.hypot(*np.diff(grid, axis=1).reshape(-1, 2).T),
                                        np.hypot(*np.diff(grid, axis=0).reshape(-1, 2).T)]))
    sigma = float(np.clip(spacing / 8.0, 1.0, 3.0))
    return np.asarray(implementation("calibration.refine_corners")(img, grid.reshape(-1, 2), sigma),
                      dtype=np.float64)
