# Answer cells of the "typical mistakes" sample submission of ch04_edges.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution, so the feedback shows what the checks recognise -- and how a wrong building block
# also sinks the exercises that use it (the 4-connected hysteresis breaks `canny`, the kernel
# that does not sum to zero breaks `log`).
# This file is data for the demo and its tests, not a module to import.

# %% direction_answer
@student("edges.direction")
def direction(ix, iy):
    """Angle of the gradient -- from the arctangent of the ratio, which loses the quadrant."""
    ix = np.asarray(ix, dtype=float)
    iy = np.asarray(iy, dtype=float)
    return np.arctan(iy / ix)

# %% sobel_answer
@student("edges.sobel")
def sobel(image, border="reflect101"):
    """Sobel -- with the kernel written the way it is drawn for convolution (signs flipped)."""
    kx = np.array([[1.0, 0.0, -1.0], [2.0, 0.0, -2.0], [1.0, 0.0, -1.0]])
    ky = kx.T
    modes = {"zero": "constant", "replicate": "edge", "reflect": "symmetric", "reflect101": "reflect"}
    p = np.pad(np.asarray(image, dtype=float), 1, mode=modes[border])
    h, w = p.shape[0] - 2, p.shape[1] - 2
    gx = np.zeros((h, w))
    gy = np.zeros((h, w))
    for m in range(3):
        for n in range(3):
            gx += kx[m, n] * p[m:m + h, n:n + w]
            gy += ky[m, n] * p[m:m + h, n:n + w]
    return gx, gy

# %% hysteresis_answer
@student("edges.hysteresis")
def hysteresis(magnitude, low, high):
    """Grows the strong pixels into weak ones -- through the 4 axis neighbours only."""
    m = np.asarray(magnitude, dtype=float)
    weak = m > low
    result = m > high
    while True:
        p = np.pad(result, 1)
        grown = weak & (result | p[:-2, 1:-1] | p[2:, 1:-1] | p[1:-1, :-2] | p[1:-1, 2:])
        if np.array_equal(grown, result):
            return result
        result = grown

# %% zero_crossings_answer
@student("edges.zero_crossings")
def zero_crossings(response, threshold=0.0):
    """Marks every pixel that takes part in a sign change -- both pixels of each pair."""
    r = np.asarray(response, dtype=float)
    out = np.zeros(r.shape, dtype=bool)
    horizontal = (r[:, :-1] * r[:, 1:] < 0) & (np.abs(r[:, :-1] - r[:, 1:]) > threshold)
    vertical = (r[:-1, :] * r[1:, :] < 0) & (np.abs(r[:-1, :] - r[1:, :]) > threshold)
    out[:, :-1] |= horizontal
    out[:, 1:] |= horizontal
    out[:-1, :] |= vertical
    out[1:, :] |= vertical
    return out

# %% log_kernel_answer
@student("edges.log_kernel")
def log_kernel(sigma, radius=None):
    """The LoG formula sampled on the square -- but the samples do not sum to zero."""
    if radius is None:
        radius = int(np.ceil(3 * sigma))
    y, x = np.mgrid[-radius:radius + 1, -radius:radius + 1]
    r2 = x**2 + y**2
    return (r2 - 2 * sigma**2) / (2 * np.pi * sigma**6) * np.exp(-r2 / (2 * sigma**2))

# %% dog_answer
@student("edges.dog")
def dog(image, sigma, k=1.6, border="reflect101"):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()

# %% detect_outlines_answer
@student("edges.detect_outlines")
def detect_outlines(image):
    """Outlines -- with Canny's default relative thresholds, which keep the noise edges."""
    return canny(image)
