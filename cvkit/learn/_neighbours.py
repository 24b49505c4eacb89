"""k-nearest-neighbour classification (§10.1) on raw feature vectors."""
from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, as_labels, check_allocation, check_int
from ..registry import algorithm
from ._common import _CHUNK_ELEMENTS, exact_l1_distances, exact_squared_distances, expanded_squared_distances

__all__ = ["knn_predict"]

_METRICS = ("l2", "l1")
_EXTRA_CANDIDATES = 8     # candidates kept beyond k before the exact re-ranking
_ROWS_ELEMENTS = 1 << 23  # test rows × training rows per block of the fast L2 search


def _first_k(distances: np.ndarray, k: int) -> np.ndarray:
    """Indices of the k smallest values of each row, by (distance, index)."""
    columns = np.broadcast_to(np.arange(distances.shape[1]), distances.shape)
    order = np.lexsort((columns, distances), axis=1)
    return order[:, :k]


def _nearest_l2(train: np.ndarray, test: np.ndarray, k: int) -> np.ndarray:
    """The k nearest training rows of every test row in (exact squared L2, index) order.

    A matrix product (‖a‖² − 2a·b + ‖b‖²) finds k + 8 candidates; their distances are then
    recomputed from the differences, which decides ties exactly. A row whose ranking could
    still be changed by rounding error (many points at the k-th distance, e.g. duplicates)
    is recomputed exactly against the whole training set.
    """
    n, d = train.shape
    m = min(n, k + _EXTRA_CANDIDATES)
    train_sq = np.einsum("ij,ij->i", train, train)
    out = np.empty((test.shape[0], k), dtype=np.int64)
    # a block's distances (rows × n) and its candidates' differences (rows × m × d) stay small
    rows = max(1, min(_ROWS_ELEMENTS // max(1, n), _CHUNK_ELEMENTS // max(1, m * d)))
    for start in range(0, test.shape[0], rows):
        block = test[start:start + rows]
        if m == n:
            out[start:start + rows] = _first_k(exact_squared_distances(block, train), k)
            continue
        block_sq = np.einsum("ij,ij->i", block, block)
        approx = expanded_squared_distances(block, train, block_sq, train_sq)
        part = np.argpartition(approx, m, axis=1)
        candidates = part[:, :m]
        beyond = np.take_along_axis(approx, part[:, m:m + 1], axis=1)[:, 0]  # smallest non-candidate
        diff = train[candidates] - block[:, None, :]
        exact = np.einsum("mcd,mcd->mc", diff, diff)
        order = np.lexsort((candidates, exact), axis=1)[:, :k]
        chosen = np.take_along_axis(candidates, order, axis=1)
        kth = np.take_along_axis(exact, order[:, -1:], axis=1)[:, 0]
        # rounding error of the expansion: a few ulps of the squared norms involved
        slack = 1e-12 * (block_sq + train_sq.max()) + 1e-300
        unsure = np.flatnonzero(beyond - 2 * slack <= kth)
        if unsure.size:
            chosen[unsure] = _first_k(exact_squared_distances(block[unsure], train), k)
        out[start:start + rows] = chosen
    return out


def _nearest_l1(train: np.ndarray, test: np.ndarray, k: int) -> np.ndarray:
    """The k nearest training rows of every test row in (L1 distance, index) order, a block of
    test rows at a time."""
    out = np.empty((test.shape[0], k), dtype=np.int64)
    rows = max(1, _ROWS_ELEMENTS // max(1, train.shape[0]))
    for start in range(0, test.shape[0], rows):
        out[start:start + rows] = _first_k(exact_l1_distances(test[start:start + rows], train), k)
    return out


def _vote(votes: np.ndarray, width: int) -> np.ndarray:
    """The most frequent of the ``width`` codes in every row of ``votes`` (ties: the smallest),
    a block of rows at a time (the counts of all rows at once could be large)."""
    out = np.empty(votes.shape[0], dtype=np.int64)
    rows = max(1, _CHUNK_ELEMENTS // width)
    for start in range(0, votes.shape[0], rows):
        block = votes[start:start + rows]
        index = np.arange(block.shape[0])[:, None]
        counts = np.bincount((index * width + block).ravel(), minlength=block.shape[0] * width)
        out[start:start + rows] = counts.reshape(block.shape[0], width).argmax(axis=1)
    return out


@algorithm("learn.knn_predict", section="10.1", check="cvkit.learn.checks:knn_predict")
def knn_predict(X_train: ArrayLike, y_train: ArrayLike, X_test: ArrayLike, k: int = 1,
                metric: Literal["l2", "l1"] = "l2") -> np.ndarray:
    """Predict labels by a majority vote of the k nearest training samples.

    Parameters
    ----------
    X_train : (N, D) array_like
        Training samples, one per row.
    y_train : (N,) array_like of int
        Their labels (integers ≥ 0).
    X_test : (M, D) array_like
        Samples to classify.
    k : int
        Number of neighbours, 1 ≤ k ≤ N; the neighbours of all test rows, M·k indices, must
        fit in 2 GiB (cvkit's limit for one array), else ``ValueError`` naming ``k``.
    metric : {"l2", "l1"}
        Euclidean distance :math:`\\sqrt{\\sum (a-b)^2}` or Manhattan distance
        :math:`\\sum |a-b|`.

    Returns
    -------
    (M,) int64 ndarray
        The predicted label of every test row.

    Notes
    -----
    §10.1 (a "shallow" classifier on raw pixels). For each test row the training rows are
    ordered by distance, **equal distances by training index** (a stable sort), and the first
    ``k`` vote; the label with the most votes wins and **a tie between labels goes to the
    smallest label**. (scikit-learn's ``KNeighborsClassifier`` also gives vote ties to the
    smallest label; its neighbour order among equal distances is not specified.)
    The L2 search uses one matrix product to find candidates and recomputes their distances
    from the differences, so ties between equal distances are decided exactly.

    Examples
    --------
    >>> import numpy as np
    >>> X_train = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 5.0], [6.0, 5.0]])
    >>> y_train = np.array([0, 0, 1, 1])
    >>> knn_predict(X_train, y_train, np.array([[0.2, 0.1], [5.4, 4.0]]))
    array([0, 1])
    >>> knn_predict(X_train, y_train, np.array([[3.0, 2.5]]), k=4)   # 2 votes each: smaller label
    array([0])
    """
    train = as_float_array(X_train, "X_train", ndim=2)
    n, d = train.shape
    labels = as_labels(y_train, "y_train", n)
    test = as_float_array(X_test, "X_test", ndim=2, allow_empty=True)
    if test.shape[1] != d:
        raise ValueError(f"X_test must have the {d} columns of X_train, got shape {test.shape}")
    k = check_int(k, "k", minimum=1)
    if k > n:
        raise ValueError(f"k must be at most the number of training samples ({n}), got {k}")
    if not isinstance(metric, str) or metric not in _METRICS:
        raise ValueError(f"metric must be one of {', '.join(map(repr, _METRICS))}, got {metric!r}")
    if test.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    check_allocation((test.shape[0], k), "k", what="the neighbours of every test row")
    if metric == "l2":
        nearest = _nearest_l2(train, test, k)
    else:
        nearest = _nearest_l1(train, test, k)
    # vote on the distinct labels in increasing order (so ties still go to the smallest label,
    # and a label as large as 10**12 costs nothing)
    distinct, codes = np.unique(labels, return_inverse=True)
    return distinct[_vote(codes.reshape(-1)[nearest], distinct.size)]
