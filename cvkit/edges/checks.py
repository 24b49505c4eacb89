"""Checks of Chapter 4's edge detectors: cases, comparators and mistake banks for the grader.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference
function (``cvkit.edges.checks:sobel`` grades ``edges.sobel``). Two comparators are defined
here because edges need them:

- :class:`Angles` compares directions modulo 2π (``atan2`` may return π where another correct
  formula returns −π);
- :class:`EdgeF1` compares boolean edge maps by their F1 score within a pixel tolerance
  (:func:`edge_f1`), so that a Canny detector that differs from the reference by a rounding
  tie on one pixel still passes, while a systematic mistake does not.

Public cases are tiny fixed arrays that already tell every mistake of the bank from the right
answer. Hidden cases are drawn from the grading seed: non-square, tiny (1×N, 2×3), constant,
uint8 and ±1e6 inputs, every option value, and for every mistake inputs that expose it even
where natural images hide it: an anti-aliased disk (every edge orientation at once) with
tight *relative* thresholds (an L1 magnitude is up to √2 off along the diagonals), integer
magnitudes equal to a threshold (≥ instead of >), plateaus along axis-aligned and diagonal
gradients (strict instead of non-strict maxima), magnitudes that are not ``hypot(ix, iy)``
(NMS that recomputes them), diagonal and long weak chains (4-connected or single-pass
hysteresis), integer responses with exact ties and zeros (zero crossings).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

import numpy as np

from ..data import disk_image, oriented_step_image, square_image
from ..filters import correlate as _correlate
from ..filters import gaussian as _gaussian
from ..grading import Case, Check, Comparator, Mismatch, Mistake, close, mistake
from ..grading.casekit import BORDERS, border_mistakes, border_zero, random_image, reflect_swapped, variant
from ..grading.casekit import distinct as _distinct
from ..grading.casekit import sigma as _sigma
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ..grading.compare import as_numeric, shape_mismatch
from ._canny import _components
from ._canny import hysteresis as _hysteresis
from ._canny import non_max_suppression as _nms
from ._gradient import direction as _direction
from ._gradient import gradient as _gradient
from ._gradient import magnitude as _magnitude
from ._gradient import prewitt as _prewitt
from ._gradient import sobel as _sobel
from ._laplacian import dog as _dog
from ._laplacian import laplacian as _laplacian
from ._laplacian import log as _log

__all__ = [
    "Angles", "EdgeF1", "edge_f1",
    "gradient", "magnitude", "direction", "prewitt", "sobel", "non_max_suppression",
    "hysteresis", "canny", "laplacian", "log_kernel", "log", "zero_crossings", "dog", "BORDERS",
]


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
def _dilate(mask: np.ndarray, radius: int) -> np.ndarray:
    """``mask`` grown by ``radius`` pixels in every direction (a (2r+1)² square)."""
    if radius <= 0:
        return mask.copy()
    h, w = mask.shape
    padded = np.zeros((h + 2 * radius, w + 2 * radius), dtype=bool)
    padded[radius:radius + h, radius:radius + w] = mask
    out = np.zeros_like(mask)
    for dy in range(2 * radius + 1):
        for dx in range(2 * radius + 1):
            out |= padded[dy:dy + h, dx:dx + w]
    return out


def edge_f1(got, expected, radius: int = 1) -> tuple[float, float, float]:
    """``(F1, precision, recall)`` of the edge map ``got`` against ``expected``.

    A pixel of ``got`` is a true positive when an ``expected`` edge pixel lies within
    ``radius`` pixels (Chebyshev distance: the (2r+1)² square around it); an ``expected``
    pixel is recalled when a ``got`` pixel lies within ``radius`` of it. Precision and recall
    are the fractions of such pixels; F1 is their harmonic mean. Two empty maps score 1.

    >>> import numpy as np
    >>> a = np.zeros((5, 5), bool); a[2, 1:4] = True
    >>> b = np.zeros((5, 5), bool); b[3, 1:4] = True
    >>> edge_f1(a, b, radius=0), edge_f1(a, b, radius=1)
    ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    """
    g = np.asarray(got, dtype=bool)
    e = np.asarray(expected, dtype=bool)
    if g.shape != e.shape or g.ndim != 2:
        raise ValueError(f"got and expected must be 2-D maps of the same shape, got {g.shape} and {e.shape}")
    n_got, n_exp = int(g.sum()), int(e.sum())
    if n_got == 0 and n_exp == 0:
        return 1.0, 1.0, 1.0
    if n_got == 0 or n_exp == 0:
        return 0.0, 0.0 if n_got else 1.0, 0.0 if n_exp else 1.0
    precision = float((g & _dilate(e, radius)).sum()) / n_got
    recall = float((e & _dilate(g, radius)).sum()) / n_exp
    if precision + recall == 0:
        return 0.0, precision, recall
    return 2 * precision * recall / (precision + recall), precision, recall


@dataclass
class EdgeF1(Comparator):
    """Boolean edge maps agree when their F1 score within ``radius`` pixels is ≥ ``min_f1``.

    The output must be a bool array of the expected shape. The report gives the F1 score,
    precision and recall and the first spurious and first missing edge pixel.
    """

    radius: int = 0
    min_f1: float = 0.98

    def describe(self) -> str:
        return f"edge maps with F1 >= {self.min_f1:g} within {self.radius} px"

    def __call__(self, got, expected, case=None):
        exp = np.asarray(expected)
        arr, problem = as_numeric(got)
        if problem:
            return Mismatch(problem)
        if arr.dtype.kind != "b":
            return Mismatch(f"dtype mismatch: expected a bool edge map, got {arr.dtype} "
                            "(return a comparison such as `strength > threshold`, or use .astype(bool))")
        if arr.shape != exp.shape:
            return Mismatch(shape_mismatch(arr.shape, exp.shape))
        f1, precision, recall = edge_f1(arr, exp, self.radius)
        if f1 >= self.min_f1:
            return None
        tolerance = "exactly" if self.radius == 0 else f"within {self.radius} px"
        spurious = arr & ~_dilate(exp.astype(bool), self.radius)
        missing = exp.astype(bool) & ~_dilate(arr, self.radius)
        lines = [
            f"Edge maps differ: F1 = {f1:.3f} (precision {precision:.3f}, recall {recall:.3f}) matching "
            f"pixels {tolerance}; at least {self.min_f1:g} is needed",
            f"Your edge pixels: {int(arr.sum())}, expected: {int(exp.sum())}; "
            f"spurious: {int(spurious.sum())}, missing: {int(missing.sum())}",
        ]
        worst = None
        if spurious.any():
            worst = tuple(int(i) for i in np.argwhere(spurious)[0])
            lines.append(f"First spurious edge pixel at {list(worst)}")
        if missing.any():
            first = tuple(int(i) for i in np.argwhere(missing)[0])
            worst = worst or first
            lines.append(f"First missing edge pixel at {list(first)}")
        return Mismatch("\n".join(lines), worst=worst, mismatched=int(spurious.sum() + missing.sum()), total=int(exp.size))


@dataclass
class Angles(Comparator):
    """Angles in radians agree when they differ by at most ``atol`` modulo 2π.

    The output must be a float array of the expected shape; NaN where a finite angle is
    expected is a mismatch.
    """

    atol: float = 1e-9

    def describe(self) -> str:
        return f"angles equal modulo 2π within {self.atol:g} rad"

    def __call__(self, got, expected, case=None):
        exp = np.asarray(expected, dtype=np.float64)
        arr, problem = as_numeric(got)
        if problem:
            return Mismatch(problem)
        if arr.dtype.kind != "f":
            return Mismatch(f"dtype mismatch: expected a float array, got {arr.dtype}")
        if arr.shape != exp.shape:
            return Mismatch(shape_mismatch(arr.shape, exp.shape))
        a = arr.astype(np.float64)
        with np.errstate(all="ignore"):
            wrapped = np.mod(a - exp + np.pi, 2 * np.pi) - np.pi
            err = np.abs(wrapped)
            bad = ~(err <= self.atol)
        n = int(bad.sum())
        if n == 0:
            return None
        score = np.where(np.isnan(err), np.inf, err)
        flat = int(np.argmax(score))
        worst = tuple(int(i) for i in np.unravel_index(flat, exp.shape)) if exp.ndim else ()
        largest = float(score.flat[flat])
        lines = [
            f"Not equal modulo 2π to tolerance atol={self.atol:g} rad",
            f"Mismatched elements: {n} / {exp.size} ({100 * n / exp.size:.3g}%)",
        ]
        if np.isfinite(largest):
            lines.append(f"Max angular difference: {largest:.6g} rad ({math.degrees(largest):.4g}°) at {list(worst)} "
                         f"(yours {a.flat[flat]:.6g}, expected {exp.flat[flat]:.6g})")
        else:
            lines.append(f"NaN or inf where an angle is expected, first at {list(worst)} (expected {exp.flat[flat]:.6g})")
        return Mismatch("\n".join(lines), max_abs=largest, worst=worst, mismatched=n, total=int(exp.size))


#: linear filters: sums of products agree to ~1e-12 of the image's scale
_LINEAR = close(rtol=1e-7, atol=1e-10, kind="f", scaled=True)
#: pointwise formulas
_POINTWISE = close(rtol=1e-9, atol=1e-12, kind="f", scaled=True)
#: boolean maps computed by exact rules
_EXACT_BOOL = close(rtol=0.0, atol=0.0, kind="b")
#: the hint of every filter's "border ignored (always zero)" mistake (casekit.border_zero)
_BORDER_HINT = "Read outside the image through `border` (zero, replicate, reflect, reflect101), not with zeros"


# --------------------------------------------------------------------------------------------
# case helpers
# --------------------------------------------------------------------------------------------
def _disk(rng: np.random.Generator, h: int, w: int, *, noise: float = 0.0, contrast=(0.5, 0.9)) -> np.ndarray:
    """An anti-aliased disk with an off-grid centre (no exact symmetry), optionally noisy."""
    radius = float(rng.uniform(0.28, 0.36) * min(h, w))
    cx = (w - 1) / 2 + float(rng.uniform(-0.4, 0.4))
    cy = (h - 1) / 2 + float(rng.uniform(-0.4, 0.4))
    inside = float(rng.uniform(*contrast))
    outside = float(rng.uniform(0.0, 0.15))
    if rng.random() < 0.5:
        inside, outside = outside, inside
    img = disk_image((h, w), centre=(cx, cy), radius=radius, inside=inside, outside=outside)
    if noise:
        img = img + rng.normal(0.0, noise, img.shape)
    return img


def _square(rng: np.random.Generator, h: int, w: int, *, noise: float = 0.05) -> np.ndarray:
    angle = float(rng.uniform(0.15, 0.6))
    side = float(rng.uniform(0.45, 0.6) * min(h, w))
    img = square_image((h, w), centre=((w - 1) / 2 + 0.3, (h - 1) / 2 - 0.2), side=side, angle=angle,
                       inside=float(rng.uniform(0.6, 0.9)), outside=float(rng.uniform(0.05, 0.25)))
    return img + rng.normal(0.0, noise, img.shape)


def _random_border(rng: np.random.Generator, choices=BORDERS) -> str:
    return str(rng.choice(choices))


# --------------------------------------------------------------------------------------------
# edges.gradient (§4.5)
# --------------------------------------------------------------------------------------------
@mistake("central difference not divided by 2",
         "The central difference is (I(x+1) − I(x−1)) / 2: correlate with [-1, 0, 1] / 2")
def _grad_not_halved(image, scheme="central", border="reflect101"):
    ix, iy = _gradient(image, scheme, border)
    return (2 * ix, 2 * iy) if scheme == "central" else (ix, iy)


@mistake("x and y swapped",
         "Return (ix, iy): ix differentiates along the columns (axis 1, x), iy down the rows (axis 0, y)")
def _grad_swapped(image, scheme="central", border="reflect101"):
    ix, iy = _gradient(image, scheme, border)
    return iy, ix


@mistake("sign flipped (kernel convolved, not correlated)",
         "A derivative is positive where the image gets brighter: Ix = I(x+1) − I(x−1), not I(x−1) − I(x+1)")
def _grad_sign(image, scheme="central", border="reflect101"):
    ix, iy = _gradient(image, scheme, border)
    return -ix, -iy


@mistake("forward and backward swapped",
         "forward: I(x+1) − I(x); backward: I(x) − I(x−1) (the same along y, rows going down)")
def _grad_fwd_bwd(image, scheme="central", border="reflect101"):
    other = {"forward": "backward", "backward": "forward"}.get(scheme, scheme)
    return _gradient(image, other, border)


@mistake("one-sided differences at the border (numpy.gradient)",
         "Use the same formula at every pixel and read the missing neighbour through `border` "
         "(pad the image); numpy.gradient switches to one-sided differences at the border")
def _grad_numpy(image, scheme="central", border="reflect101"):
    if scheme != "central":
        return _gradient(image, scheme, border)
    iy, ix = np.gradient(np.asarray(image, dtype=np.float64))
    return ix, iy


def _images(rng):
    """``img(h, w, kind="unit")``: a random (h, w) image of that kind drawn from ``rng``
    (:func:`~cvkit.grading.casekit.random_image`)."""
    def img(h, w, kind="unit"):
        return random_image(rng, (h, w), kind)
    return img


def _gradient_hidden(rng):
    img = _images(rng)

    return [
        Case((img(_size(rng, 6, 10), _size(rng, 8, 14)),), {"scheme": "central", "border": "zero"},
             "central, zero border"),
        Case((img(_size(rng, 7, 12), _size(rng, 6, 10)),), {"scheme": "central", "border": "replicate"},
             "central, replicate"),
        Case((img(_size(rng, 6, 11), _size(rng, 7, 12)),), {"scheme": "central", "border": "reflect"},
             "central, reflect"),
        Case((img(_size(rng, 8, 12), _size(rng, 6, 9)),), {}, "default scheme and border (central, reflect101)"),
        Case((img(_size(rng, 6, 10), _size(rng, 8, 13)),), {"scheme": "forward", "border": "reflect101"},
             "forward, reflect101"),
        Case((img(_size(rng, 6, 10), _size(rng, 6, 10)),), {"scheme": "backward", "border": "replicate"},
             "backward, replicate"),
        Case((img(_size(rng, 7, 11), _size(rng, 8, 12), "uint8"),), {"scheme": "forward", "border": "zero"},
             "uint8 image, forward, zero border (not rescaled)"),
        Case((img(_size(rng, 10, 20), _size(rng, 10, 20), "big"),), {"scheme": "backward", "border": "reflect"},
             "±1e6 values, backward, reflect"),
        Case((img(_size(rng, 5, 8), _size(rng, 5, 8), "const"),), {"scheme": "central", "border": "zero"},
             "constant image, zero border"),
        Case((img(1, _size(rng, 7, 12)),), {"scheme": "central", "border": _random_border(rng, BORDERS[1:])},
             "single row 1×N"),
        Case((img(_size(rng, 6, 10), 1),), {"scheme": "forward", "border": "reflect"}, "single column N×1, forward"),
        Case((img(2, 3, "normal"),), {"scheme": str(rng.choice(["central", "backward"])), "border": "reflect101"},
             "tiny 2×3 image"),
    ]


gradient = Check(
    rules=("integer",),
    public=[
        Case((_distinct((5, 6)),), {}, "5×6 image, central differences, reflect101 (defaults)"),
        Case((_distinct((6, 5)),), {"scheme": "forward", "border": "replicate"}, "forward differences, replicate"),
        Case((_distinct((5, 7)),), {"scheme": "backward", "border": "zero"}, "backward differences, zero border"),
        Case((_distinct((6, 6), seed=3),), {"border": "reflect"}, "central differences, reflect"),
    ],
    hidden=_gradient_hidden,
    compare=_LINEAR,
    mistakes=[
        _grad_not_halved,
        _grad_swapped,
        _grad_sign,
        _grad_fwd_bwd,
        _grad_numpy,
        *border_mistakes(_gradient, _BORDER_HINT),
    ],
    allowed=("filters.pad",),
)


# --------------------------------------------------------------------------------------------
# edges.magnitude (§4.5)
# --------------------------------------------------------------------------------------------
@mistake("norm ignored (always L2)",
         "Use the `norm` argument: l2 = sqrt(Ix² + Iy²), l1 = |Ix| + |Iy|, max = max(|Ix|, |Iy|)")
def _mag_always_l2(ix, iy, norm="l2"):
    return _magnitude(ix, iy, "l2")


@mistake("L2 without the square root", "l2 is sqrt(Ix² + Iy²), not Ix² + Iy²")
def _mag_squared(ix, iy, norm="l2"):
    if norm != "l2":
        return _magnitude(ix, iy, norm)
    gx, gy = np.asarray(ix, dtype=np.float64), np.asarray(iy, dtype=np.float64)
    return gx * gx + gy * gy


@mistake("L1 without absolute values", "l1 adds absolute values: |Ix| + |Iy|")
def _mag_l1_no_abs(ix, iy, norm="l2"):
    if norm != "l1":
        return _magnitude(ix, iy, norm)
    return np.asarray(ix, dtype=np.float64) + np.asarray(iy, dtype=np.float64)


@mistake("max without absolute values", "max compares absolute values: max(|Ix|, |Iy|)")
def _mag_max_no_abs(ix, iy, norm="l2"):
    if norm != "max":
        return _magnitude(ix, iy, norm)
    return np.maximum(np.asarray(ix, dtype=np.float64), np.asarray(iy, dtype=np.float64))


@mistake("l1 and max swapped", "l1 = |Ix| + |Iy| (the sum), max = max(|Ix|, |Iy|)")
def _mag_l1_max_swapped(ix, iy, norm="l2"):
    return _magnitude(ix, iy, {"l1": "max", "max": "l1"}.get(norm, norm))


def _pair_of(rng, shape, kind="normal"):
    if kind == "int":
        return (rng.integers(-40, 41, shape).astype(np.float64), rng.integers(-40, 41, shape).astype(np.float64))
    if kind == "int64":
        return rng.integers(-1020, 1021, shape), rng.integers(-1020, 1021, shape)
    if kind == "big":
        return rng.uniform(-1e6, 1e6, shape), rng.uniform(-1e6, 1e6, shape)
    return rng.normal(0.0, 2.0, shape), rng.normal(0.0, 2.0, shape)


def _magnitude_hidden(rng):
    cases = []
    for norm in ("l2", "l1", "max"):
        shape = (_size(rng, 4, 9), _size(rng, 5, 11))
        cases.append(Case(_pair_of(rng, shape), {"norm": norm}, f"random derivatives, norm={norm!r}"))
        shape = (_size(rng, 3, 7), _size(rng, 6, 10))
        cases.append(Case(_pair_of(rng, shape, "int64"), {"norm": norm},
                          f"integer (int64) derivatives, norm={norm!r} (result in float)"))
    ix, iy = _pair_of(rng, (_size(rng, 5, 8), _size(rng, 5, 8)), "big")
    cases.append(Case((ix, iy), {"norm": str(rng.choice(["l2", "l1", "max"]))}, "±1e6 derivatives"))
    ix, iy = _pair_of(rng, (_size(rng, 4, 7), _size(rng, 4, 7)), "int")
    ix[::2] = 0.0
    iy[:, ::3] = 0.0
    cases.append(Case((ix, iy), {}, "zeros among the derivatives, default norm (l2)"))
    ix, iy = _pair_of(rng, (1, _size(rng, 6, 12)))
    cases.append(Case((ix, iy), {"norm": "l1"}, "single row 1×N, l1"))
    ix, iy = _pair_of(rng, (_size(rng, 3, 5), _size(rng, 3, 5), 3))
    cases.append(Case((ix, iy), {"norm": "max"}, "3-D arrays (H, W, 3), max"))
    # squares of ±1020 overflow int16 (largest 32767): compute in float64
    ix, iy = (a.astype(np.int16) for a in _pair_of(rng, (_size(rng, 3, 6), _size(rng, 4, 8)), "int64"))
    cases.append(Case((ix, iy), {}, "int16 derivatives up to ±1020, l2 (their squares overflow int16)"))
    return cases


magnitude = Check(
    public=[
        Case((np.array([[3.0, -1.0, 0.0, 2.5], [-4.0, 6.0, -0.5, 1.0], [1.0, 0.0, -2.0, -3.0]]),
              np.array([[-4.0, 2.0, 1.5, -0.5], [3.0, -2.0, 0.0, 4.0], [-1.0, -5.0, 2.0, -3.0]])), {},
             "3×4 derivatives, default norm (l2)"),
        Case((np.array([[3.0, -1.0, 0.0, 2.5], [-4.0, 6.0, -0.5, 1.0]]),
              np.array([[-4.0, 2.0, 1.5, -0.5], [3.0, -2.0, 0.0, 4.0]])), {"norm": "l1"}, "norm='l1'"),
        Case((np.array([[3.0, -1.0, 0.0, 2.5], [-4.0, 6.0, -0.5, 1.0]]),
              np.array([[-4.0, 2.0, 1.5, -0.5], [3.0, -7.0, 0.0, 4.0]])), {"norm": "max"}, "norm='max'"),
    ],
    hidden=_magnitude_hidden,
    compare=_POINTWISE,
    mistakes=[_mag_always_l2, _mag_squared, _mag_l1_no_abs, _mag_max_no_abs, _mag_l1_max_swapped],
    rules=("integer", "narrow integer"),
)


# --------------------------------------------------------------------------------------------
# edges.direction (§4.3)
# --------------------------------------------------------------------------------------------
@mistake("atan instead of atan2",
         "arctan(Iy / Ix) cannot tell a gradient from its opposite (and divides by zero): use np.arctan2(iy, ix)")
def _dir_atan(ix, iy):
    return np.arctan(np.asarray(iy, dtype=np.float64) / np.asarray(ix, dtype=np.float64))


@mistake("x and y swapped (atan2(Ix, Iy))", "The angle from the x axis is atan2(Iy, Ix): the y component comes first")
def _dir_swapped(ix, iy):
    return np.arctan2(np.asarray(ix, dtype=np.float64), np.asarray(iy, dtype=np.float64))


@mistake("y pointing up (Iy negated)",
         "Images have y pointing down the rows: use atan2(Iy, Ix) as computed, without negating Iy")
def _dir_y_up(ix, iy):
    return np.arctan2(-np.asarray(iy, dtype=np.float64), np.asarray(ix, dtype=np.float64))


@mistake("degrees instead of radians", "Return radians, as np.arctan2 does (no np.degrees)")
def _dir_degrees(ix, iy):
    return np.degrees(_direction(ix, iy))


def _direction_hidden(rng):
    cases = []
    for label in ("random derivatives (all four quadrants)", "random derivatives, other size"):
        cases.append(Case(_pair_of(rng, (_size(rng, 4, 9), _size(rng, 5, 11))), {}, label))
    cases.append(Case(_pair_of(rng, (_size(rng, 3, 7), _size(rng, 6, 10)), "int64"), {},
                      "integer (int64) derivatives (result in float)"))
    cases.append(Case(_pair_of(rng, (_size(rng, 4, 7), _size(rng, 4, 7)), "big"), {}, "±1e6 derivatives"))
    n = _size(rng, 6, 10)
    values = rng.integers(1, 9, n).astype(np.float64) * rng.choice([-1.0, 1.0], n)
    ix = np.where(np.arange(n) % 2 == 0, values, 0.0)[None, :].repeat(2, axis=0)
    iy = np.where(np.arange(n) % 2 == 1, values, 0.0)[None, :].repeat(2, axis=0)
    cases.append(Case((ix, iy), {}, "axis-aligned gradients (Ix = 0 or Iy = 0, both signs)"))
    ix = -rng.integers(1, 9, (3, _size(rng, 4, 8))).astype(np.float64)
    cases.append(Case((ix, np.zeros_like(ix)), {}, "gradients pointing left (Iy = 0, Ix < 0: ±π)"))
    ix, iy = _pair_of(rng, (_size(rng, 4, 6), _size(rng, 4, 6)), "int")
    ix[0, 0] = iy[0, 0] = 0.0
    cases.append(Case((ix, iy), {}, "a zero gradient among others (atan2(0, 0) = 0)"))
    cases.append(Case(_pair_of(rng, (1, _size(rng, 6, 12))), {}, "single row 1×N"))
    cases.append(Case(_pair_of(rng, (_size(rng, 3, 5), _size(rng, 3, 5), 3)), {}, "3-D arrays (H, W, 3)"))
    return cases


direction = Check(
    rules=("integer",),
    public=[
        Case((np.array([[1.0, 0.0, -1.0, 0.0], [2.0, -3.0, -1.0, 4.0], [0.5, -2.0, 3.0, -1.0]]),
              np.array([[0.0, 1.0, 0.5, -2.0], [2.0, 1.0, -1.0, -3.0], [-0.5, -0.5, 1.0, 2.0]])), {},
             "3×4 derivatives in all four quadrants and on the axes"),
        Case((np.array([[-2.0, -1.0, -4.0], [3.0, -0.5, 2.0]]), np.array([[1.0, -3.0, 0.0], [-1.0, 2.0, 2.0]])), {},
             "negative Ix (the left half-plane)"),
    ],
    hidden=_direction_hidden,
    compare=Angles(atol=1e-9),
    mistakes=[_dir_atan, _dir_swapped, _dir_y_up, _dir_degrees],
)


# --------------------------------------------------------------------------------------------
# edges.prewitt and edges.sobel (§4.7)
# --------------------------------------------------------------------------------------------
def _derivative_mistakes(reference, other, other_name: str, scale: int, what: str):
    def signs(image, border="reflect101"):
        gx, gy = reference(image, border)
        return -gx, -gy

    def swapped(image, border="reflect101"):
        gx, gy = reference(image, border)
        return gy, gx

    def y_up(image, border="reflect101"):
        gx, gy = reference(image, border)
        return gx, -gy

    def other_weights(image, border="reflect101"):
        return other(image, border)

    def normalised(image, border="reflect101"):
        gx, gy = reference(image, border)
        return gx / scale, gy / scale

    centre = "1" if other_name == "Prewitt" else "2"
    return [
        Mistake("signs flipped (kernels convolved, not correlated)", signs,
                "Correlate, do not convolve: gx = I ⋆ K with K's −1 column on the left, so gx > 0 where "
                "the image gets brighter to the right"),
        Mistake("gx and gy swapped", swapped,
                "gx differentiates along x (the columns, kernel [-1, 0, 1] in each row); gy is its transpose"),
        Mistake("y pointing up (gy negated)", y_up,
                "y points down the rows: gy's kernel has −1s in the top row and +1s in the bottom row"),
        Mistake(f"centre weight {centre} (that is {other_name})", other_weights,
                f"{what}: the smoothing across the derivative is "
                + ("[1, 2, 1]" if other_name == "Prewitt" else "[1, 1, 1]")),
        Mistake(f"normalised by 1/{scale}", normalised,
                f"Do not normalise: the kernels have integer weights (a unit step gives {scale // 2})"),
        *border_mistakes(reference, _BORDER_HINT),
    ]


def _derivative_hidden(rng):
    img = _images(rng)

    step = oriented_step_image((_size(rng, 8, 12), _size(rng, 9, 14)), angle=float(rng.uniform(-np.pi, np.pi)),
                               offset=float(rng.uniform(-1, 1)), low=0.2, high=0.9)
    return [
        Case((img(_size(rng, 6, 10), _size(rng, 8, 14)),), {"border": "zero"}, "zero border"),
        Case((img(_size(rng, 7, 12), _size(rng, 6, 10)),), {"border": "replicate"}, "replicate"),
        Case((img(_size(rng, 6, 11), _size(rng, 7, 12)),), {"border": "reflect"}, "reflect"),
        Case((img(_size(rng, 8, 12), _size(rng, 6, 9)),), {}, "default border (reflect101)"),
        Case((img(_size(rng, 7, 11), _size(rng, 8, 12), "uint8"),), {"border": "reflect101"},
             "uint8 image (not rescaled)"),
        Case((img(_size(rng, 10, 20), _size(rng, 10, 20), "big"),), {"border": "reflect"}, "±1e6 values"),
        Case((img(_size(rng, 5, 8), _size(rng, 5, 8), "const"),), {"border": "zero"}, "constant image, zero border"),
        Case((step,), {"border": _random_border(rng, BORDERS[1:])}, "an anti-aliased step edge at a random angle"),
        Case((img(1, _size(rng, 7, 12)),), {"border": _random_border(rng, BORDERS[1:])}, "single row 1×N"),
        Case((img(_size(rng, 6, 10), 1),), {"border": "reflect"}, "single column N×1"),
        Case((img(2, 3, "normal"),), {"border": _random_border(rng, BORDERS[1:])}, "tiny 2×3 image"),
    ]


_DERIVATIVE_PUBLIC = [
    Case((_distinct((5, 6)),), {}, "5×6 image, default border (reflect101)"),
    Case((_distinct((6, 5), seed=3),), {"border": "replicate"}, "6×5 image, replicate"),
    Case((_distinct((5, 7), seed=5),), {"border": "zero"}, "zero border"),
    Case((_distinct((6, 6), seed=9),), {"border": "reflect"}, "reflect"),
]


def _derivative_check(reference, other, other_name: str, scale: int, what: str) -> Check:
    """The check of a smoothed-difference filter (Prewitt, Sobel): the same cases for both,
    the bank of :func:`_derivative_mistakes`."""
    return Check(
        public=_DERIVATIVE_PUBLIC,
        hidden=_derivative_hidden,
        compare=_LINEAR,
        mistakes=_derivative_mistakes(reference, other, other_name, scale, what),
        allowed=("filters.pad",),
    )


prewitt = _derivative_check(_prewitt, _sobel, "Sobel", 6, "Prewitt averages the three rows (columns) equally")
sobel = _derivative_check(_sobel, _prewitt, "Prewitt", 8, "Sobel weighs the centre row (column) twice")


# --------------------------------------------------------------------------------------------
# edges.laplacian (§4.12)
# --------------------------------------------------------------------------------------------
_EIGHT = np.array([[1.0, 1.0, 1.0], [1.0, -8.0, 1.0], [1.0, 1.0, 1.0]])


@mistake("8-neighbour Laplacian",
         "The 4-neighbour Laplacian uses only the up, down, left and right neighbours: [[0,1,0],[1,-4,1],[0,1,0]]")
def _lap_eight(image, border="reflect101"):
    return _correlate(image, _EIGHT, border)


@mistake("sign flipped", "Ixx + Iyy = (sum of the 4 neighbours) − 4·I(p), not 4·I(p) − (...)")
def _lap_sign(image, border="reflect101"):
    return -_laplacian(image, border)


@mistake("only Ixx (no Iyy)", "The Laplacian adds both second derivatives: Ixx + Iyy, i.e. all four neighbours")
def _lap_x_only(image, border="reflect101"):
    return _correlate(image, np.array([[1.0, -2.0, 1.0]]), border)


laplacian = Check(
    public=[
        Case((_distinct((5, 6)),), {}, "5×6 image, default border (reflect101)"),
        Case((_distinct((6, 5), seed=3),), {"border": "reflect"}, "reflect"),
        Case((_distinct((5, 7), seed=5),), {"border": "zero"}, "zero border"),
    ],
    hidden=_derivative_hidden,
    compare=_LINEAR,
    mistakes=[
        _lap_eight,
        _lap_sign,
        _lap_x_only,
        *border_mistakes(_laplacian, _BORDER_HINT),
    ],
    allowed=("filters.pad",),
)


# --------------------------------------------------------------------------------------------
# edges.log_kernel, edges.log (§4.12)
# --------------------------------------------------------------------------------------------
def _default_radius(sigma):
    return max(0, math.ceil(3.0 * sigma))


def _lk(sigma, radius=None, *, centred=True, scale=False, sign=1.0, variance=False, rule=None):
    """The LoG kernel with knobs for the mistakes."""
    if radius is None:
        radius = {None: _default_radius, "floor": lambda s: int(math.floor(3 * s))}[rule](sigma)
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    r2 = x[:, None] ** 2 + x[None, :] ** 2
    s2 = sigma if variance else sigma * sigma
    k = (r2 - 2 * s2) / (2 * math.pi * s2 ** 3) * np.exp(-r2 / (2 * s2))
    if centred:
        k = k - k.mean()
    if scale:
        k = k * s2
    return sign * k


_lkv = partial(variant, _lk)


log_kernel = Check(
    public=[
        Case((1.4,), {}, "σ = 1.4 (3σ = 4.2: radius 5)"),
        Case((0.8,), {}, "σ = 0.8 (3σ = 2.4: radius 3)"),
        Case((2.0,), {"radius": 3}, "σ = 2 with radius 3"),
    ],
    hidden=lambda rng: [
        Case((_sigma(rng, 0.4, 0.9),), {}, "default radius, σ < 1"),
        Case((_sigma(rng, 1.1, 1.9),), {}, "default radius, 1 < σ < 2"),
        Case((_sigma(rng, 2.0, 3.0),), {}, "default radius, σ > 2"),
        Case((_sigma(rng, 1.1, 2.5, frac=(0.1, 0.45)),), {}, "default radius, 3σ just above an integer"),
        Case((_sigma(rng, 0.6, 2.5), None), {}, "radius=None given explicitly"),
        Case((_sigma(rng, 1.2, 2.5), _size(rng, 1, 3)), {}, "explicit radius smaller than 3σ"),
        Case((_sigma(rng, 0.5, 1.5), _size(rng, 6, 8)), {}, "explicit radius larger than 3σ"),
        Case((_sigma(rng, 0.5, 2.0),), {"radius": 0}, "radius 0 (the kernel [[0.0]])"),
        Case((0.5,), {}, "σ = 0.5 (radius 2)"),
        Case((_sigma(rng, 3.0, 4.0),), {}, "large σ (small values: relative precision counts)"),
    ],
    compare=close(rtol=1e-7, atol=1e-13, kind="f", scaled=True),
    mistakes=[
        Mistake("mean not subtracted (the kernel does not sum to 0)", _lkv(centred=False),
                "Subtract the mean of the sampled kernel so that it sums to 0 (a flat region must give 0)"),
        Mistake("scale-normalised (multiplied by σ²)", _lkv(scale=True),
                "Return ∇²G itself, (x²+y²−2σ²)/(2πσ⁶)·exp(−(x²+y²)/(2σ²)), without a σ² factor"),
        Mistake("sign flipped", _lkv(sign=-1.0), "The LoG is negative at the centre: (x² + y² − 2σ²) is −2σ² there"),
        Mistake("σ used as variance", _lkv(variance=True), "σ is the standard deviation: the formula uses σ² and σ⁶"),
        Mistake("radius floor(3σ) instead of ceil", _lkv(rule="floor"),
                "The default radius rounds 3σ up: r = ceil(3σ), a (2r+1)×(2r+1) kernel"),
        Mistake("radius argument ignored", lambda sigma, radius=None: _lk(sigma, None),
                "Use the given radius; only radius=None means ceil(3σ)"),
    ],
)


def _log_with(image, sigma, border, kernel):
    return _correlate(image, kernel, border)


@mistake("kernel not zero-mean", "Subtract the mean of the sampled LoG kernel (it must sum to 0), then correlate")
def _log_uncentred(image, sigma, border="reflect101"):
    return _log_with(image, sigma, border, _lk(sigma, centred=False))


@mistake("sign flipped", "Correlate with ∇²G = (x²+y²−2σ²)/(2πσ⁶)·exp(−(x²+y²)/2σ²), negative at the centre")
def _log_sign(image, sigma, border="reflect101"):
    return -_log(image, sigma, border)


@mistake("Gaussian then 4-neighbour Laplacian (not the LoG kernel)",
         "Correlate once with the sampled LoG kernel log_kernel(σ), not smoothing then a 3×3 Laplacian")
def _log_two_steps(image, sigma, border="reflect101"):
    return _laplacian(_gaussian(image, sigma, border), border)


@mistake("scale-normalised (multiplied by σ²)", "Return the LoG response itself, without a σ² factor")
def _log_scaled(image, sigma, border="reflect101"):
    return sigma * sigma * _log(image, sigma, border)


def _log_hidden(rng):
    img = _images(rng)

    return [
        Case((img(_size(rng, 8, 12), _size(rng, 9, 14)), _sigma(rng, 0.6, 1.4)), {"border": "zero"}, "zero border"),
        Case((img(_size(rng, 9, 13), _size(rng, 8, 12)), _sigma(rng, 0.6, 1.4)), {"border": "replicate"}, "replicate"),
        Case((img(_size(rng, 9, 14), _size(rng, 9, 14)), _sigma(rng, 1.1, 1.9)), {"border": "reflect"}, "reflect"),
        Case((img(_size(rng, 10, 14), _size(rng, 9, 13)), _sigma(rng, 0.6, 1.4)), {}, "default border (reflect101)"),
        Case((img(_size(rng, 9, 13), _size(rng, 9, 13), "uint8"), _sigma(rng, 0.6, 1.3)), {"border": "reflect101"},
             "uint8 image (not rescaled)"),
        Case((img(_size(rng, 12, 18), _size(rng, 12, 18), "big"), _sigma(rng, 1.1, 2.0)), {"border": "reflect"},
             "±1e6 values, larger σ"),
        Case((img(_size(rng, 6, 9), _size(rng, 6, 9), "const"), _sigma(rng, 0.6, 1.2)), {"border": "zero"},
             "constant image, zero border"),
        Case((_disk(rng, _size(rng, 14, 18), _size(rng, 14, 18)), _sigma(rng, 0.8, 1.6)),
             {"border": _random_border(rng, BORDERS[1:])}, "an anti-aliased disk"),
        Case((img(1, _size(rng, 8, 14)), _sigma(rng, 0.5, 1.2)), {"border": _random_border(rng, BORDERS[1:])},
             "single row 1×N"),
        Case((img(2, 3, "normal"), _sigma(rng, 0.4, 0.65)), {"border": _random_border(rng, BORDERS[1:])},
             "tiny 2×3 image"),
    ]


log = Check(
    public=[
        Case((_distinct((8, 9), scale=1 / 71), 0.8), {}, "8×9 image, σ = 0.8, default border (reflect101)"),
        Case((_distinct((9, 8), seed=3, scale=1 / 71), 1.2), {"border": "reflect"}, "σ = 1.2, reflect"),
        Case((_distinct((7, 9), seed=5, dtype=np.uint8), 0.7), {"border": "zero"}, "uint8 image, σ = 0.7, zero border"),
    ],
    hidden=_log_hidden,
    compare=_LINEAR,
    mistakes=[
        _log_uncentred,
        _log_sign,
        _log_two_steps,
        border_zero(_log, _BORDER_HINT),
        _log_scaled,
        reflect_swapped(_log),
    ],
    allowed=("filters.pad", "filters.correlate", "filters.convolve", "edges.log_kernel"),
)


# --------------------------------------------------------------------------------------------
# edges.dog (§4.12)
# --------------------------------------------------------------------------------------------
@mistake("order swapped (G_σ − G_kσ)", "DoG = G_{kσ} ∗ I − G_σ ∗ I: the wider Gaussian first (same sign as the LoG)")
def _dog_swapped(image, sigma, k=1.6, border="reflect101"):
    return -_dog(image, sigma, k, border)


@mistake("second σ is σ + k instead of k·σ", "The wider Gaussian has standard deviation k·σ")
def _dog_plus_k(image, sigma, k=1.6, border="reflect101"):
    return _gaussian(image, sigma + k, border) - _gaussian(image, sigma, border)


@mistake("k ignored (always 1.6)", "Use the `k` argument: the second σ is k·σ")
def _dog_k_ignored(image, sigma, k=1.6, border="reflect101"):
    return _dog(image, sigma, 1.6, border)


@mistake("k squared (k²·σ)", "The wider Gaussian has standard deviation k·σ, not k²·σ")
def _dog_k_squared(image, sigma, k=1.6, border="reflect101"):
    return _dog(image, sigma, k * k, border)


def _k(rng, lo=1.2, hi=2.0):
    for _ in range(1000):
        k = _u(rng, lo, hi, 2)
        if abs(k - 1.6) > 0.05:
            return k
    raise RuntimeError("no suitable k")  # pragma: no cover


def _dog_hidden(rng):
    img = _images(rng)

    return [
        Case((img(_size(rng, 8, 12), _size(rng, 9, 14)), _sigma(rng, 0.6, 1.2), _k(rng)), {"border": "zero"},
             "zero border"),
        Case((img(_size(rng, 9, 13), _size(rng, 8, 12)), _sigma(rng, 0.6, 1.2)), {"border": "replicate"},
             "default k = 1.6, replicate"),
        Case((img(_size(rng, 9, 14), _size(rng, 9, 14)), _sigma(rng, 0.6, 1.2), _k(rng)), {"border": "reflect"},
             "reflect"),
        Case((img(_size(rng, 10, 14), _size(rng, 9, 13)), _sigma(rng, 0.6, 1.2)), {"k": _k(rng, 1.1, 1.5)},
             "k given by keyword, default border (reflect101)"),
        Case((img(_size(rng, 9, 13), _size(rng, 9, 13), "uint8"), _sigma(rng, 0.6, 1.2), _k(rng)),
             {"border": "reflect101"}, "uint8 image (not rescaled)"),
        Case((img(_size(rng, 12, 18), _size(rng, 12, 18), "big"), _sigma(rng, 1.1, 1.6), _k(rng)),
             {"border": "reflect"}, "±1e6 values"),
        Case((img(_size(rng, 6, 9), _size(rng, 6, 9), "const"), _sigma(rng, 0.6, 1.2), _k(rng)), {"border": "zero"},
             "constant image, zero border"),
        Case((_disk(rng, _size(rng, 14, 18), _size(rng, 14, 18)), _sigma(rng, 0.8, 1.4), _k(rng, 1.3, 2.0)),
             {"border": _random_border(rng, BORDERS[1:])}, "an anti-aliased disk"),
        Case((img(1, _size(rng, 8, 14)), _sigma(rng, 0.5, 1.2), _k(rng)), {"border": _random_border(rng, BORDERS[1:])},
             "single row 1×N"),
        Case((img(2, 3, "normal"), _sigma(rng, 0.4, 0.65), _k(rng)), {"border": _random_border(rng, BORDERS[1:])},
             "tiny 2×3 image"),
    ]


dog = Check(
    public=[
        Case((_distinct((8, 9), scale=1 / 71), 0.9, 1.5), {}, "8×9 image, σ = 0.9, k = 1.5, default border"),
        Case((_distinct((9, 8), seed=3, scale=1 / 71), 0.7), {"border": "reflect"}, "σ = 0.7, default k = 1.6, reflect"),
        Case((_distinct((7, 9), seed=5, dtype=np.uint8), 0.8, 2.0), {"border": "zero"}, "uint8 image, k = 2, zero border"),
    ],
    hidden=_dog_hidden,
    compare=_LINEAR,
    mistakes=[
        _dog_swapped,
        _dog_plus_k,
        _dog_k_ignored,
        _dog_k_squared,
        *border_mistakes(_dog, _BORDER_HINT),
    ],
    allowed=("filters.pad", "filters.gaussian_kernel", "filters.gaussian"),
)


# --------------------------------------------------------------------------------------------
# edges.zero_crossings (§4.11)
# --------------------------------------------------------------------------------------------
def _zc_variant(response, threshold=0.0, *, place="smaller", zeros=False, vertical=True, use_threshold=True,
                diagonal=False, ties="first"):
    r = np.asarray(response, dtype=np.float64)
    out = np.zeros(r.shape, dtype=bool)
    pairs = [((slice(None), slice(None, -1)), (slice(None), slice(1, None)))]
    if vertical:
        pairs.append(((slice(None, -1), slice(None)), (slice(1, None), slice(None))))
    if diagonal:
        pairs.append(((slice(None, -1), slice(None, -1)), (slice(1, None), slice(1, None))))
        pairs.append(((slice(None, -1), slice(1, None)), (slice(1, None), slice(None, -1))))
    for first, second in pairs:
        a, b = r[first], r[second]
        crossing = (a * b <= 0) & (a != b) if zeros else (np.sign(a) * np.sign(b) < 0)
        if use_threshold:
            crossing &= np.abs(a - b) > threshold
        if place == "both":
            out[first] |= crossing
            out[second] |= crossing
            continue
        if place == "positive":
            on_first = a > b
        elif place == "larger":
            on_first = np.abs(a) >= np.abs(b)
        elif ties == "first":
            on_first = np.abs(a) <= np.abs(b)
        else:
            on_first = np.abs(a) < np.abs(b)
        out[first] |= crossing & on_first
        out[second] |= crossing & ~on_first
    return out


_zc = partial(variant, _zc_variant)


def _int_response(rng, h, w, lo=-4, hi=4):
    return rng.integers(lo, hi + 1, (h, w)).astype(np.float64)


def _zero_crossings_hidden(rng):
    disk = _disk(rng, _size(rng, 14, 20), _size(rng, 14, 20))
    return [
        Case((rng.normal(0, 1, (_size(rng, 6, 10), _size(rng, 7, 12))),), {}, "random response, threshold 0"),
        Case((rng.normal(0, 1, (_size(rng, 6, 10), _size(rng, 7, 12))), _u(rng, 0.8, 1.6, 2)), {},
             "random response with a threshold"),
        Case((_int_response(rng, _size(rng, 6, 9), _size(rng, 6, 9)),), {},
             "integer response: exact zeros and ties |a| = |b|"),
        Case((_int_response(rng, _size(rng, 6, 9), _size(rng, 6, 9), -2, 2), 2.0), {},
             "integer response, threshold equal to some jumps (|a − b| > threshold)"),
        Case((_log(disk, _sigma(rng, 0.8, 1.5)),), {"threshold": 0.0}, "the LoG of an anti-aliased disk"),
        Case((_dog(disk, _sigma(rng, 0.8, 1.2)), 0.01), {}, "the DoG of a disk, small threshold"),
        Case((rng.normal(0, 1, (1, _size(rng, 8, 14))),), {}, "single row 1×N"),
        Case((rng.normal(0, 1, (_size(rng, 6, 10), 1)),), {}, "single column N×1"),
        Case((np.full((_size(rng, 3, 6), _size(rng, 3, 6)), float(rng.choice([-2.0, 0.0, 3.0]))),), {},
             "constant response (no crossings)"),
        Case((rng.uniform(-1e6, 1e6, (_size(rng, 5, 8), _size(rng, 5, 8))), float(rng.uniform(1e5, 5e5))), {},
             "±1e6 values and threshold"),
    ]


zero_crossings = Check(
    public=[
        Case((np.array([[3.0, 1.0, -2.0, -1.0, 0.0, 5.0],
                        [-2.0, 2.0, -2.0, 4.0, -3.0, 1.0],
                        [1.0, -1.0, 0.0, 2.0, 1.0, -1.0],
                        [0.0, 3.0, -4.0, 0.0, -2.0, 2.0],
                        [2.0, -1.0, 1.0, -3.0, 3.0, -0.5]]),), {},
             "5×6 integer response with exact zeros and ties"),
        Case((np.array([[0.9, -0.2, -1.5, 0.4, 1.1],
                        [0.3, 0.8, -0.6, -0.1, 0.7],
                        [-1.2, 0.5, 1.3, -0.9, -0.3],
                        [0.6, -0.4, -0.7, 1.6, 0.2]]), 1.0), {}, "4×5 response, threshold 1.0"),
        Case((_log(disk_image((12, 13), centre=(6.3, 5.8), radius=3.6), 1.0),), {},
             "the LoG (σ = 1) of a small disk"),
    ],
    hidden=_zero_crossings_hidden,
    compare=_EXACT_BOOL,
    mistakes=[
        Mistake("both pixels of a crossing marked", _zc(place="both"),
                "Mark only one pixel per crossing pair: the one whose |value| is smaller"),
        Mistake("edge always on the positive pixel", _zc(place="positive"),
                "Put the edge on the pixel of the pair with the smaller absolute value, whatever its sign"),
        Mistake("edge on the pixel farther from zero", _zc(place="larger"),
                "The edge goes on the pixel closer to the zero crossing: the smaller |value|"),
        Mistake("ties put on the lower/right pixel", _zc(ties="second"),
                "When |a| = |b| the edge goes on the upper (vertical pair) or left (horizontal pair) pixel"),
        Mistake("exact zeros counted as crossings (a·b ≤ 0)", _zc(zeros=True),
                "A crossing needs strictly opposite signs, a·b < 0: a pixel equal to 0 is not part of a pair"),
        Mistake("horizontal pairs only", _zc(vertical=False), "Check vertically adjacent pairs as well"),
        Mistake("threshold ignored", _zc(use_threshold=False), "Keep a pair only when |a − b| > threshold"),
        Mistake("diagonal pairs included", _zc(diagonal=True),
                "Only horizontally or vertically adjacent pairs count (4-neighbours), not diagonal ones"),
    ],
)


# --------------------------------------------------------------------------------------------
# edges.non_max_suppression (§4.8)
# --------------------------------------------------------------------------------------------
def _nms_variant(magnitude, ix, iy, interpolate=True, *, strict=False, swap_weights=False, border=False):
    mag = np.asarray(magnitude, dtype=np.float64)
    gx = np.asarray(ix, dtype=np.float64)
    gy = np.asarray(iy, dtype=np.float64)
    h, w = mag.shape
    padded = np.zeros((h + 2, w + 2))
    padded[1:-1, 1:-1] = mag

    def at(dy, dx):
        return padded[1 + dy: 1 + dy + h, 1 + dx: 1 + dx + w]

    ax, ay = np.abs(gx), np.abs(gy)
    if interpolate:
        vertical = ay > ax
        same = (gx > 0) == (gy > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            weight = np.minimum(ax, ay) / np.maximum(ax, ay)
        if swap_weights:
            weight = 1.0 - weight
        plus = weight * np.where(same, at(1, 1), np.where(vertical, at(1, -1), at(-1, 1))) \
            + (1 - weight) * np.where(vertical, at(1, 0), at(0, 1))
        minus = weight * np.where(same, at(-1, -1), np.where(vertical, at(-1, 1), at(1, -1))) \
            + (1 - weight) * np.where(vertical, at(-1, 0), at(0, -1))
    else:
        sector = np.floor((np.degrees(np.arctan2(gy, gx)) % 180.0 + 22.5) / 45.0).astype(int) % 4
        offsets = ((0, 1), (1, 1), (1, 0), (1, -1))
        plus = np.select([sector == k for k in range(4)], [at(dy, dx) for dy, dx in offsets])
        minus = np.select([sector == k for k in range(4)], [at(-dy, -dx) for dy, dx in offsets])
    compare = np.greater if strict else np.greater_equal
    with np.errstate(invalid="ignore"):
        keep = (mag > 0) & compare(mag, plus) & compare(mag, minus) & ((ax > 0) | (ay > 0))
    out = np.where(keep, mag, 0.0)
    if border:
        out[0] = out[-1] = 0.0
        out[:, 0] = out[:, -1] = 0.0
    return out


def _nms_misread(magnitude, ix, iy, interpolate=True, *, gradient=None, interpolation=None, recompute=False):
    """The reference suppression on misread arguments: the derivatives as ``gradient(ix, iy)``
    returns them (float arrays in), ``interpolation`` in place of ``interpolate``, or the
    magnitude recomputed from ix and iy."""
    if recompute:
        magnitude = _magnitude(ix, iy)
    if gradient is not None:
        ix, iy = gradient(np.asarray(ix, dtype=np.float64), np.asarray(iy, dtype=np.float64))
    return _nms(magnitude, ix, iy, interpolate if interpolation is None else interpolation)


_nmsv = partial(variant, _nms_variant)
_misread = partial(variant, _nms_misread)


def _gradient_field(rng, h, w, *, scale=1.0):
    """Random derivatives and their L2 magnitude: no ties, every direction."""
    ix = rng.normal(0.0, scale, (h, w))
    iy = rng.normal(0.0, scale, (h, w))
    return np.hypot(ix, iy), ix, iy


def _plateau_field(rng, h, w):
    """Integer magnitudes with two-pixel plateaus along axis-aligned and diagonal gradients
    (interpolation weights 0 or 1, so every formula is exact): a strict maximum loses them."""
    mag = rng.integers(1, 4, (h, w)).astype(np.float64)
    ix = np.zeros((h, w))
    iy = np.zeros((h, w))
    kind = rng.integers(0, 4, (h, w))
    ix[kind == 0] = 1.0
    iy[kind == 1] = -2.0
    ix[kind >= 2] = 3.0
    iy[kind == 2] = 3.0
    iy[kind == 3] = -3.0
    ix *= rng.choice([-1.0, 1.0], (h, w))
    # plant horizontal, vertical and diagonal plateaus of equal values
    for _ in range(3):
        r, c = _size(rng, 1, h - 3), _size(rng, 1, w - 3)
        value = float(rng.integers(5, 8))
        which = int(rng.integers(0, 3))
        if which == 0:
            mag[r, c:c + 2] = value
            ix[r, c:c + 2], iy[r, c:c + 2] = 1.0, 0.0
        elif which == 1:
            mag[r:r + 2, c] = value
            ix[r:r + 2, c], iy[r:r + 2, c] = 0.0, 2.0
        else:
            mag[r, c] = mag[r + 1, c + 1] = value
            ix[r, c] = ix[r + 1, c + 1] = -1.0
            iy[r, c] = iy[r + 1, c + 1] = -1.0
    return mag, ix, iy


def _sobel_field(image):
    gx, gy = _sobel(_gaussian(image, 1.0))
    return _magnitude(gx, gy), gx, gy


def _nms_public():
    rng = np.random.default_rng(11)
    field = _gradient_field(rng, 7, 8)
    plateau = _plateau_field(np.random.default_rng(5), 7, 8)
    r = np.random.default_rng(17)
    other = (np.round(r.uniform(0.5, 3.0, (6, 7)), 2), r.normal(0, 1, (6, 7)), r.normal(0, 1, (6, 7)))
    return [
        Case(field, {}, "7×8 random gradient field, M = hypot(ix, iy), interpolated (default)"),
        Case(field, {"interpolate": False}, "the same field, interpolate=False (four directions)"),
        Case(plateau, {}, "integer magnitudes with plateaus along axis-aligned and diagonal gradients"),
        Case(other, {}, "a magnitude that is not hypot(ix, iy): use the one you are given"),
    ]


def _nms_hidden(rng):
    h, w = _size(rng, 8, 12), _size(rng, 9, 14)
    field = _gradient_field(rng, h, w)
    disk = _sobel_field(_disk(rng, _size(rng, 16, 22), _size(rng, 16, 22), noise=0.01))
    mag_l1 = _magnitude(disk[1], disk[2], "l1")
    plateau1 = _plateau_field(rng, _size(rng, 7, 10), _size(rng, 7, 10))
    plateau2 = _plateau_field(rng, _size(rng, 7, 10), _size(rng, 7, 10))
    big = _gradient_field(rng, _size(rng, 7, 10), _size(rng, 7, 10), scale=1e6)
    axes = _gradient_field(rng, _size(rng, 7, 10), _size(rng, 8, 11))
    axes[1][::3] = 0.0  # Ix = 0 on some rows: vertical gradients, weight exactly 0
    axes[2][:, ::4] = 0.0
    axes = (_magnitude(axes[1], axes[2]), axes[1], axes[2])
    sparse = _gradient_field(rng, _size(rng, 7, 10), _size(rng, 7, 10))
    off = rng.random(sparse[0].shape) < 0.3
    sparse = (np.where(off, 0.0, sparse[0]), np.where(off, 0.0, sparse[1]), np.where(off, 0.0, sparse[2]))
    return [
        Case(field, {}, "random gradient field, interpolated"),
        Case(field, {"interpolate": False}, "random gradient field, interpolate=False"),
        Case(disk, {}, "Sobel gradient of a smoothed disk (every orientation)"),
        Case(disk, {"interpolate": False}, "Sobel gradient of a disk, interpolate=False"),
        Case((mag_l1,) + disk[1:], {}, "L1 magnitude of the disk's gradient (not hypot(ix, iy))"),
        Case(plateau1, {}, "integer plateaus along axis-aligned and diagonal gradients"),
        Case(plateau2, {"interpolate": False}, "integer plateaus, interpolate=False"),
        Case(big, {"interpolate": bool(rng.random() < 0.5)}, "±1e6 derivatives"),
        Case(axes, {}, "exactly horizontal and vertical gradients among others"),
        Case(sparse, {"interpolate": True}, "zero gradient (and magnitude) at 30% of the pixels"),
        Case(_gradient_field(rng, 1, _size(rng, 7, 12)), {}, "single row 1×N"),
        Case(_gradient_field(rng, 2, 3), {"interpolate": bool(rng.random() < 0.5)}, "tiny 2×3"),
    ]


non_max_suppression = Check(
    public=_nms_public,
    hidden=_nms_hidden,
    compare=close(rtol=0.0, atol=0.0, kind="f"),
    mistakes=[
        Mistake("no interpolation (nearest of four directions)", _misread(interpolation=False),
                "With interpolate=True compare with (1−w)·axis neighbour + w·diagonal neighbour, "
                "w = min(|Ix|,|Iy|)/max(|Ix|,|Iy|), instead of rounding the direction"),
        Mistake("interpolate=False ignored (always interpolated)", _misread(interpolation=True),
                "With interpolate=False round the direction to 0°, 45°, 90° or 135° and compare with those two neighbours"),
        Mistake("compared along the edge, not across it", _misread(gradient=lambda ix, iy: (-iy, ix)),
                "Compare with the neighbours along the gradient (ix, iy), which crosses the edge; not along the edge"),
        Mistake("x and y swapped in the direction", _misread(gradient=lambda ix, iy: (iy, ix)),
                "ix is the step along the columns (x), iy along the rows (y): the + neighbour is at (row + sy, col + sx)"),
        Mistake("y pointing up (Iy negated)", _misread(gradient=lambda ix, iy: (ix, -iy)),
                "y points down the rows: a gradient with Iy > 0 points to the row below (row + 1)"),
        Mistake("strict maximum (> instead of ≥)", _nmsv(strict=True),
                "Keep a pixel when M ≥ both side values: a plateau of equal values keeps both pixels"),
        Mistake("magnitude recomputed from ix and iy", _misread(recompute=True),
                "Use the magnitude you are given (it may be an L1 or smoothed magnitude), do not recompute hypot(ix, iy)"),
        Mistake("interpolation weights swapped", _nmsv(swap_weights=True),
                "The diagonal neighbour gets weight w = min/max and the axis neighbour 1 − w"),
        Mistake("image border suppressed", _nmsv(border=True),
                "Border pixels are kept when they are maxima: neighbours outside the image count as 0"),
    ],
)


# --------------------------------------------------------------------------------------------
# edges.hysteresis (§4.10)
# --------------------------------------------------------------------------------------------
def _hyst_variant(magnitude, low, high, *, connectivity=8, inclusive=False, mode="link"):
    mag = np.asarray(magnitude, dtype=np.float64)
    strong = mag >= high if inclusive else mag > high
    candidates = mag >= low if inclusive else mag > low
    if mode == "strong":
        return strong
    if mode == "weak":
        return candidates
    if mode == "single":
        return strong | (candidates & _dilate(strong, 1))
    out = np.zeros(mag.shape, dtype=bool)
    if not strong.any():
        return out
    flat, label = _components(candidates, connectivity)
    linked = np.zeros(flat.size, dtype=bool)
    linked[label[strong.reshape(-1)[flat]]] = True
    out.reshape(-1)[flat[linked[label]]] = True
    return out


_HYST_PUBLIC = np.array([
    [9, 0, 0, 0, 0, 0, 0, 4],
    [0, 5, 0, 0, 3, 3, 0, 0],
    [0, 0, 5, 0, 0, 0, 6, 0],
    [0, 0, 0, 5, 5, 5, 0, 0],
    [2, 0, 0, 0, 0, 0, 5, 8],
    [3, 6, 0, 4, 4, 0, 3, 0],
    [0, 0, 0, 4, 0, 0, 0, 8],
], dtype=np.float64)


_hyst = partial(variant, _hyst_variant)


def _chain_field(rng, h, w):
    """Long weak chains (straight and diagonal) with one strong pixel each, plus clutter."""
    mag = np.where(rng.random((h, w)) < 0.15, rng.integers(1, 4, (h, w)), 0).astype(np.float64)
    r = _size(rng, 1, h - 2)
    mag[r, 1:w - 1] = 5.0
    mag[r, int(rng.integers(1, w - 1))] = 9.0
    n = min(h, w) - 1
    c0 = _size(rng, 0, max(0, w - n))
    for k in range(n):
        mag[k, c0 + k] = max(mag[k, c0 + k], 5.0)
    mag[0, c0] = 9.0
    return mag


def _hysteresis_hidden(rng):
    disk = _nms(*_sobel_field(_disk(rng, _size(rng, 18, 24), _size(rng, 18, 24), noise=0.03)))
    top = float(disk.max())
    square = _nms(*_sobel_field(_square(rng, _size(rng, 18, 24), _size(rng, 18, 24), noise=0.06)))
    sq_top = float(square.max())
    ints = rng.integers(0, 9, (_size(rng, 8, 12), _size(rng, 8, 12))).astype(np.float64)
    return [
        Case((disk, 0.2 * top, 0.6 * top), {}, "NMS output of a noisy disk"),
        Case((square, 0.15 * sq_top, 0.5 * sq_top), {}, "NMS output of a noisy rotated square"),
        Case((_chain_field(rng, _size(rng, 9, 13), _size(rng, 9, 13)), 4.0, 8.0), {},
             "long straight and diagonal weak chains"),
        Case((_chain_field(rng, _size(rng, 9, 13), _size(rng, 9, 13)), 2.5, 6.0), {}, "weak chains and clutter"),
        Case((ints, 3.0, 6.0), {}, "integer magnitudes equal to the thresholds"),
        Case((ints * 0.5, 1.0, 1.0), {}, "low == high"),
        Case((rng.random((_size(rng, 6, 9), _size(rng, 6, 9))), 0.8, 1.5), {}, "no strong pixel (empty result)"),
        Case((rng.uniform(-1e6, 1e6, (_size(rng, 8, 11), _size(rng, 8, 11))), 2e5, 7e5), {}, "±1e6 values"),
        Case((rng.integers(0, 6, (1, _size(rng, 10, 16))).astype(np.float64), 1.0, 4.0), {}, "single row 1×N"),
        Case((rng.integers(0, 6, (2, 3)).astype(np.float64), 1.0, 3.0), {}, "tiny 2×3"),
    ]


hysteresis = Check(
    public=[
        Case((_HYST_PUBLIC, 3.0, 5.0), {}, "7×8 magnitudes: diagonal and straight chains, values equal to the thresholds"),
        Case((_HYST_PUBLIC.T.copy(), 2.0, 7.0), {}, "the transpose, other thresholds"),
        Case((np.array([[0.2, 0.7, 0.0, 0.9, 0.4],
                        [0.0, 0.45, 0.0, 0.35, 0.0],
                        [0.6, 0.0, 0.0, 0.0, 0.3],
                        [0.0, 0.5, 0.55, 0.0, 0.8]]), 0.3, 0.75), {}, "4×5 float magnitudes"),
    ],
    hidden=_hysteresis_hidden,
    refusals=[
        Case((np.linspace(0.0, 1.0, 64).reshape(8, 8), 0.6, 0.3), {}, "low above high", raises="ValueError"),
    ],
    compare=_EXACT_BOOL,
    mistakes=[
        Mistake("4-connected linking", _hyst(connectivity=4),
                "Link through all 8 neighbours, diagonals included (edges after NMS are often diagonal chains)"),
        Mistake("single pass (only direct neighbours of strong pixels)", _hyst(mode="single"),
                "Follow whole chains: a weak pixel is kept if it is connected to a strong pixel through other "
                "weak pixels (repeat until nothing changes, or label connected components)"),
        Mistake("thresholds inclusive (≥ instead of >)", _hyst(inclusive=True),
                "Strong means magnitude > high and candidate means magnitude > low (strictly)"),
        Mistake("weak pixels kept without linking", _hyst(mode="weak"),
                "A weak pixel (low < M ≤ high) is kept only if it is connected to a strong one"),
        Mistake("only strong pixels (no linking)", _hyst(mode="strong"),
                "Also keep the weak pixels (> low) connected to strong pixels"),
    ],
)


# --------------------------------------------------------------------------------------------
# edges.canny (§4.10)
# --------------------------------------------------------------------------------------------
def _canny_variant(image, sigma=1.4, low=0.1, high=0.2, relative=True, *, norm="l2", smooth=True,
                   nms="interpolate", link="8", as_relative=None, guard=True):
    img = np.asarray(image, dtype=np.float64)
    s = _gaussian(img, sigma) if smooth else img
    gx, gy = _sobel(s)
    mag = _magnitude(gx, gy, norm)
    largest = float(mag.max())
    if guard and not largest > 1e-12 * max(1.0, float(np.abs(img).max())):
        return np.zeros(img.shape, dtype=bool)
    if (relative if as_relative is None else as_relative):
        low, high = low * largest, high * largest
    if nms == "interpolate":
        thin = _nms(mag, gx, gy, True)
    elif nms == "nearest":
        thin = _nms(mag, gx, gy, False)
    else:
        thin = mag
    if link == "8":
        return _hysteresis(thin, low, high)
    if link == "4":
        return _hyst_variant(thin, low, high, connectivity=4)
    return thin > high


_cv = partial(variant, _canny_variant)


def _shaded_disk(rng: np.random.Generator, h: int, w: int, *, noise: float = 0.0) -> np.ndarray:
    """A disk lit from one side: its contrast fades from 1 to ~0.1 across it, so only part of
    its contour is strong and the rest must be linked through weak, often only diagonally
    connected, pixels."""
    radius = float(rng.uniform(0.3, 0.36) * min(h, w))
    cx = (w - 1) / 2 + float(rng.uniform(-0.4, 0.4))
    cy = (h - 1) / 2 + float(rng.uniform(-0.4, 0.4))
    inside = disk_image((h, w), centre=(cx, cy), radius=radius)
    light = float(rng.uniform(-np.pi, np.pi))
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    t = ((x - cx) * math.cos(light) + (y - cy) * math.sin(light)) / radius  # -1 .. 1 across the disk
    contrast = 0.1 + 0.9 * np.clip((t + 1) / 2, 0, 1) ** 2
    img = 0.1 + 0.8 * inside * contrast
    return img + rng.normal(0.0, noise, img.shape) if noise else img


def _absolute_thresholds(image, sigma, low_fraction, high_fraction):
    """Thresholds in magnitude units: fractions of the image's largest Sobel magnitude, rounded."""
    gx, gy = _sobel(_gaussian(image, sigma))
    top = float(_magnitude(gx, gy).max())
    digits = max(0, 2 - int(math.floor(math.log10(top))))
    return round(low_fraction * top, digits), round(high_fraction * top, digits)


def _rounding_bumps(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A constant image with a few pixels higher by 1e-13 of its level, the size of rounding
    noise: gradients far below 1e-12 of the image (no edges)."""
    level = float(rng.uniform(0.2, 0.9))
    img = np.full((h, w), level)
    for _ in range(3):
        img[int(rng.integers(2, h - 2)), int(rng.integers(2, w - 2))] = level * (1.0 + 1e-13)
    return img


def _canny_public():
    disk = disk_image((28, 30), centre=(14.3, 13.6), radius=9.3, inside=0.85, outside=0.1)
    rng = np.random.default_rng(4)
    shaded = _shaded_disk(np.random.default_rng(12), 28, 28)
    square = square_image((24, 24), centre=(11.8, 11.3), side=13.0, angle=0.35, inside=0.8, outside=0.15)
    u8 = np.clip(np.round(255 * (square + rng.normal(0, 0.02, square.shape))), 0, 255).astype(np.uint8)
    low, high = _absolute_thresholds(u8, 1.2, 0.2, 0.5)
    step = oriented_step_image((20, 22), angle=math.radians(23.0), offset=0.35, low=0.15, high=0.8)
    return [
        Case((disk, 1.5, 0.83, 0.87), {}, "anti-aliased disk, tight relative thresholds 0.83 / 0.87"),
        Case((shaded, 1.2, 0.15, 0.8), {}, "disk lit from one side: weak contour linked to strong parts"),
        Case((u8, 1.2, low, high), {"relative": False}, f"uint8 square, absolute thresholds {low:g} / {high:g}"),
        Case((u8, 1.2), {}, "the uint8 square, default relative thresholds 0.1 / 0.2"),
        Case((step, 1.0, 0.3, 0.6), {}, "straight step edge at 23° (between two NMS directions)"),
        Case((_rounding_bumps(rng, 12, 14), 1.0), {}, "nearly constant image: bumps of 1e-13 of its level, rounding noise (no edges)"),
    ]


def _canny_hidden(rng):
    def disk(noise=0.0):
        return _disk(rng, _size(rng, 26, 32), _size(rng, 26, 32), noise=noise)

    def tight():
        low = _u(rng, 0.82, 0.84)
        return low, low + 0.04

    u8 = np.clip(np.round(255 * _square(rng, _size(rng, 22, 28), _size(rng, 22, 28), noise=0.02)), 0, 255)
    u8 = u8.astype(np.uint8)
    sigma_u8 = _sigma(rng, 1.1, 1.5)
    square = 100.0 * _square(rng, _size(rng, 22, 28), _size(rng, 22, 28), noise=0.03)
    sigma_sq = _sigma(rng, 1.1, 1.5)
    angle = math.radians(float(rng.choice([22.0, 24.0, 66.0, 68.0, 112.0, 158.0])))
    return [
        Case((disk(), _sigma(rng, 1.3, 1.7), *tight()), {}, "disk, tight relative thresholds"),
        Case((disk(0.005), _sigma(rng, 1.3, 1.7), *tight()), {}, "slightly noisy disk, tight relative thresholds"),
        Case((_shaded_disk(rng, _size(rng, 24, 30), _size(rng, 24, 30)), _sigma(rng, 1.1, 1.4), 0.15, 0.8), {},
             "disk lit from one side (weak contour linked to strong parts)"),
        Case((_shaded_disk(rng, _size(rng, 24, 30), _size(rng, 24, 30), noise=0.01), _sigma(rng, 1.1, 1.4), 0.12, 0.7),
             {}, "noisy disk lit from one side"),
        Case((_square(rng, _size(rng, 22, 28), _size(rng, 22, 28), noise=0.06), _sigma(rng, 1.1, 1.6)), {},
             "noisy rotated square, default thresholds"),
        Case((oriented_step_image((_size(rng, 18, 24), _size(rng, 18, 24)), angle=angle,
                                  offset=float(rng.uniform(-1, 1)), low=0.1, high=0.85),
              _sigma(rng, 0.9, 1.3), 0.3, 0.6), {}, "straight step between two NMS directions"),
        Case((u8, sigma_u8, *_absolute_thresholds(u8, sigma_u8, 0.2, 0.5)), {"relative": False},
             "uint8 square, absolute thresholds"),
        Case((square, sigma_sq, *_absolute_thresholds(square, sigma_sq, 0.15, 0.45)), {"relative": False},
             "float square in 0..100, absolute thresholds (magnitude units)"),
        Case((np.round(255 * disk(0.01)).clip(0, 255).astype(np.uint8), _sigma(rng, 1.1, 1.6)), {"low": 0.2, "high": 0.4},
             "uint8 disk, relative thresholds given by keyword"),
        Case((_rounding_bumps(rng, _size(rng, 10, 14), _size(rng, 10, 14)),), {},
             "nearly constant image: bumps of 1e-13 of its level, rounding noise (no edges)"),
        Case((rng.random((1, _size(rng, 12, 18))), 0.7), {}, "single row 1×N"),
        Case((rng.random((_size(rng, 12, 16), _size(rng, 18, 24))), _sigma(rng, 0.5, 0.9), 0.2, 0.5), {},
             "random texture, small σ"),
    ]


canny = Check(
    public=_canny_public,
    hidden=_canny_hidden,
    compare=EdgeF1(radius=0, min_f1=0.97),
    mistakes=[
        Mistake("no flat-image guard (rounding noise becomes edges)", _cv(guard=False),
                "When the largest magnitude is at most 1e-12·max(1, max|I|) the image is flat: return no edges "
                "(relative thresholds would otherwise turn rounding noise into edges)"),
        Mistake("L1 magnitude instead of L2", _cv(norm="l1"),
                "The edge strength is the L2 norm sqrt(gx² + gy²): |gx| + |gy| favours diagonal edges by up to √2"),
        Mistake("thresholds used as absolute values", _cv(as_relative=False),
                "With relative=True multiply low and high by the largest gradient magnitude of the image"),
        Mistake("thresholds always relative (relative=False ignored)", _cv(as_relative=True),
                "With relative=False use low and high as they are, in magnitude units"),
        Mistake("no Gaussian smoothing", _cv(smooth=False), "Smooth the image with a Gaussian of standard deviation σ first"),
        Mistake("no non-maximum suppression", _cv(nms="none"),
                "Thin the magnitude with non-maximum suppression before the hysteresis thresholds"),
        Mistake("NMS without interpolation", _cv(nms="nearest"),
                "Use interpolated non-maximum suppression (interpolate=True)"),
        Mistake("4-connected hysteresis", _cv(link="4"),
                "Link weak pixels through all 8 neighbours: thin diagonal edges are only 8-connected"),
        Mistake("single threshold (no hysteresis)", _cv(link="none"),
                "Keep the weak pixels (> low) connected to strong pixels (> high), not just the strong ones"),
    ],
    allowed=("filters.pad", "filters.gaussian_kernel", "filters.gaussian", "filters.correlate",
             "edges.sobel", "edges.magnitude", "edges.non_max_suppression", "edges.hysteresis"),
)


# --------------------------------------------------------------------------------------------
# §4.10 the measured exercise: an edge detector for noisy pictures, graded by its F1 score
# --------------------------------------------------------------------------------------------
from typing import Any  # noqa: E402

from ..data import polygon_image  # noqa: E402
from ..grading.measured import MeasuredCase, Scale  # noqa: E402
from ._outlines import BUDGET_SECONDS as _OUTLINE_BUDGET  # noqa: E402
from ._outlines import F1_SCALE, largest_magnitude, noise_level, outline_canny, sobel_noise  # noqa: E402

#: the published scale the grader applies (its corners: :data:`cvkit.edges._outlines.F1_SCALE`)
OUTLINE_F1 = Scale(F1_SCALE, percent=False)
#: the pixel tolerance of the F1 score (Chebyshev distance, as :func:`edge_f1`)
OUTLINE_RADIUS = 1


def outline_scene(rng: np.random.Generator, size: int = 112) -> tuple[np.ndarray, np.ndarray]:
    """A noisy picture of four flat shapes and their true outlines: ``(image, truth)``.

    A background level in [0.3, 0.5] shaded by a ramp of 0.1–0.25 in a random direction; in each
    quarter one shape (two disks, a rotated square and a triangle, in a random order, sizes and
    positions drawn) of contrast ±[0.12, 0.3], one of the four at most ±0.16; white Gaussian noise of σ ∈ [0.07, 0.1]. The
    truth marks the pixels of each shape (more than half covered) that have a 4-neighbour
    outside it."""
    shape = (size, size)
    half = size // 2
    y, x = np.mgrid[0:size, 0:size] / (size - 1)
    light = rng.uniform(0, 2 * np.pi)
    clean = rng.uniform(0.3, 0.5) + rng.uniform(0.1, 0.25) * (np.cos(light) * x + np.sin(light) * y)
    truth = np.zeros(shape, dtype=bool)
    faint = int(rng.integers(0, 4))                              # one shape of the four is faint
    for k, (kind, (r0, c0)) in enumerate(zip(rng.permutation(["disk", "square", "triangle", "disk"]),
                                             [(0, 0), (0, half), (half, 0), (half, half)])):
        cx, cy = c0 + half / 2 + rng.uniform(-3, 3), r0 + half / 2 + rng.uniform(-3, 3)
        if kind == "disk":
            cover = disk_image(shape, centre=(cx, cy), radius=rng.uniform(12, 20))
        elif kind == "square":
            cover = square_image(shape, centre=(cx, cy), side=rng.uniform(22, 32), angle=rng.uniform(0, np.pi / 2))
        else:
            r, t0 = rng.uniform(14, 21), rng.uniform(0, 2 * np.pi)
            t = t0 + np.arange(3) * 2 * np.pi / 3
            cover = polygon_image(shape, np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], axis=1))
        contrast = rng.uniform(0.12, 0.16) if k == faint else rng.uniform(0.12, 0.3)
        clean = clean + rng.choice([-1.0, 1.0]) * contrast * cover
        inside = cover > 0.5
        p = np.pad(inside, 1, mode="edge")
        truth |= inside & ~(p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:])
    return clean + rng.normal(0.0, rng.uniform(0.07, 0.1), shape), truth


def _outlines_public() -> list[Case]:
    image, truth = outline_scene(np.random.default_rng(2026))
    return [MeasuredCase((image,), {}, "four shapes on a shaded background, noise σ ≈ 0.09", truth=truth)]


def _outlines_hidden(rng: np.random.Generator) -> list[Case]:
    pictures = [outline_scene(rng) for _ in range(2)]
    return [MeasuredCase((image,), {}, f"your picture {k}: four shapes, your noise and contrasts", truth=truth)
            for k, (image, truth) in enumerate(pictures, start=1)]


class OutlineF1(Comparator):
    """Passes when the edge map's F1 score against the case's true outlines (within
    :data:`OUTLINE_RADIUS` pixel) reaches the top of :data:`OUTLINE_F1`; below it the case earns
    the scale's share. The reference's map (``expected``) only serves for comparison."""

    judges_alone = True  # the verdict is what the output achieves on the case's truth

    @staticmethod
    def scores(got: Any, case: Any) -> tuple[float, float, float]:
        """``(F1, precision, recall)`` of ``got`` against the case's truth; zeros when ``got``
        is not a bool map of the picture's shape."""
        truth = np.asarray(getattr(case, "truth", np.zeros((0, 0), dtype=bool)))
        edges_found = np.asarray(got)
        if edges_found.dtype.kind != "b" or edges_found.shape != truth.shape or truth.ndim != 2:
            return 0.0, 0.0, 0.0
        return edge_f1(edges_found, truth, OUTLINE_RADIUS)

    @classmethod
    def f1(cls, got: Any, case: Any) -> float:
        return cls.scores(got, case)[0]

    def __call__(self, got: Any, expected: Any, case: Any = None) -> Mismatch | None:
        f1, precision, recall = self.scores(got, case)
        if f1 >= OUTLINE_F1.top:
            return None
        truth = np.asarray(getattr(case, "truth", np.zeros((0, 0), dtype=bool)))
        malformed = EdgeF1(radius=OUTLINE_RADIUS, min_f1=0.0)(got, truth)    # not a bool map of the picture's shape
        if malformed is not None:
            return malformed
        arr = np.asarray(got)
        words = [OUTLINE_F1.shortfall(f1, "F1", f" (precision {precision:.3f}, recall {recall:.3f}, tolerance "
                                                f"{OUTLINE_RADIUS} px)")]
        reference = self.f1(expected, case)
        if reference:
            words.append(f"The reference detector reached F1 = {reference:.3f} on the same picture.")
        near = int((arr & _dilate(truth, OUTLINE_RADIUS)).sum())
        if near > 1.8 * max(1, int(truth.sum())):      # about two found pixels or more per outline pixel
            words.append("Your outlines are thicker than one pixel: thin them with non-maximum suppression.")
        elif precision < 0.5:
            words.append("Most of your edge pixels are not on an outline: noise edges. Smooth more (a larger σ) or raise "
                         "the thresholds; thresholds set from the noise level work whatever the strongest edge is.")
        elif recall < 0.8:
            words.append("Part of the outlines is missing: a faint shape fell below your thresholds (lower them, or "
                         "set them from the noise rather than from the largest gradient, after smoothing).")
        return Mismatch(" ".join(words))


def _outline_credit(got: Any, case: Any) -> float:
    return OUTLINE_F1.credit(OutlineF1.f1(got, case))


def _noise_thresholds(image: np.ndarray, sigma: float) -> tuple[float, float]:
    unit = sobel_noise(sigma) * max(noise_level(image), 1e-12)
    return 3.0 * unit, 6.0 * unit


@mistake("Canny's default relative thresholds on a noisy picture",
         "Thresholds of 0.1 / 0.2 times the largest gradient keep hundreds of noise edges here: raise them, or better "
         "set them from the noise level (a few times the spread the noise alone gives the smoothed gradient)")
def _outlines_default_thresholds(image):
    top = largest_magnitude(image, 1.4)
    return outline_canny(image, 1.4, 0.1 * top, 0.2 * top)


@mistake("no non-maximum suppression",
         "Thin the smoothed gradient magnitude with non-maximum suppression before the hysteresis: without it every "
         "outline is a band several pixels wide")
def _outlines_without_nms(image):
    return outline_canny(image, 2.0, *_noise_thresholds(image, 2.0), thin=False)


@mistake("no Gaussian smoothing",
         "Smooth before differentiating: on raw noisy pixels the gradient of the noise rivals that of the faint shapes, "
         "whatever the thresholds")
def _outlines_without_smoothing(image):
    return outline_canny(image, 0.0, *_noise_thresholds(image, 0.0))


detect_outlines = Check(
    public=_outlines_public,
    hidden=_outlines_hidden,
    compare=OutlineF1(),
    mistakes=[_outlines_default_thresholds, _outlines_without_nms, _outlines_without_smoothing],
    output_names=("edges",),
    time_limit=_OUTLINE_BUDGET,
    credit=_outline_credit,
)
