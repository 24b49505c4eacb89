"""The Hough transform for straight lines (§6.0.4–6.0.5) in the normal parametrisation
ρ = x cos θ + y sin θ: every edge pixel votes once per θ into the nearest ρ bin, and lines are
the peaks of the accumulator.

Vectorised: the votes of all edge pixels for one θ are one ``np.bincount`` (a loop over the
θ samples, never over pixels).
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .._validation import MAX_ARRAY_BYTES, MAX_WORK, as_float_array, check_int, check_real
from ..registry import algorithm

__all__ = ["hough_lines", "hough_peaks", "theta_samples", "rho_samples", "MAX_THETAS"]

#: the most θ samples (theta_step ≥ π / MAX_THETAS, 0.001°): each one is a pass over the edge pixels
MAX_THETAS = 180_000


def _theta_count(theta_step: float) -> int:
    return max(1, math.ceil(math.pi / theta_step - 1e-9))


def _rho_count(shape: tuple[int, ...], rho_step: float) -> int:
    """Half the number of ρ bins less one, k = ceil(hypot(H, W) / rho_step) (saturated at 2**62)."""
    reach = math.hypot(shape[0], shape[1]) / rho_step
    return math.ceil(reach - 1e-9) if reach < 2.0**62 else 2**62


def theta_samples(theta_step: float) -> np.ndarray:
    """θk = −π/2 + k·theta_step for k < ceil(π / theta_step) (a 1e-9 guard keeps π/step
    from rounding up a whole sample)."""
    return -math.pi / 2 + np.arange(_theta_count(theta_step)) * theta_step


def rho_samples(shape: tuple[int, int], rho_step: float) -> np.ndarray:
    """Bin centres rho_step·k for |k| ≤ ceil(hypot(H, W) / rho_step)."""
    k = _rho_count(shape, rho_step)
    return np.arange(-k, k + 1) * rho_step


@algorithm("detection.hough_lines", section="6.0.5", check="cvkit.detection.checks:hough_lines")
def hough_lines(edges: ArrayLike, theta_step: float = math.pi / 180,
                rho_step: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hough accumulator of the lines through the nonzero pixels of ``edges``.

    Parameters
    ----------
    edges : (H, W) array_like
        Edge map (bool or numeric); every nonzero pixel votes.
    theta_step : float
        Sampling step of θ in radians, ``π / 180000 <= theta_step <= π`` (at most
        :data:`MAX_THETAS` samples, 0.001°: each is a pass over the edge pixels).
    rho_step : float
        Width of a ρ bin in pixels, ``> 0``.

        Bounds: the accumulator may take at most 2 GiB, and the votes, about
        ``T·(6·n + 2·R)`` operations for T θ samples, R ρ bins and n edge pixels, at most
        ``cvkit._validation.MAX_WORK`` (2**36, about a minute): ``ValueError`` naming
        ``theta_step`` and ``rho_step`` otherwise.

    Returns
    -------
    accumulator : (len(rhos), len(thetas)) int64 ndarray
        Votes: ``accumulator[r, k]`` counts the edge pixels whose line at angle ``thetas[k]``
        has ``ρ`` nearest to ``rhos[r]``.
    thetas : float64 ndarray
        ``θk = −π/2 + k·theta_step`` for ``k < ceil(π / theta_step)``: [−π/2, π/2).
    rhos : float64 ndarray
        Bin centres ``rho_step·k`` for ``|k| <= ceil(hypot(H, W) / rho_step)``: the range
        ±diagonal, symmetric about 0.

    Notes
    -----
    §6.0.5. The pixel ``(x = col, y = row)`` votes, for each θ, into the bin
    ``floor(ρ / rho_step + 0.5)`` with ``ρ = x cos θ + y sin θ`` (the nearest centre, exact
    halves rounded up). θ is the angle of the line's *normal* from the x axis (y down), ρ the
    signed distance of the line from the top-left pixel; the (m, c) form y = m x + c cannot
    represent vertical lines, this one bounds both parameters. (A 1e-9 guard is applied to the
    two ``ceil``: π / (π/180) must give 180 samples, not 181.)

    With the defaults this is ``skimage.transform.hough_line(edges)`` (same θ samples, ρ
    centres −ceil(diag) … ceil(diag)), except that scikit-image rounds exact halves away from
    zero.

    Examples
    --------
    >>> import numpy as np
    >>> e = np.zeros((5, 5), bool); e[:, 2] = True     # the vertical line x = 2
    >>> acc, thetas, rhos = hough_lines(e, theta_step=np.pi / 4)
    >>> np.degrees(thetas), acc.shape
    (array([-90., -45.,   0.,  45.]), (17, 4))
    >>> int(acc.max()), float(rhos[acc[:, 2].argmax()])
    (5, 2.0)
    """
    e = as_float_array(edges, "edges", ndim=2)
    theta_step = check_real(theta_step, "theta_step", positive=True)
    if theta_step > math.pi:
        raise ValueError(f"theta_step must be <= π, got {theta_step}")
    rho_step = check_real(rho_step, "rho_step", positive=True)
    n_theta, n_rho = _theta_count(theta_step), 2 * _rho_count(e.shape, rho_step) + 1
    if n_theta > MAX_THETAS:
        raise ValueError(f"theta_step must be >= π/{MAX_THETAS} (at most {MAX_THETAS} θ samples), got {theta_step:g} "
                         f"({n_theta} samples)")
    if 8 * n_rho * n_theta > MAX_ARRAY_BYTES:
        raise ValueError(
            f"theta_step = {theta_step:g} and rho_step = {rho_step:g} ask for an accumulator of {n_rho} × {n_theta} "
            f"bins ({8 * n_rho * n_theta / 1024**3:.3g} GiB), more than the {MAX_ARRAY_BYTES / 1024**3:g} GiB cvkit "
            f"allows for one array; use larger steps")
    work = n_theta * (6 * int(np.count_nonzero(e)) + 2 * n_rho)
    if work > MAX_WORK:
        raise ValueError(
            f"theta_step = {theta_step:g} and rho_step = {rho_step:g}: voting in {n_rho} × {n_theta} bins needs about "
            f"{work:.2g} elementary operations, more than the {MAX_WORK:.2g} (about a minute of work) cvkit allows "
            f"for one call; use larger steps")
    thetas = theta_samples(theta_step)
    rhos = rho_samples(e.shape, rho_step)
    offset = (rhos.size - 1) // 2
    acc = np.zeros((rhos.size, thetas.size), dtype=np.int64)
    rows, cols = np.nonzero(e)
    if rows.size == 0:
        return acc, thetas, rhos
    x = cols.astype(np.float64)
    y = rows.astype(np.float64)
    for k, theta in enumerate(thetas):
        rho = x * math.cos(theta) + y * math.sin(theta)
        index = np.floor(rho / rho_step + 0.5).astype(np.int64) + offset
        acc[:, k] = np.bincount(index, minlength=rhos.size)
    return acc, thetas, rhos


@algorithm("detection.hough_peaks", section="6.0.5", check="cvkit.detection.checks:hough_peaks")
def hough_peaks(accumulator: ArrayLike, thetas: ArrayLike, rhos: ArrayLike, count: int = 10,
                threshold: float | None = None, min_distance: int = 5) -> np.ndarray:
    """The strongest lines of a Hough accumulator, by greedy non-maximum suppression.

    Parameters
    ----------
    accumulator : (R, T) array_like
        Votes from :func:`hough_lines` (rows ρ, columns θ), finite.
    thetas : (T,) array_like
        θ of each column.
    rhos : (R,) array_like
        ρ of each row.
    count : int
        At most this many lines, ``>= 0``.
    threshold : float or None
        Minimal number of votes; ``None`` means half the largest value of the accumulator.
    min_distance : int
        After a peak is taken, every bin whose ρ index *and* θ index both differ from it by at
        most ``min_distance`` is suppressed (index units; θ does not wrap around), ``>= 0``.

    Returns
    -------
    (K, 2) float64 ndarray
        ``(ρ, θ)`` of the peaks, strongest first, ``K <= count``; ``(0, 2)`` when none.

    Notes
    -----
    §6.0.5. Candidates are the bins with value ``>= threshold`` and ``> 0``, visited by
    decreasing value (ties in raster order of the accumulator: smaller ρ index first, then
    smaller θ index); a candidate not suppressed by an earlier peak becomes a peak and
    suppresses its (2·min_distance + 1)² neighbourhood. Compared with
    ``skimage.transform.hough_line_peaks``: the same greedy idea, but scikit-image first keeps
    only local maxima of a maximum filter, needs ``> threshold`` and wraps θ in its
    neighbourhood; on well-separated lines the peaks agree.

    Examples
    --------
    >>> import numpy as np
    >>> acc = np.array([[0, 1, 0, 0],
    ...                 [2, 9, 8, 0],
    ...                 [0, 3, 0, 7]])
    >>> hough_peaks(acc, np.array([0.0, 0.1, 0.2, 0.3]), np.array([-1.0, 0.0, 1.0]), min_distance=1)
    array([[0. , 0.1],
           [1. , 0.3]])
    >>> hough_peaks(acc, np.array([0.0, 0.1, 0.2, 0.3]), np.array([-1.0, 0.0, 1.0]), min_distance=0)
    array([[0. , 0.1],
           [0. , 0.2],
           [1. , 0.3]])
    """
    acc = as_float_array(accumulator, "accumulator", ndim=2)
    th = as_float_array(thetas, "thetas", ndim=1)
    rh = as_float_array(rhos, "rhos", ndim=1)
    if acc.shape != (rh.size, th.size):
        raise ValueError(
            f"accumulator must have shape (len(rhos), len(thetas)) = {(rh.size, th.size)}, got {acc.shape}"
        )
    count = check_int(count, "count", minimum=0)
    min_distance = check_int(min_distance, "min_distance", minimum=0)
    if threshold is None:
        threshold = 0.5 * float(acc.max())
    else:
        threshold = check_real(threshold, "threshold")
    flat = acc.reshape(-1)
    candidates = np.flatnonzero((flat >= threshold) & (flat > 0))
    order = candidates[np.argsort(-flat[candidates], kind="stable")]
    suppressed = np.zeros(acc.shape, dtype=bool)
    peaks: list[tuple[float, float]] = []
    width = acc.shape[1]
    for index in order:
        if len(peaks) >= count:
            break
        r, t = divmod(int(index), width)
        if suppressed[r, t]:
            continue
        peaks.append((rh[r], th[t]))
        suppressed[max(0, r - min_distance):r + min_distance + 1, max(0, t - min_distance):t + min_distance + 1] = True
    return np.array(peaks, dtype=np.float64).reshape(-1, 2)
