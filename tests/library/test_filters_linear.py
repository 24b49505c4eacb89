"""Linear filters of Chapter 3 (cvkit.filters._linear) against SciPy / OpenCV oracles.

Parameter mappings (cvkit border -> oracle):
zero -> scipy "constant" (cval 0) / cv2.BORDER_CONSTANT, replicate -> "nearest" /
BORDER_REPLICATE, reflect -> "reflect" / BORDER_REFLECT, reflect101 -> "mirror" /
BORDER_REFLECT_101. cv2.filter2D is a correlation with anchor (kh//2, kw//2).
gaussian(sigma) -> scipy gaussian_filter(sigma, truncate=r/sigma) and
cv2.GaussianBlur(ksize=2r+1, sigmaX=sigmaY=sigma) with r = ceil(3 sigma - 1e-9).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.ndimage as ndi
import scipy.signal as signal
from hypothesis import given
from hypothesis import strategies as st
from input_helpers import FAST, raises_naming

import cvkit
from cvkit import filters, registry

cv2 = pytest.importorskip("cv2")

BORDERS = ("zero", "replicate", "reflect", "reflect101")
SCIPY_MODE = {"zero": "constant", "replicate": "nearest", "reflect": "reflect", "reflect101": "mirror"}
CV2_BORDER = {
    "zero": cv2.BORDER_CONSTANT,
    "replicate": cv2.BORDER_REPLICATE,
    "reflect": cv2.BORDER_REFLECT,
    "reflect101": cv2.BORDER_REFLECT_101,
}
# odd, even, mixed, 1-wide, and (for the 11x17 image) larger-than-image kernels
KERNEL_SHAPES = [(3, 3), (2, 2), (4, 3), (3, 4), (1, 5), (6, 1), (5, 7), (8, 8), (15, 9), (13, 22)]
ATOL = 1e-10


def _rng(seed=0):
    return np.random.default_rng(seed)


def _gray(shape=(11, 17), seed=1):
    return _rng(seed).random(shape)


def _color(shape=(9, 13), seed=2):
    return _rng(seed).random(shape + (3,))


def _per_channel(fn, image):
    """Apply a 2-D oracle to each channel of a colour image."""
    if image.ndim == 2:
        return fn(image)
    return np.stack([fn(image[..., c]) for c in range(image.shape[2])], axis=-1)


# --------------------------------------------------------------------------------------------
# correlate / convolve vs oracles
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("kshape", KERNEL_SHAPES)
@pytest.mark.parametrize("image", [_gray(), _color()], ids=["gray", "color"])
def test_correlate_and_convolve_match_scipy(image, kshape, border):
    kernel = _rng(hash(kshape) % 1000).standard_normal(kshape)  # asymmetric
    mode = SCIPY_MODE[border]
    got = filters.correlate(image, kernel, border=border)
    want = _per_channel(lambda ch: ndi.correlate(ch, kernel, mode=mode, cval=0.0, origin=0), image)
    assert got.shape == image.shape and got.dtype == np.float64
    np.testing.assert_allclose(got, want, rtol=0, atol=ATOL)

    got = filters.convolve(image, kernel, border=border)
    want = _per_channel(lambda ch: ndi.convolve(ch, kernel, mode=mode, cval=0.0, origin=0), image)
    np.testing.assert_allclose(got, want, rtol=0, atol=ATOL)


@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("kshape", KERNEL_SHAPES)
@pytest.mark.parametrize("image", [_gray(), _color()], ids=["gray", "color"])
def test_correlate_matches_cv2_filter2d(image, kshape, border):
    kernel = _rng(7).standard_normal(kshape)
    got = filters.correlate(image, kernel, border=border)
    want = cv2.filter2D(image, cv2.CV_64F, kernel, borderType=CV2_BORDER[border])
    np.testing.assert_allclose(got, want.reshape(image.shape), rtol=0, atol=ATOL)


@pytest.mark.parametrize("kshape", [(9, 9), (10, 12), (25, 3)])
@pytest.mark.parametrize("border", BORDERS)
def test_large_kernels_match_scipy(kshape, border):
    """Kernels with many taps (the FFT route) agree with the oracle too."""
    image = _gray((40, 52), seed=3)
    kernel = _rng(4).standard_normal(kshape)
    mode = SCIPY_MODE[border]
    np.testing.assert_allclose(
        filters.correlate(image, kernel, border), ndi.correlate(image, kernel, mode=mode), rtol=0, atol=ATOL
    )
    np.testing.assert_allclose(
        filters.convolve(image, kernel, border), ndi.convolve(image, kernel, mode=mode), rtol=0, atol=ATOL
    )
    color = _color((31, 30), seed=5)
    np.testing.assert_allclose(
        filters.correlate(color, kernel, border, output="valid"),
        _per_channel(lambda ch: signal.correlate2d(ch, kernel, mode="valid"), color),
        rtol=0,
        atol=ATOL,
    )


@pytest.mark.parametrize("shape", [(1, 1), (1, 5), (5, 1), (2, 3)])
@pytest.mark.parametrize("kshape", [(3, 3), (4, 2), (7, 7)])
@pytest.mark.parametrize("border", BORDERS)
def test_tiny_images(shape, kshape, border):
    """One-pixel-wide images: reflections of a single pixel repeat it."""
    image, kernel = _gray(shape), _rng(2).random(kshape)
    mode = SCIPY_MODE[border]
    got = filters.correlate(image, kernel, border)
    np.testing.assert_allclose(got, ndi.correlate(image, kernel, mode=mode), rtol=0, atol=ATOL)
    want = cv2.filter2D(image, cv2.CV_64F, kernel, borderType=CV2_BORDER[border]).reshape(shape)
    np.testing.assert_allclose(got, want, rtol=0, atol=ATOL)
    got = filters.convolve(image, kernel, border)
    np.testing.assert_allclose(got, ndi.convolve(image, kernel, mode=mode), rtol=0, atol=ATOL)


def test_direct_and_fft_routes_are_both_exercised_and_agree():
    """Small kernels take the tap loop, many-tap kernels the FFT; both give the same result."""
    from cvkit.filters import _linear

    from cvkit._fft import fft_pays

    assert not fft_pays(9, (11, 17), (13, 19))
    assert fft_pays(81, (40, 52), (48, 60))
    assert fft_pays(75, (40, 52), (64, 54))
    padded = _gray((30, 41), seed=8)
    kernel = _rng(9).standard_normal((7, 6))
    out_shape = (30 - 7 + 1, 41 - 6 + 1)
    np.testing.assert_allclose(
        _linear._correlate_direct(padded, kernel, out_shape),
        _linear.correlate_valid_fft(padded, kernel),
        rtol=0,
        atol=ATOL,
    )


@pytest.mark.parametrize("kshape", [(1, 1), (3, 3), (2, 2), (4, 3), (3, 6), (11, 17), (5, 1)])
@pytest.mark.parametrize("image", [_gray(), _color((12, 17))], ids=["gray", "color"])
def test_valid_output_matches_scipy_signal(image, kshape):
    kernel = _rng(11).standard_normal(kshape)
    h, w = image.shape[:2]
    got = filters.correlate(image, kernel, output="valid")
    assert got.shape[:2] == (h - kshape[0] + 1, w - kshape[1] + 1)
    want = _per_channel(lambda ch: signal.correlate2d(ch, kernel, mode="valid"), image)
    np.testing.assert_allclose(got, want, rtol=0, atol=ATOL)
    got = filters.convolve(image, kernel, output="valid")
    want = _per_channel(lambda ch: signal.convolve2d(ch, kernel, mode="valid"), image)
    np.testing.assert_allclose(got, want, rtol=0, atol=ATOL)


def test_valid_output_is_the_cropped_same_output():
    image, kernel = _gray(), _rng(3).standard_normal((5, 3))
    same = filters.correlate(image, kernel, border="zero")
    np.testing.assert_allclose(filters.correlate(image, kernel, output="valid"), same[2:-2, 1:-1], atol=ATOL)


@pytest.mark.parametrize("fn", [filters.correlate, filters.convolve])
def test_valid_kernel_larger_than_image_is_an_error(fn):
    with pytest.raises(ValueError, match="kernel"):
        fn(np.zeros((4, 6)), np.ones((5, 3)), output="valid")
    with pytest.raises(ValueError, match="kernel"):
        fn(np.zeros((4, 6)), np.ones((3, 7)), output="valid")


# --------------------------------------------------------------------------------------------
# correlate / convolve properties
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kshape", [(3, 3), (5, 3), (2, 2), (4, 5), (1, 4)])
def test_impulse_response(kshape):
    """Convolving an impulse gives the kernel; correlating gives the flipped kernel."""
    kernel = _rng(5).standard_normal(kshape)
    kh, kw = kshape
    a, b = kh // 2, kw // 2
    impulse = np.zeros((15, 16))
    c = (7, 8)
    impulse[c] = 1.0
    out = filters.convolve(impulse, kernel, border="zero")
    np.testing.assert_array_equal(out[c[0] - a : c[0] - a + kh, c[1] - b : c[1] - b + kw], kernel)
    assert np.count_nonzero(out) == np.count_nonzero(kernel)
    out = filters.correlate(impulse, kernel, border="zero")
    np.testing.assert_array_equal(
        out[c[0] + a - kh + 1 : c[0] + a + 1, c[1] + b - kw + 1 : c[1] + b + 1], kernel[::-1, ::-1]
    )


@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("kshape", [(3, 3), (5, 3), (1, 7)])
def test_convolve_is_correlate_with_flipped_kernel_for_odd_kernels(kshape, border):
    image, kernel = _color(), _rng(8).standard_normal(kshape)
    np.testing.assert_allclose(
        filters.convolve(image, kernel, border),
        filters.correlate(image, kernel[::-1, ::-1], border),
        rtol=0,
        atol=ATOL,
    )


def test_symmetric_kernel_correlation_equals_convolution():
    kernel = np.array([[1.0, 2.0, 1.0], [0.0, 5.0, 0.0], [1.0, 2.0, 1.0]])
    image = _gray()
    np.testing.assert_allclose(filters.convolve(image, kernel), filters.correlate(image, kernel), atol=ATOL)


def test_convolution_is_associative_in_valid_mode():
    """(I * A) * B == I * (A * B) (§3.5), checked on the crop where no border is involved."""
    image = _gray((20, 23))
    a, b = _rng(1).standard_normal((3, 4)), _rng(2).standard_normal((2, 5))
    left = filters.convolve(filters.convolve(image, a, output="valid"), b, output="valid")
    right = filters.convolve(image, signal.convolve2d(a, b, mode="full"), output="valid")
    np.testing.assert_allclose(left, right, rtol=0, atol=ATOL)


@pytest.mark.parametrize("fn", [filters.correlate, filters.convolve])
@pytest.mark.parametrize("border", BORDERS)
def test_linearity(fn, border):
    i1, i2 = _gray(seed=3), _gray(seed=4)
    kernel = _rng(6).standard_normal((3, 4))
    alpha, beta = 2.5, -0.75
    lhs = fn(alpha * i1 + beta * i2, kernel, border)
    rhs = alpha * fn(i1, kernel, border) + beta * fn(i2, kernel, border)
    np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-12)


def test_color_channels_are_filtered_independently():
    image, kernel = _color(), _rng(9).standard_normal((3, 5))
    got = filters.convolve(image, kernel, "reflect")
    for c in range(3):
        np.testing.assert_allclose(got[..., c], filters.convolve(image[..., c], kernel, "reflect"), atol=ATOL)


def test_zero_kernel_gives_zeros():
    np.testing.assert_array_equal(filters.correlate(_color(), np.zeros((3, 3))), np.zeros((9, 13, 3)))


@pytest.mark.parametrize(
    "call",
    [
        lambda im: filters.correlate(im, np.ones((3, 3)) / 9),
        lambda im: filters.convolve(im, np.ones((2, 3)) / 6, output="valid"),
        lambda im: filters.mean(im, 3),
        lambda im: filters.gaussian(im, 1.0),
    ],
    ids=["correlate", "convolve", "mean", "gaussian"],
)
@pytest.mark.parametrize("color", [False, True])
def test_uint8_input_unchanged_and_not_rescaled(call, color):
    shape = (8, 10, 3) if color else (8, 10)
    image = np.full(shape, 200, dtype=np.uint8)
    before = image.copy()
    out = call(image)
    np.testing.assert_array_equal(image, before)
    assert out.dtype == np.float64
    np.testing.assert_allclose(out, 200.0, rtol=0, atol=1e-9)


def test_inputs_are_not_modified():
    image, kernel = _gray(), _rng(1).standard_normal((4, 3))
    image_copy, kernel_copy = image.copy(), kernel.copy()
    for fn in (filters.correlate, filters.convolve):
        for output in ("same", "valid"):
            out = fn(image, kernel, output=output)
            assert not np.shares_memory(out, image)
    filters.gaussian(image, 1.5)
    filters.mean(image, 5)
    frames = _rng(2).random((4, 5, 6))
    frames_copy = frames.copy()
    assert not np.shares_memory(filters.temporal_mean(frames), frames)
    np.testing.assert_array_equal(image, image_copy)
    np.testing.assert_array_equal(kernel, kernel_copy)
    np.testing.assert_array_equal(frames, frames_copy)


def test_list_and_bool_inputs_are_accepted():
    out = filters.correlate([[0, 1, 0], [1, 1, 1]], [[1]])
    np.testing.assert_array_equal(out, [[0.0, 1.0, 0.0], [1.0, 1.0, 1.0]])
    out = filters.correlate(np.eye(3, dtype=bool), np.ones((1, 1)))
    np.testing.assert_array_equal(out, np.eye(3))


# --------------------------------------------------------------------------------------------
# mean
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("size", [1, 2, 3, 4, 7])
def test_mean_kernel(size):
    k = filters.mean_kernel(size)
    assert k.shape == (size, size) and k.dtype == np.float64
    assert math.isclose(k.sum(), 1.0, abs_tol=1e-12)
    np.testing.assert_array_equal(k, np.full((size, size), 1.0 / size**2))
    np.testing.assert_array_equal(k, k[::-1, ::-1])


@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("size", [1, 3, 5, 9, 15])
@pytest.mark.parametrize("image", [_gray(), _color()], ids=["gray", "color"])
def test_mean_matches_cv2_blur_and_uniform_filter(image, size, border):
    got = filters.mean(image, size, border=border)
    want_cv = cv2.blur(image, (size, size), borderType=CV2_BORDER[border])
    np.testing.assert_allclose(got, want_cv.reshape(image.shape), rtol=0, atol=ATOL)
    sizes = (size, size) + (1,) * (image.ndim - 2)
    want_sp = ndi.uniform_filter(image, size=sizes, mode=SCIPY_MODE[border], cval=0.0)
    np.testing.assert_allclose(got, want_sp, rtol=0, atol=ATOL)


def test_mean_of_constant_image_is_constant():
    np.testing.assert_allclose(filters.mean(np.full((6, 7), 3.25), 5, "reflect"), 3.25, atol=1e-12)


# --------------------------------------------------------------------------------------------
# Gaussian
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "sigma, radius", [(1.0, 3), (0.5, 2), (2.0, 6), (0.1, 1), (1.5, 5), (7 / 3, 7), (10 / 3, 10), (1e-6, 1)]
)
def test_gaussian_kernel_default_radius(sigma, radius):
    g = filters.gaussian_kernel(sigma)
    assert g.shape == (2 * radius + 1,)
    assert radius == math.ceil(3 * sigma - 1e-9)


@pytest.mark.parametrize("sigma", [0.3, 0.5, 0.8, 1.0, 1.7, 2.0, 3.5])
@pytest.mark.parametrize("radius", [None, 0, 1, 4, 9])
def test_gaussian_kernel_matches_cv2(sigma, radius):
    g = filters.gaussian_kernel(sigma, radius)
    r = math.ceil(3 * sigma - 1e-9) if radius is None else radius
    assert g.shape == (2 * r + 1,) and g.dtype == np.float64
    assert math.isclose(g.sum(), 1.0, abs_tol=1e-12)
    np.testing.assert_array_equal(g, g[::-1])
    assert np.all(np.diff(g[: r + 1]) > 0) or r == 0  # increasing up to the centre
    want = cv2.getGaussianKernel(2 * r + 1, sigma, ktype=cv2.CV_64F).ravel()
    np.testing.assert_allclose(g, want, rtol=0, atol=1e-12)
    x = np.arange(-r, r + 1)
    np.testing.assert_allclose(g / g[r], np.exp(-(x**2) / (2 * sigma**2)), rtol=1e-12)


def test_gaussian_kernel_radius_zero_is_identity():
    np.testing.assert_array_equal(filters.gaussian_kernel(2.0, radius=0), [1.0])


@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("sigma", [0.5, 1.0, 1.6, 2.0, 4.0])
@pytest.mark.parametrize("image", [_gray((13, 21)), _color((10, 15))], ids=["gray", "color"])
def test_gaussian_matches_scipy_and_cv2(image, sigma, border):
    r = math.ceil(3 * sigma - 1e-9)
    got = filters.gaussian(image, sigma, border=border)
    assert got.shape == image.shape and got.dtype == np.float64
    sigmas = (sigma, sigma) + (0.0,) * (image.ndim - 2)
    want = ndi.gaussian_filter(image, sigmas, mode=SCIPY_MODE[border], cval=0.0, truncate=r / sigma)
    np.testing.assert_allclose(got, want, rtol=0, atol=ATOL)
    want = cv2.GaussianBlur(image, (2 * r + 1, 2 * r + 1), sigmaX=sigma, sigmaY=sigma, borderType=CV2_BORDER[border])
    np.testing.assert_allclose(got, want.reshape(image.shape), rtol=0, atol=1e-8)


def test_gaussian_equals_2d_correlation_with_outer_product():
    image = _color((16, 11))
    g = filters.gaussian_kernel(1.3)
    np.testing.assert_allclose(
        filters.gaussian(image, 1.3, "replicate"),
        filters.correlate(image, np.outer(g, g), "replicate"),
        rtol=0,
        atol=ATOL,
    )


def test_gaussian_on_a_tiny_image_with_a_large_radius():
    image = _gray((3, 2))
    for border in BORDERS:
        want = ndi.gaussian_filter(image, 2.0, mode=SCIPY_MODE[border], truncate=3.0)
        np.testing.assert_allclose(filters.gaussian(image, 2.0, border), want, rtol=0, atol=ATOL)


def test_gaussian_on_a_large_image_matches_scipy():
    """Several row blocks (the implementation works in cache-sized blocks)."""
    image = _rng(12).random((300, 130))
    r = math.ceil(3 * 1.5 - 1e-9)
    want = ndi.gaussian_filter(image, 1.5, mode="mirror", truncate=r / 1.5)
    np.testing.assert_allclose(filters.gaussian(image, 1.5), want, rtol=0, atol=ATOL)


@pytest.mark.parametrize("sigma", [0.4, 1.0, 3.0, 6.0])
@pytest.mark.parametrize("image", [_gray((53, 20)), _color((37, 9))], ids=["gray", "color"])
def test_gaussian_row_blocks_smaller_than_the_kernel(monkeypatch, image, sigma):
    """Force 8-row blocks, fewer rows than the 2r halo carried from block to block."""
    from cvkit.filters import _linear

    monkeypatch.setattr(_linear, "_BLOCK_ELEMENTS", 1)
    r = math.ceil(3 * sigma - 1e-9)
    sigmas = (sigma, sigma) + (0.0,) * (image.ndim - 2)
    for border in BORDERS:
        want = ndi.gaussian_filter(image, sigmas, mode=SCIPY_MODE[border], truncate=r / sigma)
        np.testing.assert_allclose(filters.gaussian(image, sigma, border), want, rtol=0, atol=ATOL)
    kernel = _rng(1).standard_normal((3, 4))  # the tap loop's blocks too
    np.testing.assert_allclose(
        filters.correlate(image, kernel), _per_channel(lambda ch: ndi.correlate(ch, kernel, mode="mirror"), image),
        rtol=0, atol=ATOL,
    )


# --------------------------------------------------------------------------------------------
# temporal mean
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(1, 4, 5), (6, 4, 5), (3, 4, 5, 3)])
def test_temporal_mean(shape):
    frames = _rng(3).normal(100, 10, shape)
    got = filters.temporal_mean(frames)
    assert got.shape == shape[1:] and got.dtype == np.float64
    np.testing.assert_allclose(got, frames.sum(axis=0) / shape[0], rtol=1e-14)


def test_temporal_mean_reduces_noise_variance():
    rng = _rng(4)
    truth = rng.random((32, 32))
    frames = truth + rng.normal(0, 0.2, (25, 32, 32))
    residual = filters.temporal_mean(frames) - truth
    assert abs(residual.std() - 0.2 / 5) < 0.2 / 5 * 0.1


def test_temporal_mean_of_uint8_frames_is_not_rescaled():
    frames = np.stack([np.full((3, 3), 100, np.uint8), np.full((3, 3), 201, np.uint8)])
    np.testing.assert_array_equal(filters.temporal_mean(frames), np.full((3, 3), 150.5))


# --------------------------------------------------------------------------------------------
# registry: student building blocks
# --------------------------------------------------------------------------------------------
@pytest.fixture
def student_provider():
    prov = registry.provider("student")
    prov.clear()
    yield prov
    prov.clear()


def test_algorithms_are_registered():
    expected = {
        "filters.temporal_mean": "3.1",
        "filters.correlate": "3.6",
        "filters.convolve": "3.7",
        "filters.mean_kernel": "3.8",
        "filters.mean": "3.8",
        "filters.gaussian_kernel": "3.9",
        "filters.gaussian": "3.9.1",
    }
    for algorithm_id, section in expected.items():
        record = registry.get(algorithm_id)
        assert record.section == section
        assert record.reference is getattr(filters, algorithm_id.split(".")[1])
        assert record._check == f"cvkit.filters.checks:{algorithm_id.split('.')[1]}" or not isinstance(
            record._check, str
        )


def test_student_gaussian_kernel_changes_gaussian(student_provider):
    image = _gray((12, 14))
    reference = filters.gaussian(image, 1.0)

    @registry.student("filters.gaussian_kernel")
    def box_kernel(sigma, radius=None):
        return np.full(3, 1.0 / 3.0)

    with cvkit.use("student"):
        with_student = filters.gaussian(image, 1.0)
    np.testing.assert_allclose(with_student, filters.mean(image, 3), rtol=0, atol=ATOL)
    assert not np.allclose(with_student, reference)
    np.testing.assert_array_equal(filters.gaussian(image, 1.0), reference)  # back to the reference


def test_student_asymmetric_kernel_is_applied_as_a_correlation(student_provider):
    image = _color((9, 10))
    kernel = np.array([0.1, 0.2, 0.3, 0.4, 0.0])
    registry.student("filters.gaussian_kernel")(lambda sigma, radius=None: list(kernel))
    with cvkit.use("student"):
        got = filters.gaussian(image, 1.0, "reflect")
    np.testing.assert_allclose(got, filters.correlate(image, np.outer(kernel, kernel), "reflect"), atol=ATOL)


def test_student_even_length_kernel_is_reported(student_provider):
    registry.student("filters.gaussian_kernel")(lambda sigma, radius=None: np.ones(4) / 4)
    with cvkit.use("student"), pytest.raises(ValueError, match="gaussian_kernel"):
        filters.gaussian(_gray(), 1.0)


def test_student_building_blocks_of_mean(student_provider):
    calls = []

    @registry.student("filters.mean_kernel")
    def my_kernel(size):
        calls.append(("kernel", size))
        return np.ones((size, size)) / size**2

    @registry.student("filters.correlate")
    def my_correlate(image, kernel, border="reflect101", output="same"):
        calls.append(("correlate", kernel.shape, border))
        return np.zeros(np.shape(image))

    with cvkit.use("student"):
        out = filters.mean(_gray(), 5, border="replicate")
    assert calls == [("kernel", 5), ("correlate", (5, 5), "replicate")]
    np.testing.assert_array_equal(out, 0.0)


# --------------------------------------------------------------------------------------------
# bad input (hypothesis)
# --------------------------------------------------------------------------------------------
good_image = np.zeros((6, 7))


bad_ndim_shapes = st.one_of(
    st.lists(st.integers(1, 3), min_size=0, max_size=1),
    st.lists(st.integers(1, 3), min_size=4, max_size=5),
    st.tuples(st.integers(1, 3), st.integers(1, 3), st.integers(1, 5).filter(lambda c: c != 3)),
).map(tuple)
IMAGE_CALLS = [
    lambda im: filters.correlate(im, np.ones((3, 3))),
    lambda im: filters.convolve(im, np.ones((2, 2))),
    lambda im: filters.mean(im, 3),
    lambda im: filters.gaussian(im, 1.0),
]


@FAST
@given(shape=bad_ndim_shapes, which=st.integers(0, len(IMAGE_CALLS) - 1))
def test_wrong_image_shape(shape, which):
    raises_naming(ValueError, "image", IMAGE_CALLS[which], np.zeros(shape))


@FAST
@given(
    bad=st.sampled_from([np.nan, np.inf, -np.inf]),
    pos=st.tuples(st.integers(0, 5), st.integers(0, 6)),
    which=st.integers(0, len(IMAGE_CALLS) - 1),
)
def test_non_finite_image(bad, pos, which):
    image = np.zeros((6, 7))
    image[pos] = bad
    raises_naming(ValueError, "image", IMAGE_CALLS[which], image)


@FAST
@given(
    value=st.one_of(
        st.text(max_size=5),
        st.just(None),
        st.just(np.zeros((4, 4), dtype=complex)),
        st.just(np.array([["a", "b"], ["c", "d"]])),
        st.just(np.array([[object()]], dtype=object)),
    ),
    which=st.integers(0, len(IMAGE_CALLS) - 1),
)
def test_non_numeric_or_complex_image(value, which):
    raises_naming(TypeError, "image", IMAGE_CALLS[which], value)


@FAST
@given(
    kernel=st.one_of(
        st.lists(st.floats(-1, 1), min_size=1, max_size=4).map(np.array),  # 1-D
        st.just(np.ones((2, 2, 2))),
        st.just(np.zeros((0, 3))),
        st.just(np.array([[1.0, np.nan]])),
        st.just(np.array([[np.inf]])),
    ),
    fn=st.sampled_from([filters.correlate, filters.convolve]),
)
def test_bad_kernel_value(kernel, fn):
    raises_naming(ValueError, "kernel", fn, good_image, kernel)


@FAST
@given(fn=st.sampled_from([filters.correlate, filters.convolve]))
def test_complex_kernel(fn):
    raises_naming(TypeError, "kernel", fn, good_image, np.ones((3, 3), dtype=complex))


@FAST
@given(
    border=st.one_of(st.text(max_size=12).filter(lambda s: s not in BORDERS), st.integers(), st.none()),
    which=st.integers(0, 3),
)
def test_bad_border(border, which):
    calls = [
        lambda: filters.correlate(good_image, np.ones((3, 3)), border=border),
        lambda: filters.convolve(good_image, np.ones((3, 3)), border=border),
        lambda: filters.mean(good_image, 3, border=border),
        lambda: filters.gaussian(good_image, 1.0, border=border),
    ]
    raises_naming(ValueError, "border", calls[which])


@FAST
@given(output=st.one_of(st.text(max_size=8).filter(lambda s: s not in ("same", "valid")), st.integers(), st.none()))
def test_bad_output(output):
    raises_naming(ValueError, "output", filters.correlate, good_image, np.ones((3, 3)), output=output)
    raises_naming(ValueError, "output", filters.convolve, good_image, np.ones((3, 3)), output=output)


@FAST
@given(sigma=st.one_of(st.floats(max_value=0.0, allow_nan=False), st.just(np.nan), st.just(np.inf)))
def test_bad_sigma_value(sigma):
    raises_naming(ValueError, "sigma", filters.gaussian_kernel, sigma)
    raises_naming(ValueError, "sigma", filters.gaussian, good_image, sigma)


@FAST
@given(sigma=st.one_of(st.text(max_size=3), st.none(), st.just([1.0]), st.just(1 + 2j), st.booleans()))
def test_bad_sigma_type(sigma):
    raises_naming(TypeError, "sigma", filters.gaussian_kernel, sigma)
    raises_naming(TypeError, "sigma", filters.gaussian, good_image, sigma)


@FAST
@given(size=st.integers(-5, 20).filter(lambda s: s < 1 or s % 2 == 0))
def test_bad_mean_size_value(size):
    raises_naming(ValueError, "size", filters.mean, good_image, size)


@FAST
@given(size=st.integers(-5, 0))
def test_bad_mean_kernel_size_value(size):
    raises_naming(ValueError, "size", filters.mean_kernel, size)


@FAST
@given(size=st.one_of(st.floats(allow_nan=True), st.text(max_size=3), st.none(), st.booleans(), st.just(np.float64(3))))
def test_non_integer_size(size):
    raises_naming(TypeError, "size", filters.mean, good_image, size)
    raises_naming(TypeError, "size", filters.mean_kernel, size)


@FAST
@given(radius=st.one_of(st.integers(max_value=-1), st.floats(0, 5), st.just("3")))
def test_bad_radius(radius):
    exc = ValueError if isinstance(radius, int) else TypeError
    raises_naming(exc, "radius", filters.gaussian_kernel, 1.0, radius)


@FAST
@given(
    frames=st.one_of(
        st.lists(st.integers(1, 3), min_size=0, max_size=2).map(lambda s: np.zeros(tuple(s))),
        st.integers(1, 5).filter(lambda c: c != 3).map(lambda c: np.zeros((2, 3, 3, c))),
        st.just(np.zeros((0, 3, 3))),
        st.just(np.full((2, 2, 2), np.nan)),
    )
)
def test_bad_frames(frames):
    raises_naming(ValueError, "frames", filters.temporal_mean, frames)
