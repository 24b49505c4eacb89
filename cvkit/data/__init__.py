"""Images and data sets for the notebooks, made by code or shipped with installed packages.

Every loader returns float64 arrays in [0, 1] (grayscale ``(H, W)`` or RGB ``(H, W, 3)``)
unless it says otherwise; nothing is downloaded. The sample pictures and the stereo pair are
scikit-image's (the optional extra ``pip install "cvkit[data]"``), the digits scikit-learn's
(``pip install "cvkit[learn]"``): without them those loaders raise an ``ImportError`` that says
so, and everything made by code works without either. The loaders live in private submodules by
theme (``_images``: scikit-image's bundled pictures and noise helpers; further modules add
stereo pairs, chessboard views, digits, synthetic shapes); every public name of every
submodule (its ``__all__``) is available here.

>>> from cvkit import data
>>> data.camera().shape
(512, 512)
"""
from __future__ import annotations

# Written out (not gathered at import time) so that type checkers see every name; a test
# (tests/library/test_bounds_a.py) keeps this list equal to the submodules' ``__all__``.
from ._chessboard import ChessboardViews, render_chessboard, random_board_poses, chessboard_views
from ._digits import digits, held_out_digits
from ._files import read_idx, mnist, read_cifar_batch, cifar10, CIFAR10_CLASSES
from ._images import (
    camera, astronaut, coins, moon, text, brick, coffee, chelsea, image, resize_half, noisy_stack,
    with_gaussian_noise, with_impulse_noise, step_edge, psnr,
)
from ._scenes import polygon_image, part_outline, part_template, part_scene, to_scene, segments_image
from ._stereo import stereo_motorcycle, MOTORCYCLE_CALIBRATION
from ._synthetic import disk_image, square_image, oriented_step_image, step_signal
from ._textures import textures, TEXTURE_CLASSES

__all__ = [
    "ChessboardViews", "render_chessboard", "random_board_poses", "chessboard_views",
    "digits",
    "held_out_digits",
    "read_idx", "mnist", "read_cifar_batch", "cifar10", "CIFAR10_CLASSES",
    "camera", "astronaut", "coins", "moon", "text", "brick", "coffee", "chelsea", "image", "resize_half",
    "noisy_stack", "with_gaussian_noise", "with_impulse_noise", "step_edge", "psnr",
    "polygon_image", "part_outline", "part_template", "part_scene", "to_scene", "segments_image",
    "stereo_motorcycle", "MOTORCYCLE_CALIBRATION",
    "disk_image", "square_image", "oriented_step_image", "step_signal",
    "textures", "TEXTURE_CLASSES",
]
