"""Chapter 6 — instance-level object detection (§6.0.1–6.0.7 of the notes).

Find one known object (the *model*) in a target image and estimate where it is:

- **template matching** (§6.0.1–6.0.2): slide the model over the image and score every
  placement by SSD, SAD, NCC or ZNCC (:func:`match_template`, :func:`best_match`);
- **shape-based matching** (§6.0.3): compare the gradient directions at the model's edge
  points with the image's, optionally invariant to contrast polarity (:func:`shape_model`,
  :func:`shape_match`);
- the **Hough transform** for lines (§6.0.4–6.0.5): every edge pixel votes for the (ρ, θ) of
  all lines through it (:func:`hough_lines`), lines are the peaks (:func:`hough_peaks`);
- the **Generalized Hough Transform** (§6.0.6–6.0.7): an R-table of displacement vectors
  indexed by gradient direction (:func:`ght_build`) lets every edge pixel vote for the
  object's reference point, over scales and rotations (:func:`ght_detect`).

Conventions (``docs/catalog.md``): 2-D images indexed ``[row, col]``, points ``(x, y) = (col,
row)``, angles in radians with y pointing down the rows, gradients by ``edges.sobel`` with the
``reflect101`` border. Pipelines call their building blocks (``edges.sobel``,
``edges.canny``) through the registry, so ``with cvkit.use("student"):`` runs them on a
student's own pieces.

>>> import numpy as np
>>> from cvkit import detection
>>> img = np.zeros((6, 7)); img[2:4, 3:5] = [[1, 2], [3, 4]]
>>> detection.best_match(detection.match_template(img, img[2:4, 3:5], "ssd"), "ssd")
(3, 2)
"""
from ._template import match_template, best_match
from ._shape import shape_model, shape_match
from ._hough import hough_lines, hough_peaks
from ._ght import ght_build, ght_detect
from ._lines import find_lines

__all__ = [
    "match_template",
    "best_match",
    "shape_model",
    "shape_match",
    "hough_lines",
    "hough_peaks",
    "ght_build",
    "ght_detect",
    "find_lines",
]
