"""Checks of Chapter 3's filters: the cases, comparators and mistake banks the grader uses.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference
function (``cvkit.filters.checks:gaussian`` grades ``filters.gaussian``). Each check has

- ``public`` cases: tiny fixed images (5×6, distinct values) with asymmetric kernels, shown to
  the students, that already tell every mistake of the bank from the right answer;
- ``hidden`` cases drawn from the grading seed: non-square, tiny (1×N, 2×3), constant,
  uint8 and ±1e6 images, colour, every border mode (and both output modes), σ ≠ 1, radius
  given and by default, ... and, for every mistake, inputs on which it is wrong;
- a comparator with tolerances loose enough for loop, vectorised or FFT versions;
- a bank of named mistakes, each a function computing the wrong variant (run under the
  reference provider) and a hint saying how to fix it.

Images stay small (≤ 40×40, ≤ 16×20 for median, bilateral and non-local means) so that a
student's loop version finishes in well under a second per case.
"""
from __future__ import annotations

import math
from functools import partial

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..grading import Case, Check, Comparator, Measure, Mismatch, Mistake, close, mistake
from ..grading.casekit import seed as _seed
from ..grading.measured import MeasuredCase, Scale
from ..grading.casekit import BORDERS, border_mistakes, border_zero, random_image, reflect_swapped, variant
from ..grading.casekit import distinct as _distinct
from ..grading.casekit import sigma as _sigma
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ._denoise import BUDGET_SECONDS, PSNR_GAP_SCALE, denoise_unregistered, noisy_crop
from ._denoise import psnr as denoise_psnr
from ._linear import convolve as _convolve
from ._linear import correlate as _correlate
from ._linear import gaussian as _gaussian
from ._linear import mean as _mean
from ._linear import temporal_mean as _temporal_mean
from ._nonlinear import bilateral as _bilateral
from ._nonlinear import median as _median
from ._nonlinear import nl_means as _nl_means
from ._padding import border_indices
from ._padding import pad as _pad

__all__ = [
    "pad", "correlate", "convolve", "mean_kernel", "mean", "gaussian_kernel", "gaussian",
    "median", "bilateral", "nl_means", "temporal_mean", "BORDERS", "denoise", "PsnrGap", "DENOISE_SCALE",
]

#: padding copies values: exact
_EXACT = close(rtol=0.0, atol=0.0, kind="f")
#: sums of products: loop, vectorised, FFT and integral-image versions agree to ~1e-12 of the
#: image's scale
_LINEAR = close(rtol=1e-7, atol=1e-10, kind="f", scaled=True)
#: selections and weighted means
_NONLINEAR = close(rtol=1e-7, atol=1e-10, kind="f", scaled=True)
#: the hint of a filter's "border ignored (always zero)" mistake (casekit.border_zero), and the
#: linear filters' one, which says how to pad
_BORDER_HINT = "Read outside the image through `border` (filters.pad), not with zeros"
_PAD_HINT = "Read outside the image through `border` (pad with filters.pad), not with zeros"


# --------------------------------------------------------------------------------------------
# case helpers
# --------------------------------------------------------------------------------------------
def _image(rng: np.random.Generator, h: int, w: int, kind: str = "unit", channels: int | None = None) -> np.ndarray:
    """A random image (:func:`~cvkit.grading.casekit.random_image`), or ``"step"``: a noisy vertical
    edge (what edge-preserving filters are for), or ``"impulses"``: flat grey with a few black and
    white pixels."""
    shape = (int(h), int(w)) if channels is None else (int(h), int(w), channels)
    if kind == "step":
        img = np.zeros(shape)
        img[:, shape[1] // 2:] = 1.0
        return img * 0.6 + 0.2 + rng.normal(0, 0.05, shape)
    if kind == "impulses":
        img = np.full(shape, 0.5) + rng.normal(0, 0.02, shape)
        mask = rng.random(shape[:2]) < 0.15
        img[mask] = rng.choice([0.0, 1.0], size=mask.sum())[(...,) + (None,) * (len(shape) - 2)]
        return img
    return random_image(rng, shape, kind)


def _kernel(rng: np.random.Generator, kh: int, kw: int) -> np.ndarray:
    """A random kernel with no symmetry (rounded to 3 decimals: readable in reports)."""
    k = np.round(rng.normal(0.0, 1.0, (kh, kw)), 3)
    k[0, 0] += 1.5  # never symmetric under flips or transposition
    return k


# --------------------------------------------------------------------------------------------
# helpers for the mistakes (they run under the reference provider)
# --------------------------------------------------------------------------------------------
def _correlate_at(image, kernel, anchor, border, output="same"):
    """Correlation with the kernel tap ``anchor`` on the output pixel (the reference uses
    ``(kh // 2, kw // 2)``)."""
    if output == "valid":  # the anchor only moves the window of "same" outputs
        return _correlate(image, kernel, border, "valid")
    img = np.asarray(image, dtype=np.float64)
    k = np.asarray(kernel, dtype=np.float64)
    kh, kw = k.shape
    a, b = anchor
    ry, rx = max(a, kh - 1 - a), max(b, kw - 1 - b)
    padded = _pad(img, (ry, rx), border)
    h, w = img.shape[:2]
    out = np.zeros(img.shape)
    for m in range(kh):
        for n in range(kw):
            out += k[m, n] * padded[ry - a + m: ry - a + m + h, rx - b + n: rx - b + n + w]
    return out


def _box_sum(values: np.ndarray, size: int) -> np.ndarray:
    """Sums over every ``size × size`` window of the first two axes ("valid")."""
    c = np.cumsum(np.cumsum(values, axis=0), axis=1)
    c = np.pad(c, ((1, 0), (1, 0)) + ((0, 0),) * (values.ndim - 2))
    return c[size:, size:] - c[:-size, size:] - c[size:, :-size] + c[:-size, :-size]


def _channels_last(img: np.ndarray) -> np.ndarray:
    return img[..., None] if img.ndim == 2 else img


# --------------------------------------------------------------------------------------------
# filters.pad (§3.7)
# --------------------------------------------------------------------------------------------
@mistake("(ry, rx) swapped", "`radius=(ry, rx)` adds ry rows above and below and rx columns left and right")
def _pad_radius_swapped(image, radius, border="reflect101"):
    if isinstance(radius, (tuple, list, np.ndarray)):
        radius = (radius[1], radius[0])
    return _pad(image, radius, border)


@mistake("channel axis padded too", "Pad only the two image axes of an (H, W, 3) image, never the channel axis")
def _pad_channels_too(image, radius, border="reflect101"):
    out = _pad(image, radius, border)
    if out.ndim == 3 and not isinstance(radius, (tuple, list, np.ndarray)):  # np.pad(image, r, ...)
        idx = border_indices(out.shape[2], int(radius), border)
        out = out[:, :, np.maximum(idx, 0)]
        out[:, :, idx < 0] = 0.0
    return out


def _pad_hidden(rng):
    return [
        Case((_image(rng, _size(rng, 6, 12), _size(rng, 7, 15)), _size(rng, 1, 3)), {"border": "zero"},
             "int radius, zero border"),
        Case((_image(rng, _size(rng, 6, 12), _size(rng, 7, 15)), (1, 3)), {"border": "replicate"},
             "radius (1, 3), replicate"),
        Case((_image(rng, _size(rng, 7, 12), _size(rng, 6, 10)), (3, 2)), {"border": "reflect"},
             "radius (3, 2), reflect"),
        Case((_image(rng, _size(rng, 6, 11), _size(rng, 8, 14)), (2, 4)), {"border": "reflect101"},
             "radius (2, 4), reflect101"),
        Case((_image(rng, _size(rng, 6, 9), _size(rng, 6, 9), "uint8"), 3), {"border": "reflect101"},
             "uint8 image (result float, not rescaled)"),
        Case((_image(rng, _size(rng, 5, 8), _size(rng, 5, 9), channels=3), 2), {"border": "reflect"},
             "colour image, int radius (the channel axis is not padded)"),
        Case((_image(rng, _size(rng, 5, 8), _size(rng, 5, 9), channels=3), (1, 2)), {"border": "reflect101"},
             "colour image, radius (1, 2)"),
        Case((_image(rng, _size(rng, 5, 8), _size(rng, 5, 9), "uint8", channels=3), 1), {"border": "zero"},
             "colour uint8 image, radius 1"),
        Case((_image(rng, _size(rng, 8, 12), _size(rng, 8, 12), "big"), (2, 0)), {"border": "replicate"},
             "±1e6 values, radius (2, 0)"),
        Case((_image(rng, 1, _size(rng, 6, 12)), (0, 2)), {"border": "reflect101"},
             "single row 1×N, radius (0, 2)"),
        Case((_image(rng, 2, 3, "normal"), 1), {"border": str(rng.choice(BORDERS[1:]))},
             "tiny 2×3 image, radius 1"),
        Case((_image(rng, _size(rng, 5, 9), _size(rng, 6, 9), "const"), (3, 2)), {"border": "zero"},
             "constant image, zero border"),
        Case((_image(rng, _size(rng, 4, 9), _size(rng, 4, 9), "normal"), 0), {"border": "reflect"},
             "radius 0 (a float copy)"),
    ]


pad = Check(
    public=[
        Case((_distinct((5, 6)), 2), {}, "5×6 image, radius 2, default border (reflect101)"),
        Case((_distinct((5, 6)), (1, 3)), {"border": "reflect"}, "radius (ry, rx) = (1, 3), reflect"),
        Case((_distinct((4, 5, 3)), 1), {"border": "replicate"}, "colour 4×5×3 image, radius 1, replicate"),
        Case((_distinct((3, 4)), (2, 1)), {"border": "zero"}, "radius (2, 1), zero border"),
    ],
    hidden=_pad_hidden,
    compare=_EXACT,
    mistakes=[
        reflect_swapped(_pad),
        _pad_radius_swapped,
        _pad_channels_too,
        border_zero(_pad, "Use the `border` argument: zero, replicate, reflect or reflect101 (§3.7)"),
    ],
    forbidden=("numpy.pad",),
)


# --------------------------------------------------------------------------------------------
# filters.correlate (§3.6)
# --------------------------------------------------------------------------------------------
@mistake("kernel flipped (that is convolution)",
         "Correlation does not flip the kernel: O(i,j) = Σ K(m,n)·I(i+m−kh//2, j+n−kw//2)")
def _corr_flipped(image, kernel, border="reflect101", output="same"):
    return _convolve(image, kernel, border, output)


@mistake("anchor at the top-left (output shifted)",
         "Centre the kernel on the output pixel: its tap (kh//2, kw//2) lies on (i, j)")
def _corr_top_left(image, kernel, border="reflect101", output="same"):
    return _correlate_at(image, kernel, (0, 0), border, output)


@mistake("even kernel anchored at (k−1)//2",
         "The anchor of an even kernel is (kh//2, kw//2): pad kh//2 rows above and kh−1−kh//2 below")
def _corr_even_anchor(image, kernel, border="reflect101", output="same"):
    kh, kw = np.shape(kernel)
    return _correlate_at(image, kernel, ((kh - 1) // 2, (kw - 1) // 2), border, output)


@mistake("kernel transposed",
         "In kernel[m, n], m runs down the rows (y) and n along the columns (x): do not transpose it")
def _corr_transposed(image, kernel, border="reflect101", output="same"):
    return _correlate(image, np.asarray(kernel).T, border, output)


def _linear_public(even_anchor):
    """Public cases shared by correlate and convolve; ``even_anchor`` where the even kernel's
    label says its anchor is."""
    return [
        Case((_distinct((5, 6)), np.array([[1.0, 2.0, 0.0], [0.0, 1.0, -1.0], [3.0, 0.0, 1.0]])), {},
             "5×6 image, asymmetric 3×3 kernel, default border (reflect101)"),
        Case((_distinct((6, 7)), np.array([[1.0, 2.0, 3.0, 4.0], [0.0, -1.0, 0.0, 2.0]])), {"border": "reflect"},
             f"even 2×4 kernel ({even_anchor}), reflect"),
        Case((_distinct((4, 5, 3)), np.array([[1.0, 0.0], [2.0, -1.0], [0.0, 3.0]])), {"border": "zero"},
             "colour image, 3×2 kernel, zero border"),
        Case((_distinct((5, 6)), np.array([[0.0, 1.0, 2.0], [1.0, 0.0, 0.0]])), {"output": "valid"},
             "output='valid' (shape 4×4)"),
    ]


def _linear_hidden(rng):
    """Cases shared by correlate and convolve (even kernels 4×4 and 2×4)."""
    img = partial(_image, rng)

    e1, e2 = (4, 4), (2, 4)
    return [
        Case((img(_size(rng, 8, 14), _size(rng, 9, 16)), _kernel(rng, 3, 5)), {"border": "zero"},
             "asymmetric 3×5 kernel, zero border"),
        Case((img(_size(rng, 8, 14), _size(rng, 8, 14)), _kernel(rng, 5, 3)), {"border": "replicate"},
             "asymmetric 5×3 kernel, replicate"),
        Case((img(_size(rng, 9, 15), _size(rng, 9, 15)), _kernel(rng, *e1)), {"border": "reflect"},
             f"even {e1[0]}×{e1[1]} kernel, reflect"),
        Case((img(_size(rng, 9, 15), _size(rng, 10, 16)), _kernel(rng, *e2)), {"border": "reflect101"},
             f"even {e2[0]}×{e2[1]} kernel, reflect101"),
        Case((img(_size(rng, 6, 9), _size(rng, 7, 10), channels=3), _kernel(rng, 3, 3)),
             {"border": str(rng.choice(BORDERS[1:]))}, "colour image, asymmetric 3×3 kernel"),
        Case((img(_size(rng, 9, 14), _size(rng, 9, 14), "uint8"), _kernel(rng, 3, 3)),
             {"border": "reflect101", "output": "valid"}, "uint8 image, output='valid'"),
        Case((img(_size(rng, 8, 12), _size(rng, 8, 12), channels=3), _kernel(rng, e1[1], e1[0])),
             {"border": "zero", "output": "valid"}, f"colour, even {e1[1]}×{e1[0]} kernel, output='valid'"),
        Case((img(1, _size(rng, 9, 16)), _kernel(rng, 1, 5)), {"border": str(rng.choice(BORDERS))},
             "single-row 1×N image, 1×5 kernel"),
        Case((img(2, 3, "normal"), _kernel(rng, 3, 3)), {"border": str(rng.choice(BORDERS[1:]))},
             "tiny 2×3 image, 3×3 kernel"),
        Case((img(_size(rng, 6, 9), _size(rng, 6, 9), "const"), _kernel(rng, 3, 4)), {"border": "zero"},
             "constant image, zero border"),
        Case((img(_size(rng, 25, 40), _size(rng, 25, 40), "big"), _kernel(rng, 5, 7)), {"border": "reflect"},
             "±1e6 values, 5×7 kernel"),
        Case((img(_size(rng, 7, 12), _size(rng, 7, 12)), np.array([[-1.0, 0.0, 1.0]]) * rng.uniform(0.5, 2)),
             {"border": "replicate"}, "1×3 derivative kernel [-1, 0, 1]"),
    ]


def _linear_check(even_anchor, mistakes) -> Check:
    """The check of correlate or convolve: the cases of :func:`_linear_public` (``even_anchor``
    as there) and :func:`_linear_hidden`, compared as linear filters, with the bank ``mistakes``."""
    return Check(public=_linear_public(even_anchor), hidden=_linear_hidden, compare=_LINEAR, mistakes=mistakes,
                 allowed=("filters.pad",))


correlate = _linear_check("anchor (1, 2)", [
    _corr_flipped,
    _corr_top_left,
    _corr_even_anchor,
    border_zero(_correlate, _PAD_HINT),
    _corr_transposed,
    reflect_swapped(_correlate),
])


# --------------------------------------------------------------------------------------------
# filters.convolve (§3.4–3.7)
# --------------------------------------------------------------------------------------------
@mistake("kernel not flipped (that is correlation)",
         "Convolution flips the kernel: O(i,j) = Σ K(m,n)·I(i−m+kh//2, j−n+kw//2)")
def _conv_not_flipped(image, kernel, border="reflect101", output="same"):
    return _correlate(image, kernel, border, output)


@mistake("kernel flipped up-down only", "Flip the kernel in both directions, K[::-1, ::-1] (a 180° rotation)")
def _conv_flip_rows_only(image, kernel, border="reflect101", output="same"):
    return _correlate(image, np.asarray(kernel)[::-1, :], border, output)


@mistake("kernel flipped left-right only", "Flip the kernel in both directions, K[::-1, ::-1] (a 180° rotation)")
def _conv_flip_cols_only(image, kernel, border="reflect101", output="same"):
    return _correlate(image, np.asarray(kernel)[:, ::-1], border, output)


@mistake("even kernel flipped without moving its anchor",
         "After flipping an even kernel its anchor moves to (kh−1−kh//2, kw−1−kw//2): "
         "O(i,j) = Σ K(m,n)·I(i−m+kh//2, j−n+kw//2)")
def _conv_anchor_not_moved(image, kernel, border="reflect101", output="same"):
    return _correlate(image, np.asarray(kernel)[::-1, ::-1], border, output)


@mistake("kernel origin at its top-left (output shifted)",
         "The kernel's origin is its centre (kh//2, kw//2): O(i,j) = Σ K(m,n)·I(i−(m−kh//2), j−(n−kw//2))")
def _conv_top_left(image, kernel, border="reflect101", output="same"):
    kh, kw = np.shape(kernel)
    return _correlate_at(image, np.asarray(kernel)[::-1, ::-1], (kh - 1, kw - 1), border, output)


convolve = _linear_check("as scipy.ndimage.convolve", [
    _conv_not_flipped,
    _conv_flip_rows_only,
    _conv_flip_cols_only,
    _conv_anchor_not_moved,
    _conv_top_left,
    *border_mistakes(_convolve, _PAD_HINT),
])


# --------------------------------------------------------------------------------------------
# filters.mean_kernel and filters.mean (§3.8)
# --------------------------------------------------------------------------------------------
@mistake("not normalised (all ones)", "Divide by the number of taps: every value is 1/size², so the kernel sums to 1")
def _mk_ones(size):
    return np.ones((size, size))


@mistake("divided by size instead of size²", "The window has size² pixels: every value is 1/size²")
def _mk_by_size(size):
    return np.ones((size, size)) / size


@mistake("integer division (all zeros)", "1 // size² is 0: use true division, np.ones((size, size)) / size**2")
def _mk_integer_division(size):
    return np.ones((size, size)) // (size * size)


@mistake("1-D kernel", "Return the square (size, size) kernel, every value 1/size²")
def _mk_one_dimensional(size):
    return np.ones(size) / size


mean_kernel = Check(
    public=[
        Case((3,), {}, "3×3 box kernel"),
        Case((4,), {}, "even size 4"),
        Case((1,), {}, "size 1"),
    ],
    hidden=lambda rng: [
        Case((1,), {}, "size 1"),
        Case((2,), {}, "size 2"),
        Case((_size(rng, 3, 5) * 2 - 1,), {}, "odd size"),
        Case((_size(rng, 3, 6) * 2,), {}, "even size"),
        Case((_size(rng, 5, 9),), {}, "size 5..9"),
        Case((np.int64(_size(rng, 3, 7)),), {}, "size given as numpy int64"),
        Case((_size(rng, 10, 18),), {}, "large size"),
        Case((_size(rng, 19, 31),), {}, "very large size"),
    ],
    compare=close(rtol=1e-12, atol=1e-15, kind="f"),
    mistakes=[_mk_ones, _mk_by_size, _mk_integer_division, _mk_one_dimensional],
)


@mistake("sum not divided (not normalised)", "Divide the window sum by the number of pixels, size²")
def _mean_not_divided(image, size, border="reflect101"):
    return _mean(image, size, border) * size ** 2


@mistake("divided by size instead of size²", "The window has size² pixels: O(p) = (1/size²)·Σ I(q)")
def _mean_by_size(image, size, border="reflect101"):
    return _mean(image, size, border) * size


def _size_as_radius(window_filter) -> Mistake:
    """The mistake "size used as radius" of a window filter (``filters.mean``,
    ``filters.median``): ``window_filter`` run with a window of side 2·size+1."""
    return Mistake("size used as radius (window 2·size+1)",
                   lambda image, size, border="reflect101": window_filter(image, 2 * size + 1, border),
                   "`size` is the side of the window; its radius is size // 2")


def _window_public():
    """The visible cases of a window filter (``filters.mean``, ``filters.median``)."""
    return [
        Case((_distinct((5, 6)), 3), {}, "5×6 image, 3×3 window, default border (reflect101)"),
        Case((_distinct((6, 7)), 3), {"border": "reflect"}, "3×3 window, reflect"),
        Case((_distinct((4, 5, 3), dtype=np.uint8), 3), {"border": "replicate"}, "colour uint8 image, replicate"),
    ]


def _window_edge_cases(rng, img, copy_border):
    """The awkward inputs of a window filter (``filters.mean``, ``filters.median``): a constant
    image, a 1×N and a 2×3 image with 3×3 windows, and a 1×1 window (a copy)."""
    return [
        Case((img(_size(rng, 6, 10), _size(rng, 6, 10), "const"), 3), {"border": "zero"},
             "constant image, zero border"),
        Case((img(1, _size(rng, 8, 15)), 3), {"border": str(rng.choice(BORDERS))}, "single-row 1×N image"),
        Case((img(2, 3, "normal"), 3), {"border": str(rng.choice(BORDERS[1:]))}, "tiny 2×3 image"),
        Case((img(_size(rng, 5, 9), _size(rng, 5, 9)), 1), {"border": copy_border}, "size 1 (a copy)"),
    ]


def _mean_hidden(rng):
    img = partial(_image, rng)

    return [
        Case((img(_size(rng, 8, 20), _size(rng, 9, 24)), 3), {"border": "zero"}, "3×3 window, zero border"),
        Case((img(_size(rng, 10, 20), _size(rng, 10, 20)), 5), {"border": "replicate"}, "5×5 window, replicate"),
        Case((img(_size(rng, 10, 20), _size(rng, 12, 24)), 3), {"border": "reflect"}, "3×3 window, reflect"),
        Case((img(_size(rng, 12, 25), _size(rng, 12, 25)), 7), {"border": "reflect101"}, "7×7 window, reflect101"),
        Case((img(_size(rng, 7, 12), _size(rng, 8, 14), channels=3), 3), {"border": str(rng.choice(BORDERS[1:]))},
             "colour image"),
        Case((img(_size(rng, 9, 16), _size(rng, 9, 16), "uint8"), 5), {"border": "reflect101"},
             "uint8 image (not rescaled)"),
        Case((img(_size(rng, 25, 40), _size(rng, 25, 40), "big"), 5), {"border": "reflect"}, "±1e6 values"),
        *_window_edge_cases(rng, img, "replicate"),
    ]


mean = Check(
    public=_window_public,
    hidden=_mean_hidden,
    compare=_LINEAR,
    mistakes=[
        _mean_not_divided,
        _mean_by_size,
        _size_as_radius(_mean),
        *border_mistakes(_mean, _PAD_HINT),
    ],
    allowed=("filters.pad", "filters.mean_kernel"),
)


# --------------------------------------------------------------------------------------------
# filters.gaussian_kernel and filters.gaussian (§3.9)
# --------------------------------------------------------------------------------------------
def _default_radius(sigma):
    return max(0, math.ceil(3.0 * sigma - 1e-9))


def _gk(sigma, radius=None, *, variance=False, continuous=False, rule=None, last_tap=True):
    """Sampled Gaussian with knobs for the mistakes."""
    if radius is None:
        radius = {None: _default_radius, "floor": lambda s: int(math.floor(3 * s)),
                  "round": lambda s: int(round(3 * s))}[rule](sigma)
    x = np.arange(-radius, radius + (1 if last_tap else 0), dtype=np.float64)
    g = np.exp(-x * x / (2.0 * sigma)) if variance else np.exp(-x * x / (2.0 * sigma * sigma))
    if continuous:
        return g / (sigma * math.sqrt(2 * math.pi))
    return g / g.sum()


_gkv = partial(variant, _gk)


def _gk_hidden(rng):
    cases = [
        Case((_sigma(rng, 0.2, 0.33, frac=(0.55, 0.99)),), {}, "small σ < 1/3 (radius 1)"),
        Case((2.0,), {}, "σ = 2 (radius 6)"),
        Case((_sigma(rng, 0.8, 4.0, frac=(0.1, 0.4)), None), {}, "radius=None given explicitly"),
        Case((_sigma(rng, 0.4, 3.0), _size(rng, 1, 4)), {}, "explicit small radius"),
        Case((_sigma(rng, 0.5, 1.5), _size(rng, 6, 9)), {}, "explicit radius larger than 3σ"),
        Case((_sigma(rng, 0.5, 2.0),), {"radius": 0}, "radius 0 (the kernel [1.0])"),
    ]
    for lo, hi, what in ((0.4, 0.9, "σ < 1"), (1.1, 2.0, "1 < σ < 2"), (2.0, 4.0, "σ > 2")):
        cases.append(Case((_sigma(rng, lo, hi, frac=(0.55, 0.9)),), {}, f"default radius, {what}"))
    cases.append(Case((_sigma(rng, 1.1, 3.0, frac=(0.1, 0.45)),), {}, "default radius, 3σ just above an integer"))
    cases.append(Case((_sigma(rng, 0.9, 3.0, frac=(0.6, 0.9)),), {}, "default radius, 3σ just below an integer"))
    return cases


gaussian_kernel = Check(
    public=[
        Case((1.4,), {}, "σ = 1.4 (3σ = 4.2: radius 5)"),
        Case((0.9,), {}, "σ = 0.9 (3σ = 2.7: radius 3)"),
        Case((0.6,), {}, "σ = 0.6 (3σ = 1.8: radius 2)"),
        Case((0.5,), {"radius": 4}, "σ = 0.5 with radius 4"),
        Case((2.0,), {}, "σ = 2 (radius 6)"),
    ],
    hidden=_gk_hidden,
    compare=close(rtol=1e-7, atol=1e-12, kind="f"),
    mistakes=[
        Mistake("σ used as variance", _gkv(variance=True), "The exponent is −x²/(2σ²): square σ"),
        Mistake("normalised by 1/(σ√2π) instead of the sum", _gkv(continuous=True),
                "The sampled, truncated kernel must sum to exactly 1: divide by its sum, not by σ√(2π)"),
        Mistake("radius round(3σ) instead of ceil", _gkv(rule="round"),
                "The default radius rounds 3σ up: r = ceil(3σ), length 2r+1"),
        Mistake("radius floor(3σ) instead of ceil", _gkv(rule="floor"),
                "The default radius rounds 3σ up: r = ceil(3σ) (int() rounds down)"),
        Mistake("radius argument ignored", lambda sigma, radius=None: _gk(sigma, None),
                "Use the given radius; only radius=None means ceil(3σ)"),
        Mistake("last tap missing (arange(−r, r))", _gkv(last_tap=False),
                "The offsets are −r..r inclusive: np.arange(-r, r + 1), 2r+1 taps"),
    ],
)


def _gauss_with(image, g, border, axes="both", twice=False):
    g = np.asarray(g, dtype=np.float64)
    row, col = g[None, :], g[:, None]
    if axes == "x":
        out = _correlate(image, row, border)
        return _correlate(out, row, border) if twice else out
    if axes == "y":
        return _correlate(image, col, border)
    return _correlate(_correlate(image, row, border), col, border)


def _g_variant(image, sigma, border="reflect101", *, axes="both", twice=False, variance=False, continuous=False,
               rule=None):
    """The Gaussian filter with knobs for the mistakes: the passes of :func:`_gauss_with`, the
    kernel of :func:`_gk`."""
    return _gauss_with(image, _gk(sigma, variance=variance, continuous=continuous, rule=rule), border, axes, twice)


_gv = partial(variant, _g_variant)


@mistake("kernel not normalised", "Divide the kernel by its sum so that a constant image stays constant")
def _g_unnormalised(image, sigma, border="reflect101"):
    x = np.arange(-_default_radius(sigma), _default_radius(sigma) + 1)
    return _gauss_with(image, np.exp(-x * x / (2.0 * sigma * sigma)), border)


def _gaussian_hidden(rng):
    img = partial(_image, rng)

    return [
        Case((img(_size(rng, 10, 16), _size(rng, 12, 20)), _sigma(rng, 0.6, 1.6)), {"border": "zero"},
             "zero border"),
        Case((img(_size(rng, 12, 20), _size(rng, 10, 18)), _sigma(rng, 0.6, 1.6)), {"border": "replicate"},
             "replicate"),
        Case((img(_size(rng, 12, 20), _size(rng, 12, 20)), _sigma(rng, 1.1, 2.0)), {"border": "reflect"},
             "reflect"),
        Case((img(_size(rng, 12, 20), _size(rng, 14, 24)), _sigma(rng, 0.6, 1.6)), {"border": "reflect101"},
             "reflect101"),
        Case((img(_size(rng, 8, 12), _size(rng, 9, 14), channels=3), _sigma(rng, 0.6, 1.4)),
             {"border": str(rng.choice(BORDERS[1:]))}, "colour image"),
        Case((img(_size(rng, 12, 20), _size(rng, 12, 20), "uint8"), _sigma(rng, 0.6, 1.5)),
             {"border": "reflect101"}, "uint8 image (not rescaled)"),
        Case((img(_size(rng, 25, 40), _size(rng, 25, 40), "big"), _sigma(rng, 1.2, 2.6)), {"border": "reflect"},
             "±1e6 values, larger σ"),
        Case((img(_size(rng, 6, 10), _size(rng, 6, 10), "const"), _sigma(rng, 0.6, 1.4)), {"border": "zero"},
             "constant image, zero border"),
        Case((img(1, _size(rng, 12, 20)), _sigma(rng, 0.5, 1.2)), {"border": str(rng.choice(BORDERS))},
             "single-row 1×N image"),
        Case((img(2, 3, "normal"), _sigma(rng, 0.4, 0.65)), {"border": str(rng.choice(BORDERS[1:]))},
             "tiny 2×3 image"),
        Case((img(_size(rng, 30, 40), _size(rng, 30, 40), "normal"), _sigma(rng, 2.1, 3.4)),
             {"border": "replicate"}, "large σ (radius ≥ 7)"),
    ]


gaussian = Check(
    public=[
        Case((_distinct((7, 8)), 1.4), {}, "7×8 image, σ = 1.4, default border (reflect101)"),
        Case((_distinct((6, 7, 3)), 0.8), {"border": "reflect"}, "colour image, σ = 0.8, reflect"),
        Case((_distinct((6, 9), dtype=np.uint8, scale=4), 0.6), {"border": "replicate"},
             "uint8 image, σ = 0.6, replicate"),
    ],
    hidden=_gaussian_hidden,
    compare=_LINEAR,
    mistakes=[
        Mistake("σ used as variance", _gv(variance=True), "The exponent is −x²/(2σ²): square σ"),
        Mistake("only the rows smoothed (x)", _gv(axes="x"),
                "Smooth along both axes: a 1-D pass along the rows, then one along the columns (§3.9.1)"),
        Mistake("only the columns smoothed (y)", _gv(axes="y"),
                "Smooth along both axes: a 1-D pass along the rows, then one along the columns (§3.9.1)"),
        Mistake("same axis smoothed twice", _gv(axes="x", twice=True),
                "The second 1-D pass runs along the other axis (columns), not again along the rows"),
        _g_unnormalised,
        Mistake("normalised by 1/(σ√2π) instead of the sum", _gv(continuous=True),
                "The sampled, truncated kernel must sum to exactly 1: divide by its sum"),
        Mistake("radius floor(3σ) instead of ceil", _gv(rule="floor"), "The kernel radius rounds 3σ up: r = ceil(3σ)"),
        *border_mistakes(_gaussian, _BORDER_HINT),
    ],
    allowed=("filters.gaussian_kernel", "filters.pad"),
)


# --------------------------------------------------------------------------------------------
# filters.median (§3.11)
# --------------------------------------------------------------------------------------------
@mistake("median computed separably (rows, then columns)",
         "The median is not separable: take the median of all size² values of the window at once")
def _median_separable(image, size, border="reflect101"):
    img = np.asarray(image, dtype=np.float64)
    r = size // 2
    rows = _pad(img, (0, r), border)
    tmp = np.median(sliding_window_view(rows, size, axis=1), axis=-1)
    cols = _pad(tmp, (r, 0), border)
    out = np.median(sliding_window_view(cols, size, axis=0), axis=-1)
    return out


def _median_hidden(rng):
    img = partial(_image, rng)

    return [
        Case((img(_size(rng, 8, 16), _size(rng, 9, 20)), 3), {"border": "zero"}, "3×3 window, zero border"),
        Case((img(_size(rng, 10, 16), _size(rng, 10, 20), "impulses"), 3), {"border": "replicate"},
             "impulse noise, replicate"),
        Case((img(_size(rng, 10, 16), _size(rng, 10, 20)), 5), {"border": "reflect"}, "5×5 window, reflect"),
        Case((img(_size(rng, 10, 16), _size(rng, 10, 20)), 3), {"border": "reflect101"}, "3×3 window, reflect101"),
        Case((img(_size(rng, 7, 12), _size(rng, 8, 14), "impulses", channels=3), 3),
             {"border": str(rng.choice(BORDERS[1:]))}, "colour image with impulses"),
        Case((img(_size(rng, 9, 16), _size(rng, 9, 16), "uint8"), 3), {"border": "reflect101"},
             "uint8 image (not rescaled)"),
        Case((img(_size(rng, 10, 16), _size(rng, 10, 20), "big"), 5), {"border": "replicate"}, "±1e6 values"),
        *_window_edge_cases(rng, img, "reflect"),
    ]


median = Check(
    public=_window_public,
    hidden=_median_hidden,
    compare=_NONLINEAR,
    mistakes=[
        Mistake("mean instead of median", lambda image, size, border="reflect101": _mean(image, size, border),
                "Sort the size² values of the window and take the middle one (np.median), not their mean"),
        border_zero(_median, _BORDER_HINT),
        _size_as_radius(_median),
        reflect_swapped(_median),
        _median_separable,
    ],
    allowed=("filters.pad",),
)


# --------------------------------------------------------------------------------------------
# filters.bilateral (§3.12)
# --------------------------------------------------------------------------------------------
def _bilateral_variant(image, sigma_space, sigma_range, radius=None, border="reflect101", *,
                       range_on="difference", normalise=True, variance=False, swap=False, per_channel=False):
    """The bilateral filter with knobs for the mistakes (loop over window offsets)."""
    img = np.asarray(image, dtype=np.float64)
    if per_channel and img.ndim == 3:
        return np.stack([_bilateral_variant(img[..., c], sigma_space, sigma_range, radius, border)
                         for c in range(img.shape[2])], axis=-1)
    r = _default_radius(sigma_space) if radius is None else int(radius)
    ss, sr = (sigma_range, sigma_space) if swap else (sigma_space, sigma_range)
    vs, vr = (ss, sr) if variance else (ss * ss, sr * sr)
    planes = _channels_last(img)
    height, width = img.shape[:2]
    padded = _channels_last(_pad(img, r, border))
    centre = planes
    num = np.zeros(planes.shape)
    den = np.zeros((height, width))
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            q = padded[r + dy: r + dy + height, r + dx: r + dx + width]
            if range_on == "difference":
                d2 = ((q - centre) ** 2).sum(axis=-1)
            elif range_on == "intensity":
                d2 = (q ** 2).sum(axis=-1)
            else:
                d2 = 0.0
            w = np.exp(-(dy * dy + dx * dx) / (2.0 * vs) - d2 / (2.0 * vr)) * np.ones((height, width))
            num += w[..., None] * q
            den += w
    out = num / den[..., None] if normalise else num
    return out[..., 0] if img.ndim == 2 else out


_bil = partial(variant, _bilateral_variant)


def _bilateral_hidden(rng):
    img = partial(_image, rng)

    def ss():
        return _sigma(rng, 0.6, 1.3)

    return [
        Case((img(_size(rng, 8, 14), _size(rng, 10, 18), "step"), ss(), _u(rng, 0.1, 0.4, 2)),
             {"border": "zero"}, "noisy edge, default radius, zero border"),
        Case((img(_size(rng, 8, 14), _size(rng, 10, 18)), ss(), _u(rng, 0.15, 0.5, 2)),
             {"border": "replicate"}, "default radius, replicate"),
        Case((img(_size(rng, 8, 14), _size(rng, 10, 18), "step"), ss(), _u(rng, 0.1, 0.4, 2), 2),
             {"border": "reflect"}, "radius 2 given, reflect"),
        Case((img(_size(rng, 8, 14), _size(rng, 10, 18)), ss(), _u(rng, 0.15, 0.5, 2)),
             {"radius": 1, "border": "reflect101"}, "radius=1, reflect101"),
        Case((img(_size(rng, 7, 12), _size(rng, 8, 14), channels=3), ss(), _u(rng, 0.2, 0.5, 2)),
             {"border": str(rng.choice(BORDERS[1:]))}, "colour image (Euclidean RGB distance)"),
        Case((img(_size(rng, 7, 10), _size(rng, 8, 12), "step", channels=3), ss(), 0.3, 2),
             {"border": "reflect101"}, "colour edge, radius 2"),
        Case((img(_size(rng, 8, 14), _size(rng, 10, 18), "uint8"), ss(), float(rng.integers(20, 60))),
             {"border": "reflect101"}, "uint8 image, σ_range in 0..255 units"),
        Case((img(_size(rng, 8, 14), _size(rng, 10, 18), "big"), ss(), float(rng.uniform(3e5, 8e5))),
             {"border": "reflect"}, "±1e6 values"),
        Case((img(_size(rng, 6, 10), _size(rng, 6, 10), "const"), ss(), 0.2), {"border": "zero"},
             "constant image, zero border"),
        Case((img(1, _size(rng, 9, 16)), ss(), 0.3), {"border": str(rng.choice(BORDERS))}, "single-row 1×N image"),
        Case((img(2, 3, "normal"), 0.7, 2.0), {"radius": 1, "border": str(rng.choice(BORDERS[1:]))},
             "tiny 2×3 image"),
    ]


bilateral = Check(
    public=[
        Case((_distinct((6, 7), scale=1 / 41), 1.0, 0.3), {}, "6×7 image, σs = 1, σr = 0.3, default radius 3"),
        Case((_distinct((5, 6, 3), scale=1 / 89), 0.8, 0.25, 2), {"border": "reflect"},
             "colour image, radius 2, reflect"),
        Case((_distinct((6, 8), dtype=np.uint8, scale=5), 1.2, 40.0), {"border": "zero"},
             "uint8 image, σr = 40, zero border"),
    ],
    hidden=_bilateral_hidden,
    compare=_NONLINEAR,
    mistakes=[
        Mistake("range weight on the intensity, not on the difference", _bil(range_on="intensity"),
                "The range weight compares q with the centre: exp(−(I(q)−I(p))²/(2σr²))"),
        Mistake("range weight missing (a plain Gaussian filter)", _bil(range_on=None),
                "Multiply the spatial weight by the range weight exp(−(I(q)−I(p))²/(2σr²))"),
        Mistake("not normalised by Σw", _bil(normalise=False),
                "Divide by W(p) = Σ_q w(p, q), the sum of the weights of the window"),
        Mistake("σ used as variance", _bil(variance=True),
                "The exponents are −d²/(2σ²): square σs and σr"),
        Mistake("σ_space and σ_range swapped", _bil(swap=True),
                "σs goes with the pixel distance ‖p−q‖², σr with the intensity difference"),
        Mistake("colour channels filtered independently", _bil(per_channel=True),
                "For colour, one weight per neighbour from the RGB distance ‖I(q)−I(p)‖² summed over the channels"),
        border_zero(_bilateral, _BORDER_HINT),
    ],
    allowed=("filters.pad",),
)


# --------------------------------------------------------------------------------------------
# filters.nl_means (§3.13)
# --------------------------------------------------------------------------------------------
def _nlm_variant(image, h, patch_size=7, search_size=21, border="reflect101", *,
                 reduce="mean", h_power=2, centre=True, normalise=True, per_channel=False):
    """Non-local means with knobs for the mistakes (loop over search offsets)."""
    img = np.asarray(image, dtype=np.float64)
    if per_channel and img.ndim == 3:
        return np.stack([_nlm_variant(img[..., c], h, patch_size, search_size, border)
                         for c in range(img.shape[2])], axis=-1)
    sr, pr = search_size // 2, patch_size // 2
    big = sr + pr
    height, width = img.shape[:2]
    padded = _channels_last(_pad(img, big, border))
    channels = padded.shape[2]
    base = padded[sr: sr + height + 2 * pr, sr: sr + width + 2 * pr]
    num = np.zeros((height, width, channels))
    den = np.zeros((height, width))
    for dy in range(-sr, sr + 1):
        for dx in range(-sr, sr + 1):
            if not centre and dy == 0 and dx == 0:
                continue
            shifted = padded[sr + dy: sr + dy + height + 2 * pr, sr + dx: sr + dx + width + 2 * pr]
            d2 = _box_sum(((shifted - base) ** 2).sum(axis=-1), patch_size)
            if reduce == "mean":
                d2 = d2 / (patch_size * patch_size * channels)
            w = np.exp(-d2 / (h ** h_power))
            num += w[..., None] * shifted[pr: pr + height, pr: pr + width]
            den += w
    out = num / den[..., None] if normalise else num
    return out[..., 0] if img.ndim == 2 else out


_nlm = partial(variant, _nlm_variant)


def _nlm_hidden(rng):
    def img(h, w, kind="step", channels=None):
        return _image(rng, h, w, kind, channels)

    def hh(lo=0.06, hi=0.2):
        return _u(rng, lo, hi)

    return [
        Case((img(_size(rng, 9, 14), _size(rng, 10, 16)), hh(), 3, 5), {"border": "zero"},
             "patch 3, search 5, zero border"),
        Case((img(_size(rng, 9, 14), _size(rng, 10, 16), "unit"), hh(0.15, 0.4), 5, 7), {"border": "replicate"},
             "patch 5, search 7, replicate"),
        Case((img(_size(rng, 9, 14), _size(rng, 10, 16)), hh(), 3, 7), {"border": "reflect"},
             "patch 3, search 7, reflect"),
        Case((img(_size(rng, 7, 9), _size(rng, 8, 10)), hh()), {"border": "reflect101"},
             "default patch 7 and search 21 on a small image"),
        Case((img(_size(rng, 8, 11), _size(rng, 8, 12), channels=3), hh(0.08, 0.2), 3, 5),
             {"border": str(rng.choice(BORDERS[1:]))}, "colour image (one weight from all channels)"),
        Case((img(_size(rng, 6, 9), _size(rng, 6, 9), "unit", channels=3), hh(0.2, 0.4), 3, 3),
             {"border": "reflect101"}, "colour image, search 3"),
        Case((img(_size(rng, 8, 12), _size(rng, 8, 12), "uint8"), float(rng.integers(40, 90)), 3, 5),
             {"border": "reflect101"}, "uint8 image, h in 0..255 units"),
        Case((img(_size(rng, 8, 12), _size(rng, 8, 12), "big"), float(rng.uniform(3e5, 8e5)), 3, 5),
             {"border": "reflect"}, "±1e6 values"),
        Case((img(_size(rng, 6, 10), _size(rng, 6, 10), "const"), 0.1, 3, 5), {"border": "zero"},
             "constant image, zero border"),
        Case((img(1, _size(rng, 9, 16), "unit"), hh(0.15, 0.4), 3, 5), {"border": str(rng.choice(BORDERS))},
             "single-row 1×N image"),
        Case((img(2, 3, "normal"), 2.0, 3, 3), {"border": str(rng.choice(BORDERS[1:]))}, "tiny 2×3 image"),
    ]


nl_means = Check(
    public=[
        Case((_distinct((6, 7), scale=1 / 41), 0.25, 3, 5), {}, "6×7 image, h = 0.25, patch 3, search 5"),
        Case((_distinct((5, 6, 3), scale=1 / 89), 0.2, 3, 5), {"border": "reflect"},
             "colour image, patch 3, search 5, reflect"),
        Case((_distinct((6, 6), dtype=np.uint8, scale=7), 60.0, 3, 3), {"border": "zero"},
             "uint8 image, h = 60, zero border"),
    ],
    hidden=_nlm_hidden,
    compare=_NONLINEAR,
    mistakes=[
        Mistake("sum instead of mean of the squared patch differences", _nlm(reduce="sum"),
                "The patch distance d² is the MEAN squared difference over the patch_size² (× channels) values, not their sum"),
        Mistake("exp(−d²/h): h not squared", _nlm(h_power=1),
                "The weight is exp(−d²/h²): square h"),
        Mistake("centre pixel excluded", _nlm(centre=False),
                "The search window includes p itself, with weight exp(0) = 1"),
        Mistake("pixel differences only (patch ignored)",
                lambda image, h, patch_size=7, search_size=21, border="reflect101":
                    _nl_means(image, h, 1, search_size, border),
                "Compare the patch_size × patch_size patches around p and q, not just I(p) and I(q)"),
        Mistake("weights not normalised", _nlm(normalise=False),
                "Divide by the sum of the weights: O(p) = Σ w(p,q) I(q) / Σ w(p,q)"),
        Mistake("colour channels weighted independently", _nlm(per_channel=True),
                "For colour, one weight per q from the patch distance averaged over all three channels"),
        border_zero(_nl_means, _BORDER_HINT),
    ],
    allowed=("filters.pad",),
)


# --------------------------------------------------------------------------------------------
# filters.temporal_mean (§3.1)
# --------------------------------------------------------------------------------------------
@mistake("integer division (mean rounded down)",
         "Divide with `/`, not `//`, and keep the result in float: O(p) = (1/T)·Σ I_t(p)")
def _tm_floor(frames):
    return np.floor(_temporal_mean(frames))


@mistake("uint8 sum overflowed", "Convert to float before summing: a uint8 sum wraps around at 256")
def _tm_uint8_overflow(frames):
    stack = np.asarray(frames)
    if stack.dtype != np.uint8:
        return _temporal_mean(frames)
    total = np.zeros(stack.shape[1:], dtype=np.uint8)
    for frame in stack:
        total += frame  # wraps around modulo 256
    return total / stack.shape[0]


@mistake("median instead of mean", "Average the frames: O(p) = (1/T)·Σ_t I_t(p)")
def _tm_median(frames):
    return np.median(np.asarray(frames, dtype=np.float64), axis=0)


@mistake("mean over the wrong axis", "Frames are (T, H, W): average over axis 0 (time)")
def _tm_wrong_axis(frames):
    return np.asarray(frames, dtype=np.float64).mean(axis=-1)


@mistake("sum, not mean", "Divide the sum over the frames by their number T")
def _tm_sum(frames):
    return np.asarray(frames, dtype=np.float64).sum(axis=0)


def _frames(rng, t, h, w, kind="unit", channels=None):
    scene = _image(rng, h, w, "unit", channels)
    shape = (t,) + scene.shape
    if kind == "uint8":
        base = rng.integers(60, 200, scene.shape)
        return np.clip(base + rng.integers(-50, 51, shape), 0, 255).astype(np.uint8)
    if kind == "big":
        return scene * 1e6 - 5e5 + rng.normal(0, 2e5, shape)
    if kind == "const":
        return np.full(shape, 2.5)
    return scene + rng.normal(0, 0.1, shape)


def _tm_hidden(rng):
    return [
        Case((_frames(rng, _size(rng, 3, 6), _size(rng, 7, 12), _size(rng, 8, 15)),), {}, "noisy float frames"),
        Case((_frames(rng, _size(rng, 4, 8), _size(rng, 7, 12), _size(rng, 9, 15), "uint8"),), {},
             "uint8 frames (the sum exceeds 255)"),
        Case((_frames(rng, _size(rng, 3, 5), _size(rng, 5, 9), _size(rng, 10, 14), "uint8"),), {},
             "uint8 frames, other size"),
        Case((_frames(rng, _size(rng, 2, 4), _size(rng, 5, 9), _size(rng, 6, 10), channels=3),), {},
             "colour frames (T, H, W, 3)"),
        Case((_frames(rng, _size(rng, 3, 5), _size(rng, 5, 8), _size(rng, 6, 9), "uint8", channels=3),), {},
             "colour uint8 frames"),
        Case((_frames(rng, _size(rng, 3, 6), _size(rng, 10, 20), _size(rng, 21, 30), "big"),), {},
             "±1e6 values"),
        Case((rng.normal(0, 3, (_size(rng, 2, 5), _size(rng, 4, 8), _size(rng, 9, 12))),), {},
             "negative values"),
        Case((_frames(rng, 1, _size(rng, 4, 8), _size(rng, 9, 12)),), {}, "a single frame (T = 1)"),
        Case((_frames(rng, _size(rng, 3, 5), 1, _size(rng, 6, 12)),), {}, "frames of one row (T, 1, W)"),
        Case((_frames(rng, _size(rng, 2, 4), _size(rng, 4, 6), _size(rng, 7, 9), "const"),), {},
             "identical constant frames"),
    ]


temporal_mean = Check(
    rules=("integer",),
    public=[
        Case((np.array([[[200, 10, 7, 255, 0], [1, 2, 3, 4, 5], [90, 91, 92, 93, 94]],
                        [[100, 21, 8, 255, 3], [9, 8, 7, 6, 5], [90, 0, 180, 30, 60]],
                        [[250, 13, 9, 254, 0], [5, 5, 5, 5, 5], [1, 2, 3, 4, 5]],
                        [[180, 11, 6, 1, 2], [0, 0, 1, 1, 0], [255, 255, 255, 255, 255]]], dtype=np.uint8),),
             {}, "4 uint8 frames of 3×5 (the sum exceeds 255)"),
        Case((np.array([[[0.5, -1.0, 2.25, 3.0], [1.0, 0.0, -0.5, 4.5]],
                        [[1.5, 2.0, 0.25, -3.0], [2.0, 0.0, 0.5, 4.0]],
                        [[0.25, 1.5, 1.0, 0.5], [-1.0, 1.0, 3.0, 2.0]]]),),
             {}, "3 float frames of 2×4 with negative values"),
        Case((np.random.default_rng(7).permutation(72).reshape(2, 3, 4, 3) / 7.0,), {}, "2 colour frames of 3×4×3"),
    ],
    hidden=_tm_hidden,
    compare=close(rtol=1e-9, atol=1e-12, kind="f", scaled=True),
    mistakes=[_tm_floor, _tm_uint8_overflow, _tm_median, _tm_wrong_axis, _tm_sum],
)


# --------------------------------------------------------------------------------------------
# §3.14 the measured exercise: a denoiser, graded by its PSNR on noise it has not seen
# --------------------------------------------------------------------------------------------
#: the published scale of ``filters.denoise`` (PSNR gap to the reference in dB → share of the points)
DENOISE_SCALE = Scale(PSNR_GAP_SCALE, percent=False)


def _noisy_case(rng: np.random.Generator, label: str, where: bool) -> MeasuredCase:
    """A case of :func:`noisy_crop`; its label names the picture and the crop only when ``where``
    (the public case): a hidden crop's place stays unknown, even in the feedback."""
    noisy, sigma, clean, place = noisy_crop(rng)
    return MeasuredCase((noisy, sigma), {}, f"{label}: {place + ', ' if where else ''}σ = {sigma:g}", truth=clean)


def _denoise_public() -> list[Case]:
    return [_noisy_case(np.random.default_rng(2026), "a noisy crop of a cvkit.data image", True)]


def _denoise_hidden(rng: np.random.Generator) -> list[Case]:
    return [_noisy_case(np.random.default_rng(_seed(rng)), f"your own noisy crop {k + 1} of 3", False)
            for k in range(3)]


def _reference_psnr(case: MeasuredCase) -> float:
    """PSNR of the reference denoiser on the case (computed once per case)."""
    cached = case.__dict__.get("_cvkit_reference_psnr")
    if cached is None:
        noisy, sigma = case.args
        cached = case.__dict__["_cvkit_reference_psnr"] = denoise_psnr(case.truth, denoise_unregistered(noisy, sigma))
    return cached


def _psnr_gap(got, case) -> float:
    """PSNR of ``got`` minus the reference's, on the case's clean crop (−inf for a wrong shape)."""
    try:
        out = np.asarray(got, dtype=np.float64)
    except (TypeError, ValueError):
        return float("-inf")
    if out.shape != np.shape(case.truth) or not np.all(np.isfinite(out)):
        return float("-inf")
    return denoise_psnr(case.truth, out) - _reference_psnr(case)


class PsnrGap(Comparator):
    """Passes when the denoised image's PSNR is within the top of :data:`DENOISE_SCALE` of the
    reference denoiser's PSNR on the same noisy crop (``case.truth`` is the clean crop); the
    case's credit follows the scale below it."""

    judges_alone = True  # the verdict is what the output achieves on the case's truth

    def describe(self) -> str:
        return f"PSNR at most {-DENOISE_SCALE.top:g} dB below the reference denoiser's"

    def __call__(self, got, expected, case=None):
        truth = np.asarray(case.truth)
        try:
            out = np.asarray(got, dtype=np.float64)
        except (TypeError, ValueError) as error:
            return Mismatch(f"your output could not be read as an image ({error})")
        if out.shape != truth.shape:
            return Mismatch(f"shape mismatch: expected {truth.shape} (the shape of the noisy image), got {out.shape}")
        if not np.all(np.isfinite(out)):
            return Mismatch("your image holds nan or inf values")
        gap = _psnr_gap(out, case)
        if gap >= DENOISE_SCALE.top:
            return None
        noisy = np.asarray(case.args[0], dtype=np.float64)
        mine, noise_only = denoise_psnr(truth, out), denoise_psnr(truth, noisy)
        if mine < noise_only + 1.0:
            advice = ("Your image is hardly better than the noisy one: with the course's mean patch distance, h of "
                      "about σ averages the noise away (a sum over the patch needs h times the patch side).")
        elif np.std(out - noisy) > 1.5 * float(case.args[1]):
            advice = ("Your image differs from the noisy one by more than the noise: the filter removes detail too "
                      "(h or the smoothing too strong).")
        else:
            advice = "Tune the parameters on noisy crops of your own, with σ in the range of the statement."
        words = DENOISE_SCALE.shortfall(gap, "your PSNR minus the reference's (dB)",
                                        f" (yours {mine:.2f} dB, the reference denoiser's {_reference_psnr(case):.2f} dB, "
                                        f"the noisy input's {noise_only:.2f} dB)")
        return Mismatch(words + " " + advice)


@mistake("h far too large (6σ): the detail is averaged away with the noise",
         "Keep h close to σ (the course's patch distance is a mean: two noisy copies of a patch are at about 2σ²)")
def _denoise_h_too_large(noisy, sigma):
    return denoise_unregistered(np.asarray(noisy, dtype=np.float64), sigma, h_factor=6.0)


@mistake("patch distance summed over the patch, h still ≈ σ",
         "Divide the sum of squared differences by the number of values in the patch, or scale h with the patch side")
def _denoise_summed(noisy, sigma):
    return denoise_unregistered(np.asarray(noisy, dtype=np.float64), sigma, summed=True)


@mistake("σ taken as the variance (h = σ²)",
         "sigma is the noise's standard deviation, in grey levels: h ≈ σ, not σ²")
def _denoise_variance(noisy, sigma):
    return denoise_unregistered(np.asarray(noisy, dtype=np.float64), sigma ** 2, h_factor=1.1)


denoise = Check(
    public=_denoise_public,
    hidden=_denoise_hidden,
    compare=PsnrGap(),
    mistakes=[_denoise_h_too_large, _denoise_summed, _denoise_variance],
    allowed=("filters.pad",),   # not nl_means: nl_means(noisy, sigma) alone is near the reference
    arg_names=("noisy", "sigma"),
    output_names=("denoised",),
    time_limit=BUDGET_SECONDS,
    credit=lambda got, case: DENOISE_SCALE.credit(_psnr_gap(got, case)),
    measure=Measure("PSNR minus the reference's", _psnr_gap, "dB"),
)
