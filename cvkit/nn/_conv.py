"""Convolution layers of §10.7: output size, receptive field, and the 2-D convolution layer.

The layer is the *cross-correlation* deep-learning libraries call convolution (§10.7.1: the
kernel is not flipped), over all input channels at once plus a bias (§10.7.3), with zero
padding and a stride (§10.7.4). It is vectorised through a strided view of every window
(im2col without copying until the one matrix product); loops only run over kernel taps.
"""
from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .._validation import as_float_array, check_int
from ..registry import algorithm
from ._common import as_batch, as_gradient, check_cache, pair

__all__ = ["conv_output_size", "receptive_field", "conv2d_forward", "conv2d_backward"]


def _output_size(size: int, kernel: int, padding: int, stride: int, what: str = "input") -> int:
    span = size + 2 * padding - kernel
    if span < 0:
        raise ValueError(
            f"kernel {kernel} is larger than the padded {what} ({size} + 2·{padding} = {size + 2 * padding})"
        )
    return span // stride + 1


@algorithm("nn.conv_output_size", section="10.7.4", check="cvkit.nn.checks:conv_output_size")
def conv_output_size(size, kernel, padding=0, stride=1):
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
def receptive_field(layers):
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
def _conv_arguments(x, w, b, stride, padding):
    x = as_batch(x, "x")
    w = as_float_array(w, "w", ndim=4)
    b = as_float_array(b, "b", ndim=1)
    if w.shape[1] != x.shape[1]:
        raise ValueError(
            f"w must be (F, C, kh, kw) with C = {x.shape[1]} (the channels of x), got shape {w.shape}"
        )
    if b.shape[0] != w.shape[0]:
        raise ValueError(f"b must have one bias per filter ({w.shape[0]}), got shape {b.shape}")
    stride = pair(stride, "stride", minimum=1)
    padding = pair(padding, "padding", minimum=0)
    return x, w, b, stride, padding


def _windows(x: np.ndarray, kernel: tuple, stride: tuple, padding: tuple) -> tuple[np.ndarray, tuple]:
    """Zero-padded ``x`` and the strided view of its windows ``(N, C, Ho, Wo, kh, kw)``."""
    (kh, kw), (sh, sw), (ph, pw) = kernel, stride, padding
    ho = _output_size(x.shape[2], kh, ph, sh, "input height")
    wo = _output_size(x.shape[3], kw, pw, sw, "input width")
    xp = np.pad(x, ((0, 0), (0, 0), (ph, ph), (pw, pw))) if ph or pw else x
    view = sliding_window_view(xp, (kh, kw), axis=(2, 3))[:, :, ::sh, ::sw]
    return view, (ho, wo)


@algorithm("nn.conv2d_forward", section="10.7.3", check="cvkit.nn.checks:conv2d_forward")
def conv2d_forward(x, w, b, stride=1, padding=0):
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
        Step S between neighbouring windows (rows, cols).
    padding : int or (int, int)
        Zeros added on each side of the input (rows, cols).

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
    view, _ = _windows(x, w.shape[2:], s, p)
    out = np.tensordot(view, w, axes=([1, 4, 5], [1, 2, 3]))       # (N, Ho, Wo, F)
    out = np.ascontiguousarray(out.transpose(0, 3, 1, 2))
    out += b[None, :, None, None]
    return out, {"x": x, "w": w, "b": b, "stride": stride, "padding": padding}


@algorithm("nn.conv2d_backward", section="10.7.3", check="cvkit.nn.checks:conv2d_backward")
def conv2d_backward(dout, cache):
    """Gradients of :func:`conv2d_forward` with respect to the input, the filters and the biases.

    Parameters
    ----------
    dout : (N, F, Ho, Wo) array_like
        Upstream gradient ∂L/∂out.
    cache : dict
        The cache of :func:`conv2d_forward` (``x``, ``w``, ``b``, ``stride``, ``padding``).

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
    x, w, b, (sh, sw), (ph, pw) = _conv_arguments(cache["x"], cache["w"], cache["b"], cache["stride"], cache["padding"])
    kh, kw = w.shape[2:]
    view, (ho, wo) = _windows(x, (kh, kw), (sh, sw), (ph, pw))
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
