"""Chapter 2 — stereo matching (§2.5–2.6 of the notes).

Dense correspondence between the two images of a rectified stereo pair by block matching
(SAD, SSD or ZNCC windows, winner-takes-all). Depth follows from the disparity with
:func:`cvkit.formation.depth_from_disparity`; a real stereo pair with ground truth is
:func:`cvkit.data.stereo_motorcycle`.

>>> import numpy as np
>>> from cvkit import stereo
>>> right = np.random.default_rng(0).random((6, 20))
>>> left = np.roll(right, 3, axis=1)
>>> stereo.block_matching(left, right, 5, block_size=3)[2, 5:12]
array([3, 3, 3, 3, 3, 3, 3])
"""
from ._matching import block_matching, cost_volume, COSTS

__all__ = ["block_matching", "cost_volume", "COSTS"]
