"""Chapter 2 — image formation and digitization (§2.1–2.15 of the notes).

Geometry (pinhole projection, depth from stereo disparity), lenses (thin lens equation,
circle of confusion), digitization (quantization, memory), sensor figures of merit (SNR,
dynamic range) and colour sensors (Bayer mosaic, bilinear demosaicking). Stereo matching
itself lives in :mod:`cvkit.stereo`.

Scalar functions accept a number or an array of any shape and broadcast like NumPy's ufuncs
(a scalar in gives a NumPy scalar out). Images follow the conventions of the catalog: float64
results, values not rescaled, inputs never modified.

>>> from cvkit import formation
>>> formation.project_pinhole([[0.5, -0.25, 2.0]], f=800.0)
array([[ 200., -100.]])
"""
from ._geometry import project_pinhole, depth_from_disparity
from ._optics import thin_lens_image_distance, blur_circle_diameter
from ._digitization import quantize, image_memory_bits, snr_db, dynamic_range_db
from ._bayer import bayer_mosaic, demosaic_bilinear, PATTERNS, OPENCV_BAYER_NAMES

__all__ = [
    "project_pinhole",
    "depth_from_disparity",
    "thin_lens_image_distance",
    "blur_circle_diameter",
    "quantize",
    "image_memory_bits",
    "snr_db",
    "dynamic_range_db",
    "bayer_mosaic",
    "demosaic_bilinear",
    "PATTERNS",
    "OPENCV_BAYER_NAMES",
]
