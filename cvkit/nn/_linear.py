"""The fully connected (linear, affine) layer of §10.5.1 in the layer convention ``W (D, C)``."""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_allocation
from ..registry import algorithm
from ._common import as_gradient, check_cache

__all__ = ["linear_forward", "linear_backward"]


def _params(x: ArrayLike, W: ArrayLike, b: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x = as_float_array(x, "x", ndim=2)
    W = as_float_array(W, "W", ndim=2)
    b = as_float_array(b, "b", ndim=1)
    if W.shape[0] != x.shape[1]:
        raise ValueError(f"W must be (D, C) with D = {x.shape[1]} (the columns of x), got shape {W.shape}")
    if b.shape[0] != W.shape[1]:
        raise ValueError(f"b must have one entry per output (W has {W.shape[1]} columns), got shape {b.shape}")
    return x, W, b


@algorithm("nn.linear_forward", section="10.5.1", check="cvkit.nn.checks:linear_forward")
def linear_forward(x: ArrayLike, W: ArrayLike, b: ArrayLike) -> tuple[np.ndarray, dict[str, Any]]:
    """Fully connected layer: ``out = x @ W + b``.

    Parameters
    ----------
    x : (N, D) array_like
        One input vector per row (flatten feature maps first: ``x.reshape(N, -1)``).
    W : (D, C) array_like
        Weights in the *layer* convention: column ``j`` holds the weights of output ``j``.
        (Chapter 9's ``cvkit.learn`` stores the transpose, ``(C, D)``.) The output, N·C values,
        must fit in 2 GiB (cvkit's limit for one array), else ``ValueError`` naming ``W``.
    b : (C,) array_like
        One bias per output.

    Returns
    -------
    out : (N, C) float64 ndarray
        :math:`h = xW + b`, row by row the notes' :math:`W^\\top x + b`.
    cache : dict
        ``{"x": x, "W": W, "b": b}``.

    Notes
    -----
    §10.5.1: a network is a composition of such layers with non-linear activations in
    between, :math:`f(x) = W_2\\,\\phi(W_1 x + b_1) + b_2`. Without φ two linear layers collapse
    into one (§10.5.2).

    Examples
    --------
    >>> import numpy as np
    >>> out, cache = linear_forward(np.array([[1.0, 2.0]]), np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]),
    ...                             np.array([0.0, 0.0, -3.0]))
    >>> out
    array([[1., 2., 0.]])
    """
    x, W, b = _params(x, W, b)
    check_allocation((x.shape[0], W.shape[1]), "W", what="the output x @ W")
    return x @ W + b, {"x": x, "W": W, "b": b}


@algorithm("nn.linear_backward", section="10.5.1", check="cvkit.nn.checks:linear_backward")
def linear_backward(dout: ArrayLike, cache: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gradients of :func:`linear_forward`.

    Parameters
    ----------
    dout : (N, C) array_like
        Upstream gradient ∂L/∂out.
    cache : dict
        The cache of :func:`linear_forward` (``x``, ``W``, ``b``).

    Returns
    -------
    dx : (N, D) float64 ndarray
        ``dout @ W.T``.
    dW : (D, C) float64 ndarray
        ``x.T @ dout`` (summed over the batch, not averaged: a mean loss already carries its
        1/N in ``dout``).
    db : (C,) float64 ndarray
        ``dout.sum(axis=0)``.

    Examples
    --------
    >>> import numpy as np
    >>> _, cache = linear_forward(np.array([[1.0, 2.0], [3.0, 4.0]]), np.eye(2), np.zeros(2))
    >>> dx, dW, db = linear_backward(np.array([[1.0, 0.0], [0.0, 1.0]]), cache)
    >>> dW
    array([[1., 3.],
           [2., 4.]])
    >>> db
    array([1., 1.])
    """
    check_cache(cache, ("x", "W", "b"), "linear")
    x, W, b = _params(cache["x"], cache["W"], cache["b"])
    dout = as_gradient(dout, "dout", (x.shape[0], W.shape[1]))
    return dout @ W.T, x.T @ dout, dout.sum(axis=0)
