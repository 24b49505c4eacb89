"""Correct implementations of the Chapter 1–2 algorithms, written differently from cvkit's
reference.

They play the part of good students: a check must accept every one of them. Most loop over
points, pixels or windows (the way a first version looks); others use another formulation of
the same definition (image distances and similar triangles for the blur circle, the
difference of two logarithms for the dynamic range, the same-colour pixels among the 8
neighbours for demosaicking). None calls cvkit or a library the guard forbids.
``tests/library/test_checks_ch01.py`` uses the two Chapter 1 ones (``quantize``,
``image_memory_bits``).
"""
from __future__ import annotations

import math
import statistics

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view


# --------------------------------------------------------------------------------------------
# Chapter 1 warm-ups (§2.11 of the notes)
# --------------------------------------------------------------------------------------------
def image_memory_bits(width, height, bits_per_pixel):
    return math.prod((int(width), int(height), int(bits_per_pixel)))


def quantize(image, bits, vmax=1.0):
    """Value by value with Python's round() (which also rounds exact halves to even)."""
    values = np.asarray(image, dtype=np.float64)
    steps = 2 ** bits - 1
    out = np.empty(values.shape)
    for index, x in np.ndenumerate(values):
        x = min(max(float(x), 0.0), float(vmax))
        out[index] = round(x * steps / vmax) * vmax / steps
    return out


# --------------------------------------------------------------------------------------------
# geometry
# --------------------------------------------------------------------------------------------
def project_pinhole(points_cam, f):
    points = np.asarray(points_cam, dtype=np.float64)
    out = np.zeros((len(points), 2))
    for i, (x, y, z) in enumerate(points):
        out[i] = (f * x / z, f * y / z)
    return out


def depth_from_disparity(disparity, baseline, focal):
    d = np.asarray(disparity, dtype=np.float64)
    out = np.empty(d.shape)
    for index, value in np.ndenumerate(d):
        if math.isnan(value) or value < 0:
            out[index] = math.nan
        elif value == 0:
            out[index] = math.inf
        else:
            out[index] = baseline * focal / value
    return out[()] if out.ndim == 0 else out


# --------------------------------------------------------------------------------------------
# optics
# --------------------------------------------------------------------------------------------
def thin_lens_image_distance(object_distance, focal_length):
    """1/d_I = 1/f − 1/d_S, with 1/inf = 0 and 1/0 = inf."""
    d = np.asarray(object_distance, dtype=np.float64)
    with np.errstate(divide="ignore"):
        inverse = 1.0 / focal_length - 1.0 / d
        return np.where(inverse == 0, np.inf, 1.0 / np.where(inverse == 0, 1.0, inverse))


def blur_circle_diameter(object_distance, focus_distance, focal_length, aperture_diameter):
    """Similar triangles with the image distances: c = D·|d_I(d_O) − d_I(d_F)| / d_I(d_O)."""
    o, fd, f, a = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in
                                        (object_distance, focus_distance, focal_length, aperture_diameter)))

    def image_distance(d):
        return np.where(np.isinf(d), f, f * d / np.where(np.isinf(d), 1.0, d - f))

    d_io, d_if = image_distance(o), image_distance(fd)
    out = a * np.abs(d_io - d_if) / d_io
    return out[()] if out.ndim == 0 else out


# --------------------------------------------------------------------------------------------
# sensor
# --------------------------------------------------------------------------------------------
def snr_db(frames):
    """Pixel by pixel with the statistics module (exact mean and standard deviation)."""
    stack = np.asarray(frames, dtype=np.float64)
    out = np.empty(stack.shape[1:])
    for index in np.ndindex(*stack.shape[1:]):
        values = [float(v) for v in stack[(slice(None),) + index]]
        mean = statistics.fmean(values)
        std = statistics.pstdev(values)
        if mean <= 0:
            out[index] = math.nan
        elif std == 0:
            out[index] = math.inf
        else:
            out[index] = 20 * math.log10(mean / std)
    return out


def dynamic_range_db(e_max, e_min):
    return 20.0 * (np.log10(np.asarray(e_max, dtype=np.float64)) - np.log10(np.asarray(e_min, dtype=np.float64)))


# --------------------------------------------------------------------------------------------
# Bayer
# --------------------------------------------------------------------------------------------
_CHANNEL = {"R": 0, "G": 1, "B": 2}


def bayer_mosaic(rgb, pattern="RGGB"):
    img = np.asarray(rgb, dtype=np.float64)
    h, w = img.shape[:2]
    out = np.empty((h, w))
    for i in range(h):
        for j in range(w):
            out[i, j] = img[i, j, _CHANNEL[pattern[2 * (i % 2) + (j % 2)]]]
    return out


def _reflect101(k, n):
    period = 2 * (n - 1)
    k %= period
    return k if k < n else period - k


def demosaic_bilinear(raw, pattern="RGGB"):
    """For every pixel and every colour it lacks: the mean of the pixels of that colour among
    its 8 neighbours (read through reflect101)."""
    img = np.asarray(raw, dtype=np.float64)
    h, w = img.shape

    def colour(i, j):  # the colour of a site depends only on the parity of its position
        return _CHANNEL[pattern[2 * (i % 2) + (j % 2)]]

    out = np.empty((h, w, 3))
    for i in range(h):
        for j in range(w):
            for c in range(3):
                if colour(i, j) == c:
                    out[i, j, c] = img[i, j]
                    continue
                values = [img[_reflect101(i + di, h), _reflect101(j + dj, w)]
                          for di in (-1, 0, 1) for dj in (-1, 0, 1)
                          if (di or dj) and colour(i + di, j + dj) == c]
                out[i, j, c] = sum(values) / len(values)
    return out


# --------------------------------------------------------------------------------------------
# stereo
# --------------------------------------------------------------------------------------------
def block_matching(left, right, max_disparity, block_size=7, cost="sad"):
    """Pixel by pixel, disparity by disparity, one window at a time."""
    L = np.asarray(left, dtype=np.float64)
    R = np.asarray(right, dtype=np.float64)
    h, w = L.shape
    r = block_size // 2
    Lp, Rp = np.pad(L, r, mode="reflect"), np.pad(R, r, mode="reflect")
    out = np.zeros((h, w), dtype=np.int64)
    for y in range(h):
        for x in range(w):
            a = Lp[y: y + block_size, x: x + block_size]
            best = None
            for d in range(min(max_disparity, x) + 1):
                b = Rp[y: y + block_size, x - d: x - d + block_size]
                if cost == "sad":
                    score = np.abs(a - b).sum()
                elif cost == "ssd":
                    score = ((a - b) ** 2).sum()
                else:
                    if np.all(a == a.flat[0]) or np.all(b == b.flat[0]):
                        score = 0.0
                    else:
                        da, db = a - a.mean(), b - b.mean()
                        score = -(da * db).sum() / math.sqrt((da * da).sum() * (db * db).sum())
                if best is None or score < best:
                    best, out[y, x] = score, d
    return out


def block_matching_windows(left, right, max_disparity, block_size=7, cost="sad"):
    """Vectorised differently: every window of both images as a (H, W, n) view, a (D+1, H, W)
    cost volume, then argmin (which returns the first, i.e. smallest, d on ties)."""
    L = np.asarray(left, dtype=np.float64)
    R = np.asarray(right, dtype=np.float64)
    h, w = L.shape
    r = block_size // 2
    n = block_size * block_size
    wl = sliding_window_view(np.pad(L, r, mode="reflect"), (block_size, block_size)).reshape(h, w, n)
    wr = sliding_window_view(np.pad(R, r, mode="reflect"), (block_size, block_size)).reshape(h, w, n)
    if cost == "zncc":
        dl = wl - wl.mean(axis=-1, keepdims=True)
        dr = wr - wr.mean(axis=-1, keepdims=True)
        nl = np.sqrt((dl * dl).sum(axis=-1))
        nr = np.sqrt((dr * dr).sum(axis=-1))
        flat_l = wl.max(axis=-1) == wl.min(axis=-1)
        flat_r = wr.max(axis=-1) == wr.min(axis=-1)
    volume = np.full((max_disparity + 1, h, w), np.inf)
    for d in range(min(max_disparity, w - 1) + 1):
        if cost == "zncc":
            num = (dl[:, d:] * dr[:, : w - d]).sum(axis=-1)
            flat = flat_l[:, d:] | flat_r[:, : w - d]
            with np.errstate(all="ignore"):
                volume[d, :, d:] = np.where(flat, 0.0, -num / (nl[:, d:] * nr[:, : w - d]))
        else:
            diff = wl[:, d:] - wr[:, : w - d]
            volume[d, :, d:] = (np.abs(diff) if cost == "sad" else diff * diff).sum(axis=-1)
    return np.argmin(volume, axis=0).astype(np.int64)


ALTERNATIVES = {
    "formation.project_pinhole": project_pinhole,
    "formation.depth_from_disparity": depth_from_disparity,
    "formation.thin_lens_image_distance": thin_lens_image_distance,
    "formation.blur_circle_diameter": blur_circle_diameter,
    "formation.quantize": quantize,
    "formation.image_memory_bits": image_memory_bits,
    "formation.snr_db": snr_db,
    "formation.dynamic_range_db": dynamic_range_db,
    "formation.bayer_mosaic": bayer_mosaic,
    "formation.demosaic_bilinear": demosaic_bilinear,
    "stereo.block_matching": block_matching,
}

EXTRA_ALTERNATIVES = {
    "stereo.block_matching": block_matching_windows,
}


def dense_disparity(left, right, max_disparity):
    """Chapter 2's measured exercise another way: each view standardised over 7×7 windows
    (local mean and standard deviation, which removes the cameras' gain and offset), SSD of the
    standardised images over 7×7 windows from integral images, winner-takes-all, then two passes
    of a 3×3 median instead of a left-right check."""
    L = np.asarray(left, dtype=np.float64)
    R = np.asarray(right, dtype=np.float64)
    height, width = L.shape
    b, r = 7, 3

    def box(a):
        c = np.zeros((a.shape[0] + 1, a.shape[1] + 1))
        c[1:, 1:] = np.cumsum(np.cumsum(a, axis=0), axis=1)
        return c[b:, b:] - c[:-b, b:] - c[b:, :-b] + c[:-b, :-b]

    def standardised(image):
        padded = np.pad(image, r, mode="reflect")
        mean = box(padded) / b ** 2
        spread = np.sqrt(np.maximum(box(padded ** 2) / b ** 2 - mean ** 2, 1e-12))
        return (image - mean) / spread

    Ls, Rs = np.pad(standardised(L), r, mode="reflect"), np.pad(standardised(R), r, mode="reflect")
    best = np.full((height, width), np.inf)
    disparity = np.zeros((height, width))
    for d in range(min(int(max_disparity), width - 1) + 1):
        cost = box((Ls[:, d:] - Rs[:, : Ls.shape[1] - d]) ** 2)
        better = cost < best[:, d:]
        best[:, d:] = np.where(better, cost, best[:, d:])
        disparity[:, d:] = np.where(better, d, disparity[:, d:])
    for _ in range(2):
        windows = np.lib.stride_tricks.sliding_window_view(np.pad(disparity, 1, mode="edge"), (3, 3))
        disparity = np.median(windows, axis=(-2, -1))
    return disparity
