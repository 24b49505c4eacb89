"""Check of Chapter 2's block matching: synthetic stereo pairs, a tie-aware comparator and the
mistake bank.

Cases are small synthetic rectified pairs (≤ 16×22 pixels, ≤ 10 disparities, so a student's
loop over pixels and disparities finishes in well under a second): a random texture seen by
the right camera, and a left view in which a background plane and a rectangle in front of it
are shifted by two different disparities. Some cases add a flat band (every candidate ties:
the answer must be d = 0), a gain and offset between the two views (what ZNCC is for), uint8
images (differences must not wrap around), integer-valued images (exact costs, so exact ties
between some candidates), one-pixel blocks, a disparity range wider than the image, a
2×3 image with a 5×5 block, constant images.

The comparator (:class:`DisparityMaps`) requires the same disparity at every pixel, except
where the candidate's disparity and the reference's have costs that agree within round-off
(1e-9 relative): two correct programs that add the window in different orders may break such
near-ties differently. Where *all* candidates of a pixel cost exactly the same (flat
windows), and everywhere for SAD and SSD on integer-valued images (whose costs every correct
program computes exactly), only the smallest d is right.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..grading import Case, Check, Comparator, Mismatch, Mistake, mistake
from ..grading.checks import Measure
from ..grading.casekit import argument, variant
from ..grading.casekit import seed as _seed
from ..grading.compare import as_numeric
from ..grading.measured import MeasuredCase, Scale
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ._matching import _window_is_flat
from ._matching import cost_volume
from ._measured import GOOD_PIXEL_SCALE, BUDGET_SECONDS, PAIR_MAX_DISPARITY, bad_pixel_rate, match_pair, synthetic_pair

__all__ = ["block_matching", "DisparityMaps", "dense_disparity", "BadPixelRate", "DISPARITY_SCALE"]

_NAMES = ("left", "right", "max_disparity", "block_size", "cost")
_DEFAULTS = {"block_size": 7, "cost": "sad"}


def _arg(case: Case, index: int, name: str):
    return argument(case, index, name, _DEFAULTS.get(name))


def _integer_valued(array: np.ndarray) -> bool:
    return bool(np.all(np.mod(array, 1.0) == 0.0))


@dataclass
class DisparityMaps(Comparator):
    """Integer disparity maps, equal up to genuine ties of the matching cost.

    A pixel where ``got`` differs from ``expected`` is accepted only if ``got`` is a valid
    candidate (0 <= d <= min(x, max_disparity)) whose cost equals the cost of ``expected``
    within ``rtol`` × the scale of the costs, and if not every candidate of that pixel has
    exactly the same cost (then the smallest d is the only right answer). For SAD and SSD on
    integer-valued images every order of summation is exact, so there the maps must be equal:
    among tied candidates the smallest d wins.
    """

    rtol: float = 1e-9

    def describe(self) -> str:
        return "equal disparities, except between candidates whose costs tie up to round-off"

    @staticmethod
    def _costs(case: Case) -> tuple[np.ndarray, float]:
        cached = case.__dict__.get("_cvkit_costs")
        if cached is not None:
            return cached
        left = np.asarray(_arg(case, 0, "left"), dtype=np.float64)
        right = np.asarray(_arg(case, 1, "right"), dtype=np.float64)
        max_disparity = int(_arg(case, 2, "max_disparity"))
        block_size = int(_arg(case, 3, "block_size"))
        cost = _arg(case, 4, "cost")
        volume = cost_volume(left, right, max_disparity, block_size, cost)
        n = block_size * block_size
        scale = max(1.0, float(np.abs(left).max()), float(np.abs(right).max()))
        if cost == "zncc":
            volume = -volume                  # minimised, like SAD and SSD
            tol = 1e-9
        elif _integer_valued(left) and _integer_valued(right):
            tol = 0.0
        else:
            tol = 1e-9 * n * (scale if cost == "sad" else scale * scale)
        case.__dict__["_cvkit_costs"] = (volume, tol)
        return volume, tol

    def __call__(self, got, expected, case=None):
        if got is None:
            return Mismatch("your output is None: did you forget to `return` the disparity map?")
        try:
            arr = np.asarray(got)
        except Exception as exc:  # ragged lists and the like
            return Mismatch(f"your output could not be turned into an array ({type(exc).__name__}: {exc})")
        exp = np.asarray(expected)
        if arr.dtype.kind not in "iu":
            return Mismatch(
                f"dtype mismatch: expected an integer array of disparities (np.int64), got {arr.dtype}"
                + (" (use .astype(np.int64) or an integer array for the result)" if arr.dtype.kind == "f" else "")
            )
        if arr.shape != exp.shape:
            return Mismatch(f"shape mismatch: expected {exp.shape} (one disparity per left pixel), got {arr.shape}")
        differ = arr != exp
        if not differ.any():
            return None
        total = exp.size
        if case is None:
            n = int(differ.sum())
            first = tuple(int(i) for i in np.argwhere(differ)[0])
            return Mismatch(f"Mismatched disparities: {n} / {total}", worst=first, mismatched=n, total=total)
        volume, tol = self._costs(case)
        candidates = volume.shape[0]
        height, width = exp.shape
        x = np.broadcast_to(np.arange(width)[None, :], exp.shape)
        limit = np.minimum(x, candidates - 1)

        def cost_of(d):
            inside = (d >= 0) & (d <= limit)
            picked = np.take_along_axis(volume, np.clip(d, 0, candidates - 1)[None].astype(np.int64), axis=0)[0]
            return np.where(inside, picked, np.nan), inside

        cost_got, valid_got = cost_of(arr.astype(np.int64))
        cost_exp, _ = cost_of(exp.astype(np.int64))
        with np.errstate(invalid="ignore"):
            # exact costs (tol 0): a tie is a tie in every correct program, the smallest d wins
            near = (np.abs(cost_got - cost_exp) <= tol) if tol > 0 else np.zeros(exp.shape, dtype=bool)
            full_tie = (np.nanmax(volume, axis=0) == np.nanmin(volume, axis=0)) & (limit > 0)
        bad = differ & (~valid_got | ~near | full_tie)
        n = int(bad.sum())
        if n == 0:
            return None
        row, col = (int(i) for i in np.argwhere(bad)[0])
        g, e = int(arr[row, col]), int(exp[row, col])
        lines = [
            f"Mismatched disparities: {n} / {total} ({100 * n / total:.3g}%)",
            f"First at [row, col] = [{row}, {col}]: yours {g}, expected {e}",
        ]
        if not valid_got[row, col]:
            if g < 0:
                lines.append("  disparities are >= 0: the match of left (x, y) is right (x − d, y)")
            elif g > col:
                lines.append(f"  d = {g} > x = {col}: the right pixel x − d would be outside the image (only d <= x)")
            else:
                lines.append(f"  d = {g} is larger than max_disparity")
        elif full_tie[row, col] or cost_got[row, col] == cost_exp[row, col]:
            lines.append(f"  d = {g} and d = {e} have the same cost here: ties go to the smallest d")
        else:
            lines.append(f"  cost of your d: {cost_got[row, col]:.6g}, of the expected d: {cost_exp[row, col]:.6g}"
                         + (" (ZNCC shown negated: lower is better)" if _arg(case, 4, "cost") == "zncc" else ""))
        return Mismatch("\n".join(lines), worst=(row, col), mismatched=n, total=total)


# --------------------------------------------------------------------------------------------
# the mistakes (a loop over disparities with knobs)
# --------------------------------------------------------------------------------------------
def _variant(left, right, max_disparity, block_size=7, cost="sad", *, sign=1, anchor="centre",
             exclude=True, ties="smallest", wrap=False, means=True, maximise=True, border="reflect", flat_score=0.0):
    """Block matching with one thing done wrong (direct window sums; small images only)."""
    raw_l, raw_r = np.asarray(left), np.asarray(right)
    if wrap and raw_l.dtype == np.uint8 and raw_r.dtype == np.uint8 and cost != "zncc":
        diff_dtype = np.uint8
    else:
        diff_dtype = np.float64
    L = raw_l.astype(diff_dtype)
    R = raw_r.astype(diff_dtype)
    height, width = L.shape
    b = block_size
    r = b // 2
    # the window of pixel (x, y) covers rows y + a .. y + a + b − 1 (a = −r centred, 0 anchored)
    a = -r if anchor == "centre" else 0
    lo, hi = -a, b - 1 + a                           # padding needed before and after
    pad = max(lo, hi) + max_disparity + 1           # every shift stays inside the padded images
    if border == "zero":
        Lp, Rp = np.pad(L, pad), np.pad(R, pad)
    else:
        Lp, Rp = np.pad(L, pad, mode="reflect"), np.pad(R, pad, mode="reflect")
    costs = np.full((max_disparity + 1, height, width), np.nan)
    for d in range(max_disparity + 1):
        shift = sign * d
        total = np.zeros((height, width))
        total_l = np.zeros((height, width))
        total_r = np.zeros((height, width))
        total_ll = np.zeros((height, width))
        total_rr = np.zeros((height, width))
        for i in range(b):
            for j in range(b):
                rows = slice(pad + a + i, pad + a + i + height)
                lw = Lp[rows, pad + a + j: pad + a + j + width]
                rw = Rp[rows, pad + a + j - shift: pad + a + j - shift + width]
                if cost == "zncc":
                    lw, rw = lw.astype(np.float64), rw.astype(np.float64)
                    total += lw * rw
                    total_l += lw
                    total_r += rw
                    total_ll += lw * lw
                    total_rr += rw * rw
                elif cost == "sad":
                    diff = lw - rw                   # wraps around for uint8
                    total += np.abs(diff.astype(np.float64)) if diff_dtype == np.float64 else diff
                else:
                    diff = lw - rw
                    total += (diff * diff).astype(np.float64)
        if cost == "zncc":
            n = b * b
            if means:
                num = total - total_l * total_r / n
                var_l = total_ll - total_l ** 2 / n
                var_r = total_rr - total_r ** 2 / n
                rows = slice(pad + a, pad + a + height + b - 1)
                flat = (_window_is_flat(Lp[rows, pad + a: pad + a + width + b - 1], b)
                        | _window_is_flat(Rp[rows, pad + a - shift: pad + a - shift + width + b - 1], b))
            else:
                num, var_l, var_r = total, total_ll, total_rr
                flat = np.zeros((height, width), dtype=bool)
            with np.errstate(all="ignore"):
                score = np.where(~flat & (var_l > 0) & (var_r > 0), num / np.sqrt(var_l * var_r), flat_score)
            total = -score if maximise else score
        costs[d] = total
    x = np.arange(width)[None, :]
    disparity = np.zeros((height, width), dtype=np.int64)
    best = np.full((height, width), np.inf)
    for d in range(max_disparity + 1):
        if exclude:
            allowed = (x - d >= 0) if sign > 0 else (x + d <= width - 1)
        else:
            allowed = np.ones((1, width), dtype=bool)
        c = np.where(allowed, costs[d], np.inf)
        better = c <= best if ties == "largest" else c < best
        better &= allowed
        best = np.where(better, c, best)
        disparity = np.where(better, d, disparity)
    return disparity


# --------------------------------------------------------------------------------------------
# cases
# --------------------------------------------------------------------------------------------
def _pair(rng, h, w, max_disparity, *, kind="unit", flat_rows=0, gain=1.0, offset=0.0):
    """A synthetic rectified pair: background at disparity d1, a rectangle in front at d2."""
    d1 = int(rng.integers(1, max(2, max_disparity)))
    d2 = int(rng.integers(d1 + 1, max_disparity + 1)) if max_disparity > d1 else d1
    disparity = np.full((h, w), d1)
    top, left = int(rng.integers(1, max(2, h // 3))), int(rng.integers(w // 4, w // 2))
    disparity[top: top + max(2, h // 2), left: left + max(3, w // 3)] = d2

    def texture(shape):
        if kind == "uint8":
            return rng.integers(0, 256, shape).astype(np.float64)
        if kind == "int":
            return rng.integers(0, 10, shape).astype(np.float64)
        if kind == "big":
            return rng.integers(0, 1001, shape).astype(np.float64)
        return np.round(0.3 + 0.7 * rng.random(shape), 3)

    right = texture((h, w))
    cols = np.arange(w)[None, :] - disparity
    left_img = np.where(cols >= 0, right[np.arange(h)[:, None], np.clip(cols, 0, w - 1)], texture((h, w)))
    if kind == "unit":
        right = np.round(gain * right + offset, 4)
    if flat_rows:
        level = 128.0 if kind in ("uint8", "big") else (4.0 if kind == "int" else 0.5)
        left_img[:flat_rows] = level
        right[:flat_rows] = level
    if kind == "uint8":
        return left_img.astype(np.uint8), right.astype(np.uint8)
    return left_img, right


def _flat_candidates(rng, height, width, edge, shift, *, beaten):
    """A pair where some right windows are flat (0 left of column ``edge``): with ``beaten`` the
    rest is the left texture moved by ``shift`` (ZNCC 1 beats a flat window's 0), otherwise an
    anti-correlated ramp (every other window scores below 0, so the flat ones win)."""
    rows, cols = np.mgrid[0:height, 0:width]
    if beaten:
        left_img = rng.integers(1, 10, (height, width)).astype(np.float64)
        right = np.where(cols < edge, 0.0, np.roll(left_img, -shift, axis=1))
    else:  # both vary down the rows only: every right window that is not flat is the same, and
        # falls as the left one rises (ZNCC between −1 and −0.9: no tie with a flat window's 0)
        left_img = (rows + 1.0) ** 2
        right = np.where(cols < edge, 0.0, -(rows + 1.0) ** 3 - 1.0)
    return left_img, right


def _hidden(rng):
    def size(lo, hi):
        return _size(rng, lo, hi)

    cases = []

    def add(pair, max_disparity, label, **kwargs):
        cases.append(Case((pair[0], pair[1], max_disparity), kwargs, label))

    def textured(label, block_size, cost, disparities, rows, cols, **options):
        """A pair of ``rows`` × ``cols`` (drawn ranges) whose largest disparity, drawn from
        ``disparities``, is also the search range."""
        d = size(*disparities)
        add(_pair(rng, size(*rows), size(*cols), d, **options), d, label, block_size=block_size, cost=cost)

    textured("SAD, 3×3 blocks, flat band on top", 3, "sad", (3, 5), (9, 12), (14, 20), flat_rows=4)
    textured("SAD on uint8 images, 5×5 blocks", 5, "sad", (3, 6), (8, 12), (14, 20), kind="uint8")
    textured("SSD on uint8 images, flat band", 3, "ssd", (3, 5), (8, 11), (12, 18), kind="uint8", flat_rows=4)
    d = size(3, 6)
    add(_pair(rng, size(9, 12), size(14, 20), d, gain=_u(rng, 0.5, 0.8, 2),
              offset=_u(rng, 0.1, 0.3, 2)), d,
        "ZNCC, 5×5 blocks, right view darker and offset", block_size=5, cost="zncc")
    textured("SAD of single pixels (block 1), values 0..9", 1, "sad", (3, 5), (6, 9), (12, 16), kind="int")
    add(_pair(rng, size(6, 9), size(10, 14), 3, kind="big"), 0, "max_disparity = 0", block_size=3, cost="ssd")
    add(_pair(rng, 5, 6, 4, kind="int", flat_rows=0), size(7, 10), "max_disparity larger than the width",
        block_size=3, cost="sad")
    add(_pair(rng, 2, 3, 1), 2, "tiny 2×3 image, 5×5 block", block_size=5, cost="sad")
    level = _u(rng, 0.2, 0.8, 1)
    add((np.full((5, 9), level), np.full((5, 9), level)), size(3, 6), "constant images (all candidates tie)",
        block_size=3, cost="zncc")
    textured("tall image, 7×7 blocks, ZNCC", 7, "zncc", (3, 4), (14, 16), (7, 9), gain=1.2, offset=-0.2)
    textured("integer values 0..1000, SSD, 5×5 blocks", 5, "ssd", (3, 5), (9, 12), (16, 22), kind="big")
    d = size(3, 5)
    cases.append(Case(_pair(rng, size(9, 12), size(16, 22), d) + (d,), {}, "default block_size 7 and cost 'sad'"))
    add(_flat_candidates(rng, size(6, 9), size(14, 18), size(4, 7), size(1, 3), beaten=False), size(6, 9),
        "ZNCC, flat right windows (0) against anti-correlated ones (below 0)", block_size=3, cost="zncc")
    add(_flat_candidates(rng, size(6, 9), size(14, 18), size(4, 7), size(1, 3), beaten=True), size(6, 9),
        "ZNCC, flat right windows (0) against the true match (1)", block_size=3, cost="zncc")
    return cases


def _public():
    rng = np.random.default_rng(2024)
    sad_left, sad_right = _pair(rng, 9, 14, 4, flat_rows=4)
    u8_left, u8_right = _pair(rng, 8, 12, 3, kind="uint8")
    z_left, z_right = _pair(rng, 9, 14, 4, gain=0.6, offset=0.25, flat_rows=4)
    return [
        Case((sad_left, sad_right, 4), {"block_size": 3, "cost": "sad"}, "SAD, 3×3 blocks, flat band on top"),
        Case((u8_left, u8_right, 3), {"block_size": 5, "cost": "ssd"}, "SSD on uint8 images, 5×5 blocks"),
        Case((z_left, z_right, 4), {"block_size": 3, "cost": "zncc"},
             "ZNCC, right view darker and offset, flat band on top"),
        Case(_flat_candidates(rng, 7, 16, 6, 2, beaten=False) + (8,), {"block_size": 3, "cost": "zncc"},
             "ZNCC, flat right windows (0) against anti-correlated ones (below 0)"),
        Case(_flat_candidates(rng, 7, 16, 6, 2, beaten=True) + (8,), {"block_size": 3, "cost": "zncc"},
             "ZNCC, flat right windows (0) against the true match (1)"),
    ]


block_matching = Check(
    rules=("integer", "uint8"),
    public=_public,
    hidden=_hidden,
    compare=DisparityMaps(),
    mistakes=[
        Mistake("disparity sign reversed (x + d)", variant(_variant, sign=-1),
                "The match of left pixel (x, y) is right pixel (x − d, y): objects appear further left in the right image"),
        Mistake("window not centred (anchored at its top-left)", variant(_variant, anchor="corner"),
                "Centre the block on the pixel: rows y − r .. y + r and columns x − r .. x + r, r = block_size // 2"),
        Mistake("candidates with x − d < 0 not excluded", variant(_variant, exclude=False),
                "Only d <= x is a candidate (the right pixel x − d must be inside the image)"),
        Mistake("ties broken towards the largest d", variant(_variant, ties="largest"),
                "Keep the first (smallest) d among equal costs: update only when the cost is strictly better (<), or use argmin"),
        Mistake("uint8 differences wrapped around", variant(_variant, wrap=True),
                "Convert the images to float before subtracting: uint8 arithmetic wraps (3 − 5 = 254)"),
        Mistake("ZNCC minimised (it is a similarity)", variant(_variant, maximise=False),
                "SAD and SSD are minimised, but ZNCC measures similarity: take the d with the LARGEST ZNCC"),
        Mistake("ZNCC without subtracting the window means", variant(_variant, means=False),
                "Subtract each window's mean before correlating: ZNCC = Σ(L−L̄)(R−R̄) / √(Σ(L−L̄)² Σ(R−R̄)²)"),
        Mistake("zero border instead of reflect101", variant(_variant, border="zero"),
                "Read outside the images by reflect101 (np.pad(img, r, mode='reflect')), not with zeros"),
        Mistake("ZNCC of a flat window scored −1 (the worst)", variant(_variant, flat_score=-1.0),
                "A flat window (all values equal) has no correlation: score it 0, so it beats anti-correlated windows"),
        Mistake("ZNCC of a flat window scored as the best match", variant(_variant, flat_score=2.0),
                "A flat window (all values equal) scores 0, not better than a real match: ZNCC = 1 wins"),
    ],
    arg_names=_NAMES,
)



# --------------------------------------------------------------------------------------------
# §2.6 the measured exercise: a dense disparity map, graded by its bad-pixel rate
# --------------------------------------------------------------------------------------------
#: the published scale of ``stereo.dense_disparity`` (share of good pixels → share of the points)
DISPARITY_SCALE = Scale(GOOD_PIXEL_SCALE)


def _measured_pair(seed: int, label: str) -> MeasuredCase:
    left, right, truth = synthetic_pair(seed)
    return MeasuredCase((left, right, PAIR_MAX_DISPARITY), {}, label, truth=truth)


def _dense_public() -> list[Case]:
    return [_measured_pair(2026, "a synthetic pair (planes in front of a slanted background, noise, the right "
                                 "camera brighter or darker)")]


def _dense_hidden(rng: np.random.Generator) -> list[Case]:
    return [_measured_pair(_seed(rng), f"your own synthetic pair {k + 1} of 3 (scene, texture, gain and noise "
                                       f"drawn from your seed)") for k in range(3)]


def good_pixels(got, case) -> float:
    """The share of the pixels with a ground truth where ``got`` is within 1 px (0 for a map of
    the wrong shape): 1 − the bad-pixel rate."""
    return 1.0 - bad_pixel_rate(got, case.truth) if np.shape(got) == np.shape(case.truth) else 0.0


class BadPixelRate(Comparator):
    """Passes when the disparity map's share of good pixels (error ≤ 1 px, on the pixels with a
    ground truth: ``case.truth``) reaches the top of :data:`DISPARITY_SCALE`; the case's credit
    follows the scale below it. ``expected`` (the reference's map) only serves for comparison in
    the message."""

    judges_alone = True  # the verdict is what the output achieves on the case's truth

    def describe(self) -> str:
        return f"at least {DISPARITY_SCALE.show(DISPARITY_SCALE.top)} of the pixels within 1 px of the true disparity"

    def __call__(self, got, expected, case=None):
        truth = np.asarray(case.truth)
        array, problem = as_numeric(got, "your disparity map")
        if array is None:
            return Mismatch(problem or "your disparity map is not an array")
        disparity = array.astype(np.float64)
        if disparity.shape != truth.shape:
            return Mismatch(f"shape mismatch: expected {truth.shape} (one disparity per left pixel), got {disparity.shape}")
        good = good_pixels(disparity, case)
        if good >= DISPARITY_SCALE.top:
            return None
        known = np.isfinite(truth)
        words = DISPARITY_SCALE.shortfall(good, "share of good pixels (error ≤ 1 px)",
                                          f" on {int(known.sum())} pixels with a ground truth")
        words += f" The reference reached {100 * good_pixels(expected, case):.2f} % on the same pair."
        if good < DISPARITY_SCALE.bottom:
            words += (" Check the direction of the search (x − d), and that the cost ignores the two cameras' gain "
                      "and offset; windows too small for the noise give scattered errors.")
        return Mismatch(words)


@mistake("disparity searched in the wrong direction (x + d)",
         "The left pixel (x, y) matches the right pixel (x − d, y): scene points appear further left in the right view")
def _dense_flipped(left, right, max_disparity):
    return match_pair(left, right, max_disparity, flip=True)


@mistake("raw grey levels compared (SAD), whatever the cameras' gain",
         "The right camera has another gain and offset: compare windows with ZNCC (or normalise each window) "
         "instead of raw differences")
def _dense_sad(left, right, max_disparity):
    return match_pair(left, right, max_disparity, block=9, cost="sad", consistency=False, median=False, subpixel=False)


@mistake("3×3 windows, plain winner-takes-all",
         "Three by three pixels are too few to outvote the noise: use larger windows (5×5 to 9×9), check the "
         "left-right consistency and smooth the map (a median)")
def _dense_tiny_windows(left, right, max_disparity):
    return match_pair(left, right, max_disparity, block=3, consistency=False, median=False, subpixel=False)


dense_disparity = Check(
    public=_dense_public,
    hidden=_dense_hidden,
    compare=BadPixelRate(),
    mistakes=[_dense_flipped, _dense_sad, _dense_tiny_windows],
    allowed=("stereo.block_matching",),   # the student's own, the building block of their recipe
    arg_names=("left", "right", "max_disparity"),
    output_names=("disparity",),
    time_limit=BUDGET_SECONDS,
    credit=lambda got, case: DISPARITY_SCALE.credit(good_pixels(got, case)),
    measure=Measure("share of good pixels", lambda got, case: 100 * good_pixels(got, case), "%"),
)
