"""The embedded default data set: scikit-learn's 8×8 handwritten digits (1797 images)."""
from __future__ import annotations

import numpy as np

__all__ = ["digits", "held_out_digits"]

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


def _perturb(images: np.ndarray, generator: np.random.Generator) -> np.ndarray:
    """Each image's contrast scaled by a random gain in [0.85, 1] and a little Gaussian noise
    (σ = 0.03) added: the same digits, but never the exact pixels a student has seen."""
    gain = generator.uniform(0.85, 1.0, (len(images), 1, 1))
    return np.clip(images * gain + generator.normal(0.0, 0.03, images.shape), 0.0, 1.0)


def _camera(generator: np.random.Generator) -> tuple[float, float]:
    """(gain, offset) of a per-student "camera": digits arrive as offset + gain·image."""
    return float(generator.uniform(60.0, 255.0)), float(generator.uniform(0.0, 40.0))


def held_out_digits(seed: int | np.random.Generator, train_fraction: float = 0.7
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A per-seed split of all 1797 digits: ``(x_train, y_train, x_eval, y_eval)``.

    The data of the measured exercises that train a classifier (Chapters 9 and 12): each
    student's own split, drawn from their hidden seed. Each class is split at random
    (``train_fraction`` to train); the evaluation images are then perturbed (a contrast gain in
    [0.85, 1] and Gaussian noise of σ = 0.03, clipped to [0, 1]), so that they differ from every
    image of :func:`digits`. Both sets come in the grey levels of one random camera,
    ``offset + gain·image`` with the gain in [60, 255] and the offset in [0, 40] (a recipe must
    normalise its inputs).

    Parameters
    ----------
    seed : int or Generator
        The student's seed.
    train_fraction : float
        Share of each class to train on, in (0, 1).

    Returns
    -------
    x_train, y_train, x_eval, y_eval
        Images ``(N, 8, 8)`` float64, labels int64.

    Examples
    --------
    >>> x_train, y_train, x_eval, y_eval = held_out_digits(7)
    >>> x_train.shape, x_eval.shape, bool(x_train.max() > 16)
    ((1258, 8, 8), (539, 8, 8), True)
    """
    from .._validation import as_rng

    fraction = float(train_fraction)
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"train_fraction must lie in (0, 1), got {train_fraction!r}")
    generator = as_rng(seed)
    (a, ya), (b, yb) = digits(flatten=False)
    images, labels = np.concatenate([a, b]), np.concatenate([ya, yb])
    train = np.zeros(labels.size, dtype=bool)
    for label in np.unique(labels):
        members = np.flatnonzero(labels == label)
        train[generator.choice(members, size=int(round(fraction * members.size)), replace=False)] = True
    order_train = generator.permutation(np.flatnonzero(train))
    order_eval = generator.permutation(np.flatnonzero(~train))
    x_eval = _perturb(images[order_eval], generator)
    gain, offset = _camera(generator)
    return (offset + gain * images[order_train], labels[order_train].astype(np.int64),
            offset + gain * x_eval, labels[order_eval].astype(np.int64))
