"""Noise models of Chapter 3 (cvkit.noise): statistics, reproducibility, contract, bad input.

Statistical bounds are 5 standard errors of the estimate (sample size n): the mean of n
N(0, σ²) draws has standard error σ/√n, the sample standard deviation ≈ σ/√(2n), and the
fraction of "salt" among k coin flips 0.5/√k. With fixed seeds the tests are deterministic;
the bounds say how far a correct implementation could be off with any seed.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from input_helpers import FAST, raises_naming

from cvkit import noise, registry

Z = 5.0  # standard errors allowed


# --------------------------------------------------------------------------------------------
# add_gaussian
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(200, 250), (120, 100, 3)])
@pytest.mark.parametrize("sigma", [0.05, 3.0, 20.0])
def test_gaussian_noise_statistics(shape, sigma):
    image = np.random.default_rng(99).random(shape) * 255
    noisy = noise.add_gaussian(image, sigma, rng=1)
    assert noisy.shape == image.shape and noisy.dtype == np.float64
    n = image.size
    residual = noisy - image
    assert abs(residual.mean()) < Z * sigma / math.sqrt(n)
    assert abs(residual.std() - sigma) < Z * sigma / math.sqrt(2 * n)
    # independent pixels: neighbouring residuals are uncorrelated
    a, b = residual[:, :-1].ravel(), residual[:, 1:].ravel()
    assert abs(np.corrcoef(a, b)[0, 1]) < Z / math.sqrt(a.size)
    # Gaussian shape: ~68.3 % within one sigma
    inside = np.mean(np.abs(residual) < sigma)
    p = math.erf(1 / math.sqrt(2))
    assert abs(inside - p) < Z * math.sqrt(p * (1 - p) / n)


def test_gaussian_noise_is_not_clipped():
    noisy = noise.add_gaussian(np.full((50, 50), 0.5), 1.0, rng=0)
    assert noisy.min() < 0.0 and noisy.max() > 1.0


def test_gaussian_noise_sigma_zero_is_an_exact_copy():
    image = np.random.default_rng(0).random((7, 9, 3))
    out = noise.add_gaussian(image, 0, rng=3)
    assert out.dtype == np.float64 and not np.shares_memory(out, image)
    np.testing.assert_array_equal(out, image)
    image8 = np.arange(12, dtype=np.uint8).reshape(3, 4)
    np.testing.assert_array_equal(noise.add_gaussian(image8, 0.0), image8.astype(float))


def test_gaussian_noise_reproducible():
    image = np.zeros((20, 30))
    a = noise.add_gaussian(image, 2.0, rng=42)
    np.testing.assert_array_equal(a, noise.add_gaussian(image, 2.0, rng=42))
    np.testing.assert_array_equal(a, noise.add_gaussian(image, 2.0, rng=np.random.default_rng(42)))
    assert not np.array_equal(a, noise.add_gaussian(image, 2.0, rng=43))
    gen = np.random.default_rng(5)
    first, second = noise.add_gaussian(image, 1.0, rng=gen), noise.add_gaussian(image, 1.0, rng=gen)
    assert not np.array_equal(first, second)  # a Generator advances
    assert not np.array_equal(noise.add_gaussian(image, 1.0), noise.add_gaussian(image, 1.0))  # rng=None


def test_gaussian_noise_keeps_input_and_units():
    image = np.full((40, 40), 200, dtype=np.uint8)
    before = image.copy()
    noisy = noise.add_gaussian(image, 1.0, rng=0)
    np.testing.assert_array_equal(image, before)
    assert noisy.dtype == np.float64
    assert abs(noisy.mean() - 200.0) < Z / 40  # not rescaled to [0, 1]


# --------------------------------------------------------------------------------------------
# add_salt_and_pepper
# --------------------------------------------------------------------------------------------
def _distinct_image(shape, seed=0):
    """Values strictly inside (0.2, 0.8): a replaced pixel always changes."""
    return 0.2 + 0.6 * np.random.default_rng(seed).random(shape) + 1e-3


@pytest.mark.parametrize("amount", [0.0, 0.001, 0.05, 0.37, 0.5, 0.999, 1.0])
@pytest.mark.parametrize("shape", [(40, 50), (1, 7), (13, 11)])
def test_salt_and_pepper_exact_count_and_values(shape, amount):
    image = _distinct_image(shape)
    out = noise.add_salt_and_pepper(image, amount, rng=1)
    assert out.shape == shape and out.dtype == np.float64
    changed = out != image
    assert changed.sum() == round(amount * image.size)
    assert set(np.unique(out[changed])) <= {0.0, 1.0}
    np.testing.assert_array_equal(out[~changed], image[~changed])


def test_salt_and_pepper_rounding_of_count():
    image = _distinct_image((2, 5))  # 10 pixels
    for amount, count in [(0.04, 0), (0.06, 1), (0.25, 2), (0.35, 4), (0.55, 6)]:
        out = noise.add_salt_and_pepper(image, amount, rng=0)
        assert (out != image).sum() == count == round(amount * 10)


def test_salt_and_pepper_half_salt_half_pepper_and_uniform_locations():
    image = _distinct_image((100, 120))
    out = noise.add_salt_and_pepper(image, 0.4, rng=2)
    changed = out != image
    k = changed.sum()
    salt = np.mean(out[changed] == 1.0)
    assert abs(salt - 0.5) < Z * 0.5 / math.sqrt(k)
    # every quadrant gets its share of the replaced pixels (hypergeometric ≈ binomial)
    for quadrant in (changed[:50, :60], changed[:50, 60:], changed[50:, :60], changed[50:, 60:]):
        p = quadrant.size / changed.size
        assert abs(quadrant.sum() - p * k) < Z * math.sqrt(k * p * (1 - p))


def test_salt_and_pepper_colour_pixels_change_in_all_channels():
    image = _distinct_image((30, 40, 3))
    out = noise.add_salt_and_pepper(image, 0.3, rng=4, low=0.0, high=255.0)
    changed = out != image
    per_pixel = changed.sum(axis=2)
    assert set(np.unique(per_pixel)) <= {0, 3}  # a pixel changes entirely or not at all
    assert (per_pixel == 3).sum() == round(0.3 * 30 * 40)
    values = out[per_pixel == 3]  # (k, 3)
    assert np.all((values == 0.0) | (values == 255.0))
    assert np.all(values == values[:, :1])  # black or white, not coloured
    np.testing.assert_array_equal(out[per_pixel == 0], image[per_pixel == 0])


def test_salt_and_pepper_custom_levels_and_uint8_input():
    image = np.full((20, 20), 128, dtype=np.uint8)
    before = image.copy()
    out = noise.add_salt_and_pepper(image, 0.25, rng=3, low=0, high=255)
    np.testing.assert_array_equal(image, before)
    assert out.dtype == np.float64
    assert set(np.unique(out)) <= {0.0, 128.0, 255.0}
    assert (out != 128).sum() == 100


def test_salt_and_pepper_reproducible():
    image = _distinct_image((25, 25, 3))
    a = noise.add_salt_and_pepper(image, 0.2, rng=11)
    np.testing.assert_array_equal(a, noise.add_salt_and_pepper(image, 0.2, rng=11))
    np.testing.assert_array_equal(a, noise.add_salt_and_pepper(image, 0.2, rng=np.random.default_rng(11)))
    assert not np.array_equal(a, noise.add_salt_and_pepper(image, 0.2, rng=12))


def test_inputs_not_modified_and_outputs_are_new_arrays():
    image = _distinct_image((10, 12))
    before = image.copy()
    for out in (noise.add_gaussian(image, 0.1, rng=0), noise.add_salt_and_pepper(image, 0.5, rng=0)):
        assert not np.shares_memory(out, image)
    np.testing.assert_array_equal(image, before)
    noise.add_salt_and_pepper(image, 0.0, rng=0)[0, 0] = -1  # even a zero-amount output is a copy
    np.testing.assert_array_equal(image, before)


def test_registered():
    assert registry.get("noise.add_gaussian").section == "3.1"
    assert registry.get("noise.add_salt_and_pepper").section == "3.10"
    assert registry.get("noise.add_gaussian").reference is noise.add_gaussian


# --------------------------------------------------------------------------------------------
# bad input (hypothesis)
# --------------------------------------------------------------------------------------------
good = np.zeros((5, 6))


CALLS = [
    lambda im: noise.add_gaussian(im, 1.0, rng=0),
    lambda im: noise.add_salt_and_pepper(im, 0.1, rng=0),
]


@FAST
@given(
    shape=st.one_of(
        st.lists(st.integers(1, 3), max_size=1),
        st.lists(st.integers(1, 3), min_size=4, max_size=4),
        st.tuples(st.integers(1, 3), st.integers(1, 3), st.sampled_from([1, 2, 4])),
    ).map(tuple),
    which=st.integers(0, 1),
)
def test_bad_image_shape(shape, which):
    raises_naming(ValueError, "image", CALLS[which], np.zeros(shape))


@FAST
@given(
    value=st.one_of(st.text(max_size=4), st.none(), st.just(np.ones((3, 3), dtype=complex))),
    which=st.integers(0, 1),
)
def test_bad_image_type(value, which):
    raises_naming(TypeError, "image", CALLS[which], value)


@FAST
@given(bad=st.sampled_from([np.nan, np.inf]), which=st.integers(0, 1))
def test_non_finite_image(bad, which):
    image = np.zeros((4, 4))
    image[1, 2] = bad
    raises_naming(ValueError, "image", CALLS[which], image)


@FAST
@given(sigma=st.one_of(st.floats(max_value=-1e-300, allow_nan=False), st.just(np.nan), st.just(np.inf)))
def test_bad_sigma(sigma):
    raises_naming(ValueError, "sigma", noise.add_gaussian, good, sigma)


@FAST
@given(sigma=st.one_of(st.text(max_size=3), st.none(), st.booleans(), st.just(1j)))
def test_bad_sigma_type(sigma):
    raises_naming(TypeError, "sigma", noise.add_gaussian, good, sigma)


@FAST
@given(
    amount=st.one_of(
        st.floats(max_value=-1e-12, allow_nan=False),
        st.floats(min_value=1 + 1e-12, allow_nan=False),
        st.just(np.nan),
    )
)
def test_bad_amount(amount):
    raises_naming(ValueError, "amount", noise.add_salt_and_pepper, good, amount)


@FAST
@given(name=st.sampled_from(["low", "high"]), value=st.sampled_from([np.nan, np.inf, "a", None]))
def test_bad_levels(name, value):
    exc = ValueError if isinstance(value, float) else TypeError
    raises_naming(exc, name, noise.add_salt_and_pepper, good, 0.1, **{name: value})


@FAST
@given(rng=st.one_of(st.text(max_size=3), st.floats(), st.just(np.random.RandomState(0)), st.booleans()))
def test_bad_rng(rng):
    raises_naming(TypeError, "rng", noise.add_gaussian, good, 1.0, rng=rng)
    raises_naming(TypeError, "rng", noise.add_salt_and_pepper, good, 0.5, rng=rng)


@pytest.mark.parametrize("rng", [-1, np.int64(-7)])
def test_negative_seed_is_named(rng):
    raises_naming(ValueError, "rng", noise.add_gaussian, good, 1.0, rng=rng)
    raises_naming(ValueError, "rng", noise.add_salt_and_pepper, good, 0.5, rng=rng)
