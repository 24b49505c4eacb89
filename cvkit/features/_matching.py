"""Matching descriptors (§5.13–5.14): Lowe's ratio test, and a k-d tree with exact and
Best-Bin-First nearest-neighbour search.

The k-d tree is built by median splits along the dimension of largest spread down to leaves of
a few points. Searches process all queries together, leaf by leaf: every query visits the leaves
in increasing order of their distance to it (the lower bound given by the leaf's cell, the box the
splits cut out), which is exactly the order in which a best-bin-first priority queue pops them.
The exact search stops when the next leaf is farther than the current k-th neighbour; BBF also
stops when its budget of distance computations is spent.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_allocation
from ..registry import algorithm
from ._common import check_int, check_real

__all__ = ["match_ratio", "KDTree", "nearest_two"]

_BLOCK = 1 << 18  # elements of a block of temporaries: small enough to stay in cache
_ROWS_BUDGET = 1 << 24  # elements of the per-block arrays of a k-d tree search (128 MiB of float64)


def _pairwise_sq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances (len(a), len(b)) by ‖a‖² + ‖b‖² − 2a·b (BLAS), ≥ 0."""
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * (a @ b.T)
    return np.maximum(d2, 0.0, out=d2)


def nearest_two(desc1: np.ndarray, desc2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each row of desc1: index of its nearest row of desc2 (ties: the smaller index) and
    the exact distances to the nearest and the second nearest.

    Candidates come from the BLAS expansion; the few within its round-off of the best two are
    re-measured as ``sqrt(Σ (a − b)²)``, so the result is that of the direct formula.
    """
    # Values whose squares over- or underflow (beyond about 1e±154): measure in units of a
    # power of two near the largest magnitude (exact), so that inf − inf never makes a NaN.
    peak = max(np.abs(desc1).max(initial=0.0), np.abs(desc2).max(initial=0.0))
    unit = 1.0
    if peak > 2.0 ** 400 or 0.0 < peak < 2.0 ** -400:
        unit = math.ldexp(1.0, math.frexp(peak)[1])
        desc1, desc2 = desc1 / unit, desc2 / unit
    n1 = desc1.shape[0]
    j1 = np.empty(n1, dtype=np.int64)
    d1 = np.empty(n1)
    d2 = np.empty(n1)
    scale = (desc1 * desc1).sum(1).max(initial=0.0) + (desc2 * desc2).sum(1).max(initial=0.0)
    slack = 1e-9 * max(scale, 1e-300)
    rows = max(1, _BLOCK // max(1, desc2.shape[0]))
    for start in range(0, n1, rows):
        a = desc1[start:start + rows]
        approx = _pairwise_sq(a, desc2)
        second = np.partition(approx, 1, axis=1)[:, 1] if desc2.shape[0] > 1 else approx[:, 0]
        near = approx <= (second + slack)[:, None]  # the best two and whatever ties with them
        k, j = np.nonzero(near)
        diff = a[k] - desc2[j]
        exact = np.sqrt((diff * diff).sum(1))
        order = np.lexsort((j, exact, k))  # by row, then distance, then index
        k, j, exact = k[order], j[order], exact[order]
        first = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
        j1[start:start + len(a)] = j[first]
        d1[start:start + len(a)] = exact[first]
        d2[start:start + len(a)] = exact[first + 1]
    if unit != 1.0:
        with np.errstate(over="ignore"):  # a distance beyond the float range is inf
            d1 *= unit
            d2 *= unit
    return j1, d1, d2


@algorithm("features.match_ratio", section="5.13", check="cvkit.features.checks:match_ratio")
def match_ratio(desc1: ArrayLike, desc2: ArrayLike, ratio: float = 0.8) -> np.ndarray:
    """Nearest-neighbour matches that pass Lowe's ratio test.

    Parameters
    ----------
    desc1 : (N1, D) array_like
        Descriptors of the first image (the queries).
    desc2 : (N2, D) array_like
        Descriptors of the second image, N2 ≥ 2 (the ratio needs a second neighbour).
    ratio : float
        The threshold T of the test, > 0 (0.8 in Lowe's paper).

    Returns
    -------
    (M, 2) int64 ndarray
        Pairs ``(i, j)``: row j of desc2 is the nearest neighbour of row i of desc1 and
        ``d1 ≤ ratio · d2`` with ``d2 > 0``, rows in increasing i.

    Notes
    -----
    §5.13. ``d1`` and ``d2`` are the Euclidean distances from ``desc1[i]`` to its nearest and
    second-nearest rows of desc2 (two rows at the same smallest distance make ``d2 = d1``, an
    ambiguous match that fails any ratio below 1; equal distances pick the smaller j). The
    test compares *distances*, not squared distances (that would be the test with ratio²).
    Equals ``skimage.feature.match_descriptors(desc1, desc2, metric="euclidean",
    cross_check=False, max_ratio=ratio)`` except at exact equality (scikit-image keeps
    ``d1 / d2 < ratio``).

    Examples
    --------
    >>> import numpy as np
    >>> a = np.array([[0.0, 0.0], [5.0, 5.0]])
    >>> b = np.array([[0.1, 0.0], [3.0, 0.0], [5.0, 4.0], [5.0, 6.0]])
    >>> match_ratio(a, b)                     # (5, 5) is as far from (5, 4) as from (5, 6)
    array([[0, 0]])
    """
    a = as_float_array(desc1, "desc1", ndim=2, allow_empty=True)
    b = as_float_array(desc2, "desc2", ndim=2, allow_empty=True)
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"desc1 and desc2 must have the same number of columns, got {a.shape} and {b.shape}")
    if b.shape[0] < 2:
        raise ValueError(f"desc2 needs at least 2 rows for the ratio test, got shape {b.shape}")
    ratio = check_real(ratio, "ratio", positive=True)
    if a.shape[0] == 0:
        return np.zeros((0, 2), dtype=np.int64)
    j, d1, d2 = nearest_two(a, b)
    keep = (d2 > 0) & (d1 <= ratio * d2)
    i = np.flatnonzero(keep)
    return np.stack([i, j[keep]], axis=1).astype(np.int64).reshape(-1, 2)


@algorithm("features.KDTree", section="5.14", check="cvkit.features.checks:KDTree")
class KDTree:
    """A k-d tree over points, with exact and Best-Bin-First nearest-neighbour queries.

    Parameters
    ----------
    points : (N, D) array_like
        The points to index (finite, N ≥ 1). The tree keeps its own copy, and its leaves
        padded to the largest one (many equal points make one large leaf), which may take at
        most 2 GiB (``ValueError`` naming ``points``).
    leaf_size : int
        Largest number of points in a leaf, ≥ 1.

    Notes
    -----
    §5.14 (Friedman, Bentley and Finkel 1977; Beis and Lowe 1997). Each node splits its points
    at the median of the coordinate of largest variance (as FLANN does; on SIFT descriptors it
    gives BBF a better recall than the largest range): the lower half goes left
    (coordinates ≤ the split value), the upper half right (≥). A node with at most
    ``leaf_size`` points, or whose points all coincide, is a leaf (the median point and any
    equal to it may end on either side; the cells still hold their points). Each leaf owns the *cell*
    (box) that the splits on its path cut out of space; the distance from a query to a cell
    (0 inside it) is a lower bound of its distance to any point of the leaf.

    :meth:`query` visits the leaves in increasing cell distance and stops as soon as the next
    cell is farther than the current k-th nearest point: the answer is exact.
    :meth:`query_bbf` visits them in the same order — that is what Best-Bin-First's priority
    queue does — but stops after ``max_checks`` distance computations: approximate, with a
    cost that no longer grows with N. In high dimensions (SIFT's 128) the exact search visits
    most leaves, BBF a fixed few.

    Examples
    --------
    >>> import numpy as np
    >>> tree = KDTree(np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 2.0], [5.0, 5.0]]))
    >>> tree.query(np.array([2.5, 0.5]), k=2)
    (array([0.70710678, 2.54950976]), array([1, 0]))
    >>> tree.query_bbf(np.array([[2.5, 0.5]]), k=1, max_checks=4)
    (array([[0.70710678]]), array([[1]]))
    """

    def __init__(self, points: ArrayLike, leaf_size: int = 4) -> None:
        data = as_float_array(points, "points", ndim=2)
        self.leaf_size = check_int(leaf_size, "leaf_size", minimum=1)
        self.points = data.copy()
        self.n, self.dim = data.shape
        order, bounds, lo, hi = self._build()
        self._order = order                          # point indices, leaf by leaf
        self._starts = bounds[:, 0]
        self._sizes = bounds[:, 1] - bounds[:, 0]
        # the cells (L, D) kept sparsely: only the axes a split on the path bounds, padded
        # with an unbounded axis 0 entry (lo = −inf, hi = +inf)
        bounded = np.isfinite(lo) | np.isfinite(hi)
        width_axes = max(1, int(bounded.sum(1).max()))
        self._axes = np.zeros((len(lo), width_axes), dtype=np.int64)
        self._cell_lo = np.full((len(lo), width_axes), -np.inf)
        self._cell_hi = np.full((len(lo), width_axes), np.inf)
        for leaf, axes in enumerate(bounded):
            axes = np.flatnonzero(axes)
            self._axes[leaf, :axes.size] = axes
            self._cell_lo[leaf, :axes.size] = lo[leaf, axes]
            self._cell_hi[leaf, :axes.size] = hi[leaf, axes]
        width = int(self._sizes.max())
        # the leaves' points padded to a common width: (L, width) indices, N = padding
        check_allocation((len(self._starts), width, self.dim), "points", what="the leaves padded to the largest")
        slots = self._starts[:, None] + np.arange(width)[None, :]
        valid = np.arange(width)[None, :] < self._sizes[:, None]
        self._leaf_index = np.where(valid, self._order[np.minimum(slots, self.n - 1)], self.n)
        padded = np.vstack([self.points, np.full((1, self.dim), np.nan)])
        self._leaf_points = padded[self._leaf_index]  # (L, width, D)

    @property
    def leaves(self) -> int:
        """Number of leaves."""
        return len(self._starts)

    def _build(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        pts = self.points
        order = np.arange(self.n)
        lo_root = np.full(self.dim, -np.inf)
        hi_root = np.full(self.dim, np.inf)
        stack = [(0, self.n, lo_root, hi_root)]
        leaves = []
        while stack:
            start, stop, lo, hi = stack.pop()
            idx = order[start:stop]
            block = pts[idx]
            spread = block.var(0)
            axis = int(np.argmax(spread))
            if stop - start <= self.leaf_size or spread[axis] == 0:
                leaves.append((start, stop, lo, hi))
                continue
            sorted_idx = idx[np.lexsort((idx, block[:, axis]))]
            order[start:stop] = sorted_idx
            mid = start + (stop - start) // 2
            split = pts[order[mid], axis]
            left_hi, right_lo = hi.copy(), lo.copy()
            left_hi[axis] = split
            right_lo[axis] = split
            stack.append((mid, stop, right_lo, hi))  # popped second: leaves come left to right
            stack.append((start, mid, lo, left_hi))
        bounds = np.array([(a, b) for a, b, _, _ in leaves], dtype=np.int64)
        lo = np.array([leaf[2] for leaf in leaves])
        hi = np.array([leaf[3] for leaf in leaves])
        return order, bounds, lo, hi

    # ----------------------------------------------------------------------------------------
    def _queries(self, q: ArrayLike) -> tuple[np.ndarray, bool]:
        arr = as_float_array(q, "q", ndim=(1, 2), allow_empty=True)
        single = arr.ndim == 1
        arr = arr.reshape(1, -1) if single else arr
        if arr.shape[1] != self.dim:
            raise ValueError(f"q must have {self.dim} coordinates per point like the tree's points, got shape {np.shape(q)}")
        return arr, single

    def _k(self, k: int) -> int:
        k = check_int(k, "k", minimum=1)
        if k > self.n:
            raise ValueError(f"k must be at most the number of points {self.n}, got {k}")
        return k

    def query(self, q: ArrayLike, k: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The k nearest points of each query, exactly.

        Parameters
        ----------
        q : (D,) or (M, D) array_like
            One query point or M of them.
        k : int
            Number of neighbours, 1 ≤ k ≤ N. The result, M × k distances and indices, may take
            at most 2 GiB per array (``ValueError`` naming ``k``); the search itself works on
            blocks of queries sized to the tree and to k, so its memory stays bounded.

        Returns
        -------
        distances : float64 ndarray, (k,) or (M, k)
            Euclidean distances ``sqrt(Σ (p − q)²)``, ascending.
        indices : int64 ndarray, same shape
            Row indices into ``points``; equal distances list the smaller index first (as a
            stable sort of brute-force distances would).
        """
        arr, single = self._queries(q)
        k = self._k(k)
        return self._search(arr, single, k, None)

    def query_bbf(self, q: ArrayLike, k: int = 2, max_checks: int = 200) -> tuple[np.ndarray, np.ndarray]:
        """The k nearest points found by Best-Bin-First search with a budget.

        Parameters
        ----------
        q : (D,) or (M, D) array_like
        k : int
            Number of neighbours, 1 ≤ k ≤ N (2 for the ratio test).
        max_checks : int
            At most this many distance computations per query (one per point examined), ≥ k.
            Leaves are visited nearest cell first; a leaf's points are examined in their order
            in the leaf until the budget is spent.

        Returns
        -------
        distances, indices : as :meth:`query`
            The best k among the points examined: exact distances to possibly non-nearest
            points. With ``max_checks ≥ N`` the result is exact.
        """
        arr, single = self._queries(q)
        k = self._k(k)
        max_checks = check_int(max_checks, "max_checks", minimum=1)
        if max_checks < k:
            raise ValueError(f"max_checks must be at least k = {k} (one check per point examined), got {max_checks}")
        return self._search(arr, single, k, max_checks)

    def _search(self, queries: np.ndarray, single: bool, k: int,
                budget: int | None) -> tuple[np.ndarray, np.ndarray]:
        m = queries.shape[0]
        check_allocation((m, k), "k", what="the distances")
        distances = np.empty((m, k))
        indices = np.empty((m, k), dtype=np.int64)
        # queries searched together (the per-leaf steps are vectorised over them): up to 1024,
        # fewer when their (rows, leaves) cell bounds or (rows, k + leaf width) candidates
        # would outgrow _ROWS_BUDGET elements
        width = self._leaf_index.shape[1]
        per_row = max(self.leaves, k + width, width * self.dim)
        rows = max(1, min(1024, _ROWS_BUDGET // per_row))
        for start in range(0, m, rows):
            part = queries[start:start + rows]
            d2, idx = self._search_block(part, k, budget)
            distances[start:start + len(part)] = np.sqrt(d2)
            indices[start:start + len(part)] = idx
        if single:
            return distances[0], indices[0]
        return distances, indices

    def _search_block(self, q: np.ndarray, k: int, budget: int | None) -> tuple[np.ndarray, np.ndarray]:
        m = q.shape[0]
        # squared distance from every query to every leaf's cell, and the visiting order
        n_leaves, n_axes = self._axes.shape
        bound = np.empty((m, n_leaves))
        step = max(1, _BLOCK // max(1, n_leaves * n_axes))
        for a in range(0, m, step):
            coords = q[a:a + step][:, self._axes]                  # (rows, L, axes)
            gap = np.maximum(np.maximum(self._cell_lo - coords, coords - self._cell_hi), 0.0)
            bound[a:a + step] = (gap * gap).sum(2)
        visit = np.argsort(bound, axis=1, kind="stable")
        best_d = np.full((m, k), np.inf)
        best_i = np.full((m, k), self.n, dtype=np.int64)          # N: no point yet
        left = np.full(m, np.inf if budget is None else float(budget))
        active = np.arange(m)
        width = self._leaf_index.shape[1]
        for step in range(visit.shape[1]):
            leaf = visit[active, step]
            # a leaf whose cell is farther than the k-th best cannot improve (ties can: ≤)
            go = bound[active, leaf] <= best_d[active, -1]
            if budget is not None:
                go &= left[active] > 0
            active, leaf = active[go], leaf[go]
            if active.size == 0:
                break
            pts = self._leaf_points[leaf]                            # (a, width, D)
            idx = self._leaf_index[leaf]                             # (a, width)
            diff = pts - q[active, None, :]
            d2 = (diff * diff).sum(2)
            valid = idx < self.n
            if budget is not None:
                seen = np.minimum(self._sizes[leaf], left[active]).astype(np.int64)
                valid &= np.arange(width)[None, :] < seen[:, None]
                left[active] -= seen
            d2 = np.where(valid, d2, np.inf)
            idx = np.where(valid, idx, self.n)
            all_d = np.concatenate([best_d[active], d2], axis=1)
            all_i = np.concatenate([best_i[active], idx], axis=1)
            order = np.lexsort((all_i, all_d), axis=1)[:, :k]
            best_d[active] = np.take_along_axis(all_d, order, axis=1)
            best_i[active] = np.take_along_axis(all_i, order, axis=1)
        return best_d, best_i
