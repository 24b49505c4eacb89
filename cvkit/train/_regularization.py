"""Regularisation of Chapter 12 (§12.3): SGD with weight decay, early stopping, label
smoothing and stochastic depth. (Dropout, §12.3.6, is a layer: ``nn.dropout_*``.)
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TypeAlias

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, as_labels, as_rng, check_allocation, check_bool, check_int, check_real
from ..registry import algorithm

__all__ = ["sgd_weight_decay_step", "early_stopping", "smooth_labels", "stochastic_depth"]

#: a set of parameters: one array, or a list or tuple of them
Params: TypeAlias = ArrayLike | Sequence[ArrayLike]
#: what the updates return: new float64 arrays in the caller's container
UpdatedParams: TypeAlias = np.ndarray | list[np.ndarray] | tuple[np.ndarray, ...]
Rebuild: TypeAlias = Callable[[list[np.ndarray]], UpdatedParams]


def _parameter_list(value: Params, name: str) -> tuple[list[np.ndarray], Rebuild]:
    """A parameter set as a list of float64 arrays, and how to rebuild the caller's container.

    A NumPy array (or a number) is one parameter; a list or tuple holds one parameter per item.
    """
    if isinstance(value, (list, tuple)):
        if len(value) == 0:
            raise ValueError(f"{name} must hold at least one parameter array, got an empty {type(value).__name__}")
        arrays = [as_float_array(v, f"{name}[{i}]", allow_empty=True) for i, v in enumerate(value)]
        kind = type(value)

        def rebuild(items: list[np.ndarray]) -> UpdatedParams:
            return kind(items)

        return arrays, rebuild
    return [as_float_array(value, name, allow_empty=True)], (lambda items: items[0])


def _matching(params: Params, grads: Params,
              names: tuple[str, str]) -> tuple[list[np.ndarray], list[np.ndarray], Rebuild]:
    first, rebuild = _parameter_list(params, names[0])
    second, _ = _parameter_list(grads, names[1])
    if isinstance(params, (list, tuple)) != isinstance(grads, (list, tuple)) or len(first) != len(second):
        raise ValueError(
            f"{names[1]} must have the structure of {names[0]} (one array per parameter), got "
            f"{len(second)} array(s) for {len(first)} parameter(s)"
        )
    for i, (p, g) in enumerate(zip(first, second)):
        if p.shape != g.shape:
            where = f"[{i}]" if isinstance(params, (list, tuple)) else ""
            raise ValueError(f"{names[1]}{where} must have the shape of {names[0]}{where} {p.shape}, got {g.shape}")
    return first, second, rebuild


# --------------------------------------------------------------------------------------------
# §12.3.3 weight decay
# --------------------------------------------------------------------------------------------
@algorithm("train.sgd_weight_decay_step", section="12.3.3", check="cvkit.train.checks:sgd_weight_decay_step")
def sgd_weight_decay_step(params: Params, grads: Params, lr: float, weight_decay: float) -> UpdatedParams:
    r"""One plain SGD step with weight decay: shrink the parameters, then step down the gradient.

    .. math:: \theta^{(i+1)} = (1 - \mathrm{lr}\cdot\lambda)\,\theta^{(i)}
              - \mathrm{lr}\cdot\nabla_\theta L_{task}(\theta^{(i)})

    Parameters
    ----------
    params : ndarray or list/tuple of ndarrays
        The parameters θ (one array, or one array per parameter tensor of a model).
    grads : same structure as ``params``
        The gradients of the task loss at θ (shapes must match).
    lr : float
        Learning rate, >= 0.
    weight_decay : float
        λ >= 0.

    Returns
    -------
    float64 ndarray, or a list/tuple of them (the container type of ``params``)
        The updated parameters, new arrays (the inputs are not modified).

    Notes
    -----
    §12.3.3: this is gradient descent on :math:`L_{task} + \tfrac{\lambda}{2}\|\theta\|^2`;
    the gradient of the penalty is λθ, and both terms are evaluated at the *old* θ. (With the
    penalty written :math:`\lambda\|\theta\|^2` its gradient is 2λθ; the convention here, as in
    PyTorch's ``SGD(weight_decay=λ)``, is the update above.) Shrinking *after* the gradient
    step, :math:`(1 - \mathrm{lr}\lambda)(\theta - \mathrm{lr}\,g)`, is a different method.

    Examples
    --------
    >>> import numpy as np
    >>> sgd_weight_decay_step(np.array([1.0, -2.0]), np.array([0.5, 0.5]), lr=0.1, weight_decay=0.01)
    array([ 0.949, -2.048])
    >>> w, b = sgd_weight_decay_step([np.ones((2, 2)), np.zeros(2)], [np.ones((2, 2)), np.ones(2)], 0.5, 0.2)
    >>> float(w[0, 0]), float(b[0])
    (0.4, -0.5)
    """
    thetas, gradients, rebuild = _matching(params, grads, ("params", "grads"))
    lr = check_real(lr, "lr", nonnegative=True)
    weight_decay = check_real(weight_decay, "weight_decay", nonnegative=True)
    shrink = 1.0 - lr * weight_decay
    return rebuild([shrink * theta - lr * g for theta, g in zip(thetas, gradients)])


# --------------------------------------------------------------------------------------------
# §12.3.4 early stopping
# --------------------------------------------------------------------------------------------
@algorithm("train.early_stopping", section="12.3.4", check="cvkit.train.checks:early_stopping")
def early_stopping(val_losses: ArrayLike, patience: int) -> int | None:
    r"""The epoch at which early stopping halts training, or ``None`` if it never does.

    Training stops after epoch i, the first with

    .. math:: i - \operatorname{argmin}(\text{val\_losses}[0..i]) \ge \text{patience},

    i.e. once ``patience`` epochs have passed without a new best validation loss.

    Parameters
    ----------
    val_losses : (E,) array_like
        Validation loss after each epoch 0 … E − 1 (no NaN; +inf allowed for a diverged run).
    patience : int
        Number of epochs without improvement to tolerate, >= 1.

    Returns
    -------
    int or None
        The epoch index i (0-based) at which to stop, or ``None`` if the condition never
        holds within the E epochs given. The weights to keep are those of the best epoch,
        ``argmin(val_losses[:i + 1])``.

    Notes
    -----
    §12.3.4. ``argmin`` returns the *first* minimum: a later loss that only ties the best
    one is no improvement and does not reset the count.

    Examples
    --------
    >>> early_stopping([1.0, 0.8, 0.7, 0.75, 0.72, 0.71, 0.9], patience=3)
    5
    >>> early_stopping([1.0, 0.8, 0.8, 0.8], patience=2)
    3
    >>> early_stopping([3.0, 2.0, 1.0], patience=2) is None
    True
    """
    losses = as_float_array(val_losses, "val_losses", ndim=1, finite=False)
    if np.isnan(losses).any():
        raise ValueError("val_losses must not contain NaN (use inf for a diverged epoch)")
    patience = check_int(patience, "patience", minimum=1)
    n = losses.size
    previous_best = np.concatenate(([np.inf], np.minimum.accumulate(losses)[:-1]))
    improved = losses < previous_best
    improved[0] = True                                     # epoch 0 is the first best
    best_index = np.maximum.accumulate(np.where(improved, np.arange(n), 0))
    stop = np.flatnonzero(np.arange(n) - best_index >= patience)
    return int(stop[0]) if stop.size else None


# --------------------------------------------------------------------------------------------
# §12.3.5 label smoothing
# --------------------------------------------------------------------------------------------
def _labels(y: ArrayLike, classes: int) -> tuple[np.ndarray, int]:
    classes = check_int(classes, "classes", minimum=2)
    return as_labels(y, "y", classes=classes, integral_floats=True), classes


@algorithm("train.smooth_labels", section="12.3.5", check="cvkit.train.checks:smooth_labels")
def smooth_labels(y: ArrayLike, classes: int, eps: float) -> np.ndarray:
    r"""Smoothed one-hot targets: 1 − ε on the true class, ε/(C − 1) on every other class.

    .. math:: t_{n,c} = \begin{cases} 1 - \varepsilon & c = y_n \\
              \varepsilon / (C - 1) & c \ne y_n \end{cases}

    Parameters
    ----------
    y : (N,) array_like of int
        Class labels in ``0 … classes − 1`` (N may be 0).
    classes : int
        Number of classes C >= 2; the targets, N·C values, must fit in 2 GiB (cvkit's limit
        for one array), else ``ValueError`` naming ``classes``.
    eps : float
        ε in [0, 1]; 0 gives the one-hot targets.

    Returns
    -------
    (N, C) float64 ndarray
        The targets; every row sums to 1.

    Notes
    -----
    §12.3.5 defines the smoothing mass on the *other* classes, ε/(C − 1) each. PyTorch's
    ``CrossEntropyLoss(label_smoothing=ε)`` spreads ε over *all* C classes instead
    (1 − ε + ε/C on the true class, ε/C elsewhere): the same idea with a slightly different ε.

    Examples
    --------
    >>> smooth_labels([2, 0], classes=3, eps=0.1)
    array([[0.05, 0.05, 0.9 ],
           [0.9 , 0.05, 0.05]])
    """
    labels, classes = _labels(y, classes)
    eps = check_real(eps, "eps")
    if not 0.0 <= eps <= 1.0:
        raise ValueError(f"eps must be in [0, 1], got {eps}")
    check_allocation((labels.size, classes), "classes", what="the targets")
    targets = np.full((labels.size, classes), eps / (classes - 1))
    targets[np.arange(labels.size), labels] = 1.0 - eps
    return targets


# --------------------------------------------------------------------------------------------
# §12.3.7 stochastic depth
# --------------------------------------------------------------------------------------------
@algorithm("train.stochastic_depth", section="12.3.7", check="cvkit.train.checks:stochastic_depth")
def stochastic_depth(x: ArrayLike, residual: ArrayLike, survival_prob: float, training: bool,
                     rng: np.random.Generator | int | None = None) -> np.ndarray:
    r"""A residual connection whose branch is dropped at random, one coin per sample.

    Training: :math:`y_n = x_n + b_n\,F(x_n)` with :math:`b_n \sim \mathrm{Bernoulli}(p)`
    drawn once per sample n (the whole branch of that sample is kept or dropped).
    Evaluation: :math:`y = x + p\,F(x)`, the expectation of the training output.

    Parameters
    ----------
    x : (N, ...) array_like
        The block's input (its identity path), N samples along the first axis.
    residual : array_like, shape of ``x``
        The output F(x) of the block's residual branch.
    survival_prob : float
        p in [0, 1], the probability of keeping the branch.
    training : bool
        Draw the coins (True) or return the expectation (False).
    rng : numpy.random.Generator, int or None
        Source of randomness (only used when ``training``).

    Returns
    -------
    float64 ndarray, shape of ``x``

    Notes
    -----
    §12.3.7 (Huang et al., 2016): during training a dropped block shortens the network for
    that sample; at test time the full network runs with each branch scaled by its survival
    probability, so that train and test outputs agree on average. (torchvision's
    ``stochastic_depth`` uses the *inverted* convention instead: the kept branch is divided by
    p in training and left unscaled at test time.) The coins are
    ``rng.random(N) < survival_prob``.

    Examples
    --------
    >>> import numpy as np
    >>> x, r = np.zeros((4, 2)), np.ones((4, 2))
    >>> stochastic_depth(x, r, 0.8, training=False)[0]
    array([0.8, 0.8])
    >>> out = stochastic_depth(x, r, 0.5, training=True, rng=0)
    >>> sorted(set(out.ravel().tolist()))
    [0.0, 1.0]
    """
    identity = as_float_array(x, "x")
    branch = as_float_array(residual, "residual")
    if identity.ndim < 1:
        raise ValueError("x must have at least one dimension (the samples), got a scalar")
    if branch.shape != identity.shape:
        raise ValueError(f"residual must have the shape of x {identity.shape}, got {branch.shape}")
    p = check_real(survival_prob, "survival_prob")
    if not 0.0 <= p <= 1.0:
        raise ValueError(f"survival_prob must be in [0, 1], got {p}")
    check_bool(training, "training")
    generator = as_rng(rng)
    if not training:
        return identity + p * branch
    keep = generator.random(int(identity.shape[0])) < p
    return identity + np.where(keep.reshape((-1,) + (1,) * (identity.ndim - 1)), branch, 0.0)
