"""Checks of Chapter 2's image-formation functions: cases, comparators and mistake banks.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference
function (``cvkit.formation.checks:quantize`` grades ``formation.quantize``). Public cases are
tiny and fixed, and already tell every mistake of the bank from the right answer; hidden
cases are drawn from the grading seed and cover the awkward inputs of each contract (scalars
and arrays, integer dtypes, zero and negative disparities, points behind the camera, distances
at infinity, virtual images, exact half-way values, constant pixels, odd image sizes, every
Bayer pattern...), with, for every mistake, inputs on which it is wrong.

Formulas are compared with :func:`~cvkit.grading.close` at tolerances loose enough for any
order of the arithmetic; NaN and ±inf must appear exactly where expected.
"""
from __future__ import annotations

import numpy as np

from ..grading import Case, Check, Mistake, close, mistake
from ..grading.casekit import distinct as _distinct
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ._bayer import PATTERNS, channel_map
from ._bayer import bayer_mosaic as _bayer_mosaic
from ._bayer import demosaic_bilinear as _demosaic
from ._digitization import quantize as _quantize
from ._geometry import depth_from_disparity as _depth
from ._geometry import project_pinhole as _project
from ._optics import blur_circle_diameter as _blur
from ._optics import thin_lens_image_distance as _thin_lens

__all__ = [
    "project_pinhole", "depth_from_disparity", "thin_lens_image_distance", "blur_circle_diameter",
    "quantize", "image_memory_bits", "snr_db", "dynamic_range_db", "bayer_mosaic",
    "demosaic_bilinear",
]

#: formulas: any order of the arithmetic agrees to ~1e-15 relative
_FORMULA = close(rtol=1e-9, atol=1e-12, kind="f")
#: copies of values (mosaic) and their means (demosaicking)
_VALUES = close(rtol=1e-12, atol=1e-12, kind="f", scaled=True)


def _r3(values):
    """Rounded to 3 decimals (readable in the reports)."""
    return np.round(values, 3)


# --------------------------------------------------------------------------------------------
# formation.project_pinhole (§2.3)
# --------------------------------------------------------------------------------------------
@mistake("division by z forgotten", "Perspective divides by the depth: u = f·x/z, v = f·y/z (far things look small)")
def _pp_no_division(points_cam, f):
    return f * np.asarray(points_cam, dtype=np.float64)[:, :2]


@mistake("image inverted (u = −f·x/z)",
         "Use the image plane in front of the pinhole: u = +f·x/z, v = +f·y/z (no sign flip)")
def _pp_inverted(points_cam, f):
    return -_project(points_cam, f)


@mistake("u and v swapped", "Return (u, v) = (f·x/z, f·y/z) in that order: column 0 comes from x, column 1 from y")
def _pp_swapped(points_cam, f):
    return _project(points_cam, f)[:, ::-1]


@mistake("focal length ignored", "Multiply by f: u = f·x/z")
def _pp_no_focal(points_cam, f):
    return _project(points_cam, 1.0)


@mistake("divided by the distance ‖P‖, not by z",
         "Divide by the depth z (the third coordinate), not by the distance √(x²+y²+z²)")
def _pp_distance(points_cam, f):
    p = np.asarray(points_cam, dtype=np.float64)
    return f * p[:, :2] / np.linalg.norm(p, axis=1, keepdims=True)


def _points(rng, n, zlo=1.0, zhi=20.0, spread=5.0):
    xy = rng.uniform(-spread, spread, (n, 2))
    z = rng.uniform(zlo, zhi, (n, 1))
    return _r3(np.hstack([xy, z]))


def _pp_hidden(rng):
    behind = _points(rng, _size(rng, 3, 6))
    behind[::2, 2] *= -1
    ints = rng.integers(-50, 51, (_size(rng, 4, 8), 3))
    ints[:, 2] = rng.integers(1, 40, ints.shape[0]) * rng.choice([-1, 1], ints.shape[0])
    return [
        Case((_points(rng, _size(rng, 5, 10)), _u(rng, 0.5, 5.0)), {},
             "points in front of the camera, f in scene units"),
        Case((_points(rng, _size(rng, 5, 10), 2.0, 50.0, 20.0), float(rng.integers(300, 1500))), {},
             "f in pixels (hundreds)"),
        Case((behind, _u(rng, 1.0, 3.0, 2)), {}, "some points behind the camera (z < 0)"),
        Case((ints, float(rng.integers(2, 9))), {}, "integer coordinates (int dtype)"),
        Case((_points(rng, 1), _u(rng, 0.2, 2.0)), {}, "a single point (N = 1)"),
        Case((np.zeros((0, 3)), 1.5), {}, "no points (N = 0): an empty (0, 2) result"),
        Case((_points(rng, _size(rng, 3, 6), 1e3, 1e5, 1e4), _u(rng, 0.01, 0.1, 4)), {},
             "far points, short focal length"),
        Case((_points(rng, _size(rng, 3, 6), 0.01, 0.1, 0.05), _u(rng, 2.0, 8.0, 2)), {},
             "points very close to the pinhole"),
        Case((np.hstack([np.zeros((3, 2)), _r3(rng.uniform(1, 9, (3, 1)))]), 2.0), {},
             "points on the optical axis (they project to the image centre)"),
        Case((_points(rng, _size(rng, 4, 8)).tolist(), _u(rng, 0.5, 3.0, 2)), {},
             "points given as a list of lists"),
    ]


project_pinhole = Check(
    rules=("integer",),
    public=[
        Case((np.array([[1.0, 2.0, 4.0], [-3.0, 0.5, 6.0], [0.25, -1.5, 2.5]]), 2.5), {},
             "three points, f = 2.5"),
        Case((np.array([[0.3, -0.2, 1.5], [2.0, 1.0, 10.0]]), 800.0), {}, "f = 800 pixels"),
    ],
    hidden=_pp_hidden,
    compare=close(rtol=1e-10, atol=1e-12, kind="f"),
    mistakes=[_pp_no_division, _pp_inverted, _pp_swapped, _pp_no_focal, _pp_distance],
)


# --------------------------------------------------------------------------------------------
# formation.depth_from_disparity (§2.5.1)
# --------------------------------------------------------------------------------------------
@mistake("z = d / (b·f) (formula upside down)", "Depth is inversely proportional to disparity: z = b·f / d")
def _dd_inverted(disparity, baseline, focal):
    d = np.asarray(disparity, dtype=np.float64)
    with np.errstate(all="ignore"):
        return d / (baseline * focal)


@mistake("focal length missing (z = b/d)", "z = b·f / d: multiply the baseline by the focal length")
def _dd_no_focal(disparity, baseline, focal):
    return _depth(disparity, baseline, 1.0)


@mistake("negative disparities not marked NaN",
         "A negative disparity has no point in front of both cameras: return NaN there (np.where(d < 0, np.nan, …))")
def _dd_negative_kept(disparity, baseline, focal):
    d = np.asarray(disparity, dtype=np.float64)
    with np.errstate(all="ignore"):
        z = baseline * focal / d
    return np.where(d == 0, np.inf, z)


@mistake("zero disparity marked NaN, not inf",
         "d = 0 means parallel rays: the point is at infinity, so z = inf (only d < 0 is NaN)")
def _dd_zero_nan(disparity, baseline, focal):
    d = np.asarray(disparity, dtype=np.float64)
    with np.errstate(all="ignore"):
        return np.where(d > 0, baseline * focal / d, np.nan)


@mistake("floor division (//) instead of /", "Use true division `/`: depth is a real number")
def _dd_floor(disparity, baseline, focal):
    d = np.asarray(disparity)
    with np.errstate(all="ignore"):
        z = np.asarray((baseline * focal) // d, dtype=np.float64)
    z = np.where(d == 0, np.inf, z)
    return np.where(d < 0, np.nan, z)


def _disparities(rng, shape, lo=-3.0, hi=60.0, zeros=0.15, decimals=2):
    d = np.round(rng.uniform(lo, hi, shape), decimals)
    d[rng.random(shape) < zeros] = 0.0
    return d


def _dd_hidden(rng):
    b = _u(rng, 0.05, 0.5)
    f = _u(rng, 300, 1500, 1)
    nan_map = _disparities(rng, (_size(rng, 4, 7), _size(rng, 5, 9)))
    nan_map[rng.random(nan_map.shape) < 0.2] = np.nan
    return [
        Case((_disparities(rng, (_size(rng, 5, 9), _size(rng, 6, 12))), b, f), {},
             "disparity map with zeros and negatives"),
        Case((rng.integers(-4, 64, (_size(rng, 4, 8), _size(rng, 5, 10))), int(rng.integers(1, 20)),
              int(rng.integers(200, 900))), {}, "integer disparities, integer baseline and focal"),
        Case((rng.integers(0, 256, (_size(rng, 4, 8), _size(rng, 5, 10)), dtype=np.uint8), b, f), {},
             "uint8 disparities"),
        Case((nan_map, b, f), {}, "NaN marks unknown disparities (they stay NaN)"),
        Case((_u(rng, 1, 80), b, f), {}, "a single disparity (a scalar)"),
        Case((0.0, b, f), {}, "zero disparity: a point at infinity"),
        Case((-_u(rng, 0.5, 5, 2), b, f), {}, "negative disparity (no valid depth)"),
        Case((_disparities(rng, _size(rng, 8, 20), 0.01, 0.5, 0.0, 4), b, f), {},
             "1-D array of sub-pixel disparities (far points)"),
        Case((_disparities(rng, (_size(rng, 3, 6), _size(rng, 4, 7)), 100, 5000, 0.0, 1), 1.5, 12.0), {},
             "huge disparities (close points), baseline 1.5, focal 12"),
        Case((_disparities(rng, (_size(rng, 3, 5), _size(rng, 3, 5)), -60, -1, 0.0), b, f), {},
             "only negative disparities"),
    ]


depth_from_disparity = Check(
    rules=("integer",),
    public=[
        Case((np.array([[8.0, 16.5, 0.0, -2.0, 40.0], [1.0, 0.5, 3.0, 70.0, -0.5]]), 0.12, 700.0), {},
             "disparities with a zero and negatives, b = 0.12 m, f = 700 px"),
        Case((np.array([4, 7, 0, 12, -1, 30]), 3, 10), {}, "integer disparities, b = 3, f = 10"),
        Case((25.0, 0.5, 1000.0), {}, "a scalar disparity"),
    ],
    hidden=_dd_hidden,
    compare=close(rtol=1e-10, atol=1e-12, kind="f"),
    mistakes=[_dd_inverted, _dd_no_focal, _dd_negative_kept, _dd_zero_nan, _dd_floor],
)


# --------------------------------------------------------------------------------------------
# formation.thin_lens_image_distance (§2.8.1)
# --------------------------------------------------------------------------------------------
@mistake("sign error: 1/d_I = 1/d_S + 1/f", "The thin lens equation is 1/d_S + 1/d_I = 1/f, so 1/d_I = 1/f − 1/d_S")
def _tl_plus(object_distance, focal_length):
    d = np.asarray(object_distance, dtype=np.float64)
    with np.errstate(all="ignore"):
        out = focal_length * d / (d + focal_length)
    return np.where(np.isinf(d), float(focal_length), out)


@mistake("returned 1/d_I instead of d_I", "After computing 1/f − 1/d_S take its reciprocal to get the distance d_I")
def _tl_reciprocal(object_distance, focal_length):
    d = np.asarray(object_distance, dtype=np.float64)
    return 1.0 / focal_length - 1.0 / d


@mistake("object at infinity gives NaN",
         "f·d_S/(d_S − f) is inf/inf at d_S = inf: use 1/(1/f − 1/d_S) (1/inf = 0) or handle it")
def _tl_infinity_nan(object_distance, focal_length):
    d = np.asarray(object_distance, dtype=np.float64)
    with np.errstate(all="ignore"):
        return np.where(d == focal_length, np.inf, focal_length * d / (d - focal_length))


@mistake("virtual images made positive", "For d_S < f the image distance is negative (a virtual image): keep the sign")
def _tl_abs(object_distance, focal_length):
    return np.abs(_thin_lens(object_distance, focal_length))


def _tl_hidden(rng):
    f = _u(rng, 10, 200, 1)

    def far(n):
        return np.round(f * rng.uniform(1.05, 200.0, n), 2)

    def near(n):
        return np.round(f * rng.uniform(0.05, 0.95, n), 2)

    mixed = np.concatenate([far(4), near(3), [f, np.inf]])
    rng.shuffle(mixed)
    return [
        Case((far(_size(rng, 5, 10)), f), {}, "objects beyond the focal length (real images)"),
        Case((near(_size(rng, 4, 8)), f), {}, "objects inside the focal length (virtual images, negative)"),
        Case((mixed, f), {}, "mixed, with d_S = f and d_S = inf"),
        Case((np.inf, f), {}, "a single object at infinity (scalar): d_I = f"),
        Case((f, f), {}, "object at the focal distance (scalar): d_I = inf"),
        Case((float(far(1)[0]), f), {}, "a single object (scalar)"),
        Case((np.round(rng.uniform(1.2, 40.0, (_size(rng, 2, 4), _size(rng, 3, 5))), 3), 1.0), {},
             "2-D array of distances, f = 1"),
        Case((rng.integers(60, 5000, _size(rng, 4, 8)), int(rng.integers(20, 55))), {},
             "integer distances and focal length"),
        Case((np.round(rng.uniform(1e5, 1e7, 5), 0), 0.05), {}, "very far objects, tiny f (d_I ≈ f)"),
    ]


thin_lens_image_distance = Check(
    public=[
        Case((np.array([np.inf, 150.0, 100.0, 75.0, 50.0, 40.0, 25.0]), 50.0), {},
             "d_S from infinity to inside the focal length, f = 50"),
        Case((3000.0, 35.0), {}, "a scalar distance, f = 35"),
    ],
    hidden=_tl_hidden,
    compare=_FORMULA,
    mistakes=[_tl_plus, _tl_reciprocal, _tl_infinity_nan, _tl_abs],
)


# --------------------------------------------------------------------------------------------
# formation.blur_circle_diameter (§2.8–2.9)
# --------------------------------------------------------------------------------------------
def _bc_broadcast(*values):
    return np.broadcast_arrays(*[np.asarray(v, dtype=np.float64) for v in values])


@mistake("infinite distances not handled (NaN)",
         "At d_O = inf or d_F = inf the formula is inf/inf: use its limits D·f/(d_F − f) and D·f/d_O")
def _bc_naive(object_distance, focus_distance, focal_length, aperture_diameter):
    o, fd, f, a = _bc_broadcast(object_distance, focus_distance, focal_length, aperture_diameter)
    with np.errstate(all="ignore"):
        return a * f * np.abs(o - fd) / (o * (fd - f))


@mistake("absolute value missing",
         "Points nearer and farther than the focus both blur: c = D·f·|d_O − d_F| / (d_O·(d_F − f)) ≥ 0")
def _bc_no_abs(object_distance, focus_distance, focal_length, aperture_diameter):
    o, fd, f, a = _bc_broadcast(object_distance, focus_distance, focal_length, aperture_diameter)
    sign = np.sign(o - fd)
    return sign * _blur(o, fd, f, a)


@mistake("object and focus distances swapped",
         "d_O is the point's distance (in the denominator), d_F the distance the lens is focused on")
def _bc_swapped(object_distance, focus_distance, focal_length, aperture_diameter):
    return _blur(focus_distance, object_distance, focal_length, aperture_diameter)


@mistake("(d_F − f) replaced by d_F", "The sensor sits at d_I(d_F) = f·d_F/(d_F − f): keep the (d_F − f) factor")
def _bc_no_minus_f(object_distance, focus_distance, focal_length, aperture_diameter):
    o, fd, f, a = _bc_broadcast(object_distance, focus_distance, focal_length, aperture_diameter)
    return _blur(o, fd, f, a) * np.where(np.isinf(fd), 1.0, (fd - f) / np.where(np.isinf(fd), 1.0, fd))


@mistake("radius instead of diameter",
         "The cone has diameter D at the lens, so the blur circle's diameter is D·|Δd_I|/d_I (not half)")
def _bc_radius(object_distance, focus_distance, focal_length, aperture_diameter):
    return 0.5 * np.asarray(_blur(object_distance, focus_distance, focal_length, aperture_diameter))


def _bc_hidden(rng):
    f = _u(rng, 15, 100, 1)
    aperture = float(np.round(f / rng.choice([1.4, 2.0, 2.8, 4.0, 5.6, 8.0]), 3))

    def dist(n, lo=1.5, hi=100.0):
        return np.round(f * rng.uniform(lo, hi, n), 1)

    focus = float(dist(1, 5, 60)[0])
    with_inf = np.concatenate([dist(4), [focus, np.inf]])
    rng.shuffle(with_inf)
    return [
        Case((dist(_size(rng, 5, 9)), focus, f, aperture), {}, "object distances around the focus"),
        Case((with_inf, focus, f, aperture), {}, "an object in focus and one at infinity"),
        Case((dist(_size(rng, 4, 7)), np.inf, f, aperture), {}, "focused at infinity"),
        Case((np.inf, np.inf, f, aperture), {}, "object and focus at infinity (in focus: 0)"),
        Case((float(dist(1)[0]), focus, f, np.round(f / np.array([1.4, 2.0, 2.8, 4.0, 5.6, 8.0, 16.0]), 3)), {},
             "one object, apertures from f/1.4 to f/16 (c ∝ D)"),
        Case((float(dist(1)[0]), dist(_size(rng, 3, 6), 2, 30), f, aperture), {}, "focus distances as an array"),
        Case((dist(3)[:, None], dist(4)[None, :], f, aperture), {}, "broadcast (3, 1) objects × (1, 4) focus"),
        Case((dist(_size(rng, 3, 6)), focus, f, 0.0), {}, "aperture 0 (a pinhole: everything sharp)"),
        Case((rng.integers(200, 20000, _size(rng, 4, 7)), int(rng.integers(1000, 9000)), 50, 25), {},
             "integer arguments"),
        Case((np.round(rng.uniform(1.001, 1.2, 5), 4), 1.5, 1.0, 0.5), {},
             "objects just beyond the focal length (large blur)"),
    ]


blur_circle_diameter = Check(
    public=[
        Case((np.array([1000.0, 1500.0, 2000.0, 3000.0, 4000.0, np.inf]), 2000.0, 50.0, 25.0), {},
             "50 mm lens at f/2 focused at 2 m; objects from 1 m to infinity"),
        Case((5000.0, np.array([1000.0, 3000.0, np.inf]), 35.0, np.array([17.5, 8.75, 4.375])), {},
             "one object; focus and aperture as arrays"),
    ],
    hidden=_bc_hidden,
    compare=_FORMULA,
    mistakes=[_bc_no_abs, _bc_swapped, _bc_no_minus_f, _bc_radius, _bc_naive],
)


# --------------------------------------------------------------------------------------------
# formation.quantize (§2.11)
# --------------------------------------------------------------------------------------------
@mistake("step vmax/2**bits (divide by 2**bits − 1)",
         "With 2**bits levels from 0 to vmax there are 2**bits − 1 steps: step = vmax/(2**bits − 1)")
def _q_power_of_two(image, bits, vmax=1.0):
    x = np.clip(np.asarray(image, dtype=np.float64), 0.0, vmax)
    return np.round(x * 2.0 ** bits / vmax) * vmax / 2.0 ** bits


@mistake("truncated (floor) instead of rounded", "Round to the NEAREST level: np.round(x·L/vmax), not np.floor")
def _q_floor(image, bits, vmax=1.0):
    levels = 2.0 ** bits - 1
    x = np.clip(np.asarray(image, dtype=np.float64), 0.0, vmax)
    return np.floor(x * levels / vmax) * vmax / levels


@mistake("not clipped to [0, vmax]",
         "Clip first (np.clip(x, 0, vmax)): a converter cannot output levels beyond its range")
def _q_not_clipped(image, bits, vmax=1.0):
    levels = 2.0 ** bits - 1
    return np.round(np.asarray(image, dtype=np.float64) * levels / vmax) * vmax / levels


@mistake("returned the level index k, not its value",
         "Return the level's value k·vmax/(2**bits − 1) in the input's units, not the integer k")
def _q_codes(image, bits, vmax=1.0):
    levels = 2.0 ** bits - 1
    return np.round(np.clip(np.asarray(image, dtype=np.float64), 0.0, vmax) * levels / vmax)


@mistake("vmax ignored", "Scale by vmax: levels k·vmax/(2**bits − 1), clip to [0, vmax]")
def _q_no_vmax(image, bits, vmax=1.0):
    return _quantize(image, bits, 1.0)


@mistake("halves rounded up, not as np.round",
         "Use np.round (half-way values go to the even level): floor(t + 0.5) rounds 0.5 up")
def _q_half_up(image, bits, vmax=1.0):
    levels = 2.0 ** bits - 1
    x = np.clip(np.asarray(image, dtype=np.float64), 0.0, vmax)
    return np.floor(x * levels / vmax + 0.5) * vmax / levels


def _away_from_half(values, bits, vmax):
    """Nudge values that are within 1e-6 of a step of a half-way point between two levels (the
    order of the arithmetic could round them either way)."""
    levels = 2.0 ** bits - 1
    t = values * levels / vmax
    frac = t - np.floor(t)
    close_to_half = np.abs(frac - 0.5) < 1e-6
    return np.where(close_to_half, values + 0.25 * vmax / levels, values)


def _q_image(rng, shape, bits, vmax, lo=-0.1, hi=1.1, decimals=4):
    values = np.round(rng.uniform(lo * vmax, hi * vmax, shape), decimals)
    return _away_from_half(values, bits, vmax)


def _q_hidden(rng):
    def b(lo, hi):
        return _size(rng, lo, hi)

    bits_a, bits_b, bits_c = b(2, 4), b(3, 6), b(10, 16)
    halves = np.array([[0.0, 0.5, 1.0, 0.25], [0.75, 0.5, -0.5, 2.0]]) * float(rng.choice([1.0, 4.0, 255.0]))
    return [
        Case((_q_image(rng, (_size(rng, 4, 8), _size(rng, 5, 9)), bits_a, 1.0), bits_a), {},
             f"values in [-0.1, 1.1], {bits_a} bits, default vmax"),
        Case((_q_image(rng, (_size(rng, 4, 8), _size(rng, 5, 9)), bits_b, 1.0), bits_b), {"vmax": 1.0},
             f"{bits_b} bits, vmax given"),
        Case((rng.integers(0, 256, (_size(rng, 4, 7), _size(rng, 5, 8)), dtype=np.uint8), 8), {"vmax": 255.0},
             "uint8 image, 8 bits, vmax 255 (unchanged)"),
        Case((rng.integers(0, 256, (_size(rng, 4, 7), _size(rng, 5, 8)), dtype=np.uint8), b(1, 4)), {"vmax": 255},
             "uint8 image to fewer bits"),
        Case((_q_image(rng, (_size(rng, 3, 6), _size(rng, 4, 7), 3), 3, 1.0), 3), {},
             "colour image, 3 bits"),
        Case((_q_image(rng, (_size(rng, 4, 7), _size(rng, 5, 8)), bits_c, 4095.0, 0.0, 1.05, 2), bits_c),
             {"vmax": 4095.0}, f"12-bit range (vmax 4095), {bits_c} bits"),
        Case((halves, 1), {"vmax": float(np.abs(halves).max() / 2)}, "1 bit with values exactly half-way"),
        Case((_q_image(rng, _size(rng, 12, 30), 2, 2.5, -0.3, 1.3), 2), {"vmax": 2.5},
             "1-D ramp-like values, 2 bits, vmax 2.5"),
        Case((np.full((_size(rng, 3, 5), _size(rng, 3, 5)), _u(rng, 0.3, 0.7)), 1), {},
             "constant image, 1 bit"),
        Case((_q_image(rng, (3, 4), 5, 1.0, -5.0, 5.0), 5), {}, "values far outside [0, vmax]"),
    ]


quantize = Check(
    rules=("integer", "uint8"),
    public=[
        Case((np.array([[-0.2, 0.0, 0.1, 0.2, 0.3], [0.45, 0.6, 0.9, 1.0, 1.4]]), 2), {},
             "2 bits (levels 0, 1/3, 2/3, 1), values outside [0, 1] too"),
        Case((np.array([0.0, 0.25, 0.5, 0.75, 1.0, 1.5]), 1), {}, "1 bit: levels 0 and 1; 0.5 is half-way"),
        Case((np.array([[0, 17, 100, 128, 200, 255]], dtype=np.uint8), 3), {"vmax": 255.0},
             "uint8 image, 3 bits, vmax 255"),
    ],
    hidden=_q_hidden,
    compare=close(rtol=1e-10, atol=1e-12, kind="f", scaled=True),
    mistakes=[_q_power_of_two, _q_floor, _q_not_clipped, _q_codes, _q_no_vmax, _q_half_up],
)


# --------------------------------------------------------------------------------------------
# formation.image_memory_bits (§2.11)
# --------------------------------------------------------------------------------------------
@mistake("bytes instead of bits (divided by 8)", "B = N·M·m counts bits; do not divide by 8")
def _mb_bytes(width, height, bits_per_pixel):
    return width * height * bits_per_pixel // 8


@mistake("2**m levels used instead of m bits",
         "m bits per pixel encode 2**m levels, but each pixel costs m bits: B = N·M·m")
def _mb_levels(width, height, bits_per_pixel):
    return width * height * 2 ** bits_per_pixel


@mistake("bits per pixel forgotten", "Multiply the number of pixels N·M by the bits per pixel m")
def _mb_pixels(width, height, bits_per_pixel):
    return width * height


def _mb_hidden(rng):
    def side(lo, hi):
        return _size(rng, lo, hi)

    return [
        Case((side(100, 4000), side(100, 3000), 8), {}, "grayscale, 8 bits"),
        Case((side(100, 4000), side(100, 3000), 24), {}, "RGB, 24 bits"),
        Case((side(10, 2000), side(10, 2000), int(rng.choice([10, 12, 14, 16]))), {}, "raw sensor depth"),
        Case((side(2, 50), side(2, 50), 1), {}, "binary image, 1 bit"),
        Case((1, 1, side(1, 64)), {}, "a single pixel"),
        Case((7680, 4320, 48), {}, "8K, 16 bits per RGB channel"),
        Case((np.int64(side(100, 999)), np.int64(side(100, 999)), np.int64(32)), {}, "NumPy integers"),
        Case((side(1, 20), side(500, 5000), int(rng.choice([3, 5, 7]))), {}, "a thin strip, odd bits per pixel"),
    ]


image_memory_bits = Check(
    public=[
        Case((640, 480, 8), {}, "VGA grayscale"),
        Case((1920, 1080, 24), {}, "full HD RGB"),
        Case((3, 5, 2), {}, "3 × 5 pixels, 2 bits"),
    ],
    hidden=_mb_hidden,
    compare=close(rtol=0.0, atol=0.0, kind="iu"),
    mistakes=[_mb_bytes, _mb_levels, _mb_pixels],
)


# --------------------------------------------------------------------------------------------
# formation.snr_db (§2.14)
# --------------------------------------------------------------------------------------------
def _snr_generic(frames, *, factor=20.0, ddof=0, invert=False, zero_nan=True, log=np.log10):
    stack = np.asarray(frames, dtype=np.float64)
    mean = stack.mean(axis=0)
    std = stack.std(axis=0, ddof=ddof)
    std[np.all(stack == stack[0], axis=0)] = 0.0
    with np.errstate(all="ignore"):
        ratio = std / mean if invert else mean / std
        out = factor * log(ratio)
    if zero_nan:
        out = np.where(mean > 0, out, np.nan)
    else:
        out = np.where(mean < 0, np.nan, out)
    return out


@mistake("statistics over the wrong axis", "frames is (T, H, W): take the mean and std over axis 0 (time), per pixel")
def _snr_axis(frames):
    stack = np.asarray(frames, dtype=np.float64)
    with np.errstate(all="ignore"):
        return 20.0 * np.log10(stack.mean(axis=-1) / stack.std(axis=-1))


def _frames(rng, t, h, w, *, signal=(0.2, 0.9), noise=(0.005, 0.05), channels=None):
    shape = (h, w) if channels is None else (h, w, channels)
    scene = rng.uniform(*signal, shape)
    sigma = rng.uniform(*noise, shape)
    return scene + sigma * rng.standard_normal((t,) + shape)


def _snr_hidden(rng):
    special = _frames(rng, _size(rng, 3, 6), _size(rng, 3, 5), _size(rng, 4, 7))
    t = special.shape[0]
    special[:, 0, 0] = 0.75                                        # constant: inf
    zero_mean = [-1.0, 2.0, -1.0] if t % 2 else []                # exactly zero mean for any T
    special[:, 0, 1] = zero_mean + [-0.5, 0.5] * ((t - len(zero_mean)) // 2)  # mean 0: nan
    special[:, 1, 0] -= 2.0                                        # negative mean: nan
    uint8 = np.clip(np.round(rng.uniform(40, 220, (1, 4, 6)) + rng.normal(0, 6, (_size(rng, 4, 8), 4, 6))), 0, 255)
    uint8 = uint8.astype(np.uint8)
    uint8[:, 0, 0] = 128
    return [
        Case((_frames(rng, _size(rng, 4, 8), _size(rng, 4, 8), _size(rng, 5, 9)),), {}, "noisy frames of a static scene"),
        Case((_frames(rng, 2, _size(rng, 3, 6), _size(rng, 4, 8)),), {}, "only two frames (T = 2)"),
        Case((special,), {}, "a constant pixel (inf), zero and negative means (NaN)"),
        Case((uint8,), {}, "uint8 frames"),
        Case((_frames(rng, _size(rng, 3, 5), _size(rng, 3, 5), _size(rng, 3, 6), channels=3),), {}, "colour frames"),
        Case((_frames(rng, _size(rng, 5, 9), 1, _size(rng, 6, 12), signal=(500, 3000), noise=(5, 40)),), {},
             "one row, 12-bit-like values"),
        Case((_frames(rng, _size(rng, 3, 6), _size(rng, 3, 5), _size(rng, 3, 5), noise=(0.1, 0.5)),), {},
             "very noisy frames (low SNR)"),
        Case((np.full((_size(rng, 2, 5), 3, 4), 0.25),), {}, "identical frames: infinite SNR everywhere"),
        Case((_frames(rng, _size(rng, 20, 40), 2, 3),), {}, "many frames"),
    ]


snr_db = Check(
    public=[
        Case((np.array([[[0.5, 0.25, 0.0, -1.0, 0.75]], [[0.5, 0.35, 0.2, -1.5, 0.7]],
                        [[0.5, 0.3, -0.2, -0.5, 0.8]], [[0.5, 0.2, 0.0, -1.0, 0.65]]]),), {},
             "4 frames of 1×5: a constant pixel, a zero mean, a negative mean"),
        Case((np.array([[[100, 101], [50, 60]], [[102, 99], [52, 40]], [[98, 100], [51, 50]]], dtype=np.uint8),),
             {}, "3 uint8 frames of 2×2"),
    ],
    hidden=_snr_hidden,
    compare=close(rtol=1e-8, atol=1e-9, kind="f"),
    mistakes=[
        Mistake("10·log10 (a power ratio) instead of 20·log10", lambda frames: _snr_generic(frames, factor=10.0),
                "μ/σ is an amplitude ratio: SNR = 20·log10(μ/σ) dB"),
        Mistake("standard deviation with ddof=1", lambda frames: _snr_generic(frames, ddof=1),
                "Use the population standard deviation, np.std(frames, axis=0) (ddof=0)"),
        Mistake("ratio inverted (σ/μ)", lambda frames: _snr_generic(frames, invert=True),
                "Signal over noise: 20·log10(mean / std)"),
        Mistake("natural logarithm", lambda frames: _snr_generic(frames, log=np.log),
                "Decibels use log10: 20·log10(μ/σ)"),
        Mistake("mean ≤ 0 not marked NaN", lambda frames: _snr_generic(frames, zero_nan=False),
                "Return NaN wherever the mean is ≤ 0 (a zero mean gives −inf otherwise)"),
        _snr_axis,
    ],
)


# --------------------------------------------------------------------------------------------
# formation.dynamic_range_db (§2.15)
# --------------------------------------------------------------------------------------------
def _dr(e_max, e_min, factor=20.0, log=np.log10, invert=False):
    hi = np.asarray(e_max, dtype=np.float64)
    lo = np.asarray(e_min, dtype=np.float64)
    return factor * log(lo / hi if invert else hi / lo)


def _dr_hidden(rng):
    return [
        Case((_u(rng, 1e3, 1e5, 1), _u(rng, 0.5, 20)), {}, "scalars"),
        Case((np.round(rng.uniform(100, 1e5, _size(rng, 3, 7)), 1), _u(rng, 0.5, 5, 2)), {},
             "array of e_max, scalar e_min"),
        Case((np.round(rng.uniform(100, 1e5, (2, 3)), 1), np.round(rng.uniform(0.5, 5, (2, 3)), 2)), {},
             "two arrays of the same shape"),
        Case((np.round(rng.uniform(100, 1e5, (3, 1)), 1), np.round(rng.uniform(0.5, 5, (1, 4)), 2)), {},
             "broadcast (3, 1) × (1, 4)"),
        Case((int(rng.integers(2 ** 10, 2 ** 16)), int(rng.integers(1, 8))), {}, "integers"),
        Case((float(rng.uniform(0.5, 2.0)), float(rng.uniform(3.0, 9.0))), {}, "e_max < e_min (negative dB)"),
        Case((np.array([255.0, 1023.0, 4095.0, 65535.0]), 1.0), {}, "the ranges of 8-, 10-, 12-, 16-bit converters"),
        Case((1e6 * float(rng.uniform(1, 9)), 1e-3 * float(rng.uniform(1, 9))), {}, "a huge range (HDR)"),
        Case((np.round(rng.uniform(1e-6, 1e-3, 4), 9), np.round(rng.uniform(1e-9, 1e-7, 4), 12)), {},
             "tiny values (units of lux·s)"),
    ]


dynamic_range_db = Check(
    public=[
        Case((1000.0, 1.0), {}, "E_max = 1000 E_min: 60 dB"),
        Case((np.array([255.0, 4095.0, 30000.0]), np.array([1.0, 1.0, 3.0])), {}, "arrays"),
    ],
    hidden=_dr_hidden,
    compare=_FORMULA,
    mistakes=[
        Mistake("10·log10 instead of 20·log10", lambda e_max, e_min: _dr(e_max, e_min, factor=10.0),
                "E_max/E_min is an amplitude ratio: DR = 20·log10(E_max/E_min) dB"),
        Mistake("ratio inverted", lambda e_max, e_min: _dr(e_max, e_min, invert=True),
                "DR = 20·log10(E_max / E_min): the saturation level over the smallest detectable level"),
        Mistake("natural logarithm", lambda e_max, e_min: _dr(e_max, e_min, log=np.log), "Decibels use log10"),
        Mistake("in bits (log2), not in dB", lambda e_max, e_min: _dr(e_max, e_min, factor=1.0, log=np.log2),
                "The function returns decibels: 20·log10(E_max/E_min) (log2 would give bits)"),
    ],
)


# --------------------------------------------------------------------------------------------
# formation.bayer_mosaic (§2.13)
# --------------------------------------------------------------------------------------------
_SHIFTED = {"RGGB": "GRBG", "GRBG": "RGGB", "BGGR": "GBRG", "GBRG": "BGGR"}  # one column off


@mistake("pattern phase one column off",
         "Pixel (row i, col j) takes pattern[2·(i % 2) + (j % 2)]; the block starts at (0, 0)")
def _bm_shifted(rgb, pattern="RGGB"):
    return _bayer_mosaic(rgb, _SHIFTED[pattern])


@mistake("red and blue swapped (BGR order, or pattern read by columns)",
         "rgb[..., 0] is red and rgb[..., 2] blue; the pattern lists the 2×2 block row by row "
         "('GRBG' is G R on row 0, B G on row 1)")
def _bm_bgr(rgb, pattern="RGGB"):
    return _bayer_mosaic(np.asarray(rgb)[..., ::-1], pattern)


@mistake("pattern argument ignored (always RGGB)", "Use the `pattern` argument: RGGB, BGGR, GRBG or GBRG")
def _bm_ignored(rgb, pattern="RGGB"):
    return _bayer_mosaic(rgb, "RGGB")


def _rgb(rng, h, w, kind="unit"):
    if kind == "uint8":
        return rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    if kind == "big":
        return rng.uniform(-1e6, 1e6, (h, w, 3))
    return _r3(rng.random((h, w, 3)))


def _patterns(rng):
    """The four patterns in a random order, so every seed uses each of them."""
    return [str(p) for p in rng.permutation(PATTERNS)]


def _each_pattern(rng, make, rows, cols, odd, what, default_size=None):
    """Two random orders ``(p, q)`` of the four patterns, and five cases: ``p``'s patterns on
    ``make(rng, h, w[, kind])`` images of ``rows`` × ``cols`` (drawn ranges), the third by
    keyword, the fourth on a uint8 image of the odd size ``odd``; then the default pattern (on
    ``default_size`` ranges, ``(rows, cols)`` if None). The caller adds cases with ``q``."""
    p = _patterns(rng)
    q = _patterns(rng)

    def drawn(size=(rows, cols)):
        return make(rng, _size(rng, *size[0]), _size(rng, *size[1]))

    return q, [
        Case((drawn(), p[0]), {}, f"pattern {p[0]}"),
        Case((drawn(), p[1]), {}, f"pattern {p[1]}"),
        Case((drawn(),), {"pattern": p[2]}, f"pattern {p[2]} by keyword"),
        Case((make(rng, *odd, "uint8"), p[3]), {}, f"uint8 {what}, odd size {odd[0]}×{odd[1]}, {p[3]}"),
        Case((drawn(default_size or (rows, cols)),), {}, "default pattern (RGGB)"),
    ]


def _mosaic_hidden(rng):
    q, cases = _each_pattern(rng, _rgb, (4, 8), (5, 9), (5, 7), "image")
    return cases + [
        Case((_rgb(rng, 1, _size(rng, 5, 9)), q[0]), {}, f"a single row, {q[0]}"),
        Case((_rgb(rng, _size(rng, 5, 9), 1), q[1]), {}, f"a single column, {q[1]}"),
        Case((_rgb(rng, 2, 2), q[2]), {}, f"one Bayer block, {q[2]}"),
        Case((_rgb(rng, _size(rng, 6, 10), _size(rng, 3, 5), "big"), q[3]), {}, f"±1e6 values, tall image, {q[3]}"),
    ]


bayer_mosaic = Check(
    public=[
        Case((_distinct((4, 6, 3), seed=5),), {}, "4×6 image, default pattern RGGB"),
        Case((_distinct((5, 7, 3), seed=6), "GRBG"), {}, "odd size 5×7, GRBG"),
        Case((_distinct((3, 4, 3), seed=7, dtype=np.uint8), "BGGR"), {}, "uint8 image, BGGR"),
    ],
    hidden=_mosaic_hidden,
    compare=_VALUES,
    mistakes=[
        # first: on GRBG and BGGR its output is also that of the phase and BGR mistakes
        _bm_ignored,
        _bm_shifted,
        # reading 'GRBG' by columns gives 'GBRG': the same output as swapping red and blue
        _bm_bgr,
    ],
)


# --------------------------------------------------------------------------------------------
# formation.demosaic_bilinear (§2.13)
# --------------------------------------------------------------------------------------------
_K_RB = np.array([[0.25, 0.5, 0.25], [0.5, 1.0, 0.5], [0.25, 0.5, 0.25]])
_K_G = np.array([[0.0, 0.25, 0.0], [0.25, 1.0, 0.25], [0.0, 0.25, 0.0]])


def _demosaic_variant(raw, pattern="RGGB", *, pad_mode="reflect", box=False):
    """Masked-plane demosaicking with knobs: border mode of the raw image, or a plain 3×3
    mean of each masked plane (zeros of the other colours included)."""
    img = np.asarray(raw, dtype=np.float64)
    h, w = img.shape
    padded = np.pad(img, 1, mode=pad_mode) if pad_mode != "zero" else np.pad(img, 1)
    sites = channel_map(pattern, h + 2, w + 2, offset=-1)
    out = np.empty((h, w, 3))
    for channel in range(3):
        plane = np.where(sites == channel, padded, 0.0)
        kernel = np.full((3, 3), 1.0 / 9.0) if box else (_K_G if channel == 1 else _K_RB)
        acc = sum(kernel[m, n] * plane[m: m + h, n: n + w] for m in range(3) for n in range(3))
        if not box:
            measured = sites[1:-1, 1:-1] == channel
            acc[measured] = img[measured]
        out[:, :, channel] = acc
    return out


@mistake("nearest neighbour (copied from the 2×2 block)",
         "Bilinear: each missing sample is the MEAN of its nearest same-colour neighbours, not a copy of one")
def _dm_nearest(raw, pattern="RGGB"):
    """Each missing sample copied from the 2×2 block the pixel belongs to (G from its row)."""
    img = np.asarray(raw, dtype=np.float64)
    h, w = img.shape
    padded = np.pad(img, ((0, 1), (0, 1)), mode="reflect")
    sites = channel_map(pattern, h + 1, w + 1)
    out = np.empty((h, w, 3))
    rows, cols = np.mgrid[0:h, 0:w]
    top, left = rows - rows % 2, cols - cols % 2
    for channel in range(3):
        value = np.zeros((h, w))
        found = np.zeros((h, w), dtype=bool)
        for di, dj in ((rows - top, 0), (rows - top, 1), (1 - (rows - top), 0), (1 - (rows - top), 1)):
            i, j = top + di, left + dj
            hit = ~found & (sites[i, j] == channel)
            value[hit] = padded[i, j][hit]
            found |= hit
        out[:, :, channel] = value
    return out


@mistake("pattern phase one column off",
         "Site (i, j) has colour pattern[2·(i % 2) + (j % 2)]: check which pixels hold R, G and B")
def _dm_shifted(raw, pattern="RGGB"):
    return _demosaic(raw, _SHIFTED[pattern])


@mistake("output channels in BGR order", "Return R, G, B in channels 0, 1, 2")
def _dm_bgr(raw, pattern="RGGB"):
    return _demosaic(raw, pattern)[..., ::-1]


def _raw(rng, h, w, kind="unit"):
    if kind == "uint8":
        return rng.integers(0, 256, (h, w), dtype=np.uint8)
    if kind == "uint16":
        return rng.integers(0, 4096, (h, w), dtype=np.uint16)
    if kind == "big":
        return rng.uniform(-1e6, 1e6, (h, w))
    if kind == "smooth":  # a smooth colour scene: where bilinear interpolation is nearly exact
        y, x = np.mgrid[0:h, 0:w]
        scene = np.stack([0.5 + 0.3 * np.sin(0.4 * x + c) * np.cos(0.3 * y) for c in (0.0, 1.0, 2.0)], axis=-1)
        return _bayer_mosaic(scene, "RGGB")
    return _r3(rng.random((h, w)))


def _demosaic_hidden(rng):
    q, cases = _each_pattern(rng, _raw, (5, 9), (6, 10), (7, 9), "raw image", default_size=((5, 8), (5, 8)))
    return cases + [
        Case((_raw(rng, 2, 2), q[0]), {}, f"one Bayer block (2×2), {q[0]}"),
        Case((_raw(rng, 2, _size(rng, 5, 9)), q[1]), {}, f"two rows, {q[1]}"),
        Case((_raw(rng, _size(rng, 5, 9), 3, "uint16"), q[2]), {}, f"uint16 raw, 3 columns, {q[2]}"),
        Case((_raw(rng, _size(rng, 6, 9), _size(rng, 6, 9), "big"), q[3]), {}, f"±1e6 values, {q[3]}"),
        Case((np.full((_size(rng, 4, 6), _size(rng, 4, 6)), _u(rng, 0, 1)),
              str(rng.choice(PATTERNS))), {}, "a constant raw image (grey)"),
        Case((_raw(rng, 10, 12, "smooth"), "RGGB"), {}, "a smooth colour scene"),
    ]


demosaic_bilinear = Check(
    rules=("integer",),
    public=[
        Case((np.random.default_rng(11).permutation(48).reshape(6, 8) / 47.0,), {},
             "6×8 raw image, default pattern RGGB"),
        Case((np.random.default_rng(12).permutation(35).reshape(5, 7).astype(np.float64), "GRBG"), {},
             "odd size 5×7, GRBG"),
        Case((np.random.default_rng(13).permutation(24).reshape(4, 6).astype(np.uint8) * 10, "GBRG"), {},
             "uint8 raw image, GBRG"),
    ],
    hidden=_demosaic_hidden,
    compare=_VALUES,
    mistakes=[
        _dm_shifted,
        Mistake("zero border instead of reflect101", lambda raw, pattern="RGGB": _demosaic_variant(raw, pattern, pad_mode="zero"),
                "Read outside the image by reflect101 (np.pad(..., mode='reflect')): it keeps the colour of each site"),
        Mistake("replicate border (mixes colours at the edge)",
                lambda raw, pattern="RGGB": _demosaic_variant(raw, pattern, pad_mode="edge"),
                "Replicating the edge row puts the wrong colour outside the image: use reflect101"),
        Mistake("zeros of the other colours counted in the mean",
                lambda raw, pattern="RGGB": _demosaic_variant(raw, pattern, box=True),
                "Average only the sites that measured this colour: 4 (G), 2 or 4 (R, B) neighbours, not all 9 pixels"),
        _dm_nearest,
        _dm_bgr,
    ],
)
