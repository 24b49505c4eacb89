"""Training recipes of Chapter 12 (§12.5): random hyper-parameter search, ensembles of models
and exponential moving averages of weights."""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, as_rng, check_real, check_size
from ..registry import algorithm
from ._regularization import Params, UpdatedParams, _matching

__all__ = ["random_search", "ensemble_predict", "ema_update"]

#: the most settings :func:`random_search` draws at once
MAX_TRIALS = 1_000_000


def _range_spec(name: str, spec: dict[str, Any]) -> tuple[float, float, bool]:
    unknown = set(spec) - {"low", "high", "log"}
    if unknown or "low" not in spec or "high" not in spec:
        raise ValueError(
            f"space[{name!r}] must be a list of choices or a dict with keys 'low', 'high' and "
            f"optionally 'log', got keys {sorted(spec)}"
        )
    low = check_real(spec["low"], f"space[{name!r}]['low']")
    high = check_real(spec["high"], f"space[{name!r}]['high']")
    log = spec.get("log", False)
    if not isinstance(log, (bool, np.bool_)):
        raise TypeError(f"space[{name!r}]['log'] must be True or False, got {log!r}")
    if low > high:
        raise ValueError(f"space[{name!r}] needs low <= high, got low={low}, high={high}")
    if log and low <= 0:
        raise ValueError(f"space[{name!r}] is log-uniform, so low must be > 0, got {low}")
    return low, high, bool(log)


# --------------------------------------------------------------------------------------------
# §12.5.1 random search
# --------------------------------------------------------------------------------------------
@algorithm("train.random_search", section="12.5.1", check="cvkit.train.checks:random_search")
def random_search(space: dict[str, Any], trials: int,
                  rng: np.random.Generator | int | None = None) -> list[dict[str, Any]]:
    r"""Draw ``trials`` independent hyper-parameter settings from a search space.

    Parameters
    ----------
    space : dict
        Maps each hyper-parameter name (a string) to either

        - a non-empty list (or tuple) of choices, drawn uniformly, or
        - a dict ``{"low": a, "high": b, "log": bool}`` (``log`` optional, default False): a
          real number uniform on [a, b], or log-uniform (:math:`\log v \sim U(\log a, \log b)`,
          a > 0) when ``log`` is true.
    trials : int
        Number of settings, 0 ≤ trials ≤ :data:`MAX_TRIALS` (10⁶).
    rng : numpy.random.Generator, int or None
        Source of randomness.

    Returns
    -------
    list of dict
        ``trials`` dicts with the keys of ``space`` (in its order); a choice is returned as the
        object in the list, a range value as a ``float``.

    Notes
    -----
    §12.5.1 (Bergstra & Bengio, 2012): unlike a grid, every trial tries a new value of
    *every* hyper-parameter, so the few that matter get ``trials`` distinct values instead of
    ``trials**(1/d)``. Scale-like parameters (learning rate, weight decay) belong on a log
    scale. The values are drawn name by name (all trials of the first name, then the next).

    Examples
    --------
    >>> space = {"lr": {"low": 1e-4, "high": 1e-1, "log": True}, "batch": [32, 64, 128]}
    >>> settings = random_search(space, 3, rng=0)
    >>> len(settings), sorted(settings[0]), all(1e-4 <= s["lr"] <= 1e-1 for s in settings)
    (3, ['batch', 'lr'], True)
    """
    if not isinstance(space, dict) or not space:
        raise TypeError(f"space must be a non-empty dict {{name: choices or range}}, got {type(space).__name__}")
    trials = check_size(trials, "trials", minimum=0, maximum=MAX_TRIALS)
    generator = as_rng(rng)
    columns: dict[str, list[Any]] = {}
    for name, spec in space.items():
        if not isinstance(name, str):
            raise TypeError(f"space keys must be hyper-parameter names (strings), got {name!r}")
        if isinstance(spec, dict):
            low, high, log = _range_spec(name, spec)
            if log:
                values = np.exp(generator.uniform(math.log(low), math.log(high), trials))
                values = np.clip(values, low, high)  # exp(log(b)) may round just past b
            else:
                values = generator.uniform(low, high, trials)
            columns[name] = [float(v) for v in values]
        elif isinstance(spec, (list, tuple)):
            if len(spec) == 0:
                raise ValueError(f"space[{name!r}] must list at least one choice")
            picks = generator.integers(0, len(spec), trials)
            columns[name] = [spec[i] for i in picks]
        else:
            raise TypeError(
                f"space[{name!r}] must be a list of choices or a dict {{'low', 'high', 'log'}}, "
                f"got {type(spec).__name__}"
            )
    return [{name: columns[name][t] for name in space} for t in range(trials)]


# --------------------------------------------------------------------------------------------
# §12.5.2 ensembles
# --------------------------------------------------------------------------------------------
@algorithm("train.ensemble_predict", section="12.5.2", check="cvkit.train.checks:ensemble_predict")
def ensemble_predict(logits_list: Sequence[ArrayLike] | ArrayLike) -> np.ndarray:
    r"""The ensemble's prediction: the mean of the members' logits.

    .. math:: \bar s(x) = \frac1M \sum_{m=1}^{M} s_m(x)

    Parameters
    ----------
    logits_list : list of array_like, or (M, ...) array_like
        The logits (class scores) of M >= 1 models on the same inputs, e.g. M arrays of shape
        (N, C); all of one shape.

    Returns
    -------
    float64 ndarray, the shape of one member's logits

    Notes
    -----
    §12.5.2: models trained from different random initialisations make different mistakes,
    and averaging their scores before the final ``argmax`` cancels part of them. (Averaging
    softmax probabilities is the other common choice; it is *not* this function.)

    Examples
    --------
    >>> import numpy as np
    >>> ensemble_predict([np.array([[2.0, 0.0]]), np.array([[0.0, 1.0]])])
    array([[1. , 0.5]])
    """
    if isinstance(logits_list, (list, tuple)):
        if len(logits_list) == 0:
            raise ValueError("logits_list must hold the logits of at least one model, got an empty list")
        members = [as_float_array(v, f"logits_list[{i}]") for i, v in enumerate(logits_list)]
        for i, member in enumerate(members[1:], start=1):
            if member.shape != members[0].shape:
                raise ValueError(
                    f"logits_list[{i}] must have the shape of logits_list[0] {members[0].shape}, got {member.shape}"
                )
        stack = np.stack(members)
    else:
        stack = as_float_array(logits_list, "logits_list")
        if stack.ndim < 1:
            raise ValueError("logits_list must be a list of arrays or an (M, ...) array, got a scalar")
    return stack.mean(axis=0)


# --------------------------------------------------------------------------------------------
# §12.5.3 exponential moving average
# --------------------------------------------------------------------------------------------
@algorithm("train.ema_update", section="12.5.3", check="cvkit.train.checks:ema_update")
def ema_update(ema_params: Params, params: Params, decay: float = 0.999) -> UpdatedParams:
    r"""One step of the exponential moving average of a model's weights (Polyak averaging).

    .. math:: \theta_{EMA} \leftarrow \beta\, \theta_{EMA} + (1 - \beta)\, \theta

    Parameters
    ----------
    ema_params : ndarray or list/tuple of ndarrays
        The running average θ_EMA.
    params : same structure as ``ema_params``
        The current weights θ of the model being trained.
    decay : float
        β in [0, 1]: the weight of the past (0.999 averages over roughly the last 1000 steps).

    Returns
    -------
    float64 ndarray, or a list/tuple of them (the container type of ``ema_params``)
        The new average (the inputs are not modified).

    Notes
    -----
    §12.5.3: a cheap ensemble in weight space; the average, not the last iterate, is used for
    testing. The averaging window is about 1/(1 − β) steps.

    Examples
    --------
    >>> import numpy as np
    >>> ema_update(np.array([1.0, 1.0]), np.array([0.0, 2.0]), decay=0.9)
    array([0.9, 1.1])
    """
    averages, current, rebuild = _matching(ema_params, params, ("ema_params", "params"))
    decay = check_real(decay, "decay")
    if not 0.0 <= decay <= 1.0:
        raise ValueError(f"decay must be in [0, 1], got {decay}")
    return rebuild([decay * a + (1.0 - decay) * p for a, p in zip(averages, current)])
