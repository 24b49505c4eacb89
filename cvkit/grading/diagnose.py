"""The shape of an error, in plain words: how a wrong array differs from the expected one.

Pure NumPy, vectorized, no cvkit imports (it can run wherever the grader runs).

- :func:`describe_difference` — the one sentence a student reads first: how many values differ,
  *where* (everywhere, one row, one column, the border frame, the interior, one channel), the
  first differing position ``[row r, col c]`` with yours vs expected, and the largest error.
- :func:`diagnose` — what the wrong output *is*, when one simple transformation of the expected
  output explains all of it: shifted by (dy, dx), transposed, flipped or rotated, colour
  channels reordered, results returned in the wrong order, scaled, opposite sign, offset,
  linearly rescaled, rounded or cut to whole numbers, clipped, wrapped around at 256, float32;
  or, failing that, a fact that locates the error: NaN/inf where numbers are expected (or the
  reverse), only the border frame wrong, only some colour channels wrong. Each
  :class:`Diagnosis` carries a short hint.
- :func:`explain_exception` — a shape or index error read against the case's inputs ("index 4
  is out of bounds for axis 0 with size 4" on a 4×5 image: rows and columns swapped?).
- :func:`image_variants` — a square crop and a transposed copy of a case's image, on which a
  candidate that crashed can be run again.

No false diagnoses: a transformation is named only when it reproduces the wrong output
everywhere (a shift: everywhere the shifted images overlap, which must be most of it), when no
other transformation does (a constant or periodic expected output is "shifted" by anything, so
nothing is said), and when it actually changes the expected output (a shift of a constant
image is no shift). An output equal to the expected one gets no diagnosis.
"""
from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

__all__ = ["Diagnosis", "diagnose", "describe_difference", "locate", "explain_exception", "image_variants",
           "CONVENTION"]

#: the indexing convention, as students are told it
CONVENTION = "images are indexed image[row, col] = image[y, x], and image.shape is (rows, cols) = (H, W)"

_CHANNEL_NAMES = ("red", "green", "blue", "alpha")
_MAX_SHIFT = 3
_MAX_FRAME = 4


@dataclass(frozen=True)
class Diagnosis:
    """What a wrong output looks like (``what``), the advice that fixes it (``hint``), and a
    ``kind`` for programs (``"shift"``, ``"transposed"``, ``"flip"``, ``"channels"``, ``"order"``,
    ``"zeros"``, ``"sign"``, ``"scale"``, ``"offset"``, ``"affine"``, ``"rounding"``,
    ``"clipping"``, ``"wraparound"``, ``"precision"``, ``"nonfinite"``, ``"missing_nonfinite"``,
    ``"border"``, ``"edge_entries"`` (the same place in an output that is no image), ``"channel_only"``)."""

    kind: str
    what: str
    hint: str = ""

    def __str__(self) -> str:
        text = _sentence(self.what)
        return f"{text} {_sentence(self.hint)}" if self.hint else text


def _sentence(text: str) -> str:
    """``text`` with a capital first letter and a final full stop."""
    text = text.strip()
    if not text:
        return text
    text = text[0].upper() + text[1:]
    return text if text[-1] in ".!?" else text + "."


# --------------------------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------------------------
def _numeric(value: Any) -> np.ndarray | None:
    """``value`` as an array of a numeric (or bool) dtype, or None."""
    if value is None or isinstance(value, (dict, str, bytes)):
        return None
    try:
        with np.errstate(all="ignore"):
            arr = np.asarray(value)
    except Exception:
        return None
    if arr.dtype == object or arr.dtype.kind not in "biuf":
        return None
    return arr


def _close(a: np.ndarray, b: np.ndarray, rtol: float, atol: float) -> np.ndarray:
    """Elementwise ``|a − b| ≤ atol + rtol·|b|``; NaN equals NaN, inf equals inf of its sign."""
    with np.errstate(all="ignore"):
        same = (a == b) | (np.isnan(a) & np.isnan(b))
        return same | (np.abs(a - b) <= atol + rtol * np.abs(b))


def _plural(n: int, word: str, plural: str | None = None) -> str:
    return f"{n} {word if n == 1 else (plural or word + 's')}"


def _value(v: Any) -> str:
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    try:
        f = float(v)
    except (TypeError, ValueError):
        return repr(v)
    if np.isnan(f):
        return "NaN"
    if np.isinf(f):
        return "inf" if f > 0 else "−inf"
    return f"{f:.6g}"


def _number(x: float) -> str:
    return f"{x:.4g}".replace("-", "−")


def position(index: Sequence[int | np.integer], shape: tuple) -> str:
    """``[row 2, col 3]`` for a 2-D array, ``[row 2, col 3, channel 1]`` for colour, ``[4]`` in 1-D."""
    index = tuple(int(i) for i in index)
    if len(index) == 2:
        return f"[row {index[0]}, col {index[1]}]"
    if len(index) == 3 and shape[2] <= 4:
        return f"[row {index[0]}, col {index[1]}, channel {index[2]}]"
    return "[" + ", ".join(map(str, index)) + "]"


def _image_like(shape: tuple) -> bool:
    """1-D, 2-D, or (H, W, C) with at most 4 channels: where "rows", "columns", "border" and
    "channels" mean what they say (not a 4-D tensor or an (N, C, L) stack)."""
    return len(shape) in (1, 2) or (len(shape) == 3 and shape[2] <= 4)


def _scale(e: np.ndarray) -> float:
    finite = np.abs(e[np.isfinite(e)]) if e.size else np.zeros(0)
    return max(1.0, float(finite.max())) if finite.size else 1.0


# --------------------------------------------------------------------------------------------
# where the wrong values are
# --------------------------------------------------------------------------------------------
def _frame(mask: np.ndarray, limit: int = _MAX_FRAME) -> tuple[int, int, int, int] | None:
    """The thinnest frame (top, bottom, left, right widths) holding every True of a 2-D mask,
    each width at most ``limit`` and a quarter of the rows (columns), leaving an interior of at
    least a fifth of the array; None if there is none or the mask is empty."""
    H, W = mask.shape
    rr, cc = np.nonzero(mask)
    if rr.size == 0:
        return None
    depth = np.minimum(np.minimum(rr, H - 1 - rr), np.minimum(cc, W - 1 - cc))
    if depth.max() >= limit:
        return None
    # a border is thin: at most a quarter of the rows (columns) on each side
    row_limit, col_limit = min(limit, max(1, H // 4)), min(limit, max(1, W // 4))
    # a pixel is covered by the frame (t, b, l, r) when t > row, b > H − 1 − row, l > col or
    # r > W − 1 − col; for every (t, b, l) the right width r is then forced
    t = np.arange(row_limit + 1)[:, None, None, None]
    b = np.arange(row_limit + 1)[None, :, None, None]
    l = np.arange(col_limit + 1)[None, None, :, None]
    uncovered = (rr > t - 1) & (H - 1 - rr > b - 1) & (cc > l - 1)
    r = np.where(uncovered, W - cc, 0).max(axis=-1)
    t, b, l = t[..., 0], b[..., 0], l[..., 0]
    interior = (H - t - b) * (W - l - r)
    ok = (r <= col_limit) & (t + b < H) & (l + r < W) & (interior >= 0.2 * H * W)
    if not ok.any():
        return None
    t, b, l, r, interior = (np.broadcast_to(v, ok.shape)[ok] for v in (t, b, l, r, interior))
    distinct = 1 + (b != t) + ((l != t) & (l != b)) + ((r != t) & (r != b) & (r != l))
    best = np.lexsort((t + b + l + r, distinct, -interior))[0]
    return int(t[best]), int(b[best]), int(l[best]), int(r[best])


def _frame_words(t: int, b: int, l: int, r: int) -> tuple[str, bool]:
    """("the border frame 2 pixels wide", all four sides?)"""
    if t == b == l == r:
        return f"the border frame {_plural(t, 'pixel')} wide", True
    if t == b and l == r and t and l:
        return (f"the border frame ({_plural(t, 'row')} at the top and bottom, {_plural(l, 'column')} "
                f"at the left and right)"), True
    parts = []
    for n, first, kind in ((t, True, "row"), (b, False, "row"), (l, True, "column"), (r, False, "column")):
        if n:
            side = "first" if first else "last"
            parts.append(f"the {side} {kind}" if n == 1 else f"the {side} {n} {kind}s")
    return " and ".join(parts), False


def _spatial(bad: np.ndarray) -> np.ndarray:
    """The 2-D (rows, cols) mask of an array's wrong values (any channel)."""
    if bad.ndim <= 2:
        return bad
    return np.asarray(bad.reshape(bad.shape[0], bad.shape[1], -1).any(axis=2))


def locate(bad: np.ndarray) -> str:
    """Where the True values of ``bad`` are, in words ("all in row 3", "all in the border frame 2
    pixels wide (the interior is right)", "only in channel 2 (blue)"; "" when nothing simple)."""
    bad = np.asarray(bad, dtype=bool)
    n = int(bad.sum())
    if n <= 1 or bad.ndim == 0 or n == bad.size or not _image_like(bad.shape):
        return ""  # one value: its position says it all; no rows and columns in a tensor
    if bad.ndim == 1:
        idx = np.flatnonzero(bad)
        N = bad.size
        if idx.size == 1:
            return ""
        if idx[-1] < min(_MAX_FRAME, N // 3) and idx.size == idx[-1] + 1:
            return f"all in the first {idx.size} positions"
        if idx[0] >= N - min(_MAX_FRAME, N // 3) and idx.size == N - idx[0]:
            return f"all in the last {idx.size} positions"
        return f"all between positions {idx[0]} and {idx[-1]}" if idx[-1] - idx[0] + 1 < N else ""
    words = []
    spatial = _spatial(bad)
    H, W = spatial.shape
    rows, cols = np.flatnonzero(spatial.any(axis=1)), np.flatnonzero(spatial.any(axis=0))
    if spatial.all():
        pass
    elif rows.size == 1 and H > 1:
        r = int(rows[0])
        which = " (the first row)" if r == 0 else " (the last row)" if r == H - 1 else ""
        words.append(f"all in row {r}{which}")
    elif cols.size == 1 and W > 1:
        c = int(cols[0])
        which = " (the first column)" if c == 0 else " (the last column)" if c == W - 1 else ""
        words.append(f"all in column {c}{which}")
    else:
        frame = _frame(spatial) if min(H, W) >= 3 else None
        if frame is not None:
            text, all_sides = _frame_words(*frame)
            words.append(f"all in {text} ({'the interior' if all_sides else 'the rest'} is right)")
        elif H >= 3 and W >= 3 and not (spatial[0].any() or spatial[-1].any() or spatial[:, 0].any()
                                        or spatial[:, -1].any()):
            words.append("all in the interior (the outermost rows and columns are right)")
        elif rows[-1] - rows[0] + 1 < H or cols[-1] - cols[0] + 1 < W:
            words.append("all in " + ", ".join(part for part in (_span(rows, H, "row"), _span(cols, W, "column"))
                                                if part))
    if bad.ndim == 3 and 2 <= bad.shape[2] <= 4:
        channels = np.flatnonzero(bad.reshape(-1, bad.shape[2]).any(axis=0))
        if channels.size < bad.shape[2]:
            names = ", ".join(f"{k} ({_CHANNEL_NAMES[k]})" if bad.shape[2] >= 3 else str(k) for k in channels)
            words.append(f"only in channel{'s' if channels.size > 1 else ''} {names}")
    return ", ".join(words)


def _span(index: np.ndarray, size: int, word: str) -> str:
    """``"rows 2–5"``, ``"row 0"`` (one), or "" when the indices span the whole axis."""
    first, last = int(index[0]), int(index[-1])
    if first == 0 and last == size - 1:
        return ""
    return f"{word} {first}" if first == last else f"{word}s {first}–{last}"


def describe_difference(got: Any, expected: Any, bad: np.ndarray | None = None, *,
                        rtol: float = 1e-7, atol: float | None = None) -> str:
    """One sentence: how many values differ and where, the first one (yours vs expected) and
    the largest error. ``bad`` marks the wrong values (default: not within ``atol + rtol·|e|``,
    ``atol`` default ``1e-10·max(1, max|e|)``). Arrays of one shape; "" if nothing differs."""
    g, e = np.asarray(got), np.asarray(expected)
    a = g.astype(np.float64) if g.dtype.kind in "biuf" else None
    x = e.astype(np.float64) if e.dtype.kind in "biuf" else None
    if bad is None:
        if a is None or x is None or a.shape != x.shape:
            return ""
        bad = ~_close(a, x, rtol, _scale(x) * 1e-10 if atol is None else atol)
    bad = np.asarray(bad, dtype=bool)
    n, N = int(bad.sum()), int(bad.size)
    if n == 0:
        return ""
    first = int(np.flatnonzero(bad)[0])
    diff = None
    if a is not None and x is not None:
        with np.errstate(all="ignore"):
            diff = np.where(np.isfinite(a) & np.isfinite(x) & bad, np.abs(a - x), -np.inf)
    if N == 1:
        text = f"your value is {_value(g.flat[0])}, expected {_value(e.flat[0])}"
        if diff is not None and np.isfinite(diff.flat[0]):
            text += f" (error {diff.flat[0]:.3g})"
        return text + "."
    count = f"all {N} values differ" if n == N else f"{n} of {N} values differ"
    if a is not None and x is not None:
        with np.errstate(all="ignore"):
            odd = int((bad & (np.isfinite(a) != np.isfinite(x))).sum() + (bad & np.isnan(a) & np.isinf(x)).sum()
                      + (bad & np.isinf(a) & np.isnan(x)).sum())
        if odd:
            count += (" (NaN/inf in one output but not in the other)" if odd == n else
                      f" ({odd} of them NaN/inf in one output but not in the other)")
    where = locate(bad)
    shape = e.shape
    parts = [count + (f", {where}" if where else "")]
    parts.append(f"{'first at' if n > 1 else 'at'} {position(np.unravel_index(first, shape), shape)}: "
                 f"yours {_value(g.flat[first])}, expected {_value(e.flat[first])}")
    if diff is not None and np.isfinite(diff.max()) and n > 1:
        worst = int(np.argmax(diff))
        at = "" if worst == first else f" at {position(np.unravel_index(worst, shape), shape)}"
        parts.append(f"largest error {diff.flat[worst]:.3g}{at}")
    return "; ".join(parts) + "."


# --------------------------------------------------------------------------------------------
# the shape of the error
# --------------------------------------------------------------------------------------------
_SHIFT_HINT = ("check the anchor of your window: the result at [r, c] comes from the window centred on [r, c] "
               "(rows r − k … r + k for radius k; in an image padded by k that is rows r … r + 2k)")
_TRANSPOSE_HINT = f"{CONVENTION}: look for image[x, y] instead of image[y, x], or a grid built in the wrong order"


def _geometric(a: np.ndarray, e: np.ndarray, eq) -> list[Diagnosis]:
    """Transposes, flips and rotations (of the first two axes) of the expected output."""
    found = []
    if e.ndim == 1:
        if e.size >= 3 and a.shape == e.shape and eq(a, e[::-1]).all():
            found.append(Diagnosis("flip", "your output is in reverse order (the expected values back to front)",
                                   "check the direction of your indices or of a sort (ascending, not descending)"))
        return found
    if e.ndim < 2 or e.shape[0] * e.shape[1] < 4 or not _image_like(e.shape):
        return found
    points = e.ndim == 2 and e.shape[1] == 2 and e.shape[0] > 2
    candidates = [
        ("transposed", "your output is the expected one transposed (rows and columns swapped)",
         _TRANSPOSE_HINT, np.swapaxes(e, 0, 1)),
        ("flip", "your output is the expected one flipped upside down",
         "row 0 is the top of the image and y grows downwards: look for a reversed row index (H − 1 − r) or [::-1]",
         e[::-1]),
        ("flip", "your two columns are swapped (for points: x and y swapped; points are (x, y) = (col, row))"
         if points else "your output is the expected one mirrored left-right",
         "keep the order (x, y) = (col, row)" if points else
         "column 0 is the left of the image: look for a reversed column index (W − 1 − c) or [:, ::-1]",
         e[:, ::-1]),
        ("flip", "your output is the expected one rotated by 180° (flipped up-down and left-right)",
         "look for indices reversed in both directions (a kernel or an image flipped once too often?)",
         e[::-1, ::-1]),
        ("transposed", "your output is the expected one rotated by 90° counter-clockwise",
         f"{CONVENTION}: check the order of the axes and the direction of your indices",
         np.rot90(e, 1, axes=(0, 1))),
        ("transposed", "your output is the expected one rotated by 90° clockwise",
         f"{CONVENTION}: check the order of the axes and the direction of your indices",
         np.rot90(e, -1, axes=(0, 1))),
        ("transposed", "your output is the expected one transposed about the other diagonal",
         f"{CONVENTION}: check the order of the axes and the direction of your indices",
         np.swapaxes(e[::-1, ::-1], 0, 1)),
    ]
    for kind, what, hint, t in candidates:
        if t.shape == a.shape and eq(a, t).all():
            found.append(Diagnosis(kind, what, hint))
    return found


def _channels(a: np.ndarray, e: np.ndarray, eq) -> list[Diagnosis]:
    if e.ndim != 3 or not 3 <= e.shape[2] <= 4 or a.shape != e.shape:
        return []
    found = []
    C = e.shape[2]
    for perm in itertools.permutations(range(C)):
        if perm == tuple(range(C)):
            continue
        if eq(a, e[..., list(perm)]).all():
            if perm[:3] == (2, 1, 0):
                what = "your colour channels are in reverse order (BGR instead of RGB: red and blue swapped)"
            else:
                what = "your colour channels are in the wrong order: " + ", ".join(
                    f"your channel {k} holds the expected {_CHANNEL_NAMES[p]}" for k, p in enumerate(perm) if k != p)
            found.append(Diagnosis("channels", what,
                                   "colour images are (H, W, 3) RGB: [..., 0] red, [..., 1] green, [..., 2] blue "
                                   "(OpenCV's BGR order is not used here)"))
    return found


def _shift(a: np.ndarray, e: np.ndarray, eq) -> list[Diagnosis]:
    """Outputs equal to the expected one shifted by (dy, dx) wherever the two overlap."""
    if a.shape != e.shape or e.ndim == 0 or not _image_like(e.shape):
        return []
    H = e.shape[0]
    W = e.shape[1] if e.ndim >= 2 else 1
    found = []
    for dy in range(-_MAX_SHIFT, _MAX_SHIFT + 1):
        for dx in (range(-_MAX_SHIFT, _MAX_SHIFT + 1) if e.ndim >= 2 else (0,)):
            if dy == dx == 0:
                continue
            oh, ow = H - abs(dy), W - abs(dx)
            if oh < 1 or ow < 1 or oh * ow < 0.5 * H * W or oh * ow < 4:
                continue
            cols = e.ndim >= 2
            here = (slice(max(dy, 0), H + min(dy, 0)),) + ((slice(max(dx, 0), W + min(dx, 0)),) if cols else ())
            there = (slice(max(-dy, 0), H + min(-dy, 0)),) + ((slice(max(-dx, 0), W + min(-dx, 0)),) if cols else ())
            # your [r, c] holds the expected [r − dy, c − dx]
            if not eq(a[here], e[there]).all():
                continue
            moved = ~eq(e[here], e[there])       # where the shift changes the expected output at all
            if moved.sum() < max(2, 0.25 * moved.size):
                continue
            found.append((dy, dx))
    if not found:
        return []
    out = []
    for dy, dx in found:
        if e.ndim == 1:
            toward = "towards the end" if dy > 0 else "towards the start"
            what = (f"your output is shifted by {_plural(abs(dy), 'position')} {toward}: your value [i] is the one "
                    f"expected at [i {'−' if dy > 0 else '+'} {abs(dy)}]")
        else:
            moves = []
            if dy:
                moves.append(f"{_plural(abs(dy), 'row')} {'down' if dy > 0 else 'up'}")
            if dx:
                moves.append(f"{_plural(abs(dx), 'column')} {'right' if dx > 0 else 'left'}")
            r = "r" if not dy else f"r {'−' if dy > 0 else '+'} {abs(dy)}"
            c = "c" if not dx else f"c {'−' if dx > 0 else '+'} {abs(dx)}"
            what = (f"your output is shifted by {' and '.join(moves)}: your pixel [r, c] holds the value expected "
                    f"at [{r}, {c}]")
        out.append(Diagnosis("shift", what, _SHIFT_HINT))
    return out


def _values(a: np.ndarray, e: np.ndarray, eq, scale: float, got_dtype) -> list[Diagnosis]:
    """Scale, sign, offset, linear rescaling, rounding, clipping, wrap-around, float32."""
    if a.shape != e.shape or a.size < 2 or not (np.isfinite(a).all() and np.isfinite(e).all()):
        return []
    found = []
    spread = float(e.max() - e.min())
    varied = spread > 1e-9 * scale
    if not a.any() and e.any():
        if got_dtype is not None and got_dtype.kind == "b":
            return [Diagnosis("zeros", "your output is all False", "no value passes your test: check the condition "
                              "(> vs <, the threshold, the variable you compare)")]
        return [Diagnosis("zeros", "your output is all zeros",
                          "did you create the result (np.zeros_like) and never fill it, or return the wrong variable?")]
    if got_dtype is not None and got_dtype.kind == "f" and got_dtype.itemsize < 8 and \
            _close(a, e, 2e-6, 2e-6 * scale).all():
        found.append(Diagnosis("precision", f"your output is {got_dtype.name}: its values differ from the expected "
                               "ones only in the last digits", "compute and return float64 (np.float64), not float32"))
        return found
    if varied:
        j = int(np.argmax(np.abs(e)))
        c = a.flat[j] / e.flat[j] if e.flat[j] != 0 else np.nan
        if np.isfinite(c) and c != 0 and abs(c - 1) > 1e-6 and eq(a / c, e).all():
            found.append(_scale_diagnosis(float(c)))
        d = float(a.flat[j] - e.flat[j])
        if abs(d) > 1e-9 * scale and eq(a - d, e).all():
            found.append(Diagnosis("offset", f"your output is the expected one {'plus' if d > 0 else 'minus'} "
                                   f"{_number(abs(d))} everywhere",
                                   "a constant is added or missing: an offset or bias, a mean (not) subtracted, "
                                   "or counting from 1 instead of 0"))
        if not found and np.unique(e).size >= 3:
            lo, hi = int(np.argmin(e)), int(np.argmax(e))
            s = (a.flat[hi] - a.flat[lo]) / (e.flat[hi] - e.flat[lo])
            b = a.flat[lo] - s * e.flat[lo]
            if np.isfinite(s) and s != 0 and abs(s - 1) > 1e-6 and abs(b) > 1e-9 * scale \
                    and eq((a - b) / s, e).all():
                if abs(a.min()) <= 1e-9 and abs(a.max() - 1) <= 1e-9:
                    what = "your output is the expected one stretched to the range [0, 1]"
                elif abs(a.min()) <= 1e-9 * 255 and abs(a.max() - 255) <= 1e-9 * 255:
                    what = "your output is the expected one stretched to the range [0, 255]"
                else:
                    sign = "+" if b > 0 else "−"
                    what = f"your output is the expected one rescaled: ×{_number(s)} {sign} {_number(abs(b))}"
                found.append(Diagnosis("affine", what, "do not rescale or normalise the result: values stay in the "
                                       "input's units (a uint8 image stays in 0..255)"))
    whole = np.all(e == np.round(e))
    if not whole:
        kinds = [name for name, f in (("round", np.round), ("trunc", np.trunc), ("floor", np.floor))
                 if eq(a, f(e)).all()]
        if kinds:
            what = ("your values are rounded to whole numbers" if kinds == ["round"] else
                    "your values are cut to whole numbers (the decimals dropped, as .astype(int) does)"
                    if "round" not in kinds else "your values are whole numbers: the decimals are lost")
            found.append(Diagnosis("rounding", what, "keep the result in float64: do not round it or convert it to an "
                                   "integer type"))
    ranges: tuple[tuple[float, float | None], ...] = ((0.0, 1.0), (0.0, 255.0), (0.0, None),
                                                      (float(a.min()), float(a.max())))
    for low, high in ranges:
        outside = (e < low) | ((e > high) if high is not None else False)
        if not np.any(outside):
            continue
        clipped = np.clip(e, low, high)
        for f, how in ((lambda v: v, ""), (np.round, " and rounded")):
            if eq(a, f(clipped)).all() and (how == "" or not np.all(clipped == np.round(clipped))):
                span = f"[{_number(low)}, {_number(high)}]" if high is not None else f"≥ {_number(low)}"
                found.append(Diagnosis("clipping", f"your values are clipped to {span}{how}",
                                       f"do not clip (or convert to uint8): the expected output goes outside {span}"))
                break
        else:
            continue
        break
    if np.any((e < 0) | (e > 255)):
        for f in (lambda v: v, np.trunc, np.round):
            if eq(a, np.mod(f(e), 256)).all():
                found.append(Diagnosis("wraparound",
                                       "your values wrap around at 256 (uint8 overflow: 250 + 10 gives 4)",
                                       "compute in float64 (np.asarray(image, dtype=float)) before adding or "
                                       "multiplying: uint8 arithmetic wraps around"))
                break
    return found


def _scale_diagnosis(c: float) -> Diagnosis:
    if abs(c + 1) <= 1e-6:
        return Diagnosis("sign", "your output has the opposite sign (the expected values times −1)",
                         "check the order of a subtraction (a − b, not b − a) and the sign convention")
    degrees = np.degrees(1.0)
    if abs(c / degrees - 1) <= 1e-6:
        return Diagnosis("scale", "your output is the expected one × 57.3: degrees instead of radians",
                         "angles are in radians: do not convert them to degrees")
    if abs(c * degrees - 1) <= 1e-6:
        return Diagnosis("scale", "your output is the expected one ÷ 57.3: angles taken as degrees",
                         "angles are in radians: do not convert them (np.radians / np.deg2rad)")
    if abs(c) > 1 and abs(c - round(c)) <= 1e-6 * abs(c):
        what = f"your output is {int(round(abs(c)))} times the expected one" + \
            (" with the opposite sign" if c < 0 else "")
    elif abs(c) < 1 and abs(1 / c - round(1 / c)) <= 1e-6 * abs(1 / c):
        what = f"your output is the expected one divided by {int(round(abs(1 / c)))}" + \
            (" with the opposite sign" if c < 0 else "")
    else:
        what = f"your output is the expected one multiplied by {_number(c)}"
    return Diagnosis("scale", what, "check a normalisation factor: weights that should sum to 1, a division by the "
                     "number of values or by the sum of the weights, a unit (255 vs 1)")


def _is_image(shape: tuple, image: bool | tuple[int, ...]) -> bool:
    """Whether an output of this ``shape`` is a picture whose edges are an image's border:
    ``image`` True (not known: any image-like shape), False (the case has no input image) or
    the shape of the case's first argument, which is an image when it is at least 4×4 (a
    filtered, padded or cropped image of it is one too); a 4×4 matrix made from a 3×3 rotation,
    a kernel made from σ or a matrix made from (N, 2) points is not."""
    if len(shape) < 2 or min(shape[:2]) < 3 or not _image_like(shape):
        return False
    if image is True or image is False:
        return image
    return len(image) >= 2 and min(image[:2]) >= 4


def _partial(a: np.ndarray, e: np.ndarray, bad: np.ndarray, image: bool | tuple[int, ...] = True) -> Diagnosis | None:
    """Facts that locate the error when no transformation explains it (``image``: see
    :func:`_is_image`; an output that is no image gets the place, not the border's advice)."""
    with np.errstate(all="ignore"):
        nonfinite = bad & ~np.isfinite(a) & np.isfinite(e)
        missing = bad & np.isfinite(a) & ~np.isfinite(e)
    if nonfinite.any():
        k = int(np.flatnonzero(nonfinite)[0])
        nan = bool(np.isnan(a.flat[k]))
        return Diagnosis(
            "nonfinite",
            f"your output has {_plural(int(nonfinite.sum()), 'NaN/inf value')} where the expected values are numbers "
            f"(first at {position(np.unravel_index(k, e.shape), e.shape)}: yours {_value(a.flat[k])}, expected "
            f"{_value(e.flat[k])})",
            ("look for 0/0 (a division by a sum or a count that can be 0), the mean of an empty selection, or an "
             "operation on NaN" if nan else "look for a division by zero (x/0 gives inf) or an overflow")
            + ", and handle that case as the exercise says")
    if missing.any() and not (bad & ~missing).any():
        k = int(np.flatnonzero(missing)[0])
        return Diagnosis(
            "missing_nonfinite",
            f"the expected output has NaN/inf at {_plural(int(missing.sum()), 'place')} where yours has numbers "
            f"(first at {position(np.unravel_index(k, e.shape), e.shape)}: yours {_value(a.flat[k])}, expected "
            f"{_value(e.flat[k])})",
            "where the definition gives NaN or inf (e.g. a division by 0 the exercise keeps), return it: do not "
            "replace it by a number")
    if e.ndim >= 2 and min(e.shape[:2]) >= 3 and _image_like(e.shape):
        spatial = _spatial(bad)
        frame = _frame(spatial)
        if frame is not None and not _is_image(e.shape, image):
            text, all_sides = _frame_words(*frame)
            what = ("only the entries at the edges of the result (its first and last rows and columns) are wrong, "
                    "the inner ones are right" if all_sides else
                    f"only {text} of the result {'is' if ' and ' not in text else 'are'} wrong, the rest is right")
            return Diagnosis("edge_entries", what,
                             "look at how those entries are computed or filled in, apart from the others (a term "
                             "left out, an index one off, a value left at its start)")
        if frame is not None:
            text, all_sides = _frame_words(*frame)
            if all_sides:
                return Diagnosis("border", f"only {text} is wrong, the interior is right",
                                 "the formula is right; look at how you fill or read the pixels outside the image: the "
                                 "`border` mode (zero, replicate, reflect dcb|abcd|cba, reflect101 dc|abcd|cb) and "
                                 "the index arithmetic of the mirrored/replicated pixels")
            return Diagnosis("border", f"only {text} {'is' if ' and ' not in text else 'are'} wrong, the rest is right",
                             "check where your loops or slices start and end (the last index is H − 1; a slice a:b "
                             "stops before b), and the pixels whose window reaches outside the image")
    if e.ndim == 3 and 3 <= e.shape[2] <= 4:
        channels = np.flatnonzero(bad.reshape(-1, e.shape[2]).any(axis=0))
        if 0 < channels.size < e.shape[2]:
            names = " and ".join(f"{k} ({_CHANNEL_NAMES[k]})" for k in channels)
            return Diagnosis("channel_only", f"only channel{'s' if channels.size > 1 else ''} {names} "
                             f"{'are' if channels.size > 1 else 'is'} wrong",
                             "treat every channel of an (H, W, 3) image the same way (or work on the last axis "
                             "as a whole)")
    return None


def diagnose(got: Any, expected: Any, *, rtol: float = 1e-7, atol: float | None = None,
             image: bool | tuple[int, ...] = True) -> Diagnosis | None:
    """What a wrong output is, in plain words, or None.

    ``rtol``/``atol`` say when two values are equal (``atol`` default ``1e-10·max(1, max|e|)``;
    transformations are matched with at least ``rtol = 1e-9``, ``atol = 1e-9·max(1, max|e|)``,
    so that a different order of summation does not hide them). Tuples and lists of arrays
    are diagnosed element by element ("result [1]: ..."), and a pair returned in the wrong
    order is named. None when the output equals the expected one, when nothing simple explains
    the difference, or when two explanations fit equally well. ``image`` is the shape of the
    case's first argument (False: it is no array; True, the default: not known): only an
    output computed from an image (an input of at least 4×4) is told about an image's border,
    any other just where its wrong entries are.
    """
    if isinstance(expected, (tuple, list)) and not isinstance(expected, np.ndarray):
        if not isinstance(got, (tuple, list)) or len(got) != len(expected):
            return None
        numeric = [(_numeric(g), _numeric(x)) for g, x in zip(got, expected)]
        parts = [(g, x) for g, x in numeric if g is not None and x is not None]
        if len(parts) < len(numeric):
            return None
        scales = [_scale(x.astype(np.float64)) for _, x in parts]
        same = [g.shape == x.shape and _close(g.astype(float), x.astype(float), max(rtol, 1e-9),
                                               max(atol or 0.0, 1e-9 * s)).all() for (g, x), s in zip(parts, scales)]
        if all(same):
            return None
        n = len(parts)
        if n >= 2:
            for perm in itertools.permutations(range(n)):
                if perm == tuple(range(n)):
                    continue
                if all(parts[i][0].shape == parts[p][1].shape and _close(
                        parts[i][0].astype(float), parts[p][1].astype(float), max(rtol, 1e-9),
                        max(atol or 0.0, 1e-9 * scales[p])).all() for i, p in enumerate(perm)):
                    distinct = any(parts[i][1].shape != parts[p][1].shape or not _close(
                        parts[i][1].astype(float), parts[p][1].astype(float), 1e-9, 1e-9 * scales[p]).all()
                        for i, p in enumerate(perm))
                    if distinct:
                        what = ("your two results are swapped (you return the second expected result first)"
                                if n == 2 else "your results are in the wrong order: " + ", ".join(
                                    f"your [{i}] is the expected [{p}]" for i, p in enumerate(perm) if i != p))
                        return Diagnosis("order", what, "return the results in the order the exercise states")
        for i, ((part, expected_part), ok) in enumerate(zip(parts, same)):
            if not ok:
                found = diagnose(part, expected_part, rtol=rtol, atol=atol, image=image)
                if found is None:
                    return None
                return Diagnosis(found.kind, f"result [{i}]: {found.what}", found.hint)
        return None
    g, x = _numeric(got), _numeric(expected)
    if g is None or x is None:
        return None
    a, e = g.astype(np.float64), x.astype(np.float64)
    scale = _scale(e)
    atol_abs = 1e-10 * scale if atol is None else float(atol)
    if a.shape == e.shape:
        bad = ~_close(a, e, rtol, atol_abs)
        if not bad.any():
            return None
    else:
        bad = None
    rt, at = max(rtol, 1e-9), max(atol_abs, 1e-9 * scale)

    def eq(p, q):
        return _close(p, q, rt, at)

    exact = _geometric(a, e, eq) + _channels(a, e, eq) + _shift(a, e, eq)
    if a.shape == e.shape:
        exact += _values(a, e, eq, scale, g.dtype)
    if len(exact) == 1:
        return exact[0]
    if exact or bad is None:
        return None  # ambiguous, or a shape that nothing explains
    return _partial(a, e, bad, image)


# --------------------------------------------------------------------------------------------
# exceptions
# --------------------------------------------------------------------------------------------
_OUT_OF_BOUNDS = re.compile(r"index (-?\d+) is out of bounds for axis (\d+) with size (\d+)")
_SHAPE = re.compile(r"\((\d+(?:\s*,\s*\d+)*)\s*,?\s*\)")


def _images(args: Sequence[Any]) -> list[np.ndarray]:
    out = []
    for value in args:
        arr = _numeric(value) if isinstance(value, np.ndarray) else None
        if arr is not None and arr.ndim in (2, 3) and min(arr.shape[:2]) >= 2:
            out.append(arr)
    return out


def explain_exception(message: str, args: Sequence[Any] = (), *, swap_plausible: bool = True) -> str | None:
    """Plain words for an ``IndexError``/``ValueError`` about indices or shapes, read against
    the case's arguments ``args``; None when nothing specific can be said.

    ``swap_plausible=False`` (the code crashed on a square crop of the image too) leaves out
    the suggestion that rows and columns are swapped."""
    if not message:
        return None
    images = _images(args)
    m = _OUT_OF_BOUNDS.search(message)
    if m:
        index, axis, size = int(m.group(1)), int(m.group(2)), int(m.group(3))
        past_end = (f"valid indices along axis {axis} are 0 … {size - 1} (range(n) and slices a:b stop before the "
                    "end); check the limits of your loops and windows")
        if swap_plausible:
            for img in images:
                H, W = img.shape[:2]
                if axis in (0, 1) and img.shape[axis] == size and H != W:
                    other = img.shape[1 - axis]
                    if -other <= index < other:
                        kind, other_kind = ("row", "column") if axis == 0 else ("column", "row")
                        return (f"the index {index} is past the last {kind} of the {H}×{W} image ({kind}s 0 … "
                                f"{size - 1}) but would fit its {other_kind}s (0 … {other - 1}): if you index with "
                                f"[x, y], rows and columns are swapped ({CONVENTION})"
                                + (f"; otherwise {past_end}" if index == size else ""))
        if index == size:
            return f"the index {index} is one past the last one ({size - 1}): {past_end}"
        return None
    if isinstance(message, str) and ("broadcast" in message or "shape" in message):
        shapes = [tuple(int(v) for v in s.split(",") if v.strip()) for s in _SHAPE.findall(message)]
        shapes = [s for s in shapes if len(s) >= 2]
        for s, t in itertools.combinations(shapes, 2):
            if s[:2] == t[:2][::-1] and s[0] != s[1]:
                return (f"two arrays of shapes {s} and {t} are combined: one has rows and columns swapped. "
                        f"{CONVENTION}; np.meshgrid(np.arange(W), np.arange(H)) gives (H, W) arrays")
            if len(s) == len(t) and s[2:] == t[2:]:
                dr, dc = s[0] - t[0], s[1] - t[1]
                if dr and dc and dr * dc > 0 and abs(dr) % 2 == 0 and abs(dc) % 2 == 0:
                    return (f"two arrays of shapes {s} and {t} are combined: they differ by {abs(dr)} rows and "
                            f"{abs(dc)} columns, like a padded and an unpadded image: slice the padded one back to "
                            "the image's size (rows r … r + H − 1 for the window offset r)")
    return None


def image_variants(args: Sequence[Any]) -> list[tuple[str, tuple]]:
    """Variants of a case whose first argument is a non-square image: ``("square", args)`` with
    the image cropped to its top-left square and ``("transposed", args)`` with rows and columns
    swapped. [] when the first argument is not such an image."""
    if not args or not isinstance(args[0], np.ndarray):
        return []
    img = args[0]
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] > 4) or img.dtype.kind not in "biuf":
        return []
    H, W = img.shape[:2]
    if H == W or min(H, W) < 2:
        return []
    n = min(H, W)
    rest = tuple(args[1:])
    return [("square", (np.ascontiguousarray(img[:n, :n]),) + rest),
            ("transposed", (np.ascontiguousarray(np.swapaxes(img, 0, 1)),) + rest)]
