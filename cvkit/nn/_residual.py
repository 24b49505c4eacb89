"""The ResNet basic block of §11.5.2–11.5.4, built from the layers of this package.

``out = relu(bn2(conv2(relu(bn1(conv1(x))))) + shortcut(x))``: two 3×3 convolutions (padding 1,
no bias: the batch norm's β plays its part) with batch norm, the sum **before** the last ReLU,
and a shortcut that is the identity or, when the block changes the resolution and the
number of channels, a 1×1 convolution with stride 2 followed by batch norm (the projection
of §11.5.4, option B of the paper).

The block is a pipeline: it calls its layers through the registry, so
``with cvkit.use("student"):`` runs it on a student's convolution, batch norm and ReLU.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_real
from ..registry import algorithm, implementation
from ._common import as_batch, check_bool, check_cache
from ._conv import check_conv_cost

__all__ = ["residual_block_forward", "residual_block_backward", "RESIDUAL_KEYS"]

_BN = ("gamma", "beta", "running_mean", "running_var")
#: the entries of ``params``: required, and the optional projection
RESIDUAL_KEYS = tuple(["w1"] + [f"{k}1" for k in _BN] + ["w2"] + [f"{k}2" for k in _BN])
PROJECTION_KEYS = tuple(["w_proj"] + [f"{k}_proj" for k in _BN])
#: learnable entries (the keys of the gradients)
LEARNABLE = ("w1", "gamma1", "beta1", "w2", "gamma2", "beta2")
LEARNABLE_PROJ = ("w_proj", "gamma_proj", "beta_proj")


def _check_params(x: np.ndarray, params: object, x_name: str = "x") -> tuple[dict[str, np.ndarray], bool]:
    if not isinstance(params, dict):
        raise TypeError(f"params must be a dict of arrays, got {type(params).__name__}")
    missing = [k for k in RESIDUAL_KEYS if k not in params]
    if missing:
        raise ValueError(f"params lacks {', '.join(map(repr, missing))}")
    projection = "w_proj" in params
    if projection:
        missing = [k for k in PROJECTION_KEYS if k not in params]
        if missing:
            raise ValueError(f"params has w_proj but lacks {', '.join(map(repr, missing))}")
    keys = RESIDUAL_KEYS + (PROJECTION_KEYS if projection else ())
    p = {k: as_float_array(params[k], f"params[{k!r}]") for k in keys}
    c = x.shape[1]
    f = p["w1"].shape[0]
    if p["w1"].shape != (f, c, 3, 3):
        raise ValueError(f"params['w1'] must be (F, {c}, 3, 3), got shape {p['w1'].shape}")
    if p["w2"].shape != (f, f, 3, 3):
        raise ValueError(f"params['w2'] must be ({f}, {f}, 3, 3), got shape {p['w2'].shape}")
    if projection:
        if p["w_proj"].shape != (f, c, 1, 1):
            raise ValueError(f"params['w_proj'] must be ({f}, {c}, 1, 1), got shape {p['w_proj'].shape}")
    elif f != c:
        raise ValueError(
            f"without a projection the block must keep the channels: params['w1'] has {f} filters for "
            f"{c} input channels (give w_proj and its batch norm)"
        )
    # each batch norm's entries, named as the block's caller knows them (params['gamma2'])
    for suffix in ("1", "2") + (("_proj",) if projection else ()):
        for key in _BN:
            name = f"{key}{suffix}"
            if p[name].shape != (f,):
                raise ValueError(f"params[{name!r}] must have one entry per output channel ({f},), "
                                 f"got shape {p[name].shape}")
        if np.any(p[f"running_var{suffix}"] < 0):
            raise ValueError(f"params['running_var{suffix}'] must be >= 0 (a variance)")
    # the convolutions' largest arrays (their windows are 9 times the input) must fit in memory
    stride = (2, 2) if projection else (1, 1)
    ho, wo = check_conv_cost(x.shape, p["w1"].shape, stride, (1, 1), (x_name, "params['w1']", x_name))
    check_conv_cost((x.shape[0], f, ho, wo), p["w2"].shape, (1, 1), (1, 1), (x_name, "params['w2']", x_name))
    return p, projection


def _bn_args(p: dict[str, np.ndarray], suffix: str) -> tuple[np.ndarray, ...]:
    return tuple(p[f"{k}{suffix}"] for k in _BN)


def _forward(x: np.ndarray, p: dict[str, np.ndarray], projection: bool, training: bool, momentum: float,
             eps: float) -> tuple[np.ndarray, dict[str, Any]]:
    conv = implementation("nn.conv2d_forward")
    bn = implementation("nn.batchnorm2d_forward")
    relu = implementation("nn.relu_forward")
    f = p["w1"].shape[0]
    zeros = np.zeros(f)
    stride = 2 if projection else 1
    c: dict[str, Any] = {}
    h, c["conv1"] = conv(x, p["w1"], zeros, stride=stride, padding=1)
    h, c["bn1"] = bn(h, *_bn_args(p, "1"), training, momentum=momentum, eps=eps)
    h, c["relu1"] = relu(h)
    h, c["conv2"] = conv(h, p["w2"], zeros, stride=1, padding=1)
    h, c["bn2"] = bn(h, *_bn_args(p, "2"), training, momentum=momentum, eps=eps)
    if projection:
        s, c["conv_proj"] = conv(x, p["w_proj"], zeros, stride=2, padding=0)
        s, c["bn_proj"] = bn(s, *_bn_args(p, "_proj"), training, momentum=momentum, eps=eps)
    else:
        s = x
    out, c["relu_out"] = relu(h + s)
    return np.asarray(out, dtype=np.float64), c


@algorithm("nn.residual_block_forward", section="11.5.2–11.5.4", check="cvkit.nn.checks:residual_block_forward")
def residual_block_forward(x: ArrayLike, params: dict[str, ArrayLike], training: bool = True, momentum: float = 0.1,
                           eps: float = 1e-5) -> tuple[np.ndarray, dict[str, Any]]:
    """ResNet basic block: two 3×3 conv + BN layers, the shortcut added before the last ReLU.

    Parameters
    ----------
    x : (N, C, H, W) array_like
        The windows of the block's 3×3 convolutions (N·H·W·C·9 values, and the same with F)
        must fit in 2 GiB (cvkit's limit for one array), else ``ValueError`` naming ``x``.
    params : dict
        ``w1`` (F, C, 3, 3), ``gamma1``, ``beta1``, ``running_mean1``, ``running_var1`` (F,);
        ``w2`` (F, F, 3, 3) and ``gamma2`` ... ``running_var2``; optionally the projection
        ``w_proj`` (F, C, 1, 1), ``gamma_proj``, ``beta_proj``, ``running_mean_proj``,
        ``running_var_proj``. Without a projection F must equal C.
    training : bool
        Batch norm in training mode (batch statistics) or evaluation mode (running ones).
    momentum, eps : float
        Passed to every batch norm.

    Returns
    -------
    out : float64 ndarray
        ``relu(bn2(conv2(relu(bn1(conv1(x))))) + shortcut(x))``: (N, F, H, W) with the identity
        shortcut; with a projection, (N, F, ⌊(H−1)/2⌋+1, ⌊(W−1)/2⌋+1), because conv1 and the 1×1
        projection then both have stride 2.
    cache : dict
        ``{"x", "params", "training", "momentum", "eps"}`` (the arguments), plus the **new**
        running statistics of the three batch norms under their parameter names
        (``running_mean1``, ``running_var1``, ``running_mean2``, ... ``running_var_proj``):
        ``params.update({k: cache[k] for k in params if k.startswith("running")})`` keeps a
        model's statistics up to date.

    Notes
    -----
    §11.5.2: the layers learn the residual F(x) = H(x) − x; with small weights the block
    starts near the identity. §11.5.4: where the block halves the resolution and changes the
    number of channels, x cannot be added as it is; a strided 1×1 convolution (+ BN)
    projects it. The convolutions have no bias (a bias before batch norm is cancelled by
    the mean subtraction).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> def bn(c, s):
    ...     return {f"gamma{s}": np.ones(c), f"beta{s}": np.zeros(c),
    ...             f"running_mean{s}": np.zeros(c), f"running_var{s}": np.ones(c)}
    >>> params = {"w1": 0.1 * rng.standard_normal((8, 4, 3, 3)), **bn(8, "1"),
    ...           "w2": 0.1 * rng.standard_normal((8, 8, 3, 3)), **bn(8, "2"),
    ...           "w_proj": 0.1 * rng.standard_normal((8, 4, 1, 1)), **bn(8, "_proj")}
    >>> out, cache = residual_block_forward(rng.standard_normal((2, 4, 6, 6)), params)
    >>> out.shape, bool(out.min() >= 0)
    ((2, 8, 3, 3), True)
    """
    x = as_batch(x, "x")
    p, projection = _check_params(x, params)
    training = check_bool(training, "training")
    momentum = check_real(momentum, "momentum", nonnegative=True)
    eps = check_real(eps, "eps", positive=True)
    stride = 2 if projection else 1
    per_channel = x.shape[0] * ((x.shape[2] - 1) // stride + 1) * ((x.shape[3] - 1) // stride + 1)
    if training and per_channel < 2:
        raise ValueError(f"x must give its batch norms at least 2 values per channel in training: the "
                         f"{'stride-2 ' if projection else ''}convolutions leave N·H'·W' = {per_channel}")
    out, sub = _forward(x, p, projection, training, momentum, eps)
    cache = {"x": x, "params": p, "training": training, "momentum": momentum, "eps": eps}
    for name, suffix in (("bn1", "1"), ("bn2", "2")) + ((("bn_proj", "_proj"),) if projection else ()):
        cache[f"running_mean{suffix}"] = np.asarray(sub[name]["running_mean"], dtype=np.float64)
        cache[f"running_var{suffix}"] = np.asarray(sub[name]["running_var"], dtype=np.float64)
    return out, cache


@algorithm("nn.residual_block_backward", section="11.5.2–11.5.4", check="cvkit.nn.checks:residual_block_backward")
def residual_block_backward(dout: ArrayLike, cache: dict[str, Any]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Gradients of :func:`residual_block_forward`.

    Parameters
    ----------
    dout : array_like
        Upstream gradient, the shape of the block's output.
    cache : dict
        The cache of :func:`residual_block_forward`; only ``x``, ``params``, ``training``
        (and ``momentum``, ``eps`` if present) are read: the forward pass is recomputed from
        them.

    Returns
    -------
    dx : float64 ndarray, the shape of x
        The gradient through the layers **plus** the gradient through the shortcut (the
        identity passes ``dout``-after-the-ReLU straight to x: the "gradient highway").
    grads : dict
        ``w1``, ``gamma1``, ``beta1``, ``w2``, ``gamma2``, ``beta2`` and, with a projection,
        ``w_proj``, ``gamma_proj``, ``beta_proj``: the gradients of the learnable entries of
        ``params``.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> bn = lambda s: {f"gamma{s}": np.ones(2), f"beta{s}": np.zeros(2),
    ...                 f"running_mean{s}": np.zeros(2), f"running_var{s}": np.ones(2)}
    >>> params = {"w1": rng.standard_normal((2, 2, 3, 3)), **bn("1"), "w2": rng.standard_normal((2, 2, 3, 3)), **bn("2")}
    >>> out, cache = residual_block_forward(rng.standard_normal((2, 2, 4, 4)), params)
    >>> dx, grads = residual_block_backward(np.ones_like(out), cache)
    >>> dx.shape, sorted(grads)
    ((2, 2, 4, 4), ['beta1', 'beta2', 'gamma1', 'gamma2', 'w1', 'w2'])
    """
    check_cache(cache, ("x", "params", "training"), "residual_block")
    x = as_batch(cache["x"], "cache['x']")
    p, projection = _check_params(x, cache["params"], "cache['x']")
    training = check_bool(cache["training"], "cache['training']")
    momentum = check_real(cache.get("momentum", 0.1), "cache['momentum']", nonnegative=True)
    eps = check_real(cache.get("eps", 1e-5), "cache['eps']", positive=True)
    out, c = _forward(x, p, projection, training, momentum, eps)
    dout = as_float_array(dout, "dout", ndim=4)
    if dout.shape != out.shape:
        raise ValueError(f"dout must have the shape of the block's output {out.shape}, got {dout.shape}")
    conv_b = implementation("nn.conv2d_backward")
    bn_b = implementation("nn.batchnorm2d_backward")
    relu_b = implementation("nn.relu_backward")
    grads: dict[str, Any] = {}
    dz = np.asarray(relu_b(dout, c["relu_out"]), dtype=np.float64)
    dh, grads["gamma2"], grads["beta2"] = bn_b(dz, c["bn2"])
    dh, grads["w2"], _ = conv_b(dh, c["conv2"])
    dh = relu_b(dh, c["relu1"])
    dh, grads["gamma1"], grads["beta1"] = bn_b(dh, c["bn1"])
    dx, grads["w1"], _ = conv_b(dh, c["conv1"])
    dx = np.array(dx, dtype=np.float64)
    if projection:
        ds, grads["gamma_proj"], grads["beta_proj"] = bn_b(dz, c["bn_proj"])
        ds, grads["w_proj"], _ = conv_b(ds, c["conv_proj"])
        dx += ds
    else:
        dx += dz
    order = LEARNABLE + (LEARNABLE_PROJ if projection else ())
    return dx, {k: np.asarray(grads[k], dtype=np.float64) for k in order}
