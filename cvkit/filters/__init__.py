"""Chapter 3 — spatial filtering (§3.1–3.14 of the notes).

Linear filters (padding, correlation, convolution, mean, Gaussian) and non-linear,
edge-preserving denoisers (median, bilateral, non-local means); the chapter's measured
exercise is :func:`denoise` (a denoiser graded by its PSNR on per-student noisy crops). Every function accepts a
grayscale ``(H, W)`` or colour ``(H, W, 3)`` image of any real dtype, computes in float64
without rescaling, never modifies its input and reads outside the image through ``border``:

========== ========================== =======================================
border     padding of ``a b c d``     same as
========== ========================== =======================================
zero       ``0 0 | a b c d | 0 0``    OpenCV BORDER_CONSTANT, SciPy "constant"
replicate  ``a a | a b c d | d d``    OpenCV BORDER_REPLICATE, SciPy "nearest"
reflect    ``b a | a b c d | d c``    OpenCV BORDER_REFLECT, SciPy "reflect"
reflect101 ``c b | a b c d | c b``    OpenCV BORDER_REFLECT_101, SciPy "mirror"
========== ========================== =======================================
"""
from ._padding import pad
from ._linear import (
    temporal_mean,
    correlate,
    convolve,
    mean_kernel,
    mean,
    gaussian_kernel,
    gaussian,
)
from ._nonlinear import median, bilateral, nl_means
from ._denoise import denoise

__all__ = [
    "pad",
    "temporal_mean",
    "correlate",
    "convolve",
    "mean_kernel",
    "mean",
    "gaussian_kernel",
    "gaussian",
    "median",
    "bilateral",
    "nl_means",
    "denoise",
]
