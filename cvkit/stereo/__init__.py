"""Chapter 2 — stereo matching (§2.5–2.6 of the notes).

Dense correspondence between the two images of a rectified stereo pair by block matching
(SAD, SSD or ZNCC windows, winner-takes-all). Depth follows from the disparity with
:func:`cvkit.formation.depth_from_disparity`; a real stereo pair with ground truth is
:func:`cvkit.data.stereo_motorcycle`. The chapter's measured exercise is :func:`dense_disparity`: the best
map a recipe can make, graded by its bad-pixel rate (:func:`bad_pixel_rate`) on per-student
synthetic pairs with known disparity (:func:`synthetic_pair`).

>>> import numpy as np
>>> from cvkit import stereo
>>> right = np.random.default_rng(0).random((6, 20))
>>> left = np.roll(right, 3, axis=1)
>>> stereo.block_matching(left, right, 5, block_size=3)[2, 5:12]
array([3, 3, 3, 3, 3, 3, 3])
"""
from ._matching import block_matching, cost_volume, COSTS
from ._measured import dense_disparity, synthetic_pair, bad_pixel_rate

__all__ = ["block_matching", "cost_volume", "COSTS", "dense_disparity", "synthetic_pair", "bad_pixel_rate"]
