"""Checks of Chapters 9–10 (``cvkit.learn``): cases, comparators and mistake banks.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference
function (``cvkit.learn.checks:softmax`` grades ``learn.softmax``). Public cases are tiny and
fixed and already tell every mistake of the bank from the right answer; hidden cases are
drawn from the grading seed and include the awkward inputs (one sample, one class, uint8 or
integer data, huge scores, ties, every option value) and, for every mistake, inputs on which
it is wrong — also the mistakes that are right on ordinary data (softmax without the max
shift is right until the scores reach ~700; a vote tie never happens with k = 1; an empty
cluster never happens with a good seeding).

Deterministic algorithms are compared with ``allclose``. The two random ones are judged by
their results:

``learn.sgd_train``
    with ``batch_size ≥ N`` every epoch is one full-batch gradient step from ``W = 0``, which
    does not depend on the shuffle: ``W``, ``b`` and ``losses`` are compared with
    ``allclose``. With smaller batches the comparator measures the training objective
    J(W, b) = mean cross-entropy + λΣW² of the returned weights and the last epoch's loss,
    and requires them within a tolerance of the reference's (two correct runs with different
    shuffles agree to a few hundredths there; the mistakes miss by far more). Cases of the
    "one class per batch" family (sorted labels, B = N/C) show the effect of not shuffling.
``learn.kmeans``
    with ``init`` given (an extra keyword of the catalog signature) Lloyd's algorithm is
    deterministic and compared with ``allclose``; this is how empty clusters are forced
    (an initial centre far from every sample). With k-means++ seeding the comparator checks
    that every label is the nearest returned centre, that each centre is the mean of its
    samples (a fixed point), and that the inertia equals the reference's on data whose
    clusters are well separated (every correct version reaches the same optimum there).

Both are ``seeded``: the engine also calls the candidate twice with the same seed and requires
identical results (drawing from ``np.random.*`` instead of ``rng`` fails).

``learn.numerical_gradient`` takes a function. Functions cannot travel to the isolated grading
worker, so its cases hold plain data — the name of a test function and its coefficients — and
:func:`call_with_test_function` (the check's ``call``) builds the function and calls the
candidate with it.
"""
from __future__ import annotations

from collections import Counter
from typing import Any
from dataclasses import dataclass, field

import numpy as np

from ..grading import Case, Check, Comparator, Drawn, Mismatch, Mistake, close, mistake
from ..grading.casekit import variant
from ..grading.casekit import argument as _arg
from ..grading.casekit import rounded as _round
from ..grading.casekit import seed as _seed
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ..grading.compare import Close
from ..grading.runtime.adapters import TEST_FUNCTIONS, TestFunction, call_draws, call_with_test_function
from ._clustering import _assign, _update
from ._clustering import kmeans as _kmeans
from ._common import exact_l1_distances, exact_squared_distances
from ._linear import cross_entropy as _cross_entropy
from ._linear import linear_loss_and_grad as _loss_and_grad
from ._linear import numerical_gradient as _numerical_gradient
from ._linear import softmax as _softmax

__all__ = [
    "linear_scores", "softmax", "cross_entropy", "linear_loss_and_grad", "numerical_gradient",
    "sgd_train", "top_k_accuracy", "knn_predict", "kmeans", "bovw_histogram",
    "SGDResult", "KMeansResult", "TestFunction", "TEST_FUNCTIONS", "call_with_test_function",
]

_BUILDING_BLOCKS = ("learn.linear_scores", "learn.softmax", "learn.cross_entropy")


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _labels(rng: np.random.Generator, n: int, c: int, every: bool = True) -> np.ndarray:
    """n labels in 0..c−1 (each class present when ``every`` and n ≥ c)."""
    y = rng.integers(0, c, n)
    if every and n >= c:
        y[rng.permutation(n)[:c]] = np.arange(c)
    return y.astype(np.int64)


def _blobs(rng: np.random.Generator, n: int, d: int, c: int, spread: float = 1.0, distance: float = 2.0,
           shuffle: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """c Gaussian clusters (labels 0..c−1); sorted by class unless ``shuffle``."""
    means = rng.normal(0.0, distance, (c, d))
    per = np.full(c, n // c)
    per[: n - per.sum()] += 1
    X = np.concatenate([means[j] + spread * rng.standard_normal((per[j], d)) for j in range(c)])
    y = np.repeat(np.arange(c), per).astype(np.int64)
    if shuffle:
        order = rng.permutation(n)
        X, y = X[order], y[order]
    return _round(X), y


def _as_tuple(got, length: int, what: str) -> Mismatch | None:
    if not isinstance(got, (tuple, list)) or len(got) != length:
        kind = f"a {type(got).__name__}" if not isinstance(got, (tuple, list)) else f"{len(got)} values"
        return Mismatch(f"expected a tuple {what} of {length} values, got {kind}")
    return None


def _numeric(value, name: str, shape: tuple, kind: str = "f") -> tuple[np.ndarray | None, Mismatch | None]:
    try:
        arr = np.asarray(value)
    except Exception as exc:
        return None, Mismatch(f"{name} could not be turned into an array ({type(exc).__name__})")
    if arr.dtype == object or arr.dtype.kind not in "biuf":
        return None, Mismatch(f"{name} must be a numeric array, got dtype {arr.dtype}")
    if kind == "i" and arr.dtype.kind not in "iu":
        return None, Mismatch(f"{name} must be an integer array (labels), got dtype {arr.dtype}")
    if arr.shape != shape:
        return None, Mismatch(f"{name}: shape mismatch: expected {shape}, got {arr.shape}")
    return arr, None


# --------------------------------------------------------------------------------------------
# learn.linear_scores (§9.6)
# --------------------------------------------------------------------------------------------
@mistake("scores transposed (C, N)", "Return one row per sample and one column per class: X @ W.T + b has shape (N, C)")
def _scores_transposed(X, W, b):
    X, W, b = (np.asarray(a, dtype=np.float64) for a in (X, W, b))
    return W @ X.T + b[:, None]


@mistake("W not transposed (X @ W)", "W has one row per class, shape (C, D): the scores are X @ W.T + b")
def _scores_w_not_transposed(X, W, b):
    X, W, b = (np.asarray(a, dtype=np.float64) for a in (X, W, b))
    return X @ W + b


@mistake("bias missing", "Add the bias of each class: X @ W.T + b (the classifier is affine, §9.6.5)")
def _scores_no_bias(X, W, b):
    X, W = (np.asarray(a, dtype=np.float64) for a in (X, W))
    return X @ W.T


@mistake("bias added per sample instead of per class",
         "b has one entry per class: add it to every row, X @ W.T + b (broadcast over rows)")
def _scores_bias_per_sample(X, W, b):
    X, W, b = (np.asarray(a, dtype=np.float64) for a in (X, W, b))
    return X @ W.T + b[:, None]


def _scores_case(rng, n, d, c, kind="normal", label=""):
    if kind == "uint8":
        X = rng.integers(0, 256, (n, d), dtype=np.uint8)
    elif kind == "big":
        X = _round(rng.uniform(-1e6, 1e6, (n, d)), 0)
    else:
        X = _round(rng.normal(0, 2, (n, d)))
    W = _round(rng.normal(0, 1, (c, d)))
    b = _round(rng.normal(0, 3, c)) + 0.5  # never all zero
    return Case((X, W, b), {}, label)


def _scores_hidden(rng):
    c = _size(rng, 2, 5)
    return [
        _scores_case(rng, _size(rng, 6, 12), _size(rng, 7, 15), _size(rng, 2, 6), label="N > D > C"),
        _scores_case(rng, c, c, c, label="N = D = C (square: transposes do not change the shape)"),
        _scores_case(rng, _size(rng, 5, 9), c, c, label="D = C"),
        _scores_case(rng, c, _size(rng, 3, 8), c, label="N = C"),
        _scores_case(rng, 1, _size(rng, 3, 9), _size(rng, 2, 5), label="a single sample"),
        _scores_case(rng, _size(rng, 4, 8), _size(rng, 3, 6), 1, label="a single class"),
        _scores_case(rng, _size(rng, 4, 8), 1, _size(rng, 2, 4), label="one feature"),
        _scores_case(rng, _size(rng, 5, 9), _size(rng, 10, 64), _size(rng, 3, 10), "uint8",
                     label="uint8 pixels (not rescaled)"),
        _scores_case(rng, _size(rng, 4, 7), _size(rng, 4, 8), _size(rng, 2, 5), "big", label="values ±1e6"),
        Case((_round(rng.normal(0, 1, (_size(rng, 3, 6), 4))), _round(rng.normal(0, 1, (3, 4))), np.zeros(3)), {},
             "zero bias"),
    ]


linear_scores = Check(
    public=[
        Case((np.array([[1.0, 2.0, 0.0], [0.0, -1.0, 3.0], [2.0, 0.5, 1.0], [-1.0, 0.0, 2.0]]),
              np.array([[1.0, 0.0, -1.0], [0.5, 2.0, 1.0]]), np.array([0.5, -2.0])), {},
             "4 samples, 3 features, 2 classes"),
        Case((np.array([[1.0, 2.0, 3.0], [0.0, 1.0, -1.0], [2.0, -1.0, 0.5]]),
              np.array([[1.0, 0.0, 2.0], [-1.0, 1.0, 0.0], [0.5, 0.5, -1.0]]), np.array([1.0, 0.0, -3.0])), {},
             "3 samples, 3 features, 3 classes (square)"),
    ],
    hidden=_scores_hidden,
    compare=close(rtol=1e-7, atol=1e-10, kind="f", scaled=True),
    mistakes=[_scores_transposed, _scores_w_not_transposed, _scores_no_bias, _scores_bias_per_sample],
)


# --------------------------------------------------------------------------------------------
# learn.softmax (§9.7.3)
# --------------------------------------------------------------------------------------------
@mistake("no max shift (exp overflows for large scores)",
         "Subtract each row's maximum before np.exp: softmax(s) = softmax(s − max s) and the "
         "largest exponent becomes e⁰ = 1 (§9.7.3)")
def _softmax_no_shift(scores):
    s = np.asarray(scores, dtype=np.float64)
    e = np.exp(s)
    return e / e.sum(axis=-1, keepdims=True)


@mistake("shifted by the global maximum instead of each row's",
         "Subtract the maximum of each row (s.max(axis=-1, keepdims=True)); with the global "
         "maximum a row far below it underflows to 0/0")
def _softmax_global_shift(scores):
    s = np.asarray(scores, dtype=np.float64)
    e = np.exp(s - s.max())
    return e / e.sum(axis=-1, keepdims=True)


@mistake("normalised over the columns (axis=0)",
         "Each row is one sample: take the max and the sum along the last axis (axis=-1)")
def _softmax_columns(scores):
    s = np.asarray(scores, dtype=np.float64)
    e = np.exp(s - s.max(axis=0, keepdims=True))
    return e / e.sum(axis=0, keepdims=True)


@mistake("normalised over the whole array", "Normalise each row separately: e / e.sum(axis=-1, keepdims=True)")
def _softmax_whole_array(scores):
    s = np.asarray(scores, dtype=np.float64)
    e = np.exp(s - s.max())
    return e / e.sum()


def _softmax_hidden(rng):
    n, c = _size(rng, 3, 7), _size(rng, 3, 7)
    huge = _round(rng.normal(0, 1, (_size(rng, 3, 5), _size(rng, 3, 6))))
    huge[0] += 1e4
    huge[1] -= 1e4
    offsets = _round(rng.normal(0, 1, (4, _size(rng, 3, 5))))
    offsets += np.array([[-2e4], [3e4], [800.0], [-900.0]])
    square = _size(rng, 3, 6)
    return [
        Case((_round(rng.normal(0, 2, (n, c))),), {}, "(N, C) scores"),
        Case((_round(rng.normal(0, 2, (square, square))),), {}, "square (N = C): rows, not columns"),
        Case((_round(rng.normal(0, 30, (_size(rng, 4, 8), _size(rng, 5, 10)))),), {}, "scores of tens"),
        Case((huge,), {}, "scores ±1e4 (must stay finite)"),
        Case((offsets,), {}, "rows at −2e4, 3e4, 800 and −900 (a global shift is not enough)"),
        Case((_round(rng.normal(0, 1, (1, _size(rng, 3, 8)))),), {}, "a single row (1, C)"),
        Case((_round(rng.normal(0, 2, _size(rng, 3, 8))),), {}, "1-D scores (C,): one row"),
        Case((_round(rng.normal(0, 2, (_size(rng, 3, 6), 1))),), {}, "one class (all probabilities 1)"),
        Case((np.full((_size(rng, 2, 4), _size(rng, 3, 6)), _u(rng, -5, 5, 2)),), {},
             "constant scores (uniform probabilities)"),
        Case((rng.integers(-5, 6, (_size(rng, 3, 6), _size(rng, 3, 6))),), {}, "integer scores"),
    ]


softmax = Check(
    rules=("integer", "no warnings", "single point"),
    public=[
        Case((np.array([[1.0, 2.0, 0.5, -1.0], [0.0, 0.0, 3.0, 1.0], [-2.0, 1.0, 1.0, 0.0]]),), {},
             "3 × 4 scores"),
        Case((np.array([[1e4, 0.0, -1e4], [-1e4, -1e4 + 1, -1e4 + 2]]),), {},
             "scores ±1e4 in two rows (must stay finite)"),
    ],
    hidden=_softmax_hidden,
    compare=close(rtol=1e-7, atol=1e-12, kind="f"),
    mistakes=[_softmax_no_shift, _softmax_global_shift, _softmax_columns, _softmax_whole_array],
)


# --------------------------------------------------------------------------------------------
# learn.cross_entropy (§9.7.4)
# --------------------------------------------------------------------------------------------
def _ce_parts(scores, y):
    s = np.asarray(scores, dtype=np.float64)
    y = np.asarray(y)
    n = s.shape[0]
    p = _softmax(s)
    onehot = np.zeros_like(p)
    onehot[np.arange(n), y] = 1.0
    loss, _ = _cross_entropy(s, y)
    return s, y, n, p, onehot, loss


@mistake("summed over the samples instead of averaged",
         "The loss is the mean over the N samples, and so its gradient is (p − onehot) / N")
def _ce_summed(scores, y):
    s, y, n, p, onehot, loss = _ce_parts(scores, y)
    return loss * n, p - onehot


@mistake("gradient not divided by N",
         "The loss is a mean over N samples, so each row of the gradient is (p − onehot) / N")
def _ce_grad_not_averaged(scores, y):
    s, y, n, p, onehot, loss = _ce_parts(scores, y)
    return loss, p - onehot


@mistake("gradient missing the −1 at the true class",
         "∂L_i/∂s_j = p_j − [j = y_i]: subtract 1 at the true class of every row")
def _ce_no_minus_one(scores, y):
    s, y, n, p, onehot, loss = _ce_parts(scores, y)
    return loss, p / n


@mistake("−log(softmax) (infinite for large scores)",
         "Compute −s_y + logsumexp(s) with the maximum factored out: log Σ e^s = m + log Σ e^(s−m); "
         "−log(p) of a probability that underflows to 0 is inf")
def _ce_log_of_softmax(scores, y):
    s, y, n, p, onehot, loss = _ce_parts(scores, y)
    return float(-np.mean(np.log(p[np.arange(n), y]))), (p - onehot) / n


@mistake("gradient with the wrong sign",
         "The gradient of the loss is (p − onehot) / N (probabilities minus the one-hot label)")
def _ce_sign(scores, y):
    s, y, n, p, onehot, loss = _ce_parts(scores, y)
    return loss, (onehot - p) / n


def _ce_case(rng, n, c, scale=2.0, label="", integer=False):
    s = rng.integers(-6, 7, (n, c)) if integer else _round(rng.normal(0, scale, (n, c)))
    return Case((s, _labels(rng, n, c)), {}, label)


def _ce_hidden(rng):
    n = _size(rng, 3, 6)
    huge = _round(rng.normal(0, 1, (n, 4)))
    y_huge = _labels(rng, n, 4)
    huge[np.arange(n), (y_huge + 1) % 4] += 1e4  # the true class 1e4 below the best one
    sq = _size(rng, 3, 5)
    zeros = np.zeros((_size(rng, 3, 6), _size(rng, 3, 7)))
    last = _round(rng.normal(0, 1, (_size(rng, 4, 7), 3)))
    return [
        _ce_case(rng, _size(rng, 5, 9), _size(rng, 3, 6), label="(N, C) scores"),
        _ce_case(rng, sq, sq, label="square (N = C)"),
        _ce_case(rng, 1, _size(rng, 3, 6), label="a single sample"),
        _ce_case(rng, _size(rng, 4, 8), 2, label="two classes"),
        Case((huge, y_huge), {}, "true class 1e4 below the best score (loss ≈ 1e4, finite)"),
        Case((_round(rng.normal(0, 1, (3, 3))) + np.array([[3e4], [-3e4], [0.0]]), np.array([0, 1, 2])), {},
             "rows at 3e4 and −3e4"),
        _ce_case(rng, _size(rng, 4, 7), _size(rng, 3, 5), integer=True, label="integer scores"),
        Case((zeros, _labels(rng, zeros.shape[0], zeros.shape[1])), {}, "all-zero scores: loss log C"),
        _ce_case(rng, _size(rng, 5, 8), _size(rng, 3, 5), scale=20.0, label="scores of tens"),
        Case((last, np.full(last.shape[0], 2, dtype=np.int64)), {}, "every sample of the last class"),
    ]


cross_entropy = Check(
    public=[
        Case((np.array([[2.0, 1.0, 0.0], [0.5, 0.5, 2.0], [-1.0, 3.0, 0.0], [1.0, 1.0, 1.0]]),
              np.array([0, 1, 1, 2])), {}, "4 samples, 3 classes"),
        Case((np.array([[1e4, 0.0, -1e4], [0.0, 5e3, 0.0]]), np.array([2, 0])), {},
             "true class 2e4 and 5e3 below the best score"),
    ],
    hidden=_ce_hidden,
    compare=close(rtol=1e-7, atol=1e-10, scaled=True),
    mistakes=[_ce_summed, _ce_grad_not_averaged, _ce_no_minus_one, _ce_log_of_softmax, _ce_sign],
)


# --------------------------------------------------------------------------------------------
# learn.linear_loss_and_grad (§9.7)
# --------------------------------------------------------------------------------------------
def _llg_parts(W, b, X, y, reg):
    W, b, X = (np.asarray(a, dtype=np.float64) for a in (W, b, X))
    y = np.asarray(y)
    loss, dscores = _cross_entropy(X @ W.T + b, y)
    return W, b, X, y, loss, dscores


@mistake("missing factor 2 in the regularisation gradient", "d(λΣW²)/dW = 2λW: add 2 * reg * W to dW")
def _llg_reg_grad_no_2(W, b, X, y, reg=0.0):
    W, b, X, y, loss, g = _llg_parts(W, b, X, y, reg)
    return loss + reg * np.sum(W * W), g.T @ X + reg * W, g.sum(axis=0)


@mistake("loss and gradients summed over the samples, not averaged",
         "Average the data loss over the N samples (and so its gradients); the regularisation "
         "term λΣW² is added once")
def _llg_not_averaged(W, b, X, y, reg=0.0):
    W, b, X, y, loss, g = _llg_parts(W, b, X, y, reg)
    n = X.shape[0]
    return loss * n + reg * np.sum(W * W), n * g.T @ X + 2 * reg * W, n * g.sum(axis=0)


@mistake("bias regularised too",
         "Only W is regularised: loss + reg·ΣW², dW += 2·reg·W, and db is just the column sum "
         "of the score gradient")
def _llg_bias_regularised(W, b, X, y, reg=0.0):
    W, b, X, y, loss, g = _llg_parts(W, b, X, y, reg)
    return (loss + reg * (np.sum(W * W) + np.sum(b * b)), g.T @ X + 2 * reg * W, g.sum(axis=0) + 2 * reg * b)


@mistake("regularisation missing from the loss",
         "The loss includes the penalty: mean cross-entropy + reg * np.sum(W * W)")
def _llg_reg_not_in_loss(W, b, X, y, reg=0.0):
    W, b, X, y, loss, g = _llg_parts(W, b, X, y, reg)
    return loss, g.T @ X + 2 * reg * W, g.sum(axis=0)


@mistake("dW transposed (D, C)", "dW has the shape of W, (C, D): dW = dscores.T @ X + 2·reg·W")
def _llg_dw_transposed(W, b, X, y, reg=0.0):
    W, b, X, y, loss, g = _llg_parts(W, b, X, y, reg)
    return loss + reg * np.sum(W * W), X.T @ g + 2 * reg * W.T, g.sum(axis=0)


def _llg_case(rng, n, d, c, reg, label, kind="normal"):
    if kind == "uint8":
        X = rng.integers(0, 256, (n, d), dtype=np.uint8)
        W = _round(rng.normal(0, 0.01, (c, d)), 4)
    else:
        X = _round(rng.normal(0, 1, (n, d)))
        W = _round(rng.normal(0, 0.5, (c, d)))
    b = _round(rng.normal(0, 1, c)) + 0.25
    return Case((W, b, X, _labels(rng, n, c)), {"reg": reg}, label)


def _llg_hidden(rng):
    return [
        _llg_case(rng, _size(rng, 6, 12), _size(rng, 3, 7), _size(rng, 3, 5), _u(rng, 0.05, 0.5),
                  "reg > 0"),
        _llg_case(rng, _size(rng, 5, 10), _size(rng, 3, 7), _size(rng, 2, 5), 0.0, "reg = 0"),
        _llg_case(rng, 1, _size(rng, 3, 6), _size(rng, 2, 4), 0.1, "a single sample"),
        _llg_case(rng, _size(rng, 4, 8), 3, 3, 0.25, "D = C (square W)"),
        _llg_case(rng, _size(rng, 4, 8), _size(rng, 8, 20), _size(rng, 3, 6), 1e-3, "uint8 pixels, reg 1e-3",
                  kind="uint8"),
        _llg_case(rng, _size(rng, 5, 9), _size(rng, 2, 5), 2, _u(rng, 1.0, 3.0, 2),
                  "two classes, strong reg"),
        _llg_case(rng, _size(rng, 3, 6), 1, _size(rng, 2, 4), 0.5, "one feature"),
        Case((np.zeros((3, 4)), np.zeros(3), _round(rng.normal(0, 1, (5, 4))), _labels(rng, 5, 3)), {"reg": 0.7},
             "W = 0, b = 0 (loss log C)"),
        _llg_case(rng, _size(rng, 10, 20), _size(rng, 4, 8), _size(rng, 4, 7), 0.05, "more samples"),
    ]


linear_loss_and_grad = Check(
    public=[
        Case((np.array([[0.2, -0.5, 0.1, 0.0], [0.4, 0.3, -0.2, 0.5], [-0.3, 0.1, 0.6, -0.1]]),
              np.array([0.1, -0.2, 0.3]),
              np.array([[1.0, 2.0, 0.0, -1.0], [0.5, -1.0, 1.0, 2.0], [0.0, 1.0, 1.0, 0.0],
                        [2.0, 0.0, -1.0, 1.0], [-1.0, 0.5, 0.5, 0.5]]),
              np.array([0, 2, 1, 1, 0])), {"reg": 0.1}, "5 samples, 4 features, 3 classes, reg 0.1"),
    ],
    hidden=_llg_hidden,
    compare=close(rtol=1e-7, atol=1e-10, scaled=True),
    mistakes=[_llg_reg_grad_no_2, _llg_not_averaged, _llg_bias_regularised, _llg_reg_not_in_loss, _llg_dw_transposed],
    allowed=_BUILDING_BLOCKS,
)


# --------------------------------------------------------------------------------------------
# learn.numerical_gradient (§9.8.1)
# --------------------------------------------------------------------------------------------
def _cubic(rng, shape):
    a = _round(rng.uniform(0.5, 2.0, shape)) * rng.choice([-1, 1], shape)
    return "cubic", np.stack([a, _round(rng.normal(0, 2, shape)), _round(rng.normal(0, 1, shape))])


def _exp(rng, shape):
    return "exp", np.stack([_round(rng.uniform(0.5, 2.0, shape)), _round(rng.uniform(2.0, 4.0, shape))])


@mistake("one-sided difference (f(x+h) − f(x))/h",
         "Use the central difference (f(x + h·e_i) − f(x − h·e_i)) / (2h): its error is O(h²), "
         "a one-sided difference's O(h)")
def _ng_forward(f, x, eps=1e-5):
    x = np.array(x, dtype=np.float64)
    grad = np.empty(x.shape)
    base = f(x)
    for i in np.ndindex(x.shape):
        old = x[i]
        x[i] = old + eps
        grad[i] = (f(x) - base) / eps
        x[i] = old
    return grad


@mistake("divided by h instead of 2h", "The two evaluation points are 2h apart: divide f(x+h) − f(x−h) by 2*eps")
def _ng_half_step(f, x, eps=1e-5):
    return 2.0 * _numerical_gradient(f, x, eps)


@mistake("eps ignored (fixed step)", "Use the step the caller passes as eps")
def _ng_eps_ignored(f, x, eps=1e-5):
    return _numerical_gradient(f, x, 1e-5)


@mistake("integer x not converted to float (the step is lost)",
         "Work on a float copy: x = np.array(x, dtype=float); adding 1e-5 to an integer entry changes nothing")
def _ng_integer_x(f, x, eps=1e-5):
    x = np.array(x)  # keeps an integer dtype: old ± eps is truncated back to old
    grad = np.empty(x.shape)
    for i in np.ndindex(x.shape):
        old = x[i]
        x[i] = old + eps
        plus = f(x)
        x[i] = old - eps
        grad[i] = (plus - f(x)) / (2 * eps)
        x[i] = old
    return grad


@mistake("all coordinates moved at once",
         "Move one coordinate at a time: g[i] = (f(x + h·e_i) − f(x − h·e_i)) / (2h) with e_i the "
         "i-th unit vector")
def _ng_all_at_once(f, x, eps=1e-5):
    x = np.asarray(x, dtype=np.float64)
    return np.full(x.shape, (f(x + eps) - f(x - eps)) / (2 * eps))


def _ng_softmax_case(rng, label):
    n, d, c = _size(rng, 4, 7), _size(rng, 2, 4), 3
    X = _round(rng.normal(0, 1, (n, d)))
    table = np.column_stack([X, _labels(rng, n, c)])
    return Case(("softmax_loss", table, _round(rng.normal(0, 1, (c, d)))), {}, label)


def _ng_hidden(rng):
    m = _size(rng, 3, 6)
    A = _round(rng.normal(0, 1, (m, m)))
    A = A @ A.T + np.eye(m)
    return [
        Case((*_cubic(rng, (5,)), _round(rng.uniform(-2, 2, 5))), {}, "cubic, 1-D x, default eps"),
        Case((*_exp(rng, (2, 3)), _round(rng.uniform(-1, 1, (2, 3)))), {}, "Σ w·exp(s·x), 2-D x"),
        Case((*_cubic(rng, (2, 2, 2)), _round(rng.uniform(-2, 2, (2, 2, 2)))), {"eps": 1e-3}, "3-D x, eps 1e-3"),
        Case((*_cubic(rng, (4,)), _round(rng.uniform(-2, 2, 4))), {"eps": 0.1}, "eps 0.1 (a visible truncation error)"),
        Case((*_cubic(rng, (3, 2)), rng.integers(-3, 4, (3, 2))), {"eps": 1e-4}, "integer x (compute in float)"),
        Case(("quadratic", np.vstack([A, _round(rng.normal(0, 1, m))]), _round(rng.normal(0, 1, m))),
             {"eps": 1e-4}, "quadratic form"),
        _ng_softmax_case(rng, "softmax loss as a function of W (C, D)"),
        Case(("linear", _round(rng.normal(0, 1, (1, 2, 4))), _round(rng.normal(0, 1, (2, 4)))),
             {"eps": 0.5}, "linear f, eps 0.5 (exact)"),
        Case((*_cubic(rng, (1,)), _round(rng.uniform(1, 2, 1))), {"eps": 0.01}, "a single coordinate, eps 0.01"),
        Case((*_exp(rng, (6,)), _round(rng.uniform(-0.5, 0.5, 6))), {"eps": 2e-3}, "exponentials, eps 2e-3"),
    ]


numerical_gradient = Check(
    rules=("integer",),
    public=[
        Case(("cubic", np.array([[1.0, -2.0, 0.5, 1.5], [0.5, 1.0, -1.0, 0.0], [1.0, 0.0, 2.0, -1.0]]),
              np.array([1.0, -0.5, 2.0, 0.3])), {}, "cubic, 1-D x, default eps"),
        Case(("exp", np.array([[[1.0, 0.5, 2.0], [1.5, 1.0, 0.5]], [[3.0, 2.0, 4.0], [2.5, 3.0, 2.0]]]),
              np.array([[0, 1, -1], [1, 0, 0]])), {"eps": 0.01}, "exponentials, integer 2-D x, eps 0.01"),
    ],
    hidden=_ng_hidden,
    compare=close(rtol=1e-6, atol=1e-8, kind="f", scaled=True),
    call=call_with_test_function,
    arg_names=("function", "table", "x"),
    mistakes=[
        _ng_forward,
        _ng_half_step,
        _ng_eps_ignored,
        _ng_integer_x,
        _ng_all_at_once,
    ],
)


# --------------------------------------------------------------------------------------------
# learn.sgd_train (§9.8.3–9.8.4)
# --------------------------------------------------------------------------------------------
def _objective(W, b, X, y, reg):
    """J(W, b) = mean cross-entropy + reg·ΣW² on the whole training set."""
    X = np.asarray(X, dtype=np.float64)
    with np.errstate(all="ignore"):
        s = X @ W.T + b
        s = s - s.max(axis=1, keepdims=True)
        n = X.shape[0]
        value = float(np.mean(np.log(np.exp(s).sum(axis=1)) - s[np.arange(n), y]) + reg * np.sum(W * W))
    return value if np.isfinite(value) else float("inf")


@dataclass
class SGDResult(Comparator):
    """Judge ``(W, b, losses)`` of a training run.

    Full-batch cases (``batch_size ≥ N``) do not depend on the shuffle: everything is
    compared with ``allclose``. Otherwise the training objective of the returned weights and
    the last epoch's loss must be within ``case.tolerance`` of the reference's.
    """

    exact: Close = field(default_factory=lambda: close(rtol=1e-6, atol=1e-9, kind="f", scaled=True))

    def describe(self) -> str:
        return "full batch: allclose; mini-batches: training objective and last loss within a tolerance"

    def __call__(self, got, expected, case=None):
        problem = _as_tuple(got, 3, "(W, b, losses)")
        if problem:
            return problem
        W_exp, b_exp, losses_exp = (np.asarray(v) for v in expected)
        X, y, batch = _arg(case, 0, "X"), _arg(case, 1, "y"), _arg(case, 5, "batch_size")
        reg = float(_arg(case, 6, "reg", 0.0))
        parts = []
        for value, name, shape in zip(got, ("W", "b", "losses"), (W_exp.shape, b_exp.shape, losses_exp.shape)):
            arr, problem = _numeric(value, name, shape)
            if problem:
                if name == "losses" and "shape" in problem.message:
                    problem.message += " (one mean loss per epoch)"
                return problem
            parts.append(arr.astype(np.float64))
        W, b, losses = parts
        if not (np.all(np.isfinite(W)) and np.all(np.isfinite(b)) and np.all(np.isfinite(losses))):
            return Mismatch("W, b or losses contain NaN or inf (the training diverged)")
        n = np.shape(X)[0]
        if batch >= n:
            mismatch = self.exact((W, b, losses), (W_exp, b_exp, losses_exp), case)
            if mismatch is not None:
                mismatch.message = ("full-batch training (batch_size ≥ N) does not depend on the shuffle, "
                                    "so it must match exactly; " + mismatch.message.replace("result [0]", "W")
                                    .replace("result [1]", "b").replace("result [2]", "losses"))
            return mismatch
        tolerance = getattr(case, "tolerance", 0.05)
        stats = {
            "training objective J(W, b) of the returned weights": (_objective(W, b, X, y, reg),
                                                                    _objective(W_exp, b_exp, X, y, reg)),
            "mean loss of the last epoch (losses[-1])": (float(losses[-1]), float(losses_exp[-1])),
        }
        wrong = [f"{name}: yours {mine:.6g}, expected {ref:.6g} ± {tolerance:.3g}"
                 for name, (mine, ref) in stats.items() if not abs(mine - ref) <= tolerance]
        if wrong:
            return Mismatch("The training result differs from a correct run (two correct runs with "
                            "different shuffles agree within the tolerance):\n" + "\n".join(wrong))
        return None


@dataclass
class _SGDCase(Case):
    tolerance: float = 0.05


def _sgd_loop(X, y, classes, lr, epochs, batch_size, reg=0.0, rng=None, *, shuffle=True, sign=1.0, sum_steps=False,
              bias=True, loss_sum=False, one_batch=False, shuffle_once=False, replace=False):
    """SGD with switches for the mistakes (built on the reference loss and gradient)."""
    X = np.asarray(X, dtype=np.float64)
    y = np.asarray(y)
    n, d = X.shape
    gen = np.random.default_rng(rng)
    W, b = np.zeros((classes, d)), np.zeros(classes)
    losses = []
    first = gen.permutation(n)
    for epoch in range(epochs):
        if replace:
            order = gen.integers(0, n, n)
        elif shuffle_once:
            order = first
        else:
            order = (first if epoch == 0 else gen.permutation(n)) if shuffle else np.arange(n)
        total, count, batches = 0.0, 0, 0
        starts = [0] if one_batch else range(0, n, batch_size)
        for start in starts:
            idx = order[start:start + batch_size]
            loss, dW, db = _loss_and_grad(W, b, X[idx], y[idx], reg)
            factor = idx.size if sum_steps else 1.0
            W = W - sign * lr * factor * dW
            if bias:
                b = b - sign * lr * factor * db
            total += loss * idx.size
            count += idx.size
            batches += 1
        losses.append(total / count * batches if loss_sum else total / count)
    return W, b, np.array(losses)


_sgd_no_shuffle = variant(_sgd_loop, shuffle=False)
_sgd_ascent = variant(_sgd_loop, sign=-1.0)
_sgd_summed_steps = variant(_sgd_loop, sum_steps=True)
_sgd_no_bias = variant(_sgd_loop, bias=False)
_sgd_loss_sum = variant(_sgd_loop, loss_sum=True)
_sgd_one_batch = variant(_sgd_loop, one_batch=True)
_sgd_shuffled_once = variant(_sgd_loop, shuffle_once=True)
_sgd_with_replacement = variant(_sgd_loop, replace=True)

#: the statistics of a ``draws`` case of sgd_train (many runs, one seed each)
_SGD_DRAWS = ("different results (W, b) over the runs",)


def _sgd_draw_statistics(outputs, case):
    """Two samples, B = 1: each epoch's order is one of two, so E epochs of fresh shuffles end
    in 2**E results (W, b), each as likely; one shuffle for all epochs in 2, none in 1."""
    results = [np.round(np.concatenate([np.ravel(np.asarray(W, dtype=np.float64)),
                                        np.ravel(np.asarray(b, dtype=np.float64))]), 9).tobytes()
               for W, b, _ in outputs]
    return {_SGD_DRAWS[0]: float(len(set(results)))}


def _sgd_draw_tolerance(case):
    return {_SGD_DRAWS[0]: 0.0}


def _sgd_draws_case(X, y, classes, lr, epochs, first, label):
    """Many runs on two samples with B = 1 (``draws``): only the distribution of the results
    over the seeds tells a fresh shuffle per epoch from one shuffle for all (one run's
    result is judged as finite only: any order is a correct order)."""
    return _SGDCase((X, y, classes, lr, epochs, 1), {"reg": 0.0, "draws": (first, 400)}, label,
                    tolerance=float("inf"))


def _full_batch_case(rng, label, n=None, d=None, c=None, reg=None, uint8=False):
    n = n or _size(rng, 12, 30)
    d = d or _size(rng, 2, 5)
    c = c or _size(rng, 2, 4)
    X, y = _blobs(rng, n, d, c, spread=1.0)
    y = y.copy()
    y[: n // 3] = 0  # unbalanced classes: the bias must move
    lr = _u(rng, 0.1, 0.5, 2)
    if uint8:
        X = rng.integers(0, 256, (n, d), dtype=np.uint8)
        lr = 1e-4
    reg = _u(rng, 0.01, 0.2) if reg is None else reg
    batch = n if rng.random() < 0.5 else n + _size(rng, 1, 20)
    return Case((X, y, c, lr, _size(rng, 3, 12), batch), {"reg": reg, "rng": _seed(rng)}, label)


def _one_class_per_batch_case(rng, label, c=None):
    """Labels sorted by class and B = N / C: without shuffling every batch holds one class.
    The second feature tells the classes apart a little (means 0.5 apart, spread 0.3): a
    correct run ends well below the ln C of weights that learned nothing (0.50 against 0.69
    for two classes, 0.67 against 1.10 for three), so zeros cannot pass for training."""
    c = c or _size(rng, 2, 3)
    per = {2: 100, 3: 50}[c]
    n = per * c
    y = np.repeat(np.arange(c), per).astype(np.int64)
    X = np.column_stack([np.ones(n), _round(0.5 * (y - (c - 1) / 2) + 0.3 * rng.standard_normal(n))])
    lr = {2: 1.0, 3: 1.5}[c]
    return _SGDCase((X, y, c, lr, 10, per), {"reg": 0.0, "rng": _seed(rng)}, label, tolerance={2: 0.1, 3: 0.3}[c])


def _mini_batch_case(rng, label):
    """Overlapping clusters, features of order 1, lr·‖x‖² small: correct runs agree to ~0.01."""
    batch = int(rng.choice([8, 10]))
    n = batch * _size(rng, 6, 10)  # B divides N: the mean loss of an epoch is unambiguous
    c = _size(rng, 3, 4)
    X, y = _blobs(rng, n, _size(rng, 2, 4), c, spread=0.5, distance=1.0, shuffle=False)
    return _SGDCase((X, y, c, 0.1, 10, batch),
                    {"reg": float(rng.choice([0.01, 0.05])), "rng": _seed(rng)}, label, tolerance=0.05)


def _small_batch_case(rng, label, n=72, d=3, c=3):
    """Many small batches (B = 4, lr 0.1): correct runs agree to < 0.01; one batch per epoch
    stays ≥ 0.1 away."""
    X, y = _blobs(rng, n, d, c, spread=0.5, distance=1.0, shuffle=False)
    return _SGDCase((X, y, c, 0.1, 10, 4), {"reg": 0.05, "rng": _seed(rng)}, label, tolerance=0.05)


def _sgd_hidden(rng):
    return [
        _full_batch_case(rng, "batch_size ≥ N (gradient descent): exact"),
        _full_batch_case(rng, "full batch, reg 0", reg=0.0),
        _full_batch_case(rng, "full batch, one feature", d=1),
        _full_batch_case(rng, "full batch, two classes", c=2),
        _full_batch_case(rng, "full batch, uint8 pixels, lr 1e-4", uint8=True),
        Case((np.array([[1.0, 2.0]]), np.array([1]), 3, 0.5, 4, 1), {"reg": 0.1, "rng": _seed(rng)},
             "a single sample, B = 1"),
        _one_class_per_batch_case(rng, "sorted labels, B = N/2: one class per batch unless shuffled", c=2),
        _one_class_per_batch_case(rng, "sorted labels, B = N/3: one class per batch unless shuffled", c=3),
        _mini_batch_case(rng, "mini-batches on sorted blobs"),
        _small_batch_case(rng, "many small batches (B = 4)", n=4 * _size(rng, 15, 20), d=_size(rng, 2, 4)),
        _small_batch_case(rng, "many small batches (B = 4), 4 classes", n=4 * _size(rng, 15, 20), c=4),
        _sgd_draws_case(_round(rng.normal(0, 1, (2, _size(rng, 2, 3)))), np.array([0, 1]), _size(rng, 2, 3),
                        _u(rng, 0.5, 1.5, 2), 3, _seed(rng),
                        "400 runs on 2 samples, B = 1, 3 epochs, rng = r, r + 1, …: a fresh shuffle each epoch"),
    ]


def _sgd_public():
    rng = np.random.default_rng(900)
    X, y = _blobs(rng, 20, 3, 3, spread=1.0)
    y[:6] = 0
    return [
        Case((X, y, 3, 0.3, 5, 20), {"reg": 0.05, "rng": 0}, "full batch (B = N = 20): exact"),
        _SGDCase((np.column_stack([np.ones(200), _round(0.3 * rng.standard_normal(200))]),
                  np.repeat([0, 1], 100), 2, 1.0, 10, 100), {"reg": 0.0, "rng": 1},
                 "sorted labels, B = N/2: one class per batch unless shuffled", tolerance=0.1),
        _small_batch_case(rng, "64 samples, many small batches (B = 4)", n=64),
        _sgd_draws_case(np.array([[1.0, 0.5], [-0.5, 1.0]]), np.array([0, 1]), 2, 1.0, 2, 2000,
                        "400 runs on 2 samples, B = 1, 2 epochs, rng = 2000, 2001, …: a fresh shuffle each epoch"),
    ]


sgd_train = Check(
    public=_sgd_public,
    hidden=_sgd_hidden,
    compare=Drawn(single=SGDResult(), statistics=_sgd_draw_statistics, tolerance=_sgd_draw_tolerance),
    call=call_draws,
    mistakes=[
        Mistake("no shuffling (the same batches every epoch)", _sgd_no_shuffle,
                "Draw a fresh permutation every epoch, order = rng.permutation(N), and cut the batches "
                "from X[order]: sorted data then still gives mixed batches"),
        Mistake("one shuffle for all epochs", _sgd_shuffled_once,
                "Draw the permutation inside the epoch loop, order = rng.permutation(N) at the start of "
                "every epoch: the same batches every epoch let the model learn their order"),
        Mistake("samples drawn with replacement, not a shuffle", _sgd_with_replacement,
                "An epoch visits every sample exactly once: cut the batches from a permutation, "
                "order = rng.permutation(N), not from rng.integers(0, N, N)"),
        Mistake("gradient ascent (W += lr·dW)", _sgd_ascent,
                "Step against the gradient: W -= lr * dW and b -= lr * db"),
        Mistake("one mini-batch per epoch instead of ⌈N/B⌉", _sgd_one_batch,
                "An epoch is one pass over the whole training set: loop over all batches "
                "order[start:start + B] for start in range(0, N, B)"),
        Mistake("steps scaled by the batch size (summed gradients)", _sgd_summed_steps,
                "linear_loss_and_grad already averages over the batch: step by lr * dW, not lr * B * dW"),
        Mistake("bias never updated", _sgd_no_bias,
                "Update the bias too: b -= lr * db"),
        Mistake("epoch loss summed over the batches, not averaged", _sgd_loss_sum,
                "losses[e] is the mean over the epoch: Σ batch_loss·batch_size / N"),
    ],
    allowed=_BUILDING_BLOCKS + ("learn.linear_loss_and_grad",),
    seeded=True,
)


# --------------------------------------------------------------------------------------------
# learn.top_k_accuracy (§9.5)
# --------------------------------------------------------------------------------------------
def _topk_sorted(scores, y, k=5, descending=True, stable=True):
    s = np.asarray(scores, dtype=np.float64)
    order = np.argsort(-s if descending else s, axis=1, kind="stable" if stable else "quicksort")[:, :k]
    return float(np.mean(np.any(order == np.asarray(y)[:, None], axis=1)))


_topk_smallest = variant(_topk_sorted, descending=False)


@mistake("number of hits instead of the fraction", "Return the fraction of samples that are hits (divide by N)")
def _topk_count(scores, y, k=5):
    s = np.asarray(scores, dtype=np.float64)
    true = s[np.arange(s.shape[0]), np.asarray(y)]
    return float(np.sum(np.count_nonzero(s > true[:, None], axis=1) < k))


@mistake("ties at the k-th score counted as misses",
         "A sort puts equal scores in an arbitrary order: count the scores strictly greater than "
         "the true class's score and call it a hit when fewer than k are")
def _topk_ties_miss(scores, y, k=5):
    return _topk_sorted(scores, y, k)


@mistake("k ignored (top-1 accuracy)", "Use k: a hit is a true label among the k highest scores")
def _topk_top1(scores, y, k=5):
    s = np.asarray(scores, dtype=np.float64)
    return float(np.mean(s.argmax(axis=1) == np.asarray(y)))


@mistake("top-(k+1): hit when k scores or fewer are higher",
         "The true class is in the top k when FEWER than k scores beat it (rank < k)")
def _topk_off_by_one(scores, y, k=5):
    s = np.asarray(scores, dtype=np.float64)
    true = s[np.arange(s.shape[0]), np.asarray(y)]
    return float(np.mean(np.count_nonzero(s > true[:, None], axis=1) <= k))


def _topk_case(rng, n, c, k, label, kind="normal"):
    if kind == "ties":
        s = rng.integers(0, 4, (n, c)).astype(np.float64)
    elif kind == "uint8":
        s = rng.integers(0, 256, (n, c), dtype=np.uint8)
    elif kind == "probabilities":
        s = _softmax(rng.normal(0, 2, (n, c)))
    else:
        s = _round(rng.normal(0, 2, (n, c)))
    return Case((s, _labels(rng, n, c, every=False)), {"k": k}, label)


def _topk_ties_case(rng, n, c, k):
    """Scores with ties in which the true class shares the k-th score with a lower class."""
    s = rng.integers(0, 5, (n, c)).astype(np.float64)
    y = _labels(rng, n, c, every=False)
    for i in range(0, n, 2):  # half the rows: the true class tied at the k-th place, behind a lower index
        order = rng.permutation(c)
        values = np.arange(c, 0, -1, dtype=np.float64)
        values[k - 1] = values[k] = values[k - 1]  # places k−1 and k tied
        s[i, order] = values
        lower, upper = sorted((order[k - 1], order[k]))
        y[i] = upper
    return Case((s, y), {"k": k}, f"ties at the k-th score (k = {k})")


def _topk_hidden(rng):
    c = _size(rng, 5, 8)
    return [
        _topk_case(rng, _size(rng, 15, 30), c, _size(rng, 2, 3), "distinct scores"),
        _topk_case(rng, _size(rng, 15, 30), _size(rng, 4, 8), 1, "k = 1 (accuracy)"),
        _topk_case(rng, _size(rng, 5, 10), c, c, "k = C (always 1)"),
        _topk_case(rng, _size(rng, 15, 30), _size(rng, 6, 10), 5, "default-like k = 5"),
        _topk_ties_case(rng, _size(rng, 15, 30), _size(rng, 4, 6), 2),
        _topk_ties_case(rng, _size(rng, 15, 30), _size(rng, 5, 7), 3),
        _topk_case(rng, _size(rng, 15, 30), _size(rng, 3, 6), 2, "integer scores with many ties", kind="ties"),
        _topk_case(rng, 1, _size(rng, 3, 6), 2, "a single sample"),
        _topk_case(rng, _size(rng, 6, 12), _size(rng, 4, 8), 3, "uint8 scores", kind="uint8"),
        _topk_case(rng, _size(rng, 6, 12), _size(rng, 4, 8), 2, "softmax probabilities", kind="probabilities"),
        Case((_round(rng.normal(0, 1, (6, 4))), np.full(6, 3)), {"k": 2}, "every sample of the last class"),
    ]


top_k_accuracy = Check(
    rules=("integer",),
    public=[
        Case((np.array([[0.9, 0.1, 0.5, 0.3], [0.2, 0.8, 0.7, 0.1], [0.1, 0.2, 0.3, 0.4], [0.6, 0.5, 0.4, 0.3],
                        [0.25, 0.35, 0.15, 0.05], [0.3, 0.1, 0.2, 0.9]]),
              np.array([2, 0, 0, 1, 1, 3])), {"k": 2}, "6 samples, 4 classes, k = 2"),
        Case((np.array([[3.0, 2.0, 2.0, 1.0], [1.0, 3.0, 3.0, 2.0], [2.0, 2.0, 2.0, 2.0], [0.0, 1.0, 2.0, 3.0]]),
              np.array([2, 2, 3, 3])), {"k": 2}, "ties at the second score, k = 2"),
        Case((np.array([[0.5, 0.3, 0.3, 0.1, 0.1], [0.0, 0.0, 0.0, 0.1, 0.4], [0.3, 0.5, 0.3, 0.3, 0.5],
                        [0.4, 0.3, 0.3, 0.3, 0.5], [0.1, 0.4, 0.4, 0.0, 0.2]]),
              np.array([4, 2, 0, 3, 3])), {"k": 3}, "5 samples, 5 classes, k = 3"),
    ],
    hidden=_topk_hidden,
    refusals=[
        Case((np.arange(20, dtype=np.float64).reshape(5, 4) % 3, np.array([0, 1, 2, 3, 0])), {"k": 5},
             "k = 5 with 4 classes", raises="ValueError"),
    ],
    compare=close(rtol=0.0, atol=1e-12),
    mistakes=[
        _topk_ties_miss,
        Mistake("the k smallest scores", _topk_smallest,
                "Take the k HIGHEST scores: np.argsort(-scores, axis=1)[:, :k] (or count the scores "
                "greater than the true one)"),
        _topk_count,
        _topk_top1,
        _topk_off_by_one,
    ],
)


# --------------------------------------------------------------------------------------------
# learn.knn_predict (§10.1)
# --------------------------------------------------------------------------------------------
def _knn_order(X_train, X_test, metric, farthest=False, later_first=False):
    A = np.asarray(X_train, dtype=np.float64)
    B = np.asarray(X_test, dtype=np.float64)
    d = exact_squared_distances(B, A) if metric == "l2" else exact_l1_distances(B, A)
    idx = np.broadcast_to(np.arange(A.shape[0]), d.shape)
    if farthest:
        d = -d
    return np.lexsort((-idx if later_first else idx, d), axis=1)


def _knn_vote(labels, neighbours, rule="smallest"):
    out = np.empty(neighbours.shape[0], dtype=np.int64)
    for i, row in enumerate(neighbours):
        votes = [int(v) for v in labels[row]]
        if rule == "nearest":
            out[i] = Counter(votes).most_common(1)[0][0]
        else:
            counts = Counter(votes)
            top = max(counts.values())
            tied = [lab for lab, cnt in counts.items() if cnt == top]
            out[i] = max(tied) if rule == "largest" else min(tied)
    return out


def _knn_generic(X_train, y_train, X_test, k=1, metric="l2", *, farthest=False, later_first=False, rule="smallest"):
    order = _knn_order(X_train, X_test, metric, farthest, later_first)[:, :k]
    return _knn_vote(np.asarray(y_train), order, rule)


_knn_farthest = variant(_knn_generic, farthest=True)


@mistake("k ignored (always the nearest sample)",
         "Let the k nearest samples vote: take the first k indices of the sorted distances")
def _knn_k_ignored(X_train, y_train, X_test, k=1, metric="l2"):
    return _knn_generic(X_train, y_train, X_test, 1, metric)


@mistake("metric ignored (always L2)", "metric='l1' is the Manhattan distance Σ|a − b|")
def _knn_metric_ignored(X_train, y_train, X_test, k=1, metric="l2"):
    return _knn_generic(X_train, y_train, X_test, k, "l2")


_knn_nearest_wins_tie = variant(_knn_generic, rule="nearest")
_knn_largest_wins_tie = variant(_knn_generic, rule="largest")
_knn_later_first = variant(_knn_generic, later_first=True)


def _knn_grid_case(rng, n, m, k, metric, label, d=2, side=4, classes=3, dtype=np.float64):
    """Integer points on a small grid: many exactly equal distances and vote ties."""
    X = rng.integers(0, side, (n, d)).astype(dtype)
    Q = rng.integers(0, side, (m, d)).astype(dtype)
    return Case((X, _labels(rng, n, classes), Q), {"k": k, "metric": metric}, label)


def _knn_float_case(rng, n, m, k, metric, label, d=3, classes=2):
    X, y = _blobs(rng, n, d, classes, spread=1.0, distance=1.5)
    Q = _round(rng.normal(0, 2, (m, d)))
    return Case((X, y, Q), {"k": k, "metric": metric}, label)


def _vote_rules_pattern(rng):
    """7 nearest samples voting a, c, b, d, c, b, d (b < c < d): the smallest tied label b, the
    first tied label met c, the largest d and the nearest sample's a all differ."""
    labels = rng.choice(6, 4, replace=False)
    a, (b, c, d) = labels[0], sorted(labels[1:])
    offsets = np.array([[1.0, 0.0], [0.0, 2.0], [-3.0, 0.0], [0.0, -4.0], [5.0, 0.0], [0.0, 6.0], [-7.0, 0.0],
                        [0.0, 20.0]])
    return offsets, np.array([a, c, b, d, c, b, d, rng.integers(0, 6)])


def _knn_groups_case(rng, label, pattern, k, metric, groups=4):
    """Queries far apart from each other (one per group), each with its own training samples:
    ``pattern(rng)`` gives the offsets (n, 2) and labels of one group around its query."""
    X, y, Q = [], [], []
    for g in range(groups):
        centre = np.array([100.0 * g, 0.0])
        offsets, labels = pattern(rng)
        flip = rng.choice([-1.0, 1.0], 2)
        if rng.random() < 0.5:
            offsets = offsets[:, ::-1]
        X.append(centre + offsets * flip)
        y.append(labels)
        Q.append(centre)
    X, y = np.concatenate(X), np.concatenate(y).astype(np.int64)
    order = rng.permutation(len(X))
    return Case((X[order], y[order], np.array(Q)), {"k": k, "metric": metric}, label)


def _outvoted_pattern(rng):
    """The nearest sample (label a) is outvoted by the next two (label b)."""
    a, b, c = rng.choice(5, 3, replace=False)
    return np.array([[1.0, 0.0], [0.0, 2.0], [-3.0, 0.0], [0.0, -9.0]]), np.array([a, b, b, c])


def _metric_pattern(rng):
    """Nearest by L1: (0, 3) (distance 3; L2 distance 3); nearest by L2: (2, 2) (L1 4, L2 2.83)."""
    a, b = rng.choice(5, 2, replace=False)
    return np.array([[2.0, 2.0], [0.0, 3.0], [5.0, 5.0]]), np.array([a, b, a])


def _metric3_pattern(rng):
    """k = 3: the three L1-nearest vote b, b, a; the three L2-nearest a, a, b."""
    a, b = rng.choice(5, 2, replace=False)
    return np.array([[2.0, 2.0], [0.0, 3.0], [0.0, -3.0], [-2.1, -2.1], [6.0, 6.0]]), np.array([a, b, b, a, b])


def _outvoted5_pattern(rng):
    """k = 5 with sparse labels: the nearest sample's label a gets 1 vote, b gets 3."""
    a, b, c = rng.choice([0, 3, 7, 9], 3, replace=False)
    return (np.array([[1.0, 0.0], [0.0, 2.0], [-3.0, 0.0], [0.0, -4.0], [5.0, 0.0], [0.0, 30.0]]),
            np.array([a, b, c, b, b, a]))


def _knn_hidden(rng):
    return [
        _knn_float_case(rng, _size(rng, 15, 25), _size(rng, 6, 10), 1, "l2", "k = 1, L2"),
        _knn_float_case(rng, _size(rng, 15, 25), _size(rng, 8, 12), 3, "l1", "k = 3, L1"),
        _knn_float_case(rng, _size(rng, 20, 30), _size(rng, 8, 12), 5, "l2", "k = 5, L2"),
        _knn_grid_case(rng, _size(rng, 12, 20), 12, 1, "l2", "integer grid, k = 1: equal distances"),
        _knn_grid_case(rng, _size(rng, 12, 20), 16, 2, "l2", "integer grid, k = 2: vote ties", side=3),
        _knn_grid_case(rng, _size(rng, 12, 20), 12, 4, "l1", "integer grid, k = 4, L1"),
        _knn_grid_case(rng, _size(rng, 12, 20), 12, 3, "l1", "integer grid, k = 3, L1, 1-D points", d=1, side=8),
        _knn_grid_case(rng, 9, 6, 9, "l2", "k = N (every training sample votes)"),
        _knn_grid_case(rng, _size(rng, 14, 20), 14, 5, "l2", "uint8 points, k = 5, 4 classes", side=5,
                       dtype=np.uint8, classes=4),
        _knn_groups_case(rng, "the 3 nearest by L1 and by L2 vote differently (k = 3, L1)", _metric3_pattern, 3, "l1"),
        _knn_groups_case(rng, "7 neighbours voting a, c, b, d, c, b, d (a three-way tie)", _vote_rules_pattern, 7,
                         str(rng.choice(["l1", "l2"]))),
        _knn_groups_case(rng, "the nearest sample outvoted by the next two (k = 3)", _outvoted_pattern, 3,
                         str(rng.choice(["l1", "l2"]))),
        _knn_groups_case(rng, "L1-nearest and L2-nearest samples differ (k = 1, L1)", _metric_pattern, 1, "l1"),
        _knn_groups_case(rng, "labels 0, 3, 7, 9 only; the nearest outvoted (k = 5)", _outvoted5_pattern, 5,
                         str(rng.choice(["l1", "l2"]))),
    ]


knn_predict = Check(
    public=[
        Case((np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [5.0, 5.0], [6.0, 5.0], [5.0, 7.0], [9.0, 0.0], [9.0, 3.0]]),
              np.array([2, 1, 0, 1, 0, 2, 1, 0]),
              np.array([[1.0, 0.0], [0.0, 1.0], [5.0, 6.0], [9.0, 1.0], [8.0, 2.0]])),
             {"k": 2, "metric": "l2"}, "8 points, 5 queries, k = 2 (equal distances and vote ties)"),
        Case((np.array([[2.0, 2.0], [0.0, 3.0], [6.0, 0.0], [10.0, 10.0], [5.0, 4.0]]), np.array([0, 1, 2, 1, 2]),
              np.array([[0.0, 0.0], [5.0, 1.0], [1.0, 2.5], [1.0, 1.0], [7.0, 7.0]])),
             {"k": 1, "metric": "l1"}, "5 points, 4 queries, k = 1, L1 (nearest by L1 ≠ nearest by L2)"),
        Case((np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [4.0, 4.0], [5.0, 4.0], [9.0, 9.0]]),
              np.array([1, 1, 0, 0, 2, 2]),
              np.array([[0.2, 0.3], [4.4, 4.0], [1.0, 1.0], [0.0, 0.8]])), {"k": 3, "metric": "l2"},
             "k = 3 (the majority is not the nearest sample's label)"),
    ],
    hidden=_knn_hidden,
    compare=close(rtol=0.0, atol=0.0, kind="iu"),
    mistakes=[
        Mistake("the k farthest samples", _knn_farthest,
                "Sort the distances in increasing order: the nearest neighbours come first"),
        Mistake("vote ties go to the nearest neighbour's label", _knn_nearest_wins_tie,
                "Counter.most_common breaks ties by first appearance: count the votes per label "
                "(np.bincount) and take argmax, which gives ties to the smallest label"),
        _knn_k_ignored,
        _knn_metric_ignored,
        Mistake("vote ties go to the largest label", _knn_largest_wins_tie,
                "Among labels with the same number of votes take the smallest (np.argmax of the counts)"),
        Mistake("equal distances: later training sample first", _knn_later_first,
                "Use a stable sort (np.argsort(d, kind='stable')) so that equal distances keep the "
                "training order"),
    ],
)


# --------------------------------------------------------------------------------------------
# learn.kmeans (§10.3.2)
# --------------------------------------------------------------------------------------------
def _inertia(X, centers, labels) -> float:
    X = np.asarray(X, dtype=np.float64)
    return float(np.sum((X - centers[labels]) ** 2))


def _mean_gap(X, centers, labels) -> float:
    """Largest distance between a centre and the mean of its samples (0 at a fixed point)."""
    X = np.asarray(X, dtype=np.float64)
    gap = 0.0
    for j in np.unique(labels):
        gap = max(gap, float(np.linalg.norm(X[labels == j].mean(axis=0) - centers[j])))
    return gap


@dataclass
class KMeansResult(Comparator):
    """Judge ``(centers, labels)``.

    With ``init`` the algorithm is deterministic: ``allclose`` centres and equal labels.
    With k-means++ seeding: the labels must be the nearest returned centres, the centres the
    means of their samples, and the inertia that of the reference (data with well separated
    clusters, where every correct version reaches the same optimum). A call of a ``draws``
    case (points spread evenly, no clear clusters: each seed may end in another local optimum)
    is not held to the reference's inertia, only to being a converged result of Lloyd's
    algorithm; :class:`~cvkit.grading.Drawn` then compares how the results vary with the seed.
    """

    rtol: float = 1e-7

    def describe(self) -> str:
        return "init given: allclose; k-means++: nearest labels, centres = means, same inertia"

    def __call__(self, got, expected, case=None):
        problem = _as_tuple(got, 2, "(centers, labels)")
        if problem:
            return problem
        C_exp, l_exp = (np.asarray(v) for v in expected)
        C, problem = _numeric(got[0], "centers", C_exp.shape)
        if problem:
            return problem
        labels, problem = _numeric(got[1], "labels", l_exp.shape, kind="i")
        if problem:
            return problem
        C = C.astype(np.float64)
        X = np.asarray(case.args[0], dtype=np.float64)
        k = C_exp.shape[0]
        scale = max(1.0, float(np.abs(X).max()))
        nan_rows = sorted({int(i) for i in np.argwhere(~np.isfinite(C))[:, 0]})
        if nan_rows and np.all(np.isfinite(C_exp)):
            return Mismatch(f"centers contain NaN or inf (rows {nan_rows}): an empty cluster has no mean; "
                            "re-seed it instead")
        if case.kwargs.get("init") is not None:
            mismatch = close(rtol=self.rtol, atol=1e-9, scaled=True)(C, C_exp, case)
            if mismatch is not None:
                mismatch.message = "with init given k-means is deterministic; centers differ:\n" + mismatch.message
                return mismatch
            bad = np.flatnonzero(labels != l_exp)
            if bad.size:
                return Mismatch(f"with init given k-means is deterministic; labels differ at {bad.size} of "
                                f"{labels.size} samples (first at sample {bad[0]}: yours {labels[bad[0]]}, "
                                f"expected {l_exp[bad[0]]})", mismatched=int(bad.size), total=int(labels.size))
            return None
        if nan_rows:
            return Mismatch(f"centers contain NaN or inf (rows {nan_rows})")
        if labels.size and (labels.min() < 0 or labels.max() >= k):
            return Mismatch(f"labels must be in 0..{k - 1}, got values from {labels.min()} to {labels.max()}")
        d = exact_squared_distances(X, C)
        own = d[np.arange(X.shape[0]), labels]
        worse = np.flatnonzero(own > d.min(axis=1) + 1e-9 * scale ** 2)
        if worse.size:
            i = int(worse[0])
            return Mismatch(f"labels are not the nearest returned centres at {worse.size} samples (first: sample "
                            f"{i} has label {labels[i]} but centre {int(d[i].argmin())} is nearer): recompute "
                            "the labels for the centres you return")
        wrong = []
        gap_got, gap_exp = _mean_gap(X, C, labels), _mean_gap(X, C_exp, l_exp)
        if gap_exp <= 1e-9 * scale and gap_got > 1e-7 * scale:
            wrong.append(f"largest distance between a centre and the mean of its samples: yours {gap_got:.6g}, "
                         f"expected 0 (the algorithm had converged)")
        empty_got = k - np.unique(labels).size
        empty_exp = k - np.unique(l_exp).size
        if empty_got != empty_exp:
            wrong.append(f"clusters without any sample: yours {empty_got}, expected {empty_exp}")
        inertia_got, inertia_exp = _inertia(X, C, labels), _inertia(X, C_exp, l_exp)
        if case.kwargs.get("draws") is None and not abs(inertia_got - inertia_exp) <= 1e-6 * inertia_exp + 1e-9 * scale ** 2:
            wrong.append(f"inertia Σ‖x − c‖²: yours {inertia_got:.6g}, expected {inertia_exp:.6g} (the clusters "
                         "are well separated: a correct k-means finds this optimum)")
        if wrong:
            return Mismatch("The clustering differs from the expected one:\n" + "\n".join(wrong))
        return None


def _km_run(X, k, iterations=50, rng=None, init=None, *, empty="reseed", relabel=True, seeding="plusplus"):
    """Lloyd's algorithm with switches for the mistakes (reference seeding and assignment)."""
    X = np.asarray(X, dtype=np.float64)
    gen = np.random.default_rng(rng)
    if init is not None:
        centers = np.array(init, dtype=np.float64)
    elif seeding == "first":
        centers = X[:k].copy()
    else:
        return _kmeans(X, k, iterations, rng)
    x_sq = np.einsum("ij,ij->i", X, X)
    labels, dist = _assign(X, x_sq, centers)
    previous = labels
    for _ in range(iterations):
        if empty == "reseed":
            updated = _update(np.ascontiguousarray(X.T), labels, dist, k)
        else:
            updated = centers.copy()
            counts = np.bincount(labels, minlength=k)
            for j in range(k):
                if counts[j]:
                    updated[j] = X[labels == j].mean(axis=0)
                elif empty == "nan":
                    updated[j] = np.nan
                elif empty == "random":
                    updated[j] = X[gen.integers(X.shape[0])]
        if np.array_equal(updated, centers, equal_nan=True):
            break
        centers = updated
        previous = labels
        with np.errstate(invalid="ignore"):
            labels, dist = _assign(X, x_sq, centers)
    return centers, (labels if relabel else previous).astype(np.int64)


_km_nan = variant(_km_run, empty="nan")
_km_keep = variant(_km_run, empty="keep")
_km_random = variant(_km_run, empty="random")
_km_stale_labels = variant(_km_run, relabel=False)
_km_first_k = variant(_km_run, seeding="first")


def _km_fixed_seed(X, k, iterations=50, rng=None, init=None):
    return _km_run(X, k, iterations, 0, init)


def _km_spread_case(rng_or_seed, n, k, first, calls, label):
    """Points spread evenly over a square, no clear clusters: k-means++ with another seed
    often ends in another local optimum (40 calls of the reference: most results apart)."""
    g = np.random.default_rng(rng_or_seed)
    return Case((_round(g.uniform(0, 10, (n, 2))), k), {"draws": (first, calls)}, label)


def _km_blobs(rng, n, d, k, sort=True, scale=1.0):
    """k tight, well separated clusters (sorted by cluster when ``sort``)."""
    X, y = _blobs(rng, n, d, k, spread=0.1, distance=8.0, shuffle=not sort)
    # push the cluster means apart until every pair is ≥ 10 apart (100× the spread: a unique
    # optimum, which k-means++ finds unless it seeds two centres in one cluster, p < 1e-3)
    for _ in range(100):
        means = np.array([X[y == j].mean(axis=0) for j in range(k)])
        gaps = np.linalg.norm(means[:, None] - means[None], axis=2) + np.eye(k) * 1e9
        if gaps.min() >= 10.0:
            break
        X = X + y[:, None] * _round(rng.normal(0, 3.0, d))[None, :]
    return _round(X * scale)


def _far_init(rng, X, k, far):
    """Initial centres: samples of the data, except ``far`` of them placed far away."""
    idx = rng.choice(X.shape[0], k, replace=False)
    init = X[idx].astype(np.float64).copy()
    for j in rng.choice(k, far, replace=False):
        init[j] = np.abs(X).max() * 10 + 100 + 10 * j
    return init


def _km_init_case(rng, label, n, d, k, far=0, iterations=50):
    X = _round(rng.normal(0, 2, (n, d)))
    return Case((X, k), {"iterations": iterations, "rng": _seed(rng), "init": _far_init(rng, X, k, far)}, label)


def _distinct_grid_points(rng, count):
    """``count`` distinct uint8 points of the grid {0, 20, ..., 240}²."""
    cells = rng.choice(13 * 13, count, replace=False)
    return (np.column_stack([cells // 13, cells % 13]) * 20).astype(np.uint8)


def _km_hidden(rng):
    return [
        _km_init_case(rng, "init given, one initial centre far away (an empty cluster)", _size(rng, 20, 40), 2,
                      _size(rng, 3, 4), far=1),
        _km_init_case(rng, "init given, two initial centres far away (two empty clusters)", _size(rng, 20, 40),
                      _size(rng, 2, 3), _size(rng, 4, 5), far=2),
        _km_init_case(rng, "init given, iterations = 1 (not converged)", _size(rng, 20, 40), 2, 3, iterations=1),
        _km_init_case(rng, "init given, iterations = 2, far centre", _size(rng, 25, 40), 3, 4, far=1, iterations=2),
        _km_init_case(rng, "init given, iterations = 0 (the initial centres)", _size(rng, 10, 20), 2, 3, iterations=0),
        _km_init_case(rng, "init given, converges", _size(rng, 30, 50), _size(rng, 1, 3), _size(rng, 2, 5)),
        Case((_km_blobs(rng, _size(rng, 30, 60), 2, 3), 3), {"rng": _seed(rng)}, "k-means++, 3 clusters sorted"),
        Case((_km_blobs(rng, _size(rng, 40, 60), _size(rng, 3, 5), 5), 5), {"rng": _seed(rng)},
             "k-means++, 5 clusters in 3–5-D, sorted"),
        Case((_km_blobs(rng, _size(rng, 30, 50), 1, 4), 4), {"rng": _seed(rng)}, "k-means++, 1-D data"),
        Case((_km_blobs(rng, _size(rng, 30, 50), 2, 3, scale=1000.0), 3), {"rng": _seed(rng)},
             "k-means++, coordinates in the thousands"),
        Case((_round(rng.normal(0, 1, (_size(rng, 10, 20), 3))), 1), {"rng": _seed(rng)}, "k = 1 (the mean)"),
        Case((np.repeat(_distinct_grid_points(rng, 4), 3, axis=0), 4), {"rng": _seed(rng)},
             "uint8 points, each 3 times, k = number of distinct points"),
        _km_spread_case(_seed(rng), _size(rng, 28, 36), 4, _seed(rng), 40,
                        "40 calls with seeds in a row on points spread evenly: the result changes with the seed"),
    ]


def _km_public():
    rng = np.random.default_rng(700)
    X = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [6.0, 5.0], [7.0, 5.0], [6.0, 6.0], [7.0, 6.5],
                  [0.5, 6.0], [1.0, 7.0]])
    line = np.concatenate([_round(np.array([10.0 * j, 0.0]) + 0.3 * rng.standard_normal((8, 2))) for j in range(3)])
    return [
        Case((X, 3), {"iterations": 1, "rng": 1, "init": np.array([[0.0, 0.0], [50.0, 50.0], [1.0, 0.0]])},
             "init given with a centre far away: an empty cluster, iterations = 1"),
        Case((X, 3), {"iterations": 1, "rng": 2, "init": np.array([[0.0, 0.0], [6.0, 5.0], [7.0, 5.0]])},
             "init given, iterations = 1"),
        Case((line, 3), {"rng": 0}, "k-means++ on 3 clusters along a line (sorted)"),
        _km_spread_case(701, 30, 4, 5000, 40, "40 calls, rng = 5000, 5001, …, on 30 points spread evenly "
                        "(no clear clusters): k-means++ with another seed ends in another local optimum"),
    ]


kmeans = Check(
    public=_km_public,
    hidden=_km_hidden,
    refusals=[
        Case((np.repeat(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]]), 3, axis=0), 4), {"rng": 0},
             "k = 4 with 3 distinct points", raises="ValueError"),
    ],
    compare=Drawn(single=KMeansResult()),
    call=call_draws,
    mistakes=[
        Mistake("empty cluster gets a NaN centre (mean of no samples)", _km_nan,
                "When a cluster has no sample, re-seed it with the sample farthest from its centre "
                "(taken from a cluster that keeps at least one sample)"),
        Mistake("empty cluster keeps its old centre", _km_keep,
                "An empty cluster must be re-seeded with the sample farthest from its centre, not left "
                "where it is (it would stay empty)"),
        Mistake("empty cluster re-seeded with a random sample", _km_random,
                "Re-seed an empty cluster with the sample farthest from the centre it was assigned to "
                "(ties: the lowest index), not a random one"),
        Mistake("labels not recomputed for the returned centres", _km_stale_labels,
                "After the last update assign every sample to its nearest returned centre"),
        Mistake("rng ignored: a generator with a fixed seed", _km_fixed_seed,
                "Draw the k-means++ seeds from the generator the caller gives, np.random.default_rng(rng): "
                "with a fixed seed inside the function every call starts from the same centres"),
        Mistake("first k samples as initial centres (no k-means++)", _km_first_k,
                "Seed with k-means++: the first centre a random sample, each next one drawn with "
                "probability ∝ D(x)², the squared distance to the nearest centre chosen so far"),
    ],
    seeded=True,
)


# --------------------------------------------------------------------------------------------
# learn.bovw_histogram (§10.3.2)
# --------------------------------------------------------------------------------------------
def _bovw_words(descriptors, codebook, metric="l2", farthest=False):
    D = np.asarray(descriptors, dtype=np.float64)
    C = np.asarray(codebook, dtype=np.float64)
    d = exact_squared_distances(D, C) if metric == "l2" else exact_l1_distances(D, C)
    return (d.argmax(axis=1) if farthest else d.argmin(axis=1)), C.shape[0]


def _bovw_counts(words, k):
    return np.bincount(words, minlength=k).astype(np.float64)


@mistake("counts not normalised", "With normalize=True divide the counts by their sum (the number of descriptors)")
def _bovw_never_normalised(descriptors, codebook, normalize=True):
    return _bovw_counts(*_bovw_words(descriptors, codebook))


@mistake("normalised even when normalize=False", "With normalize=False return the raw counts")
def _bovw_always_normalised(descriptors, codebook, normalize=True):
    h = _bovw_counts(*_bovw_words(descriptors, codebook))
    return h / h.sum()


@mistake("farthest codeword instead of the nearest",
         "Each descriptor votes for its NEAREST codeword: argmin of the distances")
def _bovw_farthest(descriptors, codebook, normalize=True):
    h = _bovw_counts(*_bovw_words(descriptors, codebook, farthest=True))
    return h / h.sum() if normalize else h


@mistake("L1 distance instead of L2", "Quantise with the Euclidean distance: Σ (d − c)², then argmin")
def _bovw_l1(descriptors, codebook, normalize=True):
    h = _bovw_counts(*_bovw_words(descriptors, codebook, metric="l1"))
    return h / h.sum() if normalize else h


@mistake("divided by the largest count instead of the sum",
         "Normalise to frequencies that sum to 1: divide by the sum of the counts")
def _bovw_max_normalised(descriptors, codebook, normalize=True):
    h = _bovw_counts(*_bovw_words(descriptors, codebook))
    return h / h.max() if normalize else h


def _bovw_case(rng, m, k, d, normalize, label, kind="normal"):
    if kind == "integer":
        D = rng.integers(0, 4, (m, d)).astype(np.float64)
        C = rng.integers(0, 4, (k, d)).astype(np.float64)
    elif kind == "uint8":
        D = rng.integers(0, 256, (m, d), dtype=np.uint8)
        C = rng.integers(0, 256, (k, d), dtype=np.uint8)
    else:
        C = _round(rng.normal(0, 3, (k, d)))
        D = _round(C[rng.integers(0, k, m)] + rng.normal(0, 1.5, (m, d)))
    return Case((D, C), {"normalize": normalize}, label)


def _bovw_l1_case(rng, normalize):
    """Descriptors whose L1- and L2-nearest codewords differ (and a few whose agree)."""
    C = np.array([[0.0, 0.0], [3.0, 3.0], [4.0, 0.0]])
    disagree = np.array([[0.0, 3.4], [-0.5, 4.2], [0.0, 4.1], [-0.2, 3.6], [2.4, 1.1], [2.7, 1.1], [2.9, 1.2],
                         [3.1, 1.3], [3.7, 1.7], [4.0, 1.9]])
    agree = np.array([[0.1, 0.2], [3.2, 2.9], [4.1, -0.2], [0.5, 0.4]])
    rows = np.concatenate([disagree[rng.choice(10, _size(rng, 4, 7), replace=False)],
                           agree[rng.choice(4, _size(rng, 1, 3), replace=False)]])
    return Case((rows[rng.permutation(len(rows))], C), {"normalize": normalize}, "descriptors where L1 and L2 disagree")


def _bovw_hidden(rng):
    return [
        _bovw_case(rng, _size(rng, 20, 40), _size(rng, 3, 6), _size(rng, 2, 5), True, "normalised"),
        _bovw_case(rng, _size(rng, 20, 40), _size(rng, 3, 6), _size(rng, 2, 5), False, "counts (normalize=False)"),
        _bovw_l1_case(rng, True),
        _bovw_l1_case(rng, False),
        _bovw_case(rng, 1, _size(rng, 3, 5), 3, True, "a single descriptor"),
        _bovw_case(rng, _size(rng, 5, 10), 1, 2, True, "a single codeword"),
        _bovw_case(rng, _size(rng, 5, 8), _size(rng, 10, 16), 3, False, "more codewords than descriptors"),
        _bovw_case(rng, _size(rng, 20, 30), _size(rng, 3, 5), 2, True, "integer descriptors (ties to the lowest index)",
                   kind="integer"),
        _bovw_case(rng, _size(rng, 10, 20), _size(rng, 3, 6), 8, True, "uint8 descriptors", kind="uint8"),
        _bovw_case(rng, _size(rng, 20, 40), _size(rng, 4, 8), 1, False, "1-D descriptors, counts"),
    ]


bovw_histogram = Check(
    public=[
        Case((np.array([[0.1, 0.0], [2.1, 0.1], [0.0, 3.4], [2.9, 2.8], [0.2, 0.1], [2.7, 1.1], [-0.3, 0.2],
                        [1.4, 1.5]]),
              np.array([[0.0, 0.0], [3.0, 3.0], [4.0, 0.0]])), {"normalize": True},
             "8 descriptors, 3 codewords, normalised"),
        Case((np.array([[0.1, 0.0], [2.1, 0.1], [0.0, 2.1], [2.9, 2.8], [0.2, 0.1], [3.6, 1.2]]),
              np.array([[0.0, 0.0], [3.0, 3.0], [4.0, 0.0]])), {"normalize": False}, "counts (normalize=False)"),
    ],
    hidden=_bovw_hidden,
    compare=close(rtol=1e-9, atol=1e-12),
    mistakes=[_bovw_never_normalised, _bovw_always_normalised, _bovw_farthest, _bovw_l1, _bovw_max_normalised],
)


# --------------------------------------------------------------------------------------------
# §9.8.5 the measured exercise: a classifier trained on the digits, graded by its accuracy
# --------------------------------------------------------------------------------------------
from ..data import digits as _digits_data  # noqa: E402
from ..data import held_out_digits  # noqa: E402
from ..grading.measured import MeasuredCase, Scale  # noqa: E402
from ..grading.runtime.adapters import train_then_predict  # noqa: E402
from ._digits import ACCURACY_SCALE, BUDGET_SECONDS, fit_softmax  # noqa: E402

#: the published scale the grader applies (its corners: :data:`cvkit.learn._digits.ACCURACY_SCALE`)
ACCURACY = Scale(ACCURACY_SCALE)


def _flat(images: np.ndarray) -> np.ndarray:
    return np.asarray(images, dtype=np.float64).reshape(len(images), -1)


def _classifier_public() -> list[Case]:
    (x_train, y_train), (x_eval, y_eval) = _digits_data()
    return [MeasuredCase((255.0 * x_train, y_train, 255.0 * x_eval, 0), {},
                         f"cvkit.data.digits' split in 8-bit grey levels, flattened: {len(y_train)} to train, "
                         f"{len(y_eval)} to predict", truth=y_eval)]


def _classifier_hidden(rng: np.random.Generator) -> list[Case]:
    x_train, y_train, x_eval, y_eval = held_out_digits(_seed(rng))
    return [MeasuredCase((_flat(x_train), y_train, _flat(x_eval), _seed(rng)), {},
                         f"your own split of the digits, flattened, in the grey levels of an unknown camera: "
                         f"{len(y_train)} to train, {len(y_eval)} perturbed digits to predict", truth=y_eval)]


class DigitAccuracy(Comparator):
    """Passes when the predicted labels reach the top of :data:`ACCURACY` on the case's
    ``truth``; below it the case earns the scale's share (:func:`_classifier_credit`). The
    ``expected`` output (the reference's predictions) only serves for comparison in the
    message."""

    judges_alone = True  # the verdict is what the output achieves on the case's truth

    @staticmethod
    def accuracy(got: Any, case: Any) -> float:
        truth = np.asarray(getattr(case, "truth", np.zeros(0)))
        labels = np.asarray(got)
        return float(np.mean(labels == truth)) if labels.shape == truth.shape and truth.size else 0.0

    def __call__(self, got: Any, expected: Any, case: Any = None) -> Mismatch | None:
        achieved = self.accuracy(got, case)
        if achieved >= ACCURACY.top:
            return None
        truth = np.asarray(getattr(case, "truth", np.zeros(0)))
        words = ACCURACY.shortfall(achieved, "accuracy", f" on {truth.size} digits")
        reference = self.accuracy(expected, case)
        if reference:
            words += f" The reference classifier reached {100 * reference:.2f} % on the same digits."
        labels = np.asarray(got)
        if labels.size and labels.min() >= 1 and labels.max() == 10:
            words += " Your labels run from 1 to 10: the digits are labelled 0..9, predict the column of the best score."
        elif labels.size and np.bincount(labels.astype(np.int64).clip(0)).max() > 0.5 * labels.size:
            words += (" Most predictions are one class: look at what your classifier sees at prediction time "
                      "(the same normalisation as in training, no division by a standard deviation of 0) and at "
                      "the regularisation (a λ that shrinks every weight to nothing).")
        return Mismatch(words)


def _classifier_credit(got: Any, case: Any) -> float:
    return ACCURACY.credit(DigitAccuracy.accuracy(got, case))


def _linear_classifier(x_train, y_train, rng, *, reg=1e-3, label_offset=0, softmax_axis=1):
    """The reference's recipe with one of its steps done wrong (the mistakes below)."""
    X = _flat(x_train)
    mean, std = X.mean(), X.std() + 1e-12
    W, b = fit_softmax((X - mean) / std, np.asarray(y_train).astype(np.int64), 10, np.random.default_rng(rng),
                       reg=reg, softmax_axis=softmax_axis)
    return lambda x: np.argmax(((_flat(x) - mean) / std) @ W.T + b, axis=1) + label_offset


@mistake("softmax over the batch, not over the classes",
         "Each row of scores is one image: exponentiate and divide by the sum along axis=1 (over the 10 classes), "
         "so that every image's probabilities add up to 1")
def _classifier_softmax_over_batch(x_train, y_train, rng=None):
    return _linear_classifier(x_train, y_train, rng, softmax_axis=0)


@mistake("labels off by one (1..10)",
         "The class of a row is the index of its best score, 0..9: no + 1")
def _classifier_labels_off_by_one(x_train, y_train, rng=None):
    return _linear_classifier(x_train, y_train, rng, label_offset=1)


@mistake("regularisation a thousand times too strong (λ = 1)",
         "With λ = 1 the penalty λΣW² outweighs the data and the weights shrink towards 0: choose λ on a "
         "validation split (10⁻⁴ to 10⁻² here)")
def _classifier_strong_regularisation(x_train, y_train, rng=None):
    return _linear_classifier(x_train, y_train, rng, reg=1.0)


train_digit_classifier = Check(
    public=_classifier_public,
    hidden=_classifier_hidden,
    compare=DigitAccuracy(),
    mistakes=[_classifier_softmax_over_batch, _classifier_labels_off_by_one, _classifier_strong_regularisation],
    call=train_then_predict,
    arg_names=("x_train", "y_train", "x_eval", "seed"),
    output_names=("labels",),
    time_limit=BUDGET_SECONDS,
    credit=_classifier_credit,
)
