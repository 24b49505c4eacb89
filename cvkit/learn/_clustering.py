"""k-means clustering and bag-of-visual-words histograms (§10.3.2)."""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, as_rng, check_allocation, check_int, check_size
from ..registry import algorithm
from ._common import expanded_squared_distances, nearest_rows

__all__ = ["kmeans", "bovw_histogram"]

#: the most update steps :func:`kmeans` accepts
MAX_ITERATIONS = 100_000


def _plus_plus(X: np.ndarray, x_sq: np.ndarray, k: int, generator: np.random.Generator) -> np.ndarray:
    """Greedy k-means++ seeding (Arthur & Vassilvitskii 2007, as in scikit-learn).

    The first centre is a uniformly drawn sample. Each further centre is chosen among
    ``2 + ⌊ln k⌋`` candidates drawn with probability proportional to D(x)², the squared
    distance of x to its closest centre so far: the candidate that lowers Σ D² the most wins.
    """
    n = X.shape[0]
    trials = 2 + int(math.log(k))
    centers = np.empty((k, X.shape[1]))
    first = int(generator.integers(n))
    centers[0] = X[first]
    closest = expanded_squared_distances(X[first:first + 1], X, x_sq[first:first + 1], x_sq)[0]
    closest[first] = 0.0
    for c in range(1, k):
        total = closest.sum()
        # cumulative D² and uniform draws: P(i) = D(x_i)² / Σ D²; exact zeros never drawn
        cumulative = np.cumsum(closest)
        draws = generator.random(trials) * cumulative[-1]
        candidates = np.minimum(np.searchsorted(cumulative, draws, side="right"), n - 1)
        d_cand = expanded_squared_distances(X[candidates], X, x_sq[candidates], x_sq)
        d_cand[np.arange(trials), candidates] = 0.0
        np.minimum(d_cand, closest, out=d_cand)
        best = int(np.argmin(d_cand.sum(axis=1))) if total > 0 else 0
        centers[c] = X[candidates[best]]
        closest = d_cand[best]
    return centers


def _assign(X: np.ndarray, x_sq: np.ndarray, centers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the nearest centre of every row (ties: the lowest index) and its squared
    distance. The candidates come from one matrix product, ‖x‖² − 2x·c + ‖c‖² (the ‖x‖² term
    does not change the argmin); a row whose best centres lie within that form's rounding
    error of each other — data far from the origin compared with their spread — is decided
    again from the differences, so every label is exactly the nearest centre."""
    c_sq = np.einsum("ij,ij->i", centers, centers)
    partial = X @ (-2.0 * centers).T
    partial += c_sq[None, :]
    labels = partial.argmin(axis=1)
    best = partial[np.arange(X.shape[0]), labels]
    dist = np.maximum(best + x_sq, 0.0)
    if centers.shape[0] > 1:
        # |error| of one expanded distance ≤ (D + 4)·eps·(‖x‖² + ‖c‖²); two are compared
        slack = 2.0 * (X.shape[1] + 4) * np.finfo(np.float64).eps * (x_sq + c_sq.max())
        unsure = np.flatnonzero(np.count_nonzero(partial <= (best + 2.0 * slack)[:, None], axis=1) > 1)
        if unsure.size:
            labels[unsure] = nearest_rows(X[unsure], centers)
            difference = X[unsure] - centers[labels[unsure]]
            dist[unsure] = np.einsum("ij,ij->i", difference, difference)
    return labels, dist


def _update(XT: np.ndarray, labels: np.ndarray, dist: np.ndarray, k: int) -> np.ndarray:
    """Lloyd's update: every centre becomes the mean of its points; empty clusters first take,
    in increasing cluster index, the point farthest from its (old) centre among the clusters
    that keep at least one point. ``XT`` is the (D, N) transpose of the samples."""
    counts = np.bincount(labels, minlength=k)
    empty = np.flatnonzero(counts == 0)
    if empty.size:
        labels = labels.copy()
        dist = dist.copy()
        for j in empty:
            eligible = counts[labels] >= 2
            far = int(np.argmax(np.where(eligible, dist, -np.inf)))  # ties: the lowest index
            counts[labels[far]] -= 1
            labels[far] = j
            counts[j] = 1
            dist[far] = 0.0
    # per-cluster sums, one weighted bincount per dimension (loops over D, not over samples)
    sums = np.empty((k, XT.shape[0]))
    for dim, column in enumerate(XT):
        sums[:, dim] = np.bincount(labels, weights=column, minlength=k)
    return sums / counts[:, None]


@algorithm("learn.kmeans", section="10.3.2", check="cvkit.learn.checks:kmeans")
def kmeans(X: ArrayLike, k: int, iterations: int = 50, rng: np.random.Generator | int | None = None,
           init: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """k-means clustering by Lloyd's algorithm with k-means++ seeding.

    Parameters
    ----------
    X : (N, D) array_like
        Samples (e.g. local descriptors), one per row.
    k : int
        Number of clusters, 1 ≤ k ≤ the number of distinct rows of ``X`` (else ``ValueError``);
        the distances of the N samples to the k centres must fit in 2 GiB (cvkit's limit for
        one array), else ``ValueError`` naming ``k``.
    iterations : int
        Maximal number of update steps, 0 ≤ iterations ≤ :data:`MAX_ITERATIONS` (100 000);
        the loop stops earlier at a fixed point.
    rng : numpy.random.Generator, int or None
        Source of the k-means++ draws.
    init : (k, D) array_like, optional
        Initial centres to use instead of k-means++ (then nothing is drawn).

    Returns
    -------
    centers : (k, D) float64 ndarray
        The cluster centres (the codebook of §10.3.2).
    labels : (N,) int64 ndarray
        Index of the nearest returned centre of every sample (ties: the lowest index).

    Notes
    -----
    §10.3.2 (the codebook of a bag of visual words). After the seeding, each iteration

    1. assigns every sample to its nearest centre (squared Euclidean distance), then
    2. moves every centre to the mean of its samples. A cluster left **empty** is re-seeded
       first, in increasing cluster index, with the sample farthest from the centre it was
       just assigned to, taken from a cluster that keeps at least one sample (ties: the
       lowest sample index); that sample then belongs to the empty cluster (scikit-learn
       relocates empty clusters the same way).

    It stops when an update leaves the centres unchanged or after ``iterations`` updates;
    the labels are then recomputed for the returned centres. This lowers the inertia
    :math:`\\sum_i \\lVert x_i - c_{\\ell_i} \\rVert^2` at every step. Seeding is greedy
    k-means++: the first centre a uniformly drawn sample, each next one the best (lowest
    inertia) of ``2 + ⌊ln k⌋`` samples drawn with probability ∝ D(x)² (scikit-learn's
    ``KMeans(init="k-means++")``). Distances come from one matrix product
    ‖x‖² − 2x·c + ‖c‖² per iteration; a sample whose nearest centres are closer to each
    other than that form's rounding error (data far from the origin compared with their
    spread) is assigned again from the differences, so the labels are exactly the nearest
    centres.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[0.0, 0.0], [0.0, 1.0], [10.0, 10.0], [10.0, 11.0]])
    >>> centers, labels = kmeans(X, 2, rng=0)
    >>> sorted(centers.tolist()), bool(labels[0] == labels[1] != labels[2] == labels[3])
    ([[0.0, 0.5], [10.0, 10.5]], True)
    >>> kmeans(X, 2, init=np.array([[0.0, 0.0], [50.0, 50.0]]))[0]   # empty cluster re-seeded
    array([[ 0. ,  0.5],
           [10. , 10.5]])
    """
    X = as_float_array(X, "X", ndim=2)
    n, d = X.shape
    k = check_int(k, "k", minimum=1)
    iterations = check_size(iterations, "iterations", minimum=0, maximum=MAX_ITERATIONS)
    distinct = np.unique(X, axis=0).shape[0] if k > 1 else 1
    if k > distinct:
        raise ValueError(f"k must be at most the number of distinct rows of X ({distinct}), got {k}")
    check_allocation((n, k), "k", what="the distances of every sample to every centre")
    x_sq = np.einsum("ij,ij->i", X, X)
    if init is None:
        centers = _plus_plus(X, x_sq, k, as_rng(rng))
    else:
        centers = np.array(as_float_array(init, "init", ndim=2), dtype=np.float64, copy=True)
        if centers.shape != (k, d):
            raise ValueError(f"init must have shape (k, D) = ({k}, {d}), got {centers.shape}")
    labels, dist = _assign(X, x_sq, centers)
    XT = np.ascontiguousarray(X.T) if iterations else X.T  # the copy only when it is used
    for _ in range(iterations):
        updated = _update(XT, labels, dist, k)
        if np.array_equal(updated, centers):
            break
        centers = updated
        labels, dist = _assign(X, x_sq, centers)
    return centers, labels.astype(np.int64)


@algorithm("learn.bovw_histogram", section="10.3.2", check="cvkit.learn.checks:bovw_histogram")
def bovw_histogram(descriptors: ArrayLike, codebook: ArrayLike, normalize: bool = True) -> np.ndarray:
    """Bag-of-visual-words histogram: how often each codeword is the nearest one.

    Parameters
    ----------
    descriptors : (M, D) array_like
        The local descriptors of one image, M ≥ 1.
    codebook : (K, D) array_like
        The codewords (e.g. the centres returned by :func:`kmeans`).
    normalize : bool
        Divide the counts by their sum (M), giving word frequencies that sum to 1.

    Returns
    -------
    (K,) float64 ndarray
        ``h[j]`` = number of descriptors whose nearest codeword (Euclidean distance, ties to
        the lowest index) is ``j``, divided by M when ``normalize``.

    Notes
    -----
    §10.3.2, step 3: each descriptor is quantised to its nearest codeword and the image is
    represented by the histogram of the codewords, a fixed-length vector whatever the number
    of descriptors. Distances are computed from the differences (exact ties are kept).

    Examples
    --------
    >>> import numpy as np
    >>> codebook = np.array([[0.0, 0.0], [1.0, 1.0], [5.0, 5.0]])
    >>> d = np.array([[0.1, 0.0], [0.9, 1.2], [1.1, 0.8], [4.0, 4.5]])
    >>> bovw_histogram(d, codebook)
    array([0.25, 0.5 , 0.25])
    >>> bovw_histogram(d, codebook, normalize=False)
    array([1., 2., 1.])
    """
    desc = as_float_array(descriptors, "descriptors", ndim=2)
    words = as_float_array(codebook, "codebook", ndim=2)
    if words.shape[1] != desc.shape[1]:
        raise ValueError(f"codebook must have the {desc.shape[1]} columns of descriptors, got shape {words.shape}")
    if not isinstance(normalize, (bool, np.bool_)):
        raise TypeError(f"normalize must be True or False, got {normalize!r}")
    nearest = nearest_rows(desc, words)
    counts = np.bincount(nearest, minlength=words.shape[0]).astype(np.float64)
    if normalize:
        counts /= desc.shape[0]
    return counts
