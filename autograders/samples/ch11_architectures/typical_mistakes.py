# Answer cells of the "typical mistakes" sample submission of ch11_architectures.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution. Four typical mistakes, and the layer list of the architectures left unattempted.
# This file is data for the demo and its tests, not a module to import.

# %% count_parameters_answer
@student("nn.count_parameters")
def count_parameters(spec):
    """Counts batch norm's running mean and variance as parameters too (4 per channel)."""
    total = 0
    for layer in spec:
        kind = layer["type"]
        if kind == "conv":
            k = layer["kernel"]
            kh, kw = (k, k) if np.isscalar(k) else k
            total += layer["out"] * layer["in"] * kh * kw + (layer["out"] if layer.get("bias", True) else 0)
        elif kind == "linear":
            total += (layer["in"] + (1 if layer.get("bias", True) else 0)) * layer["out"]
        elif kind == "bn":
            total += 4 * layer["channels"]          # gamma, beta, running mean, running variance
        elif kind == "residual":
            total += count_parameters(layer["body"]) + count_parameters(layer.get("shortcut", []))
        elif kind == "concat":
            total += sum(count_parameters(b) for b in layer["branches"])
    return total

# %% count_flops_answer
@student("nn.count_flops")
def count_flops(spec, input_shape):
    """Counts multiply-adds, not FLOPs (one operation per multiply-add instead of two)."""
    def pair(v):
        return (v, v) if np.isscalar(v) else tuple(v)

    def walk(layers, shape):
        total = 0
        for layer in layers:
            kind = layer["type"]
            if kind in ("conv", "maxpool", "avgpool"):
                kh, kw = pair(layer["kernel"])
                sh, sw = pair(layer.get("stride", 1 if kind == "conv" else layer["kernel"]))
                ph, pw = pair(layer.get("padding", 0))
                h = (shape[1] - kh + 2 * ph) // sh + 1
                w = (shape[2] - kw + 2 * pw) // sw + 1
                if kind == "conv":
                    total += layer["out"] * h * w * layer["in"] * kh * kw
                    shape = (layer["out"], h, w)
                else:
                    shape = (shape[0], h, w)
            elif kind == "gap":
                shape = (shape[0],)
            elif kind == "flatten":
                shape = (int(np.prod(shape)),)
            elif kind == "linear":
                total += layer["in"] * layer["out"]
                shape = (layer["out"],)
            elif kind == "residual":
                out, f = walk(layer["body"], shape)
                total += f + walk(layer.get("shortcut", []), shape)[1]
                shape = out
            elif kind == "concat":
                parts = [walk(b, shape) for b in layer["branches"]]
                total += sum(f for _, f in parts)
                shape = (sum(s[0] for s, _ in parts),) + tuple(parts[0][0][1:])
        return shape, total

    return walk(spec, tuple(input_shape))[1]

# %% global_avg_pool_backward_answer
@student("nn.global_avg_pool_backward")
def global_avg_pool_backward(dout, cache):
    """Copies dout to every position, forgetting the 1/(H·W) of the mean."""
    x = cache["x"]
    return np.broadcast_to(np.asarray(dout, dtype=float)[:, :, None, None], x.shape).copy()

# %% residual_block_forward_answer
@student("nn.residual_block_forward")
def residual_block_forward(x, params, training=True):
    """Built from cvkit's layers, but the ReLU comes before the shortcut is added."""
    x = np.asarray(x, dtype=float)
    f = params["w1"].shape[0]
    stride = 2 if "w_proj" in params else 1

    def bn(h, s):
        return nn.batchnorm2d_forward(h, params["gamma" + s], params["beta" + s], params["running_mean" + s],
                                      params["running_var" + s], training)[0]

    h = nn.relu_forward(bn(nn.conv2d_forward(x, params["w1"], np.zeros(f), stride, 1)[0], "1"))[0]
    h = nn.relu_forward(bn(nn.conv2d_forward(h, params["w2"], np.zeros(f), 1, 1)[0], "2"))[0]
    if "w_proj" in params:
        shortcut = bn(nn.conv2d_forward(x, params["w_proj"], np.zeros(f), 2, 0)[0], "_proj")
    else:
        shortcut = x
    return h + shortcut, {"x": x, "params": params, "training": training}

# %% architecture_spec_answer
@student("nn.architecture_spec")
def architecture_spec(name, num_classes=1000):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()
