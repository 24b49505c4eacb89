"""Correct implementations of Chapter 12's algorithms, written differently from cvkit's reference.

They play the part of good students: a check must accept every one of them. Most are written
the way a first version looks (Python loops, ``math`` instead of NumPy, PyTorch's phase table
for the one-cycle schedule); the random ones draw their numbers in another order or with
other NumPy calls than the reference, so they only agree with it in distribution. None calls
cvkit or a library that the guard forbids.
"""
from __future__ import annotations

import math

import numpy as np


# --------------------------------------------------------------------------------------------
# schedules
# --------------------------------------------------------------------------------------------
def step_decay(epoch, lr0, drop=0.1, every=30):
    stages = int(math.floor(float(epoch) / every))
    lr = float(lr0)
    for _ in range(stages):
        lr *= drop
    return lr


def cosine_decay(epoch, epochs, lr0, lr_final=0.0):
    progress = float(epoch) / float(epochs)
    return lr0 - (lr0 - lr_final) * (1.0 - math.cos(math.pi * progress)) / 2.0


def warmup(step, warmup_steps, lr_target, lr_start=0.0):
    if warmup_steps == 0 or step >= warmup_steps:
        return float(lr_target)
    return lr_start + (lr_target - lr_start) * (step / warmup_steps)


def one_cycle(step, total_steps, lr_max, pct_start=0.3, div=25.0, final_div=1e4):
    """PyTorch's OneCycleLR.get_lr, transcribed phase by phase."""
    initial = lr_max / div
    minimum = initial / final_div
    phases = [
        {"end_step": float(pct_start * total_steps) - 1, "start_lr": initial, "end_lr": lr_max},
        {"end_step": total_steps - 1, "start_lr": lr_max, "end_lr": minimum},
    ]
    start_step = 0.0
    for i, phase in enumerate(phases):
        end_step = phase["end_step"]
        if step <= end_step or i == len(phases) - 1:
            if end_step == start_step:  # a phase of length zero (PyTorch divides by zero here)
                return phase["end_lr"]
            pct = (step - start_step) / (end_step - start_step)
            cos_out = math.cos(math.pi * pct) + 1
            return phase["end_lr"] + (phase["start_lr"] - phase["end_lr"]) / 2.0 * cos_out
        start_step = phase["end_step"]
    raise AssertionError("unreachable")


# --------------------------------------------------------------------------------------------
# regularisation
# --------------------------------------------------------------------------------------------
def sgd_weight_decay_step(params, grads, lr, weight_decay):
    def one(theta, g):
        theta = np.array(theta, dtype=np.float64)  # a copy
        theta -= lr * weight_decay * theta
        theta -= lr * np.asarray(g, dtype=np.float64)
        return theta

    if isinstance(params, (list, tuple)):
        return [one(t, g) for t, g in zip(params, grads)]
    return one(params, grads)


def early_stopping(val_losses, patience):
    best = None
    best_epoch = 0
    for epoch, loss in enumerate(val_losses):
        if best is None or loss < best:
            best, best_epoch = loss, epoch
        elif epoch - best_epoch >= patience:
            return epoch
    return None


def smooth_labels(y, classes, eps):
    y = np.asarray(y, dtype=np.int64)
    onehot = np.eye(classes)[y]
    return (1 - eps) * onehot + eps / (classes - 1) * (1 - onehot)


def stochastic_depth(x, residual, survival_prob, training, rng=None):
    x = np.asarray(x, dtype=np.float64)
    residual = np.asarray(residual, dtype=np.float64)
    if not training:
        return x + survival_prob * residual
    gen = np.random.default_rng(rng)
    out = x.copy()
    coins = gen.binomial(1, survival_prob, size=x.shape[0])
    for n in range(x.shape[0]):
        if coins[n]:
            out[n] += residual[n]
    return out


# --------------------------------------------------------------------------------------------
# augmentation
# --------------------------------------------------------------------------------------------
def _interpolation_matrix(n_in, n_out):
    """(n_out, n_in) weights of a half-pixel-centred bilinear resize with edge clamping."""
    m = np.zeros((n_out, n_in))
    for u in range(n_out):
        src = min(max((u + 0.5) * n_in / n_out - 0.5, 0.0), n_in - 1.0)
        i0 = int(math.floor(src))
        i1 = min(i0 + 1, n_in - 1)
        f = src - i0
        m[u, i0] += 1 - f
        m[u, i1] += f
    return m


def random_resized_crop(image, output_size, scale=(0.08, 1.0), ratio=(3 / 4, 4 / 3), rng=None):
    """torchvision's sampling (10 attempts, one at a time) and a resize by two matrices."""
    img = np.asarray(image, dtype=np.float64)
    oh, ow = (output_size, output_size) if np.isscalar(output_size) else output_size
    gen = np.random.default_rng(rng)
    height, width = img.shape[:2]
    area = height * width
    box = None
    for _ in range(10):
        target = area * gen.uniform(scale[0], scale[1])
        aspect = math.exp(gen.uniform(math.log(ratio[0]), math.log(ratio[1])))
        w = int(round(math.sqrt(target * aspect)))
        h = int(round(math.sqrt(target / aspect)))
        if 0 < w <= width and 0 < h <= height:
            box = (int(gen.integers(0, height - h + 1)), int(gen.integers(0, width - w + 1)), h, w)
            break
    if box is None:
        box = (0, 0, height, width)
    top, left, h, w = box
    crop = img[top: top + h, left: left + w]
    rows, cols = _interpolation_matrix(h, oh), _interpolation_matrix(w, ow)
    if crop.ndim == 2:
        return rows @ crop @ cols.T
    return np.stack([rows @ crop[..., c] @ cols.T for c in range(crop.shape[2])], axis=-1)


def cutout(image, size, rng=None):
    img = np.asarray(image, dtype=np.float64)
    gen = np.random.default_rng(rng)
    h, w = img.shape[:2]
    cy, cx = gen.integers(0, h), gen.integers(0, w)
    rows = np.arange(h)[:, None]
    cols = np.arange(w)[None, :]
    top, left = cy - size // 2, cx - size // 2
    inside = (rows >= top) & (rows < top + size) & (cols >= left) & (cols < left + size)
    if img.ndim == 3:
        inside = inside[..., None]
    return np.where(inside, 0.0, img)


def mixup(x, y_onehot, alpha=0.2, rng=None):
    """Draws the permutation first, then λ (the reference draws λ first)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y_onehot, dtype=np.float64)
    gen = np.random.default_rng(rng)
    order = np.argsort(gen.random(x.shape[0]))
    lam = gen.beta(alpha, alpha)
    return lam * x + (1 - lam) * x[order], lam * y + (1 - lam) * y[order], float(lam)


def cutmix(x, y_onehot, alpha=1.0, rng=None):
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y_onehot, dtype=np.float64)
    gen = np.random.default_rng(rng)
    n, (H, W) = x.shape[0], x.shape[-2:]
    perm = gen.permutation(n)
    lam = gen.beta(alpha, alpha)
    cut_h, cut_w = int(H * math.sqrt(1 - lam)), int(W * math.sqrt(1 - lam))
    cy, cx = gen.integers(H), gen.integers(W)
    y1, y2 = max(cy - cut_h // 2, 0), min(cy + cut_h // 2, H)
    x1, x2 = max(cx - cut_w // 2, 0), min(cx + cut_w // 2, W)
    out = x.copy()
    for i in range(n):
        out[i, ..., y1:y2, x1:x2] = x[perm[i], ..., y1:y2, x1:x2]
    lam = 1 - max(y2 - y1, 0) * max(x2 - x1, 0) / (H * W)
    return out, lam * y + (1 - lam) * y[perm], float(lam)


# --------------------------------------------------------------------------------------------
# recipes
# --------------------------------------------------------------------------------------------
def random_search(space, trials, rng=None):
    """One trial at a time; log-uniform values through log10; choices with rng.choice."""
    gen = np.random.default_rng(rng)
    settings = []
    for _ in range(trials):
        setting = {}
        for name, spec in space.items():
            if isinstance(spec, dict):
                if spec.get("log", False):
                    setting[name] = float(10 ** gen.uniform(math.log10(spec["low"]), math.log10(spec["high"])))
                    setting[name] = min(max(setting[name], spec["low"]), spec["high"])
                else:
                    setting[name] = float(spec["low"] + (spec["high"] - spec["low"]) * gen.random())
            else:
                setting[name] = spec[gen.choice(len(spec))]
        settings.append(setting)
    return settings


def ensemble_predict(logits_list):
    total = None
    count = 0
    for logits in logits_list:
        logits = np.asarray(logits, dtype=np.float64)
        total = logits.copy() if total is None else total + logits
        count += 1
    return total / count


def ema_update(ema_params, params, decay=0.999):
    def one(a, p):
        a = np.asarray(a, dtype=np.float64)
        return a + (1 - decay) * (np.asarray(p, dtype=np.float64) - a)

    if isinstance(ema_params, (list, tuple)):
        return [one(a, p) for a, p in zip(ema_params, params)]
    return one(ema_params, params)


ALTERNATIVES = {
    "train.step_decay": step_decay,
    "train.cosine_decay": cosine_decay,
    "train.warmup": warmup,
    "train.one_cycle": one_cycle,
    "train.sgd_weight_decay_step": sgd_weight_decay_step,
    "train.early_stopping": early_stopping,
    "train.smooth_labels": smooth_labels,
    "train.stochastic_depth": stochastic_depth,
    "train.random_resized_crop": random_resized_crop,
    "train.cutout": cutout,
    "train.mixup": mixup,
    "train.cutmix": cutmix,
    "train.random_search": random_search,
    "train.ensemble_predict": ensemble_predict,
    "train.ema_update": ema_update,
}

EXTRA_ALTERNATIVES: dict = {}
