"""Learning-rate schedules of Chapter 12 (§12.2.3–12.2.6): step decay, cosine decay, linear
warm-up and the one-cycle policy.

Each schedule is a closed form of the epoch (or step) number: ``lr = schedule(t, ...)``. The
time ``t`` may be a single number (the result is a Python ``float``) or an array of them (the
result is a float64 array of the same shape, handy for plotting a whole schedule at once).
Times count from 0: epoch 0 is the first epoch, step 0 the first optimisation step.
"""
from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike

from .._docstrings import filler
from .._validation import check_int, check_real
from ..registry import algorithm

__all__ = ["step_decay", "cosine_decay", "warmup", "one_cycle"]

_docs = filler({"rates": "float or float64 ndarray\n        The learning rate(s) (a ``float`` for a scalar ``step``)."})


def _times(value: ArrayLike, name: str) -> tuple[np.ndarray, bool]:
    """``value`` (a number >= 0 or an array of them) as a float64 array, and whether it was a
    scalar."""
    if isinstance(value, (bool, np.bool_)) or isinstance(value, (str, bytes)) or value is None:
        raise TypeError(f"{name} must be a number >= 0 or an array of them, got {type(value).__name__} {value!r}")
    scalar = isinstance(value, (numbers.Real, np.integer, np.floating))
    array = np.asarray(value)
    if array.dtype == object or array.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be a real number >= 0 or an array of them, got dtype {array.dtype}")
    array = array.astype(np.float64)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite (found NaN or inf)")
    if np.any(array < 0):
        raise ValueError(f"{name} must be >= 0 (counted from 0), got {value!r}")
    return array, scalar or array.ndim == 0


def _result(values: np.ndarray, scalar: bool) -> float | np.ndarray:
    return float(values) if scalar else values


# --------------------------------------------------------------------------------------------
# §12.2.3 step decay
# --------------------------------------------------------------------------------------------
@algorithm("train.step_decay", section="12.2.3", check="cvkit.train.checks:step_decay")
def step_decay(epoch: ArrayLike, lr0: float, drop: float = 0.1, every: int = 30) -> float | np.ndarray:
    r"""Step decay: multiply the learning rate by ``drop`` every ``every`` epochs.

    .. math:: \mathrm{lr}_e = \mathrm{lr}_0 \cdot \mathrm{drop}^{\lfloor e / \mathrm{every} \rfloor}

    Parameters
    ----------
    epoch : int, float or array_like
        Epoch number(s) e >= 0, counted from 0 (epochs ``0 … every − 1`` use ``lr0``).
    lr0 : float
        Initial learning rate, >= 0.
    drop : float
        Factor applied at each drop, > 0 (0.1: divide by ten, as in ResNet training).
    every : int
        Number of epochs between drops, >= 1.

    Returns
    -------
    float or float64 ndarray
        The learning rate of each epoch (a ``float`` for a scalar ``epoch``).

    Notes
    -----
    §12.2.3: start high, then divide by a constant factor at fixed epochs. The first drop
    happens at the *start* of epoch ``every`` (the epoch number is floored, not rounded).

    Examples
    --------
    >>> [step_decay(e, 0.1, drop=0.1, every=30) for e in (0, 29, 30, 60)]
    [0.1, 0.1, 0.010000000000000002, 0.0010000000000000002]
    >>> step_decay([0, 1, 2, 3], 1.0, drop=0.5, every=2)
    array([1. , 1. , 0.5, 0.5])
    """
    e, scalar = _times(epoch, "epoch")
    lr0 = check_real(lr0, "lr0", nonnegative=True)
    drop = check_real(drop, "drop", positive=True)
    every = check_int(every, "every", minimum=1)
    return _result(lr0 * drop ** np.floor(e / every), scalar)


# --------------------------------------------------------------------------------------------
# §12.2.4 cosine decay
# --------------------------------------------------------------------------------------------
@algorithm("train.cosine_decay", section="12.2.4", check="cvkit.train.checks:cosine_decay")
def cosine_decay(epoch: ArrayLike, epochs: int, lr0: float, lr_final: float = 0.0) -> float | np.ndarray:
    r"""Cosine decay from ``lr0`` at epoch 0 to ``lr_final`` at epoch ``epochs``.

    .. math:: \mathrm{lr}_e = \mathrm{lr}_E + \tfrac12(\mathrm{lr}_0 - \mathrm{lr}_E)
              \Bigl(1 + \cos\frac{e\pi}{E}\Bigr), \qquad 0 \le e \le E

    Parameters
    ----------
    epoch : int, float or array_like
        Epoch number(s) e in ``[0, epochs]``; fractional epochs are allowed (a per-step
        schedule uses ``e = step / steps_per_epoch``).
    epochs : int
        E >= 1, the epoch at which the schedule reaches ``lr_final``.
    lr0 : float
        Learning rate at e = 0.
    lr_final : float
        Learning rate at e = E (default 0).

    Returns
    -------
    float or float64 ndarray
        The learning rate(s) (a ``float`` for a scalar ``epoch``).

    Notes
    -----
    §12.2.4. The formula is the notes' (and PyTorch's ``CosineAnnealingLR`` with
    ``T_max = E``, ``eta_min = lr_E``, for e <= E): ``lr0`` at e = 0, the mean of the two at
    e = E/2, ``lr_final`` at e = E. Beyond E the cosine would rise again, so ``epoch > epochs``
    raises ``ValueError``. If training runs for E epochs numbered 0 … E − 1 and should end
    at ``lr_final``, call it with ``epochs = E − 1``.

    Examples
    --------
    >>> [round(cosine_decay(e, 4, 1.0), 4) for e in range(5)]
    [1.0, 0.8536, 0.5, 0.1464, 0.0]
    >>> cosine_decay(10, 10, 0.1, lr_final=0.001)
    0.001
    """
    e, scalar = _times(epoch, "epoch")
    epochs = check_int(epochs, "epochs", minimum=1)
    lr0 = check_real(lr0, "lr0")
    lr_final = check_real(lr_final, "lr_final")
    if np.any(e > epochs):
        raise ValueError(f"epoch must be in [0, epochs] = [0, {epochs}], got {epoch!r}")
    return _result(lr_final + 0.5 * (lr0 - lr_final) * (1.0 + np.cos(e * np.pi / epochs)), scalar)


# --------------------------------------------------------------------------------------------
# §12.2.5 warm-up
# --------------------------------------------------------------------------------------------
@algorithm("train.warmup", section="12.2.5", check="cvkit.train.checks:warmup")
@_docs
def warmup(step: ArrayLike, warmup_steps: int, lr_target: float, lr_start: float = 0.0) -> float | np.ndarray:
    r"""Linear warm-up from ``lr_start`` at step 0 to ``lr_target`` at step ``warmup_steps``.

    .. math:: \mathrm{lr}_t = \mathrm{lr}_{start} + (\mathrm{lr}_{target} - \mathrm{lr}_{start})
              \frac{\min(t, W)}{W}

    Parameters
    ----------
    step : int, float or array_like
        Step (or epoch) number(s) t >= 0.
    warmup_steps : int
        W >= 0. From step W on the result is ``lr_target``. ``W = 0`` means no warm-up
        (``lr_target`` at every step).
    lr_target : float
        The learning rate reached at the end of the warm-up (where the main schedule starts).
    lr_start : float
        The learning rate at step 0 (default 0).

    Returns
    -------
    %(rates)s

    Notes
    -----
    §12.2.5: a low learning rate for the first steps lets randomly initialised weights settle
    before the large steps of the main schedule. The ramp *reaches* ``lr_target`` at step W
    exactly (a ramp over ``range(W)`` that stops at (W − 1)/W is a classic off-by-one).
    Chain it with a decay by switching schedules at step W.

    Examples
    --------
    >>> [warmup(t, 4, 0.1) for t in range(6)]
    [0.0, 0.025, 0.05, 0.07500000000000001, 0.1, 0.1]
    >>> warmup(0, 0, 0.1)
    0.1
    """
    t, scalar = _times(step, "step")
    warmup_steps = check_int(warmup_steps, "warmup_steps", minimum=0)
    lr_target = check_real(lr_target, "lr_target")
    lr_start = check_real(lr_start, "lr_start")
    if warmup_steps == 0:
        return _result(np.full(t.shape, lr_target), scalar)
    return _result(lr_start + (lr_target - lr_start) * (np.minimum(t, warmup_steps) / warmup_steps), scalar)


# --------------------------------------------------------------------------------------------
# §12.2.6 one-cycle
# --------------------------------------------------------------------------------------------
def _anneal_cos(start: float, end: float, pct: np.ndarray) -> np.ndarray:
    """Cosine from ``start`` (pct = 0) to ``end`` (pct = 1), as PyTorch writes it."""
    return end + (start - end) / 2.0 * (np.cos(np.pi * pct) + 1.0)


@algorithm("train.one_cycle", section="12.2.6", check="cvkit.train.checks:one_cycle")
@_docs
def one_cycle(step: ArrayLike, total_steps: int, lr_max: float, pct_start: float = 0.3, div: float = 25.0,
              final_div: float = 1e4) -> float | np.ndarray:
    r"""The two-phase one-cycle schedule, exactly as PyTorch's ``OneCycleLR``.

    With :math:`T` = ``total_steps``, :math:`p` = ``pct_start``, the initial rate
    :math:`\mathrm{lr}_0 = \mathrm{lr}_{max}/\mathrm{div}` and the final rate
    :math:`\mathrm{lr}_{min} = \mathrm{lr}_0/\mathrm{final\_div}`, and the end of the
    ramp-up :math:`s_1 = pT - 1`:

    .. math::
        \mathrm{lr}_t = \begin{cases}
        \mathrm{cos\_anneal}(\mathrm{lr}_0, \mathrm{lr}_{max}, t / s_1) & t \le s_1 \\
        \mathrm{cos\_anneal}(\mathrm{lr}_{max}, \mathrm{lr}_{min}, (t - s_1)/(T - 1 - s_1)) & t > s_1
        \end{cases}

    with :math:`\mathrm{cos\_anneal}(a, b, q) = b + \tfrac{a - b}{2}(1 + \cos \pi q)`.

    Parameters
    ----------
    step : int, float or array_like
        Number(s) t of optimisation steps taken, ``0 <= t <= total_steps`` (the value PyTorch's
        scheduler holds after ``t`` calls of ``scheduler.step()``).
    total_steps : int
        T >= 1, the number of steps of the whole cycle.
    lr_max : float
        The peak learning rate, > 0.
    pct_start : float
        Fraction p of the cycle spent increasing the rate, in [0, 1].
    div : float
        ``lr_max / div`` is the rate at step 0 (PyTorch's ``div_factor``), > 0; a ``div`` so
        small that ``lr_max / div`` overflows raises ``ValueError``.
    final_div : float
        ``lr_max / (div · final_div)`` is the rate at step T − 1 (``final_div_factor``), > 0;
        likewise it must not overflow.

    Returns
    -------
    %(rates)s

    Notes
    -----
    §12.2.6; equal to ``torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=lr_max,
    total_steps=T, pct_start=p, anneal_strategy="cos", div_factor=div,
    final_div_factor=final_div, three_phase=False)`` after ``step`` steps. The boundaries:
    step 0 gives ``lr_max/div``; the peak ``lr_max`` is reached at step pT − 1 (when that is
    an integer; otherwise the peak falls between two steps and no step gets ``lr_max``
    exactly); step T − 1 gives ``lr_max/(div·final_div)``; step T (allowed by PyTorch)
    continues the cosine one step past its end. When pT ≤ 1 the ramp-up has no step at all
    and the schedule starts in the ramp-down. Where PyTorch would divide by zero (a phase of
    zero length: pT = 1 at step 0, or p = 1 at step T) the result is the end value of that
    phase (``lr_max``, resp. ``lr_max/(div·final_div)``).

    Examples
    --------
    >>> T = 10
    >>> [round(one_cycle(t, T, 1.0, pct_start=0.3), 4) for t in (0, 1, 2, 5, 9)]
    [0.04, 0.52, 1.0, 0.6113, 0.0]
    """
    t, scalar = _times(step, "step")
    total_steps = check_int(total_steps, "total_steps", minimum=1)
    lr_max = check_real(lr_max, "lr_max", positive=True)
    pct_start = check_real(pct_start, "pct_start")
    if not 0.0 <= pct_start <= 1.0:
        raise ValueError(f"pct_start must be in [0, 1], got {pct_start}")
    div = check_real(div, "div", positive=True)
    final_div = check_real(final_div, "final_div", positive=True)
    if np.any(t > total_steps):
        raise ValueError(f"step must be in [0, total_steps] = [0, {total_steps}], got {step!r}")
    initial = lr_max / div
    minimum = initial / final_div
    if not np.isfinite(initial):
        raise ValueError(f"div = {div!r} is too small: lr_max / div overflows")
    if not np.isfinite(minimum):
        raise ValueError(f"final_div = {final_div!r} is too small: lr_max / (div · final_div) overflows")
    end_up = float(pct_start * total_steps) - 1.0   # the peak; PyTorch's first end_step
    end_down = float(total_steps - 1)
    up = t <= end_up
    with np.errstate(divide="ignore", invalid="ignore"):
        q_up = np.where(end_up > 0.0, t / end_up, 1.0)                 # zero-length ramp: its end
        q_down = np.where(end_down > end_up, (t - end_up) / (end_down - end_up), 1.0)
    lr = np.where(up, _anneal_cos(initial, lr_max, q_up), _anneal_cos(lr_max, minimum, q_down))
    return _result(lr, scalar)
