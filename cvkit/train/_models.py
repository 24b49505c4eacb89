"""A small NumPy network for Chapter 12's experiments (a teaching model, not public API).

Chapter 12 measures what each step of a training recipe is worth. It needs a model that
trains on the 8×8 digits (:func:`cvkit.data.digits`) in a fraction of a second, so that a
notebook can train dozens of them: a multi-layer perceptron with ReLU hidden layers, softmax
cross-entropy on (possibly soft) targets and plain mini-batch SGD, written with whole-batch
NumPy operations. Every step of the recipe is an option of :class:`Recipe`:

============================ ==========================================================
option                       what it does (and the cvkit function it uses)
============================ ==========================================================
``lr``, ``schedule``         constant, ``"step"`` (:func:`~cvkit.train.step_decay`, ÷10
                             after each third of the epochs), ``"cosine"``
                             (:func:`~cvkit.train.cosine_decay`) or ``"one_cycle"``
                             (:func:`~cvkit.train.one_cycle`); evaluated at every step
``warmup_epochs``            linear warm-up (:func:`~cvkit.train.warmup`) before the
                             step/cosine schedule
``weight_decay``             :func:`~cvkit.train.sgd_weight_decay_step` (all parameters)
``label_smoothing``          :func:`~cvkit.train.smooth_labels`
``dropout``                  inverted dropout on every hidden layer (drop probability)
``augment``                  any of ``"crop"`` (random resized crop of scale 0.7–1 back to
                             8×8), ``"cutout"`` (a 3×3 square), ``"mixup"``
                             (:func:`~cvkit.train.mixup`), ``"cutmix"``
                             (:func:`~cvkit.train.cutmix`)
``ema_decay``                an EMA of the weights (:func:`~cvkit.train.ema_update`),
                             returned next to the final weights
============================ ==========================================================

The building blocks are looked up through :func:`cvkit.registry.implementation`, so
``with cvkit.use("student"):`` trains with a student's schedules and updates.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal, overload

import numpy as np
from numpy.typing import ArrayLike

from .._threads import single_thread
from .._validation import as_rng
from ..registry import get, implementation
from ._augment import _crop_boxes, _resample_boxes

__all__ = [
    "Recipe", "TrainResult", "init_params", "forward", "predict", "accuracy", "cross_entropy", "train",
    "learning_rates", "split_validation", "BASELINE", "TUNED_LR", "RECIPE_STEPS", "RecipeRow", "recipe_table",
    "format_recipe_table",
]

_SIDE = 8  # the digits are 8×8


@dataclass(frozen=True)
class Recipe:
    """Everything that defines one training run (see the module docstring)."""

    hidden: tuple[int, ...] = (256,)
    epochs: int = 30
    batch_size: int = 32
    lr: float = 0.05
    schedule: str = "constant"
    warmup_epochs: float = 0.0
    weight_decay: float = 0.0
    label_smoothing: float = 0.0
    dropout: float = 0.0
    augment: tuple[str, ...] = ()
    ema_decay: float | None = None
    crop_scale: tuple[float, float] = (0.7, 1.0)
    cutout_size: int = 3
    mixup_alpha: float = 0.2
    cutmix_alpha: float = 1.0

    def but(self, **changes: Any) -> Recipe:
        """A copy with some options changed."""
        return replace(self, **changes)


@dataclass
class TrainResult:
    """Weights after training, their EMA (if asked for) and the training curves."""

    params: list[np.ndarray]
    ema_params: list[np.ndarray] | None
    step_loss: np.ndarray                        # training objective of every mini-batch
    epoch_loss: np.ndarray                       # its mean over each epoch
    val_loss: np.ndarray = field(default_factory=lambda: np.zeros(0))   # after each epoch
    val_accuracy: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lrs: np.ndarray = field(default_factory=lambda: np.zeros(0))        # lr of every step
    diverged: bool = False


def init_params(sizes: Sequence[int], rng: np.random.Generator | int | None) -> list[np.ndarray]:
    """He-initialised weights ``[W1, b1, W2, b2, ...]`` for layer sizes ``(in, h1, ..., out)``."""
    generator = as_rng(rng)
    params = []
    for fan_in, fan_out in zip(sizes[:-1], sizes[1:]):
        params.append(generator.standard_normal((fan_in, fan_out)) * np.sqrt(2.0 / fan_in))
        params.append(np.zeros(fan_out))
    return params


@overload
def forward(params: list[np.ndarray], X: ArrayLike, dropout: float = ...,
            rng: np.random.Generator | int | None = ..., cache: Literal[False] = ...) -> np.ndarray: ...


@overload
def forward(params: list[np.ndarray], X: ArrayLike, dropout: float = ...,
            rng: np.random.Generator | int | None = ..., *,
            cache: Literal[True]) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]: ...


def forward(params: list[np.ndarray], X: ArrayLike, dropout: float = 0.0,
            rng: np.random.Generator | int | None = None,
            cache: bool = False) -> np.ndarray | tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """Logits of the network; with ``dropout > 0`` (training) every hidden unit is dropped with
    that probability and the kept ones divided by 1 − dropout (inverted dropout). With
    ``cache`` also the activations and dropout masks that :func:`_backward` needs."""
    generator = as_rng(rng) if dropout > 0 else None
    h = np.asarray(X, dtype=np.float64)
    activations: list[np.ndarray] = [h]
    masks: list[np.ndarray] = []
    n_layers = len(params) // 2
    for k in range(n_layers):
        z = h @ params[2 * k] + params[2 * k + 1]
        if k == n_layers - 1:
            h = z
            break
        h = np.maximum(z, 0.0)
        if generator is not None:  # dropout > 0
            mask = (generator.random(h.shape) >= dropout) / (1.0 - dropout)
            h = h * mask
            masks.append(mask)
        activations.append(h)
    return (h, activations, masks) if cache else h


def predict(params: list[np.ndarray], X: ArrayLike) -> np.ndarray:
    """Class predictions (argmax of the logits, dropout off)."""
    return np.argmax(forward(params, X), axis=1)


def accuracy(params: list[np.ndarray], X: ArrayLike, y: ArrayLike) -> float:
    return float(np.mean(predict(params, X) == np.asarray(y)))


def _log_softmax(logits: np.ndarray) -> np.ndarray:
    shifted = logits - logits.max(axis=1, keepdims=True)
    return shifted - np.log(np.exp(shifted).sum(axis=1, keepdims=True))


def cross_entropy(logits: ArrayLike, targets: ArrayLike) -> float:
    """Mean cross-entropy of soft ``targets`` (N, C) (or integer labels) under the logits."""
    scores = np.asarray(logits, dtype=np.float64)
    truth = np.asarray(targets)
    if truth.ndim == 1:
        truth = np.eye(scores.shape[1])[truth]
    with np.errstate(all="ignore"):
        return float(-np.mean(np.sum(truth * _log_softmax(scores), axis=1)))


def _backward(params: list[np.ndarray], activations: list[np.ndarray], masks: list[np.ndarray],
              logits: np.ndarray, targets: np.ndarray) -> list[np.ndarray]:
    """Gradients of the mean cross-entropy with respect to ``params``."""
    probs = np.exp(_log_softmax(logits))
    delta = (probs - targets) / logits.shape[0]
    grads: list[np.ndarray] = [np.zeros(0)] * len(params)  # every entry is set below
    for k in range(len(params) // 2 - 1, -1, -1):
        a = activations[k]
        grads[2 * k] = a.T @ delta
        grads[2 * k + 1] = delta.sum(axis=0)
        if k > 0:
            delta = delta @ params[2 * k].T
            delta = delta * (activations[k] > 0)
            if masks:
                delta = delta * masks[k - 1]
    return grads


def _augment(X: np.ndarray, targets: np.ndarray, recipe: Recipe,
             generator: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Augment a batch of flattened 8×8 digits; returns the new batch and targets."""
    n = int(X.shape[0])
    images = X.reshape(n, _SIDE, _SIDE)
    if "crop" in recipe.augment:
        top, left, h, w = _crop_boxes(n, _SIDE, _SIDE, recipe.crop_scale, (3 / 4, 4 / 3), generator, attempts=10)
        images = _resample_boxes(images, top, left, h, w, _SIDE, _SIDE)
    if "cutout" in recipe.augment:
        s = recipe.cutout_size
        cy = generator.integers(0, _SIDE, n)[:, None, None] - s // 2
        cx = generator.integers(0, _SIDE, n)[:, None, None] - s // 2
        rows = np.arange(_SIDE)[None, :, None]
        cols = np.arange(_SIDE)[None, None, :]
        inside = (rows >= cy) & (rows < cy + s) & (cols >= cx) & (cols < cx + s)
        images = np.where(inside, 0.0, images)
    if "cutmix" in recipe.augment:
        images, targets, _ = implementation("train.cutmix")(images, targets, recipe.cutmix_alpha, rng=generator)
    if "mixup" in recipe.augment:
        images, targets, _ = implementation("train.mixup")(images, targets, recipe.mixup_alpha, rng=generator)
    return images.reshape(n, -1), targets


def _sgd_fast(params: list[np.ndarray], grads: list[np.ndarray], lr: float, weight_decay: float) -> list[np.ndarray]:
    shrink = 1.0 - lr * weight_decay
    return [shrink * p - lr * g for p, g in zip(params, grads)]


def _ema_fast(ema: list[np.ndarray], params: list[np.ndarray], decay: float) -> list[np.ndarray]:
    return [decay * a + (1.0 - decay) * p for a, p in zip(ema, params)]


def _building_block(algorithm_id: str, fast: Callable[..., Any]) -> Callable[..., Any]:
    """The active provider's implementation, or (for the reference) an unchecked fast twin:
    argument validation would cost more than the tiny matrix products of this model."""
    function = implementation(algorithm_id)
    return fast if function is get(algorithm_id).reference else function


def _schedule(name: str) -> Callable[..., Any]:
    """A schedule function that takes an array of steps (the reference does; a student's
    version that only takes numbers is called step by step)."""
    function = implementation(name)
    if function is get(name).reference:
        return function
    return lambda t, *args: np.array([function(float(v), *args) for v in np.ravel(t)])


def learning_rates(recipe: Recipe, steps_per_epoch: int) -> np.ndarray:
    """The learning rate of every optimisation step of ``recipe``."""
    total = recipe.epochs * steps_per_epoch
    t = np.arange(total, dtype=np.float64)
    if recipe.schedule == "one_cycle":
        return np.asarray(_schedule("train.one_cycle")(t, total, recipe.lr), dtype=np.float64)
    warm = int(round(recipe.warmup_epochs * steps_per_epoch))
    after = t[warm:] - warm
    if recipe.schedule == "constant":
        main = np.full(after.shape, recipe.lr)
    elif recipe.schedule == "cosine":
        main = _schedule("train.cosine_decay")(after / steps_per_epoch, max(1, -(-(total - warm) // steps_per_epoch)), recipe.lr)
    elif recipe.schedule == "step":
        # ÷10 after each third of the epochs
        main = _schedule("train.step_decay")(np.floor(after / steps_per_epoch), recipe.lr, 0.1, max(1, recipe.epochs // 3))
    else:
        raise ValueError(f"schedule must be 'constant', 'step', 'cosine' or 'one_cycle', got {recipe.schedule!r}")
    ramp = _schedule("train.warmup")(t[:warm], warm, recipe.lr) if warm else np.zeros(0)
    return np.concatenate([np.asarray(ramp, dtype=np.float64), np.asarray(main, dtype=np.float64)])


def train(X: ArrayLike, y: ArrayLike, recipe: Recipe = Recipe(), rng: np.random.Generator | int | None = None,
          X_val: ArrayLike | None = None, y_val: ArrayLike | None = None, classes: int = 10) -> TrainResult:
    """Train the network on ``X`` (N, 64), labels ``y`` with ``recipe``.

    With ``X_val``/``y_val`` the validation loss and accuracy are recorded after each epoch.
    A run whose loss becomes non-finite stops and is marked ``diverged`` (its curves are
    padded with NaN).
    """
    generator = as_rng(rng)
    X = np.asarray(X, dtype=np.float64)
    y = np.asarray(y)
    n = X.shape[0]
    params = init_params((X.shape[1],) + tuple(recipe.hidden) + (classes,), generator)
    ema = [p.copy() for p in params] if recipe.ema_decay is not None else None
    targets_all = implementation("train.smooth_labels")(y, classes, recipe.label_smoothing)
    steps_per_epoch = -(-n // recipe.batch_size)
    total = recipe.epochs * steps_per_epoch
    step_loss = np.full(total, np.nan)
    lrs = learning_rates(recipe, steps_per_epoch)
    val_loss: list[float] = []
    val_acc: list[float] = []
    sgd = _building_block("train.sgd_weight_decay_step", _sgd_fast)
    ema_update = _building_block("train.ema_update", _ema_fast)
    step = 0
    diverged = False
    with np.errstate(all="ignore"), single_thread():
        for epoch in range(recipe.epochs):
            order = generator.permutation(n)
            for start in range(0, n, recipe.batch_size):
                batch = order[start: start + recipe.batch_size]
                xb, tb = X[batch], targets_all[batch]
                if recipe.augment:
                    xb, tb = _augment(xb, tb, recipe, generator)
                logits, activations, masks = forward(params, xb, recipe.dropout, generator, cache=True)
                loss = -np.mean(np.sum(tb * _log_softmax(logits), axis=1))
                step_loss[step] = loss
                if not np.isfinite(loss) or not np.all(np.isfinite(logits)):
                    diverged = True
                    break
                grads = _backward(params, activations, masks, logits, tb)
                lr = lrs[step]
                params = sgd(params, grads, lr, recipe.weight_decay)
                if ema is not None:
                    ema = ema_update(ema, params, recipe.ema_decay)
                step += 1
            if X_val is not None:
                logits = forward(params, X_val)
                truth = np.asarray(y_val)
                val_loss.append(cross_entropy(logits, truth) if not diverged else np.nan)
                val_acc.append(float(np.mean(np.argmax(logits, axis=1) == truth)) if not diverged else np.nan)
            if diverged:
                break
    if X_val is not None:
        val_loss += [np.nan] * (recipe.epochs - len(val_loss))
        val_acc += [np.nan] * (recipe.epochs - len(val_acc))
    with np.errstate(all="ignore"):
        epoch_loss = np.array([np.mean(step_loss[e * steps_per_epoch:(e + 1) * steps_per_epoch])
                               for e in range(recipe.epochs)])
    return TrainResult(params, ema, step_loss, epoch_loss, np.array(val_loss), np.array(val_acc), lrs, diverged)


# --------------------------------------------------------------------------------------------
# the recipe table
# --------------------------------------------------------------------------------------------
#: the starting point of the recipe table: a plain network and plain SGD at a constant rate
BASELINE = Recipe()


def _twice_as_long(recipe: Recipe) -> dict[str, Any]:
    return {"epochs": 2 * recipe.epochs}


#: the learning rate the sweep of the chapter selects on a validation split of the training
#: set (``benchmarks/recipe_table.py`` repeats the sweep and checks it)
TUNED_LR = 1.0

#: the steps of the recipe table: (label, changes to the recipe — a dict, or a function of the
#: recipe returning one —, members of the test-time ensemble, carried into the rows below?).
#: The training recipe is built up step by step, in the order of Karpathy's recipe
#: (§12.5.4); the augmentations are alternatives, each tried alone on the recipe above them
#: and not carried forward (stacking all of them is not a recipe anybody uses).
RECIPE_STEPS: tuple[tuple[str, dict[str, Any] | Callable[[Recipe], dict[str, Any]], int, bool], ...] = (
    ("baseline: plain SGD, constant lr 0.05", {}, 1, True),
    ("+ learning rate from the sweep (constant lr 1.0)", {"lr": TUNED_LR}, 1, True),
    ("+ warm-up (2 epochs) and cosine decay", {"schedule": "cosine", "warmup_epochs": 2.0}, 1, True),
    ("+ weight decay λ = 5e-4", {"weight_decay": 5e-4}, 1, True),
    ("+ label smoothing ε = 0.1", {"label_smoothing": 0.1}, 1, True),
    ("+ dropout 0.2", {"dropout": 0.2}, 1, True),
    ("+ twice as many epochs", _twice_as_long, 1, True),
    ("(alone) + random resized crop, scale 0.7–1", {"augment": ("crop",)}, 1, False),
    ("(alone) + cutout 3×3", {"augment": ("cutout",)}, 1, False),
    ("(alone) + mixup α = 0.2", {"augment": ("mixup",)}, 1, False),
    ("(alone) + cutmix α = 1", {"augment": ("cutmix",)}, 1, False),
    ("+ EMA of the weights, β = 0.99", {"ema_decay": 0.99}, 1, True),
    ("+ ensemble of 5 networks (averaged logits)", {}, 5, True),
)


@dataclass
class RecipeRow:
    """One row of the recipe table: the recipe trained and its accuracies over the seeds."""

    label: str
    recipe: Recipe
    members: int
    carried: bool
    test: np.ndarray
    train: np.ndarray

    def mean_std(self, which: str = "test") -> tuple[float, float]:
        values = getattr(self, which)
        return float(values.mean()), (float(values.std(ddof=1)) if values.size > 1 else 0.0)


def split_validation(X: np.ndarray, y: ArrayLike, fraction: float = 0.2,
                     seed: int = 12) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """A fixed stratified split of a training set into ``(train, validation)`` pairs: the
    data on which hyper-parameters are chosen, so that the test set is never used for it."""
    generator = np.random.default_rng(seed)
    labels = np.asarray(y)
    held = np.zeros(labels.size, dtype=bool)
    for label in np.unique(labels):
        members = np.flatnonzero(labels == label)
        held[generator.choice(members, size=int(round(fraction * members.size)), replace=False)] = True
    return (X[~held], labels[~held]), (X[held], labels[held])


def _evaluate_logits(result: TrainResult, X: ArrayLike) -> np.ndarray:
    weights = result.ema_params if result.ema_params is not None else result.params
    return forward(weights, X)


def recipe_table(train_set: tuple[np.ndarray, np.ndarray], test_set: tuple[np.ndarray, np.ndarray],
                 seeds: Sequence[int] = (0, 1, 2, 3, 4), steps: Sequence[tuple[Any, ...]] = RECIPE_STEPS,
                 baseline: Recipe = BASELINE, epochs: int | None = None,
                 progress: Callable[[], object] | None = None) -> list[RecipeRow]:
    """Measure the recipe table (see :data:`RECIPE_STEPS`).

    For each row and seed the network is trained from seed ``1000·seed + member`` (so every
    row sees the same initialisations and mini-batch orders); the ensemble row trains
    ``members`` networks per seed and averages their logits
    (:func:`~cvkit.train.ensemble_predict`); a recipe with an EMA is evaluated with the EMA
    weights. ``epochs`` overrides the baseline's number of epochs (quick versions).
    ``progress()`` is called after each network trained.

    Returns
    -------
    list of RecipeRow
    """
    (X_train, y_train), (X_test, y_test) = train_set, test_set
    with single_thread():
        return _recipe_rows(X_train, y_train, X_test, y_test, seeds, steps, baseline, epochs, progress)


def _recipe_rows(X_train: np.ndarray, y_train: np.ndarray, X_test: np.ndarray, y_test: np.ndarray,
                 seeds: Sequence[int], steps: Sequence[tuple[Any, ...]], baseline: Recipe, epochs: int | None,
                 progress: Callable[[], object] | None) -> list[RecipeRow]:
    current = baseline if epochs is None else baseline.but(epochs=epochs)
    current_members = 1
    average = implementation("train.ensemble_predict")
    rows = []
    for label, changes, members, carry in steps:
        if callable(changes):
            changes = changes(current)
        recipe = current.but(**changes)
        members = max(members, current_members)
        test, train_acc = [], []
        for seed in seeds:
            test_logits, train_logits = [], []
            for member in range(members):
                result = train(X_train, y_train, recipe, rng=1000 * seed + member)
                test_logits.append(_evaluate_logits(result, X_test))
                train_logits.append(_evaluate_logits(result, X_train))
                if progress is not None:
                    progress()
            test.append(float(np.mean(np.argmax(average(test_logits), axis=1) == y_test)))
            train_acc.append(float(np.mean(np.argmax(average(train_logits), axis=1) == y_train)))
        rows.append(RecipeRow(label, recipe, members, carry, np.array(test), np.array(train_acc)))
        if carry:
            current, current_members = recipe, members
    return rows


def format_recipe_table(rows: Sequence[RecipeRow]) -> str:
    """The table as Markdown: test accuracy (mean ± sample std over the seeds); its change
    from the last carried row above, as the mean ± std of the per-seed differences (every
    row uses the same seeds, so a step whose change is several std away from 0 helped or hurt
    consistently); and the training accuracy (the gap between the two is the generalisation
    gap)."""
    seeds = rows[0].test.size
    lines = [f"| step | test accuracy (mean ± std, {seeds} seeds) | change (paired) | train accuracy |",
             "|---|---|---|---|"]
    reference = None
    for row in rows:
        mean, std = row.mean_std("test")
        if reference is None:
            change = ""
        else:
            diff = 100 * (row.test - reference)
            change = f"{diff.mean():+.2f} ± {diff.std(ddof=1) if diff.size > 1 else 0.0:.2f}"
        label = row.label.strip() if row.carried else f"&emsp;{row.label.strip()}"
        lines.append(f"| {label} | {100 * mean:.2f} ± {100 * std:.2f} % | {change} | {100 * row.train.mean():.2f} % |")
        if row.carried:
            reference = row.test
    return "\n".join(lines)
