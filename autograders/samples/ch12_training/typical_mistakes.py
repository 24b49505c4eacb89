# Answer cells of the "typical mistakes" sample submission of ch12_training.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write (the off-by-one epoch of a cosine schedule, a
# warm-up that stops one step short of its target, PyTorch's label smoothing where the notes'
# is asked for, CutMix labels weighted by the side of the box, an EMA with its decay the wrong
# way round, dropout scaled the old way: kept units multiplied by p_keep instead of divided) and
# one exercise not attempted. Every other exercise keeps the correct solution.
# This file is data for the demo and its tests, not a module to import.

# %% cosine_decay_answer
@student("train.cosine_decay")
def cosine_decay(epoch, epochs, lr0, lr_final=0.0):
    """Cosine decay over the epochs 0 ... epochs - 1 (so it 'ends' one epoch early)."""
    return lr_final + 0.5 * (lr0 - lr_final) * (1 + math.cos(math.pi * epoch / (epochs - 1)))

# %% warmup_answer
@student("train.warmup")
def warmup(step, warmup_steps, lr_target, lr_start=0.0):
    """Warm-up written for a loop `for step in range(warmup_steps)`: its last value is (W-1)/W."""
    if warmup_steps == 0:
        return lr_target
    fraction = min(step, warmup_steps - 1) / warmup_steps
    return lr_start + (lr_target - lr_start) * fraction

# %% smooth_labels_answer
@student("train.smooth_labels")
def smooth_labels(y, classes, eps):
    """Label smoothing as in PyTorch's CrossEntropyLoss(label_smoothing=eps)."""
    onehot = np.eye(classes)[np.asarray(y, dtype=int)]
    return onehot * (1 - eps) + eps / classes

# %% cutmix_answer
@student("train.cutmix")
def cutmix(x, y_onehot, alpha=1.0, rng=None):
    """CutMix whose label weight is the fraction of the HEIGHT covered by the box."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y_onehot, dtype=float)
    rng = np.random.default_rng(rng)
    H, W = x.shape[-2:]
    lam = rng.beta(alpha, alpha)
    perm = rng.permutation(len(x))
    cut_h, cut_w = int(H * np.sqrt(1 - lam)), int(W * np.sqrt(1 - lam))
    cy, cx = rng.integers(0, H), rng.integers(0, W)
    y1, y2 = np.clip([cy - cut_h // 2, cy + cut_h // 2], 0, H)
    x1, x2 = np.clip([cx - cut_w // 2, cx + cut_w // 2], 0, W)
    out = x.copy()
    out[..., y1:y2, x1:x2] = x[perm][..., y1:y2, x1:x2]
    lam = 1 - (y2 - y1) / H
    return out, lam * y + (1 - lam) * y[perm], float(lam)

# %% ema_update_answer
@student("train.ema_update")
def ema_update(ema_params, params, decay=0.999):
    """Moving average with the decay on the NEW weights instead of the old average."""
    if isinstance(ema_params, (list, tuple)):
        return [ema_update(a, p, decay) for a, p in zip(ema_params, params)]
    return (1 - decay) * np.asarray(ema_params, dtype=float) + decay * np.asarray(params, dtype=float)

# %% dropout_forward_answer
@student("nn.dropout_forward")
def dropout_forward(x, p_keep, training, rng=None):
    """Old-style scaling: the kept units multiplied by p_keep instead of divided by it."""
    x = np.asarray(x, dtype=float)
    if not training:
        return x.copy(), {"x": x, "p_keep": p_keep, "training": training, "mask": np.ones(x.shape, dtype=bool)}
    mask = np.random.default_rng(rng).random(x.shape) < p_keep
    return x * mask * p_keep, {"x": x, "p_keep": p_keep, "training": training, "mask": mask}

# %% random_search_answer
@student("train.random_search")
def random_search(space, trials, rng=None):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()
