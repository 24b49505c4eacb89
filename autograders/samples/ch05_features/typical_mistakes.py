# Answer cells of the "typical mistakes" sample submission of ch05_features.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution, so the feedback shows what the checks recognise -- and how a wrong building block
# also sinks the exercise that uses it (the 8-neighbour extrema and the hard-binned descriptor
# change the keypoints and descriptors of `sift`).
# This file is data for the demo and its tests, not a module to import.

# %% harris_answer
@student("features.harris")
def harris(image, k=0.04, sigma=1.0):
    """Harris response -- with the trace not squared."""
    mxx, mxy, myy = structure_tensor(image, sigma)
    return mxx * myy - mxy * mxy - k * (mxx + myy)

# %% peaks_answer
@student("features.peaks")
def peaks(response, threshold, radius=1):
    """Local maxima -- strictly greater than every neighbour, so plateaus vanish."""
    r = np.asarray(response, dtype=float)
    h, w = r.shape
    p = np.pad(r, radius, mode="constant", constant_values=-np.inf)
    keep = r > threshold
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dy or dx:
                keep &= r > p[radius + dy:radius + dy + h, radius + dx:radius + dx + w]
    rows, cols = np.nonzero(keep)
    order = np.argsort(-r[rows, cols], kind="stable")
    return np.column_stack([cols[order], rows[order]]).astype(float).reshape(-1, 2)

# %% dog_extrema_answer
@student("features.dog_extrema")
def dog_extrema(dog_pyramid, contrast_threshold=0.03):
    """Extrema of each DoG level -- compared with the 8 neighbours of the same level only."""
    found = []
    for o, octave in enumerate(dog_pyramid):
        d = np.asarray(octave, dtype=float)
        n, h, w = d.shape
        if n < 3 or h < 3 or w < 3:
            continue
        c = d[1:-1, 1:-1, 1:-1]
        big = np.abs(c) > contrast_threshold
        small = big.copy()
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                if dr or dc:
                    other = d[1:-1, 1 + dr:h - 1 + dr, 1 + dc:w - 1 + dc]
                    big &= c > other
                    small &= c < other
        s, r, cc = np.nonzero(big | small)
        found.append(np.column_stack([np.full(s.size, o), s + 1, r + 1, cc + 1]))
    return np.vstack(found).astype(np.int64) if found else np.zeros((0, 4), dtype=np.int64)

# %% sift_descriptor_answer
@student("features.sift_descriptor")
def sift_descriptor(gaussian_image, x, y, sigma, angle):
    """SIFT descriptor -- every sample votes whole into its nearest cell and bin (no interpolation)."""
    L = np.asarray(gaussian_image, dtype=float)
    h, w = L.shape
    R = min(int(np.rint(3 * sigma * np.sqrt(2) * 2.5)), int(np.ceil(np.hypot(h, w))))
    cx, cy = int(np.rint(x)), int(np.rint(y))
    rr, cc = np.mgrid[max(1, cy - R):min(h - 2, cy + R) + 1, max(1, cx - R):min(w - 2, cx + R) + 1]
    rr, cc = rr.ravel(), cc.ravel()
    u = ((cc - x) * np.cos(angle) + (rr - y) * np.sin(angle)) / (3 * sigma)
    v = ((rr - y) * np.cos(angle) - (cc - x) * np.sin(angle)) / (3 * sigma)
    row, col = v + 1.5, u + 1.5
    ok = (row > -1) & (row < 4) & (col > -1) & (col < 4)
    rr, cc, u, v, row, col = rr[ok], cc[ok], u[ok], v[ok], row[ok], col[ok]
    dx = L[rr, cc + 1] - L[rr, cc - 1]
    dy = L[rr + 1, cc] - L[rr - 1, cc]
    m = np.sqrt(dx ** 2 + dy ** 2) * np.exp(-(u ** 2 + v ** 2) / 8)
    o = np.mod((np.arctan2(dy, dx) - angle) * 8 / (2 * np.pi), 8)
    r0 = np.rint(row).astype(int)
    c0 = np.rint(col).astype(int)
    o0 = np.rint(o).astype(int) % 8
    inside = (r0 >= 0) & (r0 < 4) & (c0 >= 0) & (c0 < 4)
    hist = np.zeros((4, 4, 8))
    np.add.at(hist, (r0[inside], c0[inside], o0[inside]), m[inside])
    vec = hist.ravel()
    if np.linalg.norm(vec) == 0:
        return vec
    vec = np.minimum(vec / np.linalg.norm(vec), 0.2)
    return vec / np.linalg.norm(vec)

# %% match_ratio_answer
@student("features.match_ratio")
def match_ratio(desc1, desc2, ratio=0.8):
    """Ratio test -- on squared distances (no square root needed, or so it seems)."""
    a = np.asarray(desc1, dtype=float)
    b = np.asarray(desc2, dtype=float)
    d2 = ((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)
    order = np.argsort(d2, axis=1, kind="stable")[:, :2]
    first = d2[np.arange(len(a)), order[:, 0]]
    second = d2[np.arange(len(a)), order[:, 1]]
    keep = (second > 0) & (first <= ratio * second)
    return np.column_stack([np.flatnonzero(keep), order[keep, 0]]).astype(np.int64).reshape(-1, 2)

# %% KDTree_answer
import heapq


@student("features.KDTree")
class KDTree:
    """k-d tree with exact and Best-Bin-First queries."""

    def __init__(self, points):
        # YOUR CODE HERE
        raise NotImplementedError()

    def query(self, q, k=1):
        # YOUR CODE HERE
        raise NotImplementedError()

    def query_bbf(self, q, k=2, max_checks=200):
        # YOUR CODE HERE
        raise NotImplementedError()
