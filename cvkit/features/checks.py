"""Checks of Chapter 5's local features: cases, comparators and mistake banks for the grader.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference
(``cvkit.features.checks:harris`` grades ``features.harris``; ``KDTree`` grades the class).
Comparators defined here because features need them:

- :class:`PointSets` — point lists matched one to one within a radius (extra columns such as σ
  within a tolerance), optionally in a required order, reporting the missing and extra points;
- :class:`IndexRows` — integer rows (extrema, match pairs) compared as sets and then as lists,
  reporting missing and extra rows;
- :class:`Keypoints` — SIFT's ``(keypoints, descriptors)``: keypoints matched within small
  tolerances on position, σ and angle (modulo 2π) with close descriptors, recall and precision
  both at least ``min_fraction``;
- :class:`NeighbourSearch` — k-d tree answers: exact queries must equal brute force (ties to the
  smaller index); Best-Bin-First answers must be real neighbours with their true distances, exact
  when the budget covers every point, about as good as the reference's within the budget, and
  not better than a budget allows (a search that ignores ``max_checks`` is exact everywhere).

``features.KDTree`` is a class: its check calls it through
:func:`cvkit.grading.instance_call` (``Check.call``), so a case ``(points, "query", q)`` with
``{"k": 3}`` grades ``KDTree(points).query(q, k=3)``. Mistakes of that bank are classes too.

Public cases are tiny fixed inputs that already tell every mistake of the bank from the right
answer. Hidden cases are drawn from the grading seed: non-square, tiny, constant, uint8 and
large-valued inputs, every option value, and for every mistake inputs that expose it even where
natural images hide it (integer response maps with plateaus and values equal to the threshold;
DoG stacks with ties; blobs bright *and* dark of several sizes; patches whose strongest gradients
lie far from the keypoint; descriptor ratios between 0.8 and √0.8; duplicated points and
integer grids for the k-d tree's ties; tiny BBF budgets). SIFT pieces run on small images
(≤ 48×48) so that a student's loop version finishes quickly.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

import numpy as np

from ..edges import log as _log
from ..edges import sobel as _sobel
from ..edges.checks import Angles
from ..filters import gaussian as _gaussian
from ..filters import pad as _pad
from ..grading import Case, Check, Comparator, Measure, Mismatch, Mistake, close, instance_call, mistake
from ..grading.casekit import seed as _seed
from ..grading.measured import MeasuredCase, Scale
from ..grading.casekit import BORDERS, variant
from ..grading.casekit import distinct as _distinct
from ..grading.casekit import sigma as _sigma
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ..grading.compare import as_numeric, kind_words
from ._common import box_sum, window_max
from ._corners import SHIFTS
from ._corners import harris as _harris
from ._corners import structure_tensor as _structure_tensor
from ._matching import nearest_two
from ._measured import BUDGET_SECONDS, COUNT_SCALE, PRECISION_SCALE, TOLERANCE, correct_matches, sift_matches, warped_pair
from ._scale_space import NEIGHBOURS_26, _strict_extrema, derivatives_3d, double_size
from ._scale_space import dog_extrema as _dog_extrema
from ._scale_space import dog_pyramid as _dog_pyramid
from ._scale_space import gaussian_pyramid as _gaussian_pyramid
from ._scale_space import is_edge_like as _is_edge_like
from ._scale_space import refine_extremum as _refine_extremum
from ._sift import _differences, histogram_peaks
from ._sift import orientations as _orientations
from ._sift import sift_descriptor as _sift_descriptor

__all__ = [
    "PointSets", "IndexRows", "Keypoints", "NeighbourSearch",
    "moravec", "structure_tensor", "harris", "peaks", "gaussian_pyramid", "dog_pyramid", "log_blobs",
    "dog_extrema", "refine_extremum", "is_edge_like", "orientations", "sift_descriptor", "sift",
    "match_ratio", "KDTree", "BORDERS", "match_features", "CorrectMatches", "MATCH_COUNT_SCALE",
    "MATCH_PRECISION_SCALE",
]


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
def _fmt(row) -> str:
    return "(" + ", ".join(f"{float(v):.6g}" for v in row) + ")"


def _rows_of(got, columns: int, kinds: str, what: str):
    """``got`` as an (N, columns) array of dtype kind in ``kinds``, or a Mismatch."""
    arr, problem = as_numeric(got)
    if arr is None:
        return None, Mismatch(str(problem))
    if arr.dtype.kind not in kinds:
        want = kind_words(kinds)
        cast = ".astype(float)" if "f" in kinds else ".astype(np.int64)"
        return None, Mismatch(f"dtype mismatch: expected a {want} array of {what}, got {arr.dtype} (use {cast})")
    if arr.size == 0 and arr.ndim == 1:
        return None, Mismatch(f"shape mismatch: expected (N, {columns}) {what} — with none, shape (0, {columns}) "
                              f"(e.g. np.zeros((0, {columns}))), got {arr.shape}")
    if arr.ndim != 2 or arr.shape[1] != columns:
        return None, Mismatch(f"shape mismatch: expected (N, {columns}) {what}, got {arr.shape}")
    return arr, None


@dataclass
class PointSets(Comparator):
    """Point lists agree when their rows match one to one.

    Rows are ``(x, y, extra...)``: a got row matches an expected one when their (x, y) are
    within ``radius`` pixels (Euclidean) and every extra column within ``atol``. With
    ``ordered`` the matched rows must also come in the expected order. Messages say how many
    points are missing and extra, with the first of each, and whether (x, y) look swapped.
    """

    columns: int = 2
    radius: float = 1e-9
    atol: float = 1e-9
    ordered: bool = False
    what: str = "points (x, y)"
    order_hint: str = ""

    def describe(self) -> str:
        extra = f", other columns within {self.atol:g}" if self.columns > 2 else ""
        return f"{self.what} matched within {self.radius:g} px{extra}" + (" in order" if self.ordered else "")

    def _match(self, got: np.ndarray, exp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each expected row the index of its got row (−1: missing); which got rows are used."""
        assigned = np.full(len(exp), -1, dtype=np.int64)
        used = np.zeros(len(got), dtype=bool)
        if len(got) == 0 or len(exp) == 0:
            return assigned, used
        dist = np.sqrt(((exp[:, None, :2] - got[None, :, :2]) ** 2).sum(-1))
        ok = dist <= self.radius
        if self.columns > 2:
            ok &= np.all(np.abs(exp[:, None, 2:] - got[None, :, 2:]) <= self.atol, axis=2)
        cost = np.where(ok, dist, np.inf)
        for i in range(len(exp)):
            row = np.where(used, np.inf, cost[i])
            j = int(np.argmin(row))
            if np.isfinite(row[j]):
                assigned[i] = j
                used[j] = True
        return assigned, used

    def __call__(self, got, expected, case=None):
        exp = np.asarray(expected, dtype=np.float64).reshape(-1, self.columns)
        arr, problem = _rows_of(got, self.columns, "fiu" if self.columns > 2 else "f", self.what)
        if problem:
            return problem
        arr = arr.astype(np.float64)
        if not np.all(np.isfinite(arr)):
            return Mismatch(f"your {self.what} contain NaN or inf")
        assigned, used = self._match(arr, exp)
        missing = np.flatnonzero(assigned < 0)
        extra = np.flatnonzero(~used)
        if missing.size == 0 and extra.size == 0:
            if self.ordered and np.any(assigned != np.arange(len(exp))):
                first = int(np.flatnonzero(assigned != np.arange(len(exp)))[0])
                return Mismatch(
                    f"The {self.what} are right but in another order: row {first} should be {_fmt(exp[first])}, "
                    f"yours is {_fmt(arr[first])}" + (f" ({self.order_hint})" if self.order_hint else ""),
                    mismatched=int(np.sum(assigned != np.arange(len(exp)))), total=len(exp))
            return None
        lines = [f"{self.what.capitalize()} differ: expected {len(exp)}, yours {len(arr)}; "
                 f"{missing.size} expected not found within {self.radius:g} px"
                 + (f" (other columns within {self.atol:g})" if self.columns > 2 else "")
                 + f", {extra.size} of yours not expected"]
        if missing.size:
            lines.append(f"First missing: {_fmt(exp[missing[0]])}")
        if extra.size:
            lines.append(f"First extra:   {_fmt(arr[extra[0]])}")
        if len(arr) and len(exp):
            swapped = arr.copy()
            swapped[:, [0, 1]] = swapped[:, [1, 0]]
            a2, u2 = self._match(swapped, exp)
            if np.sum(a2 >= 0) > np.sum(assigned >= 0) and np.all(a2 >= 0):
                lines.append("With x and y exchanged yours would match: points are (x, y) = (col, row)")
        return Mismatch("\n".join(lines), mismatched=int(missing.size + extra.size), total=len(exp))


@dataclass
class IndexRows(Comparator):
    """Integer rows (``(octave, scale, row, col)``, ``(i, j)`` pairs) compared exactly: first as
    sets (reporting missing and extra rows), then in order (``order`` says which)."""

    columns: int
    names: str = ""
    order: str = "sorted lexicographically"

    def describe(self) -> str:
        return f"integer rows {self.names} equal, {self.order}"

    def __call__(self, got, expected, case=None):
        exp = np.asarray(expected, dtype=np.int64).reshape(-1, self.columns)
        arr, problem = _rows_of(got, self.columns, "iu", f"rows {self.names}".strip())
        if problem:
            return problem
        arr = arr.astype(np.int64)
        got_set = {tuple(r) for r in arr.tolist()}
        exp_set = {tuple(r) for r in exp.tolist()}
        missing = [r for r in exp.tolist() if tuple(r) not in got_set]
        extra = [r for r in arr.tolist() if tuple(r) not in exp_set]
        if not missing and not extra and len(arr) == len(exp):
            if np.array_equal(arr, exp):
                return None
            first = int(np.flatnonzero(np.any(arr != exp, axis=1))[0])
            return Mismatch(f"The rows are right but not {self.order}: row {first} should be {exp[first].tolist()}, "
                            f"yours is {arr[first].tolist()}", mismatched=len(exp), total=len(exp))
        lines = [f"Rows differ: expected {len(exp)}, yours {len(arr)}; {len(missing)} missing, {len(extra)} extra"
                 + (" (some repeated)" if len(got_set) < len(arr) else "")]
        if missing:
            lines.append(f"First missing {self.names}: {missing[0]}")
        if extra:
            lines.append(f"First extra {self.names}: {extra[0]}")
        return Mismatch("\n".join(lines), mismatched=len(missing) + len(extra), total=len(exp))


@dataclass
class Keypoints(Comparator):
    """SIFT outputs ``(keypoints (N, 4), descriptors (N, 128))`` agree when their keypoints
    match one to one — position within ``position`` px, σ within ``scale`` (relative), angle
    within ``angle`` rad modulo 2π, descriptors within ``descriptor`` (Euclidean) — except at
    most ``floor(slack · N)`` on each side (a correct version may decide a threshold the other
    way by round-off on a large image; on the small graded images every keypoint counts)."""

    position: float = 1e-3
    scale: float = 1e-3
    angle: float = 1e-3
    descriptor: float = 1e-3
    slack: float = 0.05

    def describe(self) -> str:
        return (f"keypoints matched within {self.position:g} px, σ ±{100 * self.scale:g}%, angle ±{self.angle:g} rad, "
                f"descriptors within {self.descriptor:g}; at most {100 * self.slack:g}% unmatched either way")

    def __call__(self, got, expected, case=None):
        if not isinstance(got, (tuple, list)) or len(got) != 2:
            return Mismatch("expected a tuple (keypoints, descriptors), got "
                            + (f"a {type(got).__name__} of {len(got)}" if isinstance(got, (tuple, list)) else type(got).__name__))
        kp_exp = np.asarray(expected[0], dtype=np.float64).reshape(-1, 4)
        de_exp = np.asarray(expected[1], dtype=np.float64).reshape(-1, 128)
        kp, problem = _rows_of(got[0], 4, "f", "keypoints (x, y, σ, angle)")
        if problem:
            problem.message = "keypoints: " + problem.message
            return problem
        de, problem = _rows_of(got[1], 128, "f", "descriptors")
        if problem:
            problem.message = "descriptors: " + problem.message
            return problem
        if len(de) != len(kp):
            return Mismatch(f"{len(kp)} keypoints but {len(de)} descriptors: one descriptor row per keypoint row")
        if not (np.all(np.isfinite(kp)) and np.all(np.isfinite(de))):
            return Mismatch("keypoints or descriptors contain NaN or inf")
        n_exp, n_got = len(kp_exp), len(kp)
        matched = np.full(n_exp, -1)
        used = np.zeros(n_got, dtype=bool)
        close_kp = np.zeros((n_exp, n_got), dtype=bool)
        if n_exp and n_got:
            pos = np.sqrt(((kp_exp[:, None, :2] - kp[None, :, :2]) ** 2).sum(-1)) <= self.position
            sig = np.abs(kp_exp[:, None, 2] - kp[None, :, 2]) <= self.scale * kp_exp[:, None, 2]
            ang = np.abs(np.mod(kp_exp[:, None, 3] - kp[None, :, 3] + np.pi, 2 * np.pi) - np.pi) <= self.angle
            close_kp = pos & sig & ang
            for i in range(n_exp):
                for j in np.flatnonzero(close_kp[i] & ~used):
                    if np.linalg.norm(de_exp[i] - de[j]) <= self.descriptor:
                        matched[i] = j
                        used[j] = True
                        break
        found = int((matched >= 0).sum())
        allowed = int(math.floor(self.slack * max(n_exp, n_got)))
        if n_exp - found <= allowed and n_got - found <= allowed:
            return None
        lines = [f"Keypoints differ: expected {n_exp}, yours {n_got}; {found} agree, {n_exp - found} expected ones "
                 f"missing, {n_got - found} of yours extra" + (f" (at most {allowed} allowed)" if allowed else "")]
        missing = np.flatnonzero(matched < 0)
        if missing.size:
            i = int(missing[0])
            lines.append(f"First expected keypoint without a match: {_fmt(kp_exp[i])}")
            if n_got:
                near = int(np.argmin(((kp[:, :2] - kp_exp[i, :2]) ** 2).sum(1)))
                lines.append(f"  your nearest keypoint: {_fmt(kp[near])}"
                             + (" (same keypoint, different descriptor)" if close_kp[i, near] else ""))
        extra = np.flatnonzero(~used)
        if extra.size:
            lines.append(f"First keypoint of yours not expected: {_fmt(kp[int(extra[0])])}")
        return Mismatch("\n".join(lines), mismatched=int(missing.size + extra.size), total=n_exp)


def _brute_force(points: np.ndarray, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Exact k nearest neighbours (distances, indices), ties to the smaller index."""
    diff = queries[:, None, :] - points[None, :, :]
    d = np.sqrt((diff * diff).sum(-1))
    idx = np.argsort(d, axis=1, kind="stable")[:, :k]
    return np.take_along_axis(d, idx, 1), idx


@dataclass
class NeighbourSearch(Comparator):
    """k-d tree answers ``(distances, indices)`` for a case ``(points, method, q)``.

    ``"query"``: indices equal to brute force (ties: the smaller index), distances within
    ``rtol``. ``"query_bbf"``: every row lists distinct valid indices with their true
    distances in ascending order; with ``max_checks ≥ N`` the answer is exact; otherwise, over
    at least ``min_queries`` queries, the fraction of queries whose true nearest neighbour is found (recall@1) must be at least the
    expected answer's minus ``margin``, and for budgets of a single check (``max_checks = 1``)
    at most ``max(max_tiny_recall, expected + 0.3)`` — an exact search there ignores the budget.
    Exact answers are compared with the expected ones (the reference's equal brute force).
    """

    rtol: float = 1e-9
    margin: float = 0.15
    max_tiny_recall: float = 0.6
    min_queries: int = 30

    def describe(self) -> str:
        return "nearest neighbours: exact queries equal brute force; BBF by recall within its budget"

    def __call__(self, got, expected, case=None):
        points, method, q = (np.asarray(case.args[0], dtype=np.float64), case.args[1], np.asarray(case.args[2], dtype=np.float64))
        exp_d, exp_i = (np.asarray(v) for v in expected)
        if not isinstance(got, (tuple, list)) or len(got) != 2:
            return Mismatch("expected a tuple (distances, indices), got "
                            + (f"a {type(got).__name__} of {len(got)}" if isinstance(got, (tuple, list)) else type(got).__name__))
        dist, problem = as_numeric(got[0], "your distances")
        if problem:
            return Mismatch(problem)
        idx, problem = as_numeric(got[1], "your indices")
        if problem:
            return Mismatch(problem)
        if idx.dtype.kind not in "iu":
            return Mismatch(f"indices must be integers, got {idx.dtype} (use .astype(np.int64))")
        if dist.dtype.kind != "f":
            return Mismatch(f"distances must be floats, got {dist.dtype}")
        for name, arr in (("distances", dist), ("indices", idx)):
            if arr.shape != exp_i.shape:
                hint = " (one query point of shape (D,) gives arrays of shape (k,))" if q.ndim == 1 else ""
                return Mismatch(f"{name}: shape mismatch: expected {exp_i.shape}, got {arr.shape}{hint}")
        queries = q.reshape(1, -1) if q.ndim == 1 else q
        n = len(queries)
        k = exp_i.size // n if n else 0
        if n == 0 or k == 0 or k * n != exp_i.size:
            return None if np.array_equal(idx, exp_i) and np.allclose(dist, exp_d) else Mismatch("results differ")
        d2, i2 = dist.reshape(n, k).astype(np.float64), idx.reshape(n, k).astype(np.int64)
        e_d, e_i = exp_d.reshape(n, k).astype(np.float64), exp_i.reshape(n, k).astype(np.int64)
        if method == "query":
            bad = np.flatnonzero(np.any(i2 != e_i, axis=1))
            if bad.size:
                r = int(bad[0])
                ties = np.allclose(np.sort(d2[r]), e_d[r]) and set(i2[r].tolist()) != set(e_i[r].tolist()) or \
                    np.allclose(d2[r], e_d[r])
                return Mismatch(
                    f"Indices differ from the exact nearest neighbours for {bad.size} of {n} queries\n"
                    f"First: query {r}: yours {i2[r].tolist()} at {np.round(d2[r], 6).tolist()}, expected "
                    f"{e_i[r].tolist()} at {np.round(e_d[r], 6).tolist()}"
                    + (" (equal distances: list the smaller index first)" if ties else ""),
                    mismatched=int(bad.size), total=n)
            return self._distances(d2, e_d)
        # Best-Bin-First
        if np.any((i2 < 0) | (i2 >= len(points))):
            return Mismatch(f"indices must be rows of points, 0..{len(points) - 1}")
        if k > 1 and np.any(np.sort(i2, axis=1)[:, 1:] == np.sort(i2, axis=1)[:, :-1]):
            return Mismatch("a query lists the same point twice: return k distinct points")
        real = np.sqrt(((queries[:, None, :] - points[i2]) ** 2).sum(-1))
        problem = self._distances(d2, real, "the true distances of the points you return")
        if problem:
            return problem
        if np.any(np.diff(d2, axis=1) < -self.rtol * np.abs(d2[:, 1:])):
            return Mismatch("distances must be in ascending order (nearest first)")
        budget = int(case.kwargs.get("max_checks", 200))
        if budget >= len(points):
            bad = np.flatnonzero(np.any(i2 != e_i, axis=1))
            if bad.size:
                r = int(bad[0])
                return Mismatch(f"with max_checks = {budget} ≥ N = {len(points)} every point can be checked, so the answer "
                                f"must be exact; {bad.size} of {n} queries differ (first: query {r}, yours "
                                f"{i2[r].tolist()}, expected {e_i[r].tolist()})", mismatched=int(bad.size), total=n)
            return None
        if n < self.min_queries:
            return None  # too few queries to judge a recall: the answers only need to be real neighbours
        _, true_i = _brute_force(points, queries, 1)
        recall = float(np.mean(i2[:, 0] == true_i[:, 0]))
        reference = float(np.mean(e_i[:, 0] == true_i[:, 0]))
        if recall < reference - self.margin:
            return Mismatch(f"Best-Bin-First found the true nearest neighbour of {100 * recall:.1f}% of the queries "
                            f"with max_checks = {budget}; the reference finds {100 * reference:.1f}% (at least "
                            f"{100 * (reference - self.margin):.1f}% needed): visit the bins nearest the query first")
        ceiling = max(self.max_tiny_recall, reference + 0.3)
        if budget == 1 and recall > ceiling:
            return Mismatch(f"with max_checks = 1 your search found the exact nearest neighbour of {100 * recall:.1f}% of "
                            f"the queries, which one distance computation cannot do (the reference: {100 * reference:.1f}%): "
                            "count every distance you compute and stop at max_checks")
        return None

    def _distances(self, got: np.ndarray, want: np.ndarray, what: str = "brute-force distances"):
        bad = ~(np.abs(got - want) <= self.rtol * np.maximum(1.0, np.abs(want)))
        if bad.any():
            r, c = (int(v) for v in np.argwhere(bad)[0])
            hint = " (squared? take the square root)" if np.isclose(got[r, c], want[r, c] ** 2) and want[r, c] != 1 else ""
            return Mismatch(f"distances differ from {what} in {int(bad.sum())} places; first [{r}, {c}]: yours "
                            f"{got[r, c]:.9g}, expected {want[r, c]:.9g}{hint}", mismatched=int(bad.sum()), total=int(got.size))
        return None


#: sums of products: loop and vectorised versions agree to ~1e-12 of the values' scale
_LINEAR = close(rtol=1e-7, atol=1e-10, kind="f", scaled=True)
_EXACT_BOOL = close(rtol=0.0, atol=0.0, kind="b")


# --------------------------------------------------------------------------------------------
# case helpers
# --------------------------------------------------------------------------------------------
def _texture(rng: np.random.Generator, h: int, w: int, smooth: float = 1.0, scale: float = 1.0) -> np.ndarray:
    """Random texture in [0, scale], lightly smoothed (reflect101): gradients in every direction."""
    img = rng.random((h, w))
    if smooth > 0:
        img = _gaussian(img, smooth)
    img = (img - img.min()) / max(img.max() - img.min(), 1e-12)
    return img * scale


def _frac(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A real coordinate in [lo, hi] whose fractional part is far from .5 and from 0."""
    while True:
        v = _u(rng, lo, hi)
        f = v - math.floor(v)
        if 0.08 < f < 0.42 or 0.58 < f < 0.92:
            return v


def _corner_image(h: int, w: int, rng: np.random.Generator | None = None, *, noise: float = 0.0) -> np.ndarray:
    """Two overlapping rectangles of different brightness: corners, edges and flat parts."""
    img = np.full((h, w), 0.2)
    img[h // 4: 3 * h // 4, w // 5: 3 * w // 5] = 0.8
    img[h // 2: h - 2, w // 2: w - 1] = 0.5
    if rng is not None and noise:
        img = img + rng.normal(0.0, noise, img.shape)
    return img


def _blob_image(shape, blobs, background=0.5, noise=0.0, rng=None) -> np.ndarray:
    """Gaussian blobs ``(x, y, s, amplitude)`` (negative amplitude: a dark blob) on a flat background."""
    h, w = shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    img = np.full(shape, float(background))
    for bx, by, s, a in blobs:
        img += a * np.exp(-((x - bx) ** 2 + (y - by) ** 2) / (2.0 * s * s))
    if noise and rng is not None:
        img += rng.normal(0.0, noise, shape)
    return img


# --------------------------------------------------------------------------------------------
# features.moravec (§5.6)
# --------------------------------------------------------------------------------------------
_AXIS_SHIFTS = ((-1, 0), (0, -1), (0, 1), (1, 0))


def _moravec_variant(image, window=7, border="reflect101", *, shifts=SHIFTS, reduce=np.minimum, mean=False,
                     sums=False, radius=None, pad_border=None):
    img = np.asarray(image, dtype=np.float64)
    r = window // 2 if radius is None else radius
    size = 2 * r + 1
    p = _pad(img, r + 1, pad_border or border)
    h, w = img.shape
    centre = p[1: h + 2 * r + 1, 1: w + 2 * r + 1]
    best = None
    for dy, dx in shifts:
        shifted = p[1 + dy: h + 2 * r + 1 + dy, 1 + dx: w + 2 * r + 1 + dx]
        if sums:
            value = (box_sum(shifted, size) - box_sum(centre, size)) ** 2
        else:
            value = box_sum((shifted - centre) ** 2, size)
        if mean:
            value = value / (size * size)
        best = value if best is None else reduce(best, value)
    return best


_mv = partial(variant, _moravec_variant)


def _moravec_hidden(rng):
    def img(h, w, kind="texture"):
        if kind == "texture":
            return _texture(rng, h, w, smooth=0.0)
        return _corner_image(h, w, rng, noise=0.02)

    return [
        Case((img(_size(rng, 8, 12), _size(rng, 9, 14)), 3), {"border": "reflect"}, "random image, 3×3, reflect"),
        Case((img(_size(rng, 9, 13), _size(rng, 8, 12)), 5), {"border": "replicate"}, "random image, 5×5, replicate"),
        Case((img(_size(rng, 12, 16), _size(rng, 14, 18), "corners"),), {}, "rectangles (corners), default 7×7"),
        Case((img(_size(rng, 10, 14), _size(rng, 10, 14)), 7), {"border": "zero"}, "random image, 7×7, zero border"),
        Case((np.round(255 * img(_size(rng, 7, 10), _size(rng, 8, 11))).astype(np.uint8), 3), {},
             "uint8 image (not rescaled)"),
        Case((img(_size(rng, 6, 9), _size(rng, 11, 15)) * 1000.0 - 500.0, 3), {"border": "reflect101"},
             "values ±500, non-square"),
        Case((np.full((_size(rng, 6, 9), _size(rng, 6, 9)), float(rng.uniform(0.1, 0.9))), 3), {},
             "constant image (no corners)"),
        Case((img(3, _size(rng, 6, 9)), 5), {"border": str(rng.choice(["reflect", "replicate"]))},
             "3-row image, window larger than the image"),
        Case((img(_size(rng, 8, 11), _size(rng, 8, 11), "corners"), 5), {"border": "replicate"},
             "rectangles, 5×5, replicate"),
        Case((img(_size(rng, 7, 10), _size(rng, 7, 10)), 9), {"border": "reflect101"}, "9×9 window"),
    ]


moravec = Check(
    rules=("uint8",),
    public=lambda: [
        Case((_distinct((7, 8), seed=3) / 10.0, 3), {}, "distinct values 7×8, 3×3 window"),
        Case((_corner_image(10, 11), 5), {"border": "replicate"}, "two rectangles, 5×5 window, replicate"),
    ],
    hidden=_moravec_hidden,
    compare=_LINEAR,
    mistakes=[
        Mistake("4 shifts instead of 8", _mv(shifts=_AXIS_SHIFTS),
                "Compare with the window moved by each of the 8 unit shifts, the diagonal ones included"),
        Mistake("mean instead of sum of squared differences", _mv(mean=True),
                "C(p) is the *sum* of the squared differences over the window, not their mean"),
        Mistake("max instead of min over the shifts", _mv(reduce=np.maximum),
                "Cornerness is the *smallest* SSD over the shifts: an edge has one direction with no change"),
        Mistake("difference of window sums instead of pixel by pixel", _mv(sums=True),
                "Square the difference of each pair of pixels, then sum: (ΣN(q) − ΣN(p))² is blind to patterns"),
        Mistake("border ignored (zero padding)", _mv(pad_border="zero"),
                "Pad the image with the requested border rule (np.pad modes), not always with zeros"),
        Mistake("window of radius `window` instead of window // 2", lambda image, window=7, border="reflect101":
                _moravec_variant(image, window, border, radius=window),
                "`window` is the side of the square: its radius is window // 2"),
    ],
    allowed=("filters.pad",),
)


# --------------------------------------------------------------------------------------------
# features.structure_tensor, features.harris (§5.7)
# --------------------------------------------------------------------------------------------
def _central(image):
    img = np.asarray(image, dtype=np.float64)
    p = _pad(img, 1, "reflect101")
    return 0.5 * (p[1:-1, 2:] - p[1:-1, :-2]), 0.5 * (p[2:, 1:-1] - p[:-2, 1:-1])


def _st_variant(image, sigma=1.0, *, window="gaussian", smooth_first=False, swap=False, derivative="sobel"):
    img = np.asarray(image, dtype=np.float64)
    ix, iy = _sobel(img) if derivative == "sobel" else _central(img)
    if window == "gaussian":
        blur = lambda a: _gaussian(a, sigma)  # noqa: E731
    elif window == "box":
        r = max(0, int(math.ceil(3.0 * sigma - 1e-9)))
        blur = lambda a: box_sum(_pad(a, r, "reflect101"), 2 * r + 1)  # noqa: E731
    else:
        blur = lambda a: a  # noqa: E731
    if smooth_first:
        ix, iy = blur(ix), blur(iy)
        out = (ix * ix, ix * iy, iy * iy)
    else:
        out = (blur(ix * ix), blur(ix * iy), blur(iy * iy))
    return (out[2], out[1], out[0]) if swap else out


_stv = partial(variant, _st_variant)


def _corner_images(rng):
    """(image, σ or None for the default, label) for the structure tensor and Harris."""
    return [
        (_texture(rng, _size(rng, 9, 13), _size(rng, 10, 15), smooth=0.0), _sigma(rng, 0.6, 0.9), "random image, small σ"),
        (_texture(rng, _size(rng, 12, 16), _size(rng, 11, 15), smooth=1.0), None, "smooth texture, default σ"),
        (_corner_image(_size(rng, 14, 18), _size(rng, 15, 20), rng, noise=0.01), _sigma(rng, 1.2, 2.0),
         "rectangles, σ > 1"),
        (np.round(255 * _texture(rng, _size(rng, 8, 11), _size(rng, 8, 11))).astype(np.uint8), None,
         "uint8 image (not rescaled)"),
        (_texture(rng, _size(rng, 7, 10), _size(rng, 12, 16)) * 2000.0 - 1000.0, _sigma(rng, 0.7, 1.6),
         "values ±1000, non-square"),
        (np.full((_size(rng, 6, 9), _size(rng, 6, 9)), float(rng.uniform(0.2, 0.8))), None, "constant image"),
        (_texture(rng, 2, _size(rng, 5, 8), smooth=0.0), None, "2-row image"),
        (_corner_image(_size(rng, 10, 13), _size(rng, 10, 13)), _sigma(rng, 0.5, 0.9), "rectangles, σ < 1"),
    ]


def _structure_tensor_hidden(rng):
    cases = [Case((image,), {} if sigma is None else {"sigma": sigma}, label) for image, sigma, label in _corner_images(rng)]
    cases.append(Case((_texture(rng, _size(rng, 11, 14), _size(rng, 9, 12), smooth=0.7), _sigma(rng, 1.1, 2.2)), {},
                      "σ given by position"))
    return cases


def _harris_hidden(rng):
    cases = []
    for i, (image, sigma, label) in enumerate(_corner_images(rng)):
        kwargs = {} if sigma is None else {"sigma": sigma}
        if i % 2 == 0:
            kwargs["k"] = _u(rng, 0.04, 0.06)
            label += f", k = {kwargs['k']:g}"
        cases.append(Case((image,), kwargs, label))
    cases.append(Case((_texture(rng, _size(rng, 10, 13), _size(rng, 10, 13), smooth=0.5),), {"k": 0.15}, "k = 0.15 (large)"))
    cases.append(Case((_texture(rng, _size(rng, 10, 13), _size(rng, 10, 13), smooth=0.5), 0.05, _sigma(rng, 1.1, 1.6)), {},
                      "k and σ given by position"))
    return cases


structure_tensor = Check(
    public=lambda: [
        Case((_distinct((8, 9), seed=5) / 72.0, 1.3), {}, "distinct values 8×9, σ = 1.3"),
        Case((_corner_image(10, 11),), {}, "two rectangles, default σ = 1"),
    ],
    hidden=_structure_tensor_hidden,
    compare=_LINEAR,
    mistakes=[
        Mistake("no Gaussian window (raw products)", _stv(window="none"),
                "Smooth each product Ix², IxIy, Iy² with the Gaussian window w of standard deviation σ"),
        Mistake("derivatives smoothed before multiplying", _stv(smooth_first=True),
                "Multiply first, then smooth: M sums Ix² over the window; (w∗Ix)² loses the spread of directions"),
        Mistake("x and y swapped (mxx and myy exchanged)", _stv(swap=True),
                "mxx is the smoothed Ix² (x along the columns), myy the smoothed Iy² (y down the rows)"),
        Mistake("central differences instead of Sobel", _stv(derivative="central"),
                "Take Ix, Iy from the Sobel kernels [[-1,0,1],[-2,0,2],[-1,0,1]] and its transpose"),
        Mistake("box window instead of a Gaussian", _stv(window="box"),
                "The window w is a Gaussian of standard deviation σ (radius ceil(3σ)), not a flat box"),
    ],
    allowed=("filters.pad", "filters.gaussian_kernel", "filters.gaussian", "filters.correlate", "edges.sobel"),
)


def _harris_variant(image, k=0.04, sigma=1.0, *, formula="R", window=True):
    mxx, mxy, myy = _structure_tensor(image, sigma) if window else _st_variant(image, sigma, window="none")
    det = mxx * myy - mxy * mxy
    trace = mxx + myy
    if formula == "R":
        return det - k * trace * trace
    if formula == "trace":
        return det - k * trace
    if formula == "plus":
        return det + k * trace * trace
    # Shi–Tomasi: the smaller eigenvalue
    return 0.5 * (trace - np.sqrt(np.maximum((mxx - myy) ** 2 + 4.0 * mxy * mxy, 0.0)))


_hv = partial(variant, _harris_variant)


harris = Check(
    public=lambda: [
        Case((_distinct((8, 9), seed=5) / 72.0,), {"k": 0.05, "sigma": 1.3}, "distinct values 8×9, k = 0.05, σ = 1.3"),
        Case((_corner_image(12, 13),), {}, "two rectangles, defaults"),
    ],
    hidden=_harris_hidden,
    compare=_LINEAR,
    mistakes=[
        Mistake("trace not squared", _hv(formula="trace"), "R = det(M) − k·trace(M)²: square the trace"),
        Mistake("k's sign flipped", _hv(formula="plus"), "Subtract k·trace(M)²; adding it makes edges look like corners"),
        Mistake("no Gaussian window", _hv(window=False),
                "Build M from the Gaussian-smoothed products (the structure tensor), not from the raw products: "
                "without the window det(M) = 0 everywhere"),
        Mistake("smallest eigenvalue (Shi–Tomasi) instead of R", _hv(formula="min"),
                "This exercise is Harris' R = det − k·trace², which needs no eigenvalues"),
    ],
    allowed=("filters.pad", "filters.gaussian_kernel", "filters.gaussian", "filters.correlate", "edges.sobel",
             "features.structure_tensor"),
)


# --------------------------------------------------------------------------------------------
# features.peaks (§5.6–5.7)
# --------------------------------------------------------------------------------------------
def _peaks_variant(response, threshold, radius=1, *, border=True, strict=False, rowcol=False, sort=True,
                   inclusive=False):
    values = np.asarray(response, dtype=np.float64)
    h, w = values.shape
    if strict:
        keep = np.ones(values.shape, dtype=bool)
        padded = np.full((h + 2 * radius, w + 2 * radius), -np.inf)
        padded[radius:radius + h, radius:radius + w] = values
        for dy in range(-radius, radius + 1):
            for dx in range(-radius, radius + 1):
                if dy or dx:
                    keep &= values > padded[radius + dy: radius + dy + h, radius + dx: radius + dx + w]
    else:
        keep = values >= window_max(values, radius)
    keep &= values >= threshold if inclusive else values > threshold
    if not border:
        inner = np.zeros(values.shape, dtype=bool)
        inner[radius:h - radius, radius:w - radius] = True
        keep &= inner
    rows, cols = np.nonzero(keep)
    if sort:
        order = np.argsort(-values[rows, cols], kind="stable")
        rows, cols = rows[order], cols[order]
    first, second = (rows, cols) if rowcol else (cols, rows)
    return np.stack([first, second], axis=1).astype(np.float64).reshape(-1, 2)


_pv = partial(variant, _peaks_variant)


_PEAKS_PUBLIC = np.array([
    [5, 1, 0, 0, 2, 2, 0],
    [1, 0, 0, 3, 0, 0, 1],
    [0, 0, 1, 0, 0, 7, 0],
    [4, 0, 0, 0, 0, 0, 2],
    [0, 0, 6, 0, 1, 0, 0],
    [0, 2, 0, 0, 0, 0, 3],
], dtype=np.float64)


def _int_map(rng, h, w, lo=0, hi=6):
    return rng.integers(lo, hi + 1, size=(h, w)).astype(np.float64)


def _threshold_on_a_peak(values: np.ndarray, radius: int = 1) -> float:
    """The value of a local maximum (≥ its window) that is neither the smallest nor the largest."""
    candidates = np.unique(values[values >= window_max(values, radius)])
    return float(candidates[len(candidates) // 2])


def _peaks_hidden(rng):
    smooth = _texture(rng, _size(rng, 12, 16), _size(rng, 12, 16), smooth=1.5)
    ties = _int_map(rng, _size(rng, 7, 9), _size(rng, 8, 10))
    return [
        Case((ties, _threshold_on_a_peak(ties)), {}, "integers with ties, threshold equal to a peak value"),
        Case((_int_map(rng, _size(rng, 7, 10), _size(rng, 6, 9), 0, 4), 1.0), {"radius": 2},
             "integers with plateaus, radius 2"),
        Case((_int_map(rng, _size(rng, 8, 11), _size(rng, 8, 11), -3, 3), -1.0), {},
             "negative values, negative threshold"),
        Case((_harris(_corner_image(_size(rng, 14, 18), _size(rng, 15, 20), rng, noise=0.01)), 1e-3), {"radius": 1},
             "Harris response of rectangles"),
        Case((smooth, float(np.round(np.quantile(smooth, 0.5), 6))), {"radius": 3}, "smooth texture, radius 3"),
        Case((_int_map(rng, _size(rng, 5, 8), _size(rng, 5, 8)), 0.5), {"radius": 0},
             "radius 0: every pixel above the threshold"),
        Case((_int_map(rng, _size(rng, 5, 8), _size(rng, 5, 8)), 100.0), {}, "nothing above the threshold: (0, 2)"),
        Case((_int_map(rng, 1, _size(rng, 9, 14)), 1.0), {}, "single row"),
        Case((rng.integers(0, 256, (_size(rng, 7, 9), _size(rng, 7, 9))).astype(np.uint8), 200), {},
             "uint8 response"),
        Case((np.full((_size(rng, 4, 6), _size(rng, 4, 6)), 3.0), 1.0), {}, "constant map: one plateau, all pixels"),
    ]


peaks = Check(
    public=lambda: [
        Case((_PEAKS_PUBLIC, 2.0), {}, "integers with a value equal to the threshold, peaks on the border"),
        Case((np.array([[1.0, 4.0, 4.0, 0.0, 2.0], [0.0, 1.0, 0.0, 0.0, 0.0], [3.0, 0.0, 0.0, 5.0, 5.0]]), 0.5),
             {"radius": 1}, "plateaus of equal peaks"),
        Case((_PEAKS_PUBLIC, 0.0), {"radius": 2}, "radius 2"),
    ],
    hidden=_peaks_hidden,
    compare=PointSets(columns=2, ordered=True, what="peaks (x, y)",
                      order_hint="strongest first, equal values in raster order"),
    mistakes=[
        Mistake("border pixels excluded", _pv(border=False),
                "Clip the window to the image: a pixel on the border is a peak when it beats the neighbours it has"),
        Mistake("strict maximum (plateaus dropped)", _pv(strict=True),
                "Keep pixels ≥ every value of their window (equal neighbours do not disqualify)"),
        Mistake("(row, col) instead of (x, y)", _pv(rowcol=True), "Points are (x, y) = (column, row)"),
        Mistake("not sorted by strength", _pv(sort=False),
                "Sort the peaks strongest first (a stable sort keeps equal values in raster order)"),
        Mistake("≥ threshold instead of >", _pv(inclusive=True), "A peak must be strictly above the threshold"),
    ],
)


# --------------------------------------------------------------------------------------------
# features.gaussian_pyramid, features.dog_pyramid (§5.8–5.9)
# --------------------------------------------------------------------------------------------
def _nearest_double(img: np.ndarray) -> np.ndarray:
    return np.repeat(np.repeat(img, 2, axis=0), 2, axis=1)


def _gp_variant(image, sigma0=1.6, scales=3, octaves=4, upsample=True, assumed_blur=0.5, *, levels="increment",
                base="reduced", double=True, next_from="s", nearest=False):
    img = np.asarray(image, dtype=np.float64)
    b = (2.0 if (upsample and double) else 1.0) * assumed_blur
    totals = [sigma0 * 2.0 ** (i / scales) for i in range(scales + 3)]
    start = (_nearest_double(img) if nearest else double_size(img)) if upsample else img
    first = _gaussian(start, math.sqrt(sigma0 ** 2 - b ** 2) if base == "reduced" else sigma0)
    pyramid = []
    for o in range(octaves):
        if o > 0:
            prev = pyramid[-1]
            first = prev[{"s": scales, "last": scales + 2, "first": 0}[next_from]][::2, ::2]
        stack = [first]
        for i in range(1, scales + 3):
            if levels == "increment":
                stack.append(_gaussian(stack[-1], math.sqrt(totals[i] ** 2 - totals[i - 1] ** 2)))
            elif levels == "total":
                stack.append(_gaussian(stack[-1], totals[i]))
            else:  # "direct": from level 0 in one step
                stack.append(_gaussian(first, math.sqrt(totals[i] ** 2 - totals[0] ** 2)))
        pyramid.append(np.stack(stack))
    return pyramid


_gpv = partial(variant, _gp_variant)


def _gp_hidden(rng):
    def tex(h, w):
        return _texture(rng, h, w, smooth=0.5)

    def s0():
        return _u(rng, 1.3, 2.0)

    return [
        Case((tex(_size(rng, 8, 11), _size(rng, 9, 12)),), {"octaves": 2}, "defaults, 2 octaves"),
        Case((tex(_size(rng, 8, 11), _size(rng, 8, 11)),), {"sigma0": s0(), "scales": 2, "octaves": 3},
             "2 scales, 3 octaves"),
        Case((tex(_size(rng, 12, 16), _size(rng, 10, 14)),), {"upsample": False, "octaves": 3, "sigma0": s0()},
             "no upsampling, 3 octaves"),
        Case((tex(_size(rng, 7, 9), _size(rng, 10, 13)),), {"assumed_blur": _u(rng, 0.2, 0.6, 2),
                                                             "octaves": 2}, "assumed blur given"),
        Case((tex(_size(rng, 6, 8), _size(rng, 6, 8)),), {"scales": 4, "octaves": 2, "sigma0": s0()}, "4 scales"),
        Case((np.round(255 * tex(_size(rng, 7, 9), _size(rng, 7, 9))).astype(np.uint8),), {"octaves": 2},
             "uint8 image (not rescaled)"),
        Case((tex(_size(rng, 5, 7), _size(rng, 5, 7)), s0(), 1, 3), {}, "1 scale, 3 octaves (positional)"),
        Case((np.full((_size(rng, 6, 8), _size(rng, 6, 8)), float(rng.uniform(0.2, 0.8))),), {"octaves": 2},
             "constant image"),
        Case((tex(3, _size(rng, 8, 12)),), {"octaves": 3}, "3-row image (octaves shrink to 2 rows)"),
        Case((tex(_size(rng, 9, 12), _size(rng, 9, 12)),), {"upsample": False, "assumed_blur": 0.0, "octaves": 2},
             "no upsampling, no assumed blur"),
    ]


gaussian_pyramid = Check(
    public=lambda: [
        Case((_distinct((5, 6), seed=11) / 30.0,), {"octaves": 2}, "distinct values 5×6, defaults, 2 octaves"),
        Case((_corner_image(8, 9),), {"sigma0": 1.8, "scales": 2, "octaves": 2, "upsample": False},
             "rectangles, σ0 = 1.8, 2 scales, no upsampling"),
    ],
    hidden=_gp_hidden,
    refusals=[
        Case((np.linspace(0.0, 1.0, 256).reshape(16, 16),), {"sigma0": 0.9, "octaves": 2},
             "σ0 = 0.9 not above the blur of the doubled input (2·assumed_blur = 1)", raises="ValueError"),
    ],
    compare=_LINEAR,
    mistakes=[
        Mistake("each level blurred by its total σ, not the increment", _gpv(levels="total"),
                "Level i − 1 already has blur σ_(i−1): blur it by sqrt(σ_i² − σ_(i−1)²) to reach σ_i"),
        Mistake("base blurred by σ0 (assumed blur ignored)", _gpv(base="full"),
                "The input already has some blur b: blur the base by sqrt(σ0² − b²) so that its total is σ0"),
        Mistake("assumed blur not doubled when upsampling", _gpv(double=False),
                "Doubling the image doubles its blur in pixels: use b = 2·assumed_blur when upsampling"),
        Mistake("next octave from the last level, not level s", _gpv(next_from="last"),
                "Start octave o + 1 from level `scales` (total blur 2σ0) of octave o, taken [::2, ::2]"),
        Mistake("nearest-neighbour upsampling", _gpv(nearest=True),
                "Upsample bilinearly: U[2i, 2j] = I[i, j], the new samples the means of their neighbours"),
        Mistake("levels blurred from level 0 in one step, not incrementally", _gpv(levels="direct"),
                "Blur each level from the previous one by the increment sqrt(σ_i² − σ_(i−1)²)"),
    ],
    allowed=("filters.pad", "filters.gaussian_kernel", "filters.gaussian", "filters.correlate"),
)


def _dp_variant(gaussian_pyramid, *, sign=1.0, from_first=False, short=False, first_only=False):
    stacks = [np.asarray(s, dtype=np.float64) for s in gaussian_pyramid]
    if first_only:
        stacks = stacks[:1]
    out = []
    for s in stacks:
        d = (s[1:] - s[:1]) if from_first else sign * (s[1:] - s[:-1])
        out.append(d[:-1] if short else d)
    return out


_dpv = partial(variant, _dp_variant)


def _random_stacks(rng, octaves, levels, h, w, dtype=np.float64):
    out = []
    for o in range(octaves):
        stack = np.cumsum(rng.random((levels, max(1, h >> o), max(1, w >> o))), axis=0)
        out.append(np.round(stack, 3).astype(dtype) if dtype == np.float64 else np.round(10 * stack).astype(dtype))
    return out


def _dp_hidden(rng):
    img = _texture(rng, _size(rng, 8, 11), _size(rng, 8, 11), smooth=0.5)
    return [
        Case((_gaussian_pyramid(img, octaves=2),), {}, "a real pyramid (defaults, 2 octaves)"),
        Case((_random_stacks(rng, 3, _size(rng, 4, 6), _size(rng, 6, 9), _size(rng, 6, 9)),), {},
             "3 octaves of random increasing stacks"),
        Case((_random_stacks(rng, 1, 2, _size(rng, 5, 8), _size(rng, 5, 8)),), {}, "one octave of 2 levels (1 DoG level)"),
        Case((_random_stacks(rng, 2, 6, 1, _size(rng, 8, 12)),), {}, "single-row levels"),
        Case((_random_stacks(rng, 2, 5, _size(rng, 6, 8), _size(rng, 6, 8), dtype=np.uint8),), {},
             "uint8 levels (subtract in float: no wrap-around)"),
        Case((_gaussian_pyramid(img, 1.4, 2, 3, False),), {}, "pyramid without upsampling, 2 scales, 3 octaves"),
        Case(([np.full((5, _size(rng, 4, 7), _size(rng, 4, 7)), 0.5)] * 2,), {}, "constant levels (all zeros)"),
        Case((_random_stacks(rng, 4, 3, _size(rng, 12, 16), _size(rng, 12, 16)),), {}, "4 octaves of 3 levels"),
    ]


dog_pyramid = Check(
    public=lambda: [
        Case((_gaussian_pyramid(_distinct((5, 6), seed=11) / 30.0, octaves=2),), {}, "pyramid of a 5×6 image, 2 octaves"),
        Case((_random_stacks(np.random.default_rng(5), 2, 4, 4, 5),), {}, "two random increasing stacks"),
    ],
    hidden=_dp_hidden,
    compare=_LINEAR,
    mistakes=[
        Mistake("reversed difference (level i − level i+1)", _dpv(sign=-1.0),
                "DoG level i is level i+1 − level i (the more blurred minus the less blurred)"),
        Mistake("differences with level 0, not the adjacent level", _dpv(from_first=True),
                "Subtract adjacent levels: level i+1 − level i, not level i+1 − level 0"),
        Mistake("one DoG level short", _dpv(short=True), "An octave of L Gaussian levels gives L − 1 DoG levels"),
        Mistake("only the first octave", _dpv(first_only=True), "Return one DoG stack per octave of the pyramid"),
    ],
)


# --------------------------------------------------------------------------------------------
# features.log_blobs (§5.8)
# --------------------------------------------------------------------------------------------
def _lb_variant(image, sigmas, threshold, *, power=2, maxima_only=False, per_scale=False, rowcol=False):
    img = np.asarray(image, dtype=np.float64)
    sig = np.asarray(sigmas, dtype=np.float64)
    stack = np.stack([s ** power * _log(img, float(s)) for s in sig])
    if per_scale:
        s_, h, w = stack.shape
        high = np.full((s_, h + 2, w + 2), -np.inf)
        low = np.full((s_, h + 2, w + 2), np.inf)
        high[:, 1:-1, 1:-1] = stack
        low[:, 1:-1, 1:-1] = stack
        is_max = np.ones(stack.shape, bool)
        is_min = np.ones(stack.shape, bool)
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                if dr or dc:
                    is_max &= stack > high[:, 1 + dr: 1 + dr + h, 1 + dc: 1 + dc + w]
                    is_min &= stack < low[:, 1 + dr: 1 + dr + h, 1 + dc: 1 + dc + w]
    else:
        is_max, is_min = _strict_extrema(stack)
    keep = (is_max if maxima_only else (is_max | is_min)) & (np.abs(stack) > threshold)
    index, rows, cols = np.nonzero(keep)
    first, second = (rows, cols) if rowcol else (cols, rows)
    return np.stack([first, second, sig[index]], axis=1).astype(np.float64).reshape(-1, 3)


_lbv = partial(variant, _lb_variant)


def _blob_specs(rng, h, w, count):
    """Well separated blobs, bright and dark, of different sizes, off the half-pixel grid."""
    specs = []
    sizes = rng.permutation([1.4, 1.9, 2.6, 3.2])[:count]
    for i, s in enumerate(sizes):
        for _ in range(200):
            x, y = _frac(rng, 5, w - 6), _frac(rng, 5, h - 6)
            if all(math.hypot(x - a, y - b) > 3.2 * (s + c) for a, b, c, _ in specs):
                break
        amplitude = _u(rng, 0.3, 0.5) * (1 if i % 2 == 0 else -1)
        specs.append((x, y, float(s), amplitude))
    return specs


_BLOB_SIGMAS = (1.2, 1.6, 2.1, 2.8, 3.7)


def _log_blobs_public():
    image = _blob_image((26, 30), [(8.3, 8.6, 1.5, 0.5), (20.2, 17.7, 2.6, -0.4), (21.6, 6.3, 1.9, 0.35)])
    image2 = _blob_image((22, 25), [(7.2, 13.7, 2.8, 0.45), (17.4, 8.2, 1.4, -0.5)], background=0.3)
    return [
        Case((image, _BLOB_SIGMAS, 0.05), {}, "bright and dark blobs of three sizes"),
        Case((image2, (1.0, 1.4, 2.0, 2.8, 4.0), 0.04), {}, "two blobs, σ from 1 to 4"),
    ]


def _log_blobs_hidden(rng):
    def blobs(h, w, n, noise=0.0, background=0.5):
        return _blob_image((h, w), _blob_specs(rng, h, w, n), background=background, noise=noise, rng=rng)

    def sigmas(lo=1.1, hi=3.9, n=5):
        return tuple(float(v) for v in np.round(np.geomspace(lo, hi, n) * rng.uniform(0.97, 1.03), 3))

    return [
        Case((blobs(_size(rng, 26, 30), _size(rng, 28, 32), 3), sigmas(), 0.05), {}, "three blobs, bright and dark"),
        Case((blobs(_size(rng, 24, 28), _size(rng, 24, 28), 2, noise=0.003), sigmas(n=6), 0.04), {},
             "two blobs with a little noise"),
        Case((blobs(_size(rng, 28, 32), _size(rng, 22, 26), 4), sigmas(1.0, 3.5, 4), 0.05), {}, "four blobs"),
        Case((np.round(255 * blobs(_size(rng, 24, 28), _size(rng, 26, 30), 3)).astype(np.uint8), sigmas(), 12.0), {},
             "uint8 image (threshold in 0..255 units)"),
        Case((blobs(_size(rng, 22, 26), _size(rng, 22, 26), 2, background=0.0) * 100.0, sigmas(1.2, 3.0, 4), 5.0), {},
             "values 0..50"),
        Case((_texture(rng, _size(rng, 18, 22), _size(rng, 18, 22), smooth=1.0), sigmas(1.0, 2.5, 4), 0.02), {},
             "smooth texture (many small blobs)"),
        Case((np.full((_size(rng, 14, 18), _size(rng, 14, 18)), 0.4), sigmas(1.0, 2.0, 3), 0.01), {},
             "constant image: no blob"),
        Case((blobs(_size(rng, 24, 28), _size(rng, 24, 28), 3), (2.0,), 0.05), {}, "a single σ (no scale neighbours)"),
        Case((blobs(_size(rng, 24, 28), _size(rng, 26, 30), 3), sigmas(1.2, 3.6, 3), 0.05), {}, "three σ only"),
        Case((blobs(_size(rng, 26, 30), _size(rng, 26, 30), 3), list(sigmas(1.1, 3.8, 5)), 0.08), {},
             "σ given as a list, higher threshold"),
    ]


log_blobs = Check(
    public=_log_blobs_public,
    hidden=_log_blobs_hidden,
    compare=PointSets(columns=3, what="blobs (x, y, σ)"),
    mistakes=[
        Mistake("no σ² normalisation", _lbv(power=0),
                "Multiply the LoG response by σ²: derivatives fade with σ, and without it large blobs are missed"),
        Mistake("σ instead of σ² normalisation", _lbv(power=1),
                "The scale-normalised Laplacian is σ²·∇²(G_σ ∗ I): second derivatives need σ²"),
        Mistake("maxima only (bright blobs are minima)", _lbv(maxima_only=True),
                "Keep minima too: the LoG is negative inside a bright blob"),
        Mistake("extrema of each scale separately (8, not 26 neighbours)", _lbv(per_scale=True),
                "Compare each sample with its neighbours in the scales above and below too (3×3×3)"),
        Mistake("(row, col, σ) instead of (x, y, σ)", _lbv(rowcol=True), "Points are (x, y) = (column, row)"),
    ],
    allowed=("filters.pad", "filters.correlate", "edges.log_kernel", "edges.log"),
)


# --------------------------------------------------------------------------------------------
# features.dog_extrema (§5.9)
# --------------------------------------------------------------------------------------------
_EIGHT = tuple((0, dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc)


def _de_variant(dog_pyramid, contrast_threshold=0.03, *, neighbours=NEIGHBOURS_26, ties=False, maxima_only=False,
                rowcol=False, divide=False, at_threshold=False):
    found = []
    for octave, stack in enumerate(dog_pyramid):
        d = np.asarray(stack, dtype=np.float64)
        levels, h, w = d.shape
        if levels < 3 or h < 3 or w < 3:
            continue
        thr = contrast_threshold / (levels - 2) if divide else contrast_threshold
        centre = d[1:-1, 1:-1, 1:-1]
        is_max = np.abs(centre) >= thr if at_threshold else np.abs(centre) > thr
        is_min = is_max.copy()
        for ds, dr, dc in neighbours:
            other = d[1 + ds: levels - 1 + ds, 1 + dr: h - 1 + dr, 1 + dc: w - 1 + dc]
            is_max &= (centre >= other) if ties else (centre > other)
            is_min &= (centre <= other) if ties else (centre < other)
        keep = is_max if maxima_only else (is_max | is_min)
        s, r, c = np.nonzero(keep)
        s, r, c = s + 1, r + 1, c + 1
        found.append(np.stack([np.full(s.size, octave), s, c, r] if rowcol else [np.full(s.size, octave), s, r, c], axis=1))
    if not found:
        return np.zeros((0, 4), dtype=np.int64)
    rows = np.concatenate(found).astype(np.int64)
    return rows[np.lexsort(rows.T[::-1])]


_dev = partial(variant, _de_variant)


def _normal_stacks(rng, octaves, levels, h, w, scale=1.0):
    return [np.round(rng.normal(0.0, scale, (levels, max(3, h >> o), max(3, w >> o))), 4) for o in range(octaves)]


def _tie_stacks(rng, octaves, levels, h, w):
    return [rng.integers(-3, 4, (levels, max(3, h >> o), max(3, w >> o))).astype(np.float64) for o in range(octaves)]


def _threshold_stack(rng, levels, h, w, threshold):
    """A stack of small integers with two planted strict extrema: one of |D| = threshold
    exactly (not kept: the contrast must exceed the threshold) and one above it."""
    d = rng.integers(-1, 2, (levels, h, w)).astype(np.float64)
    sign = float(rng.choice([-1.0, 1.0]))
    d[1, 2, 2] = sign * threshold
    d[levels - 2, h - 3, w - 3] = -sign * (threshold + 1.0)
    return [d]


def _dog_of(rng, h, w, octaves=2, **kwargs):
    img = _blob_image((h, w), _blob_specs(rng, h, w, 2), noise=0.01, rng=rng)
    return _dog_pyramid(_gaussian_pyramid(img, octaves=octaves, **kwargs))


def _dog_extrema_public():
    rng = np.random.default_rng(21)
    return [
        Case((_normal_stacks(rng, 2, 5, 9, 11), 1.8), {}, "random DoG stacks (2 octaves), threshold 1.8"),
        Case((_tie_stacks(rng, 1, 4, 7, 9), 1.5), {}, "integer stack with ties, threshold 1.5"),
        Case((_threshold_stack(rng, 4, 8, 9, 2.0), 2.0), {}, "an extremum of |D| = threshold exactly (not kept) and one above"),
    ]


def _dog_extrema_hidden(rng):
    return [
        Case((_normal_stacks(rng, 2, 5, _size(rng, 8, 11), _size(rng, 9, 13)), 1.7), {}, "random stacks, threshold 1.7"),
        Case((_normal_stacks(rng, 1, 4, _size(rng, 9, 12), _size(rng, 7, 10)),), {"contrast_threshold": 1.9},
             "random stack, threshold by keyword"),
        Case((_tie_stacks(rng, 2, 5, _size(rng, 7, 10), _size(rng, 8, 11)), 1.5), {}, "integer stacks with ties"),
        Case((_tie_stacks(rng, 1, 3, _size(rng, 8, 10), _size(rng, 8, 10)), 0.5), {}, "integer stack of 3 levels"),
        Case((_dog_of(rng, _size(rng, 12, 15), _size(rng, 12, 15)), 0.003), {}, "DoG pyramid of a blob image"),
        Case((_normal_stacks(rng, 3, 6, _size(rng, 12, 14), _size(rng, 12, 14), scale=0.01), 0.02), {},
             "3 octaves, values around 0.01"),
        Case((_normal_stacks(rng, 1, 5, _size(rng, 6, 8), _size(rng, 14, 18)), 1.7), {}, "non-square levels"),
        Case(([np.zeros((4, _size(rng, 5, 7), _size(rng, 5, 7)))], 0.0), {}, "all zeros: no extremum"),
        Case((_normal_stacks(rng, 1, 4, 3, _size(rng, 8, 11)), 0.5), {}, "3-row levels (one interior row)"),
        Case((_normal_stacks(rng, 2, 4, _size(rng, 8, 10), _size(rng, 8, 10)), 0.0), {}, "threshold 0"),
        _threshold_case(rng),
    ]


def _threshold_case(rng):
    threshold = float(_size(rng, 2, 4))
    stacks = _threshold_stack(rng, _size(rng, 3, 5), _size(rng, 7, 10), _size(rng, 7, 10), threshold)
    return Case((stacks, threshold), {}, "an extremum of |D| = threshold exactly (not kept) and one above")


dog_extrema = Check(
    public=_dog_extrema_public,
    hidden=_dog_extrema_hidden,
    compare=IndexRows(columns=4, names="(octave, scale, row, col)"),
    mistakes=[
        Mistake("8 neighbours in the level only, not 26", _dev(neighbours=_EIGHT),
                "Compare with the 9 samples in the level above and the 9 below too: 26 neighbours"),
        Mistake("ties accepted (≥ instead of >)", _dev(ties=True),
                "An extremum must be strictly greater (or smaller) than all 26 neighbours"),
        Mistake("maxima only", _dev(maxima_only=True), "Keep the minima too (strictly below all 26 neighbours)"),
        Mistake("row and col swapped", _dev(rowcol=True), "Rows are (octave, scale, row, col)"),
        Mistake("contrast equal to the threshold kept (≥ instead of >)", _dev(at_threshold=True),
                "Keep a sample only when |D| is strictly above the threshold: |D| > contrast_threshold"),
        Mistake("threshold divided by the number of scales", _dev(divide=True),
                "Use contrast_threshold as given here (SIFT divides by the number of scales before calling this)"),
    ],
)


# --------------------------------------------------------------------------------------------
# features.refine_extremum, features.is_edge_like (§5.9)
# --------------------------------------------------------------------------------------------
def _re_variant(dog_stack, scale, row, col, *, sign=-1.0, half_value=True, half_gradient=True, cross=True,
                reverse=False):
    d = np.asarray(dog_stack, dtype=np.float64)
    g, hessian = derivatives_3d(d, int(scale), int(row), int(col))
    if not half_gradient:
        g = 2.0 * g
    if not cross:
        hessian = np.diag(np.diag(hessian))
    x = sign * np.linalg.solve(hessian, g)
    value = d[scale, row, col] + (0.5 if half_value else 1.0) * float(g @ x)
    return (x[::-1] if reverse else x), value


_rev = partial(variant, _re_variant)


def _rotation3(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q


def _quadratic_stack(rng, shape, *, centre=None, sign=-1.0, noise=0.0, scale=1.0):
    """A 3-D quadratic with cross terms around a sub-sample centre (+ noise): a DoG extremum."""
    levels, h, w = shape
    if centre is None:
        centre = (rng.uniform(0.75, levels - 1.75), rng.uniform(1.7, h - 2.7), rng.uniform(1.7, w - 2.7))
    q = _rotation3(rng)
    curv = q @ np.diag(rng.uniform(0.2, 1.0, 3)) @ q.T
    s, r, c = np.mgrid[0:levels, 0:h, 0:w].astype(np.float64)
    off = np.stack([s - centre[0], r - centre[1], c - centre[2]], axis=-1)
    values = 1.0 + sign * np.einsum("...i,ij,...j->...", off, curv, off)
    if noise:
        values = values + rng.normal(0.0, noise, values.shape)
    return values * scale, tuple(int(np.clip(np.rint(v), 1, n - 2)) for v, n in zip(centre, shape))


def _refine_public():
    rng = np.random.default_rng(31)
    d1, (s1, r1, c1) = _quadratic_stack(rng, (4, 7, 8), noise=0.01)
    d2, (s2, r2, c2) = _quadratic_stack(rng, (3, 6, 7), sign=1.0, scale=0.02, noise=0.0005)
    return [
        Case((d1, s1, r1, c1), {}, "a maximum with cross terms"),
        Case((d2, s2, r2, c2), {}, "a minimum, values around 0.02"),
    ]


def _refine_hidden(rng):
    cases = []
    for label, kw in (("maximum with cross terms", {}), ("minimum with cross terms", {"sign": 1.0}),
                      ("noisy maximum", {"noise": 0.05}), ("values × 1000", {"scale": 1000.0}),
                      ("values × 0.01 (DoG units)", {"scale": 0.01, "sign": 1.0, "noise": 0.0002})):
        shape = (_size(rng, 3, 5), _size(rng, 5, 9), _size(rng, 5, 9))
        d, (s, r, c) = _quadratic_stack(rng, shape, **kw)
        cases.append(Case((d, s, r, c), {}, label))
    d, _ = _quadratic_stack(rng, (3, 5, 5), centre=(1.0, 2.0, 2.0), noise=0.02)
    cases.append(Case((d, 1, 2, 2), {}, "the smallest stack (3×5×5)"))
    d = rng.normal(0.0, 1.0, (_size(rng, 4, 5), _size(rng, 6, 8), _size(rng, 6, 8)))
    cases.append(Case((d, 1, 1, d.shape[2] - 2), {}, "random stack, a corner sample (scale 1, row 1, last col)"))
    d = rng.integers(-5, 6, (4, 6, 7)).astype(np.float64)
    d[2, 3, 3] = 20.0
    cases.append(Case((d, 2, 3, 3), {}, "integer stack"))
    d, (s, r, c) = _quadratic_stack(rng, (5, 9, 9), noise=0.01)
    s2, r2, c2 = min(3, s + 1), min(7, r + 1), max(1, c - 1)
    cases.append(Case((d, s2, r2, c2), {}, "a sample next to the extremum (offset near 1)"))
    d, (s, r, c) = _quadratic_stack(rng, (4, 7, 6), noise=0.0)
    cases.append(Case((d.astype(np.float32), s, r, c), {}, "float32 stack"))
    return cases


refine_extremum = Check(
    public=_refine_public,
    hidden=_refine_hidden,
    refusals=[
        Case((np.arange(5 * 8 * 8, dtype=np.float64).reshape(5, 8, 8) % 7, 0, 3, 3), {},
             "a sample on the first level of the stack (no level below)", raises="ValueError"),
        Case((np.ones((5, 8, 8)), 2, 3, 3), {}, "a flat stack: the Hessian is singular", raises="ValueError"),
    ],
    compare=close(rtol=1e-7, atol=1e-9, kind="f", scaled=True),
    mistakes=[
        Mistake("offset sign flipped (+H⁻¹∇D)", _rev(sign=1.0),
                "The stationary point of D + ∇Dᵀx + ½xᵀHx is x̂ = −H⁻¹∇D"),
        Mistake("value without the ½", _rev(half_value=False), "D(x̂) = D + ½·∇Dᵀx̂ (the quadratic term halves it)"),
        Mistake("gradient without the ½ (plain differences)", _rev(half_gradient=False),
                "Central differences divide by 2: (D[+1] − D[−1]) / 2"),
        Mistake("Hessian without its cross terms", _rev(cross=False),
                "Include the mixed derivatives (D[+1,+1] − D[+1,−1] − D[−1,+1] + D[−1,−1]) / 4"),
        Mistake("offset in (col, row, scale) order", _rev(reverse=True), "Return the offset as (ds, dr, dc)"),
    ],
)


def _el_variant(dog_slice, row, col, r=10.0, *, ratio_test="curvature", det_check=True, cross=True, invert=False,
                strict=False):
    d = np.asarray(dog_slice, dtype=np.float64)
    i, j = int(row), int(col)
    v = d[i, j]
    dxx = d[i, j + 1] + d[i, j - 1] - 2.0 * v
    dyy = d[i + 1, j] + d[i - 1, j] - 2.0 * v
    dxy = 0.25 * (d[i + 1, j + 1] - d[i + 1, j - 1] - d[i - 1, j + 1] + d[i - 1, j - 1]) if cross else 0.0
    trace, det = dxx + dyy, dxx * dyy - dxy * dxy
    limit = (r + 1.0) ** 2 / r if ratio_test == "curvature" else r
    with np.errstate(all="ignore"):
        edge = trace * trace / det > limit if strict else trace * trace / det >= limit
    if det_check:
        edge = edge or det <= 0
    return bool(not edge if invert else edge)


_elv = partial(variant, _el_variant)


def _quadratic_slice(rng, size, ratio, angle, *, sign=-1.0, saddle=False, noise=0.0, scale=1.0):
    """A 2-D quadratic with principal curvatures in the given ratio, rotated by ``angle``."""
    h, w = size
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    cy, cx = (h - 1) / 2 + rng.uniform(-0.3, 0.3), (w - 1) / 2 + rng.uniform(-0.3, 0.3)
    u = (x - cx) * math.cos(angle) + (y - cy) * math.sin(angle)
    v = -(x - cx) * math.sin(angle) + (y - cy) * math.cos(angle)
    a, b = ratio, 1.0
    values = sign * (a * u * u + (-b if saddle else b) * v * v) * 0.01
    if noise:
        values = values + rng.normal(0.0, noise, values.shape)
    return values * scale, (h // 2, w // 2)


def _edge_public():
    rng = np.random.default_rng(41)
    blob, p = _quadratic_slice(rng, (5, 5), 2.0, 0.3)
    ridge, q = _quadratic_slice(rng, (5, 6), 40.0, 0.1)
    saddle, s = _quadratic_slice(rng, (5, 5), 3.0, 0.5, saddle=True)
    between, t = _quadratic_slice(rng, (5, 5), 9.0, 0.0)
    diagonal, u = _quadratic_slice(rng, (5, 5), 30.0, math.pi / 4)
    return [
        Case((blob, *p), {}, "a blob (curvature ratio 2)"),
        Case((ridge, *q), {}, "a ridge (ratio 40)"),
        Case((saddle, *s), {}, "a saddle (curvatures of opposite signs)"),
        Case((between, *t), {}, "ratio 9: trace²/det between r and (r+1)²/r"),
        Case((diagonal, *u), {}, "a diagonal ridge (ratio 30 at 45°: Dxy carries it)"),
        Case((_edge_boundary(1, transpose=False), 2, 2), {}, "trace²/det exactly (r+1)²/r (the limit itself is edge-like)"),
    ]


def _edge_boundary(k: int, transpose: bool) -> np.ndarray:
    """A 5×5 slice whose centre has the integer curvatures Dxx = 10k, Dyy = k and Dxy = 0, so
    trace²/det = 121/10 = (r+1)²/r for r = 10 whatever the order of the arithmetic."""
    boundary = np.zeros((5, 5))
    boundary[2, 1] = boundary[2, 3] = 5.0 * k
    boundary[1, 2] = boundary[3, 2] = 0.5 * k
    return -boundary.T if transpose else boundary


def _edge_hidden(rng):
    def angle():
        return float(rng.uniform(0, math.pi))

    def size():
        return (_size(rng, 5, 9), _size(rng, 5, 9))

    cases = []
    specs = [
        ("blob", dict(ratio=float(rng.uniform(1.0, 3.0)), angle=angle()), {}),
        ("dark blob (a minimum)", dict(ratio=float(rng.uniform(1.0, 4.0)), angle=angle(), sign=1.0), {}),
        ("ridge", dict(ratio=float(rng.uniform(20.0, 60.0)), angle=angle()), {}),
        ("saddle", dict(ratio=float(rng.uniform(1.0, 4.0)), angle=angle(), saddle=True), {}),
        ("ratio between r and (r+1)²/r", dict(ratio=float(rng.uniform(8.3, 9.6)), angle=0.0), {}),
        ("diagonal ridge (45°)", dict(ratio=float(rng.uniform(20.0, 50.0)), angle=math.pi / 4 + rng.uniform(-0.05, 0.05)), {}),
        ("r = 5, ratio 5.6", dict(ratio=5.6, angle=angle()), {"r": 5.0}),
        ("r = 12, ratio 11", dict(ratio=11.0, angle=angle(), sign=1.0), {"r": 12.0}),
        ("noisy blob, values × 1000", dict(ratio=float(rng.uniform(1.5, 3.0)), angle=angle(), noise=0.001, scale=1000.0), {}),
        ("saddle, r = 3", dict(ratio=float(rng.uniform(2.0, 5.0)), angle=angle(), saddle=True, sign=1.0), {"r": 3.0}),
    ]
    for label, kw, extra in specs:
        values, (row, col) = _quadratic_slice(rng, size(), **kw)
        cases.append(Case((values, row, col), extra, label))
    boundary = _edge_boundary(int(rng.integers(1, 5)), transpose=bool(rng.random() < 0.5))
    cases.append(Case((boundary, 2, 2), {}, "trace²/det exactly (r+1)²/r (the limit itself is edge-like)"))
    return cases


is_edge_like = Check(
    public=_edge_public,
    hidden=_edge_hidden,
    compare=_EXACT_BOOL,
    mistakes=[
        Mistake("trace²/det compared with r, not (r+1)²/r", _elv(ratio_test="r"),
                "With curvatures α = rβ, trace²/det = (r+1)²/r: compare with that, not with r"),
        Mistake("negative determinant not rejected", _elv(det_check=False),
                "det ≤ 0 means curvatures of opposite signs (a saddle): reject it as edge-like"),
        Mistake("Hessian without Dxy", _elv(cross=False),
                "det = Dxx·Dyy − Dxy²: a diagonal edge shows only in the mixed derivative"),
        Mistake("the limit itself not edge-like (> instead of ≥)", _elv(strict=True),
                "A point is edge-like when trace²/det ≥ (r+1)²/r: the limit itself counts"),
        Mistake("answer inverted (True for good keypoints)", _elv(invert=True),
                "Return True when the point is edge-like (to be rejected)"),
    ],
)


# --------------------------------------------------------------------------------------------
# features.orientations (§5.11)
# --------------------------------------------------------------------------------------------
def _or_variant(gaussian_image, x, y, sigma, bins=36, peak_ratio=0.8, *, magnitude=True, weighting=True,
                interpolate=True, all_peaks=True, y_up=False, floor=False):
    img = np.asarray(gaussian_image, dtype=np.float64)
    dx, dy = _differences(img)
    if y_up:
        dy = -dy
    h, w = img.shape
    cx, cy = round(x), round(y)
    radius = round(4.5 * sigma)
    rr, cc = np.mgrid[max(1, cy - radius): min(h - 2, cy + radius) + 1, max(1, cx - radius): min(w - 2, cx + radius) + 1]
    rr, cc = rr.ravel(), cc.ravel()
    gx, gy = dx[rr, cc], dy[rr, cc]
    vote = np.sqrt(gx * gx + gy * gy) if magnitude else np.ones(rr.size)
    if weighting:
        vote = vote * np.exp(-((cc - x) ** 2 + (rr - y) ** 2) / (2.0 * (1.5 * sigma) ** 2))
    if not magnitude:
        vote = np.where((gx == 0) & (gy == 0), 0.0, vote)  # a flat pixel has no direction
    position = np.arctan2(gy, gx) * (bins / (2.0 * math.pi))
    index = (np.floor(position) if floor else np.rint(position)).astype(np.int64) % bins
    hist = np.bincount(index, weights=vote, minlength=bins)
    angles = histogram_peaks(hist[None], peak_ratio)[0]
    if not interpolate:
        top = hist.max()
        left, right = np.roll(hist, 1), np.roll(hist, -1)
        chosen = np.flatnonzero((hist > left) & (hist > right) & (hist >= peak_ratio * top) & (top > 0))
        chosen = chosen[np.argsort(-hist[chosen], kind="stable")]
        angles = chosen * (2.0 * math.pi / bins)
    return angles[:1] if not all_peaks else angles


_orv = partial(variant, _or_variant)


def _roof(shape, centre, slopes, angles, crease_angle, offset, texture=None, noise_level=0.0):
    """Two planes meeting along a line (a roof): two gradient directions on either side.

    The crease runs at ``crease_angle`` through ``centre`` moved by ``offset`` across it; the
    plane on each side rises along its own ``angles[i]`` with slope ``slopes[i]``."""
    h, w = shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    cx, cy = centre
    n = (-math.sin(crease_angle), math.cos(crease_angle))
    side = (x - cx) * n[0] + (y - cy) * n[1] - offset
    planes = [s * ((x - cx) * math.cos(a) + (y - cy) * math.sin(a)) for s, a in zip(slopes, angles)]
    img = np.where(side < 0, planes[0], planes[1])
    if texture is not None:
        img = img + noise_level * texture
    return img


def _orientation_patch(rng, size, kind):
    h, w = size
    x, y = _frac(rng, w / 2 - 1.5, w / 2 + 1.5), _frac(rng, h / 2 - 1.5, h / 2 + 1.5)
    sigma = _u(rng, 1.3, 2.2)
    tex = _texture(rng, h, w, smooth=1.0)
    if kind == "texture":
        return _gaussian(tex, 1.2), x, y, sigma
    if kind == "roof":  # two directions of similar strength
        a = float(rng.uniform(0, 2 * math.pi))
        img = _roof((h, w), (x, y), (0.05, float(rng.uniform(0.04, 0.06))), (a, a + float(rng.uniform(1.2, 2.4))),
                    a + 0.3, float(rng.uniform(-1.0, 1.0)), tex, 0.02)
        return _gaussian(img, 0.8), x, y, sigma
    # "far": weak gradients near the keypoint, strong ones far away (Gaussian weighting decides)
    a = float(rng.uniform(0, 2 * math.pi))
    img = _roof((h, w), (x, y), (0.02, 0.09), (a, a + float(rng.uniform(1.5, 2.5))), a + float(rng.uniform(-0.3, 0.3)),
                2.2 * sigma, tex, 0.01)
    return _gaussian(img, 0.8), x, y, sigma


def _orientations_public():
    rng = np.random.default_rng(51)
    img, x, y, s = _orientation_patch(rng, (27, 29), "texture")
    roof, x2, y2, s2 = _orientation_patch(rng, (25, 25), "roof")
    far, x3, y3, s3 = _orientation_patch(rng, (31, 31), "far")
    return [
        Case((img, x, y, s), {}, "smooth texture"),
        Case((roof, x2, y2, s2), {"peak_ratio": 0.5}, "two planes (a roof): two directions, peak_ratio 0.5"),
        Case((far, x3, y3, s3), {"bins": 24}, "strong gradients far from the keypoint, 24 bins"),
    ]


def _orientations_hidden(rng):
    cases = []
    for kind, kwargs, label in (
            ("texture", {}, "smooth texture"),
            ("texture", {"bins": 18}, "smooth texture, 18 bins"),
            ("roof", {"peak_ratio": 0.5}, "roof: two directions, peak_ratio 0.5"),
            ("roof", {}, "roof, default peak_ratio"),
            ("far", {}, "strong gradients far from the keypoint"),
            ("far", {"bins": 12, "peak_ratio": 0.6}, "far gradients, 12 bins"),
            ("texture", {"peak_ratio": 0.3}, "texture, peak_ratio 0.3 (many peaks)")):
        img, x, y, s = _orientation_patch(rng, (_size(rng, 24, 30), _size(rng, 24, 30)), kind)
        cases.append(Case((img, x, y, s), kwargs, label))
    img, x, y, s = _orientation_patch(rng, (_size(rng, 24, 28), _size(rng, 24, 28)), "texture")
    cases.append(Case((img, _frac(rng, 2, 4), _frac(rng, 2, 4), s), {}, "keypoint near the corner (window clipped)"))
    img, x, y, s = _orientation_patch(rng, (_size(rng, 24, 28), _size(rng, 24, 28)), "roof")
    cases.append(Case((np.round(255 * img / max(1e-9, np.abs(img).max())).astype(np.int16), x, y, s), {"peak_ratio": 0.5},
                      "integer image"))
    cases.append(Case((np.full((_size(rng, 15, 20), _size(rng, 15, 20)), 0.3), 8.2, 7.7, 1.5), {}, "flat patch: no orientation"))
    return cases


orientations = Check(
    public=_orientations_public,
    hidden=_orientations_hidden,
    compare=Angles(atol=1e-6),
    mistakes=[
        Mistake("votes not weighted by the gradient magnitude", _orv(magnitude=False),
                "Each pixel votes with its gradient magnitude (times the Gaussian), not with 1"),
        Mistake("no Gaussian weighting", _orv(weighting=False),
                "Weight each vote by a Gaussian of σ_w = 1.5σ centred on the keypoint: far pixels count less"),
        Mistake("no parabolic interpolation", _orv(interpolate=False),
                "Refine each peak with the parabola through the bin and its two neighbours"),
        Mistake("only the highest peak", _orv(all_peaks=False),
                "Every strict local maximum ≥ peak_ratio × the highest bin gives an orientation"),
        Mistake("y axis up (atan2(−dy, dx))", _orv(y_up=True),
                "y points down the rows: θ = atan2(L[r+1, c] − L[r−1, c], L[r, c+1] − L[r, c−1])"),
        Mistake("bins by floor instead of round", _orv(floor=True),
                "Bin k is centred on k·2π/bins: bin = round(θ·bins/2π) mod bins"),
    ],
)


# --------------------------------------------------------------------------------------------
# features.sift_descriptor (§5.12)
# --------------------------------------------------------------------------------------------
def _desc_variant(gaussian_image, x, y, sigma, angle, *, trilinear=True, clip=True, renormalise=True, weighting=True,
                  relative=True, rotate=True):
    img = np.asarray(gaussian_image, dtype=np.float64)
    dx, dy = _differences(img)
    h, w = img.shape
    cx, cy = round(x), round(y)
    radius = min(round(3 * sigma * math.sqrt(2) * 2.5), int(math.ceil(math.hypot(h, w))))
    rr, cc = np.mgrid[max(1, cy - radius): min(h - 2, cy + radius) + 1, max(1, cx - radius): min(w - 2, cx + radius) + 1]
    rr, cc = rr.ravel(), cc.ravel()
    ox, oy = cc - x, rr - y
    t = angle if rotate else 0.0
    u = (ox * math.cos(t) + oy * math.sin(t)) / (3 * sigma)
    v = (oy * math.cos(t) - ox * math.sin(t)) / (3 * sigma)
    rbin, cbin = v + 1.5, u + 1.5
    keep = (rbin > -1) & (rbin < 4) & (cbin > -1) & (cbin < 4)
    rr, cc, u, v, rbin, cbin = rr[keep], cc[keep], u[keep], v[keep], rbin[keep], cbin[keep]
    gx, gy = dx[rr, cc], dy[rr, cc]
    m = np.sqrt(gx * gx + gy * gy)
    if weighting:
        m = m * np.exp(-(u * u + v * v) / 8.0)
    obin = np.mod((np.arctan2(gy, gx) - (angle if relative else 0.0)) * (8 / (2 * math.pi)), 8)
    hist = np.zeros((6, 6, 10))
    if trilinear:
        r0, c0, o0 = np.floor(rbin), np.floor(cbin), np.floor(obin)
        fr, fc, fo = rbin - r0, cbin - c0, obin - o0
        for a, wa in ((0, 1 - fr), (1, fr)):
            for b, wb in ((0, 1 - fc), (1, fc)):
                for e, we in ((0, 1 - fo), (1, fo)):
                    np.add.at(hist, ((r0 + 1 + a).astype(int), (c0 + 1 + b).astype(int), (o0.astype(int) % 8) + e),
                              m * wa * wb * we)
    else:
        r0 = np.rint(rbin).astype(int)
        c0 = np.rint(cbin).astype(int)
        o0 = np.rint(obin).astype(int) % 8
        np.add.at(hist, (r0 + 1, c0 + 1, o0), m)
    hist[..., 0] += hist[..., 8]
    vec = hist[1:5, 1:5, :8].reshape(-1)
    norm = np.linalg.norm(vec)
    if norm == 0:
        return vec
    vec = vec / norm
    if clip:
        vec = np.minimum(vec, 0.2)
        if renormalise:
            vec = vec / np.linalg.norm(vec)
    return vec


_dsv = partial(variant, _desc_variant)


def _descriptor_patch(rng, size, kind="texture"):
    h, w = size
    tex = _texture(rng, h, w, smooth=1.0)
    if kind == "edges":  # a few strong edges: some entries exceed 0.2 before clipping
        img = _corner_image(h, w) + 0.02 * tex
        return _gaussian(img, 1.0)
    return _gaussian(tex, 1.2)


def _descriptor_public():
    rng = np.random.default_rng(61)
    return [
        Case((_descriptor_patch(rng, (40, 42)), 20.3, 19.8, 1.6, 0.7), {}, "smooth texture, angle 0.7"),
        Case((_descriptor_patch(rng, (38, 40), "edges"), 18.7, 19.2, 1.4, 2.5), {}, "rectangles (strong edges), angle 2.5"),
    ]


def _descriptor_hidden(rng):
    def angle():
        return _u(rng, 0.2, 2 * math.pi - 0.2, 4)

    def xy(size):
        return _frac(rng, size[1] / 2 - 1.5, size[1] / 2 + 1.5), _frac(rng, size[0] / 2 - 1.5, size[0] / 2 + 1.5)

    cases = []
    for kind, sigma_range, label in (("texture", (1.2, 1.7), "texture"), ("edges", (1.2, 1.6), "strong edges"),
                                     ("texture", (1.6, 2.0), "texture, larger σ"), ("edges", (1.3, 1.8), "edges, other angle")):
        size = (_size(rng, 38, 44), _size(rng, 38, 44))
        cases.append(Case((_descriptor_patch(rng, size, kind), *xy(size), _u(rng, *sigma_range), angle()),
                          {}, label))
    size = (_size(rng, 36, 40), _size(rng, 36, 40))
    cases.append(Case((_descriptor_patch(rng, size), *xy(size), 1.5, 0.0), {}, "angle 0"))
    cases.append(Case((_descriptor_patch(rng, size), *xy(size), 1.4, -1.1), {}, "negative angle"))
    cases.append(Case((_descriptor_patch(rng, size, "edges"), _frac(rng, 5, 8), _frac(rng, 5, 8), 1.5, angle()), {},
                      "keypoint near the corner (patch clipped)"))
    cases.append(Case((np.round(200 * _descriptor_patch(rng, size)).astype(np.uint8), *xy(size), 1.5, angle()), {},
                      "uint8 image"))
    cases.append(Case((np.full(size, 0.4), *xy(size), 1.5, angle()), {}, "flat patch: the zero vector"))
    cases.append(Case((_descriptor_patch(rng, (30, 48)), _frac(rng, 22, 26), _frac(rng, 13, 16), 1.2, angle()), {},
                      "non-square image"))
    return cases


sift_descriptor = Check(
    public=_descriptor_public,
    hidden=_descriptor_hidden,
    compare=close(rtol=1e-6, atol=1e-8, kind="f"),
    mistakes=[
        Mistake("hard binning instead of trilinear interpolation", _dsv(trilinear=False),
                "Split each vote between the 2 nearest cell rows, 2 cell columns and 2 orientation bins"),
        Mistake("no 0.2 clipping", _dsv(clip=False), "Normalise, clip every entry at 0.2, normalise again"),
        Mistake("clipped at 0.2 but not renormalised", _dsv(renormalise=False),
                "After clipping at 0.2, normalise the vector to unit length again"),
        Mistake("no Gaussian weighting", _dsv(weighting=False),
                "Weight each vote by exp(−(u² + v²)/8), a Gaussian of 2 cells in the keypoint's frame"),
        Mistake("orientations not relative to the keypoint angle", _dsv(relative=False),
                "Bin θ − angle: relative gradient directions make the descriptor rotation invariant"),
        Mistake("patch not rotated to the keypoint angle", _dsv(rotate=False),
                "Rotate the sample offsets into the keypoint's frame before assigning cells"),
    ],
)


# --------------------------------------------------------------------------------------------
# features.sift (§5.14.1)
# --------------------------------------------------------------------------------------------
def _sift_variant(image, sigma0=1.6, scales=3, octaves=None, upsample=True, contrast_threshold=0.04, edge_ratio=10.0,
                  assumed_blur=0.5, border=5, max_steps=5, *, edges=True, refine=True, to_input=True, divide=True,
                  level="scale"):
    from ._sift import OFFSET_LIMIT, _default_octaves

    img = np.asarray(image, dtype=np.float64)
    if octaves is None:
        octaves = _default_octaves((2 * img.shape[0], 2 * img.shape[1]) if upsample else img.shape)
    pyramid = _gaussian_pyramid(img, sigma0, scales, octaves, upsample, assumed_blur)
    dog = _dog_pyramid(pyramid)
    threshold = contrast_threshold / scales if divide else contrast_threshold
    converged = []
    for o, s, r, c in _dog_extrema(dog, 0.5 * threshold).tolist():
        h, w = dog[o].shape[1:]
        if not (border <= r < h - border and border <= c < w - border):
            continue
        if not refine:
            converged.append((o, s, r, c, np.zeros(3), float(dog[o][s, r, c])))
            continue
        for _ in range(max_steps):
            try:
                x, value = _refine_extremum(dog[o], s, r, c)
            except ValueError:
                break
            if np.all(np.abs(x) < OFFSET_LIMIT):  # 0.6, as the reference (IPOL, VLFeat)
                converged.append((o, s, r, c, x, value))
                break
            step = np.rint(x).astype(int)
            s, r, c = s + int(step[0]), r + int(step[1]), c + int(step[2])
            if not (1 <= s <= scales and border <= r < h - border and border <= c < w - border):
                break
    keypoints, descriptors, seen = [], [], set()
    for o, s, r, c, x, value in sorted(converged, key=lambda item: item[:4]):
        if (o, s, r, c) in seen or abs(value) < threshold:
            continue
        seen.add((o, s, r, c))
        if edges and _is_edge_like(dog[o][s], r, c, edge_ratio):
            continue
        px, py, sigma = c + x[2], r + x[1], sigma0 * 2.0 ** ((s + x[0]) / scales)
        gauss = pyramid[o][s if level == "scale" else 0]
        factor = 2.0 ** o / (2.0 if upsample else 1.0) if to_input else 1.0
        for angle in _orientations(gauss, px, py, sigma):
            keypoints.append((px * factor, py * factor, sigma * factor, angle))
            descriptors.append(_sift_descriptor(gauss, px, py, sigma, angle))
    return np.array(keypoints).reshape(-1, 4), np.array(descriptors).reshape(-1, 128)


_sfv = partial(variant, _sift_variant)


def _sift_image(rng, size, blobs=2, rectangles=1, noise=0.01, lines=3):
    """Blobs (bright and dark), rectangles (straight edges, corners) and thin elongated ridges
    (DoG extrema that only the edge test rejects) in [0, 1]."""
    h, w = size
    img = _blob_image(size, _blob_specs(rng, h, w, blobs), background=0.45) if blobs else np.full(size, 0.45)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    for _ in range(lines):
        cx, cy, a = _frac(rng, 0.3 * w, 0.7 * w), _frac(rng, 0.3 * h, 0.7 * h), float(rng.uniform(0, math.pi))
        u = (x - cx) * math.cos(a) + (y - cy) * math.sin(a)
        v = -(x - cx) * math.sin(a) + (y - cy) * math.cos(a)
        long, short = float(rng.uniform(7.0, 10.0)), float(rng.uniform(0.9, 1.3))
        img += float(rng.choice([-0.3, 0.3])) * np.exp(-u * u / (2 * long * long) - v * v / (2 * short * short))
    for _ in range(rectangles):
        r0, c0 = _size(rng, 3, h // 2 - 2), _size(rng, 3, w // 2 - 2)
        r1, c1 = _size(rng, r0 + 8, h - 3), _size(rng, c0 + 8, w - 3)
        img[r0:r1, c0:c1] += float(rng.choice([-0.25, 0.25]))
    img = img + rng.normal(0.0, noise, size)
    return np.clip(img, 0.0, 1.0)


def _sift_public():
    rng = np.random.default_rng(71)
    return [
        Case((_sift_image(rng, (40, 44), blobs=3, rectangles=1),), {}, "blobs and a rectangle, defaults"),
        Case((_sift_image(rng, (36, 38), blobs=2, rectangles=2),), {"upsample": False, "scales": 2},
             "no upsampling, 2 scales"),
    ]


def _sift_hidden(rng):
    def size(lo=32, hi=40):
        return (_size(rng, lo, hi), _size(rng, lo, hi))

    return [
        Case((_sift_image(rng, size(), 3, 1),), {}, "blobs and a rectangle, defaults"),
        Case((_sift_image(rng, size(), 2, 2),), {}, "two rectangles (edges and corners)"),
        Case((_sift_image(rng, size(36, 44), 3, 1),), {"upsample": False}, "no upsampling"),
        Case((_sift_image(rng, size(), 2, 1),), {"scales": 2}, "2 scales per octave"),
        Case((_sift_image(rng, size(), 3, 1),), {"contrast_threshold": 0.02}, "lower contrast threshold 0.02"),
        Case((_sift_image(rng, size(), 2, 2),), {"edge_ratio": 5.0}, "edge ratio 5"),
        Case((_sift_image(rng, size(28, 34), 2, 1),), {"octaves": 2, "border": 4}, "2 octaves, border 4"),
        Case((_sift_image(rng, (_size(rng, 24, 28), _size(rng, 44, 52)), 2, 1),), {}, "non-square image"),
        Case((np.full(size(20, 24), 0.5),), {}, "flat image: no keypoint"),
        Case((_sift_image(rng, size(), 3, 0, noise=0.02, lines=1),), {"sigma0": 1.8}, "blobs, σ0 = 1.8"),
        Case((_sift_image(rng, size(), 1, 0, noise=0.005, lines=4),), {}, "thin ridges (edge-like extrema)"),
    ]


sift = Check(
    public=_sift_public,
    hidden=_sift_hidden,
    compare=Keypoints(),
    mistakes=[
        Mistake("no edge rejection", _sfv(edges=False),
                "Drop extrema whose principal curvatures differ too much (is_edge_like): they slide along edges"),
        Mistake("no sub-pixel refinement", _sfv(refine=False),
                "Refine each extremum with Newton steps (refine_extremum), moving while an |offset| ≥ 0.5"),
        Mistake("positions left in octave pixels", _sfv(to_input=False),
                "Map keypoints back to the input: x, y and σ times 2^o, halved when the image was upsampled"),
        Mistake("contrast threshold not divided by the number of scales", _sfv(divide=False),
                "The threshold is contrast_threshold / scales (0.04 / 3 with the defaults)"),
        Mistake("orientation and descriptor on level 0 of the octave", _sfv(level="first"),
                "Use the Gaussian level of the keypoint's own scale for its orientations and descriptor"),
    ],
    allowed=("filters.pad", "filters.gaussian_kernel", "filters.gaussian", "filters.correlate",
             "features.gaussian_pyramid", "features.dog_pyramid", "features.dog_extrema", "features.refine_extremum",
             "features.is_edge_like", "features.orientations", "features.sift_descriptor"),
    time_limit=60.0,
)


# --------------------------------------------------------------------------------------------
# features.match_ratio (§5.13)
# --------------------------------------------------------------------------------------------
def _mr_variant(desc1, desc2, ratio=0.8, *, squared=False, test=True, strict=False, zero_ok=False, swap=False):
    a = np.asarray(desc1, dtype=np.float64)
    b = np.asarray(desc2, dtype=np.float64)
    j, d1, d2 = nearest_two(a, b)
    if squared:
        d1, d2 = d1 * d1, d2 * d2
    if not test:
        keep = np.ones(len(a), dtype=bool)
    else:
        keep = (d1 < ratio * d2) if strict else (d1 <= ratio * d2)
        if not zero_ok:
            keep &= d2 > 0
    i = np.flatnonzero(keep)
    pairs = np.stack([j[keep], i] if swap else [i, j[keep]], axis=1)
    return pairs.astype(np.int64).reshape(-1, 2)


_mrv = partial(variant, _mr_variant)


def _match_case(rng, n1, n2, dim, *, specials=("squared", "equal", "duplicate"), scale=1.0, ratio=0.8):
    """Descriptors: a cloud around 50 (half the queries near a row of desc2: good matches), and
    near the origin hand-made queries whose distance ratio d1/d2 is 0.85 (passes only if squared),
    exactly 0.8 (4 and 5: passes only with ≤), or 0/0 (a duplicated row: needs d2 > 0)."""
    cloud2 = 50.0 + rng.normal(0.0, 1.0, (n2, dim))
    picks = rng.choice(n2, size=n1 // 2, replace=False)
    cloud1 = np.vstack([cloud2[picks] + rng.normal(0.0, 0.05, (len(picks), dim)),
                        50.0 + rng.normal(0.0, 1.0, (n1 - len(picks), dim))])
    extra1, extra2 = [], []
    for t, kind in enumerate(specials):
        centre = np.zeros(dim)
        centre[t % dim] = 20.0 * (t + 1)
        if kind == "squared":  # d1 = 0.85·d2: inside the test on squared distances only
            u, v = np.linalg.qr(rng.normal(size=(dim, 2)))[0].T
            extra1.append(centre)
            extra2 += [centre + 0.85 * u, centre + 1.0 * v]
        elif kind == "equal":  # d1 = 4 = 0.8 · 5 exactly (integer coordinates)
            a, b = centre.copy(), centre.copy()
            a[(t + 1) % dim] += 4.0
            b[(t + 2) % dim] += 5.0
            extra1.append(centre)
            extra2 += [a, b]
        elif kind == "duplicate":  # two copies of the query: d1 = d2 = 0
            extra1.append(centre)
            extra2 += [centre, centre]
    desc1 = np.vstack([cloud1] + [np.array(extra1)] if extra1 else [cloud1]) * scale
    desc2 = np.vstack([cloud2] + [np.array(extra2)] if extra2 else [cloud2]) * scale
    return desc1[rng.permutation(len(desc1))], desc2[rng.permutation(len(desc2))]


def _match_public():
    rng = np.random.default_rng(81)
    d1, d2 = _match_case(rng, 10, 12, 6)
    e1, e2 = _match_case(rng, 8, 9, 4, specials=("equal", "squared"))
    return [
        Case((d1, d2), {}, "good matches, a ratio of 0.85, a ratio of exactly 0.8, a duplicated row"),
        Case((e1, e2), {"ratio": 0.8}, "4-D descriptors, ratio given"),
    ]


def _match_hidden(rng):
    def case(n1, n2, dim, **kw):
        return _match_case(rng, n1, n2, dim, **kw)

    sift_like = np.abs(rng.normal(0, 1, (_size(rng, 20, 30), 32)))
    sift_like /= np.linalg.norm(sift_like, axis=1, keepdims=True)
    queries = sift_like[rng.choice(len(sift_like), 10, replace=False)] + rng.normal(0, 0.03, (10, 32))
    return [
        Case(case(_size(rng, 10, 16), _size(rng, 12, 18), 8), {}, "all special ratios, 8-D"),
        Case(case(_size(rng, 8, 12), _size(rng, 8, 12), 4, specials=("squared",)), {}, "ratio 0.85 (squared test)"),
        Case(case(_size(rng, 8, 12), _size(rng, 8, 12), 5, specials=("equal",)), {}, "ratio exactly 0.8 (≤)"),
        Case(case(_size(rng, 8, 12), _size(rng, 8, 12), 6, specials=("duplicate",)), {}, "a duplicated row (d2 = 0)"),
        Case(case(_size(rng, 12, 20), _size(rng, 14, 22), 16, specials=()), {"ratio": 0.6}, "ratio 0.6, 16-D"),
        Case(case(_size(rng, 12, 20), _size(rng, 14, 22), 16, specials=()), {"ratio": 0.95}, "ratio 0.95"),
        Case((queries, sift_like), {}, "unit descriptors (SIFT-like, 32-D)"),
        Case(case(1, 2, 4, specials=()), {}, "one query, two candidates"),
        Case((np.round(case(_size(rng, 8, 12), _size(rng, 8, 12), 6, specials=("equal", "duplicate"))[0]),
              np.round(case(_size(rng, 8, 12), _size(rng, 8, 12), 6, specials=("equal", "duplicate"))[1])), {},
             "integer descriptors (ties)"),
        Case(case(_size(rng, 8, 12), _size(rng, 8, 12), 8, scale=1e3), {}, "descriptors × 1000"),
    ]


match_ratio = Check(
    public=_match_public,
    hidden=_match_hidden,
    refusals=[
        Case((np.eye(4, 8), np.ones((1, 8))), {}, "desc2 with a single row: no second-nearest neighbour",
             raises="ValueError"),
    ],
    compare=IndexRows(columns=2, names="(i, j)", order="in increasing i"),
    mistakes=[
        Mistake("ratio test on squared distances", _mrv(squared=True),
                "Compare distances, not squared distances: d1 ≤ ratio·d2 (squared, the threshold would be ratio²)"),
        Mistake("no ratio test (every nearest neighbour)", _mrv(test=False),
                "Keep a match only when d1 ≤ ratio·d2, d1 and d2 the distances to the nearest and second nearest"),
        Mistake("strict < instead of ≤", _mrv(strict=True), "Accept d1 = ratio·d2: the test is d1 ≤ ratio·d2"),
        Mistake("zero second distance accepted", _mrv(zero_ok=True),
                "With d2 = 0 the two nearest are identical: the match is ambiguous, reject it (d2 > 0)"),
        Mistake("pairs as (j, i)", _mrv(swap=True), "Return pairs (i, j): i indexes desc1, j desc2"),
    ],
)


# --------------------------------------------------------------------------------------------
# features.KDTree (§5.14): a class, graded through instance_call
# --------------------------------------------------------------------------------------------
class _Tree:
    """A plain recursive k-d tree (one point per leaf, median split cycling the axes) whose
    knobs make the mistakes of the bank. The unmodified class is a correct alternative."""

    backtrack = True          # exact query: also visit the far side when it may hold closer points
    larger_first = False      # equal distances: the larger index first
    squared = False           # return squared distances
    plane_vs_squared = False  # pruning compares |q − split| with the *squared* k-th distance
    ignore_budget = False     # BBF: never stop (an exact search)
    depth_first = False       # BBF: visit the far branches in depth-first order, not nearest first
    flat_single = True        # a (D,) query gives (k,) arrays

    def __init__(self, points):
        self.points = np.asarray(points, dtype=np.float64).copy()
        self.root = self._build(np.arange(len(self.points)), 0)

    def _build(self, idx, depth):
        if len(idx) == 1:
            return ("leaf", int(idx[0]))
        axis = depth % self.points.shape[1]
        idx = idx[np.lexsort((idx, self.points[idx, axis]))]
        mid = len(idx) // 2
        return ("node", axis, float(self.points[idx[mid], axis]), self._build(idx[:mid], depth + 1),
                self._build(idx[mid:], depth + 1))

    def _key(self, d2, i):
        return (d2, -i) if self.larger_first else (d2, i)

    def _offer(self, best, q, i, k):
        diff = self.points[i] - q
        d2 = float(diff @ diff)
        best.append((self._key(d2, i), i, d2))
        best.sort()
        del best[k:]

    def _exact(self, node, q, k, best):
        if node[0] == "leaf":
            self._offer(best, q, node[1], k)
            return
        _, axis, split, left, right = node
        near, far = (left, right) if q[axis] <= split else (right, left)
        self._exact(near, q, k, best)
        if not self.backtrack:
            return
        gap = q[axis] - split
        worst = best[-1][2] if len(best) == k else np.inf
        if (abs(gap) if self.plane_vs_squared else gap * gap) <= worst:
            self._exact(far, q, k, best)

    def _bbf(self, q, k, budget):
        import heapq

        best, queue, checks, count = [], [(0.0, 0, self.root)], 0, 1
        while queue and (self.ignore_budget or checks < budget):
            bound, _, node = heapq.heappop(queue) if not self.depth_first else queue.pop()
            if len(best) == k and bound > best[-1][2]:
                if self.depth_first:
                    continue
                break
            while node[0] == "node":
                _, axis, split, left, right = node
                near, far = (left, right) if q[axis] <= split else (right, left)
                item = (max(bound, (q[axis] - split) ** 2), count, far)
                count += 1
                if self.depth_first:
                    queue.append(item)
                else:
                    heapq.heappush(queue, item)
                node = near
            self._offer(best, q, node[1], k)
            checks += 1
        return best

    def _answer(self, q, k, search):
        q = np.asarray(q, dtype=np.float64)
        single = q.ndim == 1
        rows = [search(row) for row in np.atleast_2d(q)]
        d = np.array([[np.sqrt(b[2]) if not self.squared else b[2] for b in r] for r in rows])
        i = np.array([[b[1] for b in r] for r in rows], dtype=np.int64)
        return (d[0], i[0]) if single and self.flat_single else (d, i)

    def query(self, q, k=1):
        def traverse(row):
            best = []
            self._exact(self.root, row, k, best)
            return best

        def brute(row):  # a full search finds the exact neighbours: brute force gives them faster
            diff = self.points - row
            d2 = (diff * diff).sum(1)
            order = np.lexsort((-np.arange(len(d2)) if self.larger_first else np.arange(len(d2)), d2))[:k]
            return [(None, int(i), float(d2[i])) for i in order]

        return self._answer(q, k, brute if self.backtrack and not self.plane_vs_squared else traverse)

    def query_bbf(self, q, k=2, max_checks=200):
        return self._answer(q, k, lambda row: self._bbf(row, k, max_checks))


def _tree_mistake(name, **knobs):
    return type(name, (_Tree,), dict(knobs))


class _NoBudget(_Tree):
    """BBF that never stops: the exact answer (computed by brute force, which gives the same
    result as searching the whole tree, much faster)."""

    def query_bbf(self, q, k=2, max_checks=200):
        q = np.asarray(q, dtype=np.float64)
        d, i = _brute_force(self.points, np.atleast_2d(q), k)
        return (d[0], i[0]) if q.ndim == 1 else (d, i)


def _clusters(rng, n, dim, centres=8, spread=0.08):
    """Points in clusters inside the unit cube (distances below 1: squared < plain)."""
    c = rng.random((centres, dim))
    return np.clip(c[rng.integers(0, centres, n)] + rng.normal(0.0, spread, (n, dim)), 0.0, 1.0)


def _grid_points(rng, n, dim, high=4):
    """Small integer coordinates with duplicates: exact ties everywhere."""
    return rng.integers(0, high + 1, (n, dim)).astype(np.float64)


def _kdtree_public():
    rng = np.random.default_rng(91)
    grid = _grid_points(rng, 40, 2)
    cube = _clusters(rng, 60, 3)
    wide = rng.random((300, 6))
    uniform = rng.random((600, 10))
    return [
        Case((grid, "query", _grid_points(rng, 6, 2) + 0.5 * rng.integers(0, 2, (6, 2))), {"k": 3},
             "integer points with duplicates (ties), k = 3"),
        Case((cube, "query", rng.random(3)), {"k": 2}, "one query point of shape (3,), points in the unit cube"),
        Case((wide, "query_bbf", rng.random((40, 6))), {"k": 1, "max_checks": 1}, "BBF with a budget of 1 check"),
        Case((uniform, "query_bbf", rng.random((200, 10))), {"k": 2, "max_checks": 64},
             "BBF, 600 points in 10-D, budget 64 (nearest bins first)"),
        Case((cube, "query_bbf", rng.random((10, 3))), {"k": 2, "max_checks": 60}, "BBF with max_checks = N (exact)"),
    ]


def _kdtree_hidden(rng):
    def cube(n, dim, **kw):
        return _clusters(rng, n, dim, **kw)

    grid = _grid_points(rng, _size(rng, 40, 60), 2)
    grid3 = _grid_points(rng, _size(rng, 30, 50), 3, high=3)
    big = cube(_size(rng, 300, 500), 6)
    uniform = rng.random((_size(rng, 550, 650), 10))
    small = cube(_size(rng, 20, 40), 4)
    return [
        Case((grid, "query", _grid_points(rng, 8, 2) + 0.5 * rng.integers(0, 2, (8, 2))), {"k": 4},
             "integer points with duplicates (ties), k = 4"),
        Case((grid3, "query", _grid_points(rng, 6, 3, high=3)), {"k": 1}, "queries on the points themselves (distance 0)"),
        Case((cube(_size(rng, 50, 80), 3), "query", rng.random(3)), {"k": 3}, "one query point of shape (D,)"),
        Case((big, "query", rng.random((30, 6))), {"k": 2}, "6-D points in the unit cube"),
        Case((small, "query", rng.random((5, 4))), {"k": len(small)}, "k = N (every point, sorted)"),
        Case((rng.normal(0, 100.0, (_size(rng, 30, 50), 1)), "query", rng.normal(0, 100.0, (7, 1))), {}, "1-D points, k = 1"),
        Case((big, "query_bbf", rng.random((40, 6))), {"k": 1, "max_checks": 1}, "BBF with a budget of 1 check"),
        Case((uniform, "query_bbf", rng.random((200, 10))), {"k": 2, "max_checks": int(rng.integers(56, 73))},
             "BBF, 600 points in 10-D, budget about 64 (nearest bins first)"),
        Case((small, "query_bbf", rng.random((8, 4))), {"k": 2, "max_checks": len(small)}, "BBF with max_checks = N (exact)"),
        Case((grid, "query_bbf", _grid_points(rng, 6, 2)), {"k": 3, "max_checks": 1000}, "BBF, budget above N, ties"),
        Case((big, "query_bbf", rng.random(6)), {"k": 2, "max_checks": 50}, "BBF, one query of shape (D,)"),
    ]


KDTree = Check(
    rules=("single point",),
    public=_kdtree_public,
    hidden=_kdtree_hidden,
    compare=NeighbourSearch(),
    mistakes=[
        Mistake("no backtracking (only the query's own leaf)", _tree_mistake("NoBacktracking", backtrack=False),
                "After the near branch, also search the far one when the splitting plane is closer than the k-th best"),
        Mistake("ties broken by the larger index", _tree_mistake("LargerFirst", larger_first=True),
                "Among equal distances list the smaller index first"),
        Mistake("squared distances returned", _tree_mistake("Squared", squared=True),
                "Return Euclidean distances: the square root of the sum of squared differences"),
        Mistake("plane distance compared with the squared distance", _tree_mistake("PlaneVsSquared", plane_vs_squared=True),
                "Prune with (q[axis] − split)² against the squared k-th distance (or both unsquared)"),
        Mistake("BBF ignores max_checks", _NoBudget,
                "Count every distance computation and stop once max_checks have been made"),
        Mistake("BBF visits branches depth first", _tree_mistake("DepthFirst", depth_first=True),
                "Keep the branches not taken in a priority queue and always resume with the one nearest the query"),
        Mistake("(1, k) arrays for a single query of shape (D,)", _tree_mistake("NotFlat", flat_single=False),
                "A single query point (D,) gives distances and indices of shape (k,)"),
    ],
    call=instance_call,
    arg_names=("points", "method", "q"),
)


# --------------------------------------------------------------------------------------------
# §5.14.1 the measured exercise: matching under a known warp, graded by its correct matches
# --------------------------------------------------------------------------------------------
#: the published scales of ``features.match_features``: correct matches, and their share
MATCH_COUNT_SCALE = Scale(COUNT_SCALE, percent=False)
MATCH_PRECISION_SCALE = Scale(PRECISION_SCALE)
#: what a candidate's matcher may call: SIFT, its building blocks and the ratio test (the grade is about
#: the matches; a student's own broken block then costs its points once)
_SIFT_BLOCKS = ("filters.pad", "filters.gaussian_kernel", "filters.gaussian", "filters.correlate",
                "features.gaussian_pyramid", "features.dog_pyramid", "features.dog_extrema",
                "features.refine_extremum", "features.is_edge_like", "features.orientations",
                "features.sift_descriptor", "features.sift", "features.match_ratio")


def _warped_case(seed: int, label: str, where: bool) -> MeasuredCase:
    """A case of :func:`warped_pair`; its label describes the picture and the warp only when
    ``where`` (the public case): a hidden pair's warp stays unknown, even in the feedback."""
    image1, image2, H, what = warped_pair(seed)
    return MeasuredCase((image1, image2), {}, f"{label}: {what}" if where else label, truth=H)


def _warp_public() -> list[Case]:
    return [_warped_case(2026, "a picture and a warped copy", True)]


def _warp_hidden(rng: np.random.Generator) -> list[Case]:
    return [_warped_case(_seed(rng), f"your own warped pair {k + 1} of 2 (picture, crop and warp drawn from your "
                                     f"seed)", False) for k in range(2)]


def _match_credit(got, case) -> float:
    correct, returned = correct_matches(got, case.truth)
    precision = correct / returned if returned else 0.0
    return min(MATCH_COUNT_SCALE.credit(correct), MATCH_PRECISION_SCALE.credit(precision))


class CorrectMatches(Comparator):
    """Passes when the matches ``(points1, points2)`` include at least the top of
    :data:`MATCH_COUNT_SCALE` correct ones (the homography ``case.truth`` maps the first point
    within :data:`~cvkit.features._measured.TOLERANCE` px of the second) at a precision at the
    top of :data:`MATCH_PRECISION_SCALE`; the case earns the smaller of the two scales' shares."""

    judges_alone = True  # the verdict is what the output achieves on the case's truth

    def describe(self) -> str:
        return (f"at least {MATCH_COUNT_SCALE.top:g} correct matches (error < {TOLERANCE:g} px) at a precision of "
                f"{MATCH_PRECISION_SCALE.show(MATCH_PRECISION_SCALE.top)} or more")

    def __call__(self, got, expected, case=None):
        if not isinstance(got, (tuple, list)) or len(got) != 2:
            return Mismatch("return a pair (points1, points2) of (M, 2) arrays of (x, y), one row per match")
        shapes = [np.shape(part) for part in got]
        if any(len(s) != 2 or s[1] != 2 for s in shapes if s != (0,)) or shapes[0][:1] != shapes[1][:1]:
            return Mismatch(f"points1 and points2 must be (M, 2) arrays of (x, y) with the same M, got shapes "
                            f"{shapes[0]} and {shapes[1]}")
        correct, returned = correct_matches(got, case.truth)
        precision = correct / returned if returned else 0.0
        if correct >= MATCH_COUNT_SCALE.top and precision >= MATCH_PRECISION_SCALE.top:
            return None
        theirs = correct_matches(expected, case.truth)
        words = []
        if precision < MATCH_PRECISION_SCALE.top:
            words.append(MATCH_PRECISION_SCALE.shortfall(precision, "precision", f" ({correct} correct of {returned})"))
        if correct < MATCH_COUNT_SCALE.top:
            words.append(MATCH_COUNT_SCALE.shortfall(correct, "correct matches (error < 2 px)", ""))
        words = [" ".join(words) + f" The case earns the smaller share: {_match_credit(got, case):.2f}. The reference "
                                   f"found {theirs[0]} correct of {theirs[1]}."]
        if correct <= 1 and returned >= 10:
            words.append(" Almost none is right: are the points (x, y) = (column, row), and is each point of image "
                         "2 the one its index pair (i, j) names?")
        elif precision < MATCH_PRECISION_SCALE.top:
            words.append(" Too many wrong matches: keep a match only when its nearest neighbour is clearly closer than "
                         "the second nearest (Lowe's ratio test).")
        return Mismatch("".join(words))


@mistake("no ratio test: every nearest neighbour kept",
         "A point of image 1 that image 2 does not show still has a nearest neighbour: keep a match only when "
         "d1 ≤ 0.8·d2 (Lowe's ratio test)")
def _match_nearest_only(image1, image2):
    return sift_matches(image1, image2, ratio=None, mutual=False)


@mistake("points returned as (row, col)",
         "Points are (x, y) = (column, row): SIFT's keypoints already are, keep their first two columns in that order")
def _match_row_col(image1, image2):
    return sift_matches(image1, image2, swap_xy=True)


@mistake("point of image 2 taken at image 1's index",
         "A match (i, j) pairs keypoint i of image 1 with keypoint j of image 2: points2 = keys2[j], not keys2[i]")
def _match_same_index(image1, image2):
    return sift_matches(image1, image2, same_index=True)


match_features = Check(
    compare=CorrectMatches(),
    credit=_match_credit,
    public=_warp_public,
    hidden=_warp_hidden,
    mistakes=[_match_nearest_only, _match_row_col, _match_same_index],
    allowed=_SIFT_BLOCKS,
    arg_names=("image1", "image2"),
    output_names=("points1", "points2"),
    time_limit=BUDGET_SECONDS,
    measure=Measure("correct matches", lambda got, case: correct_matches(got, case.truth)[0]),
)
