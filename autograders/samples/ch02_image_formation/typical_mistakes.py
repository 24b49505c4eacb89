# Answer cells of the "typical mistakes" sample submission of ch02_image_formation.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution (the image memory of §2.11 among them); demosaicking is left unattempted.
# This file is data for the demo and its tests, not a module to import.

# %% project_pinhole_answer
@student("formation.project_pinhole")
def project_pinhole(points_cam, f):
    """The formula of the box camera, image plane behind the pinhole: the image comes out upside down."""
    points = np.asarray(points_cam, dtype=float)
    return -f * points[:, :2] / points[:, 2:3]

# %% depth_from_disparity_answer
@student("formation.depth_from_disparity")
def depth_from_disparity(disparity, baseline, focal):
    """Guards the division by keeping only positive disparities -- and so loses the points at infinity."""
    d = np.asarray(disparity, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(d > 0, baseline * focal / d, np.nan)

# %% block_matching_answer
@student("stereo.block_matching")
def block_matching(left, right, max_disparity, block_size=7, cost="sad"):
    """A careful vectorised version -- but it updates with <=, so ties go to the LARGEST disparity."""
    L = np.asarray(left, dtype=float)
    R = np.asarray(right, dtype=float)
    B, r = block_size, block_size // 2
    n = B * B
    height, width = L.shape
    Lp, Rp = np.pad(L, r, mode="reflect"), np.pad(R, r, mode="reflect")

    def box(a):
        c = np.zeros((a.shape[0] + 1, a.shape[1] + 1))
        c[1:, 1:] = a.cumsum(axis=0).cumsum(axis=1)
        return c[B:, B:] - c[:-B, B:] - c[B:, :-B] + c[:-B, :-B]

    if cost == "zncc":
        mean_l, mean_r = box(Lp) / n, box(Rp) / n
        var_l = np.maximum(box(Lp * Lp) / n - mean_l ** 2, 0)
        var_r = np.maximum(box(Rp * Rp) / n - mean_r ** 2, 0)
    best = np.full((height, width), np.inf)
    disparity = np.zeros((height, width), dtype=np.int64)
    for d in range(min(max_disparity, width - 1) + 1):
        Ls, Rs = Lp[:, d:], Rp[:, : Lp.shape[1] - d]
        if cost == "sad":
            c = box(np.abs(Ls - Rs))
        elif cost == "ssd":
            c = box((Ls - Rs) ** 2)
        else:
            cov = box(Ls * Rs) / n - mean_l[:, d:] * mean_r[:, : width - d]
            den = np.sqrt(var_l[:, d:] * var_r[:, : width - d])
            c = -np.where(den > 1e-10, cov / np.where(den > 1e-10, den, 1), 0.0)
        current = best[:, d:]
        better = c <= current
        current[better] = c[better]
        disparity[:, d:][better] = d
    return disparity

# %% blur_circle_diameter_answer
@student("formation.blur_circle_diameter")
def blur_circle_diameter(object_distance, focus_distance, focal_length, aperture_diameter):
    """Copies the formula without the absolute value: points nearer than the focus get negative circles."""
    d_o, d_f, f, aperture = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in
                                                  (object_distance, focus_distance, focal_length, aperture_diameter)))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = aperture * f * (d_o - d_f) / (d_o * (d_f - f))
        c = np.where(np.isinf(d_o) & ~np.isinf(d_f), aperture * f / (d_f - f), c)
        c = np.where(np.isinf(d_f) & ~np.isinf(d_o), -aperture * f / d_o, c)
    return np.where(np.isinf(d_o) & np.isinf(d_f), 0.0, c)

# %% quantize_answer
@student("formation.quantize")
def quantize(image, bits, vmax=1.0):
    """Rounds with the school rule floor(t + 0.5): half-way values go up, not to the even level."""
    levels = 2 ** bits - 1
    t = np.clip(np.asarray(image, dtype=float), 0, vmax) / vmax * levels
    return np.floor(t + 0.5) / levels * vmax

# %% bayer_mosaic_answer
@student("formation.bayer_mosaic")
def bayer_mosaic(rgb, pattern="RGGB"):
    """OpenCV habits: channel 0 taken for blue, channel 2 for red."""
    rgb = np.asarray(rgb, dtype=float)
    channel = {"B": 0, "G": 1, "R": 2}
    raw = np.empty(rgb.shape[:2])
    for i in (0, 1):
        for j in (0, 1):
            raw[i::2, j::2] = rgb[i::2, j::2, channel[pattern[2 * i + j]]]
    return raw

# %% snr_db_answer
@student("formation.snr_db")
def snr_db(frames):
    """The sample standard deviation (ddof=1) of the statistics course, not the one asked for."""
    stack = np.asarray(frames, dtype=float)
    mean = stack.mean(axis=0)
    std = np.where(np.all(stack == stack[0], axis=0), 0.0, stack.std(axis=0, ddof=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        snr = 20 * np.log10(mean / std)
    return np.where(mean > 0, snr, np.nan)

# %% demosaic_bilinear_answer
@student("formation.demosaic_bilinear")
def demosaic_bilinear(raw, pattern="RGGB"):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()
