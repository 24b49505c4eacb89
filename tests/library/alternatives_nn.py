"""Correct implementations of the ``cvkit.nn`` algorithms, written differently from the reference.

They play the part of good students: a check must accept every one of them. Most loop over
output positions, windows or channels (the way a first version looks); some use another
formulation (σ through tanh, the receptive field from the top down, batch-norm gradients by
the chain rule through μ and σ², a binomial dropout mask, specs written out by hand).
None calls cvkit or a library the guard forbids.
"""
from __future__ import annotations

import math

import numpy as np


def _f(a):
    return np.asarray(a, dtype=np.float64)


# --------------------------------------------------------------------------------------------
# activations
# --------------------------------------------------------------------------------------------
def relu_forward(x):
    x = _f(x)
    return x * (x > 0), {"x": x}


def relu_backward(dout, cache):
    x, d = _f(cache["x"]), _f(dout)
    dx = np.zeros(x.shape)
    for i in np.ndindex(*x.shape):
        dx[i] = d[i] if x[i] >= 0 else 0.0
    return dx


def sigmoid_forward(x):
    x = _f(x)
    out = 0.5 * (1.0 + np.tanh(0.5 * x))       # σ(x) = (1 + tanh(x/2)) / 2, never overflows
    return out, {"x": x, "out": out}


def sigmoid_backward(dout, cache):
    s = _f(cache["out"])
    d = _f(dout)
    return d * s - d * s * s


def leaky_relu_forward(x, alpha=0.01):
    x = _f(x)
    slope = np.ones(x.shape)
    slope[x < 0] = alpha
    return x * slope, {"x": x, "alpha": alpha}


def leaky_relu_backward(dout, cache):
    x = _f(cache["x"])
    slope = np.select([x >= 0], [1.0], default=cache["alpha"])
    return _f(dout) * slope


# --------------------------------------------------------------------------------------------
# linear layer
# --------------------------------------------------------------------------------------------
def linear_forward(x, W, b):
    x, W, b = _f(x), _f(W), _f(b)
    return np.einsum("nd,dc->nc", x, W) + b[None, :], {"x": x, "W": W, "b": b}


def linear_backward(dout, cache):
    x, W = _f(cache["x"]), _f(cache["W"])
    d = _f(dout)
    dx = np.zeros(x.shape)
    dW = np.zeros(W.shape)
    for n in range(x.shape[0]):
        dx[n] = W @ d[n]
        dW += np.outer(x[n], d[n])
    return dx, dW, d.sum(axis=0)


# --------------------------------------------------------------------------------------------
# sizes
# --------------------------------------------------------------------------------------------
def conv_output_size(size, kernel, padding=0, stride=1):
    count, start = 0, 0
    while start + kernel <= size + 2 * padding:   # count the windows that fit
        count += 1
        start += stride
    if count == 0:
        raise ValueError("kernel larger than the padded input")
    return count


def receptive_field(layers):
    r = 1
    for kernel, stride in reversed(list(layers)):   # from the top unit down to the input
        r = (r - 1) * stride + kernel
    return r


# --------------------------------------------------------------------------------------------
# convolution
# --------------------------------------------------------------------------------------------
def _padded(x, p):
    n, c, h, w = x.shape
    xp = np.zeros((n, c, h + 2 * p, w + 2 * p))
    xp[:, :, p:p + h, p:p + w] = x
    return xp


def conv2d_forward(x, w, b, stride=1, padding=0):
    x, w, b = _f(x), _f(w), _f(b)
    n, c, h, width = x.shape
    f, _, kh, kw = w.shape
    xp = _padded(x, padding)
    ho = (h + 2 * padding - kh) // stride + 1
    wo = (width + 2 * padding - kw) // stride + 1
    out = np.zeros((n, f, ho, wo))
    for i in range(ho):
        for j in range(wo):
            patch = xp[:, :, i * stride:i * stride + kh, j * stride:j * stride + kw]   # (N, C, kh, kw)
            for k in range(f):
                out[:, k, i, j] = np.sum(patch * w[k], axis=(1, 2, 3)) + b[k]
    return out, {"x": x, "w": w, "b": b, "stride": stride, "padding": padding}


def conv2d_backward(dout, cache):
    x, w = _f(cache["x"]), _f(cache["w"])
    s, p = cache["stride"], cache["padding"]
    d = _f(dout)
    n, c, h, width = x.shape
    f, _, kh, kw = w.shape
    xp = _padded(x, p)
    dxp = np.zeros(xp.shape)
    dw = np.zeros(w.shape)
    ho, wo = d.shape[2:]
    for i in range(ho):
        for j in range(wo):
            rows, cols = slice(i * s, i * s + kh), slice(j * s, j * s + kw)
            for k in range(f):
                g = d[:, k, i, j][:, None, None, None]
                dw[k] += np.sum(g * xp[:, :, rows, cols], axis=0)
                dxp[:, :, rows, cols] += g * w[k]
    return dxp[:, :, p:p + h, p:p + width], dw, d.sum(axis=(0, 2, 3))


# --------------------------------------------------------------------------------------------
# pooling
# --------------------------------------------------------------------------------------------
def maxpool2d_forward(x, size=2, stride=2):
    x = _f(x)
    n, c, h, w = x.shape
    ho, wo = (h - size) // stride + 1, (w - size) // stride + 1
    out = np.empty((n, c, ho, wo))
    for i in range(ho):
        for j in range(wo):
            out[:, :, i, j] = x[:, :, i * stride:i * stride + size, j * stride:j * stride + size].max(axis=(2, 3))
    return out, {"x": x, "size": size, "stride": stride}


def maxpool2d_backward(dout, cache):
    x, size, stride = _f(cache["x"]), cache["size"], cache["stride"]
    d = _f(dout)
    dx = np.zeros(x.shape)
    n, c, ho, wo = d.shape
    for a in range(n):
        for ch in range(c):
            for i in range(ho):
                for j in range(wo):
                    window = x[a, ch, i * stride:i * stride + size, j * stride:j * stride + size]
                    m, l = divmod(int(np.argmax(window)), size)
                    dx[a, ch, i * stride + m, j * stride + l] += d[a, ch, i, j]
    return dx


def global_avg_pool_forward(x):
    x = _f(x)
    return x.sum(axis=3).sum(axis=2) / (x.shape[2] * x.shape[3]), {"x": x}


def global_avg_pool_backward(dout, cache):
    x = _f(cache["x"])
    dx = np.empty(x.shape)
    dx[...] = _f(dout)[:, :, None, None]
    return dx / (x.shape[2] * x.shape[3])


# --------------------------------------------------------------------------------------------
# batch norm
# --------------------------------------------------------------------------------------------
def batchnorm2d_forward(x, gamma, beta, running_mean, running_var, training, momentum=0.1, eps=1e-5):
    x = _f(x)
    gamma, beta, rm, rv = _f(gamma), _f(beta), _f(running_mean), _f(running_var)
    out = np.empty(x.shape)
    new_mean, new_var = rm.copy(), rv.copy()
    for c in range(x.shape[1]):
        values = x[:, c].ravel()
        if training:
            mu = values.sum() / values.size
            var = ((values - mu) ** 2).sum() / values.size
            new_mean[c] = (1 - momentum) * rm[c] + momentum * mu
            new_var[c] = (1 - momentum) * rv[c] + momentum * np.var(values, ddof=1)
        else:
            mu, var = rm[c], rv[c]
        out[:, c] = gamma[c] * (x[:, c] - mu) / math.sqrt(var + eps) + beta[c]
    return out, {"x": x, "gamma": gamma, "beta": beta, "running_mean": new_mean, "running_var": new_var,
                 "training": training, "momentum": momentum, "eps": eps}


def batchnorm2d_backward(dout, cache):
    """By the chain rule through x̂, σ² and μ (the computational graph, step by step)."""
    x, gamma, eps = _f(cache["x"]), _f(cache["gamma"]), cache["eps"]
    d = _f(dout)
    dx = np.empty(x.shape)
    dgamma = np.empty(x.shape[1])
    dbeta = np.empty(x.shape[1])
    for c in range(x.shape[1]):
        xc, dc = x[:, c], d[:, c]
        m = xc.size
        if cache["training"]:
            mu = xc.mean()
            var = ((xc - mu) ** 2).mean()
        else:
            mu, var = cache["running_mean"][c], cache["running_var"][c]
        std = math.sqrt(var + eps)
        x_hat = (xc - mu) / std
        dgamma[c] = np.sum(dc * x_hat)
        dbeta[c] = np.sum(dc)
        dx_hat = dc * gamma[c]
        if not cache["training"]:
            dx[:, c] = dx_hat / std
            continue
        dvar = np.sum(dx_hat * (xc - mu)) * -0.5 * (var + eps) ** -1.5
        dmu = -np.sum(dx_hat) / std + dvar * np.mean(-2.0 * (xc - mu))
        dx[:, c] = dx_hat / std + dvar * 2.0 * (xc - mu) / m + dmu / m
    return dx, dgamma, dbeta


# --------------------------------------------------------------------------------------------
# dropout
# --------------------------------------------------------------------------------------------
def dropout_forward(x, p_keep, training, rng=None):
    x = _f(x)
    if not training:
        return x.copy(), {"x": x, "p_keep": p_keep, "training": training, "mask": np.ones(x.shape, dtype=bool)}
    generator = np.random.default_rng(rng)
    mask = generator.binomial(1, p_keep, size=x.shape).astype(bool)
    return x * mask * (1.0 / p_keep), {"x": x, "p_keep": p_keep, "training": training, "mask": mask}


def dropout_backward(dout, cache):
    d = _f(dout)
    if not cache["training"]:
        return d.copy()
    return d * np.asarray(cache["mask"]) * (1.0 / cache["p_keep"])


# --------------------------------------------------------------------------------------------
# residual block, from the layers above
# --------------------------------------------------------------------------------------------
def _block(x, params, training):
    p = {k: _f(v) for k, v in params.items()}
    proj = "w_proj" in p
    f = p["w1"].shape[0]
    zero = np.zeros(f)

    def bn(h, s):
        return batchnorm2d_forward(h, p["gamma" + s], p["beta" + s], p["running_mean" + s],
                                   p["running_var" + s], training)

    c = {}
    h, c["c1"] = conv2d_forward(x, p["w1"], zero, 2 if proj else 1, 1)
    h, c["b1"] = bn(h, "1")
    h, c["r1"] = relu_forward(h)
    h, c["c2"] = conv2d_forward(h, p["w2"], zero, 1, 1)
    h, c["b2"] = bn(h, "2")
    if proj:
        s, c["cp"] = conv2d_forward(x, p["w_proj"], zero, 2, 0)
        s, c["bp"] = bn(s, "_proj")
    else:
        s = _f(x)
    out, c["r"] = relu_forward(h + s)
    return out, c, proj


def residual_block_forward(x, params, training=True):
    out, _, _ = _block(_f(x), params, training)
    return out, {"x": _f(x), "params": params, "training": training}


def residual_block_backward(dout, cache):
    out, c, proj = _block(_f(cache["x"]), cache["params"], cache["training"])
    g = {}
    dz = relu_backward(dout, c["r"])
    dh, g["gamma2"], g["beta2"] = batchnorm2d_backward(dz, c["b2"])
    dh, g["w2"], _ = conv2d_backward(dh, c["c2"])
    dh = relu_backward(dh, c["r1"])
    dh, g["gamma1"], g["beta1"] = batchnorm2d_backward(dh, c["b1"])
    dx, g["w1"], _ = conv2d_backward(dh, c["c1"])
    if proj:
        ds, g["gamma_proj"], g["beta_proj"] = batchnorm2d_backward(dz, c["bp"])
        ds, g["w_proj"], _ = conv2d_backward(ds, c["cp"])
        dx = dx + ds
    else:
        dx = dx + dz
    return dx, g


# --------------------------------------------------------------------------------------------
# architectures, written out by hand
# --------------------------------------------------------------------------------------------
def _c(cin, cout, k, s=1, p=0, bias=False):
    return {"type": "conv", "in": cin, "out": cout, "kernel": k, "stride": s, "padding": p, "bias": bias}


def architecture_spec(name, num_classes=1000):
    if name == "vgg16":
        layers, cin = [], 3
        for width, repeat in ((64, 2), (128, 2), (256, 3), (512, 3), (512, 3)):
            for _ in range(repeat):
                layers += [_c(cin, width, 3, 1, 1, bias=True), {"type": "relu"}]
                cin = width
            layers.append({"type": "maxpool", "kernel": 2, "stride": 2})
        return layers + [{"type": "flatten"}, {"type": "linear", "in": 25088, "out": 4096},
                         {"type": "relu"}, {"type": "linear", "in": 4096, "out": 4096}, {"type": "relu"},
                         {"type": "linear", "in": 4096, "out": num_classes}]
    if name in ("resnet18", "resnet50"):
        bottleneck = name == "resnet50"
        layers = [_c(3, 64, 7, 2, 3), {"type": "bn", "channels": 64}, {"type": "relu"},
                  {"type": "maxpool", "kernel": 3, "stride": 2, "padding": 1}]
        cin = 64
        for stage, blocks in enumerate((3, 4, 6, 3) if bottleneck else (2, 2, 2, 2)):
            width = 64 * 2 ** stage
            cout = 4 * width if bottleneck else width
            for i in range(blocks):
                s = 2 if i == 0 and stage > 0 else 1
                if bottleneck:
                    body = [_c(cin, width, 1), {"type": "bn", "channels": width}, {"type": "relu"},
                            _c(width, width, 3, s, 1), {"type": "bn", "channels": width}, {"type": "relu"},
                            _c(width, cout, 1), {"type": "bn", "channels": cout}]
                else:
                    body = [_c(cin, cout, 3, s, 1), {"type": "bn", "channels": cout}, {"type": "relu"},
                            _c(cout, cout, 3, 1, 1), {"type": "bn", "channels": cout}]
                shortcut = [] if (s == 1 and cin == cout) else [_c(cin, cout, 1, s), {"type": "bn", "channels": cout}]
                layers += [{"type": "residual", "body": body, "shortcut": shortcut}, {"type": "relu"}]
                cin = cout
        return layers + [{"type": "gap"}, {"type": "flatten"}, {"type": "linear", "in": cin, "out": num_classes}]
    if name == "inception_3a":
        def branch(*convs):
            out = []
            for cin, cout, k in convs:
                out += [_c(cin, cout, k, 1, k // 2, bias=True), {"type": "relu"}]
            return out
        return [{"type": "concat", "branches": [
            branch((192, 64, 1)), branch((192, 96, 1), (96, 128, 3)), branch((192, 16, 1), (16, 32, 5)),
            [{"type": "maxpool", "kernel": 3, "stride": 1, "padding": 1}] + branch((192, 32, 1))]}]
    raise ValueError(f"unknown architecture {name!r}")


def count_parameters(spec):
    total, stack = 0, list(spec)
    while stack:                                   # an explicit stack instead of recursion
        layer = stack.pop()
        t = layer["type"]
        if t == "conv":
            k = layer["kernel"]
            kh, kw = (k, k) if isinstance(k, int) else k
            total += layer["in"] * layer["out"] * kh * kw + (layer["out"] if layer.get("bias", True) else 0)
        elif t == "linear":
            total += (layer["in"] + (1 if layer.get("bias", True) else 0)) * layer["out"]
        elif t == "bn":
            total += 2 * layer["channels"]
        elif t == "residual":
            stack += layer["body"] + layer.get("shortcut", [])
        elif t == "concat":
            for b in layer["branches"]:
                stack += b
    return total


def _two(v):
    return (v, v) if isinstance(v, int) else tuple(v)


def _flow(spec, shape):
    flops = 0
    for layer in spec:
        t = layer["type"]
        if t in ("conv", "maxpool", "avgpool"):
            (kh, kw) = _two(layer["kernel"])
            (sh, sw) = _two(layer.get("stride", 1 if t == "conv" else layer["kernel"]))
            (ph, pw) = _two(layer.get("padding", 0))
            h = conv_output_size(shape[1], kh, ph, sh)
            w = conv_output_size(shape[2], kw, pw, sw)
            if t == "conv":
                flops += 2 * (kh * kw * layer["in"]) * (layer["out"] * h * w)
                shape = (layer["out"], h, w)
            else:
                shape = (shape[0], h, w)
        elif t == "gap":
            shape = (shape[0],)
        elif t == "flatten":
            shape = (int(np.prod(shape)),)
        elif t == "linear":
            flops += 2 * layer["in"] * layer["out"]
            shape = (layer["out"],)
        elif t == "residual":
            shape_body, f1 = _flow(layer["body"], shape)
            _, f2 = _flow(layer.get("shortcut", []), shape)
            shape, flops = shape_body, flops + f1 + f2
        elif t == "concat":
            results = [_flow(b, shape) for b in layer["branches"]]
            flops += sum(f for _, f in results)
            shape = (sum(s[0] for s, _ in results),) + results[0][0][1:]
    return shape, flops


def count_flops(spec, input_shape):
    return _flow(spec, tuple(input_shape))[1]


ALTERNATIVES = {
    "nn.relu_forward": relu_forward, "nn.relu_backward": relu_backward,
    "nn.sigmoid_forward": sigmoid_forward, "nn.sigmoid_backward": sigmoid_backward,
    "nn.leaky_relu_forward": leaky_relu_forward, "nn.leaky_relu_backward": leaky_relu_backward,
    "nn.linear_forward": linear_forward, "nn.linear_backward": linear_backward,
    "nn.conv_output_size": conv_output_size, "nn.receptive_field": receptive_field,
    "nn.conv2d_forward": conv2d_forward, "nn.conv2d_backward": conv2d_backward,
    "nn.maxpool2d_forward": maxpool2d_forward, "nn.maxpool2d_backward": maxpool2d_backward,
    "nn.global_avg_pool_forward": global_avg_pool_forward, "nn.global_avg_pool_backward": global_avg_pool_backward,
    "nn.batchnorm2d_forward": batchnorm2d_forward, "nn.batchnorm2d_backward": batchnorm2d_backward,
    "nn.dropout_forward": dropout_forward, "nn.dropout_backward": dropout_backward,
    "nn.residual_block_forward": residual_block_forward, "nn.residual_block_backward": residual_block_backward,
    "nn.architecture_spec": architecture_spec, "nn.count_parameters": count_parameters,
    "nn.count_flops": count_flops,
}


def dropout_forward_uniform_above(x, p_keep, training, rng=None):
    """Another correct draw: keep where u ≥ 1 − p_keep (a different set of units than the reference)."""
    x = _f(x)
    if not training:
        return x.copy(), {"x": x, "p_keep": p_keep, "training": training, "mask": np.ones(x.shape, dtype=bool)}
    mask = np.random.default_rng(rng).random(x.shape) >= 1.0 - p_keep
    return np.where(mask, x / p_keep, 0.0), {"x": x, "p_keep": p_keep, "training": training, "mask": mask}


def relu_backward_heaviside(dout, cache):
    return _f(dout) * np.heaviside(_f(cache["x"]), 1.0)


EXTRA_ALTERNATIVES = {
    "nn.dropout_forward": dropout_forward_uniform_above,
    "nn.relu_backward": relu_backward_heaviside,
}
