"""Chapter 12's measured exercise: a CNN trained on the digits, graded by its accuracy.

The student's ``train_digits(x_train, y_train, rng)`` assembles a small convolutional network
from the layers of Chapter 10 and trains it with the recipe pieces of Chapter 12; it returns a
function that predicts labels. The grade is the accuracy that function reaches on held-out
digits the student never sees, drawn per student at grading time
(:func:`held_out_split`), put through the published scale (:data:`ACCURACY_SCALE`). The time a
call may take is :data:`BUDGET_SECONDS`.

The reference recipe (:func:`train_digits`):

* the network conv 3×3 (16) – batch norm – ReLU – max-pool 2 – conv 3×3 (32) – batch norm –
  ReLU – max-pool 2 – flatten – linear (10), on compact layers of this module
  (:data:`FAST_BLOCKS`: graded as a candidate, the reference may call no registered function);
  ``train_cnn(..., blocks=registry_blocks())`` trains the same network on the registry's layers,
  which inside ``with cvkit.use("student"):`` are a student's Chapter 10 layers;
* inputs standardised with the training set's mean and standard deviation;
* plain mini-batch SGD with weight decay (``train.sgd_weight_decay_step``), a linear warm-up
  (``train.warmup``) then a cosine decay (``train.cosine_decay``), soft targets from
  ``train.smooth_labels`` (random translations by one pixel are an option; they cost accuracy
  on these 8×8 images).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._threads import single_thread
from .._validation import as_rng
from ..data import held_out_digits
from ..registry import algorithm, implementation

__all__ = ["train_digits", "ACCURACY_SCALE", "BUDGET_SECONDS", "held_out_split",
           "public_split", "train_cnn", "registry_blocks", "FAST_BLOCKS"]

#: the published scale: (accuracy, fraction of the points) corners, linear in between, flat outside
#: (``cvkit.train.checks.ACCURACY`` is the :class:`~cvkit.grading.measured.Scale` the grader applies)
ACCURACY_SCALE: tuple[tuple[float, float], ...] = ((0.90, 0.0), (0.95, 0.5), (0.97, 1.0))
#: seconds one call of ``train_digits`` may take on the grader (its case time limit)
BUDGET_SECONDS = 30.0

#: a per-seed split of all 1797 digits, perturbed, in one random camera's grey levels
#: (:func:`cvkit.data.held_out_digits`)
held_out_split = held_out_digits


def public_split() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The visible case: ``cvkit.data.digits``'s own split, in 8-bit grey levels (×255)."""
    from ..data import digits

    (a, ya), (b, yb) = digits(flatten=False)
    return 255.0 * a, ya.astype(np.int64), 255.0 * b, yb.astype(np.int64)


def _shift(x: np.ndarray, generator: np.random.Generator) -> np.ndarray:
    """Every image of ``x`` (N, C, H, W) translated by (dy, dx) ∈ {−1, 0, 1}², zero fill."""
    n, c, h, w = x.shape
    padded = np.pad(x, ((0, 0), (0, 0), (1, 1), (1, 1)))
    dy = np.asarray(generator.integers(0, 3, n))
    dx = np.asarray(generator.integers(0, 3, n))
    rows = (dy[:, None] + np.arange(h))[:, None, :, None]
    cols = (dx[:, None] + np.arange(w))[:, None, None, :]
    return padded[np.arange(n)[:, None, None, None], np.arange(c)[None, :, None, None], rows, cols]


# --------------------------------------------------------------------------------------------
# the layers (compact NumPy versions for 3×3 convolutions with padding 1 and 2×2 pooling, with
# the call conventions of cvkit.nn: forward -> (out, cache), backward(dout, cache) -> grads)
# --------------------------------------------------------------------------------------------
def _conv_f(x: np.ndarray, w: np.ndarray, b: np.ndarray, stride: int = 1, padding: int = 1) -> tuple[np.ndarray, Any]:
    n, c, h, wd = x.shape
    cols = np.lib.stride_tricks.sliding_window_view(np.pad(x, ((0, 0), (0, 0), (1, 1), (1, 1))), (3, 3), axis=(2, 3))
    cols = cols.transpose(0, 2, 3, 1, 4, 5).reshape(n * h * wd, c * 9)        # one row per output pixel
    out = (cols @ w.reshape(w.shape[0], -1).T + b).reshape(n, h, wd, -1).transpose(0, 3, 1, 2)
    return out, (cols, x.shape, w)


def _conv_b(dout: np.ndarray, cache: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    cols, (n, c, h, wd), w = cache
    d = dout.transpose(0, 2, 3, 1).reshape(n * h * wd, -1)
    dw = (d.T @ cols).reshape(w.shape)
    dcols = (d @ w.reshape(w.shape[0], -1)).reshape(n, h, wd, c, 3, 3)
    dpad = np.zeros((n, c, h + 2, wd + 2))
    for i in range(3):
        for j in range(3):
            dpad[:, :, i:i + h, j:j + wd] += dcols[:, :, :, :, i, j].transpose(0, 3, 1, 2)
    return dpad[:, :, 1:-1, 1:-1], dw, d.sum(axis=0)


def _bn_f(x: np.ndarray, gamma: np.ndarray, beta: np.ndarray, running_mean: np.ndarray, running_var: np.ndarray,
          training: bool, momentum: float = 0.1, eps: float = 1e-5) -> tuple[np.ndarray, dict[str, Any]]:
    if training:
        mean, var = x.mean(axis=(0, 2, 3)), x.var(axis=(0, 2, 3))
        count = x.size // x.shape[1]
        new_mean = (1 - momentum) * running_mean + momentum * mean
        new_var = (1 - momentum) * running_var + momentum * var * count / max(count - 1, 1)
    else:
        mean, var, new_mean, new_var = running_mean, running_var, running_mean, running_var
    inv = 1.0 / np.sqrt(var + eps)
    xhat = (x - mean[None, :, None, None]) * inv[None, :, None, None]
    out = gamma[None, :, None, None] * xhat + beta[None, :, None, None]
    return out, {"xhat": xhat, "inv": inv, "gamma": gamma, "running_mean": new_mean, "running_var": new_var}


def _bn_b(dout: np.ndarray, cache: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    xhat, inv, gamma = cache["xhat"], cache["inv"], cache["gamma"]
    dgamma, dbeta = (dout * xhat).sum(axis=(0, 2, 3)), dout.sum(axis=(0, 2, 3))
    m = dout.size // dout.shape[1]
    dx = (gamma * inv)[None, :, None, None] / m * (
        m * dout - dbeta[None, :, None, None] - xhat * dgamma[None, :, None, None])
    return dx, dgamma, dbeta


def _relu_f(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.maximum(x, 0.0), x > 0


def _relu_b(dout: np.ndarray, cache: np.ndarray) -> np.ndarray:
    return dout * cache


def _pool_f(x: np.ndarray, size: int = 2, stride: int = 2) -> tuple[np.ndarray, Any]:
    n, c, h, w = x.shape
    blocks = x.reshape(n, c, h // 2, 2, w // 2, 2)
    out = blocks.max(axis=(3, 5))
    first = np.argmax(blocks.transpose(0, 1, 2, 4, 3, 5).reshape(n, c, h // 2, w // 2, 4), axis=-1)
    return out, (first, x.shape)


def _pool_b(dout: np.ndarray, cache: Any) -> np.ndarray:
    first, (n, c, h, w) = cache
    dx = np.zeros((n, c, h // 2, w // 2, 4))
    np.put_along_axis(dx, first[..., None], dout[..., None], axis=-1)
    return dx.reshape(n, c, h // 2, w // 2, 2, 2).transpose(0, 1, 2, 4, 3, 5).reshape(n, c, h, w)


def _linear_f(x: np.ndarray, W: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, Any]:
    return x @ W + b, (x, W)


def _linear_b(dout: np.ndarray, cache: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x, W = cache
    return dout @ W.T, x.T @ dout, dout.sum(axis=0)


#: the blocks of the reference recipe (its own layers, so that grading it calls no registered function)
FAST_BLOCKS: dict[str, Callable[..., Any]] = {
    "nn.conv2d_forward": _conv_f, "nn.conv2d_backward": _conv_b,
    "nn.batchnorm2d_forward": _bn_f, "nn.batchnorm2d_backward": _bn_b,
    "nn.relu_forward": _relu_f, "nn.relu_backward": _relu_b,
    "nn.maxpool2d_forward": _pool_f, "nn.maxpool2d_backward": _pool_b,
    "nn.linear_forward": _linear_f, "nn.linear_backward": _linear_b,
    "train.sgd_weight_decay_step": lambda ps, gs, lr, wd: [(1.0 - lr * wd) * p - lr * g for p, g in zip(ps, gs)],
    "train.cosine_decay": lambda e, total, lr0: lr0 * 0.5 * (1.0 + np.cos(np.pi * e / total)),
    "train.warmup": lambda step, steps, lr: lr * min(step, steps) / steps,
    "train.smooth_labels": lambda y, classes, eps: np.where(np.eye(classes)[y] > 0, 1.0 - eps, eps / (classes - 1)),
}


def registry_blocks() -> dict[str, Callable[..., Any]]:
    """The same blocks looked up through the registry: inside ``with cvkit.use("student"):``
    the student's Chapter 10 layers and Chapter 12 recipe pieces."""
    return {name: implementation(name) for name in FAST_BLOCKS}


def train_cnn(x_train: ArrayLike, y_train: ArrayLike, rng: np.random.Generator | int | None = None, *,
              normalise: bool = True, lr: float = 0.3, epochs: int = 20, batch_size: int = 32,
              weight_decay: float = 5e-4, label_smoothing: float = 0.05, shift: bool = False,
              warmup_epochs: float = 1.0, channels: tuple[int, int] = (16, 32),
              blocks: dict[str, Callable[..., Any]] | None = None) -> Callable[[ArrayLike], np.ndarray]:
    """Train the chapter's CNN with a recipe; returns ``predict(x) -> labels``.

    ``normalise=False`` drops both normalisations (input standardisation and batch norm): the
    "no normalisation" recipe of the exercise's tests. ``blocks`` maps the ids of the layers and
    recipe pieces to functions (default :data:`FAST_BLOCKS`; :func:`registry_blocks` trains on
    the active provider's, e.g. a student's Chapter 10 layers).
    """
    generator = as_rng(rng)
    b_ = FAST_BLOCKS if blocks is None else blocks
    conv_f, conv_b = b_["nn.conv2d_forward"], b_["nn.conv2d_backward"]
    bn_f, bn_b = b_["nn.batchnorm2d_forward"], b_["nn.batchnorm2d_backward"]
    relu_f, relu_b = b_["nn.relu_forward"], b_["nn.relu_backward"]
    pool_f, pool_b = b_["nn.maxpool2d_forward"], b_["nn.maxpool2d_backward"]
    lin_f, lin_b = b_["nn.linear_forward"], b_["nn.linear_backward"]
    sgd = b_["train.sgd_weight_decay_step"]
    cosine, warm = b_["train.cosine_decay"], b_["train.warmup"]
    smooth = b_["train.smooth_labels"]

    x = np.asarray(x_train, dtype=np.float64).reshape(-1, 1, 8, 8)
    y = np.asarray(y_train).astype(np.int64)
    mean, std = (float(x.mean()), float(x.std()) + 1e-8) if normalise else (0.0, 1.0)
    x = (x - mean) / std
    p: dict[str, np.ndarray] = {
        "w1": generator.standard_normal((channels[0], 1, 3, 3)) * np.sqrt(2.0 / 9),
        "b1": np.zeros(channels[0]),
        "w2": generator.standard_normal((channels[1], channels[0], 3, 3)) * np.sqrt(2.0 / (9 * channels[0])),
        "b2": np.zeros(channels[1]),
        "W": generator.standard_normal((channels[1] * 4, 10)) * np.sqrt(1.0 / (channels[1] * 4)),
        "b": np.zeros(10),
    }
    stats: dict[str, np.ndarray] = {}
    if normalise:
        for i, c in ((1, channels[0]), (2, channels[1])):
            p[f"gamma{i}"], p[f"beta{i}"] = np.ones(c), np.zeros(c)
            stats[f"mean{i}"], stats[f"var{i}"] = np.zeros(c), np.ones(c)
    names = sorted(p)

    def scores(h: np.ndarray, training: bool, caches: dict[str, Any]) -> np.ndarray:
        for i in (1, 2):
            h, caches[f"conv{i}"] = conv_f(h, p[f"w{i}"], p[f"b{i}"], 1, 1)
            if normalise:
                h, caches[f"bn{i}"] = bn_f(h, p[f"gamma{i}"], p[f"beta{i}"], stats[f"mean{i}"], stats[f"var{i}"],
                                           training)
                if training:
                    stats[f"mean{i}"] = np.asarray(caches[f"bn{i}"]["running_mean"])
                    stats[f"var{i}"] = np.asarray(caches[f"bn{i}"]["running_var"])
            h, caches[f"relu{i}"] = relu_f(h)
            h, caches[f"pool{i}"] = pool_f(h, 2, 2)
        caches["shape"] = h.shape
        out, caches["linear"] = lin_f(h.reshape(h.shape[0], -1), p["W"], p["b"])
        return out

    def gradients(dscores: np.ndarray, caches: dict[str, Any]) -> dict[str, np.ndarray]:
        g: dict[str, np.ndarray] = {}
        dh, g["W"], g["b"] = lin_b(dscores, caches["linear"])
        dh = dh.reshape(caches["shape"])
        for i in (2, 1):
            dh = pool_b(dh, caches[f"pool{i}"])
            dh = relu_b(dh, caches[f"relu{i}"])
            if normalise:
                dh, g[f"gamma{i}"], g[f"beta{i}"] = bn_b(dh, caches[f"bn{i}"])
            dh, g[f"w{i}"], g[f"b{i}"] = conv_b(dh, caches[f"conv{i}"])
        return g

    targets = np.asarray(smooth(y, 10, label_smoothing), dtype=np.float64)
    n = len(x)
    steps_per_epoch = -(-n // batch_size)
    total = epochs * steps_per_epoch
    warm_steps = int(round(warmup_epochs * steps_per_epoch))
    step = 0
    with single_thread(), np.errstate(all="ignore"):
        for _ in range(epochs):
            order = generator.permutation(n)
            for start in range(0, n, batch_size):
                batch = order[start:start + batch_size]
                if batch.size < 2:
                    continue
                xb = _shift(x[batch], generator) if shift else x[batch]
                if step < warm_steps:
                    rate = float(warm(step, warm_steps, lr))
                else:
                    rate = float(cosine(min(step - warm_steps, total - warm_steps), total - warm_steps, lr))
                caches: dict[str, Any] = {}
                logits = scores(xb, True, caches)
                shifted = logits - logits.max(axis=1, keepdims=True)
                probs = np.exp(shifted)
                probs /= probs.sum(axis=1, keepdims=True)
                grads = gradients((probs - targets[batch]) / batch.size, caches)
                updated = sgd([p[k] for k in names], [grads[k] for k in names], rate, weight_decay)
                p.update(zip(names, (np.asarray(v) for v in updated)))
                step += 1

    def predict(images: ArrayLike) -> np.ndarray:
        h = (np.asarray(images, dtype=np.float64).reshape(-1, 1, 8, 8) - mean) / std
        with single_thread(), np.errstate(all="ignore"):
            out = np.concatenate([scores(h[s:s + 256], False, {}) for s in range(0, len(h), 256)]) \
                if len(h) else np.zeros((0, 10))
        return np.argmax(np.nan_to_num(out, nan=0.0), axis=1)

    return predict


@algorithm("train.train_digits", section="12.5.4", check="cvkit.train.checks:train_digits")
def train_digits(x_train: ArrayLike, y_train: ArrayLike,
                 rng: np.random.Generator | int | None = None) -> Callable[[ArrayLike], np.ndarray]:
    """Train the chapter's small CNN on digits with the reference recipe.

    Parameters
    ----------
    x_train : (N, 8, 8) array_like
        Digit images in the grey levels of some camera (any range: the recipe standardises them).
    y_train : (N,) array_like of int
        Their labels 0..9.
    rng : Generator, int or None
        Seed of the initial weights, the mini-batch order and the augmentation.

    Returns
    -------
    callable
        ``predict(x)`` → int64 labels ``(M,)`` of the images ``x`` (M, 8, 8).
    """
    return train_cnn(x_train, y_train, rng)
