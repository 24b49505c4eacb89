"""Checks of Chapter 8's warping functions: cases, comparators and mistake banks.

- ``bilinear_sample``: small non-square images (grey, RGB, uint8, a single row), positions of
  every shape, exactly on the last row and column, just outside, far outside and NaN, and
  every kind of ``fill`` (0, a value, NaN);
- ``warp_homography`` and ``undistort_image``: small textured images (at most 24×30), a
  perspective H, negative and unnormalised scales, output shapes other than the input's,
  barrel and pincushion lenses with 1–3 radial terms and tangential terms, skewed cameras —
  compared by :class:`WarpClose`, which ignores the few pixels whose source lies within 1e-7 px
  of the image border (where two correct programs may round to opposite sides of "inside");
- ``rotation_homography`` and ``birds_eye_homography``: compared by what the homography does
  (:class:`cvkit.calibration.checks.HomographyClose`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..calibration.checks import HomographyClose
from ..camera import distort as _distort
from ..camera import rotation_matrix as _rotation_matrix
from ..camera import undistort_points as _undistort_points
from ..camera.checks import FloatClose
from ..grading import Case, Check, Close, Comparator, Mistake, mistake
from ..grading.casekit import argument as _argument
from ..grading.casekit import uniform as _u
from ._sampling import bilinear_sample as _bilinear_sample
from ._sampling import undistort_image as _undistort_image
from ._sampling import warp_homography as _warp_homography
from ._views import birds_eye_homography as _birds_eye_homography
from ._views import rotation_homography as _rotation_homography

__all__ = ["WarpClose", "bilinear_sample", "warp_homography", "undistort_image", "rotation_homography",
           "birds_eye_homography"]


# --------------------------------------------------------------------------------------------
# comparator
# --------------------------------------------------------------------------------------------
def _warp_sources(case):
    """Source positions (x, y) of every output pixel of a warp_homography case."""
    H = np.asarray(_argument(case, 1, "H"), dtype=np.float64)
    shape = _argument(case, 2, "output_shape")
    rows, cols = int(shape[0]), int(shape[1])
    xo, yo = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
    inv = np.linalg.inv(H)
    with np.errstate(all="ignore"):
        w = inv[2, 0] * xo + inv[2, 1] * yo + inv[2, 2]
        return (inv[0, 0] * xo + inv[0, 1] * yo + inv[0, 2]) / w, (inv[1, 0] * xo + inv[1, 1] * yo + inv[1, 2]) / w


def _undistort_sources(case):
    image, A = np.asarray(case.args[0]), np.asarray(_argument(case, 1, "A"), dtype=np.float64)
    k = _argument(case, 2, "k")
    p = _argument(case, 3, "p", (0.0, 0.0))
    A = A / A[2, 2]
    rows, cols = image.shape[:2]
    u, v = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
    y = (v - A[1, 2]) / A[1, 1]
    x = (u - A[0, 2] - A[0, 1] * y) / A[0, 0]
    xd = _distort(np.column_stack([x.ravel(), y.ravel()]), k, p)
    su = A[0, 0] * xd[:, 0] + A[0, 1] * xd[:, 1] + A[0, 2]
    sv = A[1, 1] * xd[:, 1] + A[1, 2]
    return su.reshape(rows, cols), sv.reshape(rows, cols)


@dataclass
class WarpClose(Comparator):
    """allclose for warped images, except at output pixels whose source position lies within
    ``margin`` px of the input's border (x = 0, W − 1 or y = 0, H − 1): there a last-digit
    difference decides between a value and ``fill``.

    ``sources(case)`` returns the source positions (x, y), each of the output's (rows, cols).
    """

    sources: Callable[[Any], Any] | None = None
    rtol: float = 1e-9
    atol: float = 1e-9
    margin: float = 1e-7
    elementwise = True

    def describe(self) -> str:
        return f"allclose(rtol={self.rtol:g}, atol={self.atol:g}·max(1, max|expected|)) away from the border"

    def __call__(self, got, expected, case=None):
        inner = Close(rtol=self.rtol, atol=self.atol, scaled=True)
        exp = np.asarray(expected)
        if case is None or self.sources is None:
            return inner(got, expected, case)
        try:
            arr = np.asarray(got, dtype=np.float64)
        except (TypeError, ValueError):
            return inner(got, expected, case)
        if arr.shape != exp.shape:
            return inner(got, expected, case)
        x, y = self.sources(case)
        image = np.asarray(case.args[0])
        H, W = image.shape[:2]
        with np.errstate(invalid="ignore"):
            near = np.zeros(x.shape, dtype=bool)
            for value, limit in ((x, 0.0), (x, W - 1.0), (y, 0.0), (y, H - 1.0)):
                near |= np.abs(value - limit) <= self.margin
        if near.any() and near.shape == exp.shape[:2]:
            if exp.ndim == 3:
                near = np.repeat(near[..., None], exp.shape[2], axis=2)
            arr = np.where(near, exp, arr)
        return inner(arr, exp, case)


# --------------------------------------------------------------------------------------------
# case helpers
# --------------------------------------------------------------------------------------------
def _texture(rng, rows, cols, color=False, dtype="float"):
    """A smooth random texture plus a few sharp steps (so that sampling mistakes show)."""
    y, x = np.mgrid[0:rows, 0:cols].astype(float)
    channels = []
    for _ in range(3 if color else 1):
        a, b, c = rng.uniform(0.1, 0.6, 3)
        img = 0.5 + 0.2 * np.sin(a * x + b * y + c * 5) + 0.15 * np.cos(0.7 * b * x - 1.3 * a * y)
        img += 0.25 * ((x + 2 * y) % 7 < 3) + rng.uniform(-0.05, 0.05, (rows, cols))
        channels.append(img)
    img = np.stack(channels, axis=-1) if color else channels[0]
    if dtype == "uint8":
        return np.clip(np.round(img * 180), 0, 255).astype(np.uint8)
    if dtype == "int":
        return np.round(img * 1000).astype(np.int32)
    return np.round(img, 4)


# --------------------------------------------------------------------------------------------
# warp.bilinear_sample (§8.4.2)
# --------------------------------------------------------------------------------------------
@mistake("bilinear weights swapped (a on the left pixel)",
         "With a = x − x0 the RIGHT pixel (x0 + 1) gets weight a and the left one 1 − a (same for b in y)")
def _bs_swapped_weights(image, x, y, fill=0.0):
    img = np.asarray(image, dtype=np.float64)
    H, W = img.shape[:2]
    x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    with np.errstate(invalid="ignore"):
        inside = (x >= 0) & (x <= W - 1) & (y >= 0) & (y <= H - 1)
    xi, yi = np.where(inside, x, 0.0), np.where(inside, y, 0.0)
    x0 = np.minimum(np.floor(xi).astype(int), max(W - 2, 0))
    y0 = np.minimum(np.floor(yi).astype(int), max(H - 2, 0))
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    a, b = xi - x0, yi - y0
    if img.ndim == 3:
        a, b, inside = a[..., None], b[..., None], inside[..., None]
    out = img[y0, x0] * (a * b) + img[y0, x1] * ((1 - a) * b) + img[y1, x0] * (a * (1 - b)) \
        + img[y1, x1] * ((1 - a) * (1 - b))
    return np.where(inside, out, float(fill))


@mistake("x and y swapped (image[x, y])", "Images are indexed [row, col] = [y, x]: read image[y0, x0]")
def _bs_xy_swapped(image, x, y, fill=0.0):
    return _bilinear_sample(image, y, x, fill)


def _size_and_positions(image, x, y):
    """``(H, W, x, y)``: the image's size and the positions as float64 arrays."""
    H, W = np.shape(image)[:2]
    return H, W, np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)


@mistake("outside positions clamped to the border (fill ignored)",
         "Positions with x < 0, x > W − 1, y < 0 or y > H − 1 (and NaN) get `fill`, not the border value")
def _bs_clamped(image, x, y, fill=0.0):
    H, W, x, y = _size_and_positions(image, x, y)
    x = np.clip(np.nan_to_num(x, nan=0.0), 0, W - 1)
    y = np.clip(np.nan_to_num(y, nan=0.0), 0, H - 1)
    return _bilinear_sample(image, x, y, fill)


@mistake("last row and column treated as outside",
         "x = W − 1 and y = H − 1 are inside: use ≤, and clip x0 to W − 2 so that x0 + 1 stays in the image")
def _bs_last_outside(image, x, y, fill=0.0):
    H, W, x, y = _size_and_positions(image, x, y)
    out = _bilinear_sample(image, x, y, fill)
    with np.errstate(invalid="ignore"):
        edge = (x == W - 1) | (y == H - 1)
    if out.ndim > edge.ndim:
        edge = edge[..., None]
    return np.where(edge, float(fill), out)


@mistake("nearest neighbour instead of bilinear",
         "Interpolate between the four neighbours, weighted by the areas (1 − a)(1 − b), a(1 − b), (1 − a)b, ab")
def _bs_nearest(image, x, y, fill=0.0):
    with np.errstate(invalid="ignore"):
        return _bilinear_sample(image, np.round(np.asarray(x, dtype=np.float64)),
                                np.round(np.asarray(y, dtype=np.float64)), fill)


@mistake("fill ignored (0 outside)", "Use the `fill` argument for positions outside the image")
def _bs_fill_zero(image, x, y, fill=0.0):
    return _bilinear_sample(image, x, y, 0.0)


def _bs_points(rng, rows, cols, n, outside=0.2):
    x = np.round(rng.uniform(-0.99, cols - 0.01, n), 3)
    y = np.round(rng.uniform(-0.99, rows - 0.01, n), 3)
    x[: max(1, n // 8)] = cols - 1                          # on the last column
    y[n // 8: n // 8 + max(1, n // 8)] = rows - 1           # on the last row
    k = int(outside * n)
    if k:
        x[-k:] = np.round(rng.choice([-1.0, 1.0], k) * rng.uniform(0.3, 3.0, k) + np.where(
            rng.random(k) < 0.5, -0.01, cols - 1 + 0.01), 3)
    return x, y


def _bs_public():
    rng = np.random.default_rng(80401)
    img = np.array([[0.0, 10.0, 20.0, 30.0, 40.0], [5.0, 25.0, 15.0, 35.0, 0.0], [60.0, 20.0, 80.0, 10.0, 50.0],
                    [30.0, 90.0, 40.0, 70.0, 20.0]])
    x = np.array([0.25, 1.7, 3.5, 4.0, 2.0, 4.0, -0.5, 5.2, 1.0, 0.6])
    y = np.array([0.5, 2.2, 1.25, 1.5, 3.0, 3.0, 1.0, 2.0, -0.01, 0.9])
    rgb = _texture(rng, 3, 4, color=True)
    return [
        Case((img, x, y), {"fill": -1.0}, "4×5 grey image, points on the last row/column and outside, fill −1"),
        Case((rgb, np.array([[0.5, 2.75], [3.0, 1.2]]), np.array([[0.3, 1.6], [2.0, 3.5]])), {},
             "3×4 RGB image, 2×2 positions, one outside"),
    ]


def _bs_hidden(rng):
    def img(rows, cols, **kw):
        return _texture(rng, rows, cols, **kw)

    r, c = int(rng.integers(4, 9)), int(rng.integers(5, 11))
    x, y = _bs_points(rng, r, c, 24)
    xm, ym = _bs_points(rng, r, c, 12)
    return [
        Case((img(r, c), x, y), {}, "grey image, 24 points (some on the last row/col, some outside)"),
        Case((img(r, c), x.reshape(4, 6), y.reshape(4, 6)), {"fill": _u(rng, -2, 2)}, "positions as (4, 6) grids, fill"),
        Case((img(c, r, color=True), y, x), {"fill": 0.5}, "RGB image, fill 0.5"),
        Case((img(r, c, dtype="uint8"), xm, ym), {"fill": 255.0}, "uint8 image (not rescaled), fill 255"),
        Case((img(r, c, dtype="int"), xm, ym), {}, "int32 image"),
        Case((img(1, c), np.round(rng.uniform(0, c - 1, 6), 3), np.zeros(6)), {}, "a single row (y = 0 exactly)"),
        Case((img(r, c), np.array([c - 1.0, 0.0, c - 1.0, 0.0]), np.array([r - 1.0, r - 1.0, 0.0, 0.0])), {},
             "the four corner pixels exactly"),
        Case((img(r, c), np.array([-1e-9, c - 1 + 1e-9, 1.5, np.nan, 2.0, np.inf]),
              np.array([1.0, 1.0, -1e-9, 1.0, np.nan, 0.5])), {"fill": _u(rng, 1, 5)},
             "just outside, NaN and inf positions"),
        Case((img(r, c), x, y), {"fill": -1e9}, "extreme fill value (−1e9)"),
        Case((np.full((r, c), _u(rng, 0.2, 0.8)), xm, ym), {}, "constant image"),
        Case((img(r, c), np.float64(_u(rng, 0, c - 1)), np.float64(_u(rng, 0, r - 1))), {}, "a single (scalar) position"),
        Case((img(r, c), np.round(rng.uniform(0, c - 1, 9), 0), np.round(rng.uniform(0, r - 1, 9), 0)), {},
             "integer positions (exact pixel values)"),
    ]


bilinear_sample = Check(
    public=_bs_public,
    hidden=_bs_hidden,
    compare=FloatClose(rtol=1e-10, atol=1e-10),
    mistakes=[_bs_swapped_weights, _bs_xy_swapped, _bs_clamped, _bs_last_outside, _bs_nearest, _bs_fill_zero],
)


# --------------------------------------------------------------------------------------------
# warp.warp_homography (§8.4.2)
# --------------------------------------------------------------------------------------------
@mistake("forward mapping (input pixels pushed through H)",
         "Map BACKWARD: for every output pixel (x', y') read the input at H⁻¹·(x', y', 1) — no holes, no folds")
def _wh_forward(image, H, output_shape, fill=0.0):
    img = np.asarray(image, dtype=np.float64)
    H = np.asarray(H, dtype=np.float64)
    rows, cols = int(output_shape[0]), int(output_shape[1])
    yi, xi = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    w = H[2, 0] * xi + H[2, 1] * yi + H[2, 2]
    xo = np.round((H[0, 0] * xi + H[0, 1] * yi + H[0, 2]) / w).astype(int)
    yo = np.round((H[1, 0] * xi + H[1, 1] * yi + H[1, 2]) / w).astype(int)
    out = np.full((rows, cols) + img.shape[2:], float(fill))
    keep = (xo >= 0) & (xo < cols) & (yo >= 0) & (yo < rows)
    out[yo[keep], xo[keep]] = img[yi[keep], xi[keep]]
    return out


@mistake("H used instead of H⁻¹ (inverted the wrong way)",
         "H maps input to output, so an output pixel comes from H⁻¹·(x', y', 1)")
def _wh_not_inverted(image, H, output_shape, fill=0.0):
    return _warp_homography(image, np.linalg.inv(np.asarray(H, dtype=np.float64)), output_shape, fill)


@mistake("output_shape read as (width, height)", "output_shape is (rows, cols), like image.shape")
def _wh_shape_swapped(image, H, output_shape, fill=0.0):
    return _warp_homography(image, H, (output_shape[1], output_shape[0]), fill)


@mistake("no division by w (only the affine part)",
         "Divide by the third coordinate: (x, y) = (x̃/w, ỹ/w) with (x̃, ỹ, w) = H⁻¹·(x', y', 1)")
def _wh_affine(image, H, output_shape, fill=0.0):
    H = np.asarray(H, dtype=np.float64)
    A = H / H[2, 2]
    A = np.vstack([A[:2], [0.0, 0.0, 1.0]])
    return _warp_homography(image, A, output_shape, fill)


@mistake("nearest neighbour instead of bilinear",
         "Sample the input bilinearly at the real-valued source position (do not round it)")
def _wh_nearest(image, H, output_shape, fill=0.0):
    rows, cols = int(output_shape[0]), int(output_shape[1])
    inv = np.linalg.inv(np.asarray(H, dtype=np.float64))
    xo, yo = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
    w = inv[2, 0] * xo + inv[2, 1] * yo + inv[2, 2]
    x = (inv[0, 0] * xo + inv[0, 1] * yo + inv[0, 2]) / w
    y = (inv[1, 0] * xo + inv[1, 1] * yo + inv[1, 2]) / w
    return _bilinear_sample(image, np.round(x), np.round(y), fill)


@mistake("x and y of the output grid swapped",
         "x' runs along the columns and y' along the rows: np.meshgrid(np.arange(cols), np.arange(rows))")
def _wh_grid_swapped(image, H, output_shape, fill=0.0):
    rows, cols = int(output_shape[0]), int(output_shape[1])
    inv = np.linalg.inv(np.asarray(H, dtype=np.float64))
    xo, yo = np.indices((rows, cols)).astype(float)        # x from the row index: swapped
    w = inv[2, 0] * xo + inv[2, 1] * yo + inv[2, 2]
    x = (inv[0, 0] * xo + inv[0, 1] * yo + inv[0, 2]) / w
    y = (inv[1, 0] * xo + inv[1, 1] * yo + inv[1, 2]) / w
    return _bilinear_sample(image, x, y, fill)


def _similarity(rng, scale=(0.7, 1.4), angle=0.5, shift=(-4.0, 4.0)):
    s, a = rng.uniform(*scale), rng.uniform(-angle, angle)
    return np.array([[s * np.cos(a), -s * np.sin(a), rng.uniform(*shift)],
                     [s * np.sin(a), s * np.cos(a), rng.uniform(*shift)], [0.0, 0.0, 1.0]])


def _perspective(rng, rows, cols, strength=0.02):
    H = _similarity(rng, shift=(-2.0, 2.0))
    H[2, :2] = rng.uniform(-strength, strength, 2)
    return np.round(H, 6)


def _wh_public():
    rng = np.random.default_rng(80402)
    img = _texture(rng, 12, 16)
    H = np.array([[0.9, -0.25, 4.3], [0.2, 1.1, -1.6], [0.012, -0.008, 1.0]])
    rgb = _texture(rng, 8, 10, color=True)
    A = np.array([[1.2, 0.4, 1.5], [-0.3, 0.9, 2.25], [0.0, 0.0, 1.0]])
    return [
        Case((img, H), {"output_shape": (14, 18), "fill": 0.5}, "12×16 grey image, perspective H, 14×18 output"),
        Case((rgb, A, (10, 7)), {}, "8×10 RGB image, affine H, 10×7 output"),
    ]


def _wh_hidden(rng):
    r, c = int(rng.integers(10, 18)), int(rng.integers(12, 22))
    img = _texture(rng, r, c)
    shift = np.array([[1.0, 0.0, _u(rng, -3, 3)], [0.0, 1.0, _u(rng, -3, 3)], [0.0, 0.0, 1.0]])
    return [
        Case((img, _perspective(rng, r, c), (r + 2, c - 1)), {}, "perspective H"),
        Case((img, _perspective(rng, r, c, 0.04), (r, c)), {"fill": _u(rng, -1, 1)}, "strong perspective, fill"),
        Case((img, _similarity(rng), (c, r)), {}, "rotation and scale, transposed output size"),
        Case((img, shift, (r, c)), {}, "sub-pixel translation"),
        Case((img, np.eye(3), (r, c)), {}, "identity"),
        Case((img, -_u(rng, 0.5, 3) * _perspective(rng, r, c), (r, c)), {}, "H with a negative scale"),
        Case((img, _u(rng, 2, 50) * _perspective(rng, r, c), (r - 3, c + 4)), {}, "H not normalised (H[2, 2] ≠ 1)"),
        Case((_texture(rng, r, c, color=True), _perspective(rng, r, c), (r, c)), {"fill": 0.25}, "RGB image"),
        Case((_texture(rng, r, c, dtype="uint8"), _similarity(rng), (r + 1, c)), {"fill": 255.0}, "uint8 image"),
        Case((img, _similarity(rng, scale=(1.8, 2.5)), (2 * r, 2 * c)), {}, "enlarging by 2 (forward mapping leaves holes)"),
        Case((img, _similarity(rng, scale=(0.4, 0.6)), (r // 2 + 1, c // 2 + 1)), {}, "shrinking by 2"),
        Case((img, _perspective(rng, r, c).tolist(), [r, c]), {}, "H and the shape as lists"),
    ]


warp_homography = Check(
    public=_wh_public,
    hidden=_wh_hidden,
    compare=WarpClose(sources=_warp_sources),
    mistakes=[_wh_forward, _wh_not_inverted, _wh_shape_swapped, _wh_affine, _wh_nearest, _wh_grid_swapped],
    allowed=("warp.bilinear_sample",),
)


# --------------------------------------------------------------------------------------------
# warp.undistort_image (§8.4.1)
# --------------------------------------------------------------------------------------------
def _ui_sample(image, A, su, sv, clamp=False):
    img = np.asarray(image)
    rows, cols = img.shape[:2]
    su, sv = su.reshape(rows, cols), sv.reshape(rows, cols)
    if clamp:
        su, sv = np.clip(su, 0, cols - 1), np.clip(sv, 0, rows - 1)
    return _bilinear_sample(image, su, sv, 0.0)


def _ui_grid(image, A):
    A = np.asarray(A, dtype=np.float64)
    A = A / A[2, 2]
    rows, cols = np.asarray(image).shape[:2]
    u, v = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
    y = (v - A[1, 2]) / A[1, 1]
    x = (u - A[0, 2] - A[0, 1] * y) / A[0, 0]
    return A, np.column_stack([x.ravel(), y.ravel()])


def _ui_to_pixels(A, xy):
    return A[0, 0] * xy[:, 0] + A[0, 1] * xy[:, 1] + A[0, 2], A[1, 1] * xy[:, 1] + A[1, 2]


@mistake("distortion inverted (undistort_points used for the source)",
         "Map backward: an output (ideal) pixel's source is where the lens MOVES it, A·distort(A⁻¹·(u, v, 1)) "
         "— no inversion of the distortion is needed")
def _ui_inverted(image, A, k, p=(0.0, 0.0)):
    A, xy = _ui_grid(image, A)
    return _ui_sample(image, A, *_ui_to_pixels(A, _undistort_points(xy, k, p)))


@mistake("distortion about the image centre (principal point ignored)",
         "Normalise with A⁻¹: x = (u − u0 − s·y)/fu, y = (v − v0)/fv, with the principal point (u0, v0) of A")
def _ui_image_centre(image, A, k, p=(0.0, 0.0)):
    rows, cols = np.asarray(image).shape[:2]
    A = np.array(A, dtype=np.float64)
    A = A / A[2, 2]
    A[0, 2], A[1, 2] = (cols - 1) / 2, (rows - 1) / 2
    return _undistort_image(image, A, k, p)


@mistake("tangential terms ignored", "Pass p to the distortion model as well")
def _ui_no_tangential(image, A, k, p=(0.0, 0.0)):
    return _undistort_image(image, A, k, (0.0, 0.0))


@mistake("outside samples clamped to the border (no black)", "Pixels whose source is outside the input must be 0")
def _ui_clamped(image, A, k, p=(0.0, 0.0)):
    A, xy = _ui_grid(image, A)
    return _ui_sample(image, A, *_ui_to_pixels(A, _distort(xy, k, p)), clamp=True)


@mistake("distortion in pixel units (not normalised by fu, fv)",
         "Distortion acts on normalised coordinates x = (u − u0)/fu, y = (v − v0)/fv (apply A⁻¹), not on "
         "pixels scaled otherwise")
def _ui_pixels(image, A, k, p=(0.0, 0.0)):
    """Distortion applied to pixel offsets from the principal point divided by the image width."""
    rows, cols = np.asarray(image).shape[:2]
    A = np.asarray(A, dtype=np.float64)
    A = A / A[2, 2]
    u, v = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
    d = _distort(np.column_stack([(u.ravel() - A[0, 2]) / cols, (v.ravel() - A[1, 2]) / cols]), k, p)
    return _ui_sample(image, A, d[:, 0] * cols + A[0, 2], d[:, 1] * cols + A[1, 2])


def _ui_camera(rng, rows, cols, skew=False):
    f = _u(rng, 0.6, 1.0) * cols
    return np.array([[f, _u(rng, 0.5, 2.0) if skew else 0.0, cols / 2 + _u(rng, -3, 3)],
                     [0.0, f * _u(rng, 0.95, 1.05), rows / 2 + _u(rng, -3, 3)], [0.0, 0.0, 1.0]])


def _ui_public():
    rng = np.random.default_rng(80403)
    A1 = np.array([[16.0, 0.0, 13.5], [0.0, 17.0, 8.0], [0.0, 0.0, 1.0]])
    A2 = np.array([[14.0, 0.8, 9.0], [0.0, 13.0, 8.5], [0.0, 0.0, 1.0]])
    return [
        Case((_texture(rng, 18, 24), A1, (-0.3, 0.08)), {}, "18×24 grey, barrel k = (−0.3, 0.08), principal point off-centre"),
        Case((_texture(rng, 16, 20, color=True), A2, (0.35,), (0.015, -0.01)), {},
             "16×20 RGB, pincushion k1 = 0.35, tangential p, skew"),
    ]


def _ui_hidden(rng):
    def case(label, color=False, dtype="float", skew=False, k=None, p=(0.0, 0.0), as_kwarg=False):
        r, c = int(rng.integers(12, 20)), int(rng.integers(14, 24))
        A = _ui_camera(rng, r, c, skew)
        k = (-_u(rng, 0.2, 0.4), _u(rng, 0.02, 0.1)) if k is None else k
        args = (_texture(rng, r, c, color=color, dtype=dtype), A, k)
        if as_kwarg:
            return Case(args, {"p": p}, label)
        return Case(args + ((p,) if any(p) else ()), {}, label)

    return [
        case("barrel, two radial terms"),
        case("pincushion, one radial term", k=(_u(rng, 0.2, 0.4),)),
        case("three radial terms", k=(-_u(rng, 0.2, 0.3), _u(rng, 0.02, 0.08), -_u(rng, 0.005, 0.02))),
        case("tangential terms", p=(_u(rng, 0.005, 0.02), -_u(rng, 0.005, 0.02))),
        case("tangential terms as keyword", p=(-_u(rng, 0.005, 0.02), _u(rng, 0.005, 0.02)), as_kwarg=True),
        case("skewed camera", skew=True, k=(_u(rng, 0.15, 0.3),)),
        case("RGB image", color=True),
        case("uint8 image", dtype="uint8", k=(_u(rng, 0.2, 0.35), -_u(rng, 0.01, 0.03))),
        case("no distortion (k = 0): identity", k=(0.0,)),
        case("strong pincushion with tangential terms", k=(_u(rng, 0.35, 0.5),), p=(0.01, 0.01)),
    ]


undistort_image = Check(
    public=_ui_public,
    hidden=_ui_hidden,
    compare=WarpClose(sources=_undistort_sources),
    mistakes=[_ui_inverted, _ui_image_centre, _ui_no_tangential, _ui_clamped, _ui_pixels],
    allowed=("warp.bilinear_sample", "camera.distort"),
)


# --------------------------------------------------------------------------------------------
# warp.rotation_homography (§8.4.3)
# --------------------------------------------------------------------------------------------
def _rot_probes(case):
    A = np.asarray(case.args[0], dtype=np.float64)
    A = A / A[2, 2]
    offsets = np.array([[0.0, 0.0], [-0.3, -0.2], [0.3, -0.2], [0.3, 0.2], [-0.3, 0.2], [0.1, 0.05]])
    return np.column_stack([A[0, 2] + offsets[:, 0] * A[0, 0], A[1, 2] + offsets[:, 1] * A[1, 1]])


@mistake("A⁻¹·R·A (inverted the wrong way)",
         "A pixel m is back-projected by A⁻¹, rotated by R, re-projected by A: H = A·R·A⁻¹")
def _rh_wrong_way(A, R):
    A = np.asarray(A, dtype=np.float64)
    H = np.linalg.inv(A) @ np.asarray(R, dtype=np.float64) @ A
    return H / H[2, 2]


@mistake("Rᵀ used (the opposite rotation)", "Use R itself: M_C′ = R·M_C")
def _rh_transposed(A, R):
    return _rotation_homography(A, np.asarray(R, dtype=np.float64).T)


@mistake("not scaled to H[2, 2] = 1", "Divide H by H[2, 2]")
def _rh_not_scaled(A, R):
    A = np.asarray(A, dtype=np.float64)
    return A @ np.asarray(R, dtype=np.float64) @ np.linalg.inv(A)


@mistake("A⁻¹ missing (H = A·R)", "First go back from pixels to rays with A⁻¹: H = A·R·A⁻¹")
def _rh_no_inverse(A, R):
    H = np.asarray(A, dtype=np.float64) @ np.asarray(R, dtype=np.float64)
    return H / H[2, 2]


def _rot_camera(rng, skew=False, scale=1.0):
    fu = _u(rng, 400, 1200, 1)
    return np.array([[fu, _u(rng, 0.5, 3.0) if skew else 0.0, _u(rng, 250, 400, 1)],
                     [0.0, fu * _u(rng, 0.9, 1.1), _u(rng, 180, 300, 1)], [0.0, 0.0, 1.0]]) * scale


def _small_rotation(rng, limit=0.35):
    return _rotation_matrix(*rng.uniform(-limit, limit, 3))


def _roh_public():
    A = np.array([[800.0, 0.0, 330.0], [0.0, 780.0, 245.0], [0.0, 0.0, 1.0]])
    A2 = np.array([[600.0, 2.0, 300.0], [0.0, 650.0, 220.0], [0.0, 0.0, 1.0]])
    return [
        Case((A, _rotation_matrix(0.1, -0.2, 0.3)), {}, "camera rotated about all three axes"),
        Case((A2, _rotation_matrix(-0.15, 0.1, 0.0)), {}, "skewed camera, pitch and roll"),
    ]


def _roh_hidden(rng):
    return [
        Case((_rot_camera(rng), _small_rotation(rng)), {}, "small rotation"),
        Case((_rot_camera(rng, skew=True), _small_rotation(rng)), {}, "skewed camera"),
        Case((_rot_camera(rng), _rotation_matrix(0.0, _u(rng, 0.1, 0.5), 0.0)), {}, "pan (yaw of the camera)"),
        Case((_rot_camera(rng), _rotation_matrix(_u(rng, 0.1, 0.5), 0.0, 0.0)), {}, "tilt (pitch of the camera)"),
        Case((_rot_camera(rng), _rotation_matrix(0.0, 0.0, _u(rng, 0.3, 1.5))), {}, "about the optical axis only"),
        Case((_rot_camera(rng), np.eye(3)), {}, "no rotation (identity)"),
        Case((_rot_camera(rng), _small_rotation(rng, 1.0)), {}, "large rotation (up to 1 rad per axis)"),
        Case((np.round(_rot_camera(rng)).astype(np.int64), _small_rotation(rng)), {}, "integer intrinsics"),
        Case((_rot_camera(rng, scale=2.0), _small_rotation(rng)), {}, "A with A[2, 2] = 2"),
        Case((_rot_camera(rng).tolist(), _small_rotation(rng).tolist()), {}, "nested lists"),
    ]


rotation_homography = Check(
    public=_roh_public,
    hidden=_roh_hidden,
    compare=HomographyClose(atol=1e-6, rtol=1e-9, probes=_rot_probes),
    mistakes=[_rh_wrong_way, _rh_transposed, _rh_not_scaled, _rh_no_inverse],
)


# --------------------------------------------------------------------------------------------
# warp.birds_eye_homography (§8.4.3)
# --------------------------------------------------------------------------------------------
def _be_exact(src, dst):
    """The exact 4-point homography src → dst (8×8 linear system)."""
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    M, b = [], []
    for (x, y), (u, v) in zip(src, dst):
        M.append([x, y, 1, 0, 0, 0, -u * x, -u * y])
        M.append([0, 0, 0, x, y, 1, -v * x, -v * y])
        b += [u, v]
    return np.append(np.linalg.solve(np.array(M), np.array(b)), 1.0).reshape(3, 3)


@mistake("pixels_per_unit ignored", "The destination of image point i is ground_points[i]·pixels_per_unit")
def _be_no_scale(image_points, ground_points, pixels_per_unit):
    return _be_exact(image_points, ground_points)


@mistake("direction inverted (ground → image)",
         "H maps image points to the bird's-eye view: src = image_points, dst = ground_points·scale")
def _be_inverted(image_points, ground_points, pixels_per_unit):
    return _be_exact(np.asarray(ground_points, dtype=np.float64) * float(pixels_per_unit), image_points)


@mistake("ground x and y swapped", "Keep the ground points' (x, y) order")
def _be_xy_swapped(image_points, ground_points, pixels_per_unit):
    return _be_exact(image_points, np.asarray(ground_points, dtype=np.float64)[:, ::-1] * float(pixels_per_unit))


@mistake("not scaled to H[2, 2] = 1", "Divide H by H[2, 2]")
def _be_not_scaled(image_points, ground_points, pixels_per_unit):
    H = _birds_eye_homography(image_points, ground_points, pixels_per_unit)
    return H / np.linalg.norm(H)


@mistake("scale applied to the image points",
         "Scale the GROUND points (metres → pixels of the bird's-eye image), not the image points")
def _be_scale_on_image(image_points, ground_points, pixels_per_unit):
    return _be_exact(np.asarray(image_points, dtype=np.float64) * float(pixels_per_unit), ground_points)


def _road(rng):
    """Four image points of a rectangle on the road seen by a forward-looking camera."""
    f = _u(rng, 500, 900, 1)
    A = np.array([[f, 0.0, _u(rng, 300, 340, 1)], [0.0, f, _u(rng, 220, 260, 1)], [0.0, 0.0, 1.0]])
    pitch = _u(rng, 0.05, 0.25)
    height = _u(rng, 1.2, 1.8)
    # world: x right, y forward, z up; camera looks along +y, tilted down by `pitch`
    c, s = np.cos(pitch), np.sin(pitch)
    R = np.array([[1.0, 0.0, 0.0], [0.0, -s, -c], [0.0, c, -s]])
    t = -R @ np.array([0.0, 0.0, height])
    x0, y0 = _u(rng, -2.0, 0.0, 2), _u(rng, 4.0, 8.0, 2)
    w, d = _u(rng, 2.0, 4.0, 2), _u(rng, 5.0, 15.0, 2)
    ground = np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + d], [x0, y0 + d]])
    cam = np.column_stack([ground, np.zeros(4)]) @ R.T + t
    pixels = (cam @ A.T)[:, :2] / cam[:, 2:]
    return np.round(pixels, 3), ground


def _be_public():
    image = np.array([[280.0, 400.0], [380.0, 405.0], [345.0, 300.0], [305.0, 298.0]])
    ground = np.array([[0.0, 0.0], [3.5, 0.0], [3.5, 12.0], [0.0, 12.0]])
    return [Case((image, ground, 20.0), {}, "a lane seen in perspective → 3.5 m × 12 m, 20 px/m")]


def _be_hidden(rng):
    cases = []
    for label, ppu in (("road rectangle, 10 px/m", 10.0), ("road rectangle, 25.5 px/m", 25.5),
                       ("integer pixels per unit", 40), ("fine scale (100 px/m)", 100.0)):
        image, ground = _road(rng)
        cases.append(Case((image, ground, ppu), {}, label))
    image, ground = _road(rng)
    cases.append(Case((np.round(image).astype(np.int64), ground, _u(rng, 5, 30, 1)), {}, "integer image points"))
    image, ground = _road(rng)
    cases.append(Case((image.tolist(), ground.tolist(), _u(rng, 5, 30, 1)), {}, "lists"))
    image, _ = _road(rng)
    quad = np.array([[0.0, 0.0], [_u(rng, 2, 4), _u(rng, -0.5, 0.5)], [_u(rng, 2, 4), _u(rng, 6, 10)],
                     [_u(rng, -0.5, 0.5), _u(rng, 6, 10)]])
    cases.append(Case((image, quad, _u(rng, 10, 30, 1)), {}, "ground points not a rectangle"))
    image, ground = _road(rng)
    cases.append(Case((image, ground * 1000.0, _u(rng, 0.01, 0.05, 3)), {}, "ground in mm, 0.02 px/mm"))
    image, ground = _road(rng)
    cases.append(Case((image, ground - [5.0, 0.0], _u(rng, 10, 30, 1)), {}, "negative ground x (left of the origin)"))
    return cases


birds_eye_homography = Check(
    public=_be_public,
    hidden=_be_hidden,
    compare=HomographyClose(atol=1e-6, rtol=1e-9),
    mistakes=[_be_no_scale, _be_inverted, _be_xy_swapped, _be_not_scaled, _be_scale_on_image],
    allowed=("calibration.homography_dlt",),
)
