"""Chapter 5 — local invariant features (§5.1–5.14 of the notes).

Corner detectors (Moravec, the structure tensor and Harris' response, peaks of a response map);
scale space (scale-normalised LoG blobs, SIFT's Gaussian and DoG pyramids, DoG extrema over 26
neighbours, their sub-pixel refinement and edge rejection); SIFT's canonical orientations,
128-D descriptor and full pipeline; matching with Lowe's ratio test and a k-d tree with exact and
Best-Bin-First search; the chapter's measured exercise, :func:`match_features` (matches between
a picture and a warped copy, graded by how many are right under the known homography). Conventions (see ``docs/catalog.md``): images are grayscale ``(H, W)`` arrays
indexed ``[row, col]``, points are ``(x, y) = (col, row)``, angles are radians with y pointing
down. Pipelines (``harris``, ``structure_tensor``, ``log_blobs``, ``gaussian_pyramid``,
``sift``) call their building blocks through the registry, so ``with cvkit.use("student"):`` runs
them on a student's own pieces.

>>> import numpy as np
>>> from cvkit import features
>>> img = np.zeros((32, 32)); img[12:, 12:] = 1.0
>>> features.peaks(features.harris(img), 0.5 * features.harris(img).max())
array([[12., 12.]])
"""
from ._corners import moravec, structure_tensor, harris, peaks
from ._scale_space import gaussian_pyramid, dog_pyramid, log_blobs, dog_extrema, refine_extremum, is_edge_like
from ._sift import orientations, sift_descriptor, sift
from ._matching import match_ratio, KDTree
from ._measured import match_features

__all__ = [
    "moravec",
    "structure_tensor",
    "harris",
    "peaks",
    "gaussian_pyramid",
    "dog_pyramid",
    "log_blobs",
    "dog_extrema",
    "refine_extremum",
    "is_edge_like",
    "orientations",
    "sift_descriptor",
    "sift",
    "match_ratio",
    "KDTree",
    "match_features",
]
