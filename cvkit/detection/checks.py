"""Checks of Chapter 6's detectors: cases, comparators and mistake banks for the grader.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference function
(``cvkit.detection.checks:match_template`` grades ``detection.match_template``). Four
comparators are defined here because detection outputs are not plain arrays:

- :class:`ShapeModelClose` compares shape models (dicts) as *sets* of control points with
  their directions, whatever the order the points were listed in;
- :class:`RTableClose` compares R-tables bin by bin, each bin as a set of vectors;
- :class:`HoughVotes` compares ``(accumulator, thetas, rhos)``: θ and ρ samples to 1e-9, the
  integer accumulator exactly up to a tiny number of votes moved to the neighbouring ρ bin
  (a ρ that lands within rounding of a bin boundary may go either way when cos θ is computed
  in another order); the count of moved votes is the earth mover's distance along ρ;
- :class:`VotesAndBest` compares the GHT's ``(accumulator, best)`` the same way, and accepts
  a ``best`` that is the first maximum of the candidate's own accumulator and a maximum of the
  expected one within the moved votes.

Public cases are small fixed inputs that already tell every mistake of the bank from the right
answer; hidden cases are drawn from the grading seed: non-square, tiny, constant, uint8 and
±1e6 inputs, every option value, and for every mistake an input that exposes it even where a
natural image hides it (windows without contrast for NCC/ZNCC, ties for best_match, Sobel
magnitudes equal to the threshold, exact halves at θ = 0 for the Hough rounding, diagonal
gradients that sit on a bin boundary for the R-table, rotated and scaled scenes for the GHT).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..data import disk_image, part_scene, part_template, polygon_image, square_image
from ..edges import canny as _canny
from ..edges import sobel as _sobel
from ..grading import Case, Check, Comparator, Mismatch, Mistake, close, mistake
from ..grading.casekit import variant
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ..grading.compare import as_numeric, shape_advice
from . import _hough
from ._shape import NO_GRADIENT
from ._ght import ght_build as _ght_build
from ._ght import ght_detect as _ght_detect
from ._hough import hough_lines as _hough_lines
from ._shape import shape_match as _shape_match
from ._shape import shape_model as _shape_model
from ._template import match_template as _match_template

__all__ = [
    "ShapeModelClose", "RTableClose", "HoughVotes", "VotesAndBest", "moved_votes",
    "match_template", "best_match", "shape_model", "shape_match", "hough_lines", "hough_peaks",
    "ght_build", "ght_detect",
]


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
def _dict_problem(got, keys) -> str | None:
    if got is None:
        return "your output is None: did you forget to `return` the result?"
    if not isinstance(got, dict):
        return f"expected a dict with the keys {', '.join(map(repr, keys))}, got {type(got).__name__}"
    missing = [k for k in keys if k not in got]
    if missing:
        return f"your dict lacks the key(s) {', '.join(map(repr, missing))} (expected {', '.join(map(repr, keys))})"
    return None


def _rows(value, name: str) -> tuple[np.ndarray | None, str | None]:
    arr, problem = as_numeric(value, name)
    if arr is None:
        return None, problem
    if arr.size == 0:
        arr = arr.reshape(0, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        return None, f"{name} must be an (N, 2) array, got shape {arr.shape}"
    if arr.dtype.kind not in "iuf":
        return None, f"{name} must be numeric, got dtype {arr.dtype}"
    return arr.astype(np.float64), None


def _sorted_rows(a: np.ndarray, *extra: np.ndarray):
    order = np.lexsort((a[:, 0], a[:, 1])) if len(a) else np.arange(0)
    return (a[order],) + tuple(e[order] for e in extra)


@dataclass
class ShapeModelClose(Comparator):
    """Shape models agree when they have the same ``shape``, the same set of control points
    (in any order) and, point by point, directions equal within ``atol``."""

    atol: float = 1e-9

    def describe(self) -> str:
        return f"same control points (any order), directions within {self.atol:g}"

    def __call__(self, got, expected, case=None):
        problem = _dict_problem(got, ("points", "directions", "shape"))
        if problem:
            return Mismatch(problem)
        try:
            shape = tuple(int(v) for v in got["shape"])
        except Exception:
            return Mismatch(f"model['shape'] must be (h, w), got {got['shape']!r}")
        if shape != tuple(expected["shape"]):
            return Mismatch(f"model['shape']: expected {tuple(expected['shape'])} (h, w) of the template, got {shape}")
        points, problem = _rows(got["points"], "model['points']")
        if problem:
            return Mismatch(problem)
        directions, problem = _rows(got["directions"], "model['directions']")
        if problem:
            return Mismatch(problem)
        if directions.shape != points.shape:
            return Mismatch(f"model['directions'] must have one row per point: {points.shape} points, "
                            f"{directions.shape} directions")
        exp_p, exp_d = np.asarray(expected["points"], float), np.asarray(expected["directions"], float)
        if points.shape != exp_p.shape:
            return Mismatch(f"{points.shape[0]} control points, expected {exp_p.shape[0]}"
                            + (" (are the points (x, y) = (col, row) and the threshold strict, magnitude > threshold?)"))
        p, d = _sorted_rows(points, directions)
        ep, ed = _sorted_rows(exp_p, exp_d)
        if not np.array_equal(p, ep):
            bad = np.flatnonzero(np.any(p != ep, axis=1))
            k = int(bad[0])
            return Mismatch(
                f"The control points differ: {bad.size} / {len(ep)} positions (sorted by y, then x) do not match\n"
                f"First difference: yours {p[k].tolist()}, expected {ep[k].tolist()} (points are (x, y) = (col, row) "
                "from the template's top-left pixel)", mismatched=int(bad.size), total=len(ep))
        err = np.abs(d - ed).max(axis=1) if len(d) else np.zeros(0)
        bad = ~(err <= self.atol)
        if bad.any():
            k = int(np.argmax(np.where(np.isnan(err), np.inf, err)))
            return Mismatch(
                f"Directions differ at {int(bad.sum())} / {len(ed)} control points (atol={self.atol:g})\n"
                f"Largest difference at point {ep[k].tolist()}: yours {d[k].tolist()}, expected {ed[k].tolist()}",
                max_abs=float(err[k]), mismatched=int(bad.sum()), total=len(ed))
        return None


@dataclass
class RTableClose(Comparator):
    """R-tables agree when ``bins`` is equal, the reference point is within ``atol`` and each
    bin holds the same vectors (as a set, within ``atol``)."""

    atol: float = 1e-9

    def describe(self) -> str:
        return f"same R-table: every bin the same set of vectors within {self.atol:g}"

    def __call__(self, got, expected, case=None):
        problem = _dict_problem(got, ("bins", "reference", "table"))
        if problem:
            return Mismatch(problem)
        if not isinstance(got["bins"], (int, np.integer)) or int(got["bins"]) != expected["bins"]:
            return Mismatch(f"rtable['bins']: expected {expected['bins']}, got {got['bins']!r}")
        ref, problem = as_numeric(got["reference"], "rtable['reference']")
        if problem:
            return Mismatch(problem)
        if ref.shape != (2,):
            return Mismatch(f"rtable['reference'] must be (x, y), got shape {ref.shape}")
        exp_ref = np.asarray(expected["reference"], float)
        if not np.all(np.abs(ref.astype(float) - exp_ref) <= self.atol):
            return Mismatch(f"rtable['reference']: expected {exp_ref.tolist()} (x, y), got {ref.tolist()}"
                            + (" — that is (y, x)" if np.allclose(ref[::-1], exp_ref, atol=self.atol) else ""))
        table = got["table"]
        if not isinstance(table, (list, tuple)) or len(table) != expected["bins"]:
            n = len(table) if isinstance(table, (list, tuple)) else type(table).__name__
            return Mismatch(f"rtable['table'] must be a list of {expected['bins']} arrays (one per bin), got {n}")
        wrong = []
        for k, (entry, exp) in enumerate(zip(table, expected["table"])):
            rows, problem = _rows(entry, f"rtable['table'][{k}]")
            if problem:
                return Mismatch(problem)
            exp = np.asarray(exp, float).reshape(-1, 2)
            if rows.shape != exp.shape:
                wrong.append(f"bin {k}: {rows.shape[0]} vectors, expected {exp.shape[0]}")
                continue
            a, = _sorted_rows(rows)
            b, = _sorted_rows(exp)
            if not np.all(np.abs(a - b) <= self.atol):
                i = int(np.flatnonzero(np.any(np.abs(a - b) > self.atol, axis=1))[0]) if np.isfinite(a).all() else 0
                wrong.append(f"bin {k}: vectors differ, e.g. yours {a[i].tolist()}, expected {b[i].tolist()}")
        if wrong:
            return Mismatch(f"{len(wrong)} / {expected['bins']} bins differ\n" + "\n".join(wrong[:4]),
                            mismatched=len(wrong), total=expected["bins"])
        return None


def moved_votes(got: np.ndarray, expected: np.ndarray, axis: int) -> float:
    """The earth mover's distance between two vote arrays along ``axis`` (each other axis a
    separate histogram): the number of votes moved by one bin; inf when totals differ."""
    g = np.asarray(got, dtype=np.float64)
    e = np.asarray(expected, dtype=np.float64)
    if not np.allclose(g.sum(axis=axis), e.sum(axis=axis), rtol=0, atol=1e-9):
        return math.inf
    return float(np.abs(np.cumsum(g - e, axis=axis)).sum())


def _moved_allowance(expected: np.ndarray, fraction: float) -> float:
    return max(2.0, fraction * float(np.abs(expected).sum()))


@dataclass
class HoughVotes(Comparator):
    """``(accumulator, thetas, rhos)``: θ and ρ samples within ``atol``; the integer
    accumulator equal up to at most ``fraction`` of the votes (at least 2) moved to a
    neighbouring ρ bin (rounding at a bin boundary)."""

    atol: float = 1e-9
    fraction: float = 0.002

    def describe(self) -> str:
        return f"θ, ρ within {self.atol:g}; votes equal up to {100 * self.fraction:g}% moved by one ρ bin"

    def __call__(self, got, expected, case=None):
        if not isinstance(got, (tuple, list)) or len(got) != 3:
            n = len(got) if isinstance(got, (tuple, list)) else type(got).__name__
            return Mismatch(f"expected a tuple (accumulator, thetas, rhos), got {n}")
        acc_e, th_e, rh_e = expected
        for name, value, exp in (("thetas", got[1], th_e), ("rhos", got[2], rh_e)):
            arr, problem = as_numeric(value, name)
            if problem:
                return Mismatch(problem)
            if arr.shape != exp.shape:
                return Mismatch(f"{name}: expected {exp.shape[0]} samples, got shape {arr.shape}"
                                + (" (θ in [−π/2, π/2): k < ceil(π / theta_step))" if name == "thetas" else
                                   " (ρ from −ceil(diag/rho_step)·rho_step to +ceil(diag/rho_step)·rho_step, diag = hypot(H, W))"))
            diff = np.abs(arr.astype(float) - exp)
            if not np.all(diff <= self.atol):
                k = int(np.argmax(np.where(np.isnan(diff), np.inf, diff)))
                return Mismatch(f"{name} differ: sample {k} is {float(arr.flat[k]):.6g}, expected {float(exp[k]):.6g}"
                                + (" (radians, not degrees)" if name == "thetas" else ""))
        acc, problem = as_numeric(got[0], "accumulator")
        if problem:
            return Mismatch(problem)
        if acc.dtype.kind not in "iu":
            return Mismatch(f"dtype mismatch: the accumulator counts votes, expected an integer array, got {acc.dtype}")
        if acc.shape != acc_e.shape:
            return Mismatch(f"accumulator shape mismatch: expected {acc_e.shape} = (len(rhos), len(thetas)), "
                            f"got {acc.shape}{shape_advice(acc.shape, acc_e.shape)}")
        if np.array_equal(acc, acc_e):
            return None
        moved = moved_votes(acc, acc_e, axis=0)
        allowed = _moved_allowance(acc_e, self.fraction)
        if moved <= allowed:
            return None
        bad = acc != acc_e
        worst = tuple(int(i) for i in np.argwhere(bad)[0])
        # votes are whole: "at most 3" of an allowance of 3.24 (0.2 % of 1620 votes)
        may = int(math.floor(allowed))
        totals = ("the number of votes per θ differs" if math.isinf(moved) else
                  f"{moved:g} votes moved between neighbouring ρ bins, at most {may} may move")
        return Mismatch(
            f"Accumulators differ in {int(bad.sum())} / {acc_e.size} bins ({totals})\n"
            f"First at [ρ index, θ index] = {list(worst)}: yours {int(acc[worst])}, expected {int(acc_e[worst])}",
            worst=worst, mismatched=int(bad.sum()), total=int(acc_e.size))


@dataclass
class VotesAndBest(Comparator):
    """The GHT's ``(accumulator (S, A, H, W), (x, y, scale, angle))``: the accumulator equal
    up to ``fraction`` of the votes moved by one pixel along x or y; ``best`` equal to the
    expected one, or, when some votes moved, the first maximum of the candidate's accumulator
    and a maximum of the expected one within the moved votes."""

    fraction: float = 0.002

    def describe(self) -> str:
        return f"votes equal up to {100 * self.fraction:g}% moved by one pixel; best (x, y, scale, angle)"

    def __call__(self, got, expected, case=None):
        if not isinstance(got, (tuple, list)) or len(got) != 2:
            n = len(got) if isinstance(got, (tuple, list)) else type(got).__name__
            return Mismatch(f"expected a tuple (accumulator, best), got {n}")
        acc_e, best_e = expected
        acc, problem = as_numeric(got[0], "accumulator")
        if problem:
            return Mismatch(problem)
        if acc.shape != acc_e.shape:
            return Mismatch(f"accumulator shape mismatch: expected {acc_e.shape} = (len(scales), len(angles), H, W), "
                            f"got {acc.shape}{shape_advice(acc.shape, acc_e.shape)}")
        acc = acc.astype(np.float64)
        exact = np.array_equal(acc, acc_e)
        moved = 0.0
        if not exact:
            moved = min(moved_votes(acc, acc_e, axis=3), moved_votes(acc, acc_e, axis=2))
            allowed = _moved_allowance(acc_e, self.fraction)
            if not moved <= allowed:
                bad = acc != acc_e
                worst = tuple(int(i) for i in np.argwhere(bad)[0])
                total = float(acc.sum()), float(acc_e.sum())
                return Mismatch(
                    f"Accumulators differ in {int(bad.sum())} / {acc_e.size} cells: {total[0]:g} votes in yours, "
                    f"{total[1]:g} expected\nFirst at [scale, angle, y, x] = {list(worst)}: yours {acc[worst]:g}, "
                    f"expected {acc_e[worst]:g}", worst=worst, mismatched=int(bad.sum()), total=int(acc_e.size))
        best = got[1]
        if not isinstance(best, (tuple, list)) or len(best) != 4:
            return Mismatch(f"best must be a tuple (x, y, scale, angle), got {best!r}")
        try:
            x, y = int(best[0]), int(best[1])
            s, a = float(best[2]), float(best[3])
        except Exception:
            return Mismatch(f"best must be (x, y, scale, angle) numbers, got {best!r}")
        if (x, y) == best_e[:2] and abs(s - best_e[2]) <= 1e-9 and abs(a - best_e[3]) <= 1e-9:
            return None
        message = (f"best: expected (x, y, scale, angle) = ({best_e[0]}, {best_e[1]}, {best_e[2]:.6g}, {best_e[3]:.6g}), "
                   f"got ({best[0]}, {best[1]}, {s:.6g}, {a:.6g})")
        if not exact:
            shape = acc_e.shape
            i = int(np.argmax(acc.reshape(-1)))
            si, ai, yi, xi = np.unravel_index(i, shape)
            own_first = (x, y) == (int(xi), int(yi))
            if own_first and 0 <= yi < shape[2] and acc_e[si, ai, yi, xi] >= acc_e.max() - moved:
                return None
            message += " (and it is not the first maximum of your accumulator)" if not own_first else ""
        if (y, x) == best_e[:2] and x != y:
            message += " — that is (y, x): return the column first"
        return Mismatch(message)


#: pointwise formulas and sums of products
_SCORES = close(rtol=1e-7, atol=1e-9, kind="f", scaled=True)
_EXACT_INT = close(rtol=0.0, atol=0.0, kind="iu")
_FLOAT = close(rtol=1e-9, atol=1e-9, kind="f")


# --------------------------------------------------------------------------------------------
# case helpers
# --------------------------------------------------------------------------------------------
def _ints(rng, h, w, lo=0, hi=10) -> np.ndarray:
    return rng.integers(lo, hi, (h, w)).astype(np.float64)


def _cut(rng, image, h, w):
    """A template cut from a random place of ``image`` (copy) and where it was cut (x, y)."""
    y = _size(rng, 0, image.shape[0] - h)
    x = _size(rng, 0, image.shape[1] - w)
    return image[y:y + h, x:x + w].copy(), (x, y)


def _bank(function, entries):
    """A bank whose wrong versions are settings of one parametrised implementation's ``kind``:
    ``Mistake(name, variant(function, kind=kind), hint)`` for each ``(name, kind, hint)`` of
    ``entries``, in the order the feedback tries them."""
    return [Mistake(name, variant(function, kind=kind), hint) for name, kind, hint in entries]


# --------------------------------------------------------------------------------------------
# detection.match_template (§6.0.1–6.0.2)
# --------------------------------------------------------------------------------------------
def _tm(image, template, measure="zncc", *, kind=None):
    """The reference, with one measure replaced by a mistake."""
    if kind is None or not _applies(kind, measure):
        return _match_template(image, template, measure)
    img = np.asarray(image, dtype=np.float64)
    tpl = np.asarray(template, dtype=np.float64)
    h, w = tpl.shape
    windows = np.lib.stride_tricks.sliding_window_view(img, (h, w))
    if kind == "ncc_plain":
        return np.einsum("ijmn,mn->ij", windows, tpl)
    if kind == "zncc_no_mean":
        return _match_template(img, tpl, "ncc")
    if kind == "euclid":
        return np.sqrt(_match_template(img, tpl, "ssd"))
    if kind == "sad_abs_sum":
        return np.abs(np.einsum("ijmn->ij", windows) - tpl.sum())
    if kind == "global_mean":
        ic = img - img.mean()
        tz = tpl - tpl.mean()
        num = np.einsum("ijmn,mn->ij", windows - img.mean(), tz)
        den = np.sqrt(np.einsum("ijmn->ij", (windows - img.mean()) ** 2) * np.sum(tz * tz))
        del ic
        with np.errstate(all="ignore"):
            out = num / den
        return np.where(den > 0, out, 0.0)
    if kind == "nan":
        out = _match_template(img, tpl, measure)
        if measure == "ncc":
            energy = np.einsum("ijmn->ij", windows ** 2)
            return np.where(energy == 0, np.nan, out)
        var = windows.reshape(windows.shape[:2] + (-1,)).var(axis=2)
        return np.where(var <= 1e-12 * np.mean(windows.reshape(windows.shape[:2] + (-1,)) ** 2, axis=2), np.nan, out)
    if kind == "absolute_flat":  # "no contrast" tested against 1e-6 itself, not against the window's scale
        flat_w = windows.reshape(windows.shape[:2] + (-1,)).var(axis=2) * h * w <= 1e-6
        if np.sum((tpl - tpl.mean()) ** 2) <= 1e-6:
            return np.zeros(flat_w.shape)
        return np.where(flat_w, 0.0, _match_template(img, tpl, measure))
    if kind == "same":
        out = np.zeros(img.shape)
        valid = _match_template(img, tpl, measure)
        out[h // 2:h // 2 + valid.shape[0], w // 2:w // 2 + valid.shape[1]] = valid
        return out
    raise ValueError(kind)  # pragma: no cover


def _applies(kind: str, measure: str) -> bool:
    return {
        "ncc_plain": measure == "ncc", "zncc_no_mean": measure == "zncc", "euclid": measure == "ssd",
        "sad_abs_sum": measure == "sad", "global_mean": measure == "zncc", "nan": measure in ("ncc", "zncc"),
        "same": True, "absolute_flat": measure == "zncc",
    }[kind]


def _tm_public():
    rng = np.random.default_rng(61)
    img = rng.integers(0, 10, (7, 9)).astype(np.float64)
    img[0:3, 5:9] = 4.0                                   # a constant patch (zero variance)
    tpl = img[3:6, 1:4].copy()
    zeros = rng.integers(1, 9, (6, 8)).astype(np.float64)
    zeros[3:6, 0:4] = 0.0                                 # an all-zero block (zero norm)
    ntpl = zeros[1:3, 2:5].copy()
    return [
        Case((img, tpl, "ssd"), {}, "7×9 integers, 3×3 template cut at (x=1, y=3), ssd"),
        Case((img, tpl[:, :2].copy(), "sad"), {}, "3×2 template, sad"),
        Case((zeros, ntpl, "ncc"), {}, "ncc, image with an all-zero block (zero-norm windows score 0)"),
        Case((3.0 * img + 7.0, tpl), {}, "zncc (default), image under gain 3 and offset 7, a constant patch (score 0)"),
        Case((0.5 + 1e-4 * img, 0.5 + 1e-4 * tpl, "zncc"), {},
             "zncc, a low-contrast image (0.5 + 1e-4·values): faint is not flat"),
    ]


def _tm_hidden(rng):
    def unit(h, w):
        return rng.random((h, w))

    a = unit(_size(rng, 9, 12), _size(rng, 11, 15))
    t_a, _ = _cut(rng, a, _size(rng, 3, 4), _size(rng, 2, 5))
    u8 = rng.integers(0, 256, (_size(rng, 9, 12), _size(rng, 9, 13))).astype(np.uint8)
    t_u8, _ = _cut(rng, u8, 3, _size(rng, 3, 5))
    normal = rng.normal(0.0, 3.0, (_size(rng, 8, 11), _size(rng, 10, 14)))
    t_n, _ = _cut(rng, normal, _size(rng, 2, 4), _size(rng, 3, 5))
    zeros = _ints(rng, _size(rng, 9, 11), _size(rng, 10, 13), 1, 9)
    zeros[_size(rng, 3, 5):, :_size(rng, 4, 6)] = 0.0
    t_z, _ = _cut(rng, zeros, 3, 3)
    if not np.any(t_z):
        t_z[0, 0] = 1.0
    flat = _ints(rng, _size(rng, 9, 12), _size(rng, 10, 13))
    flat[:4, -5:] = float(rng.integers(0, 10))
    t_f, _ = _cut(rng, flat, 3, _size(rng, 3, 4))
    if np.all(t_f == t_f.flat[0]):
        t_f[0, 0] += 1.0
    big = rng.uniform(-1e6, 1e6, (_size(rng, 8, 11), _size(rng, 8, 11)))
    t_big, _ = _cut(rng, big, 3, 3)
    gain = _u(rng, 1.5, 4.0, 2)
    offset = _u(rng, -20, 20, 2)
    row = unit(1, _size(rng, 12, 18))
    t_row, _ = _cut(rng, row, 1, _size(rng, 3, 5))
    t_row[0, 0] = t_row[0, -1] + 0.3                       # not constant
    return [
        Case((a, t_a, "ssd"), {}, "random image, template cut from it, ssd"),
        Case((u8, t_u8, "ssd"), {}, "uint8 image (not rescaled), ssd"),
        Case((normal, t_n, "sad"), {}, "negative and positive values, non-square template, sad"),
        Case((u8, t_u8[:, ::-1].copy(), "sad"), {}, "uint8, sad"),
        Case((zeros, t_z, "ncc"), {}, "ncc, an all-zero region (zero-norm windows score 0)"),
        Case((gain * a, t_a, "ncc"), {}, f"ncc, image under gain {gain:g}"),
        Case((gain * flat + offset, t_f, "zncc"), {}, "zncc, gain and offset, constant windows (score 0)"),
        Case((big, t_big, "zncc"), {}, "zncc, ±1e6 values"),
        Case((flat, np.full((2, 3), 5.0), "zncc"), {}, "zncc, constant template (every score 0)"),
        Case((zeros, np.zeros((2, 2)), "ncc"), {}, "ncc, all-zero template (every score 0)"),
        Case((t_a, t_a[::-1].copy(), "ncc"), {}, "template as large as the image (a 1×1 map)"),
        Case((row, t_row), {}, "single row 1×N, default measure (zncc)"),
        Case((0.5 + 1e-4 * a, 0.5 + 1e-4 * t_a), {"measure": "zncc"},
             "a low-contrast image (0.5 + 1e-4·values), zncc by keyword: faint is not flat"),
        _tm_int16(rng),
    ]


def _tm_int16(rng):
    # squares and products of ±1000 overflow int16 (largest 32767): compute in float64
    image = rng.integers(-1000, 1001, (_size(rng, 8, 11), _size(rng, 9, 12))).astype(np.int16)
    template, _ = _cut(rng, image, 3, _size(rng, 2, 4))
    return Case((image, template, "ssd"), {}, "int16 values up to ±1000, ssd (their squares overflow int16)")


match_template = Check(
    rules=("integer", "narrow integer", "no warnings"),
    public=_tm_public,
    hidden=_tm_hidden,
    compare=_SCORES,
    mistakes=_bank(_tm, [
        ("NCC without normalisation (plain correlation)", "ncc_plain",
         "Divide Σ I·T by the product of the norms sqrt(Σ I²)·sqrt(Σ T²) of the window and the template"),
        ("ZNCC without mean removal (that is NCC)", "zncc_no_mean",
         "Subtract the window's mean from the window and the template's mean from the template before "
         "correlating and normalising"),
        ("image mean subtracted instead of each window's mean", "global_mean",
         "ZNCC subtracts the mean of each window (it changes with the position), not the mean of the whole image"),
        ("square root taken (Euclidean distance, not SSD)", "euclid",
         "SSD is the sum of the squared differences itself, without a square root"),
        ("SAD as |Σ (I − T)| (absolute value of the sum)", "sad_abs_sum",
         "Take the absolute value of each difference, then sum: Σ |I − T|"),
        ("windows without contrast give NaN (0/0)", "nan",
         "Where a window (or the template) has zero norm (ncc) or zero variance (zncc) return 0, "
         "e.g. np.where(denominator > 0, numerator / denominator, 0) under np.errstate"),
        ("contrast tested against a fixed threshold (faint windows scored 0)", "absolute_flat",
         "A window is flat only when its variance is tiny next to its own mean square (relative, ≤ 1e-12), "
         "not below a fixed number: a faint texture still correlates"),
        ("output padded to the image size", "same",
         "Only the placements where the whole template fits: the map is (H − h + 1, W − w + 1), "
         "S[i, j] for the top-left corner at (x=j, y=i)"),
    ]),
)


# --------------------------------------------------------------------------------------------
# detection.best_match (§6.0.2)
# --------------------------------------------------------------------------------------------
def _bm(scores, measure, *, kind):
    s = np.asarray(scores, dtype=np.float64)
    low = measure in ("ssd", "sad")
    if kind == "argmax":
        flat = int(np.argmax(s))
    elif kind == "argmin":
        flat = int(np.argmin(s))
    elif kind == "last":
        r = s.reshape(-1)[::-1]
        flat = s.size - 1 - int(np.argmin(r) if low else np.argmax(r))
    else:
        flat = int(np.argmin(s) if low else np.argmax(s))
    if kind == "flat":
        return flat
    y, x = divmod(flat, s.shape[1])
    return (int(y), int(x)) if kind == "rowcol" else (int(x), int(y))


_BM_PUBLIC = np.array([[5.0, 2.0, 9.0, 4.0, 3.0],
                       [6.0, 8.0, 1.0, 7.0, 9.0],
                       [1.0, 3.0, 5.0, 0.5, 2.0],
                       [0.5, 4.0, 6.0, 2.0, 8.0]])


def _bm_map(rng, h, w, measure, ties: bool):
    """Integer scores with the best away from the diagonal (x ≠ y), tied twice if ``ties``."""
    s = rng.integers(-20, 20, (h, w)).astype(np.float64) / 4
    low = measure in ("ssd", "sad")
    extreme = float(s.min() - 1) if low else float(s.max() + 1)
    cells = [(y, x) for y in range(h) for x in range(w) if x != y]
    picks = rng.choice(len(cells), 2 if ties else 1, replace=False)
    for p in picks:
        s[cells[int(p)]] = extreme
    return s


def _bm_hidden(rng):
    cases = []
    for measure in ("ssd", "sad", "ncc", "zncc"):
        cases.append(Case((_bm_map(rng, _size(rng, 4, 7), _size(rng, 6, 9), measure, False), measure), {},
                          f"random map, {measure}"))
    for measure in ("ssd", "zncc"):
        cases.append(Case((_bm_map(rng, _size(rng, 5, 7), _size(rng, 5, 8), measure, True), measure), {},
                          f"two tied best scores, {measure} (the first in row-major order wins)"))
    zn = np.clip(rng.normal(0, 0.4, (_size(rng, 6, 9), _size(rng, 7, 10))), -1, 1)
    zn[1, _size(rng, 3, zn.shape[1] - 1)] = 1.0
    cases.append(Case((zn, "ncc"), {}, "scores in [−1, 1], a perfect match"))
    row = _bm_map(rng, 1, _size(rng, 8, 12), "sad", False)
    cases.append(Case((row, "sad"), {}, "single row 1×N"))
    col = rng.integers(0, 50, (_size(rng, 6, 9), 1)).astype(np.float64)
    col[_size(rng, 1, col.shape[0] - 1), 0] = 99.0
    cases.append(Case((col, "zncc"), {}, "single column N×1"))
    u8 = rng.integers(0, 256, (_size(rng, 5, 8), _size(rng, 9, 12))).astype(np.uint8)
    u8[_size(rng, 2, 4), _size(rng, 5, 8)] = 0
    cases.append(Case((u8, "ssd"), {}, "uint8 scores"))
    const = np.full((_size(rng, 3, 5), _size(rng, 4, 6)), float(rng.integers(0, 5)))
    cases.append(Case((const, str(rng.choice(["ssd", "ncc"]))), {}, "constant map (every position ties: (0, 0))"))
    return cases


best_match = Check(
    public=[
        Case((_BM_PUBLIC, "ssd"), {}, "4×5 scores, ssd (lowest wins)"),
        Case((_BM_PUBLIC, "zncc"), {}, "the same map, zncc (highest wins; two ties)"),
        Case((_BM_PUBLIC, "sad"), {}, "sad (two tied lowest)"),
        Case((-_BM_PUBLIC, "ncc"), {}, "negated map, ncc"),
    ],
    hidden=_bm_hidden,
    compare=_EXACT_INT,
    mistakes=_bank(_bm, [
        ("argmax for SSD/SAD", "argmax",
         "SSD and SAD are dissimilarities: the best placement has the *lowest* score (np.argmin)"),
        ("argmin for NCC/ZNCC", "argmin",
         "NCC and ZNCC are similarities: the best placement has the *highest* score (np.argmax)"),
        ("(row, col) returned instead of (x, y)", "rowcol",
         "Return (x, y) = (column, row): np.unravel_index gives (row, col), swap them"),
        ("ties go to the last position", "last",
         "Ties go to the first position in row-major order, as np.argmin/np.argmax on the flattened map"),
        ("flat index not converted to (x, y)", "flat",
         "np.argmax of a 2-D array is an index into the flattened map: convert it with "
         "np.unravel_index (or divmod by the width) and return (x, y)"),
    ]),
)


# --------------------------------------------------------------------------------------------
# detection.shape_model (§6.0.3)
# --------------------------------------------------------------------------------------------
def _sm(template, threshold, *, kind):
    tpl = np.asarray(template, dtype=np.float64)
    gx, gy = _sobel(tpl)
    mag = np.abs(gx) + np.abs(gy) if kind == "l1" else np.hypot(gx, gy)
    keep = mag >= threshold if kind == "inclusive" else mag > threshold
    rows, cols = np.nonzero(keep)
    m = np.hypot(gx, gy)[rows, cols]
    pts = np.stack([cols, rows], axis=1).astype(np.float64)
    dirs = np.stack([gx[rows, cols] / m, gy[rows, cols] / m], axis=1)
    if kind == "rowcol":
        pts = pts[:, ::-1].copy()
    elif kind == "raw":
        dirs = np.stack([gx[rows, cols], gy[rows, cols]], axis=1)
    elif kind == "centre":
        pts = pts - np.array([tpl.shape[1] // 2, tpl.shape[0] // 2], dtype=np.float64)
    elif kind == "swapped":
        dirs = dirs[:, ::-1].copy()
    return {"points": pts, "directions": dirs, "shape": tpl.shape}


def _sm_template_public():
    t = np.zeros((7, 9))
    t[2:5, 3:7] = 2.0
    t[5, 1] = 1.0
    return t


def _sm_hidden(rng):
    def part(h, w):
        img = square_image((h, w), centre=((w - 1) / 2 + rng.uniform(-0.5, 0.5), (h - 1) / 2 + rng.uniform(-0.5, 0.5)),
                           side=0.55 * min(h, w), angle=float(rng.uniform(0.2, 1.2)),
                           inside=float(rng.uniform(0.6, 0.9)), outside=float(rng.uniform(0.0, 0.3)))
        return img

    steps = np.zeros((_size(rng, 6, 9), _size(rng, 8, 11)))
    level = float(rng.integers(1, 4))
    steps[:, _size(rng, 4, 5):] = level
    steps[_size(rng, 2, 4):, :2] = level + float(rng.integers(1, 3))
    disk = disk_image((_size(rng, 10, 13), _size(rng, 10, 14)), radius=float(rng.uniform(3.2, 4.2)),
                      inside=float(rng.uniform(0.6, 1.0)), outside=0.1)
    u8 = np.round(255 * part(_size(rng, 10, 13), _size(rng, 11, 14))).astype(np.uint8)
    ints = rng.integers(0, 4, (_size(rng, 6, 8), _size(rng, 6, 9))).astype(np.float64)
    big = 1e6 * part(_size(rng, 9, 12), _size(rng, 9, 12))
    # the ±1e6 case's threshold, in the same raw units (~1e6), is a fraction of the template's
    # largest Sobel magnitude: a fixed 1e6..2e6 exceeded every magnitude of a low-contrast
    # square (4 % of seeds), leaving no control point, on which the reference rightly raises
    big_peak = float(np.hypot(*_sobel(big)).max())
    sq = part(_size(rng, 10, 14), _size(rng, 9, 13))
    return [
        Case((steps, 4.0 * level), {}, "integer steps, threshold equal to a straight edge's magnitude 4·step (strict >)"),
        Case((steps.T.copy(), 4.0 * level), {}, "the transposed steps"),
        Case((disk, 0.6), {}, "anti-aliased disk: every direction (L2 magnitude matters)"),
        Case((disk, _u(rng, 0.8, 1.6, 2)), {}, "the disk, a higher threshold"),
        Case((u8, float(np.round(rng.uniform(90, 200)))), {}, "uint8 rotated square (raw units, not rescaled)"),
        Case((ints, 4.0), {}, "random integers 0..3, threshold 4 (magnitudes equal to it)"),
        Case((ints, 0.0), {}, "threshold 0: every pixel with a gradient"),
        Case((big, float(np.round(rng.uniform(0.35, 0.8) * big_peak / 1e6, 2)) * 1e6), {}, "±1e6 scale"),
        Case((sq, _u(rng, 0.5, 1.2, 2)), {}, "rotated square, non-square template"),
        Case((np.array([[0.0, 0.0, 5.0, 5.0, 5.0]]), 1.0), {}, "single row 1×N"),
    ]


shape_model = Check(
    public=[
        Case((_sm_template_public(), 8.0), {}, "7×9 template: a bright rectangle, threshold 8 = a straight edge's magnitude"),
        Case((_sm_template_public(), 3.0), {}, "the same, threshold 3"),
        Case((disk_image((11, 12), centre=(5.3, 4.8), radius=3.6, inside=0.9, outside=0.1), 0.9), {},
             "anti-aliased disk, threshold 0.9"),
    ],
    hidden=_sm_hidden,
    refusals=[
        Case((np.full((9, 9), 0.5), 0.1), {}, "a flat template: no pixel above the threshold", raises="ValueError"),
    ],
    compare=ShapeModelClose(atol=1e-9),
    mistakes=_bank(_sm, [
        ("points as (row, col) instead of (x, y)", "rowcol",
         "Points are (x, y) = (column, row): np.nonzero gives (rows, cols), stack them as (cols, rows)"),
        ("directions not normalised", "raw",
         "Store unit vectors: divide (gx, gy) by the magnitude sqrt(gx² + gy²)"),
        ("points measured from the template centre", "centre",
         "Measure the points from the template's top-left pixel (x = column, y = row), not from its centre"),
        ("threshold inclusive (≥ instead of >)", "inclusive",
         "Control points have magnitude strictly greater than the threshold"),
        ("threshold on the L1 magnitude |gx| + |gy|", "l1",
         "Threshold the L2 magnitude sqrt(gx² + gy²)"),
        ("directions as (gy, gx)", "swapped",
         "Each direction is (gx, gy) / |g|: the x component first"),
    ]),
    allowed=("filters.pad", "edges.sobel"),
)


# --------------------------------------------------------------------------------------------
# detection.shape_match (§6.0.3)
# --------------------------------------------------------------------------------------------
def _smatch(image, model, polarity="none", *, kind):
    img = np.asarray(image, dtype=np.float64)
    pol = polarity
    if kind == "ignored":
        pol = "none"
    elif kind == "swapped":
        pol = {"global": "local", "local": "global"}.get(polarity, polarity)
    if kind in ("ignored", "swapped"):
        return _shape_match(img, model, pol)
    points = np.asarray(model["points"]).astype(np.int64)
    dirs = np.asarray(model["directions"], dtype=np.float64)
    h, w = model["shape"]
    gx, gy = _sobel(img)
    if kind == "convolved":
        gx, gy = -gx, -gy
    mag = np.hypot(gx, gy)
    some = mag > NO_GRADIENT * float(np.abs(img).max())
    if kind == "raw":
        ux, uy = np.where(some, gx, 0.0), np.where(some, gy, 0.0)
    else:
        with np.errstate(all="ignore"):
            ux = np.where(some, gx / mag, 0.0)
            uy = np.where(some, gy / mag, 0.0)
    ho, wo = img.shape[0] - h + 1, img.shape[1] - w + 1
    terms = np.stack([d[0] * ux[y:y + ho, x:x + wo] + d[1] * uy[y:y + ho, x:x + wo] for (x, y), d in zip(points, dirs)])
    if polarity == "local":
        total = np.abs(terms).sum(axis=0)
    elif polarity == "global":
        total = np.abs(terms.sum(axis=0))
    else:
        total = terms.sum(axis=0)
    n = h * w if kind == "pixels" else len(points)
    return total / n


def _paste(background, template, x, y):
    out = background.copy()
    out[y:y + template.shape[0], x:x + template.shape[1]] = template
    return out


def _sma_public():
    tpl = np.zeros((5, 6))
    tpl[1:4, 2:5] = 1.0
    tpl[3, 1] = 1.0
    model = _shape_model(tpl, 3.0)
    rng = np.random.default_rng(66)
    img = _paste(rng.integers(0, 2, (9, 12)).astype(np.float64) * 0.3, 2.0 * tpl + 0.2, 5, 3)
    mixed = img.copy()
    mixed[:, :8] = 2.5 - mixed[:, :8]
    return [
        Case((img, model), {}, "9×12 image, the template (gain 2) at (x=5, y=3), polarity 'none'"),
        Case((1.0 - img, model), {"polarity": "global"}, "globally inverted contrast, polarity 'global'"),
        Case((mixed, model), {"polarity": "local"}, "contrast inverted on the left part, polarity 'local'"),
        Case((mixed, model, "global"), {}, "the same image, polarity 'global'"),
    ]


def _sma_hidden(rng):
    size = int(rng.choice([16, 18, 20]))
    tpl, _ = part_template(size, margin=2, supersample=2)
    model = _shape_model(tpl, _u(rng, 0.4, 0.8, 2))
    scenes = {}
    for pol in ("normal", "inverted", "mixed"):
        h, w = _size(rng, size + 6, size + 12), _size(rng, size + 8, size + 14)
        scenes[pol] = part_scene((h, w), centre=(float(rng.uniform(size / 2, w - size / 2 - 1)),
                                                 float(rng.uniform(size / 2, h - size / 2 - 1))),
                                 size=size, clutter=1, noise=0.02, polarity=pol, rng=rng, supersample=2, margin=2)[0]
    small = np.zeros((_size(rng, 4, 6), _size(rng, 5, 7)))
    small[1:-1, 2:-1] = 1.0
    small_model = _shape_model(small, 2.0)
    background = rng.random((_size(rng, 9, 12), _size(rng, 12, 15)))
    u8 = np.round(255 * _paste(background, 0.3 + 0.5 * small, _size(rng, 0, 4), _size(rng, 0, 3))).astype(np.uint8)
    single = {"points": np.array([[float(_size(rng, 0, 3)), float(_size(rng, 0, 2))]]),
              "directions": np.array([[0.6, -0.8]]), "shape": (3, 4)}
    return [
        Case((scenes["normal"], model), {}, "part in clutter, same polarity, 'none'"),
        Case((scenes["inverted"], model), {"polarity": "none"}, "inverted part, 'none' (scores near −1)"),
        Case((scenes["inverted"], model), {"polarity": "global"}, "inverted part, 'global'"),
        Case((scenes["mixed"], model), {"polarity": "local"}, "part on a split background, 'local'"),
        Case((scenes["mixed"], model), {"polarity": "global"}, "part on a split background, 'global'"),
        Case((scenes["normal"], model, "local"), {}, "part in clutter, 'local' given positionally"),
        Case((u8, small_model), {"polarity": str(rng.choice(["none", "global"]))}, "uint8 image, small model"),
        Case((np.full((_size(rng, 6, 8), _size(rng, 7, 9)), 0.4), small_model), {"polarity": "local"},
             "constant image: no gradient anywhere (score 0)"),
        Case((background, single), {"polarity": "none"}, "a model of one control point"),
        Case((1e6 * background, single), {"polarity": "local"}, "±1e6 scale (directions only)"),
        Case((small + 0.0, small_model), {}, "image the size of the template (a 1×1 map)"),
    ]


shape_match = Check(
    public=_sma_public,
    hidden=_sma_hidden,
    compare=_FLOAT,
    mistakes=_bank(_smatch, [
        ("polarity ignored (always 'none')", "ignored",
         "polarity='global': |Σ cos θk| / n; polarity='local': Σ |cos θk| / n"),
        ("'global' and 'local' swapped", "swapped",
         "global takes the absolute value of the *sum* (one inversion of the whole object), local of "
         "*each term* (inversions along parts of the contour)"),
        ("image gradient not normalised (dot product, not cosine)", "raw",
         "cos θk = dk · g / |g|: divide the image gradient by its magnitude (0 where it is 0)"),
        ("divided by the template's pixel count, not by n", "pixels",
         "Average over the n control points: divide by len(model['points'])"),
        ("image gradient with flipped signs (kernels convolved)", "convolved",
         "Use the same Sobel as the model (correlation, gx > 0 where the image gets brighter to the right)"),
    ]),
    allowed=("filters.pad", "edges.sobel"),
)


# --------------------------------------------------------------------------------------------
# detection.hough_lines (§6.0.4–6.0.5)
# --------------------------------------------------------------------------------------------
def _hl(edges, theta_step=math.pi / 180, rho_step=1.0, *, kind):
    e = np.asarray(edges)
    rows, cols = np.nonzero(e)
    thetas = _hough.theta_samples(theta_step)
    k = math.ceil(math.hypot(*e.shape) / rho_step - 1e-9)
    if kind == "maxside":
        k = math.ceil(max(e.shape) / rho_step - 1e-9)
    rhos = np.arange(-k, k + 1) * rho_step
    offset = k
    if kind == "positive":
        rhos = np.arange(0, k + 1) * rho_step
        offset = 0
    x, y = cols.astype(float), rows.astype(float)
    if kind == "xy":
        x, y = y, x
    acc = np.zeros((rhos.size, thetas.size), dtype=np.int64)
    angles = np.degrees(thetas) if kind in ("degrees", "degrees_trig") else thetas
    for j, t in enumerate(angles):
        v = (x * math.cos(t) + y * math.sin(t)) / rho_step
        if kind == "trunc":
            idx = v.astype(np.int64)
        elif kind == "even":
            idx = np.round(v).astype(np.int64)
        else:
            idx = np.floor(v + 0.5).astype(np.int64)
        idx = idx + offset
        if kind == "positive":
            idx = np.where(idx < 0, idx + rhos.size, idx)    # negative indices wrap around
        idx = idx[(idx >= 0) & (idx < rhos.size)]
        acc[:, j] = np.bincount(idx, minlength=rhos.size)
    return acc, (np.degrees(thetas) if kind == "degrees" else thetas), rhos


def _hl_public():
    e = np.zeros((6, 8), dtype=bool)
    e[1, 1:7] = True
    e[2:6, 5] = True
    e[4, 2] = True
    f = np.zeros((5, 7), dtype=np.uint8)
    f[[0, 1, 2, 3, 4, 2, 0], [1, 3, 5, 2, 0, 6, 4]] = 1
    return [
        Case((e,), {"theta_step": math.pi / 4}, "6×8 edges: a horizontal and a vertical line, θ step 45°"),
        Case((f, math.pi / 2, 2.0), {}, "5×7 uint8 points, θ ∈ {−90°, 0°}, ρ step 2 (exact halves round up)"),
        Case((e[:5, :6].copy(),), {}, "5×6 edges, default steps (1°, 1 px)"),
    ]


def _lines_image(rng, h, w, count=2, noise=0.02):
    img = np.zeros((h, w), dtype=bool)
    for _ in range(count):
        theta = rng.uniform(-math.pi / 2, math.pi / 2)
        rho = rng.uniform(0.2, 0.8) * math.hypot(h, w) * (1 if theta > -0.3 else -0.3)
        yy, xx = np.mgrid[0:h, 0:w]
        img |= np.abs(xx * math.cos(theta) + yy * math.sin(theta) - rho) < 0.5
    img |= rng.random((h, w)) < noise
    return img


def _hl_hidden(rng):
    sparse = rng.random((_size(rng, 10, 14), _size(rng, 12, 18))) < 0.12
    lines = _lines_image(rng, _size(rng, 16, 22), _size(rng, 18, 26))
    u8 = (rng.random((_size(rng, 8, 11), _size(rng, 9, 13))) < 0.2).astype(np.uint8) * 255
    odd = np.zeros((_size(rng, 6, 9), _size(rng, 11, 15)))
    odd[rng.integers(0, odd.shape[0], 12), rng.integers(0, odd.shape[1], 12)] = rng.uniform(0.2, 1.0, 12)
    odd[:, 0] = 0.0
    odd[0, 1::2] = 1.0
    return [
        Case((sparse,), {}, "random edge pixels, default steps"),
        Case((lines,), {"theta_step": math.pi / 90}, "two lines and noise, θ step 2°"),
        Case((lines, math.pi / 36, 1.5), {}, "the lines, θ step 5°, ρ step 1.5"),
        Case((u8, math.pi / 2, 2.0), {}, "uint8 0/255 edges, θ ∈ {−90°, 0°}, ρ step 2 (exact halves)"),
        Case((odd,), {"theta_step": math.pi / 4, "rho_step": 2.0}, "float edge weights (nonzero votes once), θ step 45°, ρ step 2"),
        Case((sparse.T.copy(), math.pi / 60, 0.5), {}, "transposed, ρ step 0.5"),
        Case((np.zeros((_size(rng, 5, 8), _size(rng, 6, 9)), dtype=bool),), {}, "no edge pixel (all zero votes)"),
        Case((np.ones((_size(rng, 3, 5), _size(rng, 4, 6)), dtype=bool), math.pi / 8), {}, "every pixel an edge"),
        Case(((rng.random((1, _size(rng, 10, 16))) < 0.5),), {"theta_step": math.pi / 12}, "single row 1×N"),
        Case((rng.random((_size(rng, 7, 10), _size(rng, 7, 10))) < 0.15, math.pi / 180 * 7, 3.0), {},
             "θ step 7° (π/step not an integer), ρ step 3"),
    ]


hough_lines = Check(
    public=_hl_public,
    hidden=_hl_hidden,
    compare=HoughVotes(),
    mistakes=_bank(_hl, [
        ("θ in degrees", "degrees",
         "Angles are radians: θk = −π/2 + k·theta_step, and np.cos/np.sin take radians"),
        ("θ in degrees inside np.cos/np.sin", "degrees_trig",
         "Your θ values are radians, but the votes use cos and sin of θ in degrees: "
         "np.cos/np.sin take radians, so vote with np.cos(theta), np.sin(theta) of the θk you return"),
        ("ρ from 0 only (negative ρ wrap around)", "positive",
         "ρ = x cos θ + y sin θ is negative for half of the θ range: the bins go from −ceil(diag/step) to "
         "+ceil(diag/step) (offset the index by the number of negative bins)"),
        ("ρ range ±max(H, W), not ±diagonal", "maxside",
         "|ρ| can reach the image diagonal hypot(H, W): use k up to ceil(hypot(H, W) / rho_step)"),
        ("ρ truncated, not rounded to the nearest bin", "trunc",
         "Vote into the *nearest* bin: floor(ρ / rho_step + 0.5), not int(ρ / rho_step)"),
        ("halves rounded to even (np.round)", "even",
         "Exact halves round up: use np.floor(ρ / rho_step + 0.5) (np.round sends 0.5 to 0 and 2.5 to 2)"),
        ("x and y swapped (row used as x)", "xy",
         "x is the column and y the row: ρ = col·cos θ + row·sin θ"),
    ]),
)


# --------------------------------------------------------------------------------------------
# detection.hough_peaks (§6.0.5)
# --------------------------------------------------------------------------------------------
def _hp(accumulator, thetas, rhos, count=10, threshold=None, min_distance=5, *, kind):
    acc = np.asarray(accumulator, dtype=np.float64)
    if threshold is None:
        threshold = 0.5 * acc.max()
    flat = acc.reshape(-1)
    ok = (flat > threshold) if kind == "strict" else (flat >= threshold)
    candidates = np.flatnonzero(ok & (flat > 0))
    order = candidates[np.argsort(-flat[candidates], kind="stable")]
    suppressed = np.zeros(acc.shape, dtype=bool)
    reach = {"nosuppress": -1, "exclusive": min_distance - 1}.get(kind, min_distance)
    out = []
    for index in order:
        if len(out) >= count:
            break
        r, t = divmod(int(index), acc.shape[1])
        if suppressed[r, t]:
            continue
        if kind == "indices":
            out.append((float(r), float(t)))
        elif kind == "thetarho":
            out.append((float(thetas[t]), float(rhos[r])))
        else:
            out.append((float(rhos[r]), float(thetas[t])))
        if reach >= 0:
            suppressed[max(0, r - reach):r + reach + 1, max(0, t - reach):t + reach + 1] = True
    return np.array(out, dtype=np.float64).reshape(-1, 2)


_HP_ACC = np.array([
    [0, 1, 2, 1, 0, 0, 0],
    [1, 9, 8, 2, 0, 3, 1],
    [0, 6, 2, 0, 1, 5, 9],
    [0, 2, 0, 0, 4, 7, 2],
    [5, 0, 1, 0, 0, 2, 0],
    [2, 1, 0, 8, 0, 0, 4],
], dtype=np.int64)
_HP_THETAS = -math.pi / 2 + np.arange(7) * math.pi / 7
_HP_RHOS = np.arange(-3, 3) * 2.0


def _hp_hidden(rng):
    lines = _lines_image(rng, _size(rng, 20, 26), _size(rng, 22, 30), count=3, noise=0.01)
    acc, th, rh = _hough_lines(lines, math.pi / 45)
    small = rng.integers(0, 12, (_size(rng, 7, 10), _size(rng, 8, 12)))
    small[rng.integers(0, small.shape[0], 3), rng.integers(0, small.shape[1], 3)] = 12   # ties
    th_s = -math.pi / 2 + np.arange(small.shape[1]) * math.pi / small.shape[1]
    rh_s = (np.arange(small.shape[0]) - small.shape[0] // 2) * 1.5
    shape = (_size(rng, 8, 12), _size(rng, 9, 13))
    sparse = rng.integers(1, 9, shape) * (rng.random(shape) < 0.25)
    th_p = np.linspace(-math.pi / 2, math.pi / 2, sparse.shape[1], endpoint=False)
    rh_p = np.arange(sparse.shape[0]) - sparse.shape[0] // 2.0
    iso = np.zeros((_size(rng, 9, 12), _size(rng, 12, 16)), dtype=np.int64)
    spots = [(1, 1), (1, iso.shape[1] - 2), (iso.shape[0] - 2, 2), (iso.shape[0] - 2, iso.shape[1] - 3),
             (iso.shape[0] // 2, iso.shape[1] // 2)]
    level = int(rng.integers(4, 8))
    for k, (r, t) in enumerate(spots):
        iso[r, t] = level + 3 if k == 0 else level + (k % 2)
        iso[r, min(t + 1, iso.shape[1] - 1)] = max(iso[r, min(t + 1, iso.shape[1] - 1)], 1)
    th_i = -math.pi / 2 + np.arange(iso.shape[1]) * math.pi / iso.shape[1]
    rh_i = np.arange(iso.shape[0]) * 2.0 - iso.shape[0]
    return [
        Case((iso, th_i, rh_i), {"threshold": float(level), "min_distance": 2},
             "isolated peaks, some equal to the threshold"),
        Case((acc, th, rh), {}, "accumulator of three lines, defaults (threshold half the maximum)"),
        Case((acc, th, rh), {"count": 2, "min_distance": 3}, "the same, two peaks, min_distance 3"),
        Case((small, th_s, rh_s), {"threshold": 6.0, "min_distance": 2}, "random votes with ties, threshold 6"),
        Case((small, th_s, rh_s, 4, 9), {"min_distance": 2}, "threshold given positionally, equal to some votes"),
        Case((small, th_s, rh_s), {"min_distance": 0, "count": 5}, "min_distance 0 (no suppression radius)"),
        Case((sparse, th_p, rh_p), {"threshold": 3, "min_distance": 1, "count": 6}, "sparse votes, min_distance 1"),
        Case((sparse, th_p, rh_p), {"threshold": 2, "min_distance": 3}, "sparse votes, min_distance 3"),
        Case((sparse.astype(np.float64), th_p, rh_p), {"threshold": 100.0}, "threshold above every vote: (0, 2)"),
        Case((np.zeros((4, 5), dtype=np.int64), th_p[:5] if th_p.size >= 5 else np.zeros(5), np.arange(4.0)), {},
             "all-zero accumulator: no peak"),
        Case((small, th_s, rh_s), {"count": 1}, "count 1: the strongest only"),
    ]


hough_peaks = Check(
    public=[
        Case((_HP_ACC, _HP_THETAS, _HP_RHOS), {"min_distance": 1}, "6×7 votes, default threshold 4.5, min_distance 1"),
        Case((_HP_ACC, _HP_THETAS, _HP_RHOS), {"threshold": 1, "min_distance": 2}, "threshold 1, min_distance 2"),
        Case((_HP_ACC, _HP_THETAS, _HP_RHOS, 10, 5), {"min_distance": 2},
             "threshold 5 (votes equal to it count), min_distance 2"),
        Case((_HP_ACC, _HP_THETAS, _HP_RHOS), {"count": 3, "threshold": 2, "min_distance": 3},
             "at most three peaks, min_distance 3"),
    ],
    hidden=_hp_hidden,
    compare=_FLOAT,
    mistakes=_bank(_hp, [
        ("(θ, ρ) instead of (ρ, θ)", "thetarho", "Each row is (ρ, θ): ρ first"),
        ("bin indices instead of (ρ, θ) values", "indices",
         "Return rhos[r] and thetas[t] of each peak, not the indices r and t"),
        ("min_distance ignored (no suppression)", "nosuppress",
         "After taking a peak, suppress every bin within min_distance of it in both indices"),
        ("suppression window one bin too small (< min_distance)", "exclusive",
         "Suppress the bins whose indices differ by at most min_distance (≤, inclusive)"),
        ("threshold strict (> instead of ≥)", "strict",
         "A bin whose votes equal the threshold is a candidate (value ≥ threshold)"),
    ]),
)


# --------------------------------------------------------------------------------------------
# detection.ght_build (§6.0.6)
# --------------------------------------------------------------------------------------------
def _gb(template_edges, template_image, bins=36, reference=None, *, kind):
    e = np.asarray(template_edges)
    img = np.asarray(template_image, dtype=np.float64)
    rows, cols = np.nonzero(e)
    pts = np.stack([cols, rows], axis=1).astype(np.float64)
    if reference is None:
        ref = np.array([img.shape[1] // 2, img.shape[0] // 2], float) if kind == "centre" else pts.mean(axis=0)
    else:
        ref = np.asarray(reference, dtype=np.float64)
    gx, gy = _sobel(img)
    phi = np.arctan2(gy[rows, cols], gx[rows, cols])
    if kind == "atan2xy":
        phi = np.arctan2(gx[rows, cols], gy[rows, cols])
    q = phi / (2 * math.pi / bins)
    if kind == "floor":
        index = np.floor(q).astype(np.int64) % bins
    elif kind == "halfup":
        index = np.floor(q + 0.5).astype(np.int64) % bins
    else:
        index = np.round(q).astype(np.int64) % bins
    r = pts - ref if kind == "sign" else ref - pts
    if kind == "rowcol":
        r = r[:, ::-1].copy()
        ref = ref[::-1].copy()
    return {"bins": int(bins), "reference": (float(ref[0]), float(ref[1])), "table": [r[index == k] for k in range(bins)]}


def _gb_template(h, w, offset=(0.0, 0.0), angle=0.3):
    """A bright quadrilateral with a notch (integer levels): axis-aligned and diagonal edges."""
    v = np.array([(1.0, 1.0), (w - 2.0, 1.0), (w - 2.0, h - 2.0), (w / 2, h / 2), (1.0, h - 2.0)]) + offset
    return np.round(4 * polygon_image((h, w), v, 1.0, 0.0, supersample=2)) / 4


def _gb_public():
    t = np.zeros((9, 10))
    t[2:7, 2:8] = 1.0
    t[4:7, 4:6] = 0.0
    edges_t = np.hypot(*_sobel(t)) > 2.5
    poly = _gb_template(10, 11)
    edges_p = _canny(poly, 1.0)
    return [
        Case((edges_t, t), {"bins": 8}, "9×10 notched rectangle, 8 bins (45° corners sit on a bin boundary)"),
        Case((edges_p, poly), {}, "a polygon with Canny edges, default 36 bins"),
        Case((edges_t.astype(np.uint8), t, 4, (3.0, 5.5)), {}, "uint8 edge map, 4 bins, reference given (3, 5.5)"),
    ]


def _gb_hidden(rng):
    def disk(h, w):
        return disk_image((h, w), centre=((w - 1) / 2 + rng.uniform(-0.4, 0.4), (h - 1) / 2 + rng.uniform(-0.4, 0.4)),
                          radius=0.3 * min(h, w), inside=float(rng.uniform(0.6, 0.9)), outside=0.1)

    d = disk(_size(rng, 12, 16), _size(rng, 12, 17))
    sq = _gb_template(_size(rng, 9, 12), _size(rng, 10, 14))
    notch = np.zeros((_size(rng, 8, 11), _size(rng, 9, 12)))
    notch[2:-2, 2:-2] = float(rng.integers(1, 5))
    notch[-4:-2, 4:6] = 0.0
    notch_edges = np.hypot(*_sobel(notch)) > 2.5 * notch.max()
    tpl, _ = part_template(int(rng.choice([16, 18])), margin=2, supersample=2)
    tpl = np.round(8 * tpl) / 8        # dyadic levels: Sobel sums exact in any order (ties are ties)
    u8 = np.round(255 * sq).astype(np.uint8)
    return [
        Case((_canny(d, 1.0), d), {}, "anti-aliased disk (every direction), 36 bins"),
        Case((_canny(d, 1.0), d), {"bins": int(rng.choice([10, 18, 24]))}, "the disk, fewer bins"),
        Case((notch_edges, notch), {"bins": 8}, "notched rectangle, 8 bins (corners on bin boundaries)"),
        Case((notch_edges, notch, 4), {}, "the same, 4 bins"),
        Case((notch_edges, notch, 12, (float(rng.integers(2, 6)), float(rng.integers(2, 6)) + 0.5)), {},
             "12 bins, reference given"),
        Case((_canny(sq, 1.0), sq, 36), {}, "polygon with diagonal edges, 36 bins"),
        Case((_canny(u8, 1.0).astype(np.uint8) * 255, u8), {"bins": 16}, "uint8 image and a 0/255 edge map, 16 bins"),
        Case((_canny(tpl, 1.0), tpl), {"bins": 36}, "the part, 36 bins"),
        Case((_canny(tpl, 1.0), tpl), {"bins": 1}, "a single bin (every vector in it)"),
        Case((notch_edges, 1e6 * notch), {"bins": 8, "reference": None}, "±1e6 scale, reference=None"),
    ]


ght_build = Check(
    public=_gb_public,
    hidden=_gb_hidden,
    compare=RTableClose(atol=1e-9),
    mistakes=_bank(_gb, [
        ("r vector sign reversed (p − reference)", "sign",
         "Store r = reference − p, the vector from the border point to the reference point (y = x + r)"),
        ("points as (row, col) instead of (x, y)", "rowcol",
         "Use (x, y) = (column, row) for the points, the vectors and the reference"),
        ("bins by floor (truncation) instead of rounding", "floor",
         "bin = round(φ / Δφ) mod bins: bin k collects the directions within Δφ/2 of k·Δφ"),
        ("halves rounded up (np.floor(q + 0.5)), not as np.round", "halfup",
         "Round with np.round (exact halves to even): a 45° gradient with 36 bins, φ/Δφ = 4.5, goes to bin 4"),
        ("reference at the template centre, not the barycentre", "centre",
         "With reference=None use the barycentre of the edge pixels: (mean x, mean y)"),
        ("direction as atan2(gx, gy)", "atan2xy",
         "The gradient direction is atan2(gy, gx): y component first"),
    ]),
    allowed=("filters.pad", "edges.sobel"),
)


# --------------------------------------------------------------------------------------------
# detection.ght_detect (§6.0.6–6.0.7)
# --------------------------------------------------------------------------------------------
def _gd(image, rtable, scales=(1.0,), angles=(0.0,), edge_params=None, *, kind):
    img = np.asarray(image, dtype=np.float64)
    bins = int(rtable["bins"])
    table = [np.asarray(t, dtype=np.float64).reshape(-1, 2) for t in rtable["table"]]
    sv = np.asarray(scales, dtype=np.float64).reshape(-1)
    av = np.asarray(angles, dtype=np.float64).reshape(-1)
    H, W = img.shape
    acc = np.zeros((sv.size, av.size, H, W))
    edge_map = _canny(img, **(edge_params or {}))
    gx, gy = _sobel(img)
    ey, ex = np.nonzero(edge_map)
    phi = np.arctan2(gy[ey, ex], gx[ey, ex])
    for i, s in enumerate(sv):
        for j, a in enumerate(av):
            turn = -a if kind == "reverse" else a
            q = (phi - (0.0 if kind == "norotbin" else a)) / (2 * math.pi / bins)
            index = (np.floor(q) if kind == "floor" else np.round(q)).astype(np.int64) % bins
            c, sn = math.cos(turn), math.sin(turn)
            for k in range(bins):
                r = table[k]
                members = np.flatnonzero(index == k)
                if r.shape[0] == 0 or members.size == 0:
                    continue
                rx = c * r[:, 0] - sn * r[:, 1]
                ry = sn * r[:, 0] + c * r[:, 1]
                f = (1.0 / s) if kind == "divide" else s
                sign = -1.0 if kind == "sign" else 1.0
                fx = ex[members, None] + sign * f * rx[None, :]
                fy = ey[members, None] + sign * f * ry[None, :]
                if kind == "halfup":
                    vx, vy = np.floor(fx + 0.5).astype(np.int64), np.floor(fy + 0.5).astype(np.int64)
                else:
                    vx, vy = np.round(fx).astype(np.int64), np.round(fy).astype(np.int64)
                ok = (vx >= 0) & (vx < W) & (vy >= 0) & (vy < H)
                np.add.at(acc[i, j], (vy[ok], vx[ok]), 1.0)
    flat = int(np.argmax(acc))
    i, j, y, x = np.unravel_index(flat, acc.shape)
    if kind == "rowcol":
        return _ght_detect(image, rtable, scales, angles, edge_params)[0], (int(y), int(x), float(sv[i]), float(av[j]))
    return acc, (int(x), int(y), float(sv[i]), float(av[j]))


def _gd_model(size: int, bins: int, sigma: float = 1.0, reference=None):
    tpl, _ = part_template(size, margin=2, supersample=2)
    return _ght_build(_canny(tpl, sigma), tpl, bins=bins, reference=reference)


def _gd_public():
    table = _gd_model(16, 16)
    half = _gd_model(16, 16, reference=(7.5, 6.5))
    # a little noise: no gradient sits exactly on a bin boundary (where the rounding of the
    # Sobel sums, which depends on their order, would decide the bin)
    scene, _ = part_scene((30, 36), centre=(20.3, 14.6), size=16, clutter=0, noise=0.005, rng=3, supersample=2,
                          margin=2)
    turned, _ = part_scene((30, 34), centre=(16.2, 15.1), size=16, angle=math.pi / 6, scale=1.1, clutter=0,
                           noise=0.005, rng=4, supersample=2, margin=2)
    return [
        Case((scene, half), {"edge_params": {"sigma": 1.0}},
             "the part at (20.3, 14.6) in a 30×36 scene, one pose, reference point (7.5, 6.5)"),
        Case((turned, table, (0.9, 1.1), (0.0, math.pi / 6, math.pi / 3)), {"edge_params": {"sigma": 1.0}},
             "the part turned by 30° and scaled by 1.1: 2 scales × 3 angles"),
        Case((1.0 - turned, table), {"scales": (1.1,), "angles": (-math.pi / 6, math.pi / 6)},
             "inverted contrast, default Canny, angles ±30°"),
    ]


def _gd_hidden(rng):
    size = int(rng.choice([14, 16]))
    bins = int(rng.choice([8, 16, 24]))   # multiples of 8: 0°, 45°, 90° ... are bin centres, not boundaries
    table = _gd_model(size, bins)
    half = _gd_model(size, bins, reference=(size / 2 - 0.5, size / 2 - 1.5))
    cases = []

    def scene(h, w, **kw):
        c = (float(rng.uniform(size * 0.6, w - size * 0.6)), float(rng.uniform(size * 0.6, h - size * 0.6)))
        return part_scene((h, w), centre=c, size=size, rng=rng, supersample=2, margin=2, **kw)[0]

    a = float(rng.choice([-1, 1])) * _u(rng, 0.3, 0.9)
    s = _u(rng, 0.85, 1.2, 2)
    cases.append(Case((scene(30, 38, clutter=1, noise=0.01), half), {"edge_params": {"sigma": 1.0}},
                      "part in light clutter, one pose, reference point on half pixels"))
    cases.append(Case((scene(32, 36, angle=a, clutter=0, noise=0.01), table, (1.0,), (0.0, a, 2 * a)),
                      {"edge_params": {"sigma": 1.0}}, "rotated part, three angles"))
    cases.append(Case((scene(34, 34, scale=s, clutter=0, noise=0.005), table, (1.0, s)), {"edge_params": {"sigma": 1.0}},
                      "scaled part, two scales"))
    cases.append(Case((scene(34, 40, scale=s, angle=a, occlusion=0.3, clutter=1, noise=0.01), table, (0.9, s), (a, -a)),
                      {"edge_params": {"sigma": 1.2}}, "rotated, scaled, 30% occluded"))
    cases.append(Case((scene(30, 36, polarity="inverted", clutter=0, noise=0.005), half), {},
                      "inverted contrast, default Canny, reference point on half pixels"))
    u8 = np.round(255 * np.clip(scene(28, 34, clutter=0, noise=0.01), 0, 1)).astype(np.uint8)
    cases.append(Case((u8, table), {"angles": (0.0, float(rng.uniform(2.0, 3.0)))}, "uint8 scene, two angles"))
    cases.append(Case((np.full((20, 24), 0.5), table), {"scales": (1.0, 1.2)}, "constant image: no edge, no vote"))
    sparse = {"bins": bins, "reference": table["reference"],
              "table": [t if k % 2 == 0 else np.zeros((0, 2)) for k, t in enumerate(table["table"])]}
    cases.append(Case((scene(28, 32, clutter=0, noise=0.005), sparse), {"angles": (a,)},
                      "R-table with empty bins, one rotated pose"))
    cases.append(Case((scene(size + 8, size + 14, clutter=0, noise=0.005), table, (s,), (-a,)),
                      {"edge_params": {"sigma": 1.0, "low": 0.2, "high": 0.4}}, "tight scene, Canny thresholds given"))
    return cases


ght_detect = Check(
    public=_gd_public,
    hidden=_gd_hidden,
    compare=VotesAndBest(),
    mistakes=_bank(_gd, [
        ("r vector sign reversed (votes at x − r)", "sign",
         "The reference point is at y = x + r: add the (scaled, rotated) R-table vector to the edge pixel"),
        ("scene directions quantised by floor, the model by rounding", "floor",
         "Quantise the scene's gradient direction exactly as ght_build did: round((φ − a) / Δφ) mod bins"),
        ("R-table row read at φ, not φ − a", "norotbin",
         "An object turned by a has its gradients turned by a: read the row of (φ − a)"),
        ("vectors rotated the wrong way (R(−a))", "reverse",
         "Rotate r by +a: (cos a·rx − sin a·ry, sin a·rx + cos a·ry), with y pointing down"),
        ("vectors divided by the scale", "divide",
         "A shape s times larger has s times longer vectors: r' = s·R(a)·r"),
        ("vote position halves rounded up, not as np.round", "halfup",
         "Round the vote position with np.round (halves to even), like the R-table's bins"),
        ("best as (y, x, ...) instead of (x, y, ...)", "rowcol",
         "best is (x, y, scale, angle): np.unravel_index gives (scale, angle, row, col)"),
    ]),
    allowed=("filters.pad", "filters.gaussian_kernel", "filters.gaussian", "filters.correlate", "edges.sobel",
             "edges.magnitude", "edges.non_max_suppression", "edges.hysteresis", "edges.canny"),
)


# --------------------------------------------------------------------------------------------
# §6.0.5 the measured exercise: the lines of a cluttered edge map, graded by the F1 of detection
# --------------------------------------------------------------------------------------------
from typing import Any  # noqa: E402

from ..grading.measured import MeasuredCase, Scale  # noqa: E402
from ._lines import BUDGET_SECONDS as _LINES_BUDGET  # noqa: E402
from ._lines import F1_SCALE, RHO_TOLERANCE, THETA_TOLERANCE, line_votes, strongest_peaks  # noqa: E402

#: the published scale the grader applies (its corners: :data:`cvkit.detection._lines.F1_SCALE`)
LINES_F1 = Scale(F1_SCALE, percent=False)


def _chord(rho: float, theta: float, h: int, w: int) -> np.ndarray:
    """The pixels (x, y) of the line ρ = x cos θ + y sin θ inside an h × w image, one per half
    pixel of its length, rounded (an 8-connected chain one pixel wide)."""
    c, s = math.cos(theta), math.sin(theta)
    x0, y0 = rho * c, rho * s                                # the foot of the normal
    t = np.arange(-2.0 * (h + w), 2.0 * (h + w), 0.5)
    pts = np.round(np.stack([x0 - t * s, y0 + t * c], axis=1)).astype(np.int64)
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < w) & (pts[:, 1] >= 0) & (pts[:, 1] < h)
    return np.unique(pts[inside], axis=0)


def _distinct_line(a: tuple[float, float], b: tuple[float, float], rho_gap: float, theta_gap: float) -> bool:
    """Whether two (ρ, θ) lines are at least ``theta_gap`` apart in angle or ``rho_gap`` in ρ
    (θ and θ ± π with −ρ are the same line)."""
    return bool(line_distance(np.array([a]), np.array([b]), rho_gap, theta_gap)[0, 0] > 1.0)


def line_distance(got: np.ndarray, truth: np.ndarray, rho_tol: float = RHO_TOLERANCE,
                  theta_tol: float = THETA_TOLERANCE) -> np.ndarray:
    """``(len(got), len(truth))`` distances between lines ``(ρ, θ)`` in units of the tolerances:
    max(|Δρ| / rho_tol, |Δθ| / theta_tol), the better of comparing (ρ, θ) with (ρ', θ') and
    with (−ρ', θ' ± π) (the same line); a match is a distance ≤ 1."""
    g, t = np.asarray(got, dtype=np.float64).reshape(-1, 2), np.asarray(truth, dtype=np.float64).reshape(-1, 2)
    d_theta = g[:, None, 1] - t[None, :, 1]
    wrapped = np.abs(d_theta - np.pi * np.round(d_theta / np.pi))
    flipped = (np.round(d_theta / np.pi) % 2) != 0
    d_rho = np.abs(np.where(flipped, g[:, None, 0] + t[None, :, 0], g[:, None, 0] - t[None, :, 0]))
    return np.maximum(d_rho / rho_tol, wrapped / theta_tol)


def line_scene(rng: np.random.Generator, size: int = 128) -> tuple[np.ndarray, np.ndarray]:
    """A cluttered edge map and its true lines: ``(edges (size, size) bool, lines (N, 2) (ρ, θ))``.

    Three to five lines, θ alternately in [0, π/2) and [−π/2, 0), each at least 10° or 12 px
    from the others in (θ, ρ) and crossing at least 80 pixels of the picture, with one to three gaps of 5–15 pixels (occlusions), keeping
    60 pixels or more; six to ten stray segments of 6–14 pixels in random directions; and noise
    pixels on 1–2 % of the picture."""
    h = w = size
    lines: list[tuple[float, float]] = []
    mask = np.zeros((h, w), dtype=bool)
    wanted = int(rng.integers(3, 6))
    while len(lines) < wanted:
        # normals turn both ways in alternation: at least a third of the lines have θ < 0
        theta = float(rng.uniform(0.0, np.pi / 2)) * (-1.0 if len(lines) % 2 else 1.0)
        x, y = rng.uniform(0.2 * w, 0.8 * w), rng.uniform(0.2 * h, 0.8 * h)   # a point the line passes
        rho = x * math.cos(theta) + y * math.sin(theta)
        pixels = _chord(rho, theta, h, w)
        if len(pixels) < 160 or not all(_distinct_line((rho, theta), other, 12.0, math.radians(10.0))
                                          for other in lines):
            continue                                     # chords of 2 samples per pixel: ≥ 80 px long
        keep = np.ones(len(pixels), dtype=bool)
        for _ in range(int(rng.integers(1, 4))):
            start, length = int(rng.integers(0, len(pixels))), int(rng.integers(10, 31))
            keep[start:start + length] = False
        kept = pixels[keep]
        if len(np.unique(kept, axis=0)) < 60:
            continue
        mask[kept[:, 1], kept[:, 0]] = True
        lines.append((rho, theta))
    for _ in range(int(rng.integers(6, 11))):
        x, y, a = rng.uniform(0, w), rng.uniform(0, h), rng.uniform(0, np.pi)
        t = np.arange(0.0, float(rng.integers(6, 15)), 0.5)
        pts = np.round(np.stack([x + t * math.cos(a), y + t * math.sin(a)], axis=1)).astype(np.int64)
        pts = pts[(pts[:, 0] >= 0) & (pts[:, 0] < w) & (pts[:, 1] >= 0) & (pts[:, 1] < h)]
        mask[pts[:, 1], pts[:, 0]] = True
    mask |= rng.random((h, w)) < rng.uniform(0.01, 0.02)
    return mask, np.array(lines, dtype=np.float64)


def _lines_public() -> list[Case]:
    edges, truth = line_scene(np.random.default_rng(2026))
    return [MeasuredCase((edges,), {}, f"{len(truth)} broken lines among stray segments and noise pixels", truth=truth)]


def _lines_hidden(rng: np.random.Generator) -> list[Case]:
    scenes = [line_scene(rng) for _ in range(2)]
    return [MeasuredCase((edges,), {}, f"your scene {k}: its own lines, gaps and clutter", truth=truth)
            for k, (edges, truth) in enumerate(scenes, start=1)]


class LineDetection(Comparator):
    """Passes when the lines returned reach the top of :data:`LINES_F1` in F1 against the case's
    true lines (one-to-one matches within :data:`~cvkit.detection._lines.RHO_TOLERANCE` pixels
    and :data:`~cvkit.detection._lines.THETA_TOLERANCE`); below it the case earns the scale's
    share. The reference's lines (``expected``) only serve for comparison."""

    judges_alone = True  # the verdict is what the output achieves on the case's truth

    @staticmethod
    def counts(got: Any, case: Any) -> tuple[int, int, int]:
        """``(matched, returned, true)``: greedy one-to-one matching, closest pairs first;
        ``returned`` is −1 when ``got`` is not a (K, 2) array of finite numbers."""
        truth = np.asarray(getattr(case, "truth", np.zeros((0, 2))), dtype=np.float64).reshape(-1, 2)
        try:
            found = np.asarray(got, dtype=np.float64)
        except (TypeError, ValueError):
            return 0, -1, len(truth)
        if found.size == 0:
            return 0, 0, len(truth)
        if found.ndim != 2 or found.shape[1] != 2 or not np.all(np.isfinite(found)):
            return 0, -1, len(truth)
        distance = line_distance(found, truth)
        matched, used_g, used_t = 0, set(), set()
        for flat in np.argsort(distance, axis=None, kind="stable"):
            i, j = divmod(int(flat), len(truth))
            if distance[i, j] > 1.0:
                break
            if i not in used_g and j not in used_t:
                used_g.add(i)
                used_t.add(j)
                matched += 1
        return matched, len(found), len(truth)

    @classmethod
    def f1(cls, got: Any, case: Any) -> float:
        matched, returned, true = cls.counts(got, case)
        return 2.0 * matched / (returned + true) if returned > 0 and true else 0.0

    def __call__(self, got: Any, expected: Any, case: Any = None) -> Mismatch | None:
        f1 = self.f1(got, case)
        if f1 >= LINES_F1.top:
            return None
        matched, returned, true = self.counts(got, case)
        if returned < 0:
            return Mismatch(f"expected a (K, 2) float array of (ρ, θ) rows, got {np.shape(got)}: "
                            "one row per line, ρ in pixels and θ in radians")
        words = [LINES_F1.shortfall(f1, "F1", f" ({matched} of your {returned} lines match one of the {true} true "
                                              f"lines within {RHO_TOLERANCE:g} px and "
                                              f"{math.degrees(THETA_TOLERANCE):g}°)")]
        reference = self.f1(expected, case)
        if reference:
            words.append(f"The reference found lines with F1 = {reference:.3f} in the same scene.")
        if returned > max(2 * true, true + 3):
            words.append("You return many more lines than there are: raise the vote threshold, and suppress the "
                         "bins around each peak you take (a line's votes spread over neighbouring bins).")
        elif matched < true and returned <= true:
            words.append("Lines are missing: do your θ samples cover the whole half-turn [−π/2, π/2)? Is x the "
                         "column and y the row? Is your vote threshold below the length of a broken line?")
        return Mismatch(" ".join(words))


def _lines_credit(got: Any, case: Any) -> float:
    return LINES_F1.credit(LineDetection.f1(got, case))


@mistake("θ only over [0, π/2)",
         "The normal of a line can point anywhere in a half-turn: vote for θ in [−π/2, π/2), or lines whose "
         "normal points up and right are never found")
def _lines_quarter_turn(edges):
    votes, thetas, rhos = line_votes(np.asarray(edges, dtype=bool), theta_start=0.0)
    return strongest_peaks(votes, thetas, rhos, threshold=45)


@mistake("no suppression around a peak",
         "Take the strongest bin, then zero the bins around it before the next one: a broken line's votes spread "
         "over neighbouring bins that are not lines of their own")
def _lines_without_suppression(edges):
    votes, thetas, rhos = line_votes(np.asarray(edges, dtype=bool))
    return strongest_peaks(votes, thetas, rhos, threshold=45, radius=0)


@mistake("x and y swapped (x taken from the rows)",
         "x is the column and y the row: ρ = col·cos θ + row·sin θ")
def _lines_xy_swapped(edges):
    votes, thetas, rhos = line_votes(np.asarray(edges, dtype=bool), swap_xy=True)
    return strongest_peaks(votes, thetas, rhos, threshold=45)


find_lines = Check(_lines_public, _lines_hidden, LineDetection(),
                   mistakes=[_lines_quarter_turn, _lines_without_suppression, _lines_xy_swapped],
                   time_limit=_LINES_BUDGET, output_names=("lines",), credit=_lines_credit)
