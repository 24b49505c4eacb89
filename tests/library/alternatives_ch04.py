"""Correct implementations of Chapter 4's algorithms, written differently from cvkit's reference.

They play the part of good students: a check must accept every one of them. Most loop over
pixels (the way a first version looks); others use another formulation (complex numbers for
the direction, the FFT for the LoG, a 2-D Gaussian kernel, a breadth-first flood fill for the
hysteresis, scikit-image's branch structure for the NMS). None calls cvkit or a library that
the guard forbids.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np


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
    if border == "reflect":
        m = k % (2 * n)
        return m if m < n else 2 * n - 1 - m
    if n == 1:
        return 0
    m = k % (2 * (n - 1))
    return m if m < n else 2 * (n - 1) - m


def read(image: np.ndarray, r: int, c: int, border: str) -> float:
    i = source_index(r, image.shape[0], border)
    j = source_index(c, image.shape[1], border)
    return 0.0 if i is None or j is None else float(image[i, j])


def correlate_loops(image, kernel, border):
    """Correlation, kernel centred, one pixel at a time."""
    img = np.asarray(image, dtype=np.float64)
    k = np.asarray(kernel, dtype=np.float64)
    kh, kw = k.shape
    a, b = kh // 2, kw // 2
    h, w = img.shape
    out = np.zeros((h, w))
    for r in range(h):
        for c in range(w):
            total = 0.0
            for m in range(kh):
                for n in range(kw):
                    if k[m, n] != 0.0:
                        total += k[m, n] * read(img, r + m - a, c + n - b, border)
            out[r, c] = total
    return out


# --------------------------------------------------------------------------------------------
# first derivatives
# --------------------------------------------------------------------------------------------
def gradient(image, scheme="central", border="reflect101"):
    img = np.asarray(image, dtype=np.float64)
    h, w = img.shape
    ix, iy = np.zeros((h, w)), np.zeros((h, w))
    for r in range(h):
        for c in range(w):
            if scheme == "central":
                ix[r, c] = (read(img, r, c + 1, border) - read(img, r, c - 1, border)) / 2
                iy[r, c] = (read(img, r + 1, c, border) - read(img, r - 1, c, border)) / 2
            elif scheme == "forward":
                ix[r, c] = read(img, r, c + 1, border) - img[r, c]
                iy[r, c] = read(img, r + 1, c, border) - img[r, c]
            else:
                ix[r, c] = img[r, c] - read(img, r, c - 1, border)
                iy[r, c] = img[r, c] - read(img, r - 1, c, border)
    return ix, iy


def magnitude(ix, iy, norm="l2"):
    stacked = np.stack([np.asarray(ix, dtype=np.float64), np.asarray(iy, dtype=np.float64)])
    order = {"l2": 2, "l1": 1, "max": np.inf}[norm]
    return np.linalg.norm(stacked, ord=order, axis=0)


def direction(ix, iy):
    return np.angle(np.asarray(ix, dtype=np.float64) + 1j * np.asarray(iy, dtype=np.float64))


PREWITT_X = np.array([[-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]])
SOBEL_X = np.array([[-1.0, 0.0, 1.0], [-2.0, 0.0, 2.0], [-1.0, 0.0, 1.0]])


def prewitt(image, border="reflect101"):
    return correlate_loops(image, PREWITT_X, border), correlate_loops(image, PREWITT_X.T, border)


def sobel(image, border="reflect101"):
    return correlate_loops(image, SOBEL_X, border), correlate_loops(image, SOBEL_X.T, border)


# --------------------------------------------------------------------------------------------
# second derivatives
# --------------------------------------------------------------------------------------------
def laplacian(image, border="reflect101"):
    img = np.asarray(image, dtype=np.float64)
    h, w = img.shape
    out = np.empty((h, w))
    for r in range(h):
        for c in range(w):
            out[r, c] = (read(img, r - 1, c, border) + read(img, r + 1, c, border)
                         + read(img, r, c - 1, border) + read(img, r, c + 1, border) - 4 * img[r, c])
    return out


def log_kernel(sigma, radius=None):
    if radius is None:
        radius = math.ceil(3 * sigma - 1e-9)
    values = {}
    for y in range(-radius, radius + 1):
        for x in range(-radius, radius + 1):
            q = (x * x + y * y) / (2 * sigma * sigma)
            values[y, x] = (q - 1) / (math.pi * sigma ** 4) * math.exp(-q)  # the same formula, rearranged
    mean = math.fsum(values.values()) / len(values)
    size = 2 * radius + 1
    return np.array([[values[y, x] - mean for x in range(-radius, radius + 1)] for y in range(-radius, radius + 1)]).reshape(size, size)


def _pad_sides(image, ry, rx, border):
    img = np.asarray(image, dtype=np.float64)
    h, w = img.shape
    out = np.zeros((h + 2 * ry, w + 2 * rx))
    for i in range(-ry, h + ry):
        for j in range(-rx, w + rx):
            out[i + ry, j + rx] = read(img, i, j, border)
    return out


def log(image, sigma, border="reflect101"):
    """Through NumPy's FFT: correlation with the (symmetric) LoG kernel."""
    k = log_kernel(sigma)
    r = k.shape[0] // 2
    padded = _pad_sides(image, r, r, border)
    hp, wp = padded.shape
    shape = (hp + 2 * r, wp + 2 * r)
    full = np.fft.irfft2(np.fft.rfft2(padded, shape) * np.fft.rfft2(k[::-1, ::-1], shape), shape)
    h, w = np.shape(image)
    return full[2 * r: 2 * r + h, 2 * r: 2 * r + w]


def _gaussian_2d(image, sigma, border):
    radius = math.ceil(3 * sigma - 1e-9)
    x = np.arange(-radius, radius + 1)
    g = np.exp(-(x[:, None] ** 2 + x[None, :] ** 2) / (2 * sigma * sigma))
    g /= g.sum()
    padded = _pad_sides(image, radius, radius, border)
    h, w = np.shape(image)
    out = np.zeros((h, w))
    for m in range(2 * radius + 1):
        for n in range(2 * radius + 1):
            out += g[m, n] * padded[m: m + h, n: n + w]
    return out


def dog(image, sigma, k=1.6, border="reflect101"):
    return _gaussian_2d(image, k * sigma, border) - _gaussian_2d(image, sigma, border)


def zero_crossings(response, threshold=0.0):
    r = np.asarray(response, dtype=np.float64)
    h, w = r.shape
    out = np.zeros((h, w), dtype=bool)
    for i in range(h):
        for j in range(w):
            for di, dj in ((0, 1), (1, 0)):
                k, l = i + di, j + dj
                if k >= h or l >= w:
                    continue
                a, b = r[i, j], r[k, l]
                if (a > 0 > b or a < 0 < b) and abs(a - b) > threshold:
                    if abs(a) <= abs(b):
                        out[i, j] = True
                    else:
                        out[k, l] = True
    return out


# --------------------------------------------------------------------------------------------
# NMS, hysteresis, Canny
# --------------------------------------------------------------------------------------------
def non_max_suppression(magnitude, ix, iy, interpolate=True):
    """scikit-image's branch structure, one pixel at a time; outside the image counts as 0."""
    m = np.asarray(magnitude, dtype=np.float64)
    gx = np.asarray(ix, dtype=np.float64)
    gy = np.asarray(iy, dtype=np.float64)
    h, w = m.shape

    def at(r, c):
        return m[r, c] if 0 <= r < h and 0 <= c < w else 0.0

    out = np.zeros((h, w))
    tan = math.tan(math.radians(22.5))
    for x in range(h):
        for y in range(w):
            value = m[x, y]
            i, j = gy[x, y], gx[x, y]
            if value <= 0 or (interpolate and i == 0 and j == 0):  # atan2(0, 0) = 0 without
                continue
            if not interpolate:
                ai, aj = abs(i), abs(j)
                if ai <= tan * aj:
                    n1, n2 = at(x, y + 1), at(x, y - 1)
                elif aj <= tan * ai:
                    n1, n2 = at(x + 1, y), at(x - 1, y)
                elif (i > 0) == (j > 0):
                    n1, n2 = at(x + 1, y + 1), at(x - 1, y - 1)
                else:
                    n1, n2 = at(x + 1, y - 1), at(x - 1, y + 1)
                if value >= n1 and value >= n2:
                    out[x, y] = value
                continue
            up, right = i > 0, j > 0
            ai, aj = abs(i), abs(j)
            if up == right:
                if ai > aj:
                    wt = aj / ai
                    a1, d1, a2, d2 = at(x + 1, y), at(x + 1, y + 1), at(x - 1, y), at(x - 1, y - 1)
                else:
                    wt = ai / aj
                    a1, d1, a2, d2 = at(x, y + 1), at(x + 1, y + 1), at(x, y - 1), at(x - 1, y - 1)
            else:
                if ai < aj:
                    wt = ai / aj
                    a1, d1, a2, d2 = at(x, y + 1), at(x - 1, y + 1), at(x, y - 1), at(x + 1, y - 1)
                else:
                    wt = aj / ai
                    a1, d1, a2, d2 = at(x - 1, y), at(x - 1, y + 1), at(x + 1, y), at(x + 1, y - 1)
            if d1 * wt + a1 * (1 - wt) <= value and d2 * wt + a2 * (1 - wt) <= value:
                out[x, y] = value
    return out


def hysteresis(magnitude, low, high):
    """Breadth-first flood fill from every strong pixel through 8-neighbours above low."""
    if low > high:
        raise ValueError("low must not exceed high")
    m = np.asarray(magnitude, dtype=np.float64)
    h, w = m.shape
    out = np.zeros((h, w), dtype=bool)
    queue = deque()
    for r in range(h):
        for c in range(w):
            if m[r, c] > high:
                out[r, c] = True
                queue.append((r, c))
    while queue:
        r, c = queue.popleft()
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                rr, cc = r + dr, c + dc
                if 0 <= rr < h and 0 <= cc < w and not out[rr, cc] and m[rr, cc] > low:
                    out[rr, cc] = True
                    queue.append((rr, cc))
    return out


def canny(image, sigma=1.4, low=0.1, high=0.2, relative=True):
    img = np.asarray(image, dtype=np.float64)
    smooth = _gaussian_2d(img, sigma, "reflect101")
    gx, gy = sobel(smooth)
    strength = np.sqrt(gx ** 2 + gy ** 2)
    top = strength.max()
    if top <= 1e-12 * max(1.0, np.abs(img).max()):
        return np.zeros(img.shape, dtype=bool)
    if relative:
        low, high = low * top, high * top
    return hysteresis(non_max_suppression(strength, gx, gy), low, high)


def detect_outlines(image):
    """The measured exercise, tuned another way: σ = 1.4 and *relative* thresholds 0.25 / 0.5
    of the largest gradient (a setting found by trying a grid on the visible picture), on the
    loop-built Canny above."""
    return canny(image, 1.4, 0.25, 0.5)


ALTERNATIVES = {
    "edges.gradient": gradient,
    "edges.magnitude": magnitude,
    "edges.direction": direction,
    "edges.prewitt": prewitt,
    "edges.sobel": sobel,
    "edges.non_max_suppression": non_max_suppression,
    "edges.hysteresis": hysteresis,
    "edges.canny": canny,
    "edges.laplacian": laplacian,
    "edges.log_kernel": log_kernel,
    "edges.log": log,
    "edges.zero_crossings": zero_crossings,
    "edges.dog": dog,
}
