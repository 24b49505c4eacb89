"""How a check calls a candidate that is not a plain function (:attr:`cvkit.grading.Check.call`).

These adapters run inside the grading sandbox next to the student's code, so they use only
NumPy and the standard library and never touch cvkit's reference implementations. A check
names one of them as its ``call``; the trusted grader sends its name, never code.
"""
from __future__ import annotations

import numpy as np

from typing import Callable

from .problems import least_squares_call

__all__ = ["bind_call", "instance_call", "train_then_predict", "least_squares_call", "call_with_test_function", "TestFunction", "TEST_FUNCTIONS",
           "CACHE_KEYS", "call_relu_forward", "call_sigmoid_forward", "call_leaky_relu_forward", "call_linear_forward",
           "call_conv2d_forward", "call_maxpool2d_forward", "call_global_avg_pool_forward", "call_batchnorm2d_forward",
           "call_dropout_forward", "call_residual_block_forward", "call_draws"]


def bind_call(call: Callable | None, candidate: Callable) -> Callable:
    """The callable a case runs: ``candidate`` itself, or ``call`` bound to it (it keeps the
    candidate's ``__module__``, which the guard uses to recognise the candidate's own code)."""
    if call is None:
        return candidate

    def run_case(*args, **kwargs):
        return call(candidate, *args, **kwargs)

    run_case.__module__ = getattr(candidate, "__module__", None) or run_case.__module__
    run_case.__wrapped__ = candidate  # type: ignore[attr-defined]
    run_case.__qualname__ = f"{getattr(call, '__name__', 'call')}({getattr(candidate, '__qualname__', 'candidate')})"
    return run_case


def instance_call(cls, arg, method, *args, **kwargs):
    """``cls(arg).<method>(*args, **kwargs)``: a :attr:`Check.call` for classes.

    With ``Check(call=instance_call)``, a case ``Case((points, "query", q), {"k": 2})`` grades a
    class by building ``cls(points)`` and returning ``.query(q, k=2)``.
    """
    return getattr(cls(arg), method)(*args, **kwargs)


def train_then_predict(candidate, x_train, y_train, x_eval, seed):
    """``candidate(x_train, y_train, rng)`` returns a ``predict`` function; the case's output is
    ``predict(x_eval)`` as int64 labels: a :attr:`Check.call` for exercises that train a model
    (the labels of ``x_eval`` never enter the sandbox; the check's comparator keeps them).
    ``rng`` is ``np.random.default_rng(seed)``."""
    predict = candidate(x_train, y_train, np.random.default_rng(seed))
    if not callable(predict):
        raise TypeError(f"{getattr(candidate, '__name__', 'the function')} must return a function that predicts "
                        f"labels, got {type(predict).__name__}")
    labels = np.asarray(predict(np.array(x_eval, copy=True)))
    if labels.shape != (len(x_eval),):
        raise ValueError(f"predict(x) must return one label per image, shape ({len(x_eval)},), got shape "
                         f"{labels.shape}")
    if labels.dtype.kind not in "iub" and not (labels.dtype.kind == "f" and np.all(labels == np.round(labels))):
        raise TypeError(f"predict(x) must return integer labels, got dtype {labels.dtype}")
    return labels.astype(np.int64)


# ---------------------------------------------------------------------------- learn
#: the scalar test functions of the numerical-gradient cases; their coefficients are stacked
#: into one array (``table``) so that a case is plain data the grading wire can carry
TEST_FUNCTIONS = {
    "cubic": "Σ a·x³ + c·x² + d·x (table: a, c, d)",
    "exp": "Σ w·exp(s·x) (table: w, s)",
    "quadratic": "½ xᵀAx + bᵀx (table: the rows of A, then b)",
    "linear": "Σ w·x (table: w)",
    "softmax_loss": "mean cross-entropy of the scores X·xᵀ (table: X with the labels y as last column)",
}


class TestFunction:
    """``f(x) -> float`` of one of the :data:`TEST_FUNCTIONS` with its coefficient table."""

    __test__ = False  # not a pytest test class

    def __init__(self, kind: str, table):
        if kind not in TEST_FUNCTIONS:
            raise ValueError(f"unknown test function {kind!r}; known: {', '.join(TEST_FUNCTIONS)}")
        self.kind = kind
        self.table = np.asarray(table, dtype=np.float64)

    def __call__(self, x):
        x = np.asarray(x, dtype=np.float64)
        t = self.table
        if self.kind == "cubic":
            a, c, d = t
            return float(np.sum(a * x ** 3 + c * x ** 2 + d * x))
        if self.kind == "exp":
            w, s = t
            return float(np.sum(w * np.exp(s * x)))
        if self.kind == "quadratic":
            v = x.ravel()
            return float(0.5 * v @ t[:-1] @ v + t[-1] @ v)
        if self.kind == "linear":
            return float(np.sum(t[0] * x))
        X, y = t[:, :-1], t[:, -1].astype(np.int64)  # softmax_loss, x plays W (C, D)
        s = X @ x.T
        s = s - s.max(axis=1, keepdims=True)
        return float(np.mean(np.log(np.exp(s).sum(axis=1)) - s[np.arange(s.shape[0]), y]))

    def __repr__(self):
        return f"f(x) = {TEST_FUNCTIONS[self.kind].split(' (')[0]}"


def call_with_test_function(candidate, function, table, x, *args, **kwargs):
    """The ``call`` of the numerical-gradient check: a case ``(function, table, x)`` of plain
    data runs ``candidate(TestFunction(function, table), x, ...)``."""
    return candidate(TestFunction(function, table), x, *args, **kwargs)


# ---------------------------------------------------------------------------- nn
#: the cache entries each layer's forward must return (the rest of its cache is its own business)
CACHE_KEYS = {
    "relu": ("x",),
    "sigmoid": ("x", "out"),
    "leaky_relu": ("x", "alpha"),
    "linear": ("x", "W", "b"),
    "conv2d": ("x", "w", "b", "stride", "padding"),
    "maxpool2d": ("x", "size", "stride"),
    "global_avg_pool": ("x",),
    "batchnorm2d": ("x", "gamma", "beta", "running_mean", "running_var", "training", "momentum", "eps"),
    "dropout": ("x", "p_keep", "training", "mask"),
    "residual_block": ("x", "params", "training"),
}


def _select(result, layer: str):
    if isinstance(result, tuple) and len(result) == 2 and isinstance(result[1], dict):
        out, cache = result
        return (out, {k: cache[k] for k in CACHE_KEYS[layer] if k in cache})
    return result


def _forward_call(layer: str, random: bool = False) -> Callable:
    """The :attr:`Check.call` of ``layer``'s forward: ``(out, cache with the entries
    CACHE_KEYS[layer] names)``; a ``random`` layer's also takes ``draws`` (:func:`call_draws`:
    a list of such pairs, one per seed). It carries a module-level name
    (``call_<layer>_forward``, assigned below) so that the trusted grader can send that name to
    the sandbox."""

    def call(candidate, *args, **kwargs):
        if random:
            return call_draws(lambda *a, **k: _select(candidate(*a, **k), layer), *args, **kwargs)
        return _select(candidate(*args, **kwargs), layer)

    call.__name__ = call.__qualname__ = f"call_{layer}_forward"
    call.__doc__ = (f"``(out, cache)`` of a {layer} forward, the cache cut to its entries "
                    f"{', '.join(CACHE_KEYS[layer])} (a :attr:`Check.call`).")
    return call


call_relu_forward = _forward_call("relu")
call_sigmoid_forward = _forward_call("sigmoid")
call_leaky_relu_forward = _forward_call("leaky_relu")
call_linear_forward = _forward_call("linear")
call_conv2d_forward = _forward_call("conv2d")
call_maxpool2d_forward = _forward_call("maxpool2d")
call_global_avg_pool_forward = _forward_call("global_avg_pool")
call_batchnorm2d_forward = _forward_call("batchnorm2d")
call_dropout_forward = _forward_call("dropout", random=True)
call_residual_block_forward = _forward_call("residual_block")


# ---------------------------------------------------------------------------- random algorithms
def call_draws(candidate, *args, draws=None, **kwargs):
    """The :attr:`Check.call` of a random algorithm whose draws are judged by their
    distribution: without ``draws``, one call; with ``draws=(first, count)``, ``count`` calls
    with ``rng`` = first, first + 1, …, their outputs as a list (one output cannot show that λ
    follows Beta(α, α) or that a square's centre is uniform; a few hundred can)."""
    if draws is None:
        return candidate(*args, **kwargs)
    first, count = draws
    return [candidate(*args, **{**kwargs, "rng": int(first) + i}) for i in range(int(count))]
