"""Pooling layers: max pooling (§10.7.5) and global average pooling (§11.3.5)."""
from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import ArrayLike

from .._validation import check_allocation, check_int
from ..registry import algorithm
from ._common import as_batch, as_gradient, check_cache, entry_name

__all__ = ["maxpool2d_forward", "maxpool2d_backward", "global_avg_pool_forward", "global_avg_pool_backward"]


def _pool_arguments(x: ArrayLike, size: int, stride: int,
                    prefix: str = "") -> tuple[np.ndarray, int, int, tuple[int, int]]:
    """The checked arguments and the output size ``(Ho, Wo)``; ``prefix`` (``"cache"``) names
    them as entries of a cache. The window must fit in ``x`` and the copy of all windows
    (``N·C·Ho·Wo·size²`` values) in cvkit's 2 GiB per array."""
    name = partial(entry_name, prefix)

    x = as_batch(x, name("x"))
    size = check_int(size, name("size"), minimum=1)
    stride = check_int(stride, name("stride"), minimum=1)
    n, c, h, w = x.shape
    if size > min(h, w):
        raise ValueError(f"{name('size')} must be at most the height and width of {name('x')} "
                         f"({h} × {w}), got {size}")
    ho, wo = (h - size) // stride + 1, (w - size) // stride + 1
    check_allocation((n, c, ho, wo, size * size), name("size"), what="the copy of the pooling windows")
    return x, size, stride, (ho, wo)


def _pool_windows(x: np.ndarray, size: int, stride: int) -> np.ndarray:
    """Every ``size × size`` window, flattened: ``(N, C, Ho, Wo, size²)`` (a copy)."""
    view = sliding_window_view(x, (size, size), axis=(2, 3))[:, :, ::stride, ::stride]
    return view.reshape(view.shape[:4] + (size * size,))


@algorithm("nn.maxpool2d_forward", section="10.7.5", check="cvkit.nn.checks:maxpool2d_forward")
def maxpool2d_forward(x: ArrayLike, size: int = 2, stride: int = 2) -> tuple[np.ndarray, dict[str, Any]]:
    """Max pooling: the maximum of each ``size × size`` window, channel by channel.

    Parameters
    ----------
    x : (N, C, H, W) array_like
        A batch of feature maps, at least ``size × size``.
    size : int
        Side of the (square) pooling window, 1 ≤ size ≤ min(H, W). Bounded by memory too: the
        copy of all windows (N·C·Ho·Wo·size² values) must fit in 2 GiB (cvkit's limit for one
        array), else ``ValueError`` naming ``size``, before anything is allocated.
    stride : int
        Step between windows, ≥ 1; ``stride < size`` gives overlapping windows.

    Returns
    -------
    out : (N, C, Ho, Wo) float64 ndarray
        ``Ho = ⌊(H − size)/stride⌋ + 1`` (no padding; trailing rows or columns that do not fill
        a window are dropped, like PyTorch's default ``ceil_mode=False``).
    cache : dict
        ``{"x": x, "size": size, "stride": stride}``.

    Notes
    -----
    §10.7.5: no parameters, each channel pooled independently (C stays C). The usual 2×2,
    stride 2 pooling halves the resolution and gives a little invariance to small shifts.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.array([[[[1.0, 2, 5, 0], [3, 4, 1, 1], [0, 0, 2, 2], [9, 0, 2, 2]]]])
    >>> maxpool2d_forward(x)[0][0, 0]
    array([[4., 5.],
           [9., 2.]])
    """
    x, size, stride, _ = _pool_arguments(x, size, stride)
    windows = _pool_windows(x, size, stride)
    return windows.max(axis=-1), {"x": x, "size": size, "stride": stride}


@algorithm("nn.maxpool2d_backward", section="10.7.5", check="cvkit.nn.checks:maxpool2d_backward")
def maxpool2d_backward(dout: ArrayLike, cache: dict[str, Any]) -> np.ndarray:
    """Gradient of :func:`maxpool2d_forward`: each window's gradient goes to its maximum.

    Parameters
    ----------
    dout : (N, C, Ho, Wo) array_like
        Upstream gradient.
    cache : dict
        The cache of :func:`maxpool2d_forward` (``x``, ``size``, ``stride``), checked as the
        forward's arguments (errors name ``cache['size']``, ...).

    Returns
    -------
    dx : (N, C, H, W) float64 ndarray
        Zero except at the arg-max of each window, which receives that window's ``dout``.
        When a window holds its maximum several times, only the **first** in row-major order
        gets it (``np.argmax``'s rule, and PyTorch's); when overlapping windows share a
        maximum, their gradients add up.

    Notes
    -----
    The max is locally the identity on the winning element and constant in the others, so
    the gradient is routed, not spread (spreading it evenly is average pooling's gradient).

    Examples
    --------
    >>> import numpy as np
    >>> x = np.array([[[[1.0, 7.0], [7.0, 0.0]]]])
    >>> _, cache = maxpool2d_forward(x)
    >>> maxpool2d_backward(np.array([[[[3.0]]]]), cache)[0, 0]
    array([[0., 3.],
           [0., 0.]])
    """
    check_cache(cache, ("x", "size", "stride"), "maxpool2d")
    x, size, stride, (ho, wo) = _pool_arguments(cache["x"], cache["size"], cache["stride"], prefix="cache")
    windows = _pool_windows(x, size, stride)
    dout = as_gradient(dout, "dout", x.shape[:2] + (ho, wo))
    winner = windows.argmax(axis=-1)
    dx = np.zeros(x.shape)
    for m in range(size):
        for l in range(size):
            dx[:, :, m : m + stride * (ho - 1) + 1 : stride, l : l + stride * (wo - 1) + 1 : stride] += \
                np.where(winner == m * size + l, dout, 0.0)
    return dx


@algorithm("nn.global_avg_pool_forward", section="11.3.5", check="cvkit.nn.checks:global_avg_pool_forward")
def global_avg_pool_forward(x: ArrayLike) -> tuple[np.ndarray, dict[str, Any]]:
    """Global average pooling: the mean of each feature map.

    Parameters
    ----------
    x : (N, C, H, W) array_like

    Returns
    -------
    out : (N, C) float64 ndarray
        ``x.mean(axis=(2, 3))``: one number per channel, whatever H and W are.
    cache : dict
        ``{"x": x}``.

    Notes
    -----
    §11.3.5: GoogLeNet's replacement for the flatten + huge fully connected layers of
    AlexNet and VGG; a 7×7×1024 activation becomes a 1024-vector, and the network accepts any
    input size (PyTorch's ``AdaptiveAvgPool2d(1)`` followed by a flatten).

    Examples
    --------
    >>> import numpy as np
    >>> global_avg_pool_forward(np.arange(8.0).reshape(1, 2, 2, 2))[0]
    array([[1.5, 5.5]])
    """
    x = as_batch(x, "x")
    return x.mean(axis=(2, 3)), {"x": x}


@algorithm("nn.global_avg_pool_backward", section="11.3.5", check="cvkit.nn.checks:global_avg_pool_backward")
def global_avg_pool_backward(dout: ArrayLike, cache: dict[str, Any]) -> np.ndarray:
    """Gradient of :func:`global_avg_pool_forward`: ``dout / (H·W)`` at every position.

    Parameters
    ----------
    dout : (N, C) array_like
    cache : dict
        The cache of :func:`global_avg_pool_forward` (``x``, for its shape).

    Returns
    -------
    dx : (N, C, H, W) float64 ndarray

    Examples
    --------
    >>> import numpy as np
    >>> _, cache = global_avg_pool_forward(np.zeros((1, 1, 2, 2)))
    >>> global_avg_pool_backward(np.array([[4.0]]), cache)[0, 0]
    array([[1., 1.],
           [1., 1.]])
    """
    check_cache(cache, ("x",), "global_avg_pool")
    x = as_batch(cache["x"], "cache['x']")
    n, c, h, w = x.shape
    dout = as_gradient(dout, "dout", (n, c))
    return np.broadcast_to((dout / (h * w))[:, :, None, None], x.shape).copy()
