"""Batch normalisation for feature maps (§10.7.6) and inverted dropout (§12.3.6)."""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, as_rng, check_real
from ..registry import algorithm
from ._common import as_batch, as_gradient, check_bool, check_cache

__all__ = ["batchnorm2d_forward", "batchnorm2d_backward", "dropout_forward", "dropout_backward"]


def _per_channel(value: ArrayLike, name: str, channels: int, nonnegative: bool = False) -> np.ndarray:
    v = as_float_array(value, name, ndim=1)
    if v.shape[0] != channels:
        raise ValueError(f"{name} must have one entry per channel ({channels}), got shape {v.shape}")
    if nonnegative and np.any(v < 0):
        raise ValueError(f"{name} must be >= 0 (a variance)")
    return v


def _bn_arguments(x: ArrayLike, gamma: ArrayLike, beta: ArrayLike, running_mean: ArrayLike, running_var: ArrayLike,
                  training: bool, momentum: float, eps: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool, float, float]:
    x = as_batch(x, "x")
    c = x.shape[1]
    gamma = _per_channel(gamma, "gamma", c)
    beta = _per_channel(beta, "beta", c)
    running_mean = _per_channel(running_mean, "running_mean", c)
    running_var = _per_channel(running_var, "running_var", c, nonnegative=True)
    training = check_bool(training, "training")
    momentum = check_real(momentum, "momentum", nonnegative=True)
    if momentum > 1:
        raise ValueError(f"momentum must be in [0, 1], got {momentum}")
    eps = check_real(eps, "eps", positive=True)
    return x, gamma, beta, running_mean, running_var, training, momentum, eps


def _bcast(v: np.ndarray) -> np.ndarray:
    return v[None, :, None, None]


@algorithm("nn.batchnorm2d_forward", section="10.7.6", check="cvkit.nn.checks:batchnorm2d_forward")
def batchnorm2d_forward(x: ArrayLike, gamma: ArrayLike, beta: ArrayLike, running_mean: ArrayLike,
                        running_var: ArrayLike, training: bool, momentum: float = 0.1,
                        eps: float = 1e-5) -> tuple[np.ndarray, dict[str, Any]]:
    """Spatial batch normalisation: per channel, over the batch and all positions.

    Parameters
    ----------
    x : (N, C, H, W) array_like
        A batch of feature maps. In training, N·H·W must be at least 2.
    gamma, beta : (C,) array_like
        Learnable scale γ and shift β, one per channel.
    running_mean, running_var : (C,) array_like
        Running estimates of each channel's mean and variance (not modified).
    training : bool
        Normalise with the statistics of this batch and update the running ones (True), or
        normalise with the running statistics (False, evaluation).
    momentum : float
        Weight m ∈ [0, 1] of the current batch in the running averages.
    eps : float
        ε > 0 added to the variance inside the square root.

    Returns
    -------
    out : (N, C, H, W) float64 ndarray
        :math:`\\gamma_c\\,(x - \\mu_c)/\\sqrt{\\sigma_c^2 + \\varepsilon} + \\beta_c`.
    cache : dict
        The arguments under their names (``x``, ``gamma``, ``beta``, ``training``,
        ``momentum``, ``eps``) where ``running_mean`` and ``running_var`` are the **new**
        running statistics: in training
        :math:`(1 - m)\\cdot\\mathrm{old} + m\\cdot\\mathrm{batch}`, in evaluation the unchanged
        ones (the statistics that were used).

    Notes
    -----
    §10.7.6. For channel c, :math:`\\mu_c` and :math:`\\sigma^2_c` are the mean and variance of
    the N·H·W values ``x[:, c]`` (the same kernel made all of them, so they are normalised
    alike).

    **Two variances, as PyTorch's ``BatchNorm2d``:** the batch is normalised with the
    *biased* variance (divided by n = N·H·W: the batch's own spread), while the running
    variance is updated with the *unbiased* one (divided by n − 1: an estimate of the
    population's variance, which evaluation will use). With n = 8 values the two differ by
    14 %.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.array([1.0, 2.0, 3.0, 4.0]).reshape(2, 1, 1, 2)
    >>> out, cache = batchnorm2d_forward(x, np.ones(1), np.zeros(1), np.zeros(1), np.ones(1), True)
    >>> out.ravel().round(4)
    array([-1.3416, -0.4472,  0.4472,  1.3416])
    >>> cache["running_mean"], cache["running_var"].round(4)       # 0.9·0 + 0.1·2.5, 0.9·1 + 0.1·5/3
    (array([0.25]), array([1.0667]))
    """
    x, gamma, beta, rm, rv, training, momentum, eps = _bn_arguments(
        x, gamma, beta, running_mean, running_var, training, momentum, eps)
    if training:
        n = x.shape[0] * x.shape[2] * x.shape[3]
        if n < 2:
            raise ValueError(f"x must hold at least 2 values per channel in training (N·H·W = {n})")
        mean = x.mean(axis=(0, 2, 3))
        var = x.var(axis=(0, 2, 3))                       # biased: normalises the batch
        new_mean = (1.0 - momentum) * rm + momentum * mean
        new_var = (1.0 - momentum) * rv + momentum * var * (n / (n - 1))   # unbiased estimate
    else:
        mean, var = rm, rv
        new_mean, new_var = rm.copy(), rv.copy()
    x_hat = (x - _bcast(mean)) / np.sqrt(_bcast(var) + eps)
    out = _bcast(gamma) * x_hat + _bcast(beta)
    cache = {"x": x, "gamma": gamma, "beta": beta, "running_mean": new_mean, "running_var": new_var,
             "training": training, "momentum": momentum, "eps": eps}
    return out, cache


@algorithm("nn.batchnorm2d_backward", section="10.7.6", check="cvkit.nn.checks:batchnorm2d_backward")
def batchnorm2d_backward(dout: ArrayLike, cache: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gradients of :func:`batchnorm2d_forward` with respect to x, γ and β.

    Parameters
    ----------
    dout : (N, C, H, W) array_like
        Upstream gradient.
    cache : dict
        The cache of :func:`batchnorm2d_forward` (``x``, ``gamma``, ``training``, ``eps``;
        in evaluation also ``running_mean``, ``running_var``).

    Returns
    -------
    dx : (N, C, H, W) float64 ndarray
        In training the batch mean and variance depend on every x, which gives (per channel,
        n = N·H·W, :math:`\\hat x` the normalised input)
        :math:`dx = \\frac{\\gamma}{n\\sqrt{\\sigma^2+\\varepsilon}}\\big(n\\,dout - \\sum dout -
        \\hat x \\sum dout\\,\\hat x\\big)`. In evaluation the statistics are constants and
        :math:`dx = \\gamma\\,dout/\\sqrt{\\sigma^2_{run}+\\varepsilon}`.
    dgamma : (C,) float64 ndarray
        :math:`\\sum dout\\,\\hat x` over N, H, W.
    dbeta : (C,) float64 ndarray
        :math:`\\sum dout` over N, H, W.

    Notes
    -----
    The batch statistics are recomputed from ``cache["x"]`` (the cache holds the *new*
    running statistics, which training did not normalise with).

    Examples
    --------
    >>> import numpy as np
    >>> x = np.array([1.0, 2.0, 3.0, 4.0]).reshape(2, 1, 1, 2)
    >>> _, cache = batchnorm2d_forward(x, np.ones(1), np.zeros(1), np.zeros(1), np.ones(1), True)
    >>> dx, dgamma, dbeta = batchnorm2d_backward(np.ones((2, 1, 1, 2)), cache)
    >>> bool(np.abs(dx).max() < 1e-12), dbeta        # a constant shift of the output changes nothing
    (True, array([4.]))
    """
    check_cache(cache, ("x", "gamma", "beta", "running_mean", "running_var", "training", "eps"), "batchnorm2d")
    x, gamma, _, rm, rv, training, _, eps = _bn_arguments(
        cache["x"], cache["gamma"], cache["beta"], cache["running_mean"], cache["running_var"],
        cache["training"], cache.get("momentum", 0.1), cache["eps"])
    dout = as_gradient(dout, "dout", x.shape)
    axes = (0, 2, 3)
    if training:
        mean, var = x.mean(axis=axes), x.var(axis=axes)
    else:
        mean, var = rm, rv
    inv_std = 1.0 / np.sqrt(var + eps)
    x_hat = (x - _bcast(mean)) * _bcast(inv_std)
    dbeta = dout.sum(axis=axes)
    dgamma = (dout * x_hat).sum(axis=axes)
    if training:
        n = x.shape[0] * x.shape[2] * x.shape[3]
        dx = _bcast(gamma * inv_std / n) * (n * dout - _bcast(dbeta) - x_hat * _bcast(dgamma))
    else:
        dx = dout * _bcast(gamma * inv_std)
    return dx, dgamma, dbeta


# --------------------------------------------------------------------------------------------
# dropout
# --------------------------------------------------------------------------------------------
def _p_keep(p_keep: float) -> float:
    p = check_real(p_keep, "p_keep")
    if not 0.0 < p <= 1.0:
        raise ValueError(f"p_keep must be in (0, 1] (the probability of keeping a unit), got {p}")
    return p


@algorithm("nn.dropout_forward", section="12.3.6", check="cvkit.nn.checks:dropout_forward")
def dropout_forward(x: ArrayLike, p_keep: float, training: bool,
                    rng: np.random.Generator | int | None = None) -> tuple[np.ndarray, dict[str, Any]]:
    """Inverted dropout: keep each unit with probability ``p_keep`` and scale it by ``1/p_keep``.

    Parameters
    ----------
    x : array_like
        Activations of any shape.
    p_keep : float
        Probability p ∈ (0, 1] of keeping a unit (PyTorch's ``Dropout(p)`` takes the
        *drop* probability, 1 − p_keep).
    training : bool
        Drop units (True) or pass ``x`` through unchanged (False, evaluation).
    rng : numpy.random.Generator, int or None
        Source of the mask (one uniform draw per unit: kept where ``u < p_keep``).

    Returns
    -------
    out : float64 ndarray
        ``x · mask / p_keep`` in training, a copy of ``x`` in evaluation.
    cache : dict
        ``{"x", "p_keep", "training", "rng", "mask"}``: the arguments (``rng`` as given) and
        ``mask``, the boolean array of kept units (all True in evaluation).

    Notes
    -----
    §12.3.6. Scaling the kept units at training time keeps the expected activation equal to
    x, so evaluation needs no rescaling ("inverted" dropout).

    Examples
    --------
    >>> import numpy as np
    >>> out, cache = dropout_forward(np.ones((2, 4)), 0.5, True, rng=0)
    >>> sorted(set(out.ravel().tolist()))
    [0.0, 2.0]
    >>> np.array_equal(out, 2.0 * cache["mask"])
    True
    """
    x = as_float_array(x, "x", allow_empty=True)
    p = _p_keep(p_keep)
    training = check_bool(training, "training")
    generator = as_rng(rng)
    if training:
        mask = generator.random(x.shape) < p
        out = np.where(mask, x / p, 0.0)
    else:
        mask = np.ones(x.shape, dtype=bool)
        out = x.copy()
    return out, {"x": x, "p_keep": p, "training": training, "rng": rng, "mask": mask}


@algorithm("nn.dropout_backward", section="12.3.6", check="cvkit.nn.checks:dropout_backward")
def dropout_backward(dout: ArrayLike, cache: dict[str, Any]) -> np.ndarray:
    """Gradient of :func:`dropout_forward`: ``dout · mask / p_keep`` in training, ``dout`` otherwise.

    Parameters
    ----------
    dout : array_like
        Upstream gradient.
    cache : dict
        The cache of :func:`dropout_forward` (``mask``, ``p_keep``, ``training``).

    Returns
    -------
    dx : float64 ndarray

    Examples
    --------
    >>> import numpy as np
    >>> cache = {"x": np.ones(3), "p_keep": 0.5, "training": True, "mask": np.array([True, False, True])}
    >>> dropout_backward(np.ones(3), cache)
    array([2., 0., 2.])
    """
    check_cache(cache, ("p_keep", "training", "mask"), "dropout")
    p = _p_keep(cache["p_keep"])
    training = check_bool(cache["training"], "cache['training']")
    mask = np.asarray(cache["mask"])
    if mask.dtype != bool:
        raise TypeError(f"cache['mask'] must be a boolean array, got dtype {mask.dtype}")
    dout = as_gradient(dout, "dout", mask.shape)
    if not training:
        return dout.copy()
    return np.where(mask, dout / p, 0.0)
