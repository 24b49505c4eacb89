"""Chapter 12 — regularisation and training recipes (§12.1–12.5 of the notes).

Learning-rate schedules (step and cosine decay, warm-up, one-cycle), regularisation (SGD
with weight decay, early stopping, label smoothing, stochastic depth), data augmentation
(random resized crop, cutout, mixup, cutmix) and recipes (random search, ensembles, EMA of
weights), and the chapter's measured exercise: ``train_digits``, a small CNN trained on the digits
with the reference recipe, graded by the accuracy it reaches on held-out digits. Dropout (§12.3.6) is a layer of :mod:`cvkit.nn`.

Functions that draw random numbers take ``rng`` (a ``numpy.random.Generator``, an int seed or
``None``); schedules accept a single step or an array of steps. Nothing modifies its inputs.

The private :mod:`cvkit.train._models` holds the small NumPy network the chapter trains on the
digits to measure what each step of a training recipe is worth (a teaching model, not part of
the public API).
"""
from ._schedules import step_decay, cosine_decay, warmup, one_cycle
from ._regularization import sgd_weight_decay_step, early_stopping, smooth_labels, stochastic_depth
from ._augment import random_resized_crop, cutout, mixup, cutmix
from ._recipes import random_search, ensemble_predict, ema_update
from ._digits import train_digits

__all__ = [
    "step_decay",
    "cosine_decay",
    "warmup",
    "one_cycle",
    "sgd_weight_decay_step",
    "early_stopping",
    "smooth_labels",
    "stochastic_depth",
    "random_resized_crop",
    "cutout",
    "mixup",
    "cutmix",
    "random_search",
    "ensemble_predict",
    "ema_update",
    "train_digits",
]
