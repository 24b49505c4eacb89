# Answer cells of the "typical mistakes" sample submission of ch10_representations.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution. Sections 10.1-10.3 (kNN, k-means, bag of words): two typical mistakes and one
# exercise left unattempted.
# This file is data for the demo and its tests, not a module to import.

# %% knn_predict_answer
@student("learn.knn_predict")
def knn_predict(X_train, y_train, X_test, k=1, metric="l2"):
    """kNN with Counter.most_common for the vote, which gives a tie to the label met first."""
    from collections import Counter

    A = np.asarray(X_train, dtype=float)
    out = []
    for q in np.asarray(X_test, dtype=float):
        diff = A - q
        d = np.sum(diff ** 2, axis=1) if metric == "l2" else np.sum(np.abs(diff), axis=1)
        nearest = np.argsort(d, kind="stable")[:k]
        out.append(Counter(np.asarray(y_train)[nearest].tolist()).most_common(1)[0][0])
    return np.array(out)

# %% kmeans_answer
@student("learn.kmeans")
def kmeans(X, k, iterations=50, rng=None, init=None):
    """k-means++ and Lloyd's loop, but an empty cluster's mean is np.mean of nothing: NaN."""
    X = np.asarray(X, dtype=float)
    generator = np.random.default_rng(rng)
    n = len(X)
    if init is not None:
        centers = np.array(init, dtype=float)
    else:
        centers = [X[generator.integers(n)]]
        closest = np.sum((X - centers[0]) ** 2, axis=1)
        for _ in range(1, k):
            pick = generator.choice(n, p=closest / closest.sum())
            centers.append(X[pick])
            closest = np.minimum(closest, np.sum((X - X[pick]) ** 2, axis=1))
        centers = np.array(centers)
    labels = np.argmin(np.sum((X[:, None] - centers[None]) ** 2, axis=2), axis=1)
    for _ in range(iterations):
        with np.errstate(invalid="ignore"):
            new = np.array([X[labels == j].mean(axis=0) if np.any(labels == j) else np.full(X.shape[1], np.nan)
                            for j in range(k)])
        if np.array_equal(new, centers, equal_nan=True):
            break
        centers = new
        with np.errstate(invalid="ignore"):
            labels = np.argmin(np.sum((X[:, None] - centers[None]) ** 2, axis=2), axis=1)
    return centers, labels

# %% bovw_histogram_answer
@student("learn.bovw_histogram")
def bovw_histogram(descriptors, codebook, normalize=True):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()

# --- sections 10.5-10.7 (neural network layers): five typical mistakes,
# --- and the receptive field left unattempted.

# %% relu_backward_answer
@student("nn.relu_backward")
def relu_backward(dout, cache):
    """PyTorch's convention: no gradient at x = 0 (the notes take ReLU'(0) = 1)."""
    return np.where(cache["x"] > 0, dout, 0.0)

# %% sigmoid_forward_answer
@student("nn.sigmoid_forward")
def sigmoid_forward(x):
    """The textbook formula, which overflows: exp(1000) is inf and inf/inf is NaN."""
    x = np.asarray(x, dtype=float)
    out = np.exp(x) / (1.0 + np.exp(x))
    return out, {"x": x, "out": out}

# %% conv2d_forward_answer
@student("nn.conv2d_forward")
def conv2d_forward(x, w, b, stride=1, padding=0):
    """Chapter 3's convolution: the kernel is flipped first (deep learning correlates)."""
    x, w, b = (np.asarray(a, dtype=float) for a in (x, w, b))
    w = w[:, :, ::-1, ::-1]
    n, c, h, width = x.shape
    f, _, kh, kw = w.shape
    xp = np.pad(x, ((0, 0), (0, 0), (padding, padding), (padding, padding)))
    ho, wo = (h + 2 * padding - kh) // stride + 1, (width + 2 * padding - kw) // stride + 1
    out = np.zeros((n, f, ho, wo))
    for i in range(ho):
        for j in range(wo):
            patch = xp[:, :, i * stride:i * stride + kh, j * stride:j * stride + kw]
            out[:, :, i, j] = np.tensordot(patch, w, axes=([1, 2, 3], [1, 2, 3])) + b
    return out, {"x": x, "w": w[:, :, ::-1, ::-1], "b": b, "stride": stride, "padding": padding}

# %% receptive_field_answer
@student("nn.receptive_field")
def receptive_field(layers):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()

# %% maxpool2d_backward_answer
@student("nn.maxpool2d_backward")
def maxpool2d_backward(dout, cache):
    """Sends each window's gradient to every element of the window, not only to its maximum."""
    x, size, stride = cache["x"], cache["size"], cache["stride"]
    dx = np.zeros(np.shape(x))
    ho, wo = np.shape(dout)[2:]
    for i in range(ho):
        for j in range(wo):
            dx[:, :, i * stride:i * stride + size, j * stride:j * stride + size] += dout[:, :, i:i + 1, j:j + 1]
    return dx

# %% batchnorm2d_forward_answer
@student("nn.batchnorm2d_forward")
def batchnorm2d_forward(x, gamma, beta, running_mean, running_var, training, momentum=0.1, eps=1e-5):
    """Normalises with the running statistics also while training (and updates them)."""
    x = np.asarray(x, dtype=float)
    mean, var = x.mean(axis=(0, 2, 3)), x.var(axis=(0, 2, 3), ddof=1)
    new_mean = (1 - momentum) * running_mean + momentum * mean if training else running_mean
    new_var = (1 - momentum) * running_var + momentum * var if training else running_var
    x_hat = (x - running_mean[None, :, None, None]) / np.sqrt(running_var[None, :, None, None] + eps)
    out = gamma[None, :, None, None] * x_hat + beta[None, :, None, None]
    return out, {"x": x, "gamma": gamma, "beta": beta, "running_mean": new_mean, "running_var": new_var,
                 "training": training, "momentum": momentum, "eps": eps}
