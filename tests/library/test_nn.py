"""The layers and accounting of ``cvkit.nn`` (Chapters 10–11) against oracles.

* every backward pass equals the central-difference gradient of ``sum(out · dout)`` to 1e-6
  relative error (max |analytic − numeric| / max(|analytic| + |numeric|)), on random inputs,
  with stride and padding variants;
* ``conv2d_forward`` equals, for each filter, the sum over input channels of
  ``scipy.signal.correlate(x_c, w_fc, mode="valid")`` on the zero-padded input (subsampled by
  the stride), plus the bias;
* max pooling, batch norm and dropout against brute-force definitions;
* parameter counts: VGG-16 138,357,544, ResNet-18 11,689,512, ResNet-50 25,557,032 (and
  VGG-19 143,667,240, ResNet-34 21,797,672: torchvision's numbers); FLOPs = 2 × multiply-adds:
  VGG-16 ≈ 30.9e9, ResNet-18 ≈ 3.6e9, ResNet-50 4.09 GMACs (v1.5) / 3.86 (v1), the notes'
  Inception 3×3-branch example 350 M → 202 M;
* bad input raises ValueError/TypeError naming the argument (hypothesis); inputs are never
  modified.
"""
from __future__ import annotations

import copy

import numpy as np
import pytest
import scipy.signal
from hypothesis import given, settings
from hypothesis import strategies as st

import cvkit
from cvkit import nn, registry


def _rng(seed=0):
    return np.random.default_rng(seed)


def numeric_gradient(f, x, eps=1e-5):
    """Central differences of the scalar ``f()`` with respect to the array ``x`` (changed in place
    and restored)."""
    grad = np.zeros_like(x)
    for i in np.ndindex(*x.shape):
        old = x[i]
        x[i] = old + eps
        plus = f()
        x[i] = old - eps
        minus = f()
        x[i] = old
        grad[i] = (plus - minus) / (2 * eps)
    return grad


def rel_error(a, b):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = np.max(np.abs(a) + np.abs(b))
    return 0.0 if scale == 0 else float(np.max(np.abs(a - b)) / scale)


def assert_gradient(analytic, f, x, tol=1e-6):
    numeric = numeric_gradient(f, x)
    assert analytic.shape == x.shape
    assert rel_error(analytic, numeric) < tol, rel_error(analytic, numeric)


# --------------------------------------------------------------------------------------------
# activations
# --------------------------------------------------------------------------------------------
def test_activations_values():
    x = np.array([-2.0, -0.5, 0.0, 0.5, 3.0])
    assert np.array_equal(nn.relu_forward(x)[0], [0, 0, 0, 0.5, 3.0])
    assert np.allclose(nn.sigmoid_forward(x)[0], 1 / (1 + np.exp(-x)), rtol=1e-15)
    assert np.allclose(nn.leaky_relu_forward(x, 0.1)[0], [-0.2, -0.05, 0, 0.5, 3.0])
    # the notes' convention at 0: slope 1
    _, cache = nn.relu_forward(x)
    assert np.array_equal(nn.relu_backward(np.ones(5), cache), [0, 0, 1, 1, 1])
    _, cache = nn.leaky_relu_forward(x, 0.1)
    assert np.allclose(nn.leaky_relu_backward(np.ones(5), cache), [0.1, 0.1, 1, 1, 1])


def test_sigmoid_is_stable_for_extreme_inputs():
    with np.errstate(over="raise", invalid="raise", divide="raise"):
        out, _ = nn.sigmoid_forward(np.array([-1e4, -1000.0, 1000.0, 1e4]))
    assert np.array_equal(out, [0.0, 0.0, 1.0, 1.0])


@pytest.mark.parametrize("layer", ["relu", "sigmoid", "leaky_relu"])
def test_activation_gradients(layer):
    rng = _rng(1)
    x = rng.normal(0, 2, (3, 4, 5))
    x[np.abs(x) < 1e-3] = 0.5  # away from the kink
    forward = getattr(nn, f"{layer}_forward")
    backward = getattr(nn, f"{layer}_backward")
    dout = rng.normal(size=x.shape)
    _, cache = forward(x)
    assert_gradient(backward(dout, cache), lambda: float(np.sum(forward(x)[0] * dout)), x)


def test_linear_gradients():
    rng = _rng(2)
    x, W, b = rng.normal(size=(4, 5)), rng.normal(size=(5, 3)), rng.normal(size=3)
    out, cache = nn.linear_forward(x, W, b)
    assert np.allclose(out, x @ W + b)
    dout = rng.normal(size=out.shape)
    dx, dW, db = nn.linear_backward(dout, cache)

    def loss():
        return float(np.sum(nn.linear_forward(x, W, b)[0] * dout))

    assert_gradient(dx, loss, x)
    assert_gradient(dW, loss, W)
    assert_gradient(db, loss, b)


# --------------------------------------------------------------------------------------------
# convolution
# --------------------------------------------------------------------------------------------
CONV_VARIANTS = [  # (N, C, H, W), (F, kh, kw), stride, padding
    ((2, 3, 7, 8), (4, 3, 3), 1, 0),
    ((2, 2, 7, 8), (3, 3, 3), 1, 1),
    ((1, 3, 8, 9), (2, 3, 3), 2, 1),
    ((2, 2, 9, 7), (3, 2, 3), 2, 0),
    ((1, 2, 10, 11), (2, 5, 5), 3, 2),
    ((2, 4, 5, 6), (3, 1, 1), 2, 0),
    ((1, 1, 6, 6), (2, 4, 2), 1, 3),
]


def _conv_oracle(x, w, b, stride, padding):
    xp = np.pad(x, ((0, 0), (0, 0), (padding, padding), (padding, padding)))
    n, f = x.shape[0], w.shape[0]
    maps = []
    for i in range(n):
        per_filter = []
        for k in range(f):
            full = sum(scipy.signal.correlate(xp[i, c], w[k, c], mode="valid") for c in range(x.shape[1]))
            per_filter.append(full[::stride, ::stride] + b[k])
        maps.append(per_filter)
    return np.array(maps)


@pytest.mark.parametrize(("xs", "ws", "stride", "padding"), CONV_VARIANTS)
def test_conv2d_forward_is_a_per_channel_scipy_correlation_sum(xs, ws, stride, padding):
    rng = _rng(3)
    x = rng.normal(size=xs)
    w = rng.normal(size=(ws[0], xs[1], ws[1], ws[2]))
    b = rng.normal(size=ws[0])
    out, cache = nn.conv2d_forward(x, w, b, stride=stride, padding=padding)
    expected = _conv_oracle(x, w, b, stride, padding)
    assert out.shape == expected.shape
    assert out.shape[2] == nn.conv_output_size(xs[2], ws[1], padding, stride)
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-12)
    assert set(cache) == {"x", "w", "b", "stride", "padding"}


@pytest.mark.parametrize(("xs", "ws", "stride", "padding"), CONV_VARIANTS)
def test_conv2d_backward_equals_the_numerical_gradient(xs, ws, stride, padding):
    rng = _rng(4)
    x = rng.normal(size=xs)
    w = rng.normal(size=(ws[0], xs[1], ws[1], ws[2]))
    b = rng.normal(size=ws[0])
    out, cache = nn.conv2d_forward(x, w, b, stride=stride, padding=padding)
    dout = rng.normal(size=out.shape)
    dx, dw, db = nn.conv2d_backward(dout, cache)

    def loss():
        return float(np.sum(nn.conv2d_forward(x, w, b, stride=stride, padding=padding)[0] * dout))

    assert_gradient(dx, loss, x)
    assert_gradient(dw, loss, w)
    assert_gradient(db, loss, b)


def test_conv2d_is_correlation_not_convolution():
    x = np.zeros((1, 1, 5, 5))
    x[0, 0, 2, 2] = 1.0
    w = np.arange(9.0).reshape(1, 1, 3, 3)
    out, _ = nn.conv2d_forward(x, w, np.zeros(1), padding=1)
    # correlation with an impulse gives the kernel rotated by 180°
    assert np.array_equal(out[0, 0, 1:4, 1:4], w[0, 0, ::-1, ::-1])


def test_conv2d_is_translation_equivariant():
    rng = _rng(5)
    x = np.zeros((1, 2, 12, 12))
    x[:, :, 2:7, 3:8] = rng.normal(size=(1, 2, 5, 5))
    w, b = rng.normal(size=(3, 2, 3, 3)), np.zeros(3)
    shifted = np.roll(x, (2, 3), axis=(2, 3))
    a = nn.conv2d_forward(shifted, w, b, padding=1)[0]
    c = np.roll(nn.conv2d_forward(x, w, b, padding=1)[0], (2, 3), axis=(2, 3))
    np.testing.assert_allclose(a, c, atol=1e-12)


@pytest.mark.parametrize(("size", "kernel", "padding", "stride", "expected"), [
    (7, 3, 0, 1, 5), (7, 3, 1, 1, 7), (8, 3, 1, 2, 4), (224, 7, 3, 2, 112), (112, 3, 1, 2, 56),
    (10, 4, 1, 3, 3), (5, 5, 0, 1, 1), (227, 11, 0, 4, 55),
])
def test_conv_output_size(size, kernel, padding, stride, expected):
    got = nn.conv_output_size(size, kernel, padding=padding, stride=stride)
    assert got == expected and isinstance(got, int)
    # brute force: count the windows that fit
    assert got == len(range(0, size + 2 * padding - kernel + 1, stride))


def test_receptive_field_brute_force():
    """The field of a 1-D stack measured by back-propagating an impulse through box filters."""
    rng = _rng(6)
    for _ in range(30):
        layers = [(int(rng.integers(1, 6)), int(rng.integers(1, 4))) for _ in range(rng.integers(1, 5))]
        width = 400
        signal = np.zeros(width)
        signal[width // 2] = 1.0
        # which inputs influence output unit 0 of the last layer: walk the index sets down
        positions = {0}
        for kernel, stride in reversed(layers):
            positions = {p * stride + k for p in positions for k in range(kernel)}
        assert nn.receptive_field(layers) == max(positions) - min(positions) + 1
    assert nn.receptive_field([(3, 1)] * 4) == 1 + 4 * 2          # the notes' 1 + L(K − 1)
    assert nn.receptive_field([]) == 1


# --------------------------------------------------------------------------------------------
# pooling
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("shape", "size", "stride"), [((2, 3, 6, 8), 2, 2), ((1, 2, 7, 5), 3, 2),
                                                       ((2, 1, 5, 6), 2, 1), ((1, 2, 9, 9), 3, 3)])
def test_maxpool_against_brute_force_and_numerical_gradient(shape, size, stride):
    rng = _rng(7)
    x = rng.permutation(np.prod(shape)).reshape(shape) * 0.01 + rng.normal(0, 1e-4, shape)  # distinct
    out, cache = nn.maxpool2d_forward(x, size, stride)
    for i in range(out.shape[2]):
        for j in range(out.shape[3]):
            window = x[:, :, i * stride:i * stride + size, j * stride:j * stride + size]
            assert np.array_equal(out[:, :, i, j], window.max(axis=(2, 3)))
    dout = rng.normal(size=out.shape)
    assert_gradient(nn.maxpool2d_backward(dout, cache),
                    lambda: float(np.sum(nn.maxpool2d_forward(x, size, stride)[0] * dout)), x)


def test_maxpool_backward_ties_and_overlaps():
    x = np.array([[[[1.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]]])
    _, cache = nn.maxpool2d_forward(x, 2, 1)
    dx = nn.maxpool2d_backward(np.ones((1, 1, 2, 2)), cache)
    # each 2x2 window sends its gradient to its first maximum in row-major order: (0,0) -> x[0,0],
    # (0,1) -> x[0,1], (1,0) -> x[1,0], and the all-zero window (1,1) -> its first element x[1,1]
    assert dx[0, 0].tolist() == [[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0]]
    expected = np.zeros((3, 3))
    for i in range(2):
        for j in range(2):
            window = x[0, 0, i:i + 2, j:j + 2]
            m, l = np.unravel_index(np.argmax(window), (2, 2))
            expected[i + m, j + l] += 1.0
    assert np.array_equal(dx[0, 0], expected)
    assert dx.sum() == 4.0


def test_global_average_pooling():
    rng = _rng(8)
    x = rng.normal(size=(2, 3, 4, 5))
    out, cache = nn.global_avg_pool_forward(x)
    assert np.allclose(out, x.reshape(2, 3, -1).mean(axis=2))
    dout = rng.normal(size=out.shape)
    assert_gradient(nn.global_avg_pool_backward(dout, cache),
                    lambda: float(np.sum(nn.global_avg_pool_forward(x)[0] * dout)), x)


# --------------------------------------------------------------------------------------------
# batch norm
# --------------------------------------------------------------------------------------------
def _bn_inputs(seed=9, shape=(3, 2, 3, 4)):
    rng = _rng(seed)
    x = rng.normal(2.0, 3.0, shape)
    c = shape[1]
    return (x, rng.uniform(0.5, 2, c), rng.normal(size=c), rng.normal(size=c), rng.uniform(0.5, 2, c))


def test_batchnorm_training_statistics():
    x, gamma, beta, rm, rv = _bn_inputs()
    out, cache = nn.batchnorm2d_forward(x, gamma, beta, rm, rv, True, momentum=0.2, eps=1e-5)
    n = x.shape[0] * x.shape[2] * x.shape[3]
    for c in range(x.shape[1]):
        values = x[:, c].ravel()
        np.testing.assert_allclose(out[:, c], gamma[c] * (x[:, c] - values.mean()) / np.sqrt(values.var() + 1e-5)
                                   + beta[c], rtol=1e-12)
        assert np.isclose(cache["running_mean"][c], 0.8 * rm[c] + 0.2 * values.mean())
        # unbiased variance in the running statistics, biased to normalise
        assert np.isclose(cache["running_var"][c], 0.8 * rv[c] + 0.2 * values.var(ddof=1))
        assert np.isclose(values.var(ddof=1), values.var() * n / (n - 1))
    # normalised output: zero mean, (nearly) unit variance per channel before γ, β
    x_hat = (out - beta[None, :, None, None]) / gamma[None, :, None, None]
    assert np.allclose(x_hat.mean(axis=(0, 2, 3)), 0, atol=1e-12)
    assert np.allclose(x_hat.var(axis=(0, 2, 3)), 1, atol=1e-5)


def test_batchnorm_evaluation_uses_running_statistics():
    x, gamma, beta, rm, rv = _bn_inputs()
    out, cache = nn.batchnorm2d_forward(x, gamma, beta, rm, rv, False)
    expected = gamma[None, :, None, None] * (x - rm[None, :, None, None]) / np.sqrt(rv[None, :, None, None] + 1e-5) \
        + beta[None, :, None, None]
    np.testing.assert_allclose(out, expected, rtol=1e-12)
    assert np.array_equal(cache["running_mean"], rm) and np.array_equal(cache["running_var"], rv)


@pytest.mark.parametrize("training", [True, False])
@pytest.mark.parametrize("shape", [(3, 2, 3, 4), (1, 3, 2, 2), (5, 2, 1, 1)])
def test_batchnorm_gradients(training, shape):
    x, gamma, beta, rm, rv = _bn_inputs(10, shape)
    out, cache = nn.batchnorm2d_forward(x, gamma, beta, rm, rv, training)
    dout = _rng(11).normal(size=out.shape)
    dx, dgamma, dbeta = nn.batchnorm2d_backward(dout, cache)

    def loss():
        return float(np.sum(nn.batchnorm2d_forward(x, gamma, beta, rm, rv, training)[0] * dout))

    assert_gradient(dx, loss, x)
    assert_gradient(dgamma, loss, gamma)
    assert_gradient(dbeta, loss, beta)


def test_batchnorm_needs_two_values_per_channel_in_training():
    with pytest.raises(ValueError, match="x"):
        nn.batchnorm2d_forward(np.ones((1, 2, 1, 1)), np.ones(2), np.zeros(2), np.zeros(2), np.ones(2), True)


# --------------------------------------------------------------------------------------------
# dropout
# --------------------------------------------------------------------------------------------
def test_dropout_statistics_and_gradient():
    x = _rng(12).normal(size=(200, 100)) + 5.0
    out, cache = nn.dropout_forward(x, 0.7, True, rng=3)
    mask = cache["mask"]
    assert mask.dtype == bool and mask.shape == x.shape
    assert abs(mask.mean() - 0.7) < 4.5 * np.sqrt(0.7 * 0.3 / x.size)
    np.testing.assert_allclose(out, np.where(mask, x / 0.7, 0.0))
    assert abs(out.mean() / x.mean() - 1.0) < 0.02     # expectation preserved (inverted dropout)
    again, _ = nn.dropout_forward(x, 0.7, True, rng=3)
    assert np.array_equal(out, again)
    dout = _rng(13).normal(size=x.shape)
    np.testing.assert_allclose(nn.dropout_backward(dout, cache), np.where(mask, dout / 0.7, 0.0))
    same, eval_cache = nn.dropout_forward(x, 0.7, False, rng=3)
    assert np.array_equal(same, x) and eval_cache["mask"].all()
    assert np.array_equal(nn.dropout_backward(dout, eval_cache), dout)
    # the cache holds the forward's arguments under their own names (CATALOG), plus the mask
    assert set(cache) == {"x", "p_keep", "training", "rng", "mask"} and cache["rng"] == 3
    generator = np.random.default_rng(5)
    assert nn.dropout_forward(x, 0.5, True, generator)[1]["rng"] is generator


# --------------------------------------------------------------------------------------------
# residual block
# --------------------------------------------------------------------------------------------
def _res_params(rng, c, f, projection):
    p = {}
    suffixes = [("1", c, 3), ("2", f, 3)] + ([("_proj", c, 1)] if projection else [])
    for s, cin, k in suffixes:
        p["w_proj" if s == "_proj" else "w" + s] = rng.normal(0, 0.5, (f, cin, k, k))
        p["gamma" + s] = rng.uniform(0.5, 1.5, f)
        p["beta" + s] = rng.normal(0, 0.5, f)
        p["running_mean" + s] = rng.normal(0, 0.5, f)
        p["running_var" + s] = rng.uniform(0.5, 2, f)
    return p


@pytest.mark.parametrize("projection", [False, True])
@pytest.mark.parametrize("training", [True, False])
def test_residual_block_gradients(projection, training):
    rng = _rng(14)
    c, f = 2, (3 if projection else 2)
    x = rng.normal(size=(2, c, 5, 4))
    params = _res_params(rng, c, f, projection)
    out, cache = nn.residual_block_forward(x, params, training)
    expected_hw = (3, 2) if projection else (5, 4)
    assert out.shape == (2, f) + expected_hw
    dout = rng.normal(size=out.shape)
    dx, grads = nn.residual_block_backward(dout, cache)
    learnable = ["w1", "gamma1", "beta1", "w2", "gamma2", "beta2"] + (["w_proj", "gamma_proj", "beta_proj"]
                                                                      if projection else [])
    assert sorted(grads) == sorted(learnable)

    def loss():
        return float(np.sum(nn.residual_block_forward(x, params, training)[0] * dout))

    assert_gradient(dx, loss, x)
    for key in learnable:
        assert_gradient(grads[key], loss, params[key])


def test_residual_block_with_zero_weights_is_relu_of_identity():
    """F(x) ≈ 0 (weights 0, β = 0): the block is relu(x), the identity on a ReLU's output (§11.5.2)."""
    rng = _rng(15)
    x = rng.normal(size=(2, 3, 4, 4))
    params = _res_params(rng, 3, 3, False)
    params.update(w1=np.zeros((3, 3, 3, 3)), w2=np.zeros((3, 3, 3, 3)), beta1=np.zeros(3), beta2=np.zeros(3))
    out, cache = nn.residual_block_forward(x, params, True)
    np.testing.assert_allclose(out, np.maximum(x, 0))
    assert set(cache) >= {"x", "params", "training", "running_mean1", "running_var2"}


def test_residual_block_runs_on_the_students_layers():
    calls = []

    def relu_forward(x):
        calls.append("relu")
        return nn.relu_forward(x)

    registry.register_provider("test-nn-layers", {"nn.relu_forward": relu_forward})
    rng = _rng(16)
    params = _res_params(rng, 2, 2, False)
    with cvkit.use("test-nn-layers"):
        nn.residual_block_forward(rng.normal(size=(2, 2, 3, 3)), params)
    assert calls == ["relu", "relu"]


# --------------------------------------------------------------------------------------------
# architectures
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "params"), [
    ("vgg16", 138_357_544), ("resnet18", 11_689_512), ("resnet50", 25_557_032),
    ("vgg19", 143_667_240), ("resnet34", 21_797_672), ("resnet50_v1", 25_557_032),
])
def test_parameter_counts_match_torchvision(name, params):
    assert nn.count_parameters(nn.architecture_spec(name)) == params


def test_flops():
    spec = nn.architecture_spec
    vgg = nn.count_flops(spec("vgg16"), (3, 224, 224))
    assert abs(vgg - 30.9e9) / 30.9e9 < 0.005                     # the notes' "31 GFLOPs per image"
    r18 = nn.count_flops(spec("resnet18"), (3, 224, 224))
    assert abs(r18 - 3.6e9) / 3.6e9 < 0.02
    assert abs(nn.count_flops(spec("resnet50"), (3, 224, 224)) / 2 - 4.09e9) < 0.01e9      # torchvision: 4.09 GMACs
    assert abs(nn.count_flops(spec("resnet50_v1"), (3, 224, 224)) / 2 - 3.86e9) < 0.01e9   # the original v1
    # the notes' 3×3 branch of Inception 3a: ~350 M FLOPs, ~202 M with a 1×1 reduction to 96
    naive = [{"type": "conv", "in": 192, "out": 128, "kernel": 3, "padding": 1}]
    reduced = [{"type": "conv", "in": 192, "out": 96, "kernel": 1}, {"type": "relu"},
               {"type": "conv", "in": 96, "out": 128, "kernel": 3, "padding": 1}]
    assert round(nn.count_flops(naive, (192, 28, 28)) / 1e6) == 347
    assert round(nn.count_flops(reduced, (192, 28, 28)) / 1e6) == 202
    # GoogLeNet's table: Inception 3a has 128 M multiply-adds
    assert round(nn.count_flops(spec("inception_3a"), (192, 28, 28)) / 2e6) == 128
    # a linear layer and a 1x1 convolution on a 1x1 map cost the same
    assert nn.count_flops([{"type": "linear", "in": 10, "out": 4}], (10,)) == \
        nn.count_flops([{"type": "conv", "in": 10, "out": 4, "kernel": 1}], (10, 1, 1)) == 80


def test_specs_have_the_documented_shapes():
    table = nn.layer_table(nn.architecture_spec("vgg16"), (3, 224, 224))
    top = [row for row in table if row[0] == 0]
    assert top[-1][3] == (1000,)
    assert [r[3] for r in top if r[2] == "maxpool"] == [(64, 112, 112), (128, 56, 56), (256, 28, 28),
                                                        (512, 14, 14), (512, 7, 7)]
    inception = nn.architecture_spec("inception_3a")
    assert nn.layer_table(inception, (192, 28, 28))[-1][3] == (256, 28, 28)
    naive = nn.architecture_spec("inception_3a_naive")
    assert nn.layer_table(naive, (192, 28, 28))[-1][3] == (64 + 128 + 32 + 192, 28, 28)
    # the stride of the v1.5 bottleneck sits in the 3x3 convolution
    block = next(layer for layer in nn.architecture_spec("resnet50") if layer["type"] == "residual"
                 and layer["body"][3]["stride"] == 2)
    assert block["body"][0]["stride"] == 1 and block["shortcut"][0]["stride"] == 2
    assert nn.architecture_spec("resnet18", num_classes=10)[-1]["out"] == 10


def test_spec_errors_name_the_layer():
    with pytest.raises(ValueError, match=r"spec\[1\]"):
        nn.count_flops([{"type": "conv", "in": 3, "out": 4, "kernel": 3},
                        {"type": "conv", "in": 5, "out": 4, "kernel": 3}], (3, 8, 8))
    with pytest.raises(ValueError, match="residual"):
        nn.count_flops([{"type": "residual", "body": [{"type": "conv", "in": 3, "out": 4, "kernel": 1}],
                         "shortcut": []}], (3, 8, 8))
    with pytest.raises(ValueError, match="type"):
        nn.count_parameters([{"type": "dense"}])
    with pytest.raises(ValueError, match="name"):
        nn.architecture_spec("alexnet")


# --------------------------------------------------------------------------------------------
# the small CNN
# --------------------------------------------------------------------------------------------
def test_small_cnn_gradients_are_right():
    from cvkit.learn import cross_entropy

    rng = _rng(17)
    model = nn.SmallCNN(3, channels=(2, 3), rng=0)
    X = rng.normal(size=(4, 1, 6, 6))
    y = np.array([0, 1, 2, 1])
    caches = {}
    _, dscores = cross_entropy(model.scores(X, True, caches), y)
    grads = model.gradients(dscores, caches)
    frozen = copy.deepcopy(model.params)

    def loss():
        saved = {k: model.params[k].copy() for k in ("running_mean1", "running_var1", "running_mean2", "running_var2")}
        value = cross_entropy(model.scores(X, True, {}), y)[0]
        model.params.update(saved)  # training mode updates the running statistics: undo
        return value

    for key in ("w1", "gamma1", "w2", "beta2", "W", "b"):
        assert_gradient(grads[key], loss, model.params[key], tol=1e-5)
    for key in ("w1", "W"):
        assert np.array_equal(frozen[key], model.params[key])


def test_small_cnn_learns_digits_quickly():
    X = _rng(18).normal(size=(60, 8, 8))
    y = (X[:, :4].mean(axis=(1, 2)) > X[:, 4:].mean(axis=(1, 2))).astype(int)   # top half brighter?
    model = nn.SmallCNN(2, channels=(4, 8), rng=1)
    history = model.fit(X, y, epochs=15, lr=0.05, batch_size=10, rng=2)
    assert history["loss"][-1] < history["loss"][0]
    assert model.accuracy(X, y) >= 0.9


# --------------------------------------------------------------------------------------------
# inputs are never modified; bad input names the argument
# --------------------------------------------------------------------------------------------
def test_inputs_are_not_modified():
    rng = _rng(19)
    x = rng.normal(size=(2, 2, 5, 5))
    w, b = rng.normal(size=(3, 2, 3, 3)), rng.normal(size=3)
    params = _res_params(rng, 2, 2, False)
    args = [x, w, b, params]
    before = copy.deepcopy(args)
    out, cache = nn.conv2d_forward(x, w, b, 2, 1)
    nn.conv2d_backward(np.ones_like(out), cache)
    bn_args = (x, np.ones(2), np.zeros(2), np.zeros(2), np.ones(2))
    bn_before = copy.deepcopy(bn_args)
    out, cache = nn.batchnorm2d_forward(*bn_args, True)
    nn.batchnorm2d_backward(np.ones_like(out), cache)
    out, cache = nn.residual_block_forward(x, params)
    nn.residual_block_backward(np.ones_like(out), cache)
    out, cache = nn.maxpool2d_forward(x, 3, 1)
    nn.maxpool2d_backward(np.ones_like(out), cache)
    for a, b_ in zip(args[:3] + list(bn_args), before[:3] + list(bn_before)):
        assert np.array_equal(a, b_)
    for k in params:
        assert np.array_equal(params[k], before[3][k])


@settings(max_examples=25, deadline=None)
@given(st.integers(-2, 6), st.sampled_from(["ndim", "nan", "str", "channels"]))
def test_conv2d_bad_input_names_the_argument(value, kind):
    x = np.zeros((1, 2, 5, 5))
    w, b = np.zeros((3, 2, 3, 3)), np.zeros(3)
    if kind == "ndim":
        with pytest.raises(ValueError, match="x"):
            nn.conv2d_forward(np.zeros((2, 5, 5)), w, b)
    elif kind == "nan":
        x[0, 0, 0, 0] = np.nan
        with pytest.raises(ValueError, match="x"):
            nn.conv2d_forward(x, w, b)
    elif kind == "str":
        with pytest.raises(TypeError, match="stride"):
            nn.conv2d_forward(x, w, b, stride="2")
    else:
        with pytest.raises(ValueError, match="w"):
            nn.conv2d_forward(x, np.zeros((3, 4, 3, 3)), b)
    x = np.zeros((1, 2, 5, 5))
    if value < 1:
        with pytest.raises(ValueError, match="stride"):
            nn.conv2d_forward(x, w, b, stride=value)
    if value < 0:
        with pytest.raises(ValueError, match="padding"):
            nn.conv2d_forward(x, w, b, padding=value)
    if value > 2:
        with pytest.raises(ValueError, match="kernel"):
            nn.conv2d_forward(x[:, :, :2, :2], w, b, padding=0)


@settings(max_examples=25, deadline=None)
@given(st.integers(-3, 3), st.integers(-3, 3))
def test_output_size_and_pooling_bad_input(size, kernel):
    if size < 1:
        with pytest.raises(ValueError, match="size"):
            nn.conv_output_size(size, 3)
    if kernel < 1:
        with pytest.raises(ValueError, match="kernel"):
            nn.conv_output_size(5, kernel)
    if kernel < 1:
        with pytest.raises(ValueError, match="size"):
            nn.maxpool2d_forward(np.zeros((1, 1, 4, 4)), size=kernel)
    with pytest.raises(ValueError, match="kernel"):
        nn.conv_output_size(2, 5)
    with pytest.raises(ValueError, match=r"layers\[0\]"):
        nn.receptive_field([(3,)])


@settings(max_examples=20, deadline=None)
@given(st.sampled_from(["gamma", "running_var", "momentum", "eps", "training", "p_keep"]))
def test_batchnorm_and_dropout_bad_input(which):
    x = np.zeros((2, 2, 3, 3))
    args = {"gamma": np.ones(2), "beta": np.zeros(2), "running_mean": np.zeros(2), "running_var": np.ones(2),
            "training": True, "momentum": 0.1, "eps": 1e-5}
    bad = {"gamma": np.ones(3), "running_var": -np.ones(2), "momentum": 1.5, "eps": 0.0, "training": "yes"}
    if which == "p_keep":
        for p in (0.0, 1.5):
            with pytest.raises(ValueError, match="p_keep"):
                nn.dropout_forward(x, p, True)
        return
    args[which] = bad[which]
    with pytest.raises((ValueError, TypeError), match=which):
        nn.batchnorm2d_forward(x, **args)


def test_backward_rejects_a_wrong_cache_or_gradient():
    out, cache = nn.conv2d_forward(np.zeros((1, 1, 4, 4)), np.zeros((1, 1, 3, 3)), np.zeros(1))
    with pytest.raises(ValueError, match="dout"):
        nn.conv2d_backward(np.zeros((1, 1, 3, 3)), cache)
    with pytest.raises(ValueError, match="cache"):
        nn.conv2d_backward(out, {"x": cache["x"]})
    with pytest.raises(TypeError, match="cache"):
        nn.relu_backward(np.zeros(3), (np.zeros(3),))
    with pytest.raises(ValueError, match="params"):
        nn.residual_block_forward(np.zeros((1, 2, 3, 3)), {"w1": np.zeros((2, 2, 3, 3))})


@pytest.mark.parametrize(("entry", "value", "named"), [
    ("gamma2", np.ones(3), r"params\['gamma2'\] must have one entry per output channel \(2,\)"),
    ("beta_proj", np.ones((2, 1)), r"params\['beta_proj'\]"),
    ("running_var1", -np.ones(2), r"params\['running_var1'\] must be >= 0"),
    ("running_mean_proj", np.ones(4), r"params\['running_mean_proj'\]"),
])
def test_residual_block_names_the_params_entry_at_fault(entry, value, named):
    """A bad batch-norm entry is reported under the name the block's caller gave it, not under
    the name of the inner layer's argument (gamma, running_var)."""
    params = _res_params(_rng(40), 2, 2, projection=True)
    params[entry] = value
    with pytest.raises(ValueError, match=named):
        nn.residual_block_forward(_rng(41).normal(size=(2, 2, 4, 4)), params)


def test_residual_block_in_training_needs_two_values_per_channel_after_its_stride():
    """x of 1×2×2×2 through the stride-2 block leaves one value per channel: batch norm cannot
    train on it, and the message says so for the block's own x; evaluation runs."""
    params = _res_params(_rng(42), 2, 2, projection=True)
    x = _rng(43).normal(size=(1, 2, 2, 2))
    with pytest.raises(ValueError, match=r"x must give .* at least 2 values per channel .* N·H'·W' = 1"):
        nn.residual_block_forward(x, params, training=True)
    assert nn.residual_block_forward(x, params, training=False)[0].shape == (1, 2, 1, 1)
