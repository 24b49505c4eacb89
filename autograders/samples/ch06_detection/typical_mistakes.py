# Answer cells of the "typical mistakes" sample submission of ch06_detection.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution, so the feedback shows what the checks recognise.
# This file is data for the demo and its tests, not a module to import.

# %% best_match_answer
@student("detection.best_match")
def best_match(scores, measure):
    """The best score is the largest one -- also for SSD and SAD, which are distances."""
    s = np.asarray(scores, dtype=float)
    row, col = np.unravel_index(np.argmax(s), s.shape)
    return int(col), int(row)

# %% match_template_answer
@student("detection.match_template")
def match_template(image, template, measure="zncc"):
    """ZNCC written as NCC: the means are never subtracted."""
    img = np.asarray(image, dtype=float)
    t = np.asarray(template, dtype=float)
    win = np.lib.stride_tricks.sliding_window_view(img, t.shape)
    if measure == "ssd":
        return np.einsum("ijmn->ij", (win - t) ** 2)
    if measure == "sad":
        return np.einsum("ijmn->ij", np.abs(win - t))
    dot = np.einsum("ijmn,mn->ij", win, t)
    norms = np.sqrt(np.einsum("ijmn->ij", win ** 2) * np.sum(t ** 2))
    with np.errstate(all="ignore"):
        return np.where(norms > 0, dot / norms, 0.0)

# %% hough_lines_answer
@student("detection.hough_lines")
def hough_lines(edges, theta_step=np.pi / 180, rho_step=1.0):
    """Votes into rho bins from 0 to the diagonal: negative rho wraps around to the end."""
    e = np.asarray(edges)
    thetas = -np.pi / 2 + np.arange(int(np.ceil(np.pi / theta_step - 1e-9))) * theta_step
    k = int(np.ceil(np.hypot(*e.shape) / rho_step))
    rhos = np.arange(0, k + 1) * rho_step
    acc = np.zeros((rhos.size, thetas.size), dtype=np.int64)
    ys, xs = np.nonzero(e)
    for j, t in enumerate(thetas):
        idx = np.floor((xs * np.cos(t) + ys * np.sin(t)) / rho_step + 0.5).astype(int)
        np.add.at(acc[:, j], idx, 1)
    return acc, thetas, rhos

# %% ght_build_answer
@student("detection.ght_build")
def ght_build(template_edges, template_image, bins=36, reference=None):
    """Stores the vector from the reference point to each border point (the sign reversed)."""
    img = np.asarray(template_image, dtype=float)
    p = np.pad(img, 1, mode="reflect")
    d = p[:, 2:] - p[:, :-2]
    s = p[:, :-2] + 2 * p[:, 1:-1] + p[:, 2:]
    gx = d[:-2] + 2 * d[1:-1] + d[2:]
    gy = s[2:] - s[:-2]
    ys, xs = np.nonzero(np.asarray(template_edges))
    if reference is None:
        reference = (xs.mean(), ys.mean())
    k = np.round(np.arctan2(gy[ys, xs], gx[ys, xs]) / (2 * np.pi / bins)).astype(int) % bins
    r = np.stack([xs, ys], axis=1) - np.array(reference, dtype=float)
    return {"bins": bins, "reference": (float(reference[0]), float(reference[1])),
            "table": [r[k == b] for b in range(bins)]}

# %% ght_detect_answer
@student("detection.ght_detect")
def ght_detect(image, rtable, scales=(1.0,), angles=(0.0,), edge_params=None):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()

# %% find_lines_answer
@student("detection.find_lines")
def find_lines(edges):
    """Lines -- every bin above the threshold, none suppressed: one line comes back many times."""
    accumulator, thetas, rhos = hough_lines(np.asarray(edges, dtype=bool))
    return hough_peaks(accumulator, thetas, rhos, count=50, threshold=45, min_distance=0)
