"""Chapter 5 local features (cvkit.features) against scikit-image / SciPy oracles and
brute-force definitions, plus properties, the provider switch and bad input.

Parameter mappings (cvkit -> oracle):
- structure_tensor(I, σ) -> scipy.ndimage.sobel(I, axis=1 | 0, mode="mirror") products smoothed by
  scipy.ndimage.gaussian_filter(·, σ, mode="mirror", truncate=ceil(3σ)/σ): equal to 1e-12.
- harris(I, k, σ) -> skimage.feature.corner_harris(I, method="k", k=k, sigma=σ). scikit-image pads
  with zeros (its structure_tensor's mode="constant", not exposed by corner_harris) and truncates
  the Gaussian at 4σ; ours reflects (reflect101) and truncates at 3σ. Peaks within 4 px of the
  border are excluded from both lists; then ≥ 90 % of our top-200 peaks (3-px NMS) lie within 2 px
  of one of scikit-image's (measured: 98.5–100 % on camera, coins, astronaut, brick, chelsea;
  84–90 % when the border is included, scikit-image's zero padding making corners there).
- log_blobs(I, σs, t) -> skimage.feature.blob_log(I, min_sigma, max_sigma, num_sigma, threshold=t,
  exclude_border=False) with the same linearly spaced σs, on bright blobs (scikit-image keeps the
  maxima of −σ²∇²L only and truncates at 4σ): the same blobs, positions within 1 px, equal σ.
- match_ratio(d1, d2, r) -> skimage.feature.match_descriptors(d1, d2, metric="euclidean",
  cross_check=False, max_ratio=r): equal (they differ only at d1 = r·d2 exactly: < there, ≤ here).
- KDTree.query -> brute force (sorted sqrt(Σ(p − q)²), ties to the smaller index): equal.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.ndimage as ndi
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cvkit
from cvkit import data, features, registry

try:
    from . import alternatives_ch05 as alt
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    import alternatives_ch05 as alt

skimage_feature = pytest.importorskip("skimage.feature")

MODES = {"zero": "constant", "replicate": "edge", "reflect": "symmetric", "reflect101": "reflect"}


@pytest.fixture(scope="module")
def camera():
    return data.resize_half(data.camera())


def _grey(rgb):
    return rgb @ np.array([0.2125, 0.7154, 0.0721])


# --------------------------------------------------------------------------------------------
# §5.6 Moravec
# --------------------------------------------------------------------------------------------
def moravec_brute(image, window, border):
    r = window // 2
    p = np.pad(np.asarray(image, float), r + 1, mode=MODES[border])
    h, w = image.shape
    out = np.zeros((h, w))
    for i in range(h):
        for j in range(w):
            centre = p[i + 1:i + 2 * r + 2, j + 1:j + 2 * r + 2]
            out[i, j] = min(((p[i + 1 + dy:i + 2 * r + 2 + dy, j + 1 + dx:j + 2 * r + 2 + dx] - centre) ** 2).sum()
                            for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx)
    return out


@pytest.mark.parametrize("border", sorted(MODES))
@pytest.mark.parametrize("window", [3, 5])
def test_moravec_equals_the_definition(border, window):
    image = np.random.default_rng(window).random((9, 12))
    assert np.allclose(features.moravec(image, window, border), moravec_brute(image, window, border), rtol=1e-12, atol=1e-12)


def test_moravec_flat_edge_corner():
    img = np.zeros((15, 15))
    img[7:, 7:] = 1.0
    c = features.moravec(img, 3)
    assert c[7, 7] > 0 and c[11, 7] == 0 and c[3, 3] == 0 and c[7, 11] == 0
    assert np.unravel_index(np.argmax(c), c.shape) in {(6, 6), (7, 7), (6, 7), (7, 6)}


# --------------------------------------------------------------------------------------------
# §5.7 structure tensor, Harris, peaks
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("sigma", [0.7, 1.0, 1.6, 2.3])
def test_structure_tensor_matches_scipy(camera, sigma):
    img = camera[:80, :90]
    ix, iy = ndi.sobel(img, axis=1, mode="mirror"), ndi.sobel(img, axis=0, mode="mirror")
    r = math.ceil(3 * sigma - 1e-9)

    def blur(a):
        return ndi.gaussian_filter(a, sigma, mode="mirror", truncate=r / sigma)

    for ours, theirs in zip(features.structure_tensor(img, sigma), (blur(ix * ix), blur(ix * iy), blur(iy * iy))):
        assert np.allclose(ours, theirs, rtol=1e-10, atol=1e-12)


def test_harris_is_det_minus_k_trace_squared(camera):
    mxx, mxy, myy = features.structure_tensor(camera, 1.4)
    assert np.allclose(features.harris(camera, 0.06, 1.4), mxx * myy - mxy ** 2 - 0.06 * (mxx + myy) ** 2, rtol=1e-12, atol=1e-15)


def _top_peaks(response, border=4, n=200):
    p = features.peaks(response, 0.0, radius=3)
    h, w = response.shape
    keep = (p[:, 0] >= border) & (p[:, 0] < w - border) & (p[:, 1] >= border) & (p[:, 1] < h - border)
    return p[keep][:n]


@pytest.mark.parametrize("name", ["camera", "coins", "astronaut", "brick"])
def test_harris_peaks_agree_with_scikit_image(name):
    img = getattr(data, name)()
    img = _grey(img) if img.ndim == 3 else img
    ours = _top_peaks(features.harris(img, 0.04, 1.0))
    theirs = _top_peaks(skimage_feature.corner_harris(img, method="k", k=0.04, sigma=1.0))
    d = np.sqrt(((ours[:, None] - theirs[None]) ** 2).sum(-1))
    assert len(ours) == 200 and np.mean(d.min(axis=1) <= 2.0) >= 0.9


def test_harris_sign_on_flat_edge_corner():
    img = np.zeros((31, 31))
    img[15:, 15:] = 1.0
    r = features.harris(img)
    assert r[15, 15] > 0 and r[25, 15] < 0 and r[15, 25] < 0 and abs(r[5, 5]) < 1e-12


def peaks_brute(response, threshold, radius):
    h, w = response.shape
    found = []
    for i in range(h):
        for j in range(w):
            v = response[i, j]
            if v > threshold and v >= response[max(0, i - radius):i + radius + 1, max(0, j - radius):j + radius + 1].max():
                found.append((-v, i, j))
    found.sort()
    return np.array([[j, i] for _, i, j in found], float).reshape(-1, 2)


@pytest.mark.parametrize("radius", [0, 1, 2, 4])
def test_peaks_equal_the_definition_with_ties(radius):
    rng = np.random.default_rng(radius)
    r = rng.integers(0, 5, (13, 17)).astype(float)
    assert np.array_equal(features.peaks(r, 1.0, radius), peaks_brute(r, 1.0, radius))


def test_peaks_equal_scikit_image_peak_local_max_without_plateaus():
    rng = np.random.default_rng(3)
    r = ndi.gaussian_filter(rng.random((60, 70)), 2.0)
    ours = features.peaks(r, 0.5, radius=2)
    theirs = skimage_feature.peak_local_max(r, min_distance=2, threshold_abs=0.5, exclude_border=False)
    assert {tuple(p) for p in ours[:, ::-1].astype(int)} == {tuple(p) for p in theirs}


def test_peaks_empty_and_dtype():
    out = features.peaks(np.zeros((4, 5)), 0.0)
    assert out.shape == (0, 2) and out.dtype == np.float64


# --------------------------------------------------------------------------------------------
# §5.8 LoG blobs
# --------------------------------------------------------------------------------------------
def _blobs(shape, specs):
    y, x = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    return 0.1 + sum(a * np.exp(-((x - bx) ** 2 + (y - by) ** 2) / (2 * s * s)) for bx, by, s, a in specs)


def test_log_blobs_agree_with_scikit_image_blob_log():
    specs = [(20.3, 22.6, 2.0, 0.6), (60.2, 25.4, 4.0, 0.7), (35.7, 60.3, 3.0, 0.5), (75.4, 70.2, 5.0, 0.8)]
    img = _blobs((95, 100), specs)
    sigmas = np.linspace(1.5, 6.0, 10)
    ours = features.log_blobs(img, sigmas, 0.05)
    bright = ours[[img[int(y), int(x)] > 0.2 for x, y, _ in ours]]
    theirs = skimage_feature.blob_log(img, min_sigma=1.5, max_sigma=6.0, num_sigma=10, threshold=0.05, exclude_border=False)
    assert len(bright) == len(theirs) == 4
    for r, c, s in theirs:
        d = np.hypot(bright[:, 0] - c, bright[:, 1] - r)
        assert d.min() <= 1.0 and bright[np.argmin(d), 2] == pytest.approx(s)
    for bx, by, s, _ in specs:  # and each blob at its own scale
        d = np.hypot(bright[:, 0] - bx, bright[:, 1] - by)
        assert d.min() <= 1.0 and abs(bright[np.argmin(d), 2] - s) <= 0.51


def test_log_blobs_finds_dark_blobs_as_maxima():
    img = _blobs((40, 40), [(20.4, 19.7, 3.0, -0.08)])
    blobs = features.log_blobs(img, [2.0, 2.5, 3.0, 3.5, 4.0], 0.01)
    assert len(blobs) == 1 and blobs[0, 2] == 3.0 and np.allclose(blobs[0, :2], [20, 20])


def test_log_blobs_brute_force_extrema():
    img = np.random.default_rng(5).random((16, 18))
    sigmas = [1.0, 1.4, 2.0]
    F = np.array([s * s * cvkit.edges.log(img, s) for s in sigmas])
    expected = []
    for k in range(3):
        for i in range(16):
            for j in range(18):
                block = F[max(0, k - 1):k + 2, max(0, i - 1):i + 2, max(0, j - 1):j + 2].ravel()
                v = F[k, i, j]
                rest = np.delete(block, np.flatnonzero(block == v)[0])
                if abs(v) > 0.02 and (v > rest.max() or v < rest.min()):
                    expected.append((j, i, sigmas[k]))
    assert np.array_equal(features.log_blobs(img, sigmas, 0.02), np.array(expected, float).reshape(-1, 3))


# --------------------------------------------------------------------------------------------
# §5.8–5.9 pyramids
# --------------------------------------------------------------------------------------------
def test_upsampling_is_the_stated_interpolation():
    img = np.random.default_rng(0).random((5, 7))
    pyramid = features.gaussian_pyramid(img, 1.6, 1, 1, True, 0.0)
    from cvkit.features._scale_space import double_size

    up = double_size(img)
    assert up.shape == (10, 14) and np.array_equal(up[0::2, 0::2], img)
    assert np.allclose(up[1:-1:2, 0::2], (img[:-1] + img[1:]) / 2) and np.allclose(up[-1, 0::2], img[-1])
    assert np.allclose(up[1:-1:2, 1:-1:2], (img[:-1, :-1] + img[1:, :-1] + img[:-1, 1:] + img[1:, 1:]) / 4)
    assert pyramid[0].shape == (4, 10, 14)


def test_pyramid_levels_reach_their_total_blur(camera):
    img = camera[:64, :64]
    pyramid = features.gaussian_pyramid(img, sigma0=1.6, scales=3, octaves=2, upsample=False, assumed_blur=0.0)
    base = pyramid[0][0]
    assert np.allclose(base, cvkit.filters.gaussian(img, 1.6), atol=1e-12)
    inner = (slice(12, -12), slice(12, -12))
    for i in range(1, 6):
        direct = cvkit.filters.gaussian(img, math.sqrt((1.6 * 2 ** (i / 3)) ** 2 - 1.6 ** 2 + 1.6 ** 2))
        assert np.abs(pyramid[0][i] - direct)[inner].max() < 2e-3  # discrete kernels compose almost exactly
    assert np.array_equal(pyramid[1][0], pyramid[0][3][::2, ::2])


def test_pyramid_shapes_and_bad_sigma0():
    p = features.gaussian_pyramid(np.zeros((17, 20)), octaves=4)
    assert [s.shape for s in p] == [(6, 34, 40), (6, 17, 20), (6, 9, 10), (6, 5, 5)]
    with pytest.raises(ValueError, match="sigma0"):
        features.gaussian_pyramid(np.zeros((8, 8)), sigma0=0.9)  # ≤ 2·0.5 when upsampling
    assert len(features.gaussian_pyramid(np.zeros((8, 8)), sigma0=0.9, upsample=False)) == 4


def test_dog_approximates_the_scale_normalised_laplacian(camera):
    pyramid = features.gaussian_pyramid(camera, octaves=2)
    dog = features.dog_pyramid(pyramid)
    k = 2 ** (1 / 3)
    inner = (slice(10, -10), slice(10, -10))
    for i in range(4):
        lap = cvkit.edges.laplacian(pyramid[1][i])[inner]
        d = dog[1][i][inner]
        factor = (d * lap).sum() / (lap ** 2).sum()
        assert np.corrcoef(d.ravel(), lap.ravel())[0, 1] > 0.98
        assert 0.8 < factor / ((k - 1) * (1.6 * 2 ** (i / 3)) ** 2) < 1.05


def dog_extrema_brute(dog, threshold):
    rows = []
    for o, d in enumerate(dog):
        for s in range(1, d.shape[0] - 1):
            for r in range(1, d.shape[1] - 1):
                for c in range(1, d.shape[2] - 1):
                    v = d[s, r, c]
                    others = np.delete(d[s - 1:s + 2, r - 1:r + 2, c - 1:c + 2].ravel(), 13)
                    if abs(v) > threshold and (v > others.max() or v < others.min()):
                        rows.append((o, s, r, c))
    return np.array(rows, dtype=np.int64).reshape(-1, 4)


def test_dog_extrema_equal_the_definition(camera):
    dog = features.dog_pyramid(features.gaussian_pyramid(camera[:40, :48], octaves=3))
    assert np.array_equal(features.dog_extrema(dog, 0.004), dog_extrema_brute(dog, 0.004))
    rng = np.random.default_rng(2)
    ties = [rng.integers(-2, 3, (5, 9, 11)).astype(float), rng.integers(-2, 3, (5, 5, 6)).astype(float)]
    got = features.dog_extrema(ties, 0.5)
    assert np.array_equal(got, dog_extrema_brute(ties, 0.5)) and got.dtype == np.int64


# --------------------------------------------------------------------------------------------
# §5.9 refinement and edges
# --------------------------------------------------------------------------------------------
def test_refine_extremum_is_exact_on_a_quadratic():
    s, r, c = np.mgrid[0:4, 0:7, 0:8].astype(float)
    x0 = np.array([1.7, 3.2, 3.6])
    Q = np.array([[1.0, 0.2, -0.1], [0.2, 0.8, 0.3], [-0.1, 0.3, 1.2]])
    off = np.stack([s - x0[0], r - x0[1], c - x0[2]], -1)
    d = 2.0 - np.einsum("...i,ij,...j->...", off, Q, off)
    offset, value = features.refine_extremum(d, 2, 3, 4)
    assert np.allclose(offset, x0 - [2, 3, 4]) and value == pytest.approx(2.0)
    with pytest.raises(ValueError, match="scale"):
        features.refine_extremum(d, 0, 3, 3)
    with pytest.raises(ValueError, match="col"):
        features.refine_extremum(d, 1, 3, 7)
    with pytest.raises(ValueError, match="singular"):
        features.refine_extremum(np.zeros((3, 5, 5)), 1, 2, 2)


@pytest.mark.parametrize("ratio", [1.0, 2.0, 5.0, 9.0, 11.0, 40.0])
@pytest.mark.parametrize("angle", [0.0, 0.4, math.pi / 4, 2.0])
def test_is_edge_like_equals_the_eigenvalue_ratio(ratio, angle):
    y, x = np.mgrid[0:7, 0:7].astype(float)
    u = (x - 3) * math.cos(angle) + (y - 3) * math.sin(angle)
    v = -(x - 3) * math.sin(angle) + (y - 3) * math.cos(angle)
    d = -(ratio * u * u + v * v)
    lam = np.linalg.eigvalsh(np.array([[d[3, 4] + d[3, 2] - 2 * d[3, 3], (d[4, 4] - d[4, 2] - d[2, 4] + d[2, 2]) / 4],
                                       [(d[4, 4] - d[4, 2] - d[2, 4] + d[2, 2]) / 4, d[4, 3] + d[2, 3] - 2 * d[3, 3]]]))
    expected = lam[0] * lam[1] <= 0 or max(abs(lam)) / min(abs(lam)) >= 10.0
    assert features.is_edge_like(d, 3, 3) == expected
    assert features.is_edge_like(d * np.where((x + y) % 2, 1, 1), 3, 3, r=10.0) == expected


def test_is_edge_like_saddle_and_border():
    y, x = np.mgrid[0:5, 0:5].astype(float)
    assert features.is_edge_like((x - 2) ** 2 - (y - 2) ** 2, 2, 2) is True
    with pytest.raises(ValueError, match="row"):
        features.is_edge_like(np.zeros((5, 5)), 0, 2)


# --------------------------------------------------------------------------------------------
# §5.11–5.12 orientation and descriptor
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("degrees", [0, 30, 95, 180, 250, 355])
def test_orientation_of_a_ramp_is_its_bin(degrees):
    y, x = np.mgrid[0:41, 0:41].astype(float)
    a = math.radians(degrees + 0.3)
    ramp = np.cos(a) * x + np.sin(a) * y
    got = features.orientations(ramp, 20.2, 19.7, 2.5)
    assert got.shape == (1,) and abs(got[0] - math.radians(10 * round((degrees + 0.3) / 10) % 360)) < 1e-9


@pytest.mark.parametrize(("x", "y", "sigma"), [(12.0, 12.0, 1.0), (12.5, 11.5, 1.6), (10.0, 13.0, 3.0),
                                              (11.5, 12.5, 5.0 / 9.0)])
def test_rounding_takes_halves_to_even(x, y, sigma):
    """round(4.5σ), round(x), round(y) and the bins round as Python and OpenCV do, halves to
    even: σ = 1 gives the radius 4, a keypoint at x = 12.5 the centre column 12."""
    img = cvkit.filters.gaussian(np.random.default_rng(12).uniform(0, 1, (25, 27)), 1.0)
    np.testing.assert_allclose(features.orientations(img, x, y, sigma), alt.orientations(img, x, y, sigma),
                               rtol=0, atol=1e-9)
    np.testing.assert_allclose(features.sift_descriptor(img, x, y, sigma, 0.4),
                               alt.sift_descriptor(img, x, y, sigma, 0.4), rtol=0, atol=1e-9)
    yy, xx = np.mgrid[0:21, 0:21].astype(float)       # gradient at exactly 45°: bin 4.5 -> 4 (40°)
    assert features.orientations((xx + yy) * 0.1, 10, 10, 1.2) == pytest.approx([math.radians(40)])


@pytest.mark.parametrize(("x", "y", "sigma"), [(14.0, 3.0, 2.0), (-6.0, 4.5, 1.5), (3.0, 20.0, 2.5)])
def test_descriptor_of_a_keypoint_outside_the_image_takes_every_pixel_of_its_window(x, y, sigma):
    """The window is the square of radius round(3σ·√2·5/2) about the keypoint, however far
    from the image it lies: a keypoint 6 columns right of an 8×8 image still reads its
    column 1 (13 pixels away, within the radius 21 of σ = 2)."""
    img = np.random.default_rng(0).random((8, 8))
    got = features.sift_descriptor(img, x, y, sigma, 0.0)
    np.testing.assert_allclose(got, alt.sift_descriptor(img, x, y, sigma, 0.0), rtol=0, atol=1e-12)
    assert np.linalg.norm(got) == pytest.approx(1.0)


def test_orientations_stay_below_two_pi():
    # the peak in bin 0 with a tiny negative parabola offset: np.mod(-1e-17, 2π) rounds to 2π
    yy, xx = np.mgrid[0:21, 0:21].astype(float)
    found = features.orientations(xx + 0.015 * (yy - 10) ** 2, 10.0, 10.0, 1.5)
    assert found.size and np.all((found >= 0) & (found < 2 * math.pi))


def test_orientations_rotate_with_the_image(camera):
    L = cvkit.filters.gaussian(camera, 2.0)[60:140, 80:160]
    first = features.orientations(L, 40.3, 39.8, 2.0)
    turned = features.orientations(np.rot90(L), 39.8, 79 - 40.3, 2.0)  # (x, y) -> (y, W−1−x): −90°
    assert len(first) == len(turned)
    assert np.allclose(np.mod(turned - (first - np.pi / 2), 2 * np.pi) % (2 * np.pi - 1e-9), 0, atol=1e-9)


def test_descriptor_properties_and_rotation_invariance(camera):
    L = cvkit.filters.gaussian(camera, 1.6)[50:130, 70:150]
    v = features.sift_descriptor(L, 40.3, 39.6, 2.0, 0.9)
    assert v.shape == (128,) and abs(np.linalg.norm(v) - 1) < 1e-12 and v.min() >= 0
    w = features.sift_descriptor(np.rot90(L), 39.6, 79 - 40.3, 2.0, 0.9 - np.pi / 2)
    assert np.allclose(v, w, atol=1e-9)
    assert np.allclose(features.sift_descriptor(3 * L + 7, 40.3, 39.6, 2.0, 0.9), v, atol=1e-12)
    assert not np.allclose(features.sift_descriptor(L, 40.3, 39.6, 2.0, 0.9 + 0.5), v, atol=1e-2)
    assert np.array_equal(features.sift_descriptor(np.ones((30, 30)), 15.2, 14.8, 2.0, 0.0), np.zeros(128))


def test_descriptor_and_orientation_batch_equal_single(camera):
    """The pipeline's batch path gives bit-identical results to the single-keypoint functions."""
    from cvkit.features._sift import _differences, descriptors_batch, histogram_peaks, orientation_histograms

    L = cvkit.filters.gaussian(camera, 1.3)
    rng = np.random.default_rng(4)
    xs, ys, ss, aa = rng.uniform(5, 250, 30), rng.uniform(5, 250, 30), rng.uniform(1.5, 3.8, 30), rng.uniform(0, 6.3, 30)
    dx, dy = _differences(L)
    batch = descriptors_batch(dx, dy, xs, ys, ss, aa)
    angles = histogram_peaks(orientation_histograms(dx, dy, xs, ys, ss, 36), 0.8)
    for i in range(30):
        assert np.array_equal(batch[i], features.sift_descriptor(L, xs[i], ys[i], ss[i], aa[i]))
        assert np.array_equal(angles[i], features.orientations(L, xs[i], ys[i], ss[i]))


# --------------------------------------------------------------------------------------------
# §5.13–5.14 matching
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("ratio", [0.6, 0.8, 0.95])
def test_match_ratio_equals_scikit_image(ratio):
    rng = np.random.default_rng(int(ratio * 100))
    d2 = rng.random((120, 32))
    d1 = np.vstack([d2[:60] + rng.normal(0, 0.05, (60, 32)), rng.random((50, 32))])
    ours = features.match_ratio(d1, d2, ratio)
    theirs = skimage_feature.match_descriptors(d1, d2, metric="euclidean", cross_check=False, max_ratio=ratio)
    assert np.array_equal(ours, theirs)


def test_match_ratio_boundary_and_duplicates():
    a = np.array([[0.0, 0.0], [10.0, 10.0]])
    b = np.array([[4.0, 0.0], [0.0, 5.0], [10.0, 10.0], [10.0, 10.0]])
    assert features.match_ratio(a, b).tolist() == [[0, 0]]  # 4 ≤ 0.8·5; the duplicate is ambiguous
    assert features.match_ratio(a, b, 0.79).shape == (0, 2)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("scale", [1e-200, 1e-160, 1e160, 1e250])
def test_match_ratio_at_magnitudes_whose_squares_leave_the_float_range(scale):
    """The matches depend only on ratios of distances: descriptors scaled by 1e±160 or more
    (their squares over- or underflow) match as at scale 1, with no error and no warning."""
    rng = np.random.default_rng(7)
    d2 = rng.random((40, 8))
    d1 = np.vstack([d2[:20] + rng.normal(0, 0.05, (20, 8)), rng.random((15, 8))])
    expected = features.match_ratio(d1, d2, 0.9)
    assert len(expected) > 10
    assert np.array_equal(features.match_ratio(d1 * scale, d2 * scale, 0.9), expected)
    big = np.array([[1e200, 0.0]]), np.array([[1e200, 1.0], [-1e200, 0.0]])  # d1 = 1, d2 = 2e200
    assert features.match_ratio(*big).tolist() == [[0, 0]]


def knn_brute(points, queries, k):
    d = np.sqrt(((queries[:, None, :] - points[None]) ** 2).sum(-1))
    idx = np.argsort(d, axis=1, kind="stable")[:, :k]
    return np.take_along_axis(d, idx, 1), idx


@pytest.mark.parametrize(("n", "dim", "k", "leaf"), [(500, 2, 3, 4), (300, 5, 1, 1), (800, 16, 2, 8), (40, 1, 40, 4),
                                                     (200, 128, 2, 4)])
def test_kdtree_query_equals_brute_force(n, dim, k, leaf):
    rng = np.random.default_rng(n + dim)
    points, queries = rng.normal(size=(n, dim)), rng.normal(size=(60, dim))
    tree = features.KDTree(points, leaf_size=leaf)
    d, i = tree.query(queries, k)
    bd, bi = knn_brute(points, queries, k)
    assert np.array_equal(i, bi) and np.allclose(d, bd, rtol=1e-12, atol=0)
    d1, i1 = tree.query(queries[0], k)
    assert d1.shape == (k,) and np.array_equal(i1, bi[0])
    full_d, full_i = tree.query_bbf(queries, k, max_checks=n)
    assert np.array_equal(full_i, bi)


def test_kdtree_ties_and_duplicates():
    rng = np.random.default_rng(9)
    points = rng.integers(0, 4, (300, 2)).astype(float)
    queries = rng.integers(0, 4, (50, 2)) + 0.5 * rng.integers(0, 2, (50, 2))
    d, i = features.KDTree(points).query(queries, 9)
    bd, bi = knn_brute(points, queries, 9)
    assert np.array_equal(i, bi) and np.array_equal(d, bd)


def test_bbf_respects_its_budget():
    """With a budget of max_checks points the answer can only be among that many points."""
    rng = np.random.default_rng(1)
    points, queries = rng.random((2000, 8)), rng.random((100, 8))
    tree = features.KDTree(points)
    _, exact = tree.query(queries, 1)
    recalls = [np.mean(tree.query_bbf(queries, 1, c)[1][:, 0] == exact[:, 0]) for c in (1, 10, 100, 2000)]
    assert recalls[0] < 0.2 and recalls == sorted(recalls) and recalls[-1] == 1.0


# --------------------------------------------------------------------------------------------
# pipelines use the registry
# --------------------------------------------------------------------------------------------
def test_harris_and_pyramid_use_the_students_building_blocks(camera):
    calls = []

    def my_sobel(image, border="reflect101"):
        calls.append("sobel")
        return cvkit.edges.sobel(image, border)

    def my_gaussian(image, sigma, border="reflect101"):
        calls.append("gaussian")
        return 2.0 * cvkit.filters.gaussian(image, sigma, border)

    registry.register_provider("ch05-test", {"edges.sobel": my_sobel, "filters.gaussian": my_gaussian})
    with cvkit.use("ch05-test"):
        r = features.harris(camera[:32, :32])
        p = features.gaussian_pyramid(camera[:16, :16], octaves=1)
    assert calls.count("sobel") == 1 and calls.count("gaussian") >= 3 + 6
    assert np.allclose(r, 4.0 * features.harris(camera[:32, :32]))  # M doubled: det and trace² ×4
    assert not np.allclose(p[0], features.gaussian_pyramid(camera[:16, :16], octaves=1)[0])


# --------------------------------------------------------------------------------------------
# bad input: clear errors naming the argument
# --------------------------------------------------------------------------------------------
BAD_CALLS = [
    (lambda: features.moravec(np.zeros((5, 5)), 4), ValueError, "window"),
    (lambda: features.moravec(np.zeros((5, 5)), 3, "mirror"), ValueError, "border"),
    (lambda: features.moravec(np.zeros((5, 5, 3))), ValueError, "grayscale"),
    (lambda: features.structure_tensor(np.zeros((5, 5)), -1.0), ValueError, "sigma"),
    (lambda: features.harris(np.zeros((5, 5)), "k"), TypeError, "k"),
    (lambda: features.peaks(np.zeros((5, 5, 2)), 0.0), ValueError, "response"),
    (lambda: features.peaks(np.zeros((5, 5)), 0.0, radius=-1), ValueError, "radius"),
    (lambda: features.gaussian_pyramid(np.zeros((5, 5)), scales=0), ValueError, "scales"),
    (lambda: features.gaussian_pyramid(np.zeros((5, 5)), upsample="yes"), TypeError, "upsample"),
    (lambda: features.dog_pyramid("pyramid"), TypeError, "gaussian_pyramid"),
    (lambda: features.dog_extrema([np.zeros((3, 4))]), ValueError, "dog_pyramid"),
    (lambda: features.log_blobs(np.zeros((8, 8)), [1.0, -2.0], 0.1), ValueError, "sigmas"),
    (lambda: features.log_blobs(np.zeros((8, 8)), [1.0], -0.1), ValueError, "threshold"),
    (lambda: features.refine_extremum(np.zeros((3, 5, 5)), 1.5, 2, 2), TypeError, "scale"),
    (lambda: features.is_edge_like(np.zeros((5, 5)), 2, 2, r=0), ValueError, "r"),
    (lambda: features.orientations(np.zeros((9, 9)), 4, 4, 0.0), ValueError, "sigma"),
    (lambda: features.orientations(np.zeros((9, 9)), 4, 4, 1.0, bins=2), ValueError, "bins"),
    (lambda: features.sift_descriptor(np.full((9, 9), np.nan), 4, 4, 1.0, 0.0), ValueError, "gaussian_image"),
    (lambda: features.sift(np.zeros((16, 16)), border=0), ValueError, "border"),
    (lambda: features.match_ratio(np.zeros((3, 4)), np.zeros((1, 4))), ValueError, "desc2"),
    (lambda: features.match_ratio(np.zeros((3, 4)), np.zeros((5, 3))), ValueError, "columns"),
    (lambda: features.KDTree(np.zeros((0, 3))), ValueError, "points"),
    (lambda: features.KDTree(np.zeros((5, 3))).query(np.zeros(3), 6), ValueError, "k"),
    (lambda: features.KDTree(np.zeros((5, 3))).query(np.zeros(2)), ValueError, "q"),
    (lambda: features.KDTree(np.zeros((5, 3))).query_bbf(np.zeros(3), 3, max_checks=2), ValueError, "max_checks"),
]


@pytest.mark.parametrize(("call", "error", "name"), BAD_CALLS, ids=[str(i) for i in range(len(BAD_CALLS))])
def test_bad_input_raises_naming_the_argument(call, error, name):
    with pytest.raises(error, match=name):
        call()


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(shape=st.tuples(st.integers(1, 4), st.integers(0, 4)), bad=st.sampled_from([np.nan, np.inf, -np.inf]))
def test_non_finite_images_are_refused(shape, bad):
    img = np.zeros((max(shape[0], 1) + 2, shape[1] + 3))
    img[0, 0] = bad
    for fn in (features.moravec, features.harris, lambda i: features.peaks(i, 0.0), features.sift):
        with pytest.raises(ValueError, match="finite"):
            fn(img)


@settings(max_examples=30, deadline=None)
@given(k=st.integers(-3, 12), n=st.integers(1, 8))
def test_kdtree_k_is_checked(k, n):
    tree = features.KDTree(np.arange(2.0 * n).reshape(n, 2))
    if 1 <= k <= n:
        assert tree.query(np.zeros(2), k)[1].shape == (k,)
    else:
        with pytest.raises(ValueError, match="k"):
            tree.query(np.zeros(2), k)


def test_inputs_are_not_modified(camera):
    img = camera[:40, :40].copy()
    keep = img.copy()
    features.moravec(img)
    features.harris(img)
    features.peaks(img, 0.2)
    pyr = features.gaussian_pyramid(img, octaves=2)
    snapshot = [p.copy() for p in pyr]
    dog = features.dog_pyramid(pyr)
    features.dog_extrema(dog, 0.001)
    features.orientations(img, 20.3, 20.1, 2.0)
    features.sift_descriptor(img, 20.3, 20.1, 2.0, 0.3)
    features.sift(img)
    points = np.random.default_rng(0).random((30, 3))
    before = points.copy()
    features.KDTree(points).query(points[:3], 2)
    assert np.array_equal(img, keep) and all(np.array_equal(a, b) for a, b in zip(pyr, snapshot))
    assert np.array_equal(points, before)


def test_uint8_is_not_rescaled(camera):
    u8 = np.round(camera[:32, :32] * 255).astype(np.uint8)
    assert np.allclose(features.harris(u8), features.harris(u8.astype(float)))
    assert np.array_equal(features.moravec(u8), features.moravec(u8.astype(float))) and features.moravec(u8).max() > 1


def test_algorithms_are_registered_with_sections_and_checks():
    ids = [a.id for a in registry.algorithms() if a.module == "features"]
    assert len(ids) == 16  # 15 of the catalog and the measured match_features (§5.14.1)
    for algorithm_id in ids:
        record = registry.get(algorithm_id)
        assert record.section.startswith("5.") and record.check is not None
        assert getattr(features, algorithm_id.split(".")[1]) is record.reference
