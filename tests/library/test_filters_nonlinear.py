"""Non-linear filters of Chapter 3 (cvkit.filters._nonlinear): median, bilateral, nl_means.

Oracles and parameter mappings
------------------------------
- median: ``scipy.ndimage.median_filter(size=s, mode=m)`` with m = constant / nearest /
  reflect / mirror for border = zero / replicate / reflect / reflect101, colour with
  ``size=(s, s, 1)``: exactly equal. ``cv2.medianBlur`` replicates the border and accepts
  uint8 (any odd size) and float32 (sizes 3, 5): exactly equal with ``border="replicate"``.
- bilateral, nl_means: brute-force double loops over the pixels (below), padding with
  ``numpy.pad`` (constant / edge / symmetric / reflect), to 1e-12.
- bilateral vs ``skimage.restoration.denoise_bilateral(mode="reflect")`` (= reflect101):
  only approximate. scikit-image bins the range weight (distance rounded down to one of
  ``bins`` levels), divides the colour distance by the number of channels (so its
  ``sigma_color=σ`` is our ``sigma_range=3σ`` for RGB) and reads its spatial table with the
  wrong stride (its spatial weights are shuffled). The comparison therefore makes every
  spatial weight 1 (σ_s = 1e4, explicit radius) and uses ``bins=3_000_000``, leaving only the
  binning: agreement within 1e-5 on [0, 1] images.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.ndimage as ndi
from hypothesis import given
from hypothesis import strategies as st
from input_helpers import FAST

from cvkit import registry
from cvkit.filters import bilateral, median, nl_means

BORDERS = ("zero", "replicate", "reflect", "reflect101")
SCIPY_MODE = {"zero": "constant", "replicate": "nearest", "reflect": "reflect", "reflect101": "mirror"}
NUMPY_MODE = {"zero": "constant", "replicate": "edge", "reflect": "symmetric", "reflect101": "reflect"}
ATOL = 1e-12


def _gray(shape=(9, 11), seed=1):
    return np.random.default_rng(seed).random(shape)


def _color(shape=(9, 11), seed=2):
    return np.random.default_rng(seed).random(shape + (3,))


def _np_pad(image, r, border):
    """An independent padding oracle (numpy.pad, not cvkit.filters.pad)."""
    widths = ((r, r), (r, r)) + ((0, 0),) * (image.ndim - 2)
    return np.pad(image.astype(float), widths, mode=NUMPY_MODE[border])


def _bilateral_brute(image, sigma_space, sigma_range, r, border):
    padded = _np_pad(image, r, border)
    out = np.zeros(image.shape)
    for i in range(image.shape[0]):
        for j in range(image.shape[1]):
            centre = padded[i + r, j + r]
            num, den = 0.0, 0.0
            for dy in range(-r, r + 1):
                for dx in range(-r, r + 1):
                    q = padded[i + r + dy, j + r + dx]
                    w = math.exp(-(dy * dy + dx * dx) / (2 * sigma_space**2)) * math.exp(
                        -float(np.sum((q - centre) ** 2)) / (2 * sigma_range**2)
                    )
                    num = num + w * q
                    den += w
            out[i, j] = num / den
    return out


def _nl_means_brute(image, h, patch, search, border):
    pr, sr = patch // 2, search // 2
    big = pr + sr
    padded = _np_pad(image, big, border)
    out = np.zeros(image.shape)
    for i in range(image.shape[0]):
        for j in range(image.shape[1]):
            y, x = i + big, j + big
            n_p = padded[y - pr : y + pr + 1, x - pr : x + pr + 1]
            num, den = 0.0, 0.0
            for dy in range(-sr, sr + 1):
                for dx in range(-sr, sr + 1):
                    n_q = padded[y + dy - pr : y + dy + pr + 1, x + dx - pr : x + dx + pr + 1]
                    w = math.exp(-float(np.mean((n_p - n_q) ** 2)) / h**2)
                    num = num + w * padded[y + dy, x + dx]
                    den += w
            out[i, j] = num / den
    return out


# --------------------------------------------------------------------------------------------
# registration
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "algorithm_id, function, section",
    [("filters.median", median, "3.11"), ("filters.bilateral", bilateral, "3.12"), ("filters.nl_means", nl_means, "3.13")],
)
def test_registered(algorithm_id, function, section):
    record = registry.get(algorithm_id)
    assert record.reference is function
    assert record.section == section
    assert registry.implementation(algorithm_id) is function


# --------------------------------------------------------------------------------------------
# median
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("size", [1, 3, 5, 7])
def test_median_matches_scipy_gray(border, size):
    rng = np.random.default_rng(size)
    img = rng.integers(0, 5, (12, 15)).astype(float)  # many ties
    img[3, 4], img[7, 9], img[0, 0] = 1e300, -1e300, 5e-324  # extreme values
    expected = ndi.median_filter(img, size=size, mode=SCIPY_MODE[border])
    np.testing.assert_array_equal(median(img, size, border=border), expected)


@pytest.mark.parametrize("border", BORDERS)
def test_median_matches_scipy_color_and_small_images(border):
    img = _color((8, 10))
    expected = ndi.median_filter(img, size=(5, 5, 1), mode=SCIPY_MODE[border])
    np.testing.assert_array_equal(median(img, 5, border=border), expected)
    tiny = _gray((2, 3))  # the window is larger than the image
    np.testing.assert_array_equal(median(tiny, 7, border=border), ndi.median_filter(tiny, size=7, mode=SCIPY_MODE[border]))


def test_median_band_boundaries(monkeypatch):
    """Results do not depend on how the rows are split into bands."""
    from cvkit.filters import _nonlinear

    img = _gray((23, 17), seed=5)
    expected = ndi.median_filter(img, size=5, mode="mirror")
    monkeypatch.setattr(_nonlinear, "_MEDIAN_CHUNK", 17 * 25 * 3)  # three rows per band
    np.testing.assert_array_equal(median(img, 5), expected)


def test_median_matches_opencv():
    cv2 = pytest.importorskip("cv2")
    rng = np.random.default_rng(3)
    u8 = rng.integers(0, 256, (20, 24), dtype=np.uint8)
    for size in (3, 5, 7, 9):
        np.testing.assert_array_equal(median(u8, size, border="replicate"), cv2.medianBlur(u8, size))
    u8c = rng.integers(0, 256, (20, 24, 3), dtype=np.uint8)
    np.testing.assert_array_equal(median(u8c, 5, border="replicate"), cv2.medianBlur(u8c, 5))
    f32 = rng.random((20, 24)).astype(np.float32)
    for size in (3, 5):  # OpenCV supports only these sizes for float32
        np.testing.assert_array_equal(median(f32, size, border="replicate"), cv2.medianBlur(f32, size))


def test_median_removes_isolated_impulse_and_keeps_edges():
    img = np.zeros((9, 9))
    img[:, 5:] = 1.0  # a vertical edge
    noisy = img.copy()
    noisy[2, 2], noisy[6, 7] = 1.0, 0.0  # salt on the dark side, pepper on the bright side
    np.testing.assert_array_equal(median(noisy, 3), img)


def test_median_output_values_come_from_the_input():
    img = np.random.default_rng(4).random((10, 12, 3))
    out = median(img, 5, border="reflect")
    for c in range(3):
        assert np.isin(out[..., c], img[..., c]).all()


# --------------------------------------------------------------------------------------------
# bilateral
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("make", [_gray, _color], ids=["gray", "color"])
def test_bilateral_matches_brute_force(border, make):
    img = make()
    np.testing.assert_allclose(bilateral(img, 1.3, 0.3, radius=2, border=border), _bilateral_brute(img, 1.3, 0.3, 2, border), rtol=0, atol=ATOL)
    # default radius ceil(3 * 0.6) = 2; a window (r = 4) nearly as large as the image
    np.testing.assert_allclose(bilateral(img, 0.6, 0.2, border=border), _bilateral_brute(img, 0.6, 0.2, 2, border), rtol=0, atol=ATOL)
    np.testing.assert_allclose(bilateral(img, 2.0, 0.5, radius=4, border=border), _bilateral_brute(img, 2.0, 0.5, 4, border), rtol=0, atol=ATOL)


@pytest.mark.parametrize("shape", [(1, 1), (1, 6), (5, 1), (2, 2, 3)])
def test_bilateral_degenerate_shapes(shape):
    img = np.random.default_rng(7).random(shape)
    for border in BORDERS:
        np.testing.assert_allclose(bilateral(img, 1.0, 0.4, radius=2, border=border), _bilateral_brute(img, 1.0, 0.4, 2, border), rtol=0, atol=ATOL)


def test_bilateral_default_radius():
    img = _gray((12, 12))
    np.testing.assert_array_equal(bilateral(img, 1.0, 0.2), bilateral(img, 1.0, 0.2, radius=3))
    np.testing.assert_array_equal(bilateral(img, 0.7, 0.2), bilateral(img, 0.7, 0.2, radius=3))  # ceil(2.1)
    np.testing.assert_array_equal(bilateral(img, 7 / 3, 0.2), bilateral(img, 7 / 3, 0.2, radius=7))  # 3·(7/3) rounds up
    np.testing.assert_array_equal(bilateral(img, 1.0, 0.2, radius=0), img)


@pytest.mark.parametrize("border", BORDERS)
def test_bilateral_huge_sigma_range_is_gaussian_mean(border):
    img = _color((10, 12))
    r, sigma = 2, 1.2
    y, x = np.mgrid[-r : r + 1, -r : r + 1]
    kernel = np.exp(-(x * x + y * y) / (2 * sigma**2))
    kernel /= kernel.sum()
    expected = np.stack(
        [ndi.correlate(img[..., c], kernel, mode=SCIPY_MODE[border]) for c in range(3)], axis=-1
    )
    np.testing.assert_allclose(bilateral(img, sigma, 1e9, radius=r, border=border), expected, rtol=0, atol=1e-12)


def test_bilateral_close_to_skimage():
    restoration = pytest.importorskip("skimage.restoration")
    gray = _gray((20, 24), seed=8)
    ours = bilateral(gray, 1e4, 0.2, radius=3)
    theirs = restoration.denoise_bilateral(gray, win_size=7, sigma_color=0.2, sigma_spatial=1e4, bins=3_000_000, mode="reflect")
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-5)
    color = _color((16, 18), seed=9)
    ours = bilateral(color, 1e4, 3 * 0.2, radius=3)  # skimage divides the RGB distance by 3
    theirs = restoration.denoise_bilateral(
        color, win_size=7, sigma_color=0.2, sigma_spatial=1e4, bins=3_000_000, mode="reflect", channel_axis=-1
    )
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-5)


def test_bilateral_preserves_an_edge_and_denoises():
    rng = np.random.default_rng(10)
    clean = np.zeros((16, 16))
    clean[:, 8:] = 1.0
    noisy = clean + rng.normal(0, 0.03, clean.shape)
    out = bilateral(noisy, 1.5, 0.15)
    assert np.abs(out - clean).max() < 0.1  # no blur across the step
    assert np.mean((out - clean) ** 2) < 0.5 * np.mean((noisy - clean) ** 2)


# --------------------------------------------------------------------------------------------
# non-local means
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("make", [_gray, _color], ids=["gray", "color"])
def test_nl_means_matches_brute_force(border, make):
    img = make((7, 9))
    np.testing.assert_allclose(nl_means(img, 0.3, 3, 5, border=border), _nl_means_brute(img, 0.3, 3, 5, border), rtol=0, atol=ATOL)
    np.testing.assert_allclose(nl_means(img, 0.5, 5, 3, border=border), _nl_means_brute(img, 0.5, 5, 3, border), rtol=0, atol=ATOL)
    np.testing.assert_allclose(nl_means(img, 0.2, 1, 7, border=border), _nl_means_brute(img, 0.2, 1, 7, border), rtol=0, atol=ATOL)


@pytest.mark.parametrize("shape", [(1, 1), (3, 4), (2, 5, 3)])
def test_nl_means_windows_larger_than_image(shape):
    img = np.random.default_rng(11).random(shape)
    for border in BORDERS:
        np.testing.assert_allclose(nl_means(img, 0.4, 5, 7, border=border), _nl_means_brute(img, 0.4, 5, 7, border), rtol=0, atol=ATOL)


def test_nl_means_default_sizes_match_brute_force():
    img = _gray((6, 7), seed=12)  # patch 7, search 21 (padding by 13 > image)
    np.testing.assert_allclose(nl_means(img, 0.3), _nl_means_brute(img, 0.3, 7, 21, "reflect101"), rtol=0, atol=ATOL)


def test_nl_means_search_size_one_is_identity():
    img = _color((8, 9))
    np.testing.assert_array_equal(nl_means(img, 0.1, patch_size=5, search_size=1), img)
    gray = np.random.default_rng(13).normal(100, 50, (8, 9))
    np.testing.assert_array_equal(nl_means(gray, 10.0, search_size=1), gray)


def test_nl_means_denoises_repeated_structure():
    rng = np.random.default_rng(14)
    clean = np.tile(np.repeat([0.2, 0.8], 4), (24, 3))  # stripes: many similar patches
    noisy = clean + rng.normal(0, 0.05, clean.shape)
    out = nl_means(noisy, 0.06, patch_size=5, search_size=11)
    assert np.mean((out - clean) ** 2) < 0.25 * np.mean((noisy - clean) ** 2)


# --------------------------------------------------------------------------------------------
# properties shared by the three filters
# --------------------------------------------------------------------------------------------
FILTERS = {
    "median": lambda img, border="reflect101": median(img, 3, border=border),
    "bilateral": lambda img, border="reflect101": bilateral(img, 1.0, 20.0, border=border),
    "nl_means": lambda img, border="reflect101": nl_means(img, 20.0, 3, 5, border=border),
}


@pytest.mark.parametrize("name", FILTERS)
@pytest.mark.parametrize("border", ["replicate", "reflect", "reflect101"])
def test_constant_image_unchanged(name, border):
    for img in (np.full((6, 7), 0.3), np.full((5, 6, 3), 173.0), np.full((4, 4), -2.5e10)):
        out = FILTERS[name](img, border=border)
        np.testing.assert_array_equal(out, img)


@pytest.mark.parametrize("name", FILTERS)
@pytest.mark.parametrize("border", BORDERS)
def test_output_within_input_range(name, border):
    img = np.random.default_rng(15).normal(100, 60, (10, 11, 3))
    out = FILTERS[name](img, border=border)
    lo, hi = img.min(), img.max()
    if border == "zero":  # the zeros outside the image take part
        lo, hi = min(lo, 0.0), max(hi, 0.0)
    assert out.min() >= lo and out.max() <= hi
    assert out.shape == img.shape and out.dtype == np.float64


@pytest.mark.parametrize("name", FILTERS)
def test_extreme_values(name):
    """Values near the float64 limits: differences would overflow, results must not."""
    img = np.zeros((7, 8))
    img[::2, ::3] = 1.7e308
    img[1::2, 1::3] = -1.7e308
    img[3, 4] = 5e-324
    out = FILTERS[name](img)
    assert np.isfinite(out).all() and out.min() >= img.min() and out.max() <= img.max()


@pytest.mark.parametrize("k", [2.0**600, 2.0**-600])
def test_weights_are_scale_invariant(k):
    """Scaling image and σ_r / h by a power of two (exact) scales the result exactly: no
    overflow of d² or σ² for huge values, no underflow for tiny ones."""
    img = _color((6, 7), seed=18)
    np.testing.assert_array_equal(bilateral(img * k, 1.0, 0.3 * k), k * bilateral(img, 1.0, 0.3))
    np.testing.assert_array_equal(nl_means(img * k, 0.3 * k, 3, 5), k * nl_means(img, 0.3, 3, 5))


def test_huge_and_tiny_sigma_space():
    img = _gray((8, 9), seed=19)
    flat = bilateral(img, 1e100, 0.2, radius=2)  # all spatial weights exactly 1
    np.testing.assert_array_equal(bilateral(img, 1e300, 0.2, radius=2), flat)
    np.testing.assert_array_equal(bilateral(img, 1e-300, 0.2, radius=2), img)  # only the centre counts


def test_extreme_values_give_the_scaled_result():
    """Scaling by a power of two is exact, so huge images give exactly the scaled result."""
    img = np.random.default_rng(17).uniform(-1.0, 1.0, (6, 7, 3)) * 1.7e308
    k = 2.0**600
    np.testing.assert_array_equal(bilateral(img, 1.0, 1e308), k * bilateral(img / k, 1.0, 1e308 / k))
    np.testing.assert_array_equal(nl_means(img, 1e308, 3, 5), k * nl_means(img / k, 1e308 / k, 3, 5))


@pytest.mark.parametrize("name", FILTERS)
def test_inputs_not_modified_and_uint8_not_rescaled(name):
    rng = np.random.default_rng(16)
    for shape in ((9, 10), (9, 10, 3)):
        u8 = rng.integers(0, 256, shape, dtype=np.uint8)
        keep = u8.copy()
        u8.flags.writeable = False
        out = FILTERS[name](u8)
        np.testing.assert_array_equal(u8, keep)
        as_float = keep.astype(np.float64)
        np.testing.assert_array_equal(out, FILTERS[name](as_float))
        np.testing.assert_array_equal(as_float, keep)  # float input untouched too
        assert out.dtype == np.float64 and out.max() > 1.0  # still in 0..255 units


@pytest.mark.parametrize("name", FILTERS)
def test_lists_and_other_dtypes(name):
    data = [[1, 2, 3, 4], [5, 6, 7, 8], [9, 10, 11, 12]]
    expected = FILTERS[name](np.array(data, dtype=np.float64))
    np.testing.assert_array_equal(FILTERS[name](data), expected)
    np.testing.assert_array_equal(FILTERS[name](np.array(data, dtype=np.int16)), expected)
    np.testing.assert_array_equal(FILTERS[name](np.array(data, dtype=np.float32)), expected)


# --------------------------------------------------------------------------------------------
# bad input (hypothesis): exception type and a message naming the argument
# --------------------------------------------------------------------------------------------
_GOOD = object()  # "use a valid image"


def _image(image):
    return _gray() if image is _GOOD else image


CALLS = {
    "median": lambda image=_GOOD, **kw: median(_image(image), **{"size": 3, **kw}),
    "bilateral": lambda image=_GOOD, **kw: bilateral(_image(image), **{"sigma_space": 1.0, "sigma_range": 0.1, **kw}),
    "nl_means": lambda image=_GOOD, **kw: nl_means(_image(image), **{"h": 0.1, "patch_size": 3, "search_size": 5, **kw}),
}

not_a_number = st.one_of(st.text(max_size=3), st.none(), st.booleans(), st.lists(st.integers(), max_size=2), st.just(1j))
not_an_int = st.one_of(not_a_number, st.floats(allow_nan=False, allow_infinity=False))


def _raises(exc_type, argument, call):
    with pytest.raises(exc_type) as info:
        call()
    assert argument in str(info.value), f"message {str(info.value)!r} does not name {argument!r}"


@FAST
@given(name=st.sampled_from(list(CALLS)), border=st.text(max_size=12).filter(lambda b: b not in BORDERS))
def test_bad_border(name, border):
    _raises(ValueError, "border", lambda: CALLS[name](border=border))


@FAST
@given(
    name=st.sampled_from(list(CALLS)),
    bad=st.one_of(
        st.integers(1, 4).map(lambda n: np.zeros((4,) * n if n != 2 else (4, 4, 2))),  # 1-D, 4-D, (H, W, 2)
        st.sampled_from([np.nan, np.inf, -np.inf]).map(lambda v: np.where(np.eye(5) > 0, v, 0.0)),
        st.just(np.zeros((0, 5))),
    ),
)
def test_bad_image_value(name, bad):
    _raises(ValueError, "image", lambda: CALLS[name](image=bad))


@FAST
@given(name=st.sampled_from(list(CALLS)), bad=st.one_of(st.text(max_size=3), st.none(), st.just(np.array([["a", "b"]])), st.just(np.ones((3, 3), dtype=complex))))
def test_bad_image_type(name, bad):
    _raises(TypeError, "image", lambda: CALLS[name](image=bad))


@FAST
@given(
    case=st.one_of(
        st.tuples(st.sampled_from([("median", "size"), ("nl_means", "patch_size"), ("nl_means", "search_size")]), st.integers(-50, 50).filter(lambda n: n < 1 or n % 2 == 0)),
        st.tuples(st.just(("bilateral", "radius")), st.integers(-50, -1)),
    )
)
def test_bad_int_value(case):
    (name, argument), value = case
    _raises(ValueError, argument, lambda: CALLS[name](**{argument: value}))


@FAST
@given(
    target=st.sampled_from([("median", "size"), ("nl_means", "patch_size"), ("nl_means", "search_size"), ("bilateral", "radius")]),
    value=not_an_int.filter(lambda v: v is not None),
)
def test_bad_int_type(target, value):
    name, argument = target
    _raises(TypeError, argument, lambda: CALLS[name](**{argument: value}))


@FAST
@given(
    target=st.sampled_from([("bilateral", "sigma_space"), ("bilateral", "sigma_range"), ("nl_means", "h")]),
    value=st.one_of(st.floats(max_value=0.0), st.integers(-10, 0), st.sampled_from([np.nan, np.inf, -np.inf])),
)
def test_bad_real_value(target, value):
    name, argument = target
    _raises(ValueError, argument, lambda: CALLS[name](**{argument: value}))


@FAST
@given(target=st.sampled_from([("bilateral", "sigma_space"), ("bilateral", "sigma_range"), ("nl_means", "h")]), value=not_a_number)
def test_bad_real_type(target, value):
    name, argument = target
    _raises(TypeError, argument, lambda: CALLS[name](**{argument: value}))
