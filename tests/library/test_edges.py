"""Chapter 4 edge detection (cvkit.edges) against OpenCV / SciPy / scikit-image oracles and
brute-force definitions, plus properties, the provider switch and bad input.

Parameter mappings (cvkit -> oracle):
- border: zero -> cv2.BORDER_CONSTANT / scipy "constant", replicate -> BORDER_REPLICATE /
  "nearest", reflect -> BORDER_REFLECT / "reflect", reflect101 -> BORDER_REFLECT_101 / "mirror".
- sobel(I) -> cv2.Sobel(I, CV_64F, 1, 0 | 0, 1, ksize=3) = scipy.ndimage.sobel(I, axis=1 | 0).
- prewitt(I) -> cv2.filter2D with [[-1,0,1]]*3 and its transpose (correlation, anchor centre).
- gradient(scheme) -> cv2.filter2D with [-1, 0, 1]/2 (anchor 1), [-1, 1] (anchor 0: forward,
  anchor 1: backward); central equals numpy.gradient away from the border.
- laplacian(I) -> cv2.Laplacian(I, CV_64F, ksize=1) = scipy.ndimage.laplace.
- log(I, σ) -> scipy.ndimage.gaussian_laplace(I, σ) (truncate 4.0, its default). They differ
  by the kernel: ours is the analytic LoG sampled on the (2⌈3σ⌉+1)² square and made zero-mean,
  SciPy's the sum of two separable second derivatives of the sampled, normalised Gaussian cut
  at 4σ. The tail beyond 3σ is missing from ours, so the agreement is *relative*: measured
  max |difference| ≤ 2.9% of max |response| and RMS difference ≤ 3.1% of the RMS response on
  camera and coins for σ ∈ {0.8, …, 3} (tested at 4% / 4%).
- non_max_suppression -> skimage.feature._canny_cy._nonmaximum_suppression_bilinear
  (isobel = iy, jsobel = ix) on all pixels not on the image border (scikit-image masks the
  border out).
- hysteresis -> components of skimage.measure.label(M > low, connectivity=2) containing a pixel
  > high. (skimage.filters.apply_hysteresis_threshold is 4-connected: shown to differ.)
- canny(I, σ, lo, hi) -> skimage.feature.canny(I, σ, lo·max, hi·max) with max our largest
  magnitude: F1 ≥ 0.95 within 1 px required; measured ≥ 0.99 (camera and coins, σ 1–3).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.ndimage as ndi
from hypothesis import given
from hypothesis import strategies as st
from input_helpers import FAST, raises_naming

import cvkit
from cvkit import data, edges, filters, registry
from cvkit.edges.checks import edge_f1

cv2 = pytest.importorskip("cv2")
skimage = pytest.importorskip("skimage")
from skimage import feature, measure  # noqa: E402
from skimage.filters import apply_hysteresis_threshold  # noqa: E402

BORDERS = ("zero", "replicate", "reflect", "reflect101")
CV2_BORDER = {"zero": cv2.BORDER_CONSTANT, "replicate": cv2.BORDER_REPLICATE,
              "reflect": cv2.BORDER_REFLECT, "reflect101": cv2.BORDER_REFLECT_101}
SCIPY_MODE = {"zero": "constant", "replicate": "nearest", "reflect": "reflect", "reflect101": "mirror"}
ATOL = 1e-12


def _rng(seed=0):
    return np.random.default_rng(seed)


def _gray(shape=(13, 17), seed=1):
    return _rng(seed).random(shape)


@pytest.fixture(scope="module")
def camera():
    return data.camera()


@pytest.fixture(scope="module")
def coins():
    return data.coins()


def _filter2d(image, kernel, border, anchor=(-1, -1)):
    return cv2.filter2D(image, cv2.CV_64F, np.asarray(kernel, dtype=np.float64), anchor=anchor,
                        borderType=CV2_BORDER[border]).reshape(image.shape)


# --------------------------------------------------------------------------------------------
# first derivatives vs OpenCV / SciPy
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("shape", [(13, 17), (1, 9), (8, 1), (2, 3)])
def test_sobel_matches_cv2_and_scipy(shape, border):
    image = _gray(shape)
    gx, gy = edges.sobel(image, border)
    assert gx.dtype == gy.dtype == np.float64 and gx.shape == gy.shape == shape
    want_x = cv2.Sobel(image, cv2.CV_64F, 1, 0, ksize=3, borderType=CV2_BORDER[border]).reshape(shape)
    want_y = cv2.Sobel(image, cv2.CV_64F, 0, 1, ksize=3, borderType=CV2_BORDER[border]).reshape(shape)
    np.testing.assert_allclose(gx, want_x, rtol=0, atol=ATOL)
    np.testing.assert_allclose(gy, want_y, rtol=0, atol=ATOL)
    np.testing.assert_allclose(gx, ndi.sobel(image, axis=1, mode=SCIPY_MODE[border]), rtol=0, atol=ATOL)
    np.testing.assert_allclose(gy, ndi.sobel(image, axis=0, mode=SCIPY_MODE[border]), rtol=0, atol=ATOL)


@pytest.mark.parametrize("border", BORDERS)
def test_prewitt_matches_cv2_filter2d(border):
    image = _gray((14, 11), seed=2)
    kx = np.array([[-1, 0, 1]] * 3)
    gx, gy = edges.prewitt(image, border)
    np.testing.assert_allclose(gx, _filter2d(image, kx, border), rtol=0, atol=ATOL)
    np.testing.assert_allclose(gy, _filter2d(image, kx.T, border), rtol=0, atol=ATOL)
    np.testing.assert_allclose(gx, ndi.prewitt(image, axis=1, mode=SCIPY_MODE[border]), rtol=0, atol=ATOL)


def test_the_notes_prewitt_listing_has_y_pointing_up():
    """The notes' kernely [[1,1,1],[0,0,0],[-1,-1,-1]] is our gy negated."""
    image = _gray((9, 10), seed=3)
    notes_kernel_y = np.array([[1, 1, 1], [0, 0, 0], [-1, -1, -1]])
    np.testing.assert_allclose(_filter2d(image, notes_kernel_y, "reflect101"), -edges.prewitt(image)[1], atol=ATOL)


@pytest.mark.parametrize("border", BORDERS)
def test_colour_images_are_filtered_per_channel(border):
    image = _rng(4).random((9, 12, 3))
    for fn in (edges.sobel, edges.prewitt):
        gx, gy = fn(image, border)
        for c in range(3):
            cx, cy = fn(image[..., c], border)
            np.testing.assert_allclose(gx[..., c], cx, atol=ATOL)
            np.testing.assert_allclose(gy[..., c], cy, atol=ATOL)
    lap = edges.laplacian(image, border)
    np.testing.assert_allclose(lap[..., 1], edges.laplacian(image[..., 1], border), atol=ATOL)


@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("scheme, kernel, anchor", [
    ("central", [[-0.5, 0.0, 0.5]], (1, 0)),
    ("forward", [[-1.0, 1.0]], (0, 0)),
    ("backward", [[-1.0, 1.0]], (1, 0)),
])
def test_gradient_matches_cv2_filter2d(scheme, kernel, anchor, border):
    image = _gray((12, 15), seed=5)
    ix, iy = edges.gradient(image, scheme, border)
    kernel = np.array(kernel)
    np.testing.assert_allclose(ix, _filter2d(image, kernel, border, anchor), rtol=0, atol=ATOL)
    np.testing.assert_allclose(iy, _filter2d(image, kernel.T, border, anchor[::-1]), rtol=0, atol=ATOL)


def test_central_gradient_equals_numpy_gradient_inside():
    image = _gray((10, 12), seed=6)
    ix, iy = edges.gradient(image)
    ny, nx = np.gradient(image)
    np.testing.assert_allclose(ix[:, 1:-1], nx[:, 1:-1], atol=ATOL)
    np.testing.assert_allclose(iy[1:-1], ny[1:-1], atol=ATOL)
    assert not np.allclose(ix[:, 0], nx[:, 0])  # numpy.gradient goes one-sided at the border


def test_central_is_the_mean_of_forward_and_backward():
    image = _gray((9, 11), seed=7)
    for border in BORDERS:
        c = edges.gradient(image, "central", border)
        f = edges.gradient(image, "forward", border)
        b = edges.gradient(image, "backward", border)
        np.testing.assert_allclose(c[0], (f[0] + b[0]) / 2, atol=ATOL)
        np.testing.assert_allclose(c[1], (f[1] + b[1]) / 2, atol=ATOL)


def test_derivatives_of_a_ramp():
    """I = 3x − 2y: every scheme gives (3, −2) inside; Sobel 8·(3, −2), Prewitt 6·(3, −2)."""
    y, x = np.mgrid[0:8, 0:9].astype(float)
    ramp = 3 * x - 2 * y
    for scheme in ("central", "forward", "backward"):
        ix, iy = edges.gradient(ramp, scheme)
        np.testing.assert_allclose(ix[1:-1, 1:-1], 3.0)
        np.testing.assert_allclose(iy[1:-1, 1:-1], -2.0)
    gx, gy = edges.sobel(ramp)
    np.testing.assert_allclose(gx[1:-1, 1:-1], 24.0)
    np.testing.assert_allclose(gy[1:-1, 1:-1], -16.0)
    gx, gy = edges.prewitt(ramp)
    np.testing.assert_allclose(gx[1:-1, 1:-1], 18.0)


def test_magnitude_matches_cv2_and_formulas():
    ix, iy = _rng(8).normal(size=(2, 20, 30))
    np.testing.assert_allclose(edges.magnitude(ix, iy), cv2.magnitude(ix, iy), rtol=1e-14)
    np.testing.assert_allclose(edges.magnitude(ix, iy, "l1"), np.abs(ix) + np.abs(iy), rtol=1e-15)
    np.testing.assert_allclose(edges.magnitude(ix, iy, "max"), np.maximum(np.abs(ix), np.abs(iy)), rtol=1e-15)
    assert edges.magnitude(ix.astype(np.int64), iy.astype(np.int64)).dtype == np.float64


def test_magnitude_neither_overflows_nor_underflows():
    big = edges.magnitude([3e200, -3e-200, 0.0], [4e200, 4e-200, 0.0])
    np.testing.assert_allclose(big, [5e200, 5e-200, 0.0], rtol=1e-15)


def test_norms_on_rotated_gradients():
    """A gradient of length 1 at angle θ: l2 = 1, l1 = |cos| + |sin|, max = max(|cos|, |sin|)."""
    theta = np.linspace(-np.pi, np.pi, 73)
    ix, iy = np.cos(theta), np.sin(theta)
    np.testing.assert_allclose(edges.magnitude(ix, iy), 1.0, rtol=1e-15)
    assert math.isclose(edges.magnitude(ix, iy, "l1").max(), math.sqrt(2), rel_tol=1e-12)
    assert math.isclose(edges.magnitude(ix, iy, "max").min(), 1 / math.sqrt(2), rel_tol=1e-12)


def test_direction_matches_arctan2_and_cv2_phase_modulo_2pi():
    ix, iy = _rng(9).normal(size=(2, 15, 16))
    theta = edges.direction(ix, iy)
    np.testing.assert_array_equal(theta, np.arctan2(iy, ix))
    assert theta.min() >= -np.pi and theta.max() <= np.pi
    phase = cv2.phase(ix, iy)  # [0, 2π)
    # cv2.phase uses a fast approximation (OpenCV documents about 0.3°); measured error 1.6e-4 rad
    np.testing.assert_allclose(np.mod(theta - phase + np.pi, 2 * np.pi) - np.pi, 0.0, atol=1e-3)


# --------------------------------------------------------------------------------------------
# second derivatives
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("shape", [(11, 14), (1, 7), (2, 3)])
def test_laplacian_matches_cv2_and_scipy(shape, border):
    image = _gray(shape, seed=10)
    got = edges.laplacian(image, border)
    want = cv2.Laplacian(image, cv2.CV_64F, ksize=1, borderType=CV2_BORDER[border]).reshape(shape)
    np.testing.assert_allclose(got, want, rtol=0, atol=ATOL)
    np.testing.assert_allclose(got, ndi.laplace(image, mode=SCIPY_MODE[border]), rtol=0, atol=ATOL)


@pytest.mark.parametrize("sigma", [0.5, 0.8, 1.0, 1.4, 2.0, 7 / 3, 3.0])
def test_log_kernel_formula_and_properties(sigma):
    k = edges.log_kernel(sigma)
    r = math.ceil(3 * sigma - 1e-9)
    assert k.shape == (2 * r + 1, 2 * r + 1) and k.dtype == np.float64
    assert abs(k.sum()) < 1e-15 * k.size
    np.testing.assert_array_equal(k, k.T)
    np.testing.assert_array_equal(k, k[::-1, ::-1])
    assert k[r, r] == k.min() < 0
    x = np.arange(-r, r + 1)
    r2 = x[:, None] ** 2 + x[None, :] ** 2
    raw = (r2 - 2 * sigma**2) / (2 * np.pi * sigma**6) * np.exp(-r2 / (2 * sigma**2))
    np.testing.assert_allclose(k, raw - raw.mean(), rtol=1e-12, atol=1e-16)


def test_log_kernel_radius():
    assert edges.log_kernel(1.0, radius=2).shape == (5, 5)
    np.testing.assert_array_equal(edges.log_kernel(2.0, radius=0), [[0.0]])


@pytest.mark.parametrize("sigma", [0.8, 1.0, 1.5, 2.0, 3.0])
def test_log_agrees_with_scipy_gaussian_laplace(sigma, camera, coins):
    """Relative agreement only: our kernel is cut at ⌈3σ⌉ and made zero-mean (see module doc)."""
    for image in (camera, coins):
        ours = edges.log(image, sigma)
        ref = ndi.gaussian_laplace(image, sigma, mode="mirror")
        assert np.abs(ours - ref).max() <= 0.04 * np.abs(ref).max()
        assert np.sqrt(np.mean((ours - ref) ** 2)) <= 0.04 * np.sqrt(np.mean(ref**2))


@pytest.mark.parametrize("border", BORDERS)
def test_log_is_correlation_with_the_kernel(border):
    image = _gray((12, 13), seed=11)
    np.testing.assert_allclose(edges.log(image, 1.2, border),
                               ndi.correlate(image, edges.log_kernel(1.2), mode=SCIPY_MODE[border]), rtol=0, atol=1e-12)


@pytest.mark.parametrize("border", BORDERS)
def test_dog_matches_scipy_gaussian_difference(border):
    image = _gray((15, 14), seed=12)
    sigma, k = 1.1, 1.6
    def g(s):
        r = math.ceil(3 * s - 1e-9)
        return ndi.gaussian_filter(image, s, mode=SCIPY_MODE[border], truncate=r / s)
    np.testing.assert_allclose(edges.dog(image, sigma, k, border), g(k * sigma) - g(sigma), rtol=0, atol=1e-12)


def test_dog_approximates_a_scaled_log(camera):
    """G_kσ − G_σ ≈ (k − 1)σ²·∇²G: near-perfect correlation for k close to 1."""
    crop = camera[100:300, 100:300]
    sigma = 2.0
    for k, floor in ((1.1, 0.99), (1.6, 0.95)):
        d = edges.dog(crop, sigma, k)
        lg = edges.log(crop, sigma * math.sqrt(k))
        corr = np.corrcoef(d.ravel(), lg.ravel())[0, 1]
        assert corr > floor
        scale = np.sum(d * lg) / np.sum(lg * lg)
        assert 0.7 * (k - 1) * k * sigma**2 < scale < 1.3 * (k - 1) * k * sigma**2


def _zero_crossings_brute(r, threshold):
    h, w = r.shape
    out = np.zeros((h, w), dtype=bool)
    for i in range(h):
        for j in range(w):
            for di, dj in ((0, 1), (1, 0)):
                if i + di < h and j + dj < w:
                    a, b = r[i, j], r[i + di, j + dj]
                    if a * b < 0 and abs(a - b) > threshold:
                        out[(i, j) if abs(a) <= abs(b) else (i + di, j + dj)] = True
    return out


@pytest.mark.parametrize("threshold", [0.0, 0.5, 2.0])
def test_zero_crossings_brute_force(threshold):
    for seed in range(3):
        r = np.round(_rng(seed).normal(0, 2, (12, 14)))  # integers: zeros and ties
        np.testing.assert_array_equal(edges.zero_crossings(r, threshold), _zero_crossings_brute(r, threshold))


def test_zero_crossings_of_the_log_trace_a_disk():
    """The LoG zero crossings of a disk lie on a circle of its radius (within a pixel), once a
    small threshold drops the weak crossings that the truncated kernel's tails make ~6 px away."""
    cx, cy, radius = 31.3, 29.6, 17.2
    disk = data.disk_image((64, 64), centre=(cx, cy), radius=radius)
    response = edges.log(disk, 1.5)
    far = edges.zero_crossings(response, threshold=1e-3)
    ys, xs = np.nonzero(far)
    assert np.abs(np.hypot(xs - cx, ys - cy) - radius).max() > 5  # the tails' crossings
    crossings = edges.zero_crossings(response, threshold=0.05 * np.abs(response).max())
    ys, xs = np.nonzero(crossings)
    distance = np.hypot(xs - cx, ys - cy) - radius
    assert len(xs) > 2 * np.pi * radius * 0.9
    assert np.abs(distance).max() < 1.0


# --------------------------------------------------------------------------------------------
# NMS, hysteresis, Canny vs scikit-image
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def camera_gradient(camera):
    smooth = filters.gaussian(camera, 1.4)
    gx, gy = edges.sobel(smooth)
    return edges.magnitude(gx, gy), gx, gy


def test_nms_equals_scikit_image_inside(camera_gradient):
    from skimage.feature._canny_cy import _nonmaximum_suppression_bilinear

    mag, gx, gy = camera_gradient
    inside = np.ones(mag.shape, np.uint8)
    inside[0] = inside[-1] = 0
    inside[:, 0] = inside[:, -1] = 0
    want = _nonmaximum_suppression_bilinear(np.ascontiguousarray(gy), np.ascontiguousarray(gx), mag, inside, 0.0)
    got = edges.non_max_suppression(mag, gx, gy)
    np.testing.assert_array_equal(got[1:-1, 1:-1], np.asarray(want)[1:-1, 1:-1])
    assert np.count_nonzero(got[0]) > 0  # the border is not suppressed wholesale


def _nms_brute(mag, gx, gy, interpolate):
    h, w = mag.shape
    out = np.zeros_like(mag)

    def at(r, c):
        return mag[r, c] if 0 <= r < h and 0 <= c < w else 0.0

    for r in range(h):
        for c in range(w):
            if mag[r, c] <= 0 or (gx[r, c] == 0 and gy[r, c] == 0):
                continue
            if interpolate:
                t = math.atan2(gy[r, c], gx[r, c])
                dx, dy = math.cos(t), math.sin(t)  # one step along the unit gradient...
                scale = 1 / max(abs(dx), abs(dy))  # ...stretched to the next row or column
                sides = []
                for s in (1, -1):
                    x, y = s * dx * scale, s * dy * scale  # on the square ring of radius 1
                    # bilinear interpolation between the two ring pixels around (x, y)
                    if abs(x) >= abs(y):
                        c0, f = int(round(x)), y - math.floor(y)
                        sides.append((1 - f) * at(r + math.floor(y), c + c0) + f * at(r + math.floor(y) + 1, c + c0))
                    else:
                        r0, f = int(round(y)), x - math.floor(x)
                        sides.append((1 - f) * at(r + r0, c + math.floor(x)) + f * at(r + r0, c + math.floor(x) + 1))
            else:
                angle = math.degrees(math.atan2(gy[r, c], gx[r, c])) % 180
                dy, dx = [(0, 1), (1, 1), (1, 0), (1, -1)][int((angle + 22.5) // 45) % 4]
                sides = [at(r + dy, c + dx), at(r - dy, c - dx)]
            if mag[r, c] >= max(sides) - 1e-12:
                out[r, c] = mag[r, c]
    return out


@pytest.mark.parametrize("interpolate", [True, False])
def test_nms_brute_force_on_a_random_field(interpolate):
    """Interpolation at the point where the gradient line leaves the 3×3 square (the
    definition of the catalog, written geometrically) on a field without ties."""
    rng = _rng(13)
    gx, gy = rng.normal(size=(2, 14, 17))
    mag = np.hypot(gx, gy)
    np.testing.assert_array_equal(edges.non_max_suppression(mag, gx, gy, interpolate),
                                  _nms_brute(mag, gx, gy, interpolate))


def test_nms_uses_the_magnitude_it_is_given():
    gx, gy = _rng(14).normal(size=(2, 9, 9))
    mag = _rng(15).random((9, 9))
    out = edges.non_max_suppression(mag, gx, gy)
    kept = out > 0
    np.testing.assert_array_equal(out[kept], mag[kept])
    np.testing.assert_array_equal(out, _nms_brute(mag, gx, gy, True))


def test_nms_keeps_plateaus_and_drops_zero_gradients():
    mag = np.array([[1.0, 3.0, 3.0, 1.0]])
    np.testing.assert_array_equal(edges.non_max_suppression(mag, np.ones((1, 4)), np.zeros((1, 4))), [[0, 3, 3, 0]])
    np.testing.assert_array_equal(edges.non_max_suppression(mag, np.zeros((1, 4)), np.zeros((1, 4))), 0.0)
    # without interpolation a zero gradient has the angle atan2(0, 0) = 0: left and right decide
    zero = np.zeros((1, 3))
    np.testing.assert_array_equal(edges.non_max_suppression([[0.0, 1.0, 0.0]], zero, zero, False), [[0, 1, 0]])
    np.testing.assert_array_equal(edges.non_max_suppression(np.ones((3, 1)), zero.T, zero.T, False), [[1], [1], [1]])


def _hysteresis_by_labels(mag, low, high, connectivity=2):
    labels = measure.label(mag > low, connectivity=connectivity)
    good = np.unique(labels[mag > high])
    return np.isin(labels, good[good > 0])


def test_hysteresis_equals_8_connected_labelling(camera_gradient):
    thin = edges.non_max_suppression(*camera_gradient)
    top = thin.max()
    for low, high in ((0.05, 0.15), (0.1, 0.2), (0.2, 0.6)):
        got = edges.hysteresis(thin, low * top, high * top)
        assert got.dtype == bool
        np.testing.assert_array_equal(got, _hysteresis_by_labels(thin, low * top, high * top))


def test_hysteresis_on_random_integers_with_ties():
    for seed in range(5):
        mag = _rng(seed).integers(0, 6, (30, 40)).astype(float)
        np.testing.assert_array_equal(edges.hysteresis(mag, 2, 4), _hysteresis_by_labels(mag, 2, 4))


def test_skimage_apply_hysteresis_threshold_is_4_connected():
    """The diagonal chain is linked by our 8-connected hysteresis, not by scikit-image's."""
    mag = np.diag([5.0, 2.0, 2.0, 2.0])
    ours = edges.hysteresis(mag, 1.0, 4.0)
    theirs = apply_hysteresis_threshold(mag, 1.0, 4.0)
    np.testing.assert_array_equal(ours, np.eye(4, dtype=bool))
    np.testing.assert_array_equal(theirs, np.diag([True, False, False, False]))
    np.testing.assert_array_equal(theirs, _hysteresis_by_labels(mag, 1.0, 4.0, connectivity=1))


def test_hysteresis_links_a_long_spiral():
    """A chain hundreds of pixels long is linked (no fixed number of dilations)."""
    n = 41
    mag = np.zeros((n, n))
    top, left, bottom, right = 0, 0, n - 1, n - 1
    while top <= bottom and left <= right:  # a square spiral, 2 px apart
        mag[top, left:right + 1] = 2
        mag[top:bottom + 1, right] = 2
        mag[bottom, left:right + 1] = 2
        mag[top + 2:bottom + 1, left] = 2
        top, left, bottom, right = top + 2, left + 2, bottom - 2, right - 2
        if top <= bottom:
            mag[top, left - 1] = 2
    mag[0, 0] = 9
    np.testing.assert_array_equal(edges.hysteresis(mag, 1, 5), mag > 1)


def test_hysteresis_empty_and_equal_thresholds():
    mag = _rng(3).random((8, 9))
    assert not edges.hysteresis(mag, 0.5, 2.0).any()
    np.testing.assert_array_equal(edges.hysteresis(mag, 0.5, 0.5), mag > 0.5)


@pytest.mark.parametrize("sigma", [1.0, 1.4, 2.0, 3.0])
@pytest.mark.parametrize("thresholds", [(0.1, 0.2), (0.05, 0.15)])
def test_canny_agrees_with_scikit_image(sigma, thresholds, camera, coins):
    low, high = thresholds
    for image in (camera, coins):
        ours = edges.canny(image, sigma, low, high)
        top = edges.magnitude(*edges.sobel(filters.gaussian(image, sigma))).max()
        theirs = feature.canny(image, sigma, low * top, high * top)
        f1, precision, recall = edge_f1(ours, theirs, radius=1)
        assert f1 >= 0.95, (f1, precision, recall)
        assert f1 >= 0.98  # what we measure (≥ 0.99): a regression guard


def test_canny_absolute_thresholds_and_uint8(camera):
    u8 = np.round(camera * 255).astype(np.uint8)
    rel = edges.canny(camera, 1.4, 0.1, 0.2)
    top = edges.magnitude(*edges.sobel(filters.gaussian(u8, 1.4))).max()
    absolute = edges.canny(u8, 1.4, 0.1 * top, 0.2 * top, relative=False)
    assert edge_f1(absolute, rel, 0)[0] > 0.99
    np.testing.assert_array_equal(edges.canny(u8, 1.4), edges.canny(u8.astype(float), 1.4))


def test_canny_of_constant_images_is_empty():
    for value in (0.0, 0.37, 200.0, -3e5):
        out = edges.canny(np.full((20, 24), value))
        assert out.dtype == bool and not out.any()


def test_canny_finds_a_disk_within_a_pixel():
    cx, cy, radius = 40.4, 38.7, 22.3
    disk = data.disk_image((80, 82), centre=(cx, cy), radius=radius, inside=0.8, outside=0.2)
    ys, xs = np.nonzero(edges.canny(disk, 1.4))
    assert np.abs(np.hypot(xs - cx, ys - cy) - radius).max() < 1.0
    assert len(xs) > 2 * np.pi * radius * 0.95


def test_canny_is_not_rotation_biased_like_l1():
    """On a disk with tight relative thresholds, L2 keeps the whole contour."""
    disk = data.disk_image((60, 60), centre=(30.3, 29.6), radius=20.7, inside=0.85, outside=0.1)
    out = edges.canny(disk, 1.5, 0.85, 0.88)
    ys, xs = np.nonzero(out)
    angles = np.degrees(np.arctan2(ys - 29.6, xs - 30.3))
    assert np.histogram(angles, bins=12, range=(-180, 180))[0].min() > 0


# --------------------------------------------------------------------------------------------
# properties
# --------------------------------------------------------------------------------------------
def test_inputs_are_not_modified():
    image = _gray((10, 11), seed=16)
    before = image.copy()
    gx, gy = edges.sobel(image)
    edges.prewitt(image), edges.gradient(image), edges.laplacian(image), edges.log(image, 1.0), edges.dog(image, 1.0)
    mag = edges.magnitude(gx, gy)
    gxc, gyc, magc = gx.copy(), gy.copy(), mag.copy()
    edges.direction(gx, gy)
    thin = edges.non_max_suppression(mag, gx, gy)
    thinc = thin.copy()
    edges.hysteresis(thin, 0.1, 0.5)
    edges.zero_crossings(gx)
    edges.canny(image)
    np.testing.assert_array_equal(image, before)
    np.testing.assert_array_equal(gx, gxc)
    np.testing.assert_array_equal(gy, gyc)
    np.testing.assert_array_equal(mag, magc)
    np.testing.assert_array_equal(thin, thinc)
    assert not np.shares_memory(edges.non_max_suppression(mag, gx, gy), mag)


def test_uint8_is_not_rescaled():
    image = np.zeros((6, 8), np.uint8)
    image[:, 4:] = 200
    gx, _ = edges.sobel(image)
    assert gx.dtype == np.float64 and gx.max() == 800.0
    assert edges.laplacian(image).max() == 200.0
    np.testing.assert_array_equal(edges.gradient(image, "forward")[0][:, 3], 200.0)


def test_algorithms_are_registered_with_sections_and_checks():
    expected = {
        "gradient": "4.5", "magnitude": "4.5", "direction": "4.3", "prewitt": "4.7", "sobel": "4.7",
        "non_max_suppression": "4.8", "hysteresis": "4.10", "canny": "4.10", "laplacian": "4.12",
        "log_kernel": "4.12", "log": "4.12", "zero_crossings": "4.11", "dog": "4.12", "detect_outlines": "4.10",
    }
    assert set(edges.__all__) == set(expected)
    for name, section in expected.items():
        record = registry.get(f"edges.{name}")
        assert record.section == section
        assert record.reference is getattr(edges, name)
        assert record.check is getattr(__import__("cvkit.edges.checks", fromlist=[name]), name)


# --------------------------------------------------------------------------------------------
# the provider switch
# --------------------------------------------------------------------------------------------
@pytest.fixture
def student_provider():
    prov = registry.provider("student")
    prov.clear()
    yield prov
    prov.clear()


def test_canny_calls_its_building_blocks_through_the_registry(student_provider):
    image = data.disk_image((30, 32), centre=(15.2, 14.7), radius=9.1)
    reference = edges.canny(image, 1.2)
    calls = []

    def spy(algorithm_id):
        original = registry.get(algorithm_id).reference

        def wrapper(*args, **kwargs):
            calls.append(algorithm_id)
            return original(*args, **kwargs)
        registry.student(algorithm_id)(wrapper)

    for algorithm_id in ("filters.gaussian", "edges.sobel", "edges.magnitude",
                         "edges.non_max_suppression", "edges.hysteresis"):
        spy(algorithm_id)
    with cvkit.use("student"):
        np.testing.assert_array_equal(edges.canny(image, 1.2), reference)
    assert calls == ["filters.gaussian", "edges.sobel", "edges.magnitude", "edges.non_max_suppression",
                     "edges.hysteresis"]
    calls.clear()
    edges.canny(image, 1.2)
    assert calls == []  # outside the block the reference pieces are used


def test_a_wrong_student_piece_changes_canny(student_provider):
    image = data.disk_image((40, 40), centre=(20.3, 19.6), radius=12.7, inside=0.85, outside=0.1)
    reference = edges.canny(image, 1.5, 0.83, 0.87)
    registry.student("edges.magnitude")(lambda ix, iy, norm="l2": np.abs(ix) + np.abs(iy))
    with cvkit.use("student"):
        with_l1 = edges.canny(image, 1.5, 0.83, 0.87)
    assert edge_f1(with_l1, reference, 0)[0] < 0.95


def test_log_dog_and_derivatives_use_the_registry(student_provider):
    image = _gray((9, 10), seed=17)
    registry.student("filters.pad")(lambda img, radius, border="reflect101": filters.pad(img, radius, "zero"))
    with cvkit.use("student"):
        np.testing.assert_allclose(edges.sobel(image)[0], edges.sobel(image, "zero")[0])
        np.testing.assert_allclose(edges.laplacian(image), edges.laplacian(image, "zero"))
    registry.student("edges.log_kernel")(lambda sigma, radius=None: np.ones((3, 3)))
    with cvkit.use("student"):
        np.testing.assert_allclose(edges.log(image, 1.0), ndi.correlate(image, np.ones((3, 3)), mode="constant"))
    registry.student("filters.gaussian")(lambda img, sigma, border="reflect101": np.full(np.shape(img), sigma))
    with cvkit.use("student"):
        np.testing.assert_allclose(edges.dog(image, 1.0, 2.0), 1.0)


# --------------------------------------------------------------------------------------------
# bad input (hypothesis)
# --------------------------------------------------------------------------------------------
GOOD = np.zeros((6, 7))


IMAGE_CALLS = [
    lambda im: edges.gradient(im),
    lambda im: edges.sobel(im),
    lambda im: edges.prewitt(im),
    lambda im: edges.laplacian(im),
    lambda im: edges.log(im, 1.0),
    lambda im: edges.dog(im, 1.0),
    lambda im: edges.canny(im),
]
bad_ndim_shapes = st.one_of(
    st.lists(st.integers(1, 3), min_size=0, max_size=1),
    st.lists(st.integers(1, 3), min_size=4, max_size=5),
    st.tuples(st.integers(1, 3), st.integers(1, 3), st.integers(1, 5).filter(lambda c: c != 3)),
).map(tuple)


@FAST
@given(shape=bad_ndim_shapes, which=st.integers(0, len(IMAGE_CALLS) - 1))
def test_wrong_image_shape(shape, which):
    raises_naming(ValueError, "image", IMAGE_CALLS[which], np.zeros(shape))


def test_canny_refuses_colour():
    raises_naming(ValueError, "image", edges.canny, np.zeros((5, 6, 3)))


@FAST
@given(bad=st.sampled_from([np.nan, np.inf, -np.inf]), pos=st.tuples(st.integers(0, 5), st.integers(0, 6)),
       which=st.integers(0, len(IMAGE_CALLS) - 1))
def test_non_finite_image(bad, pos, which):
    image = np.zeros((6, 7))
    image[pos] = bad
    raises_naming(ValueError, "image", IMAGE_CALLS[which], image)


@FAST
@given(value=st.one_of(st.text(max_size=5), st.just(None), st.just(np.zeros((4, 4), dtype=complex)),
                       st.just(np.array([["a", "b"], ["c", "d"]]))),
       which=st.integers(0, len(IMAGE_CALLS) - 1))
def test_non_numeric_image(value, which):
    raises_naming(TypeError, "image", IMAGE_CALLS[which], value)


@FAST
@given(border=st.one_of(st.text(max_size=12).filter(lambda s: s not in BORDERS), st.integers(), st.none()),
       which=st.integers(0, 5))
def test_bad_border(border, which):
    calls = [
        lambda: edges.gradient(GOOD, border=border), lambda: edges.sobel(GOOD, border=border),
        lambda: edges.prewitt(GOOD, border=border), lambda: edges.laplacian(GOOD, border=border),
        lambda: edges.log(GOOD, 1.0, border=border), lambda: edges.dog(GOOD, 1.0, border=border),
    ]
    raises_naming(ValueError, "border", calls[which])


@FAST
@given(word=st.text(max_size=10).filter(lambda s: s not in ("central", "forward", "backward", "l2", "l1", "max")))
def test_bad_scheme_and_norm(word):
    raises_naming(ValueError, "scheme", edges.gradient, GOOD, scheme=word)
    raises_naming(ValueError, "norm", edges.magnitude, GOOD, GOOD, norm=word)


@FAST
@given(sigma=st.one_of(st.floats(max_value=0.0), st.just(np.nan), st.just(np.inf)),
       which=st.integers(0, 4))
def test_bad_sigma(sigma, which):
    calls = [lambda: edges.log(GOOD, sigma), lambda: edges.dog(GOOD, sigma), lambda: edges.canny(GOOD, sigma),
             lambda: edges.log_kernel(sigma), lambda: edges.dog(GOOD, 1.0, k=sigma)]
    raises_naming(ValueError, "k" if which == 4 else "sigma", calls[which])


@FAST
@given(shape=st.tuples(st.integers(1, 5), st.integers(1, 5)).filter(lambda s: s != (6, 7)))
def test_shape_mismatch(shape):
    other = np.zeros(shape)
    raises_naming(ValueError, "iy", edges.magnitude, GOOD, other)
    raises_naming(ValueError, "iy", edges.direction, GOOD, other)
    raises_naming(ValueError, "shape", edges.non_max_suppression, GOOD, GOOD, other)
    raises_naming(ValueError, "shape", edges.non_max_suppression, other, GOOD, GOOD)


@FAST
@given(low=st.floats(0.0, 10.0), gap=st.floats(1e-3, 10.0))
def test_low_above_high(low, gap):
    raises_naming(ValueError, "low", edges.hysteresis, GOOD, low + gap, low)
    raises_naming(ValueError, "low", edges.canny, GOOD, 1.0, low + gap, low)


def test_other_bad_arguments():
    raises_naming(ValueError, "low", edges.canny, GOOD, 1.0, -0.1, 0.2)
    raises_naming(TypeError, "relative", edges.canny, GOOD, relative="yes")
    raises_naming(TypeError, "interpolate", edges.non_max_suppression, GOOD, GOOD, GOOD, interpolate=1)
    raises_naming(ValueError, "threshold", edges.zero_crossings, GOOD, -1.0)
    raises_naming(ValueError, "response", edges.zero_crossings, np.zeros((3, 4, 3)))
    raises_naming(ValueError, "magnitude", edges.hysteresis, np.zeros(5), 0.1, 0.2)
    raises_naming(ValueError, "high", edges.hysteresis, GOOD, 0.1, np.nan)
    raises_naming(ValueError, "radius", edges.log_kernel, 1.0, radius=-1)
    raises_naming(TypeError, "radius", edges.log_kernel, 1.0, radius=1.5)
    raises_naming(ValueError, "ix", edges.magnitude, [np.nan], [1.0])
    raises_naming(ValueError, "magnitude", edges.non_max_suppression, np.full((3, 3), np.inf), np.ones((3, 3)), np.ones((3, 3)))


# --------------------------------------------------------------------------------------------
# synthetic data
# --------------------------------------------------------------------------------------------
def test_synthetic_disk_has_the_area_of_its_circle():
    disk = data.disk_image((100, 120), centre=(60.3, 49.8), radius=31.4)
    assert abs(disk.sum() - np.pi * 31.4**2) < 0.002 * np.pi * 31.4**2
    assert disk.min() == 0.0 and disk.max() == 1.0


def test_synthetic_square_and_step():
    square = data.square_image((50, 50), side=20.0, angle=0.3)
    assert abs(square.sum() - 400.0) < 1.0
    step = data.oriented_step_image((40, 40), angle=math.radians(30), offset=2.0)
    gx, gy = edges.sobel(step)
    strongest = np.argmax(edges.magnitude(gx, gy))
    assert abs(math.degrees(edges.direction(gx, gy).flat[strongest]) - 30) < 5
    signal = data.step_signal(101, position=40.25, width=2.0)
    assert np.argmax(np.diff(signal)) in (39, 40)
    with pytest.raises(ValueError, match="radius"):
        data.disk_image((10, 10), radius=-1)
    with pytest.raises(ValueError, match="shape"):
        data.square_image((10,))


@pytest.mark.parametrize("interpolate", [True, False])
def test_nms_row_blocks_give_the_same_result(monkeypatch, interpolate, camera_gradient):
    """NMS works in blocks of rows; one-row blocks (every halo at a block edge) change nothing."""
    from cvkit.edges import _canny

    mag, gx, gy = (a[:90, :70] for a in camera_gradient)
    whole = edges.non_max_suppression(mag, gx, gy, interpolate)
    monkeypatch.setattr(_canny, "_BLOCK_ELEMENTS", 1)
    np.testing.assert_array_equal(edges.non_max_suppression(mag, gx, gy, interpolate), whole)
    np.testing.assert_array_equal(whole, _nms_brute(mag, gx, gy, interpolate))


def test_no_warnings_on_zero_gradients():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        zeros = np.zeros((6, 7))
        assert not edges.non_max_suppression(np.ones((6, 7)), zeros, zeros).any()
        # without interpolation: atan2(0, 0) = 0, a flat plateau keeps every pixel (≥ both sides)
        assert edges.non_max_suppression(np.ones((6, 7)), zeros, zeros, interpolate=False).all()
        assert not edges.canny(zeros).any()
        edges.direction(zeros, zeros)


def test_detect_outlines_refuses_a_picture_that_is_not_one():
    picture = np.random.default_rng(0).random((24, 24))
    with pytest.raises(TypeError, match="image"):
        edges.detect_outlines(picture.astype(str))   # numeric text was parsed as numbers before
    spoiled = picture.copy()
    spoiled[3, 4] = np.nan
    with pytest.raises(ValueError, match="image.*finite"):
        edges.detect_outlines(spoiled)
    with pytest.raises(ValueError, match="image"):
        edges.detect_outlines(np.stack([picture] * 3, axis=-1))
    before = picture.copy()
    edges.detect_outlines(picture)
    np.testing.assert_array_equal(picture, before)
