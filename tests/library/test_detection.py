"""Chapter 6 detection (cvkit.detection) against OpenCV / scikit-image oracles and brute-force
definitions, plus invariances, the GHT target on generated scenes, the provider switch and bad
input.

Parameter mappings (cvkit -> oracle):
- match_template(I, T, "ssd" | "ncc" | "zncc") -> cv2.matchTemplate(I32, T32, TM_SQDIFF |
  TM_CCORR_NORMED | TM_CCOEFF_NORMED) (OpenCV computes in float32: compared to 2e-5 relative,
  3e-4 for ZNCC whose low-contrast windows lose digits in float32);
  "zncc" -> skimage.feature.match_template(I, T) (pad_input=False, float64: 1e-10). SAD has no
  library peer: brute force.
- hough_lines(E) -> skimage.transform.hough_line(E) (default θ = linspace(−π/2, π/2, 180,
  endpoint=False), ρ centres −ceil(diag)…ceil(diag)). scikit-image rounds exact halves away from
  zero and we round them up, so the accumulators are equal when no vote falls on an exact half
  (no edge pixel in row 0 or column 0, where θ = ±30°, ±60° give ρ = k + ½).
- hough_peaks(acc, θ, ρ, count, threshold, min_distance) -> skimage.transform.hough_line_peaks(
  acc, θ, ρ, min_distance, min_angle, threshold, num_peaks): the top peaks agree, ρ within 1 px,
  θ within one step.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from input_helpers import FAST

import cvkit
from cvkit import data, detection, edges, registry

cv2 = pytest.importorskip("cv2")
skfeature = pytest.importorskip("skimage.feature")
sktransform = pytest.importorskip("skimage.transform")


def _camera_crop():
    return data.camera()[100:228, 150:310]


# --------------------------------------------------------------------------------------------
# template matching
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("measure", "flag"), [("ssd", "TM_SQDIFF"), ("ncc", "TM_CCORR_NORMED"),
                                               ("zncc", "TM_CCOEFF_NORMED")])
def test_match_template_equals_opencv(measure, flag):
    img = _camera_crop()
    tpl = img[40:61, 70:97].copy()
    ours = detection.match_template(img, tpl, measure)
    theirs = cv2.matchTemplate(img.astype(np.float32), tpl.astype(np.float32), getattr(cv2, flag))
    assert ours.shape == theirs.shape == (128 - 21 + 1, 160 - 27 + 1)
    scale = max(1.0, float(np.abs(ours).max()))
    # OpenCV works in float32: ~1e-7 relative for SSD and NCC, up to ~1e-4 for ZNCC on the
    # low-contrast windows of the sky (a small variance from two large float32 sums)
    assert np.max(np.abs(ours - theirs)) <= (3e-4 if measure == "zncc" else 2e-5) * scale
    assert np.median(np.abs(ours - theirs)) <= 2e-6 * scale


@pytest.mark.parametrize("gain", [1e-7, 1e-170, 1e170])
def test_ncc_ignores_the_templates_gain(gain):
    # NCC is a cosine: a tiny (or huge) template is not an all-zero one
    rng = np.random.default_rng(0)
    img, tpl = rng.random((20, 20)), rng.random((5, 5))
    plain = detection.match_template(img, tpl, "ncc")
    np.testing.assert_allclose(detection.match_template(img, gain * tpl, "ncc"), plain, rtol=0, atol=1e-12)
    assert plain.max() > 0.8
    assert not np.any(detection.match_template(img, np.zeros((5, 5)), "ncc"))


def test_zncc_equals_scikit_image_fft_and_direct_paths():
    rng = np.random.default_rng(0)
    img = rng.random((70, 90))
    for shape in [(3, 5), (16, 24)]:        # a direct tap loop, then the FFT
        tpl = img[10:10 + shape[0], 20:20 + shape[1]]
        ours = detection.match_template(img, tpl)
        theirs = skfeature.match_template(img, tpl)
        assert np.max(np.abs(ours - theirs)) < 1e-10
        assert detection.best_match(ours, "zncc") == (20, 10)


def test_fft_and_direct_correlation_agree():
    from cvkit.detection._template import _correlate_valid

    rng = np.random.default_rng(1)
    img = rng.normal(size=(40, 50))
    tpl = rng.normal(size=(12, 9))
    brute = np.array([[np.sum(img[i:i + 12, j:j + 9] * tpl) for j in range(42)] for i in range(29)])
    assert np.allclose(_correlate_valid(img, tpl), brute, atol=1e-10)


def test_sad_and_ssd_equal_brute_force():
    rng = np.random.default_rng(2)
    img = rng.integers(0, 256, (19, 23)).astype(np.uint8)
    tpl = rng.integers(0, 256, (5, 4)).astype(np.uint8)
    f, t = img.astype(float), tpl.astype(float)
    sad = np.array([[np.abs(f[i:i + 5, j:j + 4] - t).sum() for j in range(20)] for i in range(15)])
    ssd = np.array([[((f[i:i + 5, j:j + 4] - t) ** 2).sum() for j in range(20)] for i in range(15)])
    assert np.array_equal(detection.match_template(img, tpl, "sad"), sad)
    assert np.allclose(detection.match_template(img, tpl, "ssd"), ssd, rtol=1e-12, atol=1e-6)


@pytest.mark.parametrize("offset", [1e4, 1e6, -3e7])
def test_ssd_of_an_image_far_from_zero_keeps_its_precision(offset):
    """SSD does not see an offset common to image and template; a faint texture on a large
    offset is scored as on no offset (the sums do not cancel to rounding noise)."""
    rng = np.random.default_rng(0)
    texture = 0.01 * rng.random((30, 40))
    tpl = texture[10:20, 5:15]
    direct = np.array([[((texture[i:i + 10, j:j + 10] - tpl) ** 2).sum() for j in range(31)] for i in range(21)])
    got = detection.match_template(texture + offset, tpl + offset, "ssd")
    np.testing.assert_allclose(got, direct, rtol=1e-6, atol=1e-12)
    assert detection.best_match(got, "ssd") == (5, 10)


def test_invariances_of_the_measures():
    """What the notes claim: SSD/SAD change under gain and offset, NCC survives a gain only,
    ZNCC survives gain and offset."""
    img = _camera_crop()
    tpl = img[30:50, 60:85].copy()
    for measure, gain_ok, offset_ok in [("ssd", False, False), ("sad", False, False),
                                        ("ncc", True, False), ("zncc", True, True)]:
        base = detection.match_template(img, tpl, measure)
        gained = detection.match_template(1.7 * img, tpl, measure)
        shifted = detection.match_template(img + 0.3, tpl, measure)
        assert np.allclose(gained, base, atol=1e-9) == gain_ok, measure
        assert np.allclose(shifted, base, atol=1e-9) == offset_ok, measure


def test_flat_windows_score_zero_without_warnings():
    img = np.zeros((12, 14))
    img[6:, 7:] = np.arange(42).reshape(6, 7) % 5 + 1
    tpl = img[7:10, 8:11].copy()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ncc = detection.match_template(img, tpl, "ncc")
        zncc = detection.match_template(img, tpl, "zncc")
        flat_tpl = detection.match_template(img, np.full((3, 3), 2.0), "zncc")
        zero_tpl = detection.match_template(img, np.zeros((3, 3)), "ncc")
    assert np.all(np.isfinite(ncc)) and np.all(np.isfinite(zncc))
    assert np.all(ncc[:3, :5] == 0) and np.all(zncc[:3, :5] == 0)       # the all-zero corner
    assert np.all(flat_tpl == 0) and np.all(zero_tpl == 0)
    big = np.full((30, 30), 1e3)                                          # constant, large offset
    big[15:, 15:] += np.random.default_rng(3).random((15, 15))
    z = detection.match_template(big, big[16:20, 16:20], "zncc")
    assert np.all(z[:10, :10] == 0) and np.isclose(z[16, 16], 1.0)
    z_small = detection.match_template(big - 1e3, big[16:20, 16:20] - 1e3, "zncc")
    assert np.allclose(z, z_small, atol=1e-9)                             # the offset costs no digits
    # the documented rule: a variance below 1e-12 of the mean square counts as flat
    assert np.all(detection.match_template(big + 1e6, big[16:20, 16:20], "zncc") == 0)


def test_best_match_rules():
    s = np.array([[2.0, 1.0, 1.0], [3.0, 1.0, 3.0]])
    assert detection.best_match(s, "sad") == (1, 0)            # ties: first in row-major order
    assert detection.best_match(s, "ncc") == (0, 1)
    x, y = detection.best_match(s, "ssd")
    assert type(x) is int and type(y) is int


def test_inputs_are_not_modified():
    rng = np.random.default_rng(4)
    img = rng.random((20, 25))
    tpl = img[3:8, 4:10].copy()
    keep = img.copy(), tpl.copy()
    for m in ("ssd", "sad", "ncc", "zncc"):
        detection.match_template(img, tpl, m)
    model = detection.shape_model(tpl, 0.5)
    points = model["points"].copy()
    detection.shape_match(img, model, "local")
    assert np.array_equal(img, keep[0]) and np.array_equal(tpl, keep[1])
    assert np.array_equal(model["points"], points)


# --------------------------------------------------------------------------------------------
# shape-based matching
# --------------------------------------------------------------------------------------------
def _brute_shape_match(image, model, polarity):
    gx, gy = edges.sobel(image)
    h, w = model["shape"]
    out = np.zeros((image.shape[0] - h + 1, image.shape[1] - w + 1))
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            cos = []
            for (x, y), d in zip(model["points"].astype(int), model["directions"]):
                g = np.array([gx[i + y, j + x], gy[i + y, j + x]])
                n = np.linalg.norm(g)
                cos.append(0.0 if n <= 1e-10 * np.abs(image).max() else float(d @ g) / n)
            cos = np.array(cos)
            out[i, j] = {"none": cos.mean(), "global": abs(cos.sum()) / len(cos), "local": np.abs(cos).mean()}[polarity]
    return out


def test_shape_model_and_match_equal_their_definitions():
    tpl, _ = data.part_template(20, margin=2)
    model = detection.shape_model(tpl, 0.5)
    gx, gy = edges.sobel(tpl)
    mag = np.hypot(gx, gy)
    assert model["points"].shape[0] == int((mag > 0.5).sum())
    x, y = model["points"].astype(int).T
    assert np.allclose(model["directions"], np.stack([gx[y, x], gy[y, x]], 1) / mag[y, x, None])
    assert model["shape"] == (20, 20)
    scene, _ = data.part_scene((30, 34), centre=(17.0, 14.0), size=20, margin=2, clutter=1, noise=0.02, rng=5)
    for polarity in ("none", "global", "local"):
        assert np.allclose(detection.shape_match(scene, model, polarity), _brute_shape_match(scene, model, polarity))


def test_shape_matching_polarity_invariance():
    """The part is found at the right place; inverting its contrast flips the 'none' score,
    not the 'global' one; a split background defeats 'global' but not 'local'."""
    size = 24
    tpl, _ = data.part_template(size, margin=2)
    model = detection.shape_model(tpl, 0.5)
    centre = (30.5, 26.5)                     # the template's top-left pixel lands on (19, 15)
    where = (19, 15)
    normal, _ = data.part_scene((52, 60), centre=centre, size=size, margin=2, clutter=3, noise=0.01, rng=6)
    inverted, _ = data.part_scene((52, 60), centre=centre, size=size, margin=2, clutter=3, noise=0.01,
                                  polarity="inverted", rng=6)
    mixed, _ = data.part_scene((52, 60), centre=centre, size=size, margin=2, clutter=3, noise=0.01,
                               polarity="mixed", rng=6)
    s = detection.shape_match(normal, model)
    assert detection.best_match(s, "zncc") == where and s.max() > 0.9
    s_inv = detection.shape_match(inverted, model)
    assert s_inv.min() < -0.9 and detection.best_match(-s_inv, "zncc") == where
    assert detection.best_match(detection.shape_match(inverted, model, "global"), "zncc") == where
    local = detection.shape_match(mixed, model, "local")
    glob = detection.shape_match(mixed, model, "global")
    assert detection.best_match(local, "zncc") == where
    assert local.max() > 0.85 and glob[where[1], where[0]] < local[where[1], where[0]] - 0.3


def test_shape_model_needs_a_control_point():
    with pytest.raises(ValueError, match="threshold"):
        detection.shape_model(np.ones((5, 5)), 0.0)


# --------------------------------------------------------------------------------------------
# Hough transform
# --------------------------------------------------------------------------------------------
def _line_edges(shape, lines, noise=0.0, seed=0):
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    img = np.zeros(shape, bool)
    for rho, theta in lines:
        img |= np.abs(x * np.cos(theta) + y * np.sin(theta) - rho) < 0.5
    img |= np.random.default_rng(seed).random(shape) < noise
    return img


def test_hough_lines_equals_scikit_image():
    e = _line_edges((60, 80), [(30.0, 0.4), (-20.0, -1.1), (45.0, 1.3)], noise=0.02)
    e[0, :] = False
    e[:, 0] = False                           # no exact halves (see the module docstring)
    acc, thetas, rhos = detection.hough_lines(e)
    h, t, d = sktransform.hough_line(e)
    assert np.allclose(thetas, t, atol=1e-12) and np.array_equal(rhos, d)
    assert np.array_equal(acc, h)
    # with the first row and column back the only differences are exact halves (a few votes)
    e2 = _line_edges((60, 80), [(30.0, 0.4)], noise=0.05, seed=1)
    acc2, _, _ = detection.hough_lines(e2)
    h2, _, _ = sktransform.hough_line(e2)
    assert np.array_equal(acc2.sum(axis=0), h2.sum(axis=0))
    assert np.abs(acc2.astype(int) - h2.astype(int)).sum() <= 2 * (e2[0].sum() + e2[:, 0].sum()) * 4


def test_hough_lines_brute_force_with_other_steps():
    rng = np.random.default_rng(7)
    e = rng.random((13, 17)) < 0.2
    acc, thetas, rhos = detection.hough_lines(e, theta_step=math.pi / 36, rho_step=1.5)
    assert len(thetas) == 36 and np.isclose(thetas[0], -math.pi / 2)
    k = math.ceil(math.hypot(13, 17) / 1.5)
    assert np.allclose(rhos, np.arange(-k, k + 1) * 1.5)
    brute = np.zeros_like(acc)
    for y, x in zip(*np.nonzero(e)):
        for j, t in enumerate(thetas):
            brute[int(math.floor((x * math.cos(t) + y * math.sin(t)) / 1.5 + 0.5)) + k, j] += 1
    assert np.array_equal(acc, brute) and acc.dtype.kind == "i"
    assert len(detection.hough_lines(e, theta_step=math.pi / 180)[1]) == 180   # the 1e-9 guard


def test_hough_peaks_agree_with_scikit_image():
    lines = [(30.0, 0.4), (-20.0, -1.1), (45.0, 1.3)]
    e = _line_edges((80, 100), lines, noise=0.01)
    acc, thetas, rhos = detection.hough_lines(e)
    ours = detection.hough_peaks(acc, thetas, rhos, count=3, min_distance=9)
    _, t_peaks, r_peaks = sktransform.hough_line_peaks(acc, thetas, rhos, min_distance=9, min_angle=9, num_peaks=3)
    step = thetas[1] - thetas[0]
    theirs = sorted(zip(r_peaks, t_peaks))
    assert len(ours) == 3
    for (rho, theta), (r2, t2) in zip(sorted(map(tuple, ours)), theirs):
        assert abs(rho - r2) <= 1.0 and abs(theta - t2) <= step + 1e-12
    for rho, theta in lines:             # and they are the drawn lines
        assert np.min(np.abs(ours[:, 0] - rho) + 10 * np.abs(ours[:, 1] - theta)) <= 1.0 + 10 * step


def test_hough_peaks_greedy_rules():
    acc = np.array([[0, 5, 5, 0], [0, 0, 0, 0], [0, 0, 0, 5]])
    peaks = detection.hough_peaks(acc, np.arange(4.0), np.arange(3.0), min_distance=1)
    assert np.array_equal(peaks, [[0.0, 1.0], [2.0, 3.0]])       # tie: the first in raster order
    assert detection.hough_peaks(np.zeros((3, 4)), np.arange(4.0), np.arange(3.0)).shape == (0, 2)
    assert len(detection.hough_peaks(acc, np.arange(4.0), np.arange(3.0), min_distance=0, count=2)) == 2


# --------------------------------------------------------------------------------------------
# Generalized Hough Transform
# --------------------------------------------------------------------------------------------
def test_rtable_reconstructs_the_edge_points():
    tpl, _ = data.part_template(30)
    e = edges.canny(tpl, 1.0)
    table = detection.ght_build(e, tpl, bins=24)
    ref = np.array(table["reference"])
    ys, xs = np.nonzero(e)
    assert np.allclose(ref, (xs.mean(), ys.mean()))
    points = np.vstack([ref - r for r in table["table"]])
    assert sorted(map(tuple, points.round(9))) == sorted(zip(xs.astype(float), ys.astype(float)))
    gx, gy = edges.sobel(tpl)
    for k, r in enumerate(table["table"]):
        for x, y in (ref - r).astype(int):
            assert int(np.round(math.atan2(gy[y, x], gx[y, x]) / (2 * math.pi / 24))) % 24 == k


def test_ght_finds_a_translated_part_exactly():
    size = 30
    tpl, _ = data.part_template(size)
    table = detection.ght_build(edges.canny(tpl, 1.0), tpl, reference=((size - 1) / 2, (size - 1) / 2))
    big = np.full((70, 90), 0.2)
    big[20:20 + size, 41:41 + size] = tpl
    acc, best = detection.ght_detect(big, table, edge_params={"sigma": 1.0})
    assert best[:2] == (56, 34)          # 41 + 14.5 and 20 + 14.5, halves rounded to even
    assert acc.shape == (1, 1, 70, 90) and acc.max() >= 0.8 * sum(len(r) for r in table["table"])


def test_ght_target_scale_rotation_clutter_occlusion():
    """Issue target: with clutter and 30% occlusion the part is found within 2 px, at the
    right scale and angle (±1 step), in at least 9 of 10 random scenes."""
    size = 40
    tpl, _ = data.part_template(size)
    table = detection.ght_build(edges.canny(tpl, 1.0), tpl, bins=36)
    scales = np.round(np.arange(0.8, 1.2001, 0.1), 3)
    angles = np.deg2rad(np.arange(-180, 180, 10))       # the R-table's 10° bins
    found = 0
    for seed in range(10):
        rng = np.random.default_rng(100 + seed)
        s, a = float(rng.uniform(0.8, 1.2)), float(rng.uniform(-math.pi, math.pi))
        scene, pose = data.part_scene((112, 112), scale=s, angle=a, size=size, clutter=6, occlusion=0.3, rng=rng)
        assert 0.25 <= pose["occluded"] <= 0.31
        _, (x, y, s_hat, a_hat) = detection.ght_detect(scene, table, scales, angles, edge_params={"sigma": 1.0})
        tx, ty = data.to_scene(pose, table["reference"])
        angle_error = abs((a_hat - a + math.pi) % (2 * math.pi) - math.pi)
        found += (math.hypot(x - tx, y - ty) <= 2 and abs(s_hat - s) <= 0.1 + 1e-9
                  and angle_error <= math.radians(15) + 1e-9)
    assert found >= 9


def test_ght_uses_the_registry_for_canny():
    """ght_detect calls edges.canny through the registry: a student's Canny is used under
    cvkit.use('student')."""
    calls = []

    @cvkit.student("edges.canny")
    def my_canny(image, sigma=1.4, low=0.1, high=0.2, relative=True):
        calls.append(sigma)
        return np.zeros(np.shape(image), dtype=bool)

    try:
        tpl, _ = data.part_template(20)
        table = detection.ght_build(edges.canny(tpl), tpl)
        with cvkit.use("student"):
            acc, _ = detection.ght_detect(tpl, table, edge_params={"sigma": 2.0})
        assert calls == [2.0] and acc.sum() == 0
    finally:
        registry.provider("student").remove("edges.canny")


# --------------------------------------------------------------------------------------------
# bad input (hypothesis)
# --------------------------------------------------------------------------------------------


@FAST
@given(shape=st.sampled_from([(5,), (4, 4, 3), (2, 2, 2, 2)]))
def test_wrong_ndim_is_refused(shape):
    bad = np.zeros(shape)
    good = np.ones((6, 6))
    with pytest.raises(ValueError, match="image"):
        detection.match_template(bad, good[:2, :2])
    with pytest.raises(ValueError, match="template"):
        detection.match_template(good, bad)
    with pytest.raises(ValueError, match="edges"):
        detection.hough_lines(bad)
    with pytest.raises(ValueError, match="scores"):
        detection.best_match(bad, "ssd")


@FAST
@given(word=st.one_of(st.text(max_size=8).filter(lambda s: s not in ("ssd", "sad", "ncc", "zncc")), st.none(),
                      st.integers()))
def test_bad_measure_and_polarity(word):
    img = np.random.default_rng(0).random((8, 8))
    with pytest.raises(ValueError, match="measure"):
        detection.match_template(img, img[:3, :3], word)
    with pytest.raises(ValueError, match="measure"):
        detection.best_match(img, word)
    if word not in ("none", "global", "local"):
        with pytest.raises(ValueError, match="polarity"):
            detection.shape_match(img, detection.shape_model(img[:4, :4], 0.0), word)


@FAST
@given(bad=st.sampled_from([np.nan, np.inf, -np.inf]), pos=st.tuples(st.integers(0, 5), st.integers(0, 6)))
def test_non_finite_values_are_refused(bad, pos):
    img = np.random.default_rng(1).random((6, 7))
    img[pos] = bad
    with pytest.raises(ValueError, match="finite"):
        detection.match_template(img, np.ones((2, 2)))
    with pytest.raises(ValueError, match="finite"):
        detection.shape_model(img, 0.1)
    with pytest.raises(ValueError, match="finite"):
        detection.hough_peaks(img, np.arange(7.0), np.arange(6.0))


@FAST
@given(step=st.one_of(st.floats(max_value=0.0), st.just(np.nan), st.just(np.inf), st.floats(3.2, 100.0)))
def test_bad_steps(step):
    e = np.ones((4, 4), bool)
    with pytest.raises(ValueError, match="theta_step"):
        detection.hough_lines(e, theta_step=step)
    if not (step > 0 and math.isfinite(step)):
        with pytest.raises(ValueError, match="rho_step"):
            detection.hough_lines(e, rho_step=step)


def test_other_bad_arguments_name_the_argument():
    img = np.random.default_rng(2).random((10, 12))
    with pytest.raises(ValueError, match="fit"):
        detection.match_template(img[:3, :3], img)
    with pytest.raises(ValueError, match="accumulator"):
        detection.hough_peaks(np.ones((3, 4)), np.arange(3.0), np.arange(3.0))
    with pytest.raises(ValueError, match="count"):
        detection.hough_peaks(np.ones((3, 4)), np.arange(4.0), np.arange(3.0), count=-1)
    with pytest.raises(TypeError, match="min_distance"):
        detection.hough_peaks(np.ones((3, 4)), np.arange(4.0), np.arange(3.0), min_distance=1.5)
    with pytest.raises(ValueError, match="template_edges"):
        detection.ght_build(np.zeros((5, 5)), img[:5, :5])
    with pytest.raises(ValueError, match="same shape"):
        detection.ght_build(np.ones((5, 5)), img[:5, :6])
    with pytest.raises(ValueError, match="bins"):
        detection.ght_build(np.ones((5, 5)), img[:5, :5], bins=0)
    with pytest.raises(TypeError, match="rtable"):
        detection.ght_detect(img, [1, 2, 3])
    table = detection.ght_build(np.ones((5, 5)), img[:5, :5], bins=4)
    with pytest.raises(ValueError, match="scales"):
        detection.ght_detect(img, table, scales=(0.0,))
    with pytest.raises(TypeError, match="edge_params"):
        detection.ght_detect(img, table, edge_params=[1])
    with pytest.raises(ValueError, match="model"):
        detection.shape_match(img, {"points": np.zeros((2, 2))})
    with pytest.raises(ValueError, match="inside the template"):
        detection.shape_match(img, {"points": np.array([[5.0, 0.0]]), "directions": np.array([[1.0, 0.0]]),
                                    "shape": (3, 3)})


def test_find_lines_refuses_what_hough_lines_refuses():
    # text, NaN and a 1-D map were taken as edge maps before ("False" is a non-empty string)
    edges = np.zeros((20, 20), bool)
    edges[:, 5] = True
    with pytest.raises(TypeError, match="edges"):
        detection.find_lines(edges.astype(str))
    with pytest.raises(ValueError, match="edges.*finite"):
        detection.find_lines(np.where(edges, np.nan, 0.0))
    with pytest.raises(ValueError, match="edges.*2 dimensions"):
        detection.find_lines(edges.ravel())
    # a 0/1 numeric map is still an edge map, found as its bool twin
    np.testing.assert_array_equal(detection.find_lines(edges.astype(np.uint8)), detection.find_lines(edges))
