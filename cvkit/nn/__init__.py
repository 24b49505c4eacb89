"""Chapters 10–11 — neural network layers in NumPy and the architectures built from them.

Every layer is a pair ``<name>_forward(...) -> (out, cache)`` and ``<name>_backward(dout, cache)``;
the cache is a dict holding the forward's arguments under their own names plus what the layer
adds, so that a backward pass can be run (and graded) on any forward's cache. Feature maps are
``(N, C, H, W)``; everything is float64 and inputs are never modified.

* activations (§10.5.3–10.5.4): :func:`relu_forward`, :func:`sigmoid_forward`,
  :func:`leaky_relu_forward` and their backward passes;
* the fully connected layer (§10.5.1): :func:`linear_forward` with ``W`` in the layer
  convention ``(D, C)``;
* convolution (§10.7): :func:`conv_output_size`, :func:`receptive_field`,
  :func:`conv2d_forward` (cross-correlation, zero padding, stride);
* pooling and normalisation: :func:`maxpool2d_forward` (§10.7.5),
  :func:`global_avg_pool_forward` (§11.3.5), :func:`batchnorm2d_forward` (§10.7.6),
  :func:`dropout_forward` (§12.3.6);
* ResNet's basic block (§11.5): :func:`residual_block_forward`;
* architectures as data (§11.2–11.5): :func:`architecture_spec`, :func:`count_parameters`,
  :func:`count_flops`;
* a small CNN trained with these layers (:class:`SmallCNN`), for the transfer-learning
  experiments of §11.6.

>>> from cvkit import nn
>>> nn.count_parameters(nn.architecture_spec("vgg16"))
138357544
"""
from ._activations import (
    relu_forward,
    relu_backward,
    sigmoid_forward,
    sigmoid_backward,
    leaky_relu_forward,
    leaky_relu_backward,
)
from ._linear import linear_forward, linear_backward
from ._conv import conv_output_size, receptive_field, conv2d_forward, conv2d_backward
from ._pool import maxpool2d_forward, maxpool2d_backward, global_avg_pool_forward, global_avg_pool_backward
from ._norm import batchnorm2d_forward, batchnorm2d_backward, dropout_forward, dropout_backward
from ._residual import residual_block_forward, residual_block_backward
from ._architectures import ARCHITECTURES, architecture_spec, count_parameters, count_flops, layer_table
from ._model import SmallCNN

__all__ = [
    "relu_forward", "relu_backward", "sigmoid_forward", "sigmoid_backward",
    "leaky_relu_forward", "leaky_relu_backward",
    "linear_forward", "linear_backward",
    "conv_output_size", "receptive_field", "conv2d_forward", "conv2d_backward",
    "maxpool2d_forward", "maxpool2d_backward", "global_avg_pool_forward", "global_avg_pool_backward",
    "batchnorm2d_forward", "batchnorm2d_backward", "dropout_forward", "dropout_backward",
    "residual_block_forward", "residual_block_backward",
    "architecture_spec", "count_parameters", "count_flops", "layer_table", "ARCHITECTURES", "SmallCNN",
]
