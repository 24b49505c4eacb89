"""Convolution layers of §10.7: output size, receptive field, and the 2-D convolution layer.

The layer is the *cross-correlation* deep-learning libraries call convolution (§10.7.1: the
kernel is not flipped), over all input channels at once plus a bias (§10.7.3), with zero
padding and a stride (§10.7.4). It is vectorised through a strided view of every window
(im2col without copying until the one matrix product); loops only run over kernel taps.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from functools import partial
from typing import Any, TypeAlias

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import ArrayLike

from .._validation import MAX_ARRAY_BYTES, as_float_array, check_allocation, check_int
from ..registry import algorithm
from ._common import as_batch, as_gradient, check_cache, entry_name, pair

__all__ = ["conv_output_size", "receptive_field", "conv2d_forward", "conv2d_backward"]

#: ``stride`` and ``padding`` of the convolution: an int or a pair (rows, cols)
IntOrPair: TypeAlias = int | Sequence[int]


def _output_size(size: int, kernel: int, padding: int, stride: int, what: str = "input",
                 kernel_name: str = "kernel") -> int:
    span = size + 2 * padding - kernel
    if span < 0:
        raise ValueError(
            f"{kernel_name} {kernel} is larger than the padded {what} ({size} + 2·{padding} = {size + 2 * padding})"
        )
    return span // stride + 1


@algorithm("nn.conv_output_size", section="10.7.4", exercise="10.7.3", check="cvkit.nn.checks:conv_output_size")
def conv_output_size(size: int, kernel: int, padding: int = 0, stride: int = 1) -> int:
    """Spatial size of the output of a convolution (or pooling) layer along one axis.

    Parameters
    ----------
    size : int
        Input size H (≥ 1).
    kernel : int
        Kernel size K (≥ 1).
    padding : int
        Zeros added on **each** side, P ≥ 0.
    stride : int
        Step S ≥ 1 between neighbouring windows.

    Returns
    -------
    int
        :math:`H_{out} = \\lfloor (H - K + 2P)/S \\rfloor + 1`, the number of window positions
        that fit entirely in the padded input. A kernel larger than ``H + 2P`` raises
        ``ValueError``.

    Notes
    -----
    §10.7.4 (Figure 90). With S = 1 and P = (K − 1)/2 the size is kept ("same" padding); the
    floor drops the last rows when the stride does not divide H − K + 2P (PyTorch's default,
    ``ceil_mode=False``).

    Examples
    --------
    >>> conv_output_size(224, 7, padding=3, stride=2)
    112
    >>> conv_output_size(7, 3), conv_output_size(7, 3, padding=1), conv_output_size(8, 3, 1, 2)
    (5, 7, 4)
    """
    size = check_int(size, "size", minimum=1)
    kernel = check_int(kernel, "kernel", minimum=1)
    padding = check_int(padding, "padding", minimum=0)
    stride = check_int(stride, "stride", minimum=1)
    return _output_size(size, kernel, padding, stride)


@algorithm("nn.receptive_field", section="10.7.4", check="cvkit.nn.checks:receptive_field")
def receptive_field(layers: Iterable[tuple[int, int]]) -> int:
    """Side of the receptive field of one unit of the last layer of a stack.

    Parameters
    ----------
    layers : sequence of (kernel, stride)
        The layers from the input up, each a pair of ints (kernel ≥ 1, stride ≥ 1):
        convolutions and poolings alike (padding does not change the size of the field).
        An empty stack gives 1.

    Returns
    -------
    int
        :math:`r_L = 1 + \\sum_{l=1}^{L} (K_l - 1) \\prod_{j<l} S_j`: layer ``l`` widens the
        field by ``K_l − 1`` of *its* input units, each of which is ``∏_{j<l} S_j`` input pixels
        apart.

    Notes
    -----
    §10.7.4 (Figures 89 and 91). With stride 1 everywhere this is the notes'
    :math:`1 + L(K - 1)`: linear growth with depth. Strides multiply the spacing of later
    layers, so the field grows exponentially with the number of strided layers.

    Examples
    --------
    >>> receptive_field([(3, 1), (3, 1)])            # two 3×3 convs see a 5×5 patch, like one 5×5
    5
    >>> receptive_field([(3, 1), (2, 2), (3, 1), (2, 2), (3, 1)])
    18
    """
    if isinstance(layers, (str, bytes)) or not hasattr(layers, "__iter__"):
        raise TypeError(f"layers must be a list of (kernel, stride) pairs, got {type(layers).__name__}")
    field, jump = 1, 1
    for index, layer in enumerate(layers):
        try:
            kernel, stride = layer
        except (TypeError, ValueError):
            raise ValueError(f"layers[{index}] must be a pair (kernel, stride), got {layer!r}") from None
        kernel = check_int(kernel, f"layers[{index}] kernel", minimum=1)
        stride = check_int(stride, f"layers[{index}] stride", minimum=1)
        field += (kernel - 1) * jump
        jump *= stride
    return int(field)


# --------------------------------------------------------------------------------------------
# the convolution layer
# --------------------------------------------------------------------------------------------
def _conv_arguments(x: ArrayLike, w: ArrayLike, b: ArrayLike, stride: IntOrPair, padding: IntOrPair,
                    prefix: str = "") -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[int, int], tuple[int, int]]:
    """The arguments of the layer checked; ``prefix`` (``"cache"``) names them as entries of a
    cache: ``cache['x']``."""
    name = partial(entry_name, prefix)

    x = as_batch(x, name("x"))
    w = as_float_array(w, name("w"), ndim=4)
    b = as_float_array(b, name("b"), ndim=1)
    if w.shape[1] != x.shape[1]:
        raise ValueError(
            f"{name('w')} must be (F, C, kh, kw) with C = {x.shape[1]} (the channels of {name('x')}), got shape {w.shape}"
        )
    if b.shape[0] != w.shape[0]:
        raise ValueError(f"{name('b')} must have one bias per filter ({w.shape[0]}), got shape {b.shape}")
    return x, w, b, pair(stride, name("stride"), minimum=1), pair(padding, name("padding"), minimum=0)


def _workspace(x_shape: tuple[int, ...], w_shape: tuple[int, ...], stride: tuple[int, int],
               padding: tuple[int, int], w_name: str = "w") -> tuple[tuple[int, int], list[tuple[tuple[int, ...], str]]]:
    """Output size and the largest arrays the layer allocates: the zero-padded input, the
    im2col copy of every window that ``tensordot`` makes (the backward pass makes one as large),
    and the output."""
    n, c, h, width = x_shape
    f, _, kh, kw = w_shape
    (sh, sw), (ph, pw) = stride, padding
    ho = _output_size(h, kh, ph, sh, "input height", f"{w_name}'s kernel height")
    wo = _output_size(width, kw, pw, sw, "input width", f"{w_name}'s kernel width")
    arrays: list[tuple[tuple[int, ...], str]] = [
        ((n, ho, wo, c * kh * kw), "the windows of the input (im2col)"), ((n, f, ho, wo), "the output")]
    if ph or pw:
        arrays.append(((n, c, h + 2 * ph, width + 2 * pw), "the zero-padded input"))
    return (ho, wo), arrays


def _fits(arrays: list[tuple[tuple[int, ...], str]]) -> bool:
    return all(8 * math.prod(shape) <= MAX_ARRAY_BYTES for shape, _ in arrays)


def check_conv_cost(x_shape: tuple[int, ...], w_shape: tuple[int, ...], stride: tuple[int, int],
                    padding: tuple[int, int], names: tuple[str, str, str] = ("x", "w", "padding")) -> tuple[int, int]:
    """The output size ``(Ho, Wo)`` of a convolution, after checking that none of its arrays
    would exceed :data:`cvkit._validation.MAX_ARRAY_BYTES` (``ValueError`` before anything is
    allocated). ``names`` are the caller's names of the input, the filters and the padding:
    the padding is named when the layer with at most ``kernel − 1`` zeros a side would fit, the
    input otherwise."""
    x_name, w_name, padding_name = names
    size, arrays = _workspace(x_shape, w_shape, stride, padding, w_name)
    if _fits(arrays):
        return size
    # padding beyond kernel − 1 only adds windows of zeros: blame it when the layer fits without
    reasonable = (min(padding[0], w_shape[2] - 1), min(padding[1], w_shape[3] - 1))
    fits_reasonably = reasonable != padding and _fits(_workspace(x_shape, w_shape, stride, reasonable, w_name)[1])
    blame = padding_name if fits_reasonably else x_name
    for shape, what in arrays:
        check_allocation(shape, blame, what=what)
    raise AssertionError("unreachable: an array above exceeds the limit")


def _windows(x: np.ndarray, kernel: tuple[int, int], stride: tuple[int, int],
             padding: tuple[int, int]) -> np.ndarray:
    """The strided view of the windows ``(N, C, Ho, Wo, kh, kw)`` of the zero-padded ``x``."""
    (kh, kw), (sh, sw), (ph, pw) = kernel, stride, padding
    xp = np.pad(x, ((0, 0), (0, 0), (ph, ph), (pw, pw))) if ph or pw else x
    return sliding_window_view(xp, (kh, kw), axis=(2, 3))[:, :, ::sh, ::sw]


@algorithm("nn.conv2d_forward", section="10.7.3", check="cvkit.nn.checks:conv2d_forward")
def conv2d_forward(x: ArrayLike, w: ArrayLike, b: ArrayLike, stride: IntOrPair = 1,
                   padding: IntOrPair = 0) -> tuple[np.ndarray, dict[str, Any]]:
    """Convolution layer: zero-padded cross-correlation over all input channels, plus a bias.

    Parameters
    ----------
    x : (N, C, H, W) array_like
        A batch of N feature maps with C channels.
    w : (F, C, kh, kw) array_like
        F filters, each as deep as the input (a "3×3 convolution" on C channels has
        C·3·3 weights per filter). Any kernel size, odd or even, square or not.
    b : (F,) array_like
        One bias per filter.
    stride : int or (int, int)
        Step S ≥ 1 between neighbouring windows (rows, cols).
    padding : int or (int, int)
        Zeros P ≥ 0 added on each side of the input (rows, cols). Bounded by memory: the
        padded input, the copy of its windows that the product makes (N·Ho·Wo·C·kh·kw values)
        and the output must each fit in 2 GiB (cvkit's limit for one array,
        :data:`cvkit._validation.MAX_ARRAY_BYTES`), or ``ValueError`` names ``padding`` (when
        at most kh − 1 zeros a side would fit) or ``x``, before anything is allocated.

    Returns
    -------
    out : (N, F, Ho, Wo) float64 ndarray
        :math:`\\mathrm{out}[n, f, i, j] = b_f + \\sum_{c, m, l} w[f, c, m, l]\\,
        x_p[n, c, S i + m, S j + l]` with :math:`x_p` the zero-padded input and
        :math:`H_o = \\lfloor (H - k_h + 2P)/S \\rfloor + 1` (:func:`conv_output_size`).
    cache : dict
        ``{"x", "w", "b", "stride", "padding"}``: the arguments (arrays as float64, stride and
        padding as given).

    Notes
    -----
    §10.7.1–10.7.4. The kernel is **not** flipped: deep-learning "convolution" is
    correlation, a dot product between the filter and each input patch. One filter gives one
    feature map; F filters give F channels. Vectorised as im2col: a strided view of all
    windows and one ``tensordot`` with the filters.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.arange(16.0).reshape(1, 1, 4, 4)
    >>> w = np.array([[[[1.0, 0.0], [0.0, -1.0]]]])       # x[i, j] - x[i+1, j+1]
    >>> out, cache = conv2d_forward(x, w, np.array([0.5]))
    >>> out[0, 0]
    array([[-4.5, -4.5, -4.5],
           [-4.5, -4.5, -4.5],
           [-4.5, -4.5, -4.5]])
    >>> conv2d_forward(x, w, np.zeros(1), stride=2, padding=1)[0].shape
    (1, 1, 3, 3)
    """
    x, w, b, s, p = _conv_arguments(x, w, b, stride, padding)
    check_conv_cost(x.shape, w.shape, s, p)
    view = _windows(x, (w.shape[2], w.shape[3]), s, p)
    out = np.tensordot(view, w, axes=([1, 4, 5], [1, 2, 3]))       # (N, Ho, Wo, F)
    out = np.ascontiguousarray(out.transpose(0, 3, 1, 2))
    out += b[None, :, None, None]
    return out, {"x": x, "w": w, "b": b, "stride": stride, "padding": padding}


@algorithm("nn.conv2d_backward", section="10.7.3", check="cvkit.nn.checks:conv2d_backward")
def conv2d_backward(dout: ArrayLike, cache: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gradients of :func:`conv2d_forward` with respect to the input, the filters and the biases.

    Parameters
    ----------
    dout : (N, F, Ho, Wo) array_like
        Upstream gradient ∂L/∂out.
    cache : dict
        The cache of :func:`conv2d_forward` (``x``, ``w``, ``b``, ``stride``, ``padding``);
        its entries are checked as the forward's arguments (same memory bound), errors naming
        them ``cache['x']``, ``cache['padding']``, ...

    Returns
    -------
    dx : (N, C, H, W) float64 ndarray
        Each output gradient spread back over its window with the filter's weights
        (summed where windows overlap), the padding cropped off.
    dw : (F, C, kh, kw) float64 ndarray
        :math:`\\sum_{n,i,j} \\mathrm{dout}[n,f,i,j]\\; x_p[n, c, Si + m, Sj + l]`: the
        correlation of the padded input with ``dout``.
    db : (F,) float64 ndarray
        ``dout.sum(axis=(0, 2, 3))``.

    Notes
    -----
    With stride 1, ``dx`` is the *full convolution* of ``dout`` with the filters (the forward
    kernel flipped): the forward correlates, the backward convolves. With stride S the
    gradient lands only on every S-th window position. Input rows or columns no window reaches
    (when S does not divide H − kh + 2P) get zero gradient.

    Examples
    --------
    >>> import numpy as np
    >>> _, cache = conv2d_forward(np.zeros((1, 1, 3, 3)), np.ones((1, 1, 2, 2)), np.zeros(1))
    >>> dx, dw, db = conv2d_backward(np.ones((1, 1, 2, 2)), cache)
    >>> dx[0, 0]
    array([[1., 2., 1.],
           [2., 4., 2.],
           [1., 2., 1.]])
    >>> db
    array([4.])
    """
    check_cache(cache, ("x", "w", "b", "stride", "padding"), "conv2d")
    x, w, b, (sh, sw), (ph, pw) = _conv_arguments(
        cache["x"], cache["w"], cache["b"], cache["stride"], cache["padding"], prefix="cache")
    kh, kw = w.shape[2:]
    ho, wo = check_conv_cost(x.shape, w.shape, (sh, sw), (ph, pw),
                             ("cache['x']", "cache['w']", "cache['padding']"))
    view = _windows(x, (kh, kw), (sh, sw), (ph, pw))
    dout = as_gradient(dout, "dout", (x.shape[0], w.shape[0], ho, wo))
    db = dout.sum(axis=(0, 2, 3))
    dw = np.tensordot(dout, view, axes=([0, 2, 3], [0, 2, 3]))      # (F, C, kh, kw)
    dcols = np.tensordot(dout, w, axes=([1], [0]))                  # (N, Ho, Wo, C, kh, kw)
    n, c, h, width = x.shape
    dxp = np.zeros((n, c, h + 2 * ph, width + 2 * pw))
    for m in range(kh):
        for l in range(kw):
            dxp[:, :, m : m + sh * (ho - 1) + 1 : sh, l : l + sw * (wo - 1) + 1 : sw] += \
                dcols[:, :, :, :, m, l].transpose(0, 3, 1, 2)
    dx = np.ascontiguousarray(dxp[:, :, ph : ph + h, pw : pw + width])
    return dx, dw, db
