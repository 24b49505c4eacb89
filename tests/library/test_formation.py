"""Chapter 2 image formation (cvkit.formation) against oracles, definitions and properties.

Oracles and mappings:
- project_pinhole(P, f) = cv2.projectPoints(P, rvec=0, tvec=0, K=[[f,0,0],[0,f,0],[0,0,1]],
  no distortion);
- depth_from_disparity(d, b, f) = Z of cv2.reprojectImageTo3D(d, Q) with
  Q = [[1,0,0,0],[0,1,0,0],[0,0,0,f],[0,0,1/b,0]] (Z = f / (d/b) = b·f/d);
- quantize(x, 8) · 255 = skimage.util.img_as_ubyte(x), quantize(x, 16) · 65535 = img_as_uint(x)
  for x in [0, 1] (both round half to even);
- image_memory_bits(W, H, m) = 8 · numpy nbytes of an (H, W) uint8 / uint16 / (H, W, 3) uint8
  array (m = 8, 16, 24);
- snr_db(F) = −20·log10(scipy.stats.variation(F, axis=0)) (variation = std/mean, ddof 0);
- demosaic_bilinear = cv2.cvtColor(raw, COLOR_Bayer<XY>2RGB) away from a 1-pixel border,
  with cvkit RGGB/BGGR/GRBG/GBRG = OpenCV BG/RG/GB/GR (OpenCV rounds to integers: ±0.5);
- thin lens and blur circle against their definitions (the lens equation, a traced marginal ray).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cvkit import formation, registry

cv2 = pytest.importorskip("cv2")


def _rng(seed=0):
    return np.random.default_rng(seed)


# --------------------------------------------------------------------------------------------
# projection and depth
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("f", [0.035, 1.0, 800.0])
def test_project_pinhole_matches_cv2_project_points(f):
    rng = _rng(1)
    points = np.hstack([rng.uniform(-5, 5, (50, 2)), rng.uniform(0.5, 30, (50, 1))])
    camera = np.array([[f, 0, 0], [0, f, 0], [0, 0, 1.0]])
    expected, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), camera, None)
    np.testing.assert_allclose(formation.project_pinhole(points, f), expected[:, 0, :], rtol=1e-12, atol=1e-12)


def test_image_size_is_inversely_proportional_to_depth():
    """§2.7: a segment of length L parallel to the image plane at depth z images to L·f/z."""
    f, length = 50.0, 3.0
    for z in (2.0, 4.0, 8.0, 16.0):
        ends = np.array([[0.7, -1.0, z], [0.7 + length, -1.0, z]])
        u = formation.project_pinhole(ends, f)
        assert math.isclose(np.linalg.norm(u[1] - u[0]), length * f / z, rel_tol=1e-12)


def test_parallel_lines_meet_at_the_vanishing_point():
    """Points P0 + t·D with t → ∞ project to f·(Dx/Dz, Dy/Dz), for every start point P0."""
    f, direction = 2.0, np.array([1.0, -0.5, 2.0])
    vanishing = f * direction[:2] / direction[2]
    for start in ([0.0, 0.0, 1.0], [3.0, 1.0, 2.0], [-2.0, 4.0, 5.0]):
        far = np.asarray(start) + 1e12 * direction
        np.testing.assert_allclose(formation.project_pinhole(far[None], f)[0], vanishing, rtol=1e-10)


def test_project_pinhole_edge_cases():
    assert formation.project_pinhole(np.zeros((0, 3)), 2.0).shape == (0, 2)
    np.testing.assert_array_equal(formation.project_pinhole([[1, 2, -4]], 2), [[-0.5, -1.0]])
    with pytest.raises(ValueError, match="z = 0"):
        formation.project_pinhole([[1.0, 2.0, 0.0]], 1.0)


def test_depth_from_disparity_matches_cv2_reproject():
    rng = _rng(2)
    b, f = 0.193, 994.978
    disparity = rng.uniform(1, 64, (20, 30)).astype(np.float32)
    q = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, f], [0, 0, 1 / b, 0]], dtype=np.float64)
    z = cv2.reprojectImageTo3D(disparity, q)[..., 2]
    np.testing.assert_allclose(formation.depth_from_disparity(disparity, b, f), z, rtol=1e-5)


def test_depth_from_disparity_special_values():
    z = formation.depth_from_disparity(np.array([4.0, 0.0, -1.0, np.nan, np.inf]), 2.0, 10.0)
    np.testing.assert_array_equal(z, [5.0, np.inf, np.nan, np.nan, 0.0])
    assert isinstance(formation.depth_from_disparity(20, 2, 10), np.floating)
    assert formation.depth_from_disparity(np.array([[1, 2]], dtype=np.uint8), 1, 1).dtype == np.float64


def test_depth_and_projection_are_consistent():
    """A point at depth z seen by two cameras b apart has disparity u_L − u_R = b·f/z."""
    rng = _rng(3)
    b, f = 0.3, 700.0
    points = np.hstack([rng.uniform(-2, 2, (40, 2)), rng.uniform(1, 50, (40, 1))])
    u_left = formation.project_pinhole(points, f)[:, 0]
    u_right = formation.project_pinhole(points - [b, 0, 0], f)[:, 0]
    np.testing.assert_allclose(formation.depth_from_disparity(u_left - u_right, b, f), points[:, 2], rtol=1e-10)


# --------------------------------------------------------------------------------------------
# lenses
# --------------------------------------------------------------------------------------------
def test_thin_lens_satisfies_the_lens_equation():
    f = 35.0
    d_s = np.concatenate([np.geomspace(36, 1e6, 30), np.geomspace(0.1, 34.9, 20)])
    d_i = formation.thin_lens_image_distance(d_s, f)
    np.testing.assert_allclose(1 / d_s + 1 / d_i, 1 / f, rtol=1e-10)
    assert np.all(d_i[d_s > f] > 0) and np.all(d_i[d_s < f] < 0)
    assert np.all(np.diff(d_i[:30]) < 0)  # closer objects focus further behind the lens (§2.10)


def test_thin_lens_limits():
    np.testing.assert_array_equal(formation.thin_lens_image_distance([np.inf, 50.0], 50.0), [50.0, np.inf])
    assert formation.thin_lens_image_distance(np.inf, 7.5) == 7.5


def _traced_blur(d_o, d_f, f, aperture):
    """Trace the ray from the axial point at d_o through the lens rim (height D/2): after the
    thin lens it converges to the axis at d_i(d_o); its height on the sensor at d_i(d_f) is
    (D/2)·|1 − d_i(d_f)/d_i(d_o)|, the blur circle's radius."""
    d_io = f * d_o / (d_o - f)
    d_if = f * d_f / (d_f - f)
    slope = -(aperture / 2) / d_io
    height = aperture / 2 + slope * d_if
    return 2 * abs(height)


def test_blur_circle_matches_a_traced_ray():
    rng = _rng(4)
    for _ in range(200):
        f = rng.uniform(10, 200)
        d_o, d_f = f * rng.uniform(1.01, 500, 2)
        aperture = f / rng.choice([1.4, 2, 4, 8, 16])
        got = formation.blur_circle_diameter(d_o, d_f, f, aperture)
        assert math.isclose(got, _traced_blur(d_o, d_f, f, aperture), rel_tol=1e-9, abs_tol=1e-12)


def test_blur_circle_properties():
    d_o = np.geomspace(60, 1e5, 50)
    c = formation.blur_circle_diameter(d_o, 2000.0, 50.0, 25.0)
    assert formation.blur_circle_diameter(2000.0, 2000.0, 50.0, 25.0) == 0.0
    # proportional to the aperture: stopping down from f/2 to f/8 divides every circle by 4
    np.testing.assert_allclose(formation.blur_circle_diameter(d_o, 2000.0, 50.0, 6.25), c / 4, rtol=1e-12)
    # limits at infinity
    assert math.isclose(formation.blur_circle_diameter(np.inf, 2000.0, 50.0, 25.0), 25 * 50 / 1950, rel_tol=1e-12)
    assert math.isclose(formation.blur_circle_diameter(500.0, np.inf, 50.0, 25.0), 25 * 50 / 500, rel_tol=1e-12)
    assert formation.blur_circle_diameter(np.inf, np.inf, 50.0, 25.0) == 0.0
    far = formation.blur_circle_diameter(1e12, 2000.0, 50.0, 25.0)
    assert math.isclose(far, formation.blur_circle_diameter(np.inf, 2000.0, 50.0, 25.0), rel_tol=1e-8)
    assert formation.blur_circle_diameter(np.ones((3, 1)) * 1000, np.full((1, 4), 3000.0), 50.0, 10.0).shape == (3, 4)


# --------------------------------------------------------------------------------------------
# digitization
# --------------------------------------------------------------------------------------------
def test_quantize_matches_skimage_conversions():
    skutil = pytest.importorskip("skimage.util")
    x = np.concatenate([_rng(5).random(20000), np.arange(511) / 510.0])
    np.testing.assert_array_equal(formation.quantize(x, 8) * 255, skutil.img_as_ubyte(x))
    np.testing.assert_allclose(formation.quantize(x, 16) * 65535, skutil.img_as_uint(x), atol=1e-9)


def test_quantize_properties():
    rng = _rng(6)
    x = rng.uniform(-0.5, 1.5, 5000)
    for bits in (1, 2, 3, 5, 8):
        q = formation.quantize(x, bits)
        step = 1 / (2 ** bits - 1)
        levels = np.unique(q)
        assert len(levels) == 2 ** bits
        np.testing.assert_allclose(levels, np.arange(2 ** bits) * step, atol=1e-15)
        inside = (x >= 0) & (x <= 1)
        assert np.abs(q - x)[inside].max() <= step / 2 + 1e-15
        np.testing.assert_array_equal(formation.quantize(q, bits), q)  # idempotent
    img = rng.integers(0, 256, (5, 7), dtype=np.uint8)
    np.testing.assert_array_equal(formation.quantize(img, 8, vmax=255), img)
    np.testing.assert_array_equal(formation.quantize([0.5, 1.5, 2.5], 2, vmax=3), [0.0, 2.0, 2.0])


def test_quantize_does_not_modify_its_input():
    x = np.array([0.2, 0.7, 1.3])
    before = x.copy()
    formation.quantize(x, 2)
    np.testing.assert_array_equal(x, before)


def test_image_memory_bits_matches_numpy_nbytes():
    for (h, w) in ((480, 640), (1080, 1920), (1, 1), (3, 7)):
        assert formation.image_memory_bits(w, h, 8) == np.zeros((h, w), np.uint8).nbytes * 8
        assert formation.image_memory_bits(w, h, 16) == np.zeros((h, w), np.uint16).nbytes * 8
        assert formation.image_memory_bits(w, h, 24) == np.zeros((h, w, 3), np.uint8).nbytes * 8
    big = formation.image_memory_bits(10 ** 6, 10 ** 6, 64)
    assert isinstance(big, int) and big == 64 * 10 ** 12


def test_snr_matches_scipy_variation():
    stats = pytest.importorskip("scipy.stats")
    frames = 0.5 + 0.05 * _rng(7).standard_normal((12, 6, 9))
    np.testing.assert_allclose(formation.snr_db(frames), -20 * np.log10(stats.variation(frames, axis=0)), rtol=1e-10)


def test_snr_special_values_and_averaging():
    frames = np.array([[[1.0, 0.0, -2.0, 3.0]], [[1.0, 0.0, -1.0, 5.0]]])
    np.testing.assert_array_equal(formation.snr_db(frames)[0, :3], [np.inf, np.nan, np.nan])
    assert math.isclose(formation.snr_db(frames)[0, 3], 20 * math.log10(4.0), rel_tol=1e-12)
    # averaging T frames divides σ by √T: the SNR of the average grows by 10·log10(T) dB
    rng = _rng(8)
    scene = rng.uniform(0.3, 0.7, (16, 16))
    stack = scene + 0.05 * rng.standard_normal((64, 16, 16))
    single = np.median(formation.snr_db(stack))
    averaged = np.median(formation.snr_db(stack.reshape(16, 4, 16, 16).mean(axis=1)))
    assert abs((averaged - single) - 10 * math.log10(4)) < 1.5
    with pytest.raises(ValueError, match="T >= 2"):
        formation.snr_db(np.ones((1, 3, 3)))


def test_dynamic_range():
    assert formation.dynamic_range_db(1000.0, 1.0) == pytest.approx(60.0, abs=1e-12)
    bits = np.arange(1, 17)
    np.testing.assert_allclose(formation.dynamic_range_db(2.0 ** bits, 1.0), 20 * np.log10(2) * bits, rtol=1e-12)
    assert formation.dynamic_range_db([[1.0], [4.0]], [2.0, 1.0, 0.5]).shape == (2, 3)
    assert formation.dynamic_range_db(1.0, 10.0) == pytest.approx(-20.0)


@pytest.mark.filterwarnings("error")
def test_ratios_beyond_the_float_range_give_their_value_without_a_warning():
    """Valid inputs whose ratio over- or underflows: the exact value, and no RuntimeWarning
    (a caller running with warnings as errors must not see one)."""
    assert formation.dynamic_range_db(1e-300, 1e300) == pytest.approx(-12000.0)
    assert formation.dynamic_range_db(1e300, 1e-300) == pytest.approx(12000.0)
    np.testing.assert_array_equal(formation.depth_from_disparity(np.array([1e-320, 2.0]), 1.0, 1.0), [np.inf, 0.5])


# --------------------------------------------------------------------------------------------
# Bayer
# --------------------------------------------------------------------------------------------
def test_bayer_mosaic_by_definition():
    rng = _rng(9)
    rgb = rng.random((7, 9, 3))
    channel = {"R": 0, "G": 1, "B": 2}
    for pattern in formation.PATTERNS:
        raw = formation.bayer_mosaic(rgb, pattern)
        for i in range(7):
            for j in range(9):
                assert raw[i, j] == rgb[i, j, channel[pattern[2 * (i % 2) + j % 2]]]


def test_half_the_sites_are_green():
    rgb = np.zeros((8, 10, 3))
    rgb[..., 1] = 1.0
    for pattern in formation.PATTERNS:
        assert formation.bayer_mosaic(rgb, pattern).mean() == 0.5


@pytest.mark.parametrize("pattern", formation.PATTERNS)
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_demosaic_matches_opencv_away_from_the_border(pattern, dtype):
    top = np.iinfo(dtype).max
    rng = _rng(10)
    raw = rng.integers(0, top + 1, (24, 31)).astype(dtype)
    code = getattr(cv2, f"COLOR_Bayer{formation.OPENCV_BAYER_NAMES[pattern]}2RGB")
    expected = cv2.cvtColor(raw, code).astype(np.float64)
    got = formation.demosaic_bilinear(raw, pattern)
    assert np.abs(got - expected)[1:-1, 1:-1].max() <= 0.5  # OpenCV rounds to integers


def test_demosaic_keeps_measured_samples_and_constant_colours():
    rng = _rng(11)
    for pattern in formation.PATTERNS:
        rgb = rng.random((9, 12, 3))
        raw = formation.bayer_mosaic(rgb, pattern)
        out = formation.demosaic_bilinear(raw, pattern)
        np.testing.assert_array_equal(formation.bayer_mosaic(out, pattern), raw)
        colour = np.ones((7, 8, 3)) * [0.1, 0.6, 0.9]
        np.testing.assert_allclose(formation.demosaic_bilinear(formation.bayer_mosaic(colour, pattern), pattern),
                                   colour, rtol=0, atol=1e-15)


def test_demosaic_is_exact_on_linear_ramps_inside():
    """Bilinear interpolation reproduces colour planes that are linear in x and y."""
    y, x = np.mgrid[0:10, 0:12].astype(float)
    rgb = np.stack([0.1 + 0.02 * x + 0.03 * y, 0.5 - 0.01 * x + 0.02 * y, 0.2 + 0.04 * x - 0.01 * y], axis=-1)
    out = formation.demosaic_bilinear(formation.bayer_mosaic(rgb, "GBRG"), "GBRG")
    np.testing.assert_allclose(out[1:-1, 1:-1], rgb[1:-1, 1:-1], atol=1e-14)


def test_demosaic_borders_read_same_colour_sites():
    """reflect101 keeps the phase: at the left edge a missing red sample at a green site is
    the mean of its two red neighbours, which are the same pixel."""
    raw = np.arange(20.0).reshape(4, 5)
    out = formation.demosaic_bilinear(raw, "GRBG")  # row 0: G R G R G
    assert out[0, 0, 0] == raw[0, 1]
    assert out[0, 4, 0] == raw[0, 3]


# --------------------------------------------------------------------------------------------
# registry, inputs
# --------------------------------------------------------------------------------------------
IDS = ["project_pinhole", "depth_from_disparity", "thin_lens_image_distance", "blur_circle_diameter",
       "quantize", "image_memory_bits", "snr_db", "dynamic_range_db", "bayer_mosaic", "demosaic_bilinear"]


@pytest.mark.parametrize("name", IDS)
def test_registered_with_check(name):
    record = registry.get(f"formation.{name}")
    assert record.reference is getattr(formation, name)
    assert record.check is not None and record.section.startswith("2.")


def test_inputs_are_not_modified():
    rng = _rng(12)
    arrays = {
        "points": rng.random((5, 3)) + 1, "d": rng.random((4, 4)), "rgb": rng.random((4, 6, 3)),
        "raw": rng.random((4, 6)), "frames": rng.random((3, 4, 4)) + 1,
    }
    before = {k: v.copy() for k, v in arrays.items()}
    formation.project_pinhole(arrays["points"], 2.0)
    formation.depth_from_disparity(arrays["d"], 1.0, 1.0)
    formation.thin_lens_image_distance(arrays["d"] + 2, 1.0)
    formation.bayer_mosaic(arrays["rgb"])
    formation.demosaic_bilinear(arrays["raw"])
    formation.snr_db(arrays["frames"])
    for key in arrays:
        np.testing.assert_array_equal(arrays[key], before[key])


# --------------------------------------------------------------------------------------------
# bad input (hypothesis)
# --------------------------------------------------------------------------------------------
finite = st.floats(-1e6, 1e6, allow_nan=False)
not_positive = st.one_of(st.floats(max_value=0.0, allow_nan=False), st.just(np.nan), st.just(np.inf))


@given(shape=st.sampled_from([(3,), (4, 2), (2, 4), (1, 3, 3), ()]))
def test_project_pinhole_bad_shape(shape):
    with pytest.raises(ValueError, match="points_cam"):
        formation.project_pinhole(np.ones(shape), 1.0)


@given(f=not_positive)
def test_project_pinhole_bad_focal(f):
    with pytest.raises(ValueError, match="f must"):
        formation.project_pinhole([[1.0, 1.0, 1.0]], f)


@given(value=st.one_of(st.text(max_size=3), st.none(), st.just([["a", 1, 2]]), st.just(np.array([[1 + 1j, 1, 1]]))))
def test_project_pinhole_bad_type(value):
    with pytest.raises(TypeError, match="points_cam"):
        formation.project_pinhole(value, 1.0)


@given(bad=st.sampled_from([np.nan, np.inf, -np.inf]))
def test_project_pinhole_non_finite(bad):
    with pytest.raises(ValueError, match="points_cam"):
        formation.project_pinhole([[1.0, bad, 2.0]], 1.0)


@given(b=not_positive, which=st.sampled_from(["baseline", "focal"]))
def test_depth_bad_parameters(b, which):
    kwargs = {"baseline": 1.0, "focal": 1.0, which: b}
    with pytest.raises(ValueError, match=which):
        formation.depth_from_disparity([1.0], **kwargs)


@given(d=st.one_of(st.floats(max_value=0.0, allow_nan=False), st.just(np.nan)))
def test_thin_lens_bad_distance(d):
    with pytest.raises(ValueError, match="object_distance"):
        formation.thin_lens_image_distance([100.0, d], 50.0)


@given(f=not_positive)
def test_thin_lens_bad_focal(f):
    with pytest.raises(ValueError, match="focal_length"):
        formation.thin_lens_image_distance(100.0, f)


@given(which=st.integers(0, 3), value=st.floats(-100, 50))
def test_blur_circle_bad_values(which, value):
    args = [1000.0, 2000.0, 50.0, 25.0]
    names = ["object_distance", "focus_distance", "focal_length", "aperture_diameter"]
    bad = {0: value, 1: value, 2: min(value, 0.0), 3: min(value, -1e-3)}[which]
    args[which] = bad
    with pytest.raises(ValueError, match=names[which]):
        formation.blur_circle_diameter(*args)


def test_blur_circle_shapes_must_broadcast():
    with pytest.raises(ValueError, match="broadcast"):
        formation.blur_circle_diameter(np.ones(3) * 100, np.ones(4) * 200, 50.0, 10.0)


@given(bits=st.one_of(st.integers(max_value=0), st.integers(min_value=54, max_value=200)))
def test_quantize_bad_bits_value(bits):
    with pytest.raises(ValueError, match="bits"):
        formation.quantize([0.5], bits)


@given(bits=st.one_of(st.floats(allow_nan=False), st.text(max_size=2), st.booleans(), st.none()))
def test_quantize_bad_bits_type(bits):
    with pytest.raises(TypeError, match="bits"):
        formation.quantize([0.5], bits)


@given(vmax=not_positive)
def test_quantize_bad_vmax(vmax):
    with pytest.raises(ValueError, match="vmax"):
        formation.quantize([0.5], 4, vmax)


@given(bad=st.sampled_from([np.nan, np.inf]))
def test_quantize_non_finite_image(bad):
    with pytest.raises(ValueError, match="image"):
        formation.quantize([0.5, bad], 4)


@given(which=st.integers(0, 2), value=st.one_of(st.integers(max_value=0), st.floats(allow_nan=False), st.text(max_size=2)))
def test_image_memory_bits_bad_arguments(which, value):
    names = ["width", "height", "bits_per_pixel"]
    args = [10, 10, 8]
    args[which] = value
    with pytest.raises((ValueError, TypeError), match=names[which]):
        formation.image_memory_bits(*args)


@given(shape=st.sampled_from([(5,), (4, 4), (2, 3, 4, 2), (2, 3, 4, 5, 1)]))
def test_snr_bad_shape(shape):
    with pytest.raises(ValueError, match="frames"):
        formation.snr_db(np.ones(shape))


@given(which=st.sampled_from(["e_max", "e_min"]), value=not_positive)
def test_dynamic_range_bad_values(which, value):
    kwargs = {"e_max": 10.0, "e_min": 1.0, which: value}
    with pytest.raises(ValueError, match=which):
        formation.dynamic_range_db(**kwargs)


@given(pattern=st.one_of(st.text(max_size=5).filter(lambda s: s not in formation.PATTERNS), st.none(), st.integers()))
@settings(max_examples=30)
def test_bad_pattern(pattern):
    with pytest.raises(ValueError, match="pattern"):
        formation.bayer_mosaic(np.ones((2, 2, 3)), pattern)
    with pytest.raises(ValueError, match="pattern"):
        formation.demosaic_bilinear(np.ones((2, 2)), pattern)


@given(shape=st.sampled_from([(4, 4), (4, 4, 4), (4, 4, 1), (4,)]))
def test_bayer_mosaic_bad_shape(shape):
    with pytest.raises(ValueError, match="rgb"):
        formation.bayer_mosaic(np.ones(shape))


@given(shape=st.sampled_from([(1, 5), (5, 1), (4,), (4, 4, 3)]))
def test_demosaic_bad_shape(shape):
    with pytest.raises(ValueError, match="raw"):
        formation.demosaic_bilinear(np.ones(shape))


def test_extreme_but_finite_inputs_give_the_finite_answer():
    """An intermediate product beyond the float range must not turn a finite answer into inf,
    0 or nan (never a silent wrong answer), and the warnings stay inside."""
    import warnings

    frames = np.random.default_rng(0).uniform(1, 2, (5, 4, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_allclose(formation.snr_db(frames * 1e160), formation.snr_db(frames), rtol=1e-13)
        np.testing.assert_allclose(formation.snr_db(frames * 1e-160), formation.snr_db(frames), rtol=1e-13)
        np.testing.assert_allclose(formation.snr_db(np.array([[[1e-320]], [[2e-320]]])), [[20 * np.log10(3.0)]],
                                   rtol=1e-12)
        assert formation.thin_lens_image_distance(1e308, 50.0) == pytest.approx(50.0)
        assert formation.blur_circle_diameter(1e300, 1e10, 50.0, 25.0) == pytest.approx(25 * 50 / (1e10 - 50))
        assert formation.dynamic_range_db(1e300, 1e-300) == pytest.approx(12000.0)
        np.testing.assert_allclose(formation.quantize([1.7e308, 0.9e308], 2, vmax=1.7e308),
                                   [1.7e308, 1.7e308 / 3 * 2], rtol=1e-15)
        np.testing.assert_allclose(formation.project_pinhole([[1e306, -2e306, 1e10]], 800.0), [[8e298, -1.6e299]],
                                   rtol=1e-15)
