"""The linear classifier of Chapter 9: scores, softmax, cross-entropy, gradients, SGD, top-k.

Conventions: ``X`` is ``(N, D)`` (one flattened image per row), labels ``y`` are integers
``0..C−1``, ``W`` is ``(C, D)`` (one template per class, as in the notes' ``f(x) = Wx + b``)
and ``b`` is ``(C,)``, so the scores of all rows are ``X @ W.T + b``, an ``(N, C)`` array.
Everything is computed in float64 and no input is ever modified.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, as_labels, as_rng, check_allocation, check_int, check_real, check_size
from ..registry import algorithm, implementation

__all__ = [
    "linear_scores", "softmax", "cross_entropy", "linear_loss_and_grad", "numerical_gradient",
    "sgd_train", "top_k_accuracy",
]

#: the most epochs :func:`sgd_train` accepts
MAX_EPOCHS = 100_000


def _weights(W: ArrayLike, b: ArrayLike, d: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    W = as_float_array(W, "W", ndim=2)
    b = as_float_array(b, "b", ndim=1)
    if b.shape[0] != W.shape[0]:
        raise ValueError(f"b must have one bias per class (W has {W.shape[0]} rows), got shape {b.shape}")
    if d is not None and W.shape[1] != d:
        raise ValueError(f"W must have one column per feature of X ({d}), got shape {W.shape}")
    return W, b


@algorithm("learn.linear_scores", section="9.6.1–9.6.5", check="cvkit.learn.checks:linear_scores")
def linear_scores(X: ArrayLike, W: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Class scores of a linear (affine) classifier, one row per sample.

    Parameters
    ----------
    X : (N, D) array_like
        One flattened image (feature vector) per row, any real dtype.
    W : (C, D) array_like
        One row (a template) per class. The scores, N·C values, must fit in 2 GiB (cvkit's
        limit for one array), else ``ValueError`` naming ``W``.
    b : (C,) array_like
        One bias per class.

    Returns
    -------
    (N, C) float64 ndarray
        ``scores[i, j] = W[j] · X[i] + b[j]``: row ``i`` is ``f(x_i; W, b) = W x_i + b``.

    Notes
    -----
    §9.6.1–9.6.5: :math:`f(x; \\theta) = Wx + b` ("linear" in machine learning means affine).
    Each score is the dot product of the image with a class template (§9.6.4), and the
    predicted class is ``argmax`` over a row (§9.6.3).

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0], [0.0, -1.0], [3.0, 0.5]])
    >>> W = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    >>> linear_scores(X, W, np.array([0.0, 0.0, -1.0]))
    array([[ 1. ,  2. ,  2. ],
           [ 0. , -1. , -2. ],
           [ 3. ,  0.5,  2.5]])
    """
    X = as_float_array(X, "X", ndim=2)
    W, b = _weights(W, b, X.shape[1])
    check_allocation((X.shape[0], W.shape[0]), "W", what="the scores X @ W.T")
    return X @ W.T + b


@algorithm("learn.softmax", section="9.7.3", check="cvkit.learn.checks:softmax")
def softmax(scores: ArrayLike) -> np.ndarray:
    """Row-wise softmax: scores → probabilities (each row non-negative, summing to 1).

    Parameters
    ----------
    scores : (N, C) or (C,) array_like
        Finite real scores (logits); a 1-D array is one row.

    Returns
    -------
    float64 ndarray, same shape as ``scores``
        :math:`p_j = e^{s_j} / \\sum_k e^{s_k}` along the last axis.

    Notes
    -----
    §9.7.3. The maximum of each row is subtracted before exponentiating:
    :math:`\\mathrm{softmax}(s) = \\mathrm{softmax}(s - \\max_k s_k)`, so the largest
    exponent is ``e^0 = 1`` — nothing overflows, the denominator is ≥ 1, and scores of ±1e4
    (or ±1e300) give finite probabilities. Probabilities far below the row's maximum
    underflow to exactly 0.

    Examples
    --------
    >>> import numpy as np
    >>> softmax(np.array([[1.0, 2.0, 3.0], [1e4, 0.0, -1e4]])).round(4)
    array([[0.09  , 0.2447, 0.6652],
           [1.    , 0.    , 0.    ]])
    """
    s = as_float_array(scores, "scores", ndim=(1, 2))
    with np.errstate(over="ignore", under="ignore"):
        shifted = s - s.max(axis=-1, keepdims=True)
        e = np.exp(shifted)
    e /= e.sum(axis=-1, keepdims=True)
    return e


@algorithm("learn.cross_entropy", section="9.7.4", check="cvkit.learn.checks:cross_entropy")
def cross_entropy(scores: ArrayLike, y: ArrayLike) -> tuple[float, np.ndarray]:
    """Mean cross-entropy (softmax + negative log-likelihood) and its gradient.

    Parameters
    ----------
    scores : (N, C) array_like
        Finite scores (logits), one row per sample.
    y : (N,) array_like of int
        True labels in ``0..C−1``.

    Returns
    -------
    loss : float
        :math:`L = \\frac{1}{N} \\sum_i \\big(-s_{i,y_i} + \\log \\sum_k e^{s_{ik}}\\big)`.
    dscores : (N, C) float64 ndarray
        :math:`\\partial L / \\partial s_{ij} = (p_{ij} - [j = y_i]) / N`, with ``p`` the row-wise
        softmax.

    Notes
    -----
    §9.7.4. The log-sum-exp is computed with the row maximum factored out,
    :math:`\\log \\sum_k e^{s_k} = m + \\log \\sum_k e^{s_k - m}`, so the loss stays finite and
    exact for huge scores (a true class 2·10⁴ below the best one costs 2·10⁴, where
    ``-log(softmax)`` would give ``-log(0) = inf``). The same as PyTorch's
    ``torch.nn.CrossEntropyLoss()`` (mean reduction) and scikit-learn's ``log_loss`` on the
    softmax probabilities.

    Examples
    --------
    >>> import numpy as np
    >>> loss, dscores = cross_entropy(np.array([[2.0, 0.0], [0.0, 0.0]]), np.array([0, 1]))
    >>> round(loss, 6)
    0.410038
    >>> dscores.round(4)
    array([[-0.0596,  0.0596],
           [ 0.25  , -0.25  ]])
    """
    s = as_float_array(scores, "scores", ndim=2)
    n, c = s.shape
    labels = as_labels(y, "y", n, c)
    rows = np.arange(n)
    with np.errstate(over="ignore", under="ignore"):
        shifted = s - s.max(axis=1, keepdims=True)
        log_norm = np.log(np.exp(shifted).sum(axis=1))  # log Σ exp(s) − max s, in [0, log C]
        log_p = shifted - log_norm[:, None]
        p = np.exp(log_p)
    loss = float(-log_p[rows, labels].mean())
    p[rows, labels] -= 1.0
    p /= n
    return loss, p


@algorithm("learn.linear_loss_and_grad", section="9.7", check="cvkit.learn.checks:linear_loss_and_grad")
def linear_loss_and_grad(W: ArrayLike, b: ArrayLike, X: ArrayLike, y: ArrayLike,
                         reg: float = 0.0) -> tuple[float, np.ndarray, np.ndarray]:
    """Regularised cross-entropy loss of a linear classifier and its gradients.

    Parameters
    ----------
    W : (C, D) array_like
        Class templates.
    b : (C,) array_like
        Biases.
    X : (N, D) array_like
        Samples, one per row.
    y : (N,) array_like of int
        Labels in ``0..C−1``.
    reg : float
        L2 regularisation strength λ ≥ 0 (the bias is not regularised).

    Returns
    -------
    loss : float
        :math:`\\frac{1}{N}\\sum_i L_i + \\lambda \\sum W^2`, ``L_i`` the cross-entropy of
        sample ``i``.
    dW : (C, D) float64 ndarray
        :math:`\\partial\\,\\mathrm{loss}/\\partial W = G^\\top X + 2\\lambda W`, with ``G`` the
        ``(N, C)`` gradient of the mean cross-entropy with respect to the scores.
    db : (C,) float64 ndarray
        :math:`\\sum_i G_i` (the column sums of ``G``).

    Notes
    -----
    §9.7 (learning as the minimisation of the mean loss over the training set) with the
    scores of §9.6 and the loss of §9.7.4. The scores and the cross-entropy come from
    ``implementation("learn.linear_scores")`` and ``implementation("learn.cross_entropy")``,
    so ``with cvkit.use("student"):`` runs this on a student's building blocks.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 0.0], [0.0, 1.0]]); y = np.array([0, 1])
    >>> loss, dW, db = linear_loss_and_grad(np.zeros((2, 2)), np.zeros(2), X, y)
    >>> round(loss, 6), dW, db                  # log 2, and a step of -dW favours the truth
    (0.693147, array([[-0.25,  0.25],
           [ 0.25, -0.25]]), array([0., 0.]))
    """
    X = as_float_array(X, "X", ndim=2)
    W, b = _weights(W, b, X.shape[1])
    labels = as_labels(y, "y", X.shape[0], W.shape[0])
    reg = check_real(reg, "reg", nonnegative=True)
    scores = implementation("learn.linear_scores")(X, W, b)
    loss, dscores = implementation("learn.cross_entropy")(scores, labels)
    dscores = as_float_array(dscores, "the gradient returned by learn.cross_entropy", ndim=2)
    loss = float(loss) + reg * float(np.sum(W * W))
    dW = dscores.T @ X
    if reg:
        dW += (2.0 * reg) * W
    return loss, dW, dscores.sum(axis=0)


@algorithm("learn.numerical_gradient", section="9.8.1", check="cvkit.learn.checks:numerical_gradient")
def numerical_gradient(f: Callable[[np.ndarray], Any], x: ArrayLike, eps: float = 1e-5) -> np.ndarray:
    """Central-difference gradient of a scalar function, one coordinate at a time.

    Parameters
    ----------
    f : callable
        ``f(x)`` → a real number, for an array of the shape of ``x``.
    x : array_like
        The point (any shape, any real dtype; computed in float64).
    eps : float
        The step h > 0. It must move every coordinate: an ``eps`` that rounds away
        (``x_i ± eps == x_i``, e.g. ``1e-300``, or 1e-5 next to 1e12) or that takes ``x ± eps``
        out of the floating-point range raises ``ValueError`` (the differences would be 0 or
        not finite, not a gradient).

    Returns
    -------
    float64 ndarray, same shape as ``x``
        :math:`g_i = \\big(f(x + h e_i) - f(x - h e_i)\\big) / (2h)`.

    Notes
    -----
    §9.8.1: the numerical gradient, easy to write but slow (two evaluations of ``f`` per
    coordinate) and approximate: its truncation error is :math:`h^2 f'''/6` per coordinate
    (a one-sided difference would make it :math:`h f''/2`) and its rounding error about
    :math:`10^{-16} |f| / h`, so h ≈ 1e-5 balances the two. Use it to check analytic
    gradients. ``f`` is evaluated on a float64 copy of ``x`` whose coordinates are moved one at
    a time and put back exactly; the caller's ``x`` is never touched.

    Examples
    --------
    >>> import numpy as np
    >>> g = numerical_gradient(lambda v: float(np.sum(v ** 3)), np.array([[1.0, -2.0]]))
    >>> g.shape, bool(np.allclose(g, [[3.0, 12.0]]))
    ((1, 2), True)
    """
    if not callable(f):
        raise TypeError(f"f must be a callable returning a number, got {type(f).__name__}")
    point = as_float_array(x, "x", allow_empty=True)
    eps = check_real(eps, "eps", positive=True)
    _check_step(point, eps)
    # C order, so that the flat reshape below is a view (for a transposed or Fortran-ordered x
    # it would be a copy, and f would never see the moved coordinate)
    work = np.array(point, dtype=np.float64, order="C", copy=True)
    flat = work.reshape(-1)  # a view: moving flat[i] moves work
    grad = np.empty(flat.size)

    def value(v: np.ndarray) -> float:
        out = f(v)
        try:
            return float(out)
        except (TypeError, ValueError):
            raise TypeError(f"f must return a single number, got {type(out).__name__} "
                            f"{np.shape(out) if hasattr(out, 'shape') else ''}".rstrip()) from None

    for i in range(flat.size):
        old = flat[i]
        flat[i] = old + eps
        plus = value(work)
        flat[i] = old - eps
        minus = value(work)
        flat[i] = old
        grad[i] = (plus - minus) / (2.0 * eps)
    return grad.reshape(point.shape)


def _check_step(point: np.ndarray, eps: float) -> None:
    """Refuse a step ``eps`` that rounding loses at some coordinate of ``point`` or that
    overflows it."""
    with np.errstate(over="ignore"):
        up, down = point + eps, point - eps
    if not (np.all(np.isfinite(up)) and np.all(np.isfinite(down))):
        raise ValueError(f"eps must keep x ± eps finite, got eps = {eps!r}")
    lost = np.flatnonzero((up == point) | (down == point))
    if lost.size:
        at = float(point.reshape(-1)[lost[0]])
        raise ValueError(
            f"eps = {eps!r} is lost to rounding at x = {at!r} (x ± eps == x, so the difference would be "
            f"0): use an eps well above {float(np.spacing(abs(at))):.3g}")


@algorithm("learn.sgd_train", section="9.8.3–9.8.4", check="cvkit.learn.checks:sgd_train")
def sgd_train(X: ArrayLike, y: ArrayLike, classes: int, lr: float, epochs: int, batch_size: int, reg: float = 0.0,
              rng: np.random.Generator | int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Train a linear softmax classifier by mini-batch stochastic gradient descent.

    Parameters
    ----------
    X : (N, D) array_like
        Training samples, one per row.
    y : (N,) array_like of int
        Labels in ``0..classes−1``.
    classes : int
        The number of classes C ≥ 1; the weights ``(C, D)`` must fit in 2 GiB (cvkit's limit
        for one array), else ``ValueError`` naming ``classes``.
    lr : float
        Learning rate (step size) > 0.
    epochs : int
        Number of passes over the training set, 1 ≤ epochs ≤ :data:`MAX_EPOCHS` (100 000).
    batch_size : int
        Samples per mini-batch B ≥ 1 (``B = 1``: online SGD; ``B ≥ N``: batch gradient descent).
        The scores of a mini-batch, min(B, N)·C values, must fit in 2 GiB, else ``ValueError``
        naming ``batch_size``.
    reg : float
        L2 regularisation strength λ ≥ 0 (see :func:`linear_loss_and_grad`).
    rng : numpy.random.Generator, int or None
        Source of the shuffles.

    Returns
    -------
    W : (C, D) float64 ndarray
    b : (C,) float64 ndarray
    losses : (epochs,) float64 ndarray
        ``losses[e]``: the mean over the samples of epoch ``e`` of the mini-batch losses
        computed in its forward passes (before each step), i.e. the batch losses weighted by
        their sizes. It includes the regularisation term.

    Notes
    -----
    §9.8–9.8.4. ``W`` and ``b`` start at zero (the loss is convex, so no random start is
    needed; scikit-learn's linear models start there too). Each epoch draws a fresh
    permutation ``rng.permutation(N)`` and cuts it into consecutive batches of ``B`` samples
    (the last one smaller when B does not divide N, never dropped); for each batch it computes
    ``loss, dW, db = linear_loss_and_grad(W, b, X[batch], y[batch], reg)`` (through
    ``implementation``, so a student's version can be plugged in) and steps
    ``W -= lr·dW, b -= lr·db``: ⌈N/B⌉ updates per epoch.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[0.0, 1.0], [1.0, 0.0], [0.1, 0.9], [0.9, 0.2]]); y = np.array([0, 1, 0, 1])
    >>> W, b, losses = sgd_train(X, y, 2, lr=0.5, epochs=30, batch_size=2, rng=0)
    >>> W.shape, b.shape, losses.shape, bool(losses[-1] < losses[0])
    ((2, 2), (2,), (30,), True)
    >>> linear_scores(X, W, b).argmax(axis=1)
    array([0, 1, 0, 1])
    """
    X = as_float_array(X, "X", ndim=2)
    n, d = X.shape
    classes = check_int(classes, "classes", minimum=1)
    labels = as_labels(y, "y", n, classes)
    lr = check_real(lr, "lr", positive=True)
    epochs = check_size(epochs, "epochs", minimum=1, maximum=MAX_EPOCHS)
    batch_size = check_int(batch_size, "batch_size", minimum=1)
    reg = check_real(reg, "reg", nonnegative=True)
    check_allocation((classes, d), "classes", what="the weights W")
    check_allocation((min(batch_size, n), classes), "batch_size", what="the scores of a mini-batch")
    generator = as_rng(rng)
    step = implementation("learn.linear_loss_and_grad")
    W = np.zeros((classes, d))
    b = np.zeros(classes)
    losses = np.empty(epochs)
    for epoch in range(epochs):
        order = generator.permutation(n)
        total = 0.0
        for start in range(0, n, batch_size):
            batch = order[start:start + batch_size]
            loss, dW, db = step(W, b, X[batch], labels[batch], reg)
            W = W - lr * np.asarray(dW, dtype=np.float64)
            b = b - lr * np.asarray(db, dtype=np.float64)
            total += float(loss) * batch.size
        losses[epoch] = total / n
    return W, b, losses


@algorithm("learn.top_k_accuracy", section="9.5", check="cvkit.learn.checks:top_k_accuracy")
def top_k_accuracy(scores: ArrayLike, y: ArrayLike, k: int = 5) -> float:
    """Fraction of samples whose true label is among their k highest scores.

    Parameters
    ----------
    scores : (N, C) array_like
        Finite scores (or probabilities), one row per sample.
    y : (N,) array_like of int
        True labels in ``0..C−1``.
    k : int
        1 ≤ k ≤ C (``k = 1`` is the usual accuracy); ``k > C`` raises ``ValueError``.

    Returns
    -------
    float
        The fraction of rows ``i`` for which fewer than ``k`` scores are strictly greater than
        ``scores[i, y[i]]``.

    Notes
    -----
    §9.5 (top-5 accuracy on ILSVRC). Ties at the k-th score count as hits: the true class
    is "among the k highest" when it is not beaten by k others, whatever the order a sort
    would give to equal scores. (scikit-learn's ``top_k_accuracy_score`` breaks such ties
    by sorting instead; on scores without ties the two agree.)

    Examples
    --------
    >>> import numpy as np
    >>> s = np.array([[0.1, 0.5, 0.4], [0.7, 0.2, 0.1], [0.3, 0.3, 0.4]])
    >>> y = np.array([2, 1, 1])
    >>> top_k_accuracy(s, y, k=1), top_k_accuracy(s, y, k=2)
    (0.0, 1.0)
    """
    s = as_float_array(scores, "scores", ndim=2)
    n, c = s.shape
    labels = as_labels(y, "y", n, c)
    k = check_int(k, "k", minimum=1)
    if k > c:
        raise ValueError(f"k must be at most the number of classes ({c}), got {k}")
    true = s[np.arange(n), labels]
    beaten_by = np.count_nonzero(s > true[:, None], axis=1)
    return float(np.mean(beaten_by < k))
