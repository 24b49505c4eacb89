# Answer cells of the "typical mistakes" sample submission of ch03_filtering.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution, so the feedback shows what the checks recognise (and how one wrong building
# block, the Gaussian kernel here, also sinks the exercise that uses it).
# This file is data for the demo and its tests, not a module to import.

# %% temporal_mean_answer
@student("filters.temporal_mean")
def temporal_mean(frames):
    """Average of the frames -- divides the caller's array in place."""
    frames /= len(frames)
    return frames.sum(axis=0)

# %% add_gaussian_answer
@student("noise.add_gaussian")
def add_gaussian(image, sigma, rng=None):
    """Gaussian noise drawn from NumPy's global generator instead of `rng`."""
    image = np.asarray(image, dtype=float)
    return image + np.random.normal(0.0, sigma, size=image.shape)

# %% correlate_answer
@student("filters.correlate")
def correlate(image, kernel, border="reflect101", output="same"):
    """Correlation -- but the kernel is flipped first, which makes it a convolution."""
    image = np.asarray(image, dtype=float)
    kernel = np.asarray(kernel, dtype=float)[::-1, ::-1]
    kh, kw = kernel.shape
    h, w = image.shape[:2]
    padded = image if output == "valid" else pad(image, (kh // 2, kw // 2), border)
    windows = np.lib.stride_tricks.sliding_window_view(padded, (kh, kw), axis=(0, 1))
    out = np.einsum("ij...kl,kl->ij...", windows, kernel)
    return out if output == "valid" else out[:h, :w]

# %% mean_answer
@student("filters.mean")
def mean(image, size, border="reflect101"):
    """The box filter delegated to SciPy (the exercise is to write it)."""
    from scipy import ndimage

    modes = {"zero": "constant", "replicate": "nearest", "reflect": "reflect", "reflect101": "mirror"}
    image = np.asarray(image, dtype=float)
    sizes = (size, size) + (1,) * (image.ndim - 2)
    return ndimage.uniform_filter(image, sizes, mode=modes[border])

# %% gaussian_kernel_answer
@student("filters.gaussian_kernel")
def gaussian_kernel(sigma, radius=None):
    """Sampled Gaussian -- with sigma where the variance sigma**2 belongs."""
    if radius is None:
        radius = int(np.ceil(3 * sigma - 1e-9))
    x = np.arange(-radius, radius + 1, dtype=float)
    weights = np.exp(-x**2 / (2 * sigma))
    return weights / weights.sum()

# %% median_answer
@student("filters.median")
def median(image, size, border="reflect101"):
    """Sorts nothing: averages the window, which is the mean filter."""
    image = np.asarray(image, dtype=float)
    padded = pad(image, size // 2, border)
    windows = np.lib.stride_tricks.sliding_window_view(padded, (size, size), axis=(0, 1))
    return windows.mean(axis=(-2, -1))

# %% bilateral_answer
@student("filters.bilateral")
def bilateral(image, sigma_space, sigma_range, radius=None, border="reflect101"):
    """Bilateral filter whose range weight looks at I(q) instead of I(q) - I(p)."""
    image = np.asarray(image, dtype=float)
    r = int(np.ceil(3 * sigma_space)) if radius is None else radius
    padded = pad(image, r, border)
    h, w = image.shape[:2]
    total = np.zeros(image.shape)
    weight_sum = np.zeros(image.shape[:2])
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            q = padded[r + dy : r + dy + h, r + dx : r + dx + w]
            squared = q**2 if image.ndim == 2 else (q**2).sum(axis=-1)
            weight = np.exp(-(dx * dx + dy * dy) / (2 * sigma_space**2)) * np.exp(-squared / (2 * sigma_range**2))
            total += (weight if image.ndim == 2 else weight[..., None]) * q
            weight_sum += weight
    return total / (weight_sum if image.ndim == 2 else weight_sum[..., None])

# %% nl_means_answer
@student("filters.nl_means")
def nl_means(image, h, patch_size=7, search_size=21, border="reflect101"):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()
