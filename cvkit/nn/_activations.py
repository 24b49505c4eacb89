"""Activation layers of §10.5.3–10.5.4: ReLU, logistic sigmoid, leaky ReLU.

Each is a pair ``<name>_forward(x, ...) -> (out, cache)`` / ``<name>_backward(dout, cache) -> dx``
working element by element on an array of any shape (a batch of vectors ``(N, D)`` or of
feature maps ``(N, C, H, W)``). The cache is a dict holding the forward's arguments under their
own names (``x``, and ``alpha`` for the leaky ReLU) plus, for the sigmoid, its output ``out``.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_real
from ..registry import algorithm
from ._common import as_gradient, check_cache

__all__ = [
    "relu_forward", "relu_backward", "sigmoid_forward", "sigmoid_backward",
    "leaky_relu_forward", "leaky_relu_backward",
]


def _x(x: ArrayLike) -> np.ndarray:
    return as_float_array(x, "x", allow_empty=True)


# --------------------------------------------------------------------------------------------
# ReLU
# --------------------------------------------------------------------------------------------
@algorithm("nn.relu_forward", section="10.5.3–10.5.4", check="cvkit.nn.checks:relu_forward")
def relu_forward(x: ArrayLike) -> tuple[np.ndarray, dict[str, Any]]:
    """Rectified linear unit, element by element: ``max(0, x)``.

    Parameters
    ----------
    x : array_like
        Pre-activations of any shape and real dtype, finite.

    Returns
    -------
    out : float64 ndarray, same shape as ``x``
        :math:`\\mathrm{ReLU}(a) = \\max(0, a)`.
    cache : dict
        ``{"x": x}`` (as float64), what :func:`relu_backward` needs.

    Notes
    -----
    §10.5.3. The positive part passes unchanged, everything else becomes 0.

    Examples
    --------
    >>> import numpy as np
    >>> out, cache = relu_forward(np.array([-2.0, 0.0, 3.0]))
    >>> out
    array([0., 0., 3.])
    >>> sorted(cache)
    ['x']
    """
    x = _x(x)
    return np.maximum(x, 0.0), {"x": x}


@algorithm("nn.relu_backward", section="10.5.3–10.5.4", check="cvkit.nn.checks:relu_backward")
def relu_backward(dout: ArrayLike, cache: dict[str, Any]) -> np.ndarray:
    """Gradient of :func:`relu_forward`: ``dout`` where ``x ≥ 0``, 0 elsewhere.

    Parameters
    ----------
    dout : array_like
        Upstream gradient ∂L/∂out, the shape of ``cache["x"]``.
    cache : dict
        The cache of :func:`relu_forward` (only ``cache["x"]`` is read).

    Returns
    -------
    dx : float64 ndarray
        :math:`\\partial L/\\partial x = \\partial L/\\partial \\mathrm{out} \\cdot [x \\ge 0]`.

    Notes
    -----
    §10.5.4 (Figure 78): the derivative of ReLU is taken as **1 for x ≥ 0** and 0 otherwise.
    At exactly ``x = 0`` ReLU has no derivative and any value in [0, 1] is a valid
    subgradient; the notes choose 1. PyTorch chooses 0, so on inputs with exact zeros the two
    differ (on continuous random inputs they never do).

    Examples
    --------
    >>> import numpy as np
    >>> _, cache = relu_forward(np.array([-2.0, 0.0, 3.0]))
    >>> relu_backward(np.array([5.0, 5.0, 5.0]), cache)
    array([0., 5., 5.])
    """
    check_cache(cache, ("x",), "relu")
    x = _x(cache["x"])
    dout = as_gradient(dout, "dout", x.shape)
    return np.where(x >= 0, dout, 0.0)


# --------------------------------------------------------------------------------------------
# sigmoid
# --------------------------------------------------------------------------------------------
def _sigmoid(x: np.ndarray) -> np.ndarray:
    """``1 / (1 + exp(−x))`` without overflow: ``exp`` only ever sees ``−|x|``."""
    with np.errstate(under="ignore"):
        e = np.exp(-np.abs(x))
        return np.where(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


@algorithm("nn.sigmoid_forward", section="10.5.3–10.5.4", check="cvkit.nn.checks:sigmoid_forward")
def sigmoid_forward(x: ArrayLike) -> tuple[np.ndarray, dict[str, Any]]:
    """Logistic sigmoid, element by element: ``1 / (1 + exp(−x))``.

    Parameters
    ----------
    x : array_like
        Pre-activations of any shape and real dtype, finite (±1e4 is fine).

    Returns
    -------
    out : float64 ndarray, same shape as ``x``
        :math:`\\sigma(a) = 1/(1 + e^{-a})`, in [0, 1].
    cache : dict
        ``{"x": x, "out": out}``.

    Notes
    -----
    §10.5.3. Written as :math:`1/(1+e^{-|a|})` for a ≥ 0 and :math:`e^{-|a|}/(1+e^{-|a|})`
    for a < 0, so the exponential never overflows: σ(−1000) is 0 and σ(1000) is 1 without a
    warning (the textbook form ``exp(a)/(1+exp(a))`` gives ``inf/inf = nan`` there).

    Examples
    --------
    >>> import numpy as np
    >>> out, cache = sigmoid_forward(np.array([-1000.0, 0.0, 2.0]))
    >>> out.round(4)
    array([0.    , 0.5   , 0.8808])
    >>> sorted(cache)
    ['out', 'x']
    """
    x = _x(x)
    out = _sigmoid(x)
    return out, {"x": x, "out": out}


@algorithm("nn.sigmoid_backward", section="10.5.3–10.5.4", check="cvkit.nn.checks:sigmoid_backward")
def sigmoid_backward(dout: ArrayLike, cache: dict[str, Any]) -> np.ndarray:
    """Gradient of :func:`sigmoid_forward`: ``dout · σ(x)(1 − σ(x))``.

    Parameters
    ----------
    dout : array_like
        Upstream gradient, the shape of the forward's output.
    cache : dict
        The cache of :func:`sigmoid_forward`; ``cache["out"]`` (= σ(x)) is used.

    Returns
    -------
    dx : float64 ndarray

    Notes
    -----
    §10.5.4 (Figure 77): :math:`\\sigma'(a) = \\sigma(a)(1 - \\sigma(a))`, at most 1/4 (at
    a = 0) and vanishing for large |a|: the saturation that makes deep sigmoid networks hard
    to train.

    Examples
    --------
    >>> import numpy as np
    >>> _, cache = sigmoid_forward(np.array([0.0, 2.0]))
    >>> sigmoid_backward(np.array([1.0, 1.0]), cache).round(4)
    array([0.25 , 0.105])
    """
    check_cache(cache, ("out",), "sigmoid")
    out = as_float_array(cache["out"], "cache['out']", allow_empty=True)
    dout = as_gradient(dout, "dout", out.shape)
    return dout * out * (1.0 - out)


# --------------------------------------------------------------------------------------------
# leaky ReLU
# --------------------------------------------------------------------------------------------
@algorithm("nn.leaky_relu_forward", section="10.5.3–10.5.4", check="cvkit.nn.checks:leaky_relu_forward")
def leaky_relu_forward(x: ArrayLike, alpha: float = 0.01) -> tuple[np.ndarray, dict[str, Any]]:
    """Leaky ReLU: ``x`` where ``x ≥ 0``, ``alpha·x`` elsewhere.

    Parameters
    ----------
    x : array_like
        Pre-activations of any shape and real dtype, finite.
    alpha : float
        Slope for negative inputs (the notes' 0.01 by default). Any finite real; the usual
        range is 0 < alpha < 1.

    Returns
    -------
    out : float64 ndarray
        :math:`a` if :math:`a \\ge 0`, :math:`\\alpha a` otherwise.
    cache : dict
        ``{"x": x, "alpha": alpha}``.

    Notes
    -----
    §10.5.3 (Figure 76). Computed piecewise with ``np.where``, which is the definition for any
    α; ``max(a, αa)`` is the same function only for α ≤ 1.

    Examples
    --------
    >>> import numpy as np
    >>> leaky_relu_forward(np.array([-100.0, 0.0, 3.0]))[0]
    array([-1.,  0.,  3.])
    """
    x = _x(x)
    alpha = check_real(alpha, "alpha")
    return np.where(x >= 0, x, alpha * x), {"x": x, "alpha": alpha}


@algorithm("nn.leaky_relu_backward", section="10.5.3–10.5.4", check="cvkit.nn.checks:leaky_relu_backward")
def leaky_relu_backward(dout: ArrayLike, cache: dict[str, Any]) -> np.ndarray:
    """Gradient of :func:`leaky_relu_forward`: ``dout`` where ``x ≥ 0``, ``alpha·dout`` elsewhere.

    Parameters
    ----------
    dout : array_like
        Upstream gradient.
    cache : dict
        The cache of :func:`leaky_relu_forward` (``x`` and ``alpha``).

    Returns
    -------
    dx : float64 ndarray

    Notes
    -----
    §10.5.4 (Figure 79): slope 1 for a ≥ 0 (also at exactly 0, as for ReLU) and α below.

    Examples
    --------
    >>> import numpy as np
    >>> _, cache = leaky_relu_forward(np.array([-2.0, 0.0, 3.0]), alpha=0.1)
    >>> leaky_relu_backward(np.ones(3), cache)
    array([0.1, 1. , 1. ])
    """
    check_cache(cache, ("x", "alpha"), "leaky_relu")
    x = _x(cache["x"])
    alpha = check_real(cache["alpha"], "cache['alpha']")
    dout = as_gradient(dout, "dout", x.shape)
    return np.where(x >= 0, dout, alpha * dout)
