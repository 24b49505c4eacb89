"""Distance helpers shared by the learning algorithms of Chapters 9–10 (their labels are checked
by :func:`cvkit._validation.as_labels`)."""
from __future__ import annotations

import numpy as np

_CHUNK_ELEMENTS = 1 << 22  # elements of a (rows, others, D) difference block: 32 MB of float64


def exact_squared_distances(points: np.ndarray, others: np.ndarray) -> np.ndarray:
    """``d[i, j] = Σ (points[i] − others[j])²`` from the differences themselves (no expansion
    ‖a‖² − 2a·b + ‖b‖², whose round-off could split exact ties), in blocks of rows."""
    m, d = points.shape
    out = np.empty((m, others.shape[0]))
    rows = max(1, _CHUNK_ELEMENTS // max(1, others.shape[0] * d))
    for start in range(0, m, rows):
        diff = points[start:start + rows, None, :] - others[None, :, :]
        np.einsum("mnd,mnd->mn", diff, diff, out=out[start:start + rows])
    return out


def exact_l1_distances(points: np.ndarray, others: np.ndarray) -> np.ndarray:
    """``d[i, j] = Σ |points[i] − others[j]|``, in blocks of rows."""
    m, d = points.shape
    out = np.empty((m, others.shape[0]))
    rows = max(1, _CHUNK_ELEMENTS // max(1, others.shape[0] * d))
    for start in range(0, m, rows):
        diff = points[start:start + rows, None, :] - others[None, :, :]
        np.abs(diff, out=diff)
        diff.sum(axis=2, out=out[start:start + rows])
    return out


def nearest_rows(points: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Index of the nearest row of ``others`` for every row of ``points`` (exact squared
    distances, ties to the lowest index), a block of rows at a time: the full ``(M, K)``
    distance matrix is never held."""
    out = np.empty(points.shape[0], dtype=np.intp)
    rows = max(1, _CHUNK_ELEMENTS // max(1, others.shape[0]))
    for start in range(0, points.shape[0], rows):
        out[start:start + rows] = exact_squared_distances(points[start:start + rows], others).argmin(axis=1)
    return out


def expanded_squared_distances(points: np.ndarray, others: np.ndarray,
                               points_sq: np.ndarray | None = None,
                               others_sq: np.ndarray | None = None) -> np.ndarray:
    """``‖a‖² − 2a·b + ‖b‖²`` through one matrix product (fast; rounding error about
    ``1e-16·(‖a‖² + ‖b‖²)``), clipped at 0."""
    if points_sq is None:
        points_sq = np.einsum("ij,ij->i", points, points)
    if others_sq is None:
        others_sq = np.einsum("ij,ij->i", others, others)
    out = points @ others.T
    out *= -2.0
    out += points_sq[:, None]
    out += others_sq[None, :]
    np.maximum(out, 0.0, out=out)
    return out
