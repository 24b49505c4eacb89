"""Correct implementations of Chapter 6's algorithms, written differently from cvkit's reference.

They play the part of good students: a check must accept every one of them. Most loop over
placements or pixels (the way a first version looks); others use another formulation (a
masked-argmax loop for the Hough peaks, np.add.at and complex numbers for the GHT). The only
cvkit function any of them calls is ``edges.canny`` in ``ght_detect``, which that exercise
allows.
"""
from __future__ import annotations

import math

import numpy as np


def sobel(image):
    """Sobel by explicit loops over the 3×3 taps, reflect101 border."""
    img = np.asarray(image, dtype=np.float64)
    p = np.pad(img, 1, mode="reflect")          # NumPy's "reflect" is reflect101
    kx = np.array([[-1.0, 0.0, 1.0], [-2.0, 0.0, 2.0], [-1.0, 0.0, 1.0]])
    h, w = img.shape
    gx = np.zeros((h, w))
    gy = np.zeros((h, w))
    for m in range(3):
        for n in range(3):
            gx += kx[m, n] * p[m:m + h, n:n + w]
            gy += kx.T[m, n] * p[m:m + h, n:n + w]
    return gx, gy


# --------------------------------------------------------------------------------------------
# template matching
# --------------------------------------------------------------------------------------------
def match_template(image, template, measure="zncc"):
    """One window at a time, with NumPy's var/mean/norm."""
    img = np.asarray(image, dtype=np.float64)
    t = np.asarray(template, dtype=np.float64)
    h, w = t.shape
    H, W = img.shape
    out = np.zeros((H - h + 1, W - w + 1))
    image_ms = np.mean(img ** 2)
    t_norm = np.linalg.norm(t)
    t_zero = t - t.mean()
    t_flat = np.var(t) <= 1e-12 * np.mean(t ** 2)
    for i in range(H - h + 1):
        for j in range(W - w + 1):
            win = img[i:i + h, j:j + w]
            if measure == "ssd":
                out[i, j] = np.sum((win - t) ** 2)
            elif measure == "sad":
                out[i, j] = np.sum(np.abs(win - t))
            elif measure == "ncc":
                if np.mean(win ** 2) <= 1e-12 * image_ms or np.mean(t ** 2) <= 1e-12 * image_ms:
                    continue
                out[i, j] = np.sum(win * t) / (np.linalg.norm(win) * t_norm)
            else:
                if t_flat or np.var(win) <= 1e-12 * np.mean(win ** 2):
                    continue
                wz = win - win.mean()
                out[i, j] = np.sum(wz * t_zero) / math.sqrt(np.sum(wz ** 2) * np.sum(t_zero ** 2))
    return out


def best_match(scores, measure):
    s = np.asarray(scores, dtype=np.float64)
    best = None
    for y in range(s.shape[0]):
        for x in range(s.shape[1]):
            v = s[y, x]
            if best is None or (v < best[0] if measure in ("ssd", "sad") else v > best[0]):
                best = (v, x, y)
    return best[1], best[2]


# --------------------------------------------------------------------------------------------
# shape-based matching
# --------------------------------------------------------------------------------------------
def shape_model(template, threshold):
    gx, gy = sobel(template)
    points, directions = [], []
    for y in range(gx.shape[0]):
        for x in range(gx.shape[1]):
            m = math.hypot(gx[y, x], gy[y, x])
            if m > threshold:
                points.append((x, y))
                directions.append((gx[y, x] / m, gy[y, x] / m))
    if not points:
        raise ValueError("no control point above the threshold")
    # listed column by column (another order than the reference's)
    order = sorted(range(len(points)), key=lambda k: (points[k][0], points[k][1]))
    return {"points": np.array([points[k] for k in order], dtype=float),
            "directions": np.array([directions[k] for k in order]),
            "shape": tuple(np.shape(template))}


def shape_match(image, model, polarity="none"):
    gx, gy = sobel(image)
    mag = np.hypot(gx, gy)
    no_gradient = 1e-10 * np.abs(np.asarray(image, dtype=float)).max()
    h, w = model["shape"]
    H, W = gx.shape
    out = np.zeros((H - h + 1, W - w + 1))
    pts = np.asarray(model["points"]).astype(int)
    dirs = np.asarray(model["directions"], dtype=float)
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            cosines = []
            for (x, y), (dx, dy) in zip(pts, dirs):
                m = mag[i + y, j + x]
                cosines.append(0.0 if m <= no_gradient else (dx * gx[i + y, j + x] + dy * gy[i + y, j + x]) / m)
            c = np.array(cosines)
            if polarity == "global":
                out[i, j] = abs(c.sum()) / len(c)
            elif polarity == "local":
                out[i, j] = np.abs(c).sum() / len(c)
            else:
                out[i, j] = c.mean()
    return out


# --------------------------------------------------------------------------------------------
# Hough transform for lines
# --------------------------------------------------------------------------------------------
def hough_lines(edges, theta_step=math.pi / 180, rho_step=1.0):
    e = np.asarray(edges)
    n_theta = int(math.ceil(math.pi / theta_step - 1e-9))
    thetas = np.array([-math.pi / 2 + k * theta_step for k in range(n_theta)])
    k_max = int(math.ceil(math.hypot(e.shape[0], e.shape[1]) / rho_step - 1e-9))
    rhos = np.array([k * rho_step for k in range(-k_max, k_max + 1)])
    acc = np.zeros((rhos.size, thetas.size), dtype=np.int64)
    cos, sin = np.cos(thetas), np.sin(thetas)
    for y, x in zip(*np.nonzero(e)):
        for k in range(n_theta):
            rho = x * cos[k] + y * sin[k]
            acc[int(math.floor(rho / rho_step + 0.5)) + k_max, k] += 1
    return acc, thetas, rhos


def hough_peaks(accumulator, thetas, rhos, count=10, threshold=None, min_distance=5):
    """Repeated masked argmax (np.argmax takes the first maximum: raster order on ties)."""
    acc = np.asarray(accumulator, dtype=np.float64).copy()
    if threshold is None:
        threshold = 0.5 * acc.max()
    peaks = []
    while len(peaks) < count:
        r, t = np.unravel_index(int(np.argmax(acc)), acc.shape)
        v = acc[r, t]
        if not (v >= threshold and v > 0):
            break
        peaks.append((float(rhos[r]), float(thetas[t])))
        acc[max(0, r - min_distance):r + min_distance + 1, max(0, t - min_distance):t + min_distance + 1] = -np.inf
    return np.array(peaks, dtype=float).reshape(-1, 2)


# --------------------------------------------------------------------------------------------
# Generalized Hough Transform
# --------------------------------------------------------------------------------------------
def ght_build(template_edges, template_image, bins=36, reference=None):
    gx, gy = sobel(template_image)
    ys, xs = np.nonzero(np.asarray(template_edges))
    if reference is None:
        reference = (xs.mean(), ys.mean())
    table = [[] for _ in range(bins)]
    step = 2 * math.pi / bins
    for x, y in zip(xs, ys):
        k = int(np.round(math.atan2(gy[y, x], gx[y, x]) / step)) % bins
        table[k].append((reference[0] - x, reference[1] - y))
    return {"bins": bins, "reference": (float(reference[0]), float(reference[1])),
            "table": [np.array(t, dtype=float).reshape(-1, 2) for t in table]}


def ght_detect(image, rtable, scales=(1.0,), angles=(0.0,), edge_params=None):
    """Complex numbers for the rotation, np.add.at for the votes, one loop over edge pixels."""
    from cvkit import edges  # allowed building block

    img = np.asarray(image, dtype=np.float64)
    edge_map = edges.canny(img, **(edge_params or {}))
    gx, gy = sobel(img)
    H, W = img.shape
    bins = rtable["bins"]
    step = 2 * math.pi / bins
    vectors = [np.asarray(t, dtype=float).reshape(-1, 2) for t in rtable["table"]]
    acc = np.zeros((len(scales), len(angles), H, W))
    for y, x in zip(*np.nonzero(edge_map)):
        phi = math.atan2(gy[y, x], gx[y, x])
        for j, a in enumerate(angles):
            r = vectors[int(np.round((phi - a) / step)) % bins]
            if len(r) == 0:
                continue
            turned = (r[:, 0] * math.cos(a) - r[:, 1] * math.sin(a)) + 1j * (r[:, 0] * math.sin(a) + r[:, 1] * math.cos(a))
            for i, s in enumerate(scales):
                vx = np.round(x + s * turned.real).astype(int)
                vy = np.round(y + s * turned.imag).astype(int)
                ok = (vx >= 0) & (vx < W) & (vy >= 0) & (vy < H)
                np.add.at(acc[i, j], (vy[ok], vx[ok]), 1.0)
    i, j, y, x = np.unravel_index(int(np.argmax(acc)), acc.shape)
    return acc, (int(x), int(y), float(scales[i]), float(angles[j]))


def find_lines(edges):
    """The measured exercise another way: θ over [0, π) (ρ of either sign), votes cast with
    ``np.add.at`` pixel by pixel, peaks above 45 % of the strongest, each clearing a window of
    ±8 bins before the next is taken."""
    ys, xs = np.nonzero(np.asarray(edges, dtype=bool))
    thetas = np.arange(180) * math.pi / 180
    reach = int(math.ceil(math.hypot(*np.shape(edges))))
    acc = np.zeros((2 * reach + 1, len(thetas)))
    for x, y in zip(xs, ys):
        rho = np.floor(x * np.cos(thetas) + y * np.sin(thetas) + 0.5).astype(int)
        np.add.at(acc, (rho + reach, np.arange(len(thetas))), 1)
    lines = []
    floor = 0.45 * acc.max()
    while True:
        r, t = np.unravel_index(np.argmax(acc), acc.shape)
        if acc[r, t] < floor or acc[r, t] <= 0:
            break
        lines.append((r - reach, thetas[t]))
        acc[max(0, r - 8):r + 9, max(0, t - 8):t + 9] = 0
    return np.array(lines, dtype=float).reshape(-1, 2)


ALTERNATIVES = {
    "detection.match_template": match_template,
    "detection.best_match": best_match,
    "detection.shape_model": shape_model,
    "detection.shape_match": shape_match,
    "detection.hough_lines": hough_lines,
    "detection.hough_peaks": hough_peaks,
    "detection.ght_build": ght_build,
    "detection.ght_detect": ght_detect,
}
