"""Correct implementations of Chapter 5's algorithms, written differently from cvkit's reference.

They play the part of good students: a check must accept every one of them. Most loop over
pixels or keypoint samples (the way a first version looks); others use another formulation
(2-D Gaussian kernels instead of separable ones, the inverse of the Hessian instead of a solve,
eigenvalues for the edge test, a dictionary-based k-d tree split at the mean with a plane-distance
priority queue). None calls cvkit or a library that the guard forbids.
"""
from __future__ import annotations

import heapq
import math

import numpy as np

MODES = {"zero": "constant", "replicate": "edge", "reflect": "symmetric", "reflect101": "reflect"}


# --------------------------------------------------------------------------------------------
# filters written from scratch
# --------------------------------------------------------------------------------------------
def padded(image, r, border="reflect101"):
    return np.pad(np.asarray(image, dtype=np.float64), r, mode=MODES[border])


def correlate2d(image, kernel, border="reflect101"):
    """Correlation with a (2a+1)×(2b+1) kernel, one tap at a time."""
    k = np.asarray(kernel, dtype=np.float64)
    a, b = k.shape[0] // 2, k.shape[1] // 2
    p = np.pad(np.asarray(image, dtype=np.float64), ((a, a), (b, b)), mode=MODES[border])
    h, w = np.shape(image)
    out = np.zeros((h, w))
    for m in range(k.shape[0]):
        for n in range(k.shape[1]):
            out += k[m, n] * p[m:m + h, n:n + w]
    return out


def gaussian_2d(image, sigma):
    """Gaussian smoothing with the 2-D kernel (outer product of the normalised 1-D one)."""
    r = max(0, int(math.ceil(3 * sigma - 1e-9)))
    x = np.arange(-r, r + 1)
    g = np.exp(-x * x / (2 * sigma * sigma))
    g /= g.sum()
    return correlate2d(image, np.outer(g, g))


def sobel(image):
    kx = np.array([[-1.0, 0.0, 1.0], [-2.0, 0.0, 2.0], [-1.0, 0.0, 1.0]])
    return correlate2d(image, kx), correlate2d(image, kx.T)


# --------------------------------------------------------------------------------------------
# §5.6–5.7 corners
# --------------------------------------------------------------------------------------------
def moravec(image, window=7, border="reflect101"):
    """Pixel by pixel: the window SSD for each of the 8 shifts, the smallest kept."""
    img = np.asarray(image, dtype=np.float64)
    r = window // 2
    p = padded(img, r + 1, border)
    h, w = img.shape
    out = np.zeros((h, w))
    for i in range(h):
        for j in range(w):
            centre = p[i + 1: i + 2 * r + 2, j + 1: j + 2 * r + 2]
            ssd = []
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    if dy or dx:
                        moved = p[i + 1 + dy: i + 2 * r + 2 + dy, j + 1 + dx: j + 2 * r + 2 + dx]
                        ssd.append(float(((moved - centre) ** 2).sum()))
            out[i, j] = min(ssd)
    return out


def structure_tensor(image, sigma=1.0):
    ix, iy = sobel(image)
    return gaussian_2d(ix * ix, sigma), gaussian_2d(ix * iy, sigma), gaussian_2d(iy * iy, sigma)


def harris(image, k=0.04, sigma=1.0):
    a, b, c = structure_tensor(image, sigma)
    return (a * c - b * b) - k * (a + c) ** 2


def peaks(response, threshold, radius=1):
    """Every pixel against its clipped window, then a sort by (−value, row, col)."""
    r = np.asarray(response, dtype=np.float64)
    h, w = r.shape
    found = []
    for i in range(h):
        for j in range(w):
            v = r[i, j]
            if v > threshold and v >= r[max(0, i - radius): i + radius + 1, max(0, j - radius): j + radius + 1].max():
                found.append((-v, i, j))
    found.sort()
    return np.array([[j, i] for _, i, j in found], dtype=np.float64).reshape(-1, 2)


# --------------------------------------------------------------------------------------------
# §5.8–5.9 scale space
# --------------------------------------------------------------------------------------------
def upsample(img):
    """Every output pixel is the mean of the (up to) 4 input pixels around it."""
    h, w = img.shape
    i = np.arange(2 * h)
    j = np.arange(2 * w)
    i0, j0 = i // 2, j // 2
    i1, j1 = np.minimum(i0 + i % 2, h - 1), np.minimum(j0 + j % 2, w - 1)
    return 0.25 * (img[np.ix_(i0, j0)] + img[np.ix_(i0, j1)] + img[np.ix_(i1, j0)] + img[np.ix_(i1, j1)])


def gaussian_pyramid(image, sigma0=1.6, scales=3, octaves=4, upsample_=True, assumed_blur=0.5, **kwargs):
    up = kwargs.pop("upsample", upsample_)
    img = np.asarray(image, dtype=np.float64)
    b = 2 * assumed_blur if up else assumed_blur
    base = gaussian_2d(upsample(img) if up else img, math.sqrt(sigma0 ** 2 - b ** 2))
    out = []
    for o in range(octaves):
        levels = [base if o == 0 else out[-1][scales][::2, ::2]]
        for i in range(1, scales + 3):
            before, after = sigma0 * 2 ** ((i - 1) / scales), sigma0 * 2 ** (i / scales)
            levels.append(gaussian_2d(levels[-1], math.sqrt(after ** 2 - before ** 2)))
        out.append(np.array(levels))
    return out


def dog_pyramid(gaussian_pyramid):
    return [np.diff(np.asarray(octave, dtype=np.float64), axis=0) for octave in gaussian_pyramid]


def log_kernel(sigma):
    r = int(math.ceil(3 * sigma))
    y, x = np.mgrid[-r:r + 1, -r:r + 1].astype(np.float64)
    k = (x * x + y * y - 2 * sigma * sigma) / (2 * math.pi * sigma ** 6) * np.exp(-(x * x + y * y) / (2 * sigma * sigma))
    return k - k.mean()


def log_blobs(image, sigmas, threshold):
    stack = np.array([s * s * correlate2d(image, log_kernel(s)) for s in sigmas])
    n, h, w = stack.shape
    blobs = []
    for k in range(n):
        for i in range(h):
            for j in range(w):
                v = stack[k, i, j]
                if abs(v) <= threshold:
                    continue
                block = stack[max(0, k - 1): k + 2, max(0, i - 1): i + 2, max(0, j - 1): j + 2]
                others = np.sort(block.ravel())
                if (v == others[-1] and others[-2] < v) or (v == others[0] and others[1] > v):
                    blobs.append((j, i, sigmas[k]))
    return np.array(blobs, dtype=np.float64).reshape(-1, 3)


def dog_extrema(dog_pyramid, contrast_threshold=0.03):
    rows = []
    for o, stack in enumerate(dog_pyramid):
        d = np.asarray(stack, dtype=np.float64)
        for s in range(1, d.shape[0] - 1):
            for r in range(1, d.shape[1] - 1):
                for c in range(1, d.shape[2] - 1):
                    v = d[s, r, c]
                    if abs(v) <= contrast_threshold:
                        continue
                    block = d[s - 1:s + 2, r - 1:r + 2, c - 1:c + 2].ravel()
                    others = np.delete(block, 13)
                    if v > others.max() or v < others.min():
                        rows.append((o, s, r, c))
    return np.array(rows, dtype=np.int64).reshape(-1, 4)


def refine_extremum(dog_stack, scale, row, col):
    d = np.asarray(dog_stack, dtype=np.float64)
    s, r, c = scale, row, col
    if not all(0 < i < n - 1 for i, n in zip((s, r, c), d.shape)):
        raise ValueError("the sample must have a neighbour on every side")

    def D(ds, dr, dc):
        return d[s + ds, r + dr, c + dc]

    g = np.array([D(1, 0, 0) - D(-1, 0, 0), D(0, 1, 0) - D(0, -1, 0), D(0, 0, 1) - D(0, 0, -1)]) / 2
    axes = [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
    hessian = np.zeros((3, 3))
    for a in range(3):
        for b in range(3):
            if a == b:
                e = axes[a]
                hessian[a, a] = D(*e) + D(*(-x for x in e)) - 2 * D(0, 0, 0)
            else:
                ea, eb = np.array(axes[a]), np.array(axes[b])
                hessian[a, b] = (D(*(ea + eb)) - D(*(ea - eb)) - D(*(eb - ea)) + D(*(-ea - eb))) / 4
    offset = -np.linalg.inv(hessian) @ g
    return offset, float(D(0, 0, 0) + 0.5 * g.dot(offset))


def is_edge_like(dog_slice, row, col, r=10.0):
    """By the eigenvalues: a saddle, or a ratio of curvatures ≥ r."""
    d = np.asarray(dog_slice, dtype=np.float64)
    i, j = row, col
    dxx = d[i, j + 1] + d[i, j - 1] - 2 * d[i, j]
    dyy = d[i + 1, j] + d[i - 1, j] - 2 * d[i, j]
    dxy = (d[i + 1, j + 1] - d[i + 1, j - 1] - d[i - 1, j + 1] + d[i - 1, j - 1]) / 4
    small, large = sorted(np.linalg.eigvalsh(np.array([[dxx, dxy], [dxy, dyy]])), key=abs)
    if small * large <= 0:
        return True
    return bool(abs(large / small) >= r)


# --------------------------------------------------------------------------------------------
# §5.11–5.12 orientation and descriptor, pixel by pixel
# --------------------------------------------------------------------------------------------
def _gradient(L, r, c):
    dx = L[r, c + 1] - L[r, c - 1]
    dy = L[r + 1, c] - L[r - 1, c]
    return math.hypot(dx, dy), math.atan2(dy, dx)


def orientations(gaussian_image, x, y, sigma, bins=36, peak_ratio=0.8):
    L = np.asarray(gaussian_image, dtype=np.float64)
    h, w = L.shape
    hist = np.zeros(bins)
    radius = round(4.5 * sigma)
    cx, cy = round(x), round(y)
    for r in range(cy - radius, cy + radius + 1):
        for c in range(cx - radius, cx + radius + 1):
            if 1 <= r <= h - 2 and 1 <= c <= w - 2:
                m, theta = _gradient(L, r, c)
                weight = math.exp(-((c - x) ** 2 + (r - y) ** 2) / (2 * (1.5 * sigma) ** 2))
                hist[round(theta * bins / (2 * math.pi)) % bins] += m * weight
    top = hist.max()
    found = []
    for k in range(bins):
        left, right = hist[k - 1], hist[(k + 1) % bins]
        if top > 0 and hist[k] > left and hist[k] > right and hist[k] >= peak_ratio * top:
            offset = 0.5 * (left - right) / (left - 2 * hist[k] + right)
            found.append((-hist[k], k, ((k + offset) * 2 * math.pi / bins) % (2 * math.pi)))
    return np.array([a for _, _, a in sorted(found)])


def sift_descriptor(gaussian_image, x, y, sigma, angle):
    L = np.asarray(gaussian_image, dtype=np.float64)
    h, w = L.shape
    hist = np.zeros((4, 4, 8))
    radius = round(3 * sigma * math.sqrt(2) * 2.5)
    cx, cy = round(x), round(y)
    cos_a, sin_a = math.cos(angle), math.sin(angle)
    for r in range(max(1, cy - radius), min(h - 2, cy + radius) + 1):
        for c in range(max(1, cx - radius), min(w - 2, cx + radius) + 1):
            u = ((c - x) * cos_a + (r - y) * sin_a) / (3 * sigma)
            v = ((r - y) * cos_a - (c - x) * sin_a) / (3 * sigma)
            row_bin, col_bin = v + 1.5, u + 1.5
            if not (-1 < row_bin < 4 and -1 < col_bin < 4):
                continue
            m, theta = _gradient(L, r, c)
            m *= math.exp(-(u * u + v * v) / 8)
            o_bin = ((theta - angle) * 8 / (2 * math.pi)) % 8
            r0, c0, o0 = math.floor(row_bin), math.floor(col_bin), math.floor(o_bin)
            for dr in (0, 1):
                for dc in (0, 1):
                    for do in (0, 1):
                        rb, cb = r0 + dr, c0 + dc
                        if 0 <= rb < 4 and 0 <= cb < 4:
                            wr = row_bin - r0 if dr else 1 - (row_bin - r0)
                            wc = col_bin - c0 if dc else 1 - (col_bin - c0)
                            wo = o_bin - o0 if do else 1 - (o_bin - o0)
                            hist[rb, cb, (o0 + do) % 8] += m * wr * wc * wo
    vec = hist.ravel()
    n = np.linalg.norm(vec)
    if n == 0:
        return vec
    vec = np.minimum(vec / n, 0.2)
    return vec / np.linalg.norm(vec)


# --------------------------------------------------------------------------------------------
# §5.14.1 SIFT from the pieces above (vectorised enough to be quick on small images)
# --------------------------------------------------------------------------------------------
def _window(L, x, y, radius):
    """Rows, cols, magnitudes and directions of the pixels of the square about (round x, round y)."""
    L = np.asarray(L, dtype=np.float64)
    h, w = L.shape
    cx, cy = round(x), round(y)
    rr, cc = np.mgrid[max(1, cy - radius): min(h - 2, cy + radius) + 1, max(1, cx - radius): min(w - 2, cx + radius) + 1]
    rr, cc = rr.ravel(), cc.ravel()
    dx = L[rr, cc + 1] - L[rr, cc - 1]
    dy = L[rr + 1, cc] - L[rr - 1, cc]
    return rr, cc, np.hypot(dx, dy), np.arctan2(dy, dx)


def orientations_vectorised(L, x, y, sigma, bins=36, peak_ratio=0.8):
    rr, cc, m, theta = _window(L, x, y, round(4.5 * sigma))
    weight = m * np.exp(-((cc - x) ** 2 + (rr - y) ** 2) / (2 * (1.5 * sigma) ** 2))
    hist = np.zeros(bins)
    np.add.at(hist, np.rint(theta * bins / (2 * math.pi)).astype(int) % bins, weight)
    left, right = np.roll(hist, 1), np.roll(hist, -1)
    peaks_ = np.flatnonzero((hist > left) & (hist > right) & (hist >= peak_ratio * hist.max()) & (hist.max() > 0))
    peaks_ = peaks_[np.argsort(-hist[peaks_], kind="stable")]
    offset = 0.5 * (left[peaks_] - right[peaks_]) / (left[peaks_] - 2 * hist[peaks_] + right[peaks_])
    return ((peaks_ + offset) * 2 * math.pi / bins) % (2 * math.pi)


def descriptor_vectorised(L, x, y, sigma, angle):
    h, w = L.shape
    radius = min(round(3 * sigma * math.sqrt(2) * 2.5), int(math.ceil(math.hypot(h, w))))
    rr, cc, m, theta = _window(L, x, y, radius)
    u = ((cc - x) * math.cos(angle) + (rr - y) * math.sin(angle)) / (3 * sigma)
    v = ((rr - y) * math.cos(angle) - (cc - x) * math.sin(angle)) / (3 * sigma)
    rb, cb = v + 1.5, u + 1.5
    ok = (rb > -1) & (rb < 4) & (cb > -1) & (cb < 4)
    rb, cb, u, v, m, theta = rb[ok], cb[ok], u[ok], v[ok], m[ok], theta[ok]
    m = m * np.exp(-(u * u + v * v) / 8)
    ob = ((theta - angle) * 8 / (2 * math.pi)) % 8
    hist = np.zeros((6, 6, 9))
    r0, c0, o0 = np.floor(rb), np.floor(cb), np.floor(ob)
    for dr in (0, 1):
        for dc in (0, 1):
            for do in (0, 1):
                wgt = m * np.abs(1 - dr - (rb - r0)) * np.abs(1 - dc - (cb - c0)) * np.abs(1 - do - (ob - o0))
                np.add.at(hist, ((r0 + 1 + dr).astype(int), (c0 + 1 + dc).astype(int), (o0 + do).astype(int) % 9), wgt)
    hist[..., 0] += hist[..., 8]
    vec = hist[1:5, 1:5, :8].ravel()
    n = np.linalg.norm(vec)
    if n == 0:
        return vec
    vec = np.minimum(vec / n, 0.2)
    return vec / np.linalg.norm(vec)


def _fast_dog_extrema(dog, threshold):
    rows = []
    for o, d in enumerate(dog):
        if d.shape[1] < 3 or d.shape[2] < 3:
            continue
        inner = d[1:-1, 1:-1, 1:-1]
        shifted = [d[1 + a:d.shape[0] - 1 + a, 1 + b:d.shape[1] - 1 + b, 1 + c:d.shape[2] - 1 + c]
                   for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1) if a or b or c]
        big = np.all([inner > s for s in shifted], axis=0)
        small = np.all([inner < s for s in shifted], axis=0)
        s, r, c = np.nonzero((big | small) & (np.abs(inner) > threshold))
        rows += [(o, a + 1, b + 1, e + 1) for a, b, e in zip(s, r, c)]
    return sorted(rows)


def sift(image, sigma0=1.6, scales=3, octaves=None, upsample=True, contrast_threshold=0.04, edge_ratio=10.0,
         assumed_blur=0.5, border=5, max_steps=5):
    img = np.asarray(image, dtype=np.float64)
    if octaves is None:
        side = min(img.shape) * (2 if upsample else 1)
        octaves = max(1, int(math.floor(math.log2(side / 8))) + 1) if side >= 8 else 1
    pyramid = gaussian_pyramid(img, sigma0, scales, octaves, upsample=upsample, assumed_blur=assumed_blur)
    dog = dog_pyramid(pyramid)
    final = {}
    for o, s, r, c in _fast_dog_extrema(dog, 0.5 * contrast_threshold / scales):
        h, w = dog[o].shape[1:]
        if not (border <= r < h - border and border <= c < w - border):
            continue
        for _ in range(max_steps):
            try:
                offset, value = refine_extremum(dog[o], s, r, c)
            except np.linalg.LinAlgError:
                break
            if np.all(np.abs(offset) < 0.6):
                final.setdefault((o, s, r, c), (offset, value))
                break
            s, r, c = s + int(np.rint(offset[0])), r + int(np.rint(offset[1])), c + int(np.rint(offset[2]))
            if not (1 <= s <= scales and border <= r < h - border and border <= c < w - border):
                break
    keypoints, descriptors = [], []
    for (o, s, r, c), (offset, value) in sorted(final.items()):
        if abs(value) * scales < contrast_threshold or is_edge_like(dog[o][s], r, c, edge_ratio):
            continue
        x, y, sig = c + offset[2], r + offset[1], sigma0 * 2 ** ((s + offset[0]) / scales)
        f = 2 ** o / (2 if upsample else 1)
        for a in orientations_vectorised(pyramid[o][s], x, y, sig):
            keypoints.append((x * f, y * f, sig * f, a))
            descriptors.append(descriptor_vectorised(pyramid[o][s], x, y, sig, a))
    return np.array(keypoints, dtype=np.float64).reshape(-1, 4), np.array(descriptors, dtype=np.float64).reshape(-1, 128)


# --------------------------------------------------------------------------------------------
# §5.13–5.14 matching
# --------------------------------------------------------------------------------------------
def match_ratio(desc1, desc2, ratio=0.8):
    a = np.asarray(desc1, dtype=np.float64)
    b = np.asarray(desc2, dtype=np.float64)
    if len(b) < 2:
        raise ValueError("desc2 needs two rows for a ratio")
    pairs = []
    for i, q in enumerate(a):
        d = np.sqrt(((b - q) ** 2).sum(axis=1))
        order = np.argsort(d, kind="stable")
        d1, d2 = d[order[0]], d[order[1]]
        if d2 > 0 and d1 <= ratio * d2:
            pairs.append((i, int(order[0])))
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


class KDTree:
    """Nodes as dicts; split at the mean of the widest coordinate; leaves of up to 3 points;
    BBF with Lowe's priority: the squared distance to the splitting plane, accumulated."""

    def __init__(self, points):
        self.points = np.array(points, dtype=np.float64)
        self.root = self._build(list(range(len(self.points))))

    def _build(self, idx):
        pts = self.points[idx]
        spread = pts.max(axis=0) - pts.min(axis=0)
        if len(idx) <= 3 or spread.max() == 0:
            return {"leaf": idx}
        axis = int(np.argmax(spread))
        split = float(pts[:, axis].mean())
        left = [i for i in idx if self.points[i, axis] < split]
        right = [i for i in idx if self.points[i, axis] >= split]
        if not left or not right:
            return {"leaf": idx}
        return {"axis": axis, "split": split, "left": self._build(left), "right": self._build(right)}

    def _consider(self, best, q, idx, k):
        for i in idx:
            d = float(np.sqrt(((self.points[i] - q) ** 2).sum()))
            best.append((d, i))
        best.sort()
        del best[k:]

    def _search(self, node, q, k, best):
        if "leaf" in node:
            self._consider(best, q, node["leaf"], k)
            return
        gap = q[node["axis"]] - node["split"]
        near, far = (node["left"], node["right"]) if gap < 0 else (node["right"], node["left"])
        self._search(near, q, k, best)
        if len(best) < k or abs(gap) <= best[-1][0]:
            self._search(far, q, k, best)

    def _shape(self, q, rows):
        d = np.array([[b[0] for b in r] for r in rows])
        i = np.array([[b[1] for b in r] for r in rows], dtype=np.int64)
        return (d[0], i[0]) if np.ndim(q) == 1 else (d, i)

    def query(self, q, k=1):
        rows = []
        for row in np.atleast_2d(np.asarray(q, dtype=np.float64)):
            best = []
            self._search(self.root, row, k, best)
            rows.append(best)
        return self._shape(q, rows)

    def query_bbf(self, q, k=2, max_checks=200):
        rows = []
        for row in np.atleast_2d(np.asarray(q, dtype=np.float64)):
            best, checks, tie = [], 0, 0
            queue = [(0.0, tie, self.root)]
            while queue and checks < max_checks:
                bound, _, node = heapq.heappop(queue)
                if len(best) == k and bound > best[-1][0] ** 2:
                    break
                while "leaf" not in node:
                    gap = row[node["axis"]] - node["split"]
                    near, far = (node["left"], node["right"]) if gap < 0 else (node["right"], node["left"])
                    tie += 1
                    heapq.heappush(queue, (bound + gap * gap, tie, far))
                    node = near
                take = node["leaf"][: max_checks - checks]
                checks += len(take)
                self._consider(best, row, take, k)
            rows.append(best)
        return self._shape(q, rows)


ALTERNATIVES = {
    "features.moravec": moravec,
    "features.structure_tensor": structure_tensor,
    "features.harris": harris,
    "features.peaks": peaks,
    "features.gaussian_pyramid": gaussian_pyramid,
    "features.dog_pyramid": dog_pyramid,
    "features.log_blobs": log_blobs,
    "features.dog_extrema": dog_extrema,
    "features.refine_extremum": refine_extremum,
    "features.is_edge_like": is_edge_like,
    "features.orientations": orientations,
    "features.sift_descriptor": sift_descriptor,
    "features.sift": sift,
    "features.match_ratio": match_ratio,
    "features.KDTree": KDTree,
}


def match_features(image1, image2):
    """Chapter 5's measured exercise another way: SIFT from cvkit (the check serves it), then for
    every descriptor of image 1 its two nearest of image 2 by sorting the distances row by row,
    the ratio test at 0.75, and a cross-check that the match's own nearest neighbour in image 1
    is the point it came from."""
    from cvkit.features import sift

    keys1, desc1 = sift(np.asarray(image1, dtype=np.float64))
    keys2, desc2 = sift(np.asarray(image2, dtype=np.float64))
    points1, points2 = [], []
    if len(desc1) == 0 or len(desc2) < 2:
        return np.zeros((0, 2)), np.zeros((0, 2))
    for i, d in enumerate(desc1):
        distances = np.sqrt(((desc2 - d) ** 2).sum(axis=1))
        first, second = np.argsort(distances, kind="stable")[:2]
        if distances[first] > 0.75 * distances[second]:
            continue
        back = np.argmin(np.sqrt(((desc1 - desc2[first]) ** 2).sum(axis=1)))
        if back == i:
            points1.append(keys1[i, :2])
            points2.append(keys2[first, :2])
    return np.array(points1).reshape(-1, 2), np.array(points2).reshape(-1, 2)
