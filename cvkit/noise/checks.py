"""Checks of Chapter 3's noise models, graded by properties and statistics.

Two correct versions of a random function may draw different numbers, so outputs are not
compared value by value: :class:`~cvkit.grading.Statistics` computes named numbers of the
candidate's output and of the reference's (noise mean and spread in units of σ, tail
fraction, fraction of pixels replaced, ...) and requires them to agree within a tolerance
derived from the sample size: six standard errors of the difference of two independent
samples (√2 × the standard error of one), so a correct version fails with probability
~1e-9 per statistic. Exact properties (how many pixels an impulse noise replaces, that
replaced values are ``low`` or ``high``) have tolerance 0. ``seeded=True``: the engine also
calls the candidate twice with the same seed and requires identical outputs, which catches
drawing from ``np.random.*`` instead of ``rng``.

Hidden cases use 64×64 to 96×96 pixels (a few thousand samples per statistic).
"""
from __future__ import annotations

import math

import numpy as np

from ..grading import Case, Check, Drawn, Statistics, mistake
from ..grading.casekit import argument as _arg
from ..grading.casekit import seed as _seed
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ..grading.runtime.adapters import call_draws
from . import add_gaussian as _add_gaussian
from . import add_salt_and_pepper as _add_salt_and_pepper

__all__ = ["add_gaussian", "add_salt_and_pepper"]

_SQRT2 = math.sqrt(2.0)


# --------------------------------------------------------------------------------------------
# noise.add_gaussian (§3.1)
# --------------------------------------------------------------------------------------------
_TAIL = math.erfc(2.0 / _SQRT2)  # P(|z| > 2) for a standard normal z, ≈ 0.0455


def _gaussian_statistics(output, case):
    image = np.asarray(case.args[0], dtype=np.float64)
    sigma = float(_arg(case, 1, "sigma"))
    out = np.asarray(output, dtype=np.float64)
    noise = out - image
    if sigma == 0.0:
        return {"largest |output − image| (σ = 0)": float(np.abs(noise).max())}
    z = noise / sigma
    stats = {
        "mean of (output − image)/σ": float(z.mean()),
        "standard deviation of (output − image)/σ": float(z.std()),
        "fraction of pixels with |output − image| > 2σ": float(np.mean(np.abs(z) > 2.0)),
    }
    if image.min() >= 0.0 and image.max() <= 1.0:
        stats["fraction of output values outside [0, 1] (noise is not clipped)"] = float(np.mean((out < 0) | (out > 1)))
    if image.ndim == 3:
        flat = z.reshape(-1, image.shape[2]).T
        c = np.corrcoef(flat)
        stats["correlation of the noise between colour channels"] = float((c[0, 1] + c[0, 2] + c[1, 2]) / 3)
    return stats


def _gaussian_tolerance(case):
    image = np.asarray(case.args[0], dtype=np.float64)
    sigma = float(_arg(case, 1, "sigma"))
    if sigma == 0.0:
        return {"largest |output − image| (σ = 0)": 0.0}
    n = image.size
    tol = {
        # six standard errors of the difference of two independent samples of n values
        "mean of (output − image)/σ": 6 * _SQRT2 / math.sqrt(n),
        "standard deviation of (output − image)/σ": 6 / math.sqrt(n),  # SE of one std: 1/√(2n)
        "fraction of pixels with |output − image| > 2σ": 6 * math.sqrt(2 * _TAIL * (1 - _TAIL) / n),
        "correlation of the noise between colour channels": 6 * _SQRT2 / math.sqrt(n),
    }
    if image.min() >= 0.0 and image.max() <= 1.0:
        # each value leaves [0, 1] with probability Φ(−x/σ) + Φ((x − 1)/σ)
        p = 0.5 * (np.vectorize(math.erfc)(image / (sigma * _SQRT2)) + np.vectorize(math.erfc)((1 - image) / (sigma * _SQRT2)))
        sd = math.sqrt(2 * float(np.sum(p * (1 - p)))) / n
        tol["fraction of output values outside [0, 1] (noise is not clipped)"] = max(6 * sd, 3.0 / n)
    return tol


@mistake("σ used as variance",
         "σ is the standard deviation: noise = σ·rng.standard_normal(shape), not σ²·rng.standard_normal(shape)")
def _g_variance(image, sigma, rng=None):
    img = np.asarray(image, dtype=np.float64)
    return img + sigma ** 2 * np.random.default_rng(rng).standard_normal(img.shape)


@mistake("clipped to [0, 1]",
         "Return image + noise as it is: the model I + n is not clipped (and images need not be in [0, 1])")
def _g_clipped(image, sigma, rng=None):
    img = np.asarray(image, dtype=np.float64)
    return np.clip(img + sigma * np.random.default_rng(rng).standard_normal(img.shape), 0.0, 1.0)


@mistake("uniform noise", "Draw from a normal distribution N(0, σ²): rng.normal(0, sigma, shape)")
def _g_uniform(image, sigma, rng=None):
    img = np.asarray(image, dtype=np.float64)
    return img + np.random.default_rng(rng).uniform(-sigma, sigma, img.shape)


@mistake("one noise value for the whole image",
         "Draw an independent value for every pixel: pass the image's shape to the generator")
def _g_one_value(image, sigma, rng=None):
    img = np.asarray(image, dtype=np.float64)
    return img + sigma * np.random.default_rng(rng).standard_normal()


@mistake("same noise in every colour channel",
         "Draw the noise with the image's full shape (H, W, 3): every channel gets its own value")
def _g_same_for_channels(image, sigma, rng=None):
    img = np.asarray(image, dtype=np.float64)
    noise = sigma * np.random.default_rng(rng).standard_normal(img.shape[:2])
    return img + (noise[..., None] if img.ndim == 3 else noise)


@mistake("rng ignored: the same noise on every call",
         "Draw from the generator the caller gives, np.random.default_rng(rng): a generator made with a "
         "fixed seed inside the function adds the same noise to every image")
def _g_fixed_seed(image, sigma, rng=None):
    return _add_gaussian(image, sigma, rng=0)


def _unit_image(rng, h, w, channels=None):
    shape = (h, w) if channels is None else (h, w, channels)
    return rng.random(shape)


def _gaussian_hidden(rng):
    sigma_small = _u(rng, 0.1, 0.25)
    return [
        Case((_unit_image(rng, 64, _size(rng, 64, 80)), sigma_small), {"rng": _seed(rng)},
             "image in [0, 1], σ = 0.1..0.25"),
        Case((rng.integers(0, 256, (_size(rng, 64, 80), _size(rng, 64, 80)), dtype=np.uint8),
              float(rng.integers(5, 30))), {"rng": _seed(rng)}, "uint8 image, σ in 0..255 units (not rescaled)"),
        Case((_unit_image(rng, 48, _size(rng, 40, 56), 3), _u(rng, 0.1, 0.2)),
             {"rng": _seed(rng)}, "colour image in [0, 1]"),
        Case((rng.integers(0, 256, (40, _size(rng, 40, 56), 3), dtype=np.uint8), float(rng.integers(10, 25))),
             {"rng": _seed(rng)}, "colour uint8 image"),
        Case((rng.uniform(-1e6, 1e6, (64, 64)), float(np.round(rng.uniform(1e5, 5e5), 0))), {"rng": _seed(rng)},
             "±1e6 values, σ = 1e5..5e5"),
        Case((rng.normal(0, 3, (_size(rng, 64, 72), 64)), _u(rng, 1.5, 3.0)),
             {"rng": _seed(rng)}, "negative values, σ > 1"),
        Case((np.full((96, 96), 0.5), 0.3), {"rng": _seed(rng)}, "constant image 0.5, σ = 0.3"),
        Case((_unit_image(rng, 1, 4096), _u(rng, 0.3, 0.7)), {"rng": _seed(rng)},
             "single-row 1×4096 image"),
        Case((_unit_image(rng, 64, 64), sigma_small), {"rng": np.random.default_rng(_seed(rng))},
             "rng given as a numpy Generator"),
        Case((_unit_image(rng, 16, 20), 0.0), {"rng": _seed(rng)}, "σ = 0 (the image, as float)"),
        Case((_unit_image(rng, 16, _size(rng, 16, 24)), _u(rng, 0.05, 0.2)), {"draws": (_seed(rng), 20)},
             "20 calls, rng = r, r + 1, …: fresh noise on every call"),
    ]


add_gaussian = Check(
    rules=("integer",),
    public=[
        Case((np.random.default_rng(100).random((64, 64)), 0.1), {"rng": 0}, "64×64 image in [0, 1], σ = 0.1"),
        Case((np.random.default_rng(101).random((40, 40, 3)), 0.2), {"rng": 1}, "colour 40×40×3 image, σ = 0.2"),
        Case((np.random.default_rng(102).integers(0, 256, (64, 64), dtype=np.uint8), 20.0), {"rng": 2},
             "uint8 64×64 image, σ = 20"),
        Case((np.random.default_rng(103).random((16, 16)), 0.1), {"draws": (300, 20)},
             "20 calls, rng = 300, 301, …: fresh noise on every call"),
    ],
    hidden=_gaussian_hidden,
    compare=Drawn(single=Statistics(statistics=_gaussian_statistics, tolerance=_gaussian_tolerance, dtype_kind="f")),
    call=call_draws,
    mistakes=[_g_variance, _g_clipped, _g_uniform, _g_one_value, _g_same_for_channels, _g_fixed_seed],
    seeded=True,
)


# --------------------------------------------------------------------------------------------
# noise.add_salt_and_pepper (§3.10)
# --------------------------------------------------------------------------------------------
def _sp_args(case):
    image = np.asarray(case.args[0], dtype=np.float64)
    amount = float(_arg(case, 1, "amount"))
    low = float(_arg(case, 3, "low", 0.0))
    high = float(_arg(case, 4, "high", 1.0))
    return image, amount, low, high


def _sp_statistics(output, case):
    image, amount, low, high = _sp_args(case)
    out = np.asarray(output, dtype=np.float64)
    changed_values = out != image
    changed = changed_values if image.ndim == 2 else changed_values.any(axis=-1)
    height, width = image.shape[:2]
    count = int(changed.sum())
    stats = {"fraction of pixels changed": count / (height * width)}
    values = out[changed_values]
    stats["fraction of changed values that are neither low nor high"] = (
        float(np.mean((values != low) & (values != high))) if values.size else 0.0
    )
    if count:
        pixels = out[changed]  # (K,) or (K, 3)
        if image.ndim == 3:
            is_low, is_high = (pixels == low).all(axis=-1), (pixels == high).all(axis=-1)
            stats["fraction of changed pixels not entirely low or entirely high"] = float(np.mean(~(is_low | is_high)))
        else:
            is_high = pixels == high
        stats["fraction of changed pixels set to high"] = float(np.mean(is_high))
        rows, cols = np.nonzero(changed)
        stats["mean row of the changed pixels (0 top, 1 bottom)"] = float(rows.mean() / max(height - 1, 1))
        stats["mean column of the changed pixels (0 left, 1 right)"] = float(cols.mean() / max(width - 1, 1))
    return stats


def _sp_tolerance(case):
    image, amount, low, high = _sp_args(case)
    count = max(1, int(round(amount * image.shape[0] * image.shape[1])))
    spread = 6 * _SQRT2 / math.sqrt(count)  # six standard errors of a difference of two means
    return {
        "fraction of pixels changed": 0.0,  # exactly round(amount · H · W) pixels
        "fraction of changed values that are neither low nor high": 0.0,
        "fraction of changed pixels not entirely low or entirely high": 0.0,
        "fraction of changed pixels set to high": spread * 0.5,  # a fair coin: SD 1/2
        "mean row of the changed pixels (0 top, 1 bottom)": spread * 0.3,  # uniform position: SD ≈ 0.29
        "mean column of the changed pixels (0 left, 1 right)": spread * 0.3,
    }


def _sp_setup(image, amount, rng):
    img = np.array(image, dtype=np.float64)
    n_pixels = img.shape[0] * img.shape[1]
    return img, n_pixels, int(round(amount * n_pixels)), np.random.default_rng(rng)


@mistake("salt and pepper each with fraction amount (twice too many)",
         "Replace round(amount·H·W) pixels in total, each by high or low with probability 1/2")
def _sp_twice(image, amount, rng=None, low=0.0, high=1.0):
    img, n_pixels, count, gen = _sp_setup(image, amount, rng)
    flat = img.reshape(n_pixels, -1)
    flat[gen.choice(n_pixels, count, replace=False)] = high
    flat[gen.choice(n_pixels, count, replace=False)] = low
    return img


@mistake("only salt", "Each replaced pixel gets high or low with probability 1/2 (salt AND pepper)")
def _sp_only_salt(image, amount, rng=None, low=0.0, high=1.0):
    img, n_pixels, count, gen = _sp_setup(image, amount, rng)
    img.reshape(n_pixels, -1)[gen.choice(n_pixels, count, replace=False)] = high
    return img


@mistake("channels replaced independently",
         "Choose whole pixels: a replaced pixel gets low (or high) in all three channels")
def _sp_per_channel(image, amount, rng=None, low=0.0, high=1.0):
    img, _, _, gen = _sp_setup(image, amount, rng)
    flat = img.reshape(-1)
    count = int(round(amount * flat.size))
    chosen = gen.choice(flat.size, count, replace=False)
    flat[chosen] = np.where(gen.random(count) < 0.5, high, low)
    return img


@mistake("low and high ignored (always 0 and 1)", "Use the `low` and `high` arguments (0 and 255 for a uint8 image)")
def _sp_fixed_values(image, amount, rng=None, low=0.0, high=1.0):
    img, n_pixels, count, gen = _sp_setup(image, amount, rng)
    chosen = gen.choice(n_pixels, count, replace=False)
    img.reshape(n_pixels, -1)[chosen] = np.where(gen.random(count) < 0.5, 1.0, 0.0)[:, None]
    return img


@mistake("pixels drawn with replacement (too few replaced)",
         "Draw distinct pixels: rng.choice(H * W, size=count, replace=False)")
def _sp_with_replacement(image, amount, rng=None, low=0.0, high=1.0):
    img, n_pixels, count, gen = _sp_setup(image, amount, rng)
    rows = gen.integers(0, img.shape[0], count)
    cols = gen.integers(0, img.shape[1], count)
    img[rows, cols] = np.where(gen.random(count) < 0.5, high, low)[(...,) + (None,) * (img.ndim - 2)]
    return img


@mistake("rng ignored: the same pixels replaced on every call",
         "Draw from the generator the caller gives, np.random.default_rng(rng): a generator made with a "
         "fixed seed inside the function hits the same pixels of every image")
def _sp_fixed_seed(image, amount, rng=None, low=0.0, high=1.0):
    return _add_salt_and_pepper(image, amount, rng=0, low=low, high=high)


def _inner_image(rng, h, w, channels=None, lo=0.05, hi=0.95):
    """Values never equal to low or high, so every replaced pixel shows."""
    shape = (h, w) if channels is None else (h, w, channels)
    return rng.uniform(lo, hi, shape)


def _sp_hidden(rng):
    return [
        Case((_inner_image(rng, 64, _size(rng, 64, 80)), _u(rng, 0.06, 0.15)),
             {"rng": _seed(rng)}, "image in [0, 1], default low = 0 and high = 1"),
        Case((_inner_image(rng, _size(rng, 64, 80), 72), 0.2), {"rng": _seed(rng), "low": -1.0, "high": 2.0},
             "low = −1, high = 2"),
        Case((rng.integers(1, 255, (64, _size(rng, 64, 80)), dtype=np.uint8), _u(rng, 0.06, 0.12)),
             {"rng": _seed(rng), "low": 0.0, "high": 255.0}, "uint8 image, low = 0, high = 255"),
        Case((_inner_image(rng, 48, _size(rng, 48, 56), 3), _u(rng, 0.1, 0.2)),
             {"rng": _seed(rng)}, "colour image (a pixel turns black or white in all channels)"),
        Case((rng.integers(1, 255, (40, _size(rng, 48, 56), 3), dtype=np.uint8), 0.25),
             {"rng": _seed(rng), "low": 0.0, "high": 255.0}, "colour uint8 image"),
        Case((_inner_image(rng, 32, 32), 0.0), {"rng": _seed(rng)}, "amount 0 (nothing changes)"),
        Case((_inner_image(rng, 48, 48), 1.0), {"rng": _seed(rng)}, "amount 1 (every pixel replaced)"),
        Case((_inner_image(rng, 64, 64), _u(rng, 0.08, 0.15)),
             {"rng": np.random.default_rng(_seed(rng))}, "rng given as a numpy Generator"),
        Case((rng.uniform(-1e6, 1e6, (64, 64)), 0.1), {"rng": _seed(rng), "low": -2e6, "high": 2e6},
             "±1e6 values, low = −2e6, high = 2e6"),
        Case((_inner_image(rng, 64, 64, lo=0.3, hi=0.7), 0.5), {"rng": _seed(rng), "low": 0.25, "high": 0.75},
             "amount 0.5, low = 0.25, high = 0.75"),
        Case((_inner_image(rng, 1, 4096), 0.1), {"rng": _seed(rng)}, "single-row 1×4096 image"),
        Case((_inner_image(rng, 16, _size(rng, 16, 24)), _u(rng, 0.1, 0.3)), {"draws": (_seed(rng), 20)},
             "20 calls, rng = r, r + 1, …: other pixels on every call"),
    ]


add_salt_and_pepper = Check(
    public=[
        Case((np.random.default_rng(200).uniform(0.05, 0.95, (64, 64)), 0.1), {"rng": 0},
             "64×64 image, amount 0.1"),
        Case((np.random.default_rng(201).uniform(0.05, 0.95, (48, 48, 3)), 0.15), {"rng": 1},
             "colour 48×48×3 image, amount 0.15"),
        Case((np.random.default_rng(202).integers(1, 255, (64, 64), dtype=np.uint8), 0.2),
             {"rng": 2, "low": 0.0, "high": 255.0}, "uint8 image, amount 0.2, low = 0, high = 255"),
        Case((np.random.default_rng(203).uniform(0.05, 0.95, (16, 16)), 0.2), {"draws": (400, 20)},
             "20 calls, rng = 400, 401, …: other pixels on every call"),
    ],
    hidden=_sp_hidden,
    compare=Drawn(single=Statistics(statistics=_sp_statistics, tolerance=_sp_tolerance, dtype_kind="f")),
    call=call_draws,
    mistakes=[_sp_twice, _sp_only_salt, _sp_per_channel, _sp_fixed_values, _sp_with_replacement, _sp_fixed_seed],
    seeded=True,
)
