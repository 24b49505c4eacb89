"""Texture patches for bag-of-visual-words experiments (§10.3): brick, grass and gravel.

The three 512×512 grayscale textures bundled with scikit-image are cut into square patches
on a grid; patches from the left three quarters of each picture are for training, those from
the right quarter for testing, so no pixel is shared between the two sets.
"""
from __future__ import annotations

import numpy as np

from .._validation import check_int
from ._digits import Split
from ._images import image as _image

__all__ = ["textures", "TEXTURE_CLASSES"]

#: class names of :func:`textures`, in label order
TEXTURE_CLASSES = ("brick", "grass", "gravel")

_SIDE = 512
_TRAIN_WIDTH = 384  # columns 0..383 train, 384..511 test


def textures(patch_size: int = 32, flatten: bool = False) -> Split:
    """Patches of scikit-image's brick, grass and gravel textures with a fixed train/test split.

    Parameters
    ----------
    patch_size : int
        Side of the square patches, 8..128. Patches sit on the grid
        ``0, p, 2p, …`` (they do not overlap).
    flatten : bool
        Return each patch as a vector of ``p²`` values instead of ``(p, p)``.

    Returns
    -------
    (X_train, y_train), (X_test, y_test)
        ``X`` float64 in [0, 1], shape ``(N, p, p)`` (or ``(N, p²)``); ``y`` int64 labels
        0 = brick, 1 = grass, 2 = gravel (:data:`TEXTURE_CLASSES`). Training patches come from
        columns 0..383 of each image, test patches from columns 384..511, rows anywhere; with
        ``p = 32`` that is 192 training and 64 test patches per class. Patches are ordered by
        class, then row, then column.

    Examples
    --------
    >>> (X_train, y_train), (X_test, y_test) = textures()
    >>> X_train.shape, X_test.shape, np.bincount(y_test).tolist()
    ((576, 32, 32), (192, 32, 32), [64, 64, 64])
    """
    p = check_int(patch_size, "patch_size", minimum=8)
    if p > 128:
        raise ValueError(f"patch_size must be at most 128, got {p}")
    train_x: list[np.ndarray] = []
    train_y: list[np.ndarray] = []
    test_x: list[np.ndarray] = []
    test_y: list[np.ndarray] = []
    for label, name in enumerate(TEXTURE_CLASSES):
        img = _image(name)
        rows = _SIDE // p
        for (c0, c1), xs, ys in (((0, _TRAIN_WIDTH), train_x, train_y), ((_TRAIN_WIDTH, _SIDE), test_x, test_y)):
            cols = (c1 - c0) // p
            block = img[: rows * p, c0: c0 + cols * p]
            patches = block.reshape(rows, p, cols, p).transpose(0, 2, 1, 3).reshape(-1, p, p)
            xs.append(patches)
            ys.append(np.full(len(patches), label, dtype=np.int64))
    X_train, X_test = np.concatenate(train_x), np.concatenate(test_x)
    if flatten:
        X_train, X_test = X_train.reshape(len(X_train), -1), X_test.reshape(len(X_test), -1)
    return (X_train, np.concatenate(train_y)), (X_test, np.concatenate(test_y))
