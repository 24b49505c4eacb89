"""The embedded default data set: scikit-learn's 8×8 handwritten digits (1797 images)."""
from __future__ import annotations

import numpy as np

__all__ = ["digits"]

#: ``(X_train, y_train), (X_test, y_test)``
Split = tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]

_TEST_FRACTION = 0.3
_SPLIT_SEED = 2026


def digits(flatten: bool = True) -> Split:
    """The 8×8 digits shipped with scikit-learn, with a fixed stratified train/test split.

    Parameters
    ----------
    flatten : bool
        Return each image as a 64-vector (``(N, 64)``) instead of ``(N, 8, 8)``.

    Returns
    -------
    (X_train, y_train), (X_test, y_test)
        ``X`` float64 in [0, 1] (the original 0..16 grey levels divided by 16), ``y`` int64
        labels 0..9. The split is the same on every machine: 30 % of each class for testing
        (1258 training and 539 test images), drawn once with a fixed seed.

    Raises
    ------
    ImportError
        Without scikit-learn, an optional extra: ``pip install "cvkit[learn]"``.

    Examples
    --------
    >>> (X_train, y_train), (X_test, y_test) = digits()
    >>> X_train.shape, X_test.shape, int(y_train.max())
    ((1258, 64), (539, 64), 9)
    """
    try:
        from sklearn.datasets import load_digits
    except ImportError as exc:  # scikit-learn is the `learn` extra
        raise ImportError(
            'cvkit.data.digits loads scikit-learn\'s digits, and scikit-learn is not installed: '
            'pip install "cvkit[learn]"') from exc
    bunch = load_digits()
    images = bunch.images.astype(np.float64) / 16.0
    labels = bunch.target.astype(np.int64)
    rng = np.random.default_rng(_SPLIT_SEED)
    test = np.zeros(labels.size, dtype=bool)
    for label in np.unique(labels):
        members = np.flatnonzero(labels == label)
        chosen = rng.choice(members, size=int(round(_TEST_FRACTION * members.size)), replace=False)
        test[chosen] = True
    X = images.reshape(len(images), -1) if flatten else images
    return (X[~test], labels[~test]), (X[test], labels[test])
