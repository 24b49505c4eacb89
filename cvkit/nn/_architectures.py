"""Architectures as data (§11.2–11.5): layer lists, parameter and FLOP accounting.

A *spec* is a list of layer dicts, applied in order to one image ``(C, H, W)``:

================ ====================================================== ==========================
``type``         keys (defaults)                                        parameters
================ ====================================================== ==========================
``"conv"``       ``in``, ``out``, ``kernel``, ``stride`` (1),            ``out·in·kh·kw`` (+ ``out``
                 ``padding`` (0), ``bias`` (True); kernel, stride and   with a bias)
                 padding an int or a pair (rows, cols)
``"bn"``         ``channels``                                           ``2·channels`` (γ, β; the
                                                                        running statistics are
                                                                        buffers, not parameters)
``"relu"``       —                                                      0
``"maxpool"``    ``kernel``, ``stride`` (= kernel), ``padding`` (0)     0
``"avgpool"``    ``kernel``, ``stride`` (= kernel), ``padding`` (0)     0
``"gap"``        — : ``(C, H, W)`` → ``(C,)``                           0
``"flatten"``    — : ``(C, H, W)`` → ``(C·H·W,)``                       0
``"linear"``     ``in``, ``out``, ``bias`` (True)                       ``in·out`` (+ ``out``)
``"residual"``   ``body``, ``shortcut`` (specs; an empty shortcut is    those of body and shortcut
                 the identity): output = body(x) + shortcut(x)
``"concat"``     ``branches`` (a list of specs): outputs stacked along  those of the branches
                 the channels
================ ====================================================== ==========================

The ReLU after a residual sum is a separate ``{"type": "relu"}`` following the residual layer.
Output sizes follow :func:`cvkit.nn.conv_output_size` (floor). FLOPs count 2 per multiply-add of
the convolution and linear layers only (bias additions, batch norm, ReLU, pooling and the
residual sums are left out, as in the usual tables).
"""
from __future__ import annotations

import copy
import math
import numbers
from typing import Any

import numpy as np

from .._validation import check_int
from ..registry import algorithm

__all__ = ["architecture_spec", "count_parameters", "count_flops", "ARCHITECTURES", "layer_table"]

_TYPES = ("conv", "bn", "relu", "maxpool", "avgpool", "gap", "flatten", "linear", "residual", "concat")


# --------------------------------------------------------------------------------------------
# building blocks of the specs
# --------------------------------------------------------------------------------------------
Layer = dict[str, Any]
Spec = list[Layer]


def _conv(cin: int, cout: int, kernel: int, stride: int = 1, padding: int = 0, bias: bool = False) -> Layer:
    return {"type": "conv", "in": cin, "out": cout, "kernel": kernel, "stride": stride,
            "padding": padding, "bias": bias}


def _bn(c: int) -> Layer:
    return {"type": "bn", "channels": c}


_RELU: Layer = {"type": "relu"}


def _vgg(config: list[int | str], num_classes: int) -> Spec:
    spec: Spec = []
    cin = 3
    for v in config:
        if isinstance(v, str):  # "M"
            spec.append({"type": "maxpool", "kernel": 2, "stride": 2, "padding": 0})
        else:
            spec += [_conv(cin, v, 3, 1, 1, bias=True), dict(_RELU)]
            cin = v
    spec += [
        {"type": "flatten"},
        {"type": "linear", "in": 512 * 7 * 7, "out": 4096, "bias": True}, dict(_RELU),
        {"type": "linear", "in": 4096, "out": 4096, "bias": True}, dict(_RELU),
        {"type": "linear", "in": 4096, "out": num_classes, "bias": True},
    ]
    return spec


def _stem(kind: str) -> Spec:
    if kind == "c":  # ResNet-C: three 3×3 convolutions instead of the 7×7
        return [_conv(3, 32, 3, 2, 1), _bn(32), dict(_RELU), _conv(32, 32, 3, 1, 1), _bn(32), dict(_RELU),
                _conv(32, 64, 3, 1, 1), _bn(64), dict(_RELU),
                {"type": "maxpool", "kernel": 3, "stride": 2, "padding": 1}]
    return [_conv(3, 64, 7, 2, 3), _bn(64), dict(_RELU), {"type": "maxpool", "kernel": 3, "stride": 2, "padding": 1}]


def _shortcut(cin: int, cout: int, stride: int, avg_down: bool) -> Spec:
    if stride == 1 and cin == cout:
        return []
    if avg_down and stride != 1:  # ResNet-D: average pooling, then a stride-1 projection
        return [{"type": "avgpool", "kernel": stride, "stride": stride, "padding": 0},
                _conv(cin, cout, 1, 1, 0), _bn(cout)]
    return [_conv(cin, cout, 1, stride, 0), _bn(cout)]


def _basic_block(cin: int, cout: int, stride: int, avg_down: bool = False) -> Spec:
    body = [_conv(cin, cout, 3, stride, 1), _bn(cout), dict(_RELU), _conv(cout, cout, 3, 1, 1), _bn(cout)]
    return [{"type": "residual", "body": body, "shortcut": _shortcut(cin, cout, stride, avg_down)}, dict(_RELU)]


def _bottleneck(cin: int, width: int, stride: int, stride_in_3x3: bool = True, avg_down: bool = False) -> Spec:
    cout = 4 * width
    s1, s3 = (1, stride) if stride_in_3x3 else (stride, 1)
    body = [_conv(cin, width, 1, s1, 0), _bn(width), dict(_RELU),
            _conv(width, width, 3, s3, 1), _bn(width), dict(_RELU),
            _conv(width, cout, 1, 1, 0), _bn(cout)]
    return [{"type": "residual", "body": body, "shortcut": _shortcut(cin, cout, stride, avg_down)}, dict(_RELU)]


def _resnet(blocks: tuple[int, ...], bottleneck: bool, num_classes: int, stem: str = "b", stride_in_3x3: bool = True,
            avg_down: bool = False) -> Spec:
    spec = _stem(stem)
    cin = 64
    for stage, (count, width) in enumerate(zip(blocks, (64, 128, 256, 512))):
        for i in range(count):
            stride = 2 if (i == 0 and stage > 0) else 1
            if bottleneck:
                spec += _bottleneck(cin, width, stride, stride_in_3x3, avg_down)
                cin = 4 * width
            else:
                spec += _basic_block(cin, width, stride, avg_down)
                cin = width
    spec += [{"type": "gap"}, {"type": "linear", "in": cin, "out": num_classes, "bias": True}]
    return spec


def _inception(cin: int, n1: int, r3: int, n3: int, r5: int, n5: int, pool_proj: int, reduce: bool = True) -> Spec:
    """GoogLeNet's Inception module (2014: convolutions with bias and ReLU, no batch norm)."""
    def conv(a: int, b: int, k: int) -> Spec:
        return [_conv(a, b, k, 1, k // 2, bias=True), dict(_RELU)]

    pool = {"type": "maxpool", "kernel": 3, "stride": 1, "padding": 1}
    if reduce:
        branches = [conv(cin, n1, 1), conv(cin, r3, 1) + conv(r3, n3, 3), conv(cin, r5, 1) + conv(r5, n5, 5),
                    [pool] + conv(cin, pool_proj, 1)]
    else:  # the naive module: no 1×1 reductions, the pooled input concatenated as it is
        branches = [conv(cin, n1, 1), conv(cin, n3, 3), conv(cin, n5, 5), [pool]]
    return [{"type": "concat", "branches": branches}]


_VGG16: list[int | str] = [64, 64, "M", 128, 128, "M", 256, 256, 256, "M", 512, 512, 512, "M", 512, 512, 512, "M"]
_VGG19: list[int | str] = [64, 64, "M", 128, 128, "M", 256, 256, 256, 256, "M", 512, 512, 512, 512, "M", 512, 512, 512, 512, "M"]

#: names accepted by :func:`architecture_spec` → (input shape, what it is)
ARCHITECTURES: dict[str, tuple[tuple[int, int, int], str]] = {
    "vgg16": ((3, 224, 224), "VGG-16 (configuration D), as torchvision's vgg16"),
    "vgg19": ((3, 224, 224), "VGG-19 (configuration E)"),
    "resnet18": ((3, 224, 224), "ResNet-18, basic blocks [2, 2, 2, 2]"),
    "resnet34": ((3, 224, 224), "ResNet-34, basic blocks [3, 4, 6, 3]"),
    "resnet50": ((3, 224, 224), "ResNet-50 v1.5 = ResNet-B (stride 2 in the 3×3 of the bottleneck), torchvision's"),
    "resnet50_v1": ((3, 224, 224), "ResNet-50 as in the 2015 paper (stride 2 in the first 1×1)"),
    "resnet50_c": ((3, 224, 224), "ResNet-C: ResNet-B with a stem of three 3×3 convolutions"),
    "resnet50_d": ((3, 224, 224), "ResNet-D: ResNet-C with 2×2 average pooling before the strided projections"),
    "inception_3a": ((192, 28, 28), "GoogLeNet's Inception (3a) module with 1×1 reductions, 192 → 256 channels"),
    "inception_3a_naive": ((192, 28, 28), "the naive Inception (3a): no 1×1 reductions, 192 → 416 channels (the pooled input passes through)"),
}


@algorithm("nn.architecture_spec", section="11.2–11.5", check="cvkit.nn.checks:architecture_spec")
def architecture_spec(name: str, num_classes: int = 1000) -> Spec:
    """The layers of a classic architecture as a list of layer dicts.

    Parameters
    ----------
    name : str
        ``"vgg16"``, ``"resnet18"``, ``"resnet50"`` (torchvision's v1.5: the stride-2 of a
        downsampling bottleneck sits in its 3×3 convolution), ``"inception_3a"`` (GoogLeNet's
        first Inception module: 192 channels at 28×28 in, 64 + 128 + 32 + 32 = 256 out); also
        ``"vgg19"``, ``"resnet34"``, ``"resnet50_v1"`` (stride in the first 1×1, the paper's
        original), ``"resnet50_c"``, ``"resnet50_d"`` (the tweaks of §11.5.7) and
        ``"inception_3a_naive"`` (without the 1×1 reductions). See :data:`ARCHITECTURES`.
    num_classes : int
        Outputs of the last linear layer (ignored by the Inception modules).

    Returns
    -------
    list of dict
        The spec (format in the module docstring). VGG and ResNets take a ``(3, 224, 224)``
        image; the Inception modules a ``(192, 28, 28)`` activation.

    Notes
    -----
    §11.2: VGG-16 is 13 3×3 convolutions (stride 1, padding 1, with bias) in five stages
    separated by 2×2 max pooling, then three fully connected layers (25088 → 4096 → 4096 →
    classes); the adaptive average pooling of torchvision is the identity at 224×224 and is
    left out. §11.5: the ResNets have a 7×7/2 stem convolution + BN + ReLU + 3×3/2 max
    pooling, four stages of residual blocks (64, 128, 256, 512 channels; ×4 at the output of
    a bottleneck), convolutions without bias followed by batch norm, projection shortcuts
    (1×1 conv with stride + BN) where the shape changes, global average pooling and one
    linear layer. §11.3: GoogLeNet's convolutions have a bias and no batch norm.

    Examples
    --------
    >>> spec = architecture_spec("resnet18")
    >>> spec[0]
    {'type': 'conv', 'in': 3, 'out': 64, 'kernel': 7, 'stride': 2, 'padding': 3, 'bias': False}
    >>> count_parameters(spec), count_parameters(architecture_spec("vgg16"))
    (11689512, 138357544)
    """
    if not isinstance(name, str):
        raise TypeError(f"name must be a string, got {type(name).__name__}")
    key = name.lower().replace("-", "")
    if key not in ARCHITECTURES:
        raise ValueError(f"name must be one of {', '.join(map(repr, ARCHITECTURES))}, got {name!r}")
    classes = check_int(num_classes, "num_classes", minimum=1)
    if key == "vgg16":
        return _vgg(_VGG16, classes)
    if key == "vgg19":
        return _vgg(_VGG19, classes)
    if key == "resnet18":
        return _resnet((2, 2, 2, 2), False, classes)
    if key == "resnet34":
        return _resnet((3, 4, 6, 3), False, classes)
    if key == "resnet50":
        return _resnet((3, 4, 6, 3), True, classes)
    if key == "resnet50_v1":
        return _resnet((3, 4, 6, 3), True, classes, stride_in_3x3=False)
    if key == "resnet50_c":
        return _resnet((3, 4, 6, 3), True, classes, stem="c")
    if key == "resnet50_d":
        return _resnet((3, 4, 6, 3), True, classes, stem="c", avg_down=True)
    return _inception(192, 64, 96, 128, 16, 32, 32, reduce=(key == "inception_3a"))


# --------------------------------------------------------------------------------------------
# accounting
# --------------------------------------------------------------------------------------------
def _int(value: object, what: str, minimum: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Integral, np.integer)):
        raise TypeError(f"{what} must be an integer, got {type(value).__name__} {value!r}")
    if int(value) < minimum:
        raise ValueError(f"{what} must be >= {minimum}, got {value}")
    return int(value)


def _pair(value: object, what: str, minimum: int) -> tuple[int, int]:
    if isinstance(value, (tuple, list)):
        if len(value) != 2:
            raise ValueError(f"{what} must be an int or a pair (rows, cols), got {value!r}")
        return _int(value[0], what, minimum), _int(value[1], what, minimum)
    v = _int(value, what, minimum)
    return v, v


def _layers(spec: object, where: str) -> Spec:
    if not isinstance(spec, (list, tuple)):
        raise TypeError(f"{where} must be a list of layer dicts, got {type(spec).__name__}")
    for i, layer in enumerate(spec):
        if not isinstance(layer, dict) or "type" not in layer:
            raise ValueError(f"{where}[{i}] must be a dict with a 'type', got {layer!r}"[:200])
        if layer["type"] not in _TYPES:
            raise ValueError(f"{where}[{i}] has unknown type {layer['type']!r}; known: {', '.join(_TYPES)}")
    return list(spec)


def _key(layer: Layer, key: str, where: str) -> Any:
    if key not in layer:
        raise ValueError(f"{where} ({layer['type']}) lacks {key!r}")
    return layer[key]


def _parameters(spec: object, where: str = "spec") -> int:
    total = 0
    for i, layer in enumerate(_layers(spec, where)):
        at, kind = f"{where}[{i}]", layer["type"]
        if kind == "conv":
            kh, kw = _pair(_key(layer, "kernel", at), f"{at} kernel", 1)
            cin, cout = _int(_key(layer, "in", at), f"{at} in", 1), _int(_key(layer, "out", at), f"{at} out", 1)
            total += cout * cin * kh * kw + (cout if layer.get("bias", True) else 0)
        elif kind == "linear":
            cin, cout = _int(_key(layer, "in", at), f"{at} in", 1), _int(_key(layer, "out", at), f"{at} out", 1)
            total += cin * cout + (cout if layer.get("bias", True) else 0)
        elif kind == "bn":
            total += 2 * _int(_key(layer, "channels", at), f"{at} channels", 1)
        elif kind == "residual":
            total += _parameters(_key(layer, "body", at), f"{at}['body']")
            total += _parameters(layer.get("shortcut", []), f"{at}['shortcut']")
        elif kind == "concat":
            branches = _key(layer, "branches", at)
            if not isinstance(branches, (list, tuple)) or not branches:
                raise ValueError(f"{at} branches must be a non-empty list of specs")
            total += sum(_parameters(b, f"{at}['branches'][{j}]") for j, b in enumerate(branches))
    return total


def _walk(spec: object, shape: tuple[int, ...], where: str = "spec", rows: list[tuple[Any, ...]] | None = None,
          depth: int = 0) -> tuple[tuple[int, ...], int]:
    """Output shape and 2·MACs of ``spec`` applied to one input of ``shape``; optionally the
    per-layer rows ``(depth, where, type, output shape, parameters, flops)``."""
    flops = 0
    for i, layer in enumerate(_layers(spec, where)):
        at, kind = f"{where}[{i}]", layer["type"]
        layer_flops = 0
        if kind in ("conv", "maxpool", "avgpool", "bn"):
            if len(shape) != 3:
                raise ValueError(f"{at} ({kind}) needs a (C, H, W) input, got shape {shape}")
        if kind == "conv":
            c, h, w = shape
            cin = _int(_key(layer, "in", at), f"{at} in", 1)
            if cin != c:
                raise ValueError(f"{at} (conv) expects {cin} input channels, its input has {c}")
            cout = _int(_key(layer, "out", at), f"{at} out", 1)
            kh, kw = _pair(_key(layer, "kernel", at), f"{at} kernel", 1)
            sh, sw = _pair(layer.get("stride", 1), f"{at} stride", 1)
            ph, pw = _pair(layer.get("padding", 0), f"{at} padding", 0)
            ho, wo = _out(h, kh, ph, sh, at), _out(w, kw, pw, sw, at)
            shape = (cout, ho, wo)
            layer_flops = 2 * cout * ho * wo * cin * kh * kw
        elif kind in ("maxpool", "avgpool"):
            c, h, w = shape
            kh, kw = _pair(_key(layer, "kernel", at), f"{at} kernel", 1)
            sh, sw = _pair(layer.get("stride", layer["kernel"]), f"{at} stride", 1)
            ph, pw = _pair(layer.get("padding", 0), f"{at} padding", 0)
            shape = (c, _out(h, kh, ph, sh, at), _out(w, kw, pw, sw, at))
        elif kind == "bn":
            channels = _int(_key(layer, "channels", at), f"{at} channels", 1)
            if channels != shape[0]:
                raise ValueError(f"{at} (bn) has {channels} channels, its input has {shape[0]}")
        elif kind == "gap":
            if len(shape) != 3:
                raise ValueError(f"{at} (gap) needs a (C, H, W) input, got shape {shape}")
            shape = (shape[0],)
        elif kind == "flatten":
            shape = (math.prod(shape),)
        elif kind == "linear":
            cin = _int(_key(layer, "in", at), f"{at} in", 1)
            cout = _int(_key(layer, "out", at), f"{at} out", 1)
            if len(shape) != 1 or shape[0] != cin:
                raise ValueError(f"{at} (linear) expects a vector of {cin} values, its input has shape {shape}"
                                 + (" (flatten or gap first)" if len(shape) != 1 else ""))
            shape = (cout,)
            layer_flops = 2 * cin * cout
        elif kind == "residual":
            body_shape, body_flops = _walk(_key(layer, "body", at), shape, f"{at}['body']", rows, depth + 1)
            short_shape, short_flops = _walk(layer.get("shortcut", []), shape, f"{at}['shortcut']", rows, depth + 1)
            if body_shape != short_shape:
                raise ValueError(f"{at} (residual): the body gives {body_shape} but the shortcut {short_shape}")
            shape, layer_flops = body_shape, body_flops + short_flops
        elif kind == "concat":
            outs = []
            for j, branch in enumerate(_key(layer, "branches", at)):
                s, f = _walk(branch, shape, f"{at}['branches'][{j}]", rows, depth + 1)
                outs.append(s)
                layer_flops += f
            if not outs or any(len(s) != 3 or s[1:] != outs[0][1:] for s in outs):
                raise ValueError(f"{at} (concat): branch outputs {outs} differ in size")
            shape = (sum(s[0] for s in outs),) + outs[0][1:]
        flops += layer_flops
        if rows is not None:
            rows.append((depth, at, kind, shape, _parameters([layer], at), layer_flops))
    return shape, flops


def _out(size: int, kernel: int, padding: int, stride: int, at: str) -> int:
    span = size + 2 * padding - kernel
    if span < 0:
        raise ValueError(f"{at}: kernel {kernel} is larger than its padded input ({size} + 2·{padding})")
    return span // stride + 1


def _input_shape(input_shape: object) -> tuple[int, ...]:
    if not isinstance(input_shape, (tuple, list)) or len(input_shape) not in (1, 3):
        raise ValueError(f"input_shape must be (C, H, W) (or (D,) for a vector), got {input_shape!r}")
    return tuple(_int(v, "input_shape", 1) for v in input_shape)


@algorithm("nn.count_parameters", section="11.2–11.5", check="cvkit.nn.checks:count_parameters")
def count_parameters(spec: Spec) -> int:
    """Number of learnable parameters of a spec.

    Parameters
    ----------
    spec : list of dict
        Layers as made by :func:`architecture_spec` (format in the module docstring).

    Returns
    -------
    int
        Convolutions ``out·in·kh·kw`` (+ ``out`` biases), linear layers ``in·out`` (+ ``out``),
        batch norms ``2·channels`` (γ and β), residual and concat layers the sum of their parts;
        ReLU, pooling, GAP and flatten have none. VGG-16: 138,357,544; ResNet-18: 11,689,512;
        ResNet-50: 25,557,032 (the counts of torchvision's models).

    Notes
    -----
    §11.2.3: most of VGG-16's parameters sit in its first fully connected layer
    (25088·4096 + 4096 ≈ 103 M); §11.3.5: global average pooling is what frees GoogLeNet
    and ResNet of that layer.

    Examples
    --------
    >>> count_parameters([{"type": "conv", "in": 3, "out": 64, "kernel": 3, "padding": 1},
    ...                   {"type": "bn", "channels": 64}, {"type": "relu"}])
    1920
    >>> count_parameters(architecture_spec("resnet50"))
    25557032
    """
    return int(_parameters(spec))


@algorithm("nn.count_flops", section="11.2–11.3", check="cvkit.nn.checks:count_flops")
def count_flops(spec: Spec, input_shape: tuple[int, ...]) -> int:
    """Floating-point operations of one forward pass of one image: 2 × multiply-adds.

    Parameters
    ----------
    spec : list of dict
        Layers as made by :func:`architecture_spec`.
    input_shape : (C, H, W) tuple of int
        Shape of one input image (no batch axis).

    Returns
    -------
    int
        Σ over convolutions of ``2·out·Ho·Wo·in·kh·kw`` (each output value is a dot product
        of ``in·kh·kw`` terms) and over linear layers of ``2·in·out``; output sizes from
        :func:`conv_output_size`. Raises ``ValueError`` where a layer does not fit its input
        (channel counts, residual or concat shapes).

    Notes
    -----
    §11.2.3 quotes ≈ 31 GFLOPs per 224×224 image for VGG-16 (this gives 30.94e9);
    ResNet-18 gives 3.63e9, ResNet-50 8.18e9 (torchvision lists 1.81 and 4.09 "GFLOPs", which
    are multiply-adds). §11.3.4: a 3×3 convolution 192 → 128 on 28×28 costs 347 M FLOPs; with
    a 1×1 reduction to 96 channels first, 202 M.

    Examples
    --------
    >>> conv = {"type": "conv", "in": 192, "out": 128, "kernel": 3, "padding": 1}
    >>> count_flops([conv], (192, 28, 28))
    346816512
    >>> reduce = {"type": "conv", "in": 192, "out": 96, "kernel": 1}
    >>> count_flops([reduce, {"type": "relu"}, dict(conv, **{"in": 96})], (192, 28, 28))
    202309632
    """
    _, flops = _walk(spec, _input_shape(input_shape))
    return int(flops)


def layer_table(spec: Spec, input_shape: tuple[int, ...]) -> list[tuple[Any, ...]]:
    """Rows ``(depth, where, type, output shape, parameters, flops)`` of every layer, for tables
    in the notebooks: the layers nested in a residual or concat layer (``depth`` > 0) come just
    before the row of that layer, whose parameters and FLOPs include theirs."""
    rows: list[tuple[Any, ...]] = []
    _walk(copy.deepcopy(spec), _input_shape(input_shape), "spec", rows)
    return rows
