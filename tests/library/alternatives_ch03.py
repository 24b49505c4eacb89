"""Correct implementations of Chapter 3's algorithms, written differently from cvkit's reference.

They play the part of good students: a check must accept every one of them. Most loop over
pixels or windows (the way a first version looks); some use another formulation (FFT,
integral image, a 2-D kernel instead of two 1-D passes, other random draws). None calls
cvkit or a library that the guard forbids.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view


# --------------------------------------------------------------------------------------------
# borders
# --------------------------------------------------------------------------------------------
def source_index(k: int, n: int, border: str):
    """Index in 0..n-1 read for position ``k`` of a line of length ``n`` (None: a zero)."""
    if 0 <= k < n:
        return k
    if border == "zero":
        return None
    if border == "replicate":
        return 0 if k < 0 else n - 1
    if border == "reflect":  # dcb|abcd|cba
        m = k % (2 * n)
        return m if m < n else 2 * n - 1 - m
    if border == "reflect101":  # dc|abcd|cb
        if n == 1:
            return 0
        m = k % (2 * (n - 1))
        return m if m < n else 2 * (n - 1) - m
    raise ValueError(f"unknown border {border!r}")


def pad_sides(image, top, bottom, left, right, border):
    """``image`` (float64) grown by the given numbers of pixels on each side."""
    img = np.asarray(image, dtype=np.float64)
    h, w = img.shape[:2]
    rows = [source_index(k, h, border) for k in range(-top, h + bottom)]
    cols = [source_index(k, w, border) for k in range(-left, w + right)]
    out = np.zeros((len(rows), len(cols)) + img.shape[2:])
    for i, r in enumerate(rows):
        if r is None:
            continue
        for j, c in enumerate(cols):
            if c is not None:
                out[i, j] = img[r, c]
    return out


def pad(image, radius, border="reflect101"):
    ry, rx = (radius, radius) if np.isscalar(radius) else radius
    return pad_sides(image, ry, ry, rx, rx, border)


# --------------------------------------------------------------------------------------------
# correlation and convolution
# --------------------------------------------------------------------------------------------
def correlate(image, kernel, border="reflect101", output="same"):
    """One window per output pixel."""
    k = np.asarray(kernel, dtype=np.float64)
    kh, kw = k.shape
    if output == "valid":
        padded = np.asarray(image, dtype=np.float64)
    else:
        padded = pad_sides(image, kh // 2, kh - 1 - kh // 2, kw // 2, kw - 1 - kw // 2, border)
    ho, wo = padded.shape[0] - kh + 1, padded.shape[1] - kw + 1
    weights = k if padded.ndim == 2 else k[:, :, None]
    out = np.empty((ho, wo) + padded.shape[2:])
    for i in range(ho):
        for j in range(wo):
            out[i, j] = (padded[i: i + kh, j: j + kw] * weights).sum(axis=(0, 1))
    return out


def correlate_fft(image, kernel, border="reflect101", output="same"):
    """Through numpy's FFT: correlation = convolution with the flipped kernel."""
    k = np.asarray(kernel, dtype=np.float64)
    kh, kw = k.shape
    if output == "valid":
        padded = np.asarray(image, dtype=np.float64)
    else:
        padded = pad_sides(image, kh // 2, kh - 1 - kh // 2, kw // 2, kw - 1 - kw // 2, border)
    hp, wp = padded.shape[:2]
    shape = (hp + kh - 1, wp + kw - 1)
    spectrum_k = np.fft.rfft2(k[::-1, ::-1], shape)
    planes = padded[..., None] if padded.ndim == 2 else padded
    out = np.stack([np.fft.irfft2(np.fft.rfft2(planes[..., c], shape) * spectrum_k, shape)
                    [kh - 1: hp, kw - 1: wp] for c in range(planes.shape[2])], axis=-1)
    return out[..., 0] if padded.ndim == 2 else out


def convolve(image, kernel, border="reflect101", output="same"):
    """The formula O(i, j) = Σ K(m, n)·I(i − m + kh//2, j − n + kw//2), tap by tap, reading the
    image through index lists instead of padding it."""
    img = np.asarray(image, dtype=np.float64)
    k = np.asarray(kernel, dtype=np.float64)
    kh, kw = k.shape
    h, w = img.shape[:2]
    if output == "valid":  # positions where the flipped kernel fits: rows kh−1 .. h−1
        out_rows, out_cols = range(kh - 1, h), range(kw - 1, w)
        a, b = 0, 0
    else:
        out_rows, out_cols = range(h), range(w)
        a, b = kh // 2, kw // 2
    out = np.zeros((len(out_rows), len(out_cols)) + img.shape[2:])
    for m in range(kh):
        rows = [source_index(i - m + a, h, border) for i in out_rows]
        for n in range(kw):
            cols = [source_index(j - n + b, w, border) for j in out_cols]
            shifted = img[np.ix_([r or 0 for r in rows], [c or 0 for c in cols])]
            shifted[[r is None for r in rows]] = 0.0
            shifted[:, [c is None for c in cols]] = 0.0
            out += k[m, n] * shifted
    return out


# --------------------------------------------------------------------------------------------
# mean, Gaussian
# --------------------------------------------------------------------------------------------
def mean_kernel(size):
    kernel = np.empty((size, size))
    for i in range(size):
        for j in range(size):
            kernel[i, j] = 1.0 / size / size
    return kernel


def mean(image, size, border="reflect101"):
    """Integral image (summed-area table): four look-ups per window."""
    r = size // 2
    padded = pad(image, r, border)
    table = np.zeros((padded.shape[0] + 1, padded.shape[1] + 1) + padded.shape[2:])
    table[1:, 1:] = padded.cumsum(axis=0).cumsum(axis=1)
    sums = table[size:, size:] - table[:-size, size:] - table[size:, :-size] + table[:-size, :-size]
    return sums / (size * size)


def gaussian_kernel(sigma, radius=None):
    if radius is None:
        radius = math.ceil(3 * sigma - 1e-9)
    values = [math.exp(-(x * x) / (2 * sigma * sigma)) for x in range(-radius, radius + 1)]
    total = math.fsum(values)
    return np.array([v / total for v in values])


def gaussian(image, sigma, border="reflect101"):
    """Not separable: one correlation with the 2-D kernel G(x)·G(y)."""
    g = gaussian_kernel(sigma)
    return correlate(image, np.outer(g, g), border)


# --------------------------------------------------------------------------------------------
# median, bilateral, non-local means
# --------------------------------------------------------------------------------------------
def median(image, size, border="reflect101"):
    r = size // 2
    padded = pad(image, r, border)
    h, w = padded.shape[0] - 2 * r, padded.shape[1] - 2 * r
    out = np.empty((h, w) + padded.shape[2:])
    middle = size * size // 2
    for i in range(h):
        for j in range(w):
            window = padded[i: i + size, j: j + size].reshape(size * size, -1)
            out[i, j] = np.sort(window, axis=0)[middle].reshape(out.shape[2:])
    return out


def bilateral(image, sigma_space, sigma_range, radius=None, border="reflect101"):
    if radius is None:
        radius = math.ceil(3 * sigma_space - 1e-9)
    r = radius
    img = np.asarray(image, dtype=np.float64)
    padded = pad(img, r, border)
    planes = padded[..., None] if img.ndim == 2 else padded
    y, x = np.mgrid[-r: r + 1, -r: r + 1]
    spatial = np.exp(-(x * x + y * y) / (2 * sigma_space ** 2))
    h, w = img.shape[:2]
    out = np.empty((h, w, planes.shape[2]))
    for i in range(h):
        for j in range(w):
            window = planes[i: i + 2 * r + 1, j: j + 2 * r + 1]
            diff2 = ((window - planes[i + r, j + r]) ** 2).sum(axis=-1)
            weights = spatial * np.exp(-diff2 / (2 * sigma_range ** 2))
            out[i, j] = (weights[..., None] * window).sum(axis=(0, 1)) / weights.sum()
    return out[..., 0] if img.ndim == 2 else out


def nl_means(image, h, patch_size=7, search_size=21, border="reflect101"):
    img = np.asarray(image, dtype=np.float64)
    sr, pr = search_size // 2, patch_size // 2
    big = sr + pr
    padded = pad(img, big, border)
    planes = padded[..., None] if img.ndim == 2 else padded
    height, width = img.shape[:2]
    out = np.empty((height, width, planes.shape[2]))
    for i in range(height):
        for j in range(width):
            ci, cj = i + big, j + big  # p in the padded image
            region = planes[ci - sr - pr: ci + sr + pr + 1, cj - sr - pr: cj + sr + pr + 1]
            patches = sliding_window_view(region, (patch_size, patch_size), axis=(0, 1))  # (S, S, C, P, P)
            centre = planes[ci - pr: ci + pr + 1, cj - pr: cj + pr + 1]  # (P, P, C)
            d2 = ((patches - np.moveaxis(centre, -1, 0)) ** 2).mean(axis=(2, 3, 4))
            weights = np.exp(-d2 / (h * h))
            values = planes[ci - sr: ci + sr + 1, cj - sr: cj + sr + 1]
            out[i, j] = (weights[..., None] * values).sum(axis=(0, 1)) / weights.sum()
    return out[..., 0] if img.ndim == 2 else out


def temporal_mean(frames):
    total = None
    count = 0
    for frame in frames:
        frame = np.asarray(frame, dtype=np.float64)
        total = frame.copy() if total is None else total + frame
        count += 1
    return total / count


# --------------------------------------------------------------------------------------------
# noise: other draws than the reference's
# --------------------------------------------------------------------------------------------
def add_gaussian(image, sigma, rng=None):
    gen = np.random.default_rng(rng)
    img = np.asarray(image, dtype=np.float64)
    noise = gen.normal(0.0, sigma, size=img.shape[::-1]).T  # drawn in another order
    return img + noise


def add_salt_and_pepper(image, amount, rng=None, low=0.0, high=1.0):
    gen = np.random.default_rng(rng)
    out = np.array(image, dtype=np.float64)
    h, w = out.shape[:2]
    count = int(round(amount * h * w))
    order = gen.permutation(h * w)[:count]
    coins = gen.integers(0, 2, size=count)
    for index, coin in zip(order.tolist(), coins.tolist()):
        out[index // w, index % w] = high if coin else low
    return out


ALTERNATIVES = {
    "filters.pad": pad,
    "filters.correlate": correlate,
    "filters.convolve": convolve,
    "filters.mean_kernel": mean_kernel,
    "filters.mean": mean,
    "filters.gaussian_kernel": gaussian_kernel,
    "filters.gaussian": gaussian,
    "filters.median": median,
    "filters.bilateral": bilateral,
    "filters.nl_means": nl_means,
    "filters.temporal_mean": temporal_mean,
    "noise.add_gaussian": add_gaussian,
    "noise.add_salt_and_pepper": add_salt_and_pepper,
}

#: further correct versions, formulated differently again
EXTRA_ALTERNATIVES = {
    "filters.correlate": correlate_fft,
}


def denoise(noisy, sigma):
    """Chapter 3's measured exercise another way: non-local means with 5×5 patches compared
    through their (H, W, 25) stacks of values, a 13×13 search window and h = 1.1σ, the image
    extended by edge replication."""
    image = np.asarray(noisy, dtype=np.float64)
    rows, cols = image.shape
    reach, half = 6, 2
    padded = np.pad(image, reach + half, mode="edge")
    patches = np.lib.stride_tricks.sliding_window_view(padded, (5, 5)).reshape(rows + 2 * reach, cols + 2 * reach, 25)
    mine = patches[reach:reach + rows, reach:reach + cols]
    values = padded[half:-half, half:-half]
    total = np.zeros((rows, cols))
    weights = np.zeros((rows, cols))
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            other = patches[reach + dy:reach + dy + rows, reach + dx:reach + dx + cols]
            w = np.exp(-np.mean((other - mine) ** 2, axis=-1) / (1.1 * sigma) ** 2)
            total += w * values[reach + dy:reach + dy + rows, reach + dx:reach + dx + cols]
            weights += w
    return total / weights
