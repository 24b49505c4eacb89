"""Checks of Chapter 12: the cases, comparators and mistake banks the grader uses.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference
function (``cvkit.train.checks:one_cycle`` grades ``train.one_cycle``).

*Deterministic functions* (schedules, the SGD step, early stopping, label smoothing,
ensembles, EMA) are compared value by value; their public cases are the boundaries where the
classic off-by-one mistakes show (the last epoch before a drop, the end of the warm-up, the
one-cycle peak at step pct_start·T − 1 and its end at T − 1, tied validation losses, ...)
and their hidden cases add random configurations, every option and the awkward values.

*Random functions* (stochastic depth, random resized crop, cutout, mixup, cutmix, random
search) are graded by properties that every correct draw has and by statistics of their
distribution, never draw by draw (``seeded=True``: the same seed must also reproduce the
same result). The inputs are built so that the properties can be read off the output:

- stochastic depth: a sample's output is exactly ``x + residual`` or ``x``;
- random resized crop: the input is a *plane* ``α + a·row + b·col`` per channel, which a
  bilinear resize of a crop keeps a plane; the slopes of the output give the crop's height
  and width (hence its area fraction and aspect ratio), a nearest-neighbour resize shows as
  steps;
- cutout: the input has no zeros, so the erased square is exactly where the output changed;
- mixup / cutmix: every sample of the batch is distinct, so each output sample tells which
  partner it was mixed with, with which λ, and (cutmix) which box was pasted;
- random search: thousands of trials per call, so the frequency of each choice and the
  distribution of each range (uniform or log-uniform) are measured.

Statistical tolerances are six standard errors of the difference of two independent draws
(a correct version fails with probability ~1e-9 per statistic); exact properties have
tolerance 0 (or round-off).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar

import numpy as np

from ..grading import Case, Check, Comparator, Drawn, Measure, Mismatch, Mistake, Statistics, close, mistake
from ..grading.casekit import variant
from ..grading.compare import binomial_variance_tolerance
from ..grading.casekit import argument as _arg
from ..grading.casekit import seed as _seed
from ..grading.casekit import size as _size
from ..grading.runtime.adapters import call_draws

__all__ = [
    "step_decay", "cosine_decay", "warmup", "one_cycle", "sgd_weight_decay_step", "early_stopping",
    "smooth_labels", "stochastic_depth", "random_resized_crop", "cutout", "mixup", "cutmix",
    "random_search", "ensemble_predict", "ema_update", "ExactValue", "StructuredStatistics",
]

_SQRT2 = math.sqrt(2.0)


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
@dataclass
class ExactValue(Comparator):
    """An integer or ``None`` that must equal the expected one (early stopping's epoch)."""

    what: str = "value"

    def describe(self) -> str:
        return f"the exact {self.what} (an int, or None)"

    def __call__(self, got, expected, case=None):
        def show(v):
            return "None" if v is None else repr(v)

        if expected is None:
            if got is None:
                return None
            return Mismatch(f"expected None (the condition never holds), got {show(got)}")
        if got is None:
            return Mismatch(f"expected {self.what} {expected}, got None (did you forget to `return` it?)")
        if isinstance(got, (bool, np.bool_)) or not isinstance(got, (numbers.Integral, np.integer)):
            if isinstance(got, (numbers.Real, np.floating)) and float(got) == int(expected):
                return Mismatch(f"expected the int {expected}, got the float {got!r}: return an int")
            return Mismatch(f"expected {self.what} {expected} (an int), got {type(got).__name__} {show(got)}")
        if int(got) != int(expected):
            return Mismatch(f"expected {self.what} {expected}, got {int(got)}")
        return None


@dataclass
class StructuredStatistics(Statistics):
    """Random outputs that are not a single array (a tuple, a list of dicts), judged like
    :class:`~cvkit.grading.Statistics`: ``structure(got, expected, case)`` returns a message
    when the output's form is wrong (``None`` if fine); ``statistics(output, case)`` returns
    named numbers of an output, ``tolerance(case)`` how far the candidate's may be from the
    reference draw's."""

    structure: Callable[[Any, Any, Any], str | None] = field(kw_only=True)
    heading: ClassVar[str] = "Properties or statistics differ from the expected ones"

    def describe(self) -> str:
        return "properties and statistics of the output (two correct versions may draw differently)"

    def __call__(self, got, expected, case=None):
        problem = self.structure(got, expected, case)
        if problem:
            return Mismatch(problem)
        return self.judge(got, expected, case)


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _round(value: float, digits: int = 4) -> float:
    return float(np.round(value, digits))


def _scalar_or_array(values, scalar_input):
    return float(values) if scalar_input else values


def _as_times(t):
    arr = np.asarray(t, dtype=np.float64)
    return arr, arr.ndim == 0


#: schedules: closed forms evaluated in another order agree to ~1e-15 relative
_SCHEDULE = close(rtol=1e-9, atol=1e-15)
#: parameter updates and averages
_UPDATE = close(rtol=1e-9, atol=1e-12, scaled=True)


# --------------------------------------------------------------------------------------------
# train.step_decay (§12.2.3)
# --------------------------------------------------------------------------------------------
def _step_with(exponent):
    def wrong(epoch, lr0, drop=0.1, every=30):
        e, scalar = _as_times(epoch)
        return _scalar_or_array(lr0 * drop ** exponent(e, every), scalar)
    return wrong


_sd_early = _step_with(lambda e, every: np.floor((e + 1) / every))
_sd_round = _step_with(lambda e, every: np.round(e / every))
_sd_ceil = _step_with(lambda e, every: np.ceil(e / every))
_sd_continuous = _step_with(lambda e, every: e / every)
_sd_every_epoch = _step_with(lambda e, every: e)


@mistake("divides by drop instead of multiplying",
         "drop is a factor < 1 that multiplies the rate: lr0 · drop ** k (0.1 divides the rate by ten)")
def _sd_divides(epoch, lr0, drop=0.1, every=30):
    e, scalar = _as_times(epoch)
    return _scalar_or_array(lr0 / drop ** np.floor(e / every), scalar)


def _step_hidden(rng):
    def every_():
        return _size(rng, 6, 40)

    def drop_():
        return float(rng.choice([0.1, 0.2, 0.5, _round(rng.uniform(0.05, 0.9), 3)]))

    def lr_():
        return _round(rng.uniform(0.005, 1.0))

    def at(k, lo, hi):  # an epoch k·every + r with r/every in (lo, hi), never on a boundary
        every = every_()
        while True:
            r = int(rng.integers(1, every))
            if lo < r / every < hi and r != every - 1:
                return k * every + r, every

    cases = []
    e, every = at(int(rng.integers(0, 4)), 0.05, 0.45)
    cases.append(Case((e, lr_()), {"drop": drop_(), "every": every}, "early in a stage (a fraction < 1/2 of `every`)"))
    e, every = at(int(rng.integers(1, 4)), 0.1, 0.45)
    cases.append(Case((e, lr_(), drop_(), every), {}, "drop and every given positionally"))
    e, every = at(int(rng.integers(0, 4)), 0.55, 0.95)
    cases.append(Case((e, lr_()), {"drop": drop_(), "every": every}, "late in a stage (a fraction > 1/2 of `every`)"))
    e, every = at(int(rng.integers(1, 4)), 0.55, 0.95)
    cases.append(Case((np.int64(e), lr_()), {"drop": drop_(), "every": every}, "late in a stage, epoch as numpy.int64"))
    every = every_()
    cases.append(Case((0, lr_()), {"drop": drop_(), "every": every}, "epoch 0"))
    every = every_()
    cases.append(Case((every, lr_()), {"drop": drop_(), "every": every}, "epoch = every: the first drop"))
    every = every_()
    k = int(rng.integers(3, 8))
    cases.append(Case((k * every, lr_()), {"drop": 0.5, "every": every}, f"epoch {k}·every: {k} drops"))
    e = _size(rng, 2, 9)
    cases.append(Case((e, lr_()), {"drop": drop_(), "every": 1}, "every = 1: a drop at every epoch"))
    e, every = at(int(rng.integers(0, 3)), 0.2, 0.45)
    cases.append(Case((e, lr_()), {"every": every}, "default drop 0.1"))
    cases.append(Case((_size(rng, 1, 28), lr_()), {}, "defaults (drop 0.1 every 30): before the first drop"))
    every = every_()
    cases.append(Case((2 * every - 1, lr_()), {"drop": drop_(), "every": every}, "the last epoch before the second drop"))
    return cases


step_decay = Check(
    public=[
        Case((10, 0.1), {}, "epoch 10, defaults (drop 0.1 every 30)"),
        Case((30, 0.1), {}, "epoch 30: the first drop"),
        Case((3, 1.0), {"drop": 0.5, "every": 1}, "every = 1: a drop at every epoch"),
        Case((55, 0.4), {"drop": 0.3, "every": 20}, "epoch 55, every 20: two drops so far"),
        Case((41, 0.1), {"drop": 0.5, "every": 20}, "epoch 41, every 20"),
        Case((29, 0.2), {"drop": 0.5, "every": 30}, "epoch 29: the last epoch before the first drop"),
    ],
    hidden=_step_hidden,
    compare=_SCHEDULE,
    mistakes=[
        Mistake("decays one epoch early ((epoch + 1) // every)", _sd_early,
                "Epochs count from 0: epochs 0 … every−1 keep lr0 and the first drop is at epoch `every`; "
                "use floor(epoch / every), not floor((epoch + 1) / every)"),
        Mistake("epoch / every rounded instead of floored", _sd_round,
                "Use the integer part: epoch // every (np.floor), not round(); the rate only drops once a whole stage is over"),
        Mistake("epoch / every rounded up (ceil)", _sd_ceil,
                "Use floor(epoch / every): with ceil the first drop happens right after epoch 0"),
        Mistake("exponent not floored (smooth exponential decay)", _sd_continuous,
                "Step decay is piecewise constant: lr0 · drop ** (epoch // every), with an integer exponent"),
        Mistake("drop applied at every epoch (every ignored)", _sd_every_epoch,
                "The exponent counts stages, not epochs: epoch // every"),
        _sd_divides,
    ],
)


# --------------------------------------------------------------------------------------------
# train.cosine_decay (§12.2.4)
# --------------------------------------------------------------------------------------------
def _cosine(e, E, lr0, lr_final):
    return lr_final + 0.5 * (lr0 - lr_final) * (1 + np.cos(e * np.pi / E))


@mistake("E − 1 in the denominator (off by one epoch)",
         "The cosine runs over E epochs: cos(e·π/E) with e = 0 … E, so that epoch E gives lr_final")
def _cd_off_by_one(epoch, epochs, lr0, lr_final=0.0):
    e, scalar = _as_times(epoch)
    with np.errstate(all="ignore"):
        return _scalar_or_array(_cosine(e, epochs - 1, lr0, lr_final), scalar)


@mistake("epochs counted from 1 (e + 1)",
         "Epoch 0 must give lr0: use cos(e·π/E) with the epoch as given, counted from 0")
def _cd_from_one(epoch, epochs, lr0, lr_final=0.0):
    e, scalar = _as_times(epoch)
    return _scalar_or_array(_cosine(e + 1, epochs, lr0, lr_final), scalar)


@mistake("decays to 0 (lr_final ignored)", "The schedule ends at lr_final: lr_E + ½(lr0 − lr_E)(1 + cos(eπ/E))")
def _cd_to_zero(epoch, epochs, lr0, lr_final=0.0):
    e, scalar = _as_times(epoch)
    return _scalar_or_array(_cosine(e, epochs, lr0, 0.0), scalar)


@mistake("lr_final added instead of blended",
         "Interpolate between the two rates: lr_E + ½(lr0 − lr_E)(1 + cos(eπ/E)) — the half-cosine multiplies (lr0 − lr_E)")
def _cd_added(epoch, epochs, lr0, lr_final=0.0):
    e, scalar = _as_times(epoch)
    return _scalar_or_array(lr_final + 0.5 * lr0 * (1 + np.cos(e * np.pi / epochs)), scalar)


@mistake("cos instead of ½(1 + cos)",
         "A plain cosine goes from +1 to −1 and ends below lr_final; ½(1 + cos(eπ/E)) goes from 1 to 0")
def _cd_plain_cos(epoch, epochs, lr0, lr_final=0.0):
    e, scalar = _as_times(epoch)
    return _scalar_or_array(lr_final + (lr0 - lr_final) * np.cos(e * np.pi / epochs), scalar)


def _cosine_hidden(rng):
    def E_():
        return _size(rng, 5, 120)

    def lrs():
        lr0 = _round(rng.uniform(0.01, 1.0))
        return lr0, _round(lr0 * rng.uniform(0.01, 0.3), 6)

    cases = []
    E = E_(); lr0, lrE = lrs()
    cases.append(Case((0, E, lr0), {"lr_final": lrE}, "epoch 0: lr0"))
    E = E_(); lr0, lrE = lrs()
    cases.append(Case((E, E, lr0), {"lr_final": lrE}, "epoch E: lr_final"))
    E = 2 * _size(rng, 3, 50); lr0, lrE = lrs()
    cases.append(Case((E // 2, E, lr0, lrE), {}, "epoch E/2: the mean of lr0 and lr_final (positional lr_final)"))
    E = E_(); lr0, lrE = lrs()
    cases.append(Case((E - 1, E, lr0), {"lr_final": lrE}, "epoch E − 1"))
    E = E_(); lr0, lrE = lrs()
    cases.append(Case((int(rng.integers(1, E)), E, lr0), {"lr_final": lrE}, "an epoch inside the schedule"))
    E = E_(); lr0, _ = lrs()
    cases.append(Case((int(rng.integers(1, E)), E, lr0), {}, "default lr_final = 0"))
    E = E_(); lr0, lrE = lrs()
    cases.append(Case((_round(rng.uniform(0.5, E - 0.5), 3), E, lr0), {"lr_final": lrE},
                      "fractional epoch (a per-step schedule)"))
    E = E_(); lr0, lrE = lrs()
    cases.append(Case((np.int64(int(rng.integers(1, E))), np.int64(E), lr0), {"lr_final": lrE}, "numpy integers"))
    cases.append(Case((1, 1, _round(rng.uniform(0.1, 1.0))), {"lr_final": 0.001}, "E = 1, epoch 1"))
    E = E_(); lr0, lrE = lrs()
    cases.append(Case((int(rng.integers(1, E)), E, lrE), {"lr_final": lr0}, "lr_final > lr0 (a rising schedule)"))
    return cases


cosine_decay = Check(
    public=[
        Case((0, 10, 0.1), {"lr_final": 0.001}, "epoch 0: lr0"),
        Case((5, 10, 0.1), {"lr_final": 0.001}, "epoch E/2: the mean of lr0 and lr_final"),
        Case((10, 10, 0.1), {"lr_final": 0.001}, "epoch E: lr_final"),
        Case((3, 8, 0.5), {"lr_final": 0.05}, "epoch 3 of 8"),
        Case((7, 20, 1.0), {}, "default lr_final = 0"),
    ],
    hidden=_cosine_hidden,
    compare=_SCHEDULE,
    mistakes=[_cd_off_by_one, _cd_from_one, _cd_to_zero, _cd_added, _cd_plain_cos],
)


# --------------------------------------------------------------------------------------------
# train.warmup (§12.2.5)
# --------------------------------------------------------------------------------------------
def _warm_with(fraction):
    def wrong(step, warmup_steps, lr_target, lr_start=0.0):
        t, scalar = _as_times(step)
        with np.errstate(all="ignore"):
            return _scalar_or_array(lr_start + (lr_target - lr_start) * fraction(t, warmup_steps), scalar)
    return wrong


_wu_never = _warm_with(lambda t, W: np.minimum(t, W - 1) / W)
_wu_no_clamp = _warm_with(lambda t, W: t / W)
_wu_ahead = _warm_with(lambda t, W: np.minimum(t + 1, W) / W)
_wu_floor = _warm_with(lambda t, W: np.minimum(t, W) // W)


@mistake("lr_start ignored (ramps up from 0)",
         "Ramp from lr_start: lr_start + (lr_target − lr_start) · min(step, W) / W")
def _wu_from_zero(step, warmup_steps, lr_target, lr_start=0.0):
    t, scalar = _as_times(step)
    with np.errstate(all="ignore"):
        return _scalar_or_array(lr_target * np.minimum(t, warmup_steps) / warmup_steps, scalar)


def _warmup_hidden(rng):
    def W_():
        return _size(rng, 3, 500)

    def lr_():
        return _round(rng.uniform(0.01, 1.0))

    cases = []
    W = W_()
    cases.append(Case((W, W, lr_()), {}, "step W: the end of the warm-up"))
    W = W_()
    cases.append(Case((W + _size(rng, 1, 100), W, lr_()), {}, "after the warm-up: lr_target"))
    W = W_()
    cases.append(Case((0, W, lr_()), {"lr_start": _round(rng.uniform(0.0001, 0.005), 6)}, "step 0: lr_start"))
    W = W_()
    cases.append(Case((int(rng.integers(1, W)), W, lr_()), {}, "inside the warm-up, lr_start = 0"))
    W = W_()
    cases.append(Case((int(rng.integers(1, W)), W, lr_(), _round(rng.uniform(0.001, 0.01), 6)), {},
                      "inside the warm-up, lr_start given positionally"))
    W = W_()
    cases.append(Case((W - 1, W, lr_()), {"lr_start": 0.001}, "step W − 1: one step before the target"))
    W = W_()
    cases.append(Case((2 * W, W, lr_()), {"lr_start": 0.002}, "long after the warm-up"))
    cases.append(Case((1, 1, lr_()), {}, "W = 1, step 1"))
    cases.append(Case((_size(rng, 0, 5), 0, lr_()), {}, "W = 0: no warm-up, lr_target from the start"))
    W = W_()
    cases.append(Case((np.int64(int(rng.integers(1, W))), np.int64(W), lr_()), {}, "numpy integers"))
    W = W_()
    cases.append(Case((_round(rng.uniform(0.5, W - 0.5), 2), W, lr_()), {"lr_start": 0.01},
                      "fractional step (a warm-up counted in epochs)"))
    return cases


warmup = Check(
    public=[
        Case((0, 5, 0.1), {}, "step 0: lr_start = 0"),
        Case((5, 5, 0.1), {}, "step W = 5: the end of the warm-up"),
        Case((8, 5, 0.1), {}, "step 8 > W: stays at lr_target"),
        Case((2, 4, 0.2), {"lr_start": 0.02}, "step 2 of 4, lr_start = 0.02"),
        Case((4, 4, 0.2), {"lr_start": 0.02}, "step W = 4 with lr_start"),
    ],
    hidden=_warmup_hidden,
    compare=_SCHEDULE,
    mistakes=[
        Mistake("warm-up never reaches the target (stops at (W − 1)/W)", _wu_never,
                "At step W (and after) the rate must equal lr_target: use min(step, W) / W, not min(step, W − 1) / W"),
        Mistake("integer division (//) in the ramp: stays at lr_start until step W", _wu_floor,
                "min(step, W) // W is 0 for every step before W: use true division, min(step, W) / W"),
        Mistake("no clamp: keeps rising after W", _wu_no_clamp,
                "After W steps the rate stays at lr_target: min(step, W) / W"),
        Mistake("one step ahead ((step + 1) / W)", _wu_ahead,
                "Step 0 must give lr_start: the fraction is min(step, W) / W with steps counted from 0"),
        _wu_from_zero,
    ],
)


# --------------------------------------------------------------------------------------------
# train.one_cycle (§12.2.6)
# --------------------------------------------------------------------------------------------
def _one_cycle_variant(step, total_steps, lr_max, pct_start=0.3, div=25.0, final_div=1e4, *,
                       peak=None, linear=False, final=None, end=None):
    t, scalar = _as_times(step)
    initial = lr_max / div
    minimum = initial / final_div if final is None else final(lr_max, div, final_div)
    end_up = float(pct_start * total_steps) - 1.0 if peak is None else peak(pct_start, total_steps)
    end_down = float(total_steps - 1) if end is None else end(total_steps)

    def anneal(a, b, q):
        return a + (b - a) * q if linear else b + (a - b) / 2.0 * (np.cos(np.pi * q) + 1.0)

    with np.errstate(all="ignore"):
        q_up = np.where(end_up > 0, t / end_up, 1.0)
        q_down = np.where(end_down > end_up, (t - end_up) / (end_down - end_up), 1.0)
        lr = np.where(t <= end_up, anneal(initial, lr_max, q_up), anneal(lr_max, minimum, q_down))
    return _scalar_or_array(lr, scalar)


_oc_late = variant(_one_cycle_variant, peak=lambda p, T: float(p * T))
_oc_int_peak = variant(_one_cycle_variant, peak=lambda p, T: float(int(p * T)) - 1.0)
_oc_linear = variant(_one_cycle_variant, linear=True)
_oc_final = variant(_one_cycle_variant, final=lambda m, d, f: m / f)
_oc_end_T = variant(_one_cycle_variant, end=lambda T: float(T))


def _one_cycle_hidden(rng):
    def lr_():
        return _round(rng.uniform(0.05, 2.0))

    def integer_peak():  # T and p with p·T an integer >= 3
        while True:
            T = _size(rng, 12, 400)
            p = float(rng.choice([0.2, 0.25, 0.3, 0.4, 0.5]))
            if float(p * T) == round(p * T) and p * T >= 3:
                return T, p

    cases = []
    T, p = integer_peak()
    cases.append(Case((int(round(p * T)) - 1, T, lr_()), {"pct_start": p}, "the peak, step pct_start·T − 1: lr_max"))
    T, p = integer_peak()
    cases.append(Case((int(round(p * T)), T, lr_()), {"pct_start": p}, "step pct_start·T: the first step down"))
    T, p = integer_peak()
    cases.append(Case((T - 1, T, lr_()), {"pct_start": p}, "step T − 1: the final rate lr_max/(div·final_div)"))
    T, p = integer_peak()
    cases.append(Case((int(rng.integers(1, int(round(p * T)) - 1)), T, lr_()), {"pct_start": p}, "inside the ramp-up"))
    T, p = integer_peak()
    cases.append(Case((int(rng.integers(int(round(p * T)) + 1, T - 1)), T, lr_(), p), {}, "inside the ramp-down (positional pct_start)"))
    T = _size(rng, 20, 200)
    cases.append(Case((int(rng.integers(1, T - 1)), T, lr_()), {}, "default pct_start = 0.3"))
    while True:  # p·T not an integer: the peak falls between two steps
        T, p = _size(rng, 11, 97), float(rng.choice([0.3, 0.35, 0.45]))
        if abs(p * T - round(p * T)) > 0.15 and p * T > 3:
            break
    peak = float(p * T) - 1.0
    cases.append(Case((int(math.floor(peak)) + 1, T, lr_()), {"pct_start": p}, "p·T not an integer: the step after the peak"))
    T, p = integer_peak()
    cases.append(Case((int(rng.integers(1, T - 1)), T, lr_()),
                      {"pct_start": p, "div": float(rng.choice([10.0, 5.0])), "final_div": float(rng.choice([100.0, 1e3]))},
                      "other div and final_div"))
    T, p = integer_peak()
    cases.append(Case((T, T, lr_()), {"pct_start": p}, "step T: one step past the end (PyTorch allows it)"))
    T, p = integer_peak()
    cases.append(Case((0, T, lr_()), {"pct_start": p, "div": 10.0}, "step 0: lr_max/div"))
    cases.append(Case((np.int64(_size(rng, 1, 5)), np.int64(8), lr_()), {"pct_start": 0.1}, "p·T < 1: no ramp-up step at all"))
    return cases


one_cycle = Check(
    public=[
        Case((0, 10, 1.0), {}, "step 0: lr_max/div"),
        Case((2, 10, 1.0), {}, "step 2 = pct_start·T − 1: the peak lr_max"),
        Case((5, 10, 1.0), {}, "step 5: inside the ramp-down"),
        Case((9, 10, 1.0), {}, "step T − 1: lr_max/(div·final_div)"),
        Case((2, 7, 0.5), {"pct_start": 0.3}, "T = 7: the peak pct_start·T − 1 = 1.1 is not a step"),
        Case((1, 10, 1.0), {}, "step 1: inside the ramp-up"),
    ],
    hidden=_one_cycle_hidden,
    compare=_SCHEDULE,
    mistakes=[
        Mistake("peak one step late (at pct_start·T)", _oc_late,
                "PyTorch's ramp-up ends at step pct_start·T − 1 (steps count from 0); use that float as the phase boundary"),
        Mistake("peak step truncated to an integer", _oc_int_peak,
                "Keep the phase boundary as the float pct_start·T − 1 (PyTorch does not round it)"),
        Mistake("linear ramps instead of cosine", _oc_linear,
                "Both phases are half-cosines: end + (start − end)/2 · (1 + cos(π·pct))"),
        Mistake("final rate lr_max/final_div (div forgotten)", _oc_final,
                "The final rate is the initial rate divided by final_div: lr_max / (div · final_div)"),
        Mistake("ramp-down ends at step T (not T − 1)", _oc_end_T,
                "The last step is T − 1: the ramp-down runs from pct_start·T − 1 to T − 1"),
    ],
)


# --------------------------------------------------------------------------------------------
# train.sgd_weight_decay_step (§12.3.3)
# --------------------------------------------------------------------------------------------
def _apply(params, grads, rule):
    if isinstance(params, (list, tuple)):
        out = [rule(np.asarray(p, dtype=np.float64), np.asarray(g, dtype=np.float64)) for p, g in zip(params, grads)]
        return type(params)(out)
    return rule(np.asarray(params, dtype=np.float64), np.asarray(grads, dtype=np.float64))


@mistake("weight decay applied after the gradient step",
         "Decay the OLD parameters: θ_new = (1 − lr·λ)·θ − lr·g, not (1 − lr·λ)·(θ − lr·g)")
def _wd_after(params, grads, lr, weight_decay):
    return _apply(params, grads, lambda p, g: (1 - lr * weight_decay) * (p - lr * g))


@mistake("decay not multiplied by the learning rate",
         "The shrink factor is (1 − lr·λ): the decay is a gradient step too and scales with lr")
def _wd_no_lr(params, grads, lr, weight_decay):
    return _apply(params, grads, lambda p, g: (1 - weight_decay) * p - lr * g)


@mistake("decay with the wrong sign (1 + lr·λ)",
         "Weight decay shrinks the parameters towards 0: multiply by (1 − lr·λ)")
def _wd_sign(params, grads, lr, weight_decay):
    return _apply(params, grads, lambda p, g: (1 + lr * weight_decay) * p - lr * g)


@mistake("decay doubled (1 − 2·lr·λ)",
         "The convention here is the notes' update (1 − lr·λ)θ (the penalty λ/2·‖θ‖²): no factor 2")
def _wd_twice(params, grads, lr, weight_decay):
    return _apply(params, grads, lambda p, g: (1 - 2 * lr * weight_decay) * p - lr * g)


@mistake("gradient added (ascent)", "Step against the gradient: − lr·g")
def _wd_ascent(params, grads, lr, weight_decay):
    return _apply(params, grads, lambda p, g: (1 - lr * weight_decay) * p + lr * g)


def _sgd_hidden(rng):
    def arr(*shape, scale=1.0):
        return np.round(rng.normal(0.0, scale, shape), 4)

    def lr_():  # never 0.5, where 'no lr' and 'doubled' coincide
        return float(rng.choice([_round(rng.uniform(0.05, 0.45), 3), _round(rng.uniform(0.55, 0.9), 3)]))

    def wd_():
        return _round(rng.uniform(0.01, 0.4), 4)

    cases = []
    n = _size(rng, 3, 9)
    cases.append(Case((arr(n), arr(n), lr_(), wd_()), {}, "a vector of parameters"))
    h, w = _size(rng, 2, 6), _size(rng, 2, 6)
    cases.append(Case((arr(h, w), arr(h, w), lr_(), wd_()), {}, "a weight matrix"))
    cases.append(Case(([arr(h, w), arr(w)], [arr(h, w), arr(w)], lr_(), wd_()), {}, "a list [W, b]"))
    cases.append(Case(((arr(4, 3), arr(3), arr(3, 2), arr(2)), (arr(4, 3), arr(3), arr(3, 2), arr(2)), lr_(), wd_()), {},
                      "a tuple of four parameter arrays (a two-layer network)"))
    cases.append(Case((arr(5), arr(5), lr_(), 0.0), {}, "weight_decay = 0: plain SGD"))
    cases.append(Case((arr(5), arr(5), 0.0, wd_()), {}, "lr = 0: nothing changes"))
    cases.append(Case((arr(6), np.zeros(6), lr_(), wd_()), {}, "zero gradient: only the decay"))
    cases.append(Case((arr(2, 3, scale=1e6), arr(2, 3, scale=1e6), lr_(), wd_()), {}, "±1e6 values"))
    cases.append(Case((arr(4, 2), arr(4, 2)), {"lr": lr_(), "weight_decay": wd_()}, "lr and weight_decay as keywords"))
    cases.append(Case(([np.float64(rng.normal())], [np.float64(rng.normal())], 1.0, 0.5), {}, "lr = 1, λ = 0.5, a single number"))
    return cases


sgd_weight_decay_step = Check(
    public=[
        Case((np.array([1.0, -2.0, 0.5]), np.array([0.5, 0.5, -1.0]), 0.1, 0.2), {}, "three parameters, lr 0.1, λ 0.2"),
        Case(([np.array([[1.0, -1.0], [2.0, 0.0]]), np.array([0.5, -0.5])],
              [np.array([[0.1, 0.2], [-0.3, 0.4]]), np.array([1.0, 1.0])], 0.25, 0.1), {}, "a list [W, b]"),
        Case((np.array([3.0, -3.0]), np.array([0.0, 0.0]), 0.3, 0.4), {}, "zero gradient: only the decay"),
    ],
    hidden=_sgd_hidden,
    compare=_UPDATE,
    mistakes=[_wd_after, _wd_no_lr, _wd_sign, _wd_twice, _wd_ascent],
)


# --------------------------------------------------------------------------------------------
# train.early_stopping (§12.3.4)
# --------------------------------------------------------------------------------------------
def _es_scan(val_losses, patience, *, improves, stop, none_ok=True, best_instead=False):
    losses = [float(v) for v in np.asarray(val_losses, dtype=np.float64)]
    best, best_i = math.inf, -1
    for i, loss in enumerate(losses):
        if best_i < 0 or improves(loss, best, losses, i):
            best, best_i = loss, i
        if stop(i, best_i, patience, losses):
            return best_i if best_instead else i
    return None if none_ok else len(losses) - 1


_es_ties = variant(_es_scan, improves=lambda l, b, ls, i: l <= b, stop=lambda i, b, p, ls: i - b >= p)
_es_late = variant(_es_scan, improves=lambda l, b, ls, i: l < b, stop=lambda i, b, p, ls: i - b > p)


@mistake("counts from the previous epoch, not from the best",
         "Compare with the best loss so far (argmin of the losses up to i), not with the loss of the epoch before")
def _es_previous(val_losses, patience):
    """Counts epochs since the loss last went down (from the previous epoch), not since the best."""
    losses = [float(v) for v in np.asarray(val_losses, dtype=np.float64)]
    count = 0
    for i in range(1, len(losses)):
        count = 0 if losses[i] < losses[i - 1] else count + 1
        if count >= patience:
            return i
    return None


_es_best = variant(_es_scan, improves=lambda l, b, ls, i: l < b, stop=lambda i, b, p, ls: i - b >= p, best_instead=True)
_es_never_none = variant(_es_scan, improves=lambda l, b, ls, i: l < b, stop=lambda i, b, p, ls: i - b >= p, none_ok=False)


def _curve(rng, n, noise=0.02):
    """A validation curve that first falls, then rises (overfitting), with noise."""
    e = np.arange(n)
    turn = rng.uniform(0.3, 0.7) * n
    clean = 1.0 / (1.0 + e) + 0.002 * np.maximum(e - turn, 0.0) ** 1.5 + 0.3
    return np.round(clean + rng.normal(0.0, noise, n), 3)


def _rising_tail(losses, length):
    """``losses`` followed by ``length`` strictly increasing losses above all of them."""
    losses = np.asarray(losses, dtype=np.float64)
    top = float(np.max(losses[np.isfinite(losses)])) if np.isfinite(losses).any() else 1.0
    return np.concatenate([losses, np.round(top + 0.01 * np.arange(1, length + 1), 3)])


def _es_hidden(rng):
    cases = []
    n, p = _size(rng, 25, 45), _size(rng, 3, 6)
    cases.append(Case((_rising_tail(_curve(rng, n), p + 2), p), {}, "a noisy U-shaped validation curve"))
    n, p = _size(rng, 25, 45), _size(rng, 4, 8)
    cases.append(Case((_rising_tail(_curve(rng, n, 0.005), p + 2).tolist(), p), {}, "a list of losses"))
    losses = _curve(rng, 30, 0.0)
    k = int(np.argmin(losses))
    losses[k + 1: k + 3] = losses[k]  # ties with the best loss right after it
    cases.append(Case((_rising_tail(losses[: k + 3], 5), 3), {}, "later losses equal to the best one (no improvement)"))
    best = _round(rng.uniform(0.4, 0.6), 3)
    ties = np.array([best + 0.3, best + 0.1, best, best, best + 0.05, best, best + 0.02])
    cases.append(Case((_rising_tail(ties, 5), 2), {}, "the best loss reached again (a tie is no improvement)"))
    losses = np.round(np.linspace(2.0, 0.5, _size(rng, 10, 30)), 4)
    cases.append(Case((losses, _size(rng, 2, 5)), {}, "a curve that keeps improving: never stops (None)"))
    p = _size(rng, 3, 5)
    down = np.round(np.linspace(1.0, 0.6, 8), 4)
    bumps = np.round(0.6 + np.array([0.05, 0.02, 0.04, 0.01, 0.03, 0.005, 0.02, 0.004, 0.03]), 4)
    cases.append(Case((_rising_tail(np.concatenate([down, bumps]), p + 2), p), {}, "small ups and downs above the best loss"))
    cases.append(Case((np.array([0.9, 0.8, 0.85]), 1), {}, "patience 1: stop at the first epoch without improvement"))
    cases.append(Case((np.array([0.5]), 1), {}, "a single epoch"))
    n = _size(rng, 8, 15)
    cases.append(Case((_curve(rng, n), n + 2), {}, "patience longer than the run: None"))
    losses = _curve(rng, 20, 0.01)
    losses[int(rng.integers(12, 18))] = np.inf
    cases.append(Case((_rising_tail(losses, 6), 4), {}, "a diverged epoch (inf)"))
    p = _size(rng, 2, 4)
    cases.append(Case((_rising_tail(np.round(rng.uniform(0.4, 1.0, 12), 2), p + 2), np.int64(p)), {},
                      "random losses, numpy patience"))
    return cases


early_stopping = Check(
    public=[
        Case(([1.0, 0.8, 0.7, 0.75, 0.72, 0.71, 0.9], 3), {}, "best at epoch 2, then three epochs without a new best"),
        Case(([1.0, 0.8, 0.8, 0.9, 0.9, 0.95], 2), {}, "an equal loss is no improvement"),
        Case(([3.0, 2.0, 1.0, 0.5], 2), {}, "always improving: never stops (None)"),
        Case(([0.9, 0.7, 0.75, 0.72, 0.74, 0.73, 0.71, 0.8, 0.9], 2), {}, "ups and downs above the best loss"),
        Case(([0.5, 0.6], 1), {}, "patience 1"),
    ],
    hidden=_es_hidden,
    compare=ExactValue("epoch"),
    mistakes=[
        Mistake("an equal loss counts as an improvement", _es_ties,
                "Only a strictly lower loss is a new best: argmin returns the FIRST minimum (use <, not <=)"),
        Mistake("stops one epoch late (> patience)", _es_late,
                "Stop at the first epoch i with i − best ≥ patience (≥, not >)"),
        _es_previous,
        Mistake("returns the best epoch instead of the stopping epoch", _es_best,
                "Return the epoch i at which training stops; the best epoch argmin(losses[:i+1]) is where to restore the weights from"),
        Mistake("never returns None (the last epoch instead)", _es_never_none,
                "If the condition never holds, return None: training ran to the end without early stopping"),
    ],
)


# --------------------------------------------------------------------------------------------
# train.smooth_labels (§12.3.5)
# --------------------------------------------------------------------------------------------
def _smooth(y, classes, on, off):
    labels = np.asarray(y).astype(np.int64)
    out = np.full((labels.size, classes), float(off))
    out[np.arange(labels.size), labels] = on
    return out


@mistake("PyTorch's convention (ε/C on every class)",
         "The notes put 1 − ε on the true class and ε/(C − 1) on each OTHER class (PyTorch spreads ε over all C)")
def _ls_torch(y, classes, eps):
    return _smooth(y, classes, 1 - eps + eps / classes, eps / classes)


@mistake("ε/C on the other classes (rows sum to less than 1)",
         "The mass ε is shared by the C − 1 other classes: ε/(C − 1) each, so that every row sums to 1")
def _ls_over_c(y, classes, eps):
    return _smooth(y, classes, 1 - eps, eps / classes)


@mistake("ε on every other class (not divided)", "Divide ε among the C − 1 other classes: ε/(C − 1)")
def _ls_not_divided(y, classes, eps):
    return _smooth(y, classes, 1 - eps, eps)


@mistake("true class left at 1", "The true class gets 1 − ε (the mass given to the others comes from it)")
def _ls_true_one(y, classes, eps):
    return _smooth(y, classes, 1.0, eps / (classes - 1))


@mistake("1 − ε and ε swapped", "The true class keeps most of the mass, 1 − ε; the others share ε")
def _ls_swapped(y, classes, eps):
    return _smooth(y, classes, eps, (1 - eps) / (classes - 1))


def _ls_hidden(rng):
    def labels(n, c, dtype=np.int64):
        return rng.integers(0, c, n).astype(dtype)

    def eps_():
        return _round(rng.uniform(0.05, 0.3), 3)

    cases = []
    c = _size(rng, 5, 12)
    cases.append(Case((labels(_size(rng, 10, 30), c), c, eps_()), {}, "random labels"))
    cases.append(Case((labels(_size(rng, 5, 15), 10, np.int32), 10, 0.1), {}, "int32 labels, C = 10, ε = 0.1"))
    cases.append(Case((labels(8, 2), 2, eps_()), {}, "two classes"))
    c = _size(rng, 3, 6)
    cases.append(Case((labels(6, c).tolist(), c, eps_()), {}, "labels as a Python list"))
    c = _size(rng, 3, 8)
    cases.append(Case((labels(7, c), c, 0.0), {}, "ε = 0: one-hot"))
    c = _size(rng, 3, 8)
    cases.append(Case((labels(5, c), c, 1.0), {}, "ε = 1: nothing on the true class"))
    cases.append(Case((np.array([0]), _size(rng, 50, 100), eps_()), {}, "one sample, many classes"))
    c = _size(rng, 4, 9)
    cases.append(Case((np.arange(c), c, eps_()), {}, "every class once"))
    c = _size(rng, 3, 6)
    cases.append(Case((labels(9, c), np.int64(c), np.float32(0.25)), {}, "numpy C and float32 ε"))
    cases.append(Case((np.zeros(0, dtype=np.int64), 4, 0.1), {}, "no samples: a (0, C) array"))
    return cases


smooth_labels = Check(
    public=[
        Case((np.array([2, 0, 1]), 3, 0.1), {}, "three samples, C = 3, ε = 0.1"),
        Case((np.array([0, 3, 3, 1]), 4, 0.2), {}, "C = 4, ε = 0.2"),
        Case((np.array([1, 0]), 2, 0.3), {}, "two classes"),
    ],
    hidden=_ls_hidden,
    compare=close(rtol=1e-12, atol=1e-15, kind="f"),
    mistakes=[_ls_torch, _ls_over_c, _ls_not_divided, _ls_true_one, _ls_swapped],
)


# --------------------------------------------------------------------------------------------
# train.stochastic_depth (§12.3.7)
# --------------------------------------------------------------------------------------------
def _sdepth_args(case):
    x = np.asarray(case.args[0], dtype=np.float64)
    r = np.asarray(_arg(case, 1, "residual"), dtype=np.float64)
    p = float(_arg(case, 2, "survival_prob"))
    training = bool(_arg(case, 3, "training"))
    return x, r, p, training


def _sdepth_statistics(output, case):
    x, r, p, training = _sdepth_args(case)
    out = np.asarray(output, dtype=np.float64)
    scale = max(1.0, float(np.abs(x).max() + np.abs(r).max()))
    if not training:
        return {"largest |output − (x + p·residual)| (evaluation)": float(np.abs(out - (x + p * r)).max()) / scale}
    n = x.shape[0]
    flat = lambda a: a.reshape(n, -1)  # noqa: E731
    tol = 1e-12 * scale
    kept = np.all(np.abs(flat(out) - flat(x + r)) <= tol, axis=1)
    dropped = np.all(np.abs(flat(out) - flat(x)) <= tol, axis=1)
    return {
        "some sample is neither x + residual nor x (1 = yes)": float(np.any(~(kept | dropped))),
        "fraction of samples with the branch kept": float(np.mean(kept & ~dropped)),
    }


def _sdepth_tolerance(case):
    x, r, p, training = _sdepth_args(case)
    n = x.shape[0]
    return {
        "largest |output − (x + p·residual)| (evaluation)": 1e-12,
        "some sample is neither x + residual nor x (1 = yes)": 0.0,
        "fraction of samples with the branch kept": 6 * math.sqrt(2 * p * (1 - p) / n),
    }


def _sdepth_with(keep_rule, train_scale=1.0, eval_scale=None, fixed_seed=False):
    def wrong(x, residual, survival_prob, training, rng=None):
        x = np.asarray(x, dtype=np.float64)
        r = np.asarray(residual, dtype=np.float64)
        p = float(survival_prob)
        if not training:
            return x + (p if eval_scale is None else eval_scale(p)) * r
        keep = keep_rule(np.random.default_rng(0 if fixed_seed else rng), x.shape, p)
        return x + np.where(keep, r * train_scale(p) if callable(train_scale) else r * train_scale, 0.0)
    return wrong


def _per_sample(gen, shape, p):
    return (gen.random(shape[0]) < p).reshape((-1,) + (1,) * (len(shape) - 1))


_sdp_swapped = _sdepth_with(lambda g, s, p: (g.random(s[0]) < 1 - p).reshape((-1,) + (1,) * (len(s) - 1)),
                            eval_scale=lambda p: 1 - p)
_sdp_batch = _sdepth_with(lambda g, s, p: np.full((1,) * len(s), g.random() < p))
_sdp_elements = _sdepth_with(lambda g, s, p: g.random(s) < p)
_sdp_eval_full = _sdepth_with(_per_sample, eval_scale=lambda p: 1.0)
_sdp_inverted = _sdepth_with(_per_sample, train_scale=lambda p: 1.0 / p, eval_scale=lambda p: 1.0)
_sdp_fixed_seed = _sdepth_with(_per_sample, fixed_seed=True)


def _exactly_kept(gen, shape, p):
    keep = np.zeros(shape[0], dtype=bool)
    keep[gen.permutation(shape[0])[:int(round(p * shape[0]))]] = True
    return keep.reshape((-1,) + (1,) * (len(shape) - 1))


_sdp_exact_count = _sdepth_with(_exactly_kept)

#: the statistic of a stochastic-depth ``draws`` case (many calls, one seed each)
_SDEPTH_DRAWS = "variance of the number of samples kept per call"


def _sdepth_draw_statistics(outputs, case):
    n = _sdepth_args(case)[0].shape[0]
    kept = [n * _sdepth_statistics(output, case)["fraction of samples with the branch kept"] for output in outputs]
    return {_SDEPTH_DRAWS: float(np.var(kept))}


def _sdepth_draw_tolerance(case):
    x, _, p, _ = _sdepth_args(case)
    return {_SDEPTH_DRAWS: binomial_variance_tolerance(x.shape[0], p, int(case.kwargs["draws"][1]))}


def _sdepth_hidden(rng):
    def pair(*shape):
        return rng.normal(0.0, 1.0, shape), rng.uniform(0.5, 2.0, shape) * rng.choice([-1.0, 1.0], shape)

    cases = []
    x, r = pair(_size(rng, 1500, 2500), 3)
    cases.append(Case((x, r, _round(rng.uniform(0.7, 0.9), 2), True), {"rng": _seed(rng)}, "training, (N, 3), p ≈ 0.8"))
    x, r = pair(_size(rng, 1500, 2500), 2, 2)
    cases.append(Case((x, r, _round(rng.uniform(0.15, 0.3), 2), True), {"rng": _seed(rng)}, "training, (N, 2, 2), p ≈ 0.2"))
    x, r = pair(_size(rng, 2000, 3000))
    cases.append(Case((x, r, 0.5, True), {"rng": _seed(rng)}, "training, one number per sample, p = 0.5"))
    x, r = pair(_size(rng, 1000, 1500), 4)
    cases.append(Case((x, r), {"survival_prob": 0.75, "training": True, "rng": np.random.default_rng(_seed(rng))},
                      "keywords, rng given as a numpy Generator"))
    x, r = pair(_size(rng, 1200, 2000), 3)
    cases.append(Case((x * 1e6, r * 1e6, 0.6, True), {"rng": _seed(rng)}, "training, ±1e6 values"))
    x, r = pair(_size(rng, 5, 9), 3)
    cases.append(Case((x, r, _round(rng.uniform(0.5, 0.9), 2), False), {}, "evaluation: x + p·residual"))
    x, r = pair(_size(rng, 5, 9), 2, 3)
    cases.append(Case((x, r, _round(rng.uniform(0.1, 0.4), 2), False), {"rng": _seed(rng)}, "evaluation, (N, 2, 3), p < 1/2"))
    x, r = pair(_size(rng, 300, 500), 2)
    cases.append(Case((x, r, 1.0, True), {"rng": _seed(rng)}, "p = 1: always kept"))
    x, r = pair(_size(rng, 300, 500), 2)
    cases.append(Case((x, r, 0.0, True), {"rng": _seed(rng)}, "p = 0: always dropped"))
    x, r = pair(_size(rng, 1500, 2000), 2)
    cases.append(Case((x, r, 0.9, True), {"rng": _seed(rng)}, "training, p = 0.9"))
    x, r = pair(_size(rng, 24, 40), 2)
    cases.append(Case((x, r, _round(rng.uniform(0.3, 0.7), 2), True), {"draws": (_seed(rng), 500)},
                      "500 calls, rng = r, r + 1, …: each sample's coin on its own, fresh on every call"))
    return cases


def _sdepth_public():
    g = np.random.default_rng(120)
    x1, r1 = g.normal(size=(1000, 3)), g.uniform(0.5, 2.0, (1000, 3))
    x2, r2 = g.normal(size=(800, 2, 2)), -g.uniform(0.5, 2.0, (800, 2, 2))
    x3, r3 = g.normal(size=(6, 3)), g.uniform(0.5, 2.0, (6, 3))
    return [
        Case((x1, r1, 0.8, True), {"rng": 0}, "training, 1000 samples of 3 values, p = 0.8"),
        Case((x2, r2, 0.3, True), {"rng": 1}, "training, 800 samples of 2×2, p = 0.3"),
        Case((x3, r3, 0.7, False), {}, "evaluation, p = 0.7"),
        Case((x1[:32], r1[:32], 0.5, True), {"draws": (700, 500)},
             "500 calls, rng = 700, 701, …: each sample's coin on its own, fresh on every call"),
    ]


stochastic_depth = Check(
    public=_sdepth_public,
    hidden=_sdepth_hidden,
    compare=Drawn(single=Statistics(statistics=_sdepth_statistics, tolerance=_sdepth_tolerance, dtype_kind="f"),
                  statistics=_sdepth_draw_statistics, tolerance=_sdepth_draw_tolerance),
    call=call_draws,
    mistakes=[
        Mistake("survival and drop probability swapped", _sdp_swapped,
                "survival_prob is the probability of KEEPING the branch: keep = rng.random(N) < survival_prob"),
        Mistake("one coin for the whole batch", _sdp_batch,
                "Draw one coin per sample (rng.random(N)), not one for the batch"),
        Mistake("one coin per element instead of per sample", _sdp_elements,
                "A sample keeps or drops its WHOLE branch: draw N coins and broadcast them over the other axes"),
        Mistake("evaluation returns x + residual (no p)", _sdp_eval_full,
                "At test time use the expectation of the training output: x + p·residual"),
        Mistake("inverted scaling (residual / p in training)", _sdp_inverted,
                "This chapter's convention (Huang et al.): x + residual for a kept sample in training, x + p·residual at test time"),
        Mistake("exactly round(p·N) samples kept on every call", _sdp_exact_count,
                "Toss one coin per sample, keep = rng.random(N) < survival_prob: how many samples keep their "
                "branch varies from call to call (Binomial(N, p))"),
        Mistake("rng ignored: the same samples kept on every call", _sdp_fixed_seed,
                "Draw from the generator the caller gives, np.random.default_rng(rng): a generator made with a "
                "fixed seed inside the function keeps the same samples in every training step"),
    ],
    seeded=True,
)


# --------------------------------------------------------------------------------------------
# train.random_resized_crop (§12.4)
# --------------------------------------------------------------------------------------------
def _plane_image(rng, h, w, channels=None, dtype=np.float64):
    """An image whose every channel is a plane α + a·row + b·col (a, b ≠ 0)."""
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
    if dtype == np.uint8:  # small integer slopes keep 0..255
        a, b = int(rng.integers(1, 3)), int(rng.integers(1, 3))
        plane = (a * rows + b * cols + int(rng.integers(0, 10))) * int(rng.choice([1, -1]))
        plane = plane - plane.min()
        if channels is None:
            return plane.astype(np.uint8)
        return np.stack([plane, plane.max() - plane, np.full_like(plane, 7.0) + rows], axis=-1).astype(np.uint8)
    if channels is None:
        return np.round(rng.uniform(-1, 1), 3) + rng.uniform(0.5, 2) * rows + rng.uniform(-2, -0.5) * cols
    return np.stack([rows * 1.0, cols * 1.0, 0.5 * rows - 0.25 * cols + 3.0], axis=-1)


def _fit_plane(values):
    """Least-squares plane α + a·row + b·col of a 2-D array: (α, a, b, max |residual|)."""
    h, w = values.shape
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
    design = np.stack([np.ones(h * w), rows.ravel(), cols.ravel()], axis=1)
    coef, *_ = np.linalg.lstsq(design, values.ravel(), rcond=None)
    residual = values.ravel() - design @ coef
    return coef, float(np.abs(residual).max()) if residual.size else 0.0


def _rrc_settings(case):
    image = np.asarray(case.args[0], dtype=np.float64)
    size = _arg(case, 1, "output_size")
    scale = tuple(_arg(case, 2, "scale", (0.08, 1.0)))
    ratio = tuple(_arg(case, 3, "ratio", (3 / 4, 4 / 3)))
    return image, size, scale, ratio


def _channels(a):
    return [a] if a.ndim == 2 else [a[..., c] for c in range(a.shape[2])]


def _rrc_statistics(output, case):
    image, _, scale, ratio = _rrc_settings(case)
    out = np.asarray(output, dtype=np.float64)
    span = max(1.0, float(image.max() - image.min()))
    stats = {"fraction of output values outside the input's range":
             float(np.mean((out < image.min() - 1e-9 * span) | (out > image.max() + 1e-9 * span)))}
    in_fits = [_fit_plane(c) for c in _channels(image)]
    if any(res > 1e-9 * span for _, res in in_fits) or min(out.shape[:2]) < 2:
        return stats  # not a plane-coded image: only the range can be checked
    out_fits = [_fit_plane(c) for c in _channels(out)]
    stats["output is not a resampled plane (largest residual / value range)"] = max(res for _, res in out_fits) / span
    oh, ow = out.shape[:2]
    height, width = image.shape[:2]
    k_rows = int(np.argmax([abs(c[1]) for c, _ in in_fits]))
    k_cols = int(np.argmax([abs(c[2]) for c, _ in in_fits]))
    crop_h = out_fits[k_rows][0][1] / in_fits[k_rows][0][1] * oh   # rows of the crop per output row × oh
    crop_w = out_fits[k_cols][0][2] / in_fits[k_cols][0][2] * ow
    if not (crop_h > 0 and crop_w > 0):
        stats["crop size read from the output is not positive (1 = yes)"] = 1.0
        return stats
    stats["crop size read from the output is not positive (1 = yes)"] = 0.0
    slack = 1.0  # a crop of whole pixels: h and w are rounded, and resizes differ by < 1 px
    area = height * width
    area_lo = (max(crop_h - slack, 0) * max(crop_w - slack, 0)) / area
    area_hi = ((crop_h + slack) * (crop_w + slack)) / area
    stats["area fraction of the crop outside `scale` (by how much)"] = max(0.0, scale[0] - area_hi, area_lo - scale[1])
    r_lo, r_hi = max(crop_w - slack, 0) / (crop_h + slack), (crop_w + slack) / max(crop_h - slack, 1e-9)
    stats["aspect ratio w/h of the crop outside `ratio` (by how much)"] = max(0.0, ratio[0] - r_hi, r_lo - ratio[1])
    stats["crop larger than the image (1 = yes)"] = float(crop_h > height + slack or crop_w > width + slack)
    return stats


def _rrc_tolerance(case):
    return {
        "fraction of output values outside the input's range": 0.0,
        "output is not a resampled plane (largest residual / value range)": 1e-7,
        "crop size read from the output is not positive (1 = yes)": 0.0,
        "area fraction of the crop outside `scale` (by how much)": 1e-9,
        "aspect ratio w/h of the crop outside `ratio` (by how much)": 1e-9,
        "crop larger than the image (1 = yes)": 0.0,
    }


def _rrc_box(image, scale, ratio, gen, *, side=False, inverted=False, square=False, corner=False, fixed_area=False):
    height, width = image.shape[:2]
    for _ in range(100):
        s = scale[1] if fixed_area else gen.uniform(*scale)
        r = math.exp(gen.uniform(math.log(ratio[0]), math.log(ratio[1])))
        if square:
            r = 1.0
        area = (s * s if side else s) * height * width
        w, h = round(math.sqrt(area * r)), round(math.sqrt(area / r))
        if inverted:
            w, h = h, w
        if 1 <= w <= width and 1 <= h <= height:
            top, left = int(gen.integers(0, height - h + 1)), int(gen.integers(0, width - w + 1))
            return (0, 0, h, w) if corner else (top, left, h, w)
    return 0, 0, height, width


def _bilinear(crop, oh, ow, nearest=False):
    h, w = crop.shape[:2]

    def axis(n_in, n_out):
        src = np.clip((np.arange(n_out) + 0.5) * n_in / n_out - 0.5, 0, n_in - 1)
        if nearest:
            i = np.minimum(np.floor(src + 0.5).astype(int), n_in - 1)
            return i, i, np.zeros(n_out)
        i0 = np.floor(src).astype(int)
        return i0, np.minimum(i0 + 1, n_in - 1), src - i0

    r0, r1, fr = axis(h, oh)
    c0, c1, fc = axis(w, ow)
    extra = (None,) * (crop.ndim - 2)
    fr = fr[(slice(None), None) + extra]
    fc = fc[(None, slice(None)) + extra]
    top = crop[r0][:, c0] * (1 - fc) + crop[r0][:, c1] * fc
    bottom = crop[r1][:, c0] * (1 - fc) + crop[r1][:, c1] * fc
    return top * (1 - fr) + bottom * fr


def _rrc_variant(image, output_size, scale=(0.08, 1.0), ratio=(3 / 4, 4 / 3), rng=None, *, swap_size=False,
                 nearest=False, **box_options):
    img = np.asarray(image, dtype=np.float64)
    oh, ow = (output_size, output_size) if np.ndim(output_size) == 0 else tuple(output_size)
    if swap_size:
        oh, ow = ow, oh
    top, left, h, w = _rrc_box(img, scale, ratio, np.random.default_rng(rng), **box_options)
    return _bilinear(img[top: top + h, left: left + w], int(oh), int(ow), nearest=nearest)


_rrc_side = variant(_rrc_variant, side=True)
_rrc_inverted = variant(_rrc_variant, inverted=True)
_rrc_square = variant(_rrc_variant, square=True)
_rrc_nearest = variant(_rrc_variant, nearest=True)
_rrc_swapped = variant(_rrc_variant, swap_size=True)
_rrc_corner = variant(_rrc_variant, corner=True)
_rrc_fixed_area = variant(_rrc_variant, fixed_area=True)



_RRC_DRAWS = ("share of the draws whose crop starts at the top-left corner (a uniform position seldom does)",
              "variance of the crop's area fraction over the draws")


def _rrc_draw_statistics(outputs, case):
    """Crops read back from the outputs of a coded image (channel 0 holds the row, channel 1
    the column): with half-pixel centres output pixel u samples row top + (u + 0.5)·h/out_h − 0.5."""
    image = np.asarray(case.args[0], dtype=np.float64)
    corner, areas = 0, []
    for output in outputs:
        out = np.asarray(output, dtype=np.float64)
        (a_r, b_r, _), _ = _fit_plane(out[..., 0])
        (a_c, _, c_c), _ = _fit_plane(out[..., 1])
        top, left = a_r - 0.5 * b_r + 0.5, a_c - 0.5 * c_c + 0.5
        corner += top < 0.5 and left < 0.5
        areas.append(b_r * out.shape[0] * c_c * out.shape[1] / (image.shape[0] * image.shape[1]))
    return dict(zip(_RRC_DRAWS, (corner / len(outputs), float(np.var(areas)))))


def _rrc_draw_tolerance(case):
    """The area fraction s is uniform in `scale`: six standard errors of the difference of two
    samples' variance (fourth central moment (b − a)⁴/80), plus the crop's rounding to whole
    pixels; a corner that comes back in a quarter of the draws is no uniform position."""
    count = case.kwargs["draws"][1]
    low, high = _arg(case, 2, "scale", (0.08, 1.0))
    width = float(high) - float(low)
    spread = 6.0 * math.sqrt(2.0 * (width ** 4 / 80 - (width ** 2 / 12) ** 2) / count) + 0.002
    return dict(zip(_RRC_DRAWS, (0.25, spread)))


def _rrc_hidden(rng):
    cases = []
    h, w = _size(rng, 56, 72), _size(rng, 64, 90)
    cases.append(Case((_plane_image(rng, h, w), (9, 13)), {"scale": (0.3, 0.5), "rng": _seed(rng)},
                      "scale (0.3, 0.5): a crop of 30–50 % of the AREA"))
    h, w = _size(rng, 48, 64), _size(rng, 80, 100)
    cases.append(Case((_plane_image(rng, h, w), (10, 12)), {"scale": (0.4, 0.6), "ratio": (1.5, 2.5), "rng": _seed(rng)},
                      "ratio (1.5, 2.5): wide crops"))
    h, w = _size(rng, 64, 80), _size(rng, 40, 56)
    cases.append(Case((_plane_image(rng, h, w), (12, 7)), {"scale": (0.3, 0.6), "ratio": (0.4, 0.7), "rng": _seed(rng)},
                      "ratio (0.4, 0.7): tall crops, (h, w) output"))
    h, w = _size(rng, 40, 56), _size(rng, 40, 56)
    cases.append(Case((_plane_image(rng, h, w), 8), {"rng": _seed(rng)}, "defaults, int output_size"))
    h, w = _size(rng, 40, 56), _size(rng, 48, 64)
    cases.append(Case((_plane_image(rng, h, w, channels=3), (6, 10)), {"scale": (0.25, 0.5), "rng": _seed(rng)},
                      "colour image"))
    h, w = _size(rng, 40, 60), _size(rng, 40, 60)
    cases.append(Case((_plane_image(rng, h, w, dtype=np.uint8), (8, 9)), {"scale": (0.2, 0.45), "rng": _seed(rng)},
                      "uint8 image (result float, not rescaled)"))
    h, w = _size(rng, 40, 56), _size(rng, 48, 64)
    cases.append(Case((_plane_image(rng, h, w, channels=3, dtype=np.uint8), (9, 7)),
                      {"scale": (0.3, 0.55), "ratio": (1.2, 1.8), "rng": np.random.default_rng(_seed(rng))},
                      "colour uint8, rng given as a numpy Generator"))
    h, w = _size(rng, 48, 64), _size(rng, 48, 64)
    cases.append(Case((_plane_image(rng, h, w), (11, 8), (0.5, 0.5), (1.0, 1.0)), {"rng": _seed(rng)},
                      "scale and ratio fixed, given positionally: area 1/2, square crop"))
    h, w = _size(rng, 40, 50), _size(rng, 40, 50)
    cases.append(Case((_plane_image(rng, h, w) * 1e6, (7, 7)), {"scale": (0.35, 0.6), "rng": _seed(rng)}, "±1e6 values"))
    h, w = _size(rng, 30, 40), _size(rng, 30, 40)
    cases.append(Case((_plane_image(rng, h, w), (5, 6)), {"scale": (0.9, 1.0), "rng": _seed(rng)}, "scale (0.9, 1): almost the whole image"))
    cases.append(Case((rng.random((_size(rng, 20, 30), _size(rng, 20, 30))), (6, 8)), {"rng": _seed(rng)},
                      "a random image (only the value range is checked)"))
    h, w = _size(rng, 44, 60), _size(rng, 44, 60)
    cases.append(Case((_plane_image(rng, h, w, channels=3), (6, 5)), {"scale": (0.1, 0.45), "draws": (_seed(rng), 400)},
                      "400 calls, one seed each: position uniform, area fraction uniform in (0.1, 0.45)"))
    return cases


def _rrc_public():
    g = np.random.default_rng(130)
    return [
        Case((_plane_image(g, 60, 80), (10, 12)), {"scale": (0.3, 0.5), "rng": 0}, "60×80 image, scale (0.3, 0.5)"),
        Case((_plane_image(g, 50, 90), (8, 12)), {"scale": (0.4, 0.6), "ratio": (1.5, 2.5), "rng": 1},
             "wide crops: ratio (1.5, 2.5)"),
        Case((_plane_image(g, 48, 48, channels=3), (9, 6)), {"scale": (0.25, 0.5), "ratio": (0.5, 0.75), "rng": 2},
             "colour, tall crops, (h, w) = (9, 6)"),
        Case((_plane_image(g, 48, 56, channels=3), (6, 6)), {"scale": (0.1, 0.5), "draws": (4000, 400)},
             "400 calls, rng = 4000, 4001, …: position uniform, area fraction uniform in (0.1, 0.5)"),
    ]


random_resized_crop = Check(
    rules=("integer",),
    public=_rrc_public,
    hidden=_rrc_hidden,
    compare=Drawn(single=Statistics(statistics=_rrc_statistics, tolerance=_rrc_tolerance, dtype_kind="f"),
                  statistics=_rrc_draw_statistics, tolerance=_rrc_draw_tolerance),
    call=call_draws,
    mistakes=[
        Mistake("scale taken as a fraction of the side, not the area", _rrc_side,
                "s ~ U(scale) is the fraction of the image's AREA: w = √(s·H·W·r), h = √(s·H·W/r)"),
        Mistake("aspect ratio inverted (h/w instead of w/h)", _rrc_inverted,
                "ratio is width/height: w = √(A·r), h = √(A/r)"),
        Mistake("aspect ratio ignored (square crops)", _rrc_square,
                "Draw log r ~ U(log ratio[0], log ratio[1]) and shape the crop with it"),
        Mistake("nearest-neighbour resize instead of bilinear", _rrc_nearest,
                "Blend the two nearest pixels on each axis: (1 − f)·I[i0] + f·I[i0 + 1] with source position (u + 0.5)·h/out_h − 0.5"),
        Mistake("output_size (h, w) read as (w, h)", _rrc_swapped,
                "output_size is (height, width), like NumPy shapes"),
        Mistake("crop always at the top-left corner", _rrc_corner,
                "Draw the crop's top-left corner uniformly among the positions that keep it inside: "
                "rng.integers(0, H − h + 1), rng.integers(0, W − w + 1)"),
        Mistake("area fixed at scale[1] (not drawn)", _rrc_fixed_area,
                "Draw the area fraction anew each call: s ~ U(scale[0], scale[1])"),
    ],
    seeded=True,
)


# --------------------------------------------------------------------------------------------
# train.cutout (§12.4)
# --------------------------------------------------------------------------------------------
def _cutout_statistics(output, case):
    image = np.asarray(case.args[0], dtype=np.float64)
    size = int(_arg(case, 1, "size"))
    out = np.asarray(output, dtype=np.float64)
    height, width = image.shape[:2]
    changed_values = out != image
    changed = changed_values if image.ndim == 2 else changed_values.any(axis=-1)
    stats = {"fraction of changed values that are not 0": float(np.mean(out[changed_values] != 0)) if changed_values.any() else 0.0}
    if image.ndim == 3:
        stats["an erased pixel kept some channel (1 = yes)"] = float(np.any(changed & ~changed_values.all(axis=-1)))
    if not changed.any():
        stats["nothing was erased (1 = yes)"] = 1.0
        return stats
    stats["nothing was erased (1 = yes)"] = 0.0
    rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
    t, b, l, r = rows[0], rows[-1], cols[0], cols[-1]
    stats["erased pixels do not fill a rectangle (1 = yes)"] = float(not changed[t: b + 1, l: r + 1].all())

    def excess(first, last, n):  # 0 for `size` pixels, or fewer where the border clips the square
        side = last - first + 1
        if side == size or (side < size and (first == 0 or last == n - 1)):
            return 0.0
        return float(side - size)

    stats["height of the erased rectangle − size (0 if equal, or clipped by the border)"] = excess(t, b, height)
    stats["width of the erased rectangle − size (0 if equal, or clipped by the border)"] = excess(l, r, width)
    return stats


def _cutout_tolerance(case):
    return {}  # every statistic is an exact property (tolerance 0)



def _cutout_centre(output, case) -> tuple[float | None, float | None]:
    """The square's centre (row, col) read from the erased rectangle of a correct cutout: the
    side the border did not clip places it (``None`` where both sides are clipped)."""
    image = np.asarray(case.args[0], dtype=np.float64)
    size = int(_arg(case, 1, "size"))
    changed = np.asarray(output, dtype=np.float64) != image
    changed = changed if image.ndim == 2 else changed.any(axis=-1)
    centre: list[float | None] = []
    for axis in (1, 0):
        hit = np.flatnonzero(changed.any(axis=axis))
        if hit.size == 0:
            centre.append(None)
        elif hit[0] > 0:
            centre.append(float(hit[0] + size // 2))
        elif hit[-1] < changed.shape[1 - axis] - 1:
            centre.append(float(hit[-1] - size + 1 + size // 2))
        else:
            centre.append(None)
    return centre[0], centre[1]


_CUTOUT_DRAWS = ("mean row of the square's centre / (H − 1)", "variance of the row of the centre / (H − 1)",
                 "mean column of the square's centre / (W − 1)", "variance of the column of the centre / (W − 1)",
                 "share of the draws with the most frequent centre (a uniform centre seldom repeats)")


def _cutout_draw_statistics(outputs, case):
    image = np.asarray(case.args[0])
    centres = [_cutout_centre(o, case) for o in outputs]
    stats = []
    for axis, extent in ((0, image.shape[0]), (1, image.shape[1])):
        values = np.array([c[axis] for c in centres if c[axis] is not None]) / max(1, extent - 1)
        stats += [float(values.mean()), float(values.var())] if values.size else [np.nan, np.nan]
    stats.append(max(centres.count(c) for c in set(centres)) / len(centres) if centres else 0.0)
    return dict(zip(_CUTOUT_DRAWS, stats))


def _cutout_draw_tolerance(case):
    """Six standard errors of the difference of two samples' mean (variance 1/12) and variance
    (fourth central moment 1/80) of a uniform centre: a correct version fails about once in 10⁸."""
    count = case.kwargs["draws"][1]
    mean, variance = 6.0 * math.sqrt(2.0 / (12.0 * count)), 6.0 * math.sqrt(2.0 * (1 / 80 - 1 / 144) / count)
    return dict(zip(_CUTOUT_DRAWS, (mean, variance, mean, variance, 0.25)))


def _cutout_variant(image, size, rng=None, *, half_odd=False, double=False, one_channel=False, fill_mean=False,
                    centre="uniform"):
    img = np.array(image, dtype=np.float64, copy=True)
    gen = np.random.default_rng(rng)
    cy, cx = int(gen.integers(0, img.shape[0])), int(gen.integers(0, img.shape[1]))
    if centre == "middle":
        cy, cx = img.shape[0] // 2, img.shape[1] // 2
    elif centre == "corner":  # the drawn point taken as the square's top-left corner
        cy, cx = cy + size // 2, cx + size // 2
    elif centre == "inside":  # the square kept whole: a centre drawn away from the border
        cy = int(gen.integers(size // 2, max(size // 2 + 1, img.shape[0] - size + size // 2 + 1)))
        cx = int(gen.integers(size // 2, max(size // 2 + 1, img.shape[1] - size + size // 2 + 1)))
    if double:
        size = 2 * size
    if half_odd:  # DeVries' bounds y ± size // 2: an odd size loses a row and a column
        y1, y2, x1, x2 = cy - size // 2, cy + size // 2, cx - size // 2, cx + size // 2
    else:
        y1, x1 = cy - size // 2, cx - size // 2
        y2, x2 = y1 + size, x1 + size
    window = (slice(max(0, y1), max(0, y2)), slice(max(0, x1), max(0, x2)))
    value = float(np.mean(img)) if fill_mean else 0.0
    if one_channel and img.ndim == 3:
        img[window + (0,)] = value
    else:
        img[window] = value
    return img


_co_half = variant(_cutout_variant, half_odd=True)
_co_double = variant(_cutout_variant, double=True)
_co_channel = variant(_cutout_variant, one_channel=True)
_co_mean = variant(_cutout_variant, fill_mean=True)
_co_middle = variant(_cutout_variant, centre="middle")
_co_corner = variant(_cutout_variant, centre="corner")
_co_inside = variant(_cutout_variant, centre="inside")


def _no_zero_image(rng, h, w, channels=None, dtype=np.float64):
    shape = (h, w) if channels is None else (h, w, channels)
    if dtype == np.uint8:
        return rng.integers(1, 256, shape).astype(np.uint8)
    return rng.uniform(0.05, 1.0, shape)


def _cutout_hidden(rng):
    def odd(lo, hi):
        return 2 * _size(rng, lo, hi) + 1

    cases = []
    cases.append(Case((_no_zero_image(rng, _size(rng, 30, 40), _size(rng, 30, 44)), odd(1, 4)), {"rng": _seed(rng)}, "odd size"))
    cases.append(Case((_no_zero_image(rng, _size(rng, 28, 40), _size(rng, 40, 50)), odd(2, 4)), {"rng": _seed(rng)},
                      "odd size, non-square image"))
    cases.append(Case((_no_zero_image(rng, _size(rng, 30, 40), _size(rng, 30, 40)), 2 * _size(rng, 2, 4)), {"rng": _seed(rng)},
                      "even size"))
    cases.append(Case((_no_zero_image(rng, _size(rng, 24, 32), _size(rng, 24, 32), 3), odd(1, 3)), {"rng": _seed(rng)},
                      "colour image (all three channels erased)"))
    cases.append(Case((_no_zero_image(rng, _size(rng, 24, 32), _size(rng, 24, 32), 3, np.uint8), odd(1, 3)),
                      {"rng": _seed(rng)}, "colour uint8 image"))
    cases.append(Case((_no_zero_image(rng, _size(rng, 30, 40), _size(rng, 30, 40), dtype=np.uint8), odd(1, 3)),
                      {"rng": np.random.default_rng(_seed(rng))}, "uint8 image, rng given as a numpy Generator"))
    cases.append(Case((_no_zero_image(rng, 10, 12), 9), {"rng": _seed(rng)}, "a square almost as large as the image (clipped)"))
    cases.append(Case((_no_zero_image(rng, 6, 8), 12), {"rng": _seed(rng)}, "size larger than the image: all erased"))
    cases.append(Case((_no_zero_image(rng, _size(rng, 20, 30), _size(rng, 20, 30)), 1), {"rng": _seed(rng)}, "size 1: one pixel"))
    cases.append(Case((_no_zero_image(rng, 1, _size(rng, 40, 60)), odd(1, 3)), {"rng": _seed(rng)}, "a single-row image"))
    cases.append(Case((_no_zero_image(rng, _size(rng, 30, 40), _size(rng, 30, 40)) * 1e6, odd(2, 3)), {"rng": _seed(rng)},
                      "±1e6 values"))
    cases.append(Case((_no_zero_image(rng, _size(rng, 30, 40), _size(rng, 30, 40)), odd(1, 2)), {"rng": _seed(rng)}, "odd size (again)"))
    height, width, size = _size(rng, 16, 22), _size(rng, 16, 22), odd(3, 5)
    cases.append(Case((_no_zero_image(rng, height, width), size), {"draws": (_seed(rng), 400)},
                      f"400 calls, one seed each: the centre uniform over the {height}×{width} image, size {size}"))
    return cases


def _cutout_public():
    g = np.random.default_rng(140)
    return [
        Case((_no_zero_image(g, 32, 40), 5), {"rng": 0}, "32×40 image, size 5"),
        Case((_no_zero_image(g, 24, 24, 3), 7), {"rng": 3}, "colour 24×24 image, size 7"),
        Case((_no_zero_image(g, 30, 30), 4), {"rng": 2}, "even size 4"),
        Case((_no_zero_image(g, 40, 36), 3), {"rng": 5}, "size 3"),
        Case((_no_zero_image(g, 20, 24), 9), {"draws": (2000, 400)},
             "400 calls, rng = 2000, 2001, …: the centre uniform over the 20×24 image, size 9"),
    ]


cutout = Check(
    public=_cutout_public,
    hidden=_cutout_hidden,
    compare=Drawn(single=Statistics(statistics=_cutout_statistics, tolerance=_cutout_tolerance, dtype_kind="f"),
                  statistics=_cutout_draw_statistics, tolerance=_cutout_draw_tolerance),
    call=call_draws,
    mistakes=[
        Mistake("odd sizes lose a row and a column (y ± size // 2)", _co_half,
                "Take exactly `size` rows: from cy − size // 2 to cy − size // 2 + size (exclusive), then clip"),
        Mistake("size used as the half-width (a 2·size square)", _co_double,
                "size is the side of the square, not its half-width"),
        Mistake("colour: only the first channel erased", _co_channel,
                "Erase every channel of the square: image[rows, cols] = 0 (or [..., :])"),
        Mistake("square filled with the image mean instead of 0", _co_mean,
                "Cutout sets the square to 0"),
        Mistake("square always at the image's centre", _co_middle,
                "Draw the centre anew each call, uniform over the image: rng.integers(0, H), rng.integers(0, W)"),
        Mistake("the drawn point used as the top-left corner", _co_corner,
                "The drawn point is the square's centre: rows cy − size // 2 to cy − size // 2 + size, then clip"),
        Mistake("square kept inside the image (centre drawn away from the border)", _co_inside,
                "The centre is uniform over the whole image and the square is clipped where it leaves it"),
    ],
    seeded=True,
)


# --------------------------------------------------------------------------------------------
# train.mixup and train.cutmix (§12.4)
# --------------------------------------------------------------------------------------------
def _triple_structure(got, expected, case):
    if not isinstance(got, (tuple, list)) or len(got) != 3:
        n = len(got) if isinstance(got, (tuple, list)) else type(got).__name__
        return f"expected a tuple (x_mixed, y_mixed, lam), got {n if isinstance(n, str) else f'a sequence of {n}'}"
    names = ("x_mixed", "y_mixed")
    for i in range(2):
        try:
            arr = np.asarray(got[i], dtype=np.float64)
        except Exception:
            return f"{names[i]} is not a numeric array"
        if arr.shape != np.shape(expected[i]):
            return f"{names[i]}: shape mismatch: expected {np.shape(expected[i])}, got {arr.shape}"
    lam = got[2]
    if np.ndim(lam) != 0 or isinstance(lam, (bool, np.bool_, str)):
        return f"lam must be one number (one λ per batch), got {type(lam).__name__} of shape {np.shape(lam)}"
    try:
        value = float(lam)
    except Exception:
        return f"lam must be a number, got {type(lam).__name__}"
    if not 0.0 <= value <= 1.0:
        return f"lam must be in [0, 1], got {value}"
    return None


def _mix_inputs(case):
    return np.asarray(case.args[0], dtype=np.float64), np.asarray(_arg(case, 1, "y_onehot"), dtype=np.float64)


def _partner_counts(partners):
    return float(np.bincount(partners, minlength=partners.size).max() > 1) if partners.size else 0.0


def _mixup_partners(output, case):
    """``(partners, decodable, d)``: for each sample the j that best explains
    x_mixed[i] = λ x[i] + (1 − λ) x[j], whether λ leaves the partners tell-apart, and the
    squared residuals."""
    x, _ = _mix_inputs(case)
    xm, lam = np.asarray(output[0], np.float64), float(output[2])
    n = x.shape[0]
    flat, flat_m = x.reshape(n, -1), xm.reshape(n, -1)
    scale = max(1.0, float(np.abs(x).max()))
    rest = flat_m - lam * flat                                            # ≈ (1 − λ) x[j]
    d = ((rest[:, None, :] - (1 - lam) * flat[None, :, :]) ** 2).sum(axis=2)
    partners = np.argmin(d, axis=1)
    # with λ so close to 1 that (1 − λ)·x[j] is lost in round-off the partners cannot be told apart
    # (and do not matter: then y_mixed ≈ y too)
    separation = np.where(np.eye(n, dtype=bool), np.inf, np.linalg.norm(flat[:, None] - flat[None], axis=2))
    decodable = n > 1 and (1 - lam) * float(separation.min()) > 1e-10 * scale
    return partners, decodable, d


def _mixup_statistics(output, case):
    x, y = _mix_inputs(case)
    ym, lam = np.asarray(output[1], np.float64), float(output[2])
    n = x.shape[0]
    scale = max(1.0, float(np.abs(x).max()))
    partners, decodable, d = _mixup_partners(output, case)
    return {
        "largest |x_mixed − (λ·x + (1 − λ)·x[partner])|": float(np.sqrt(d[np.arange(n), partners].max())) / scale,
        "largest |y_mixed − (λ·y + (1 − λ)·y[partner])|": float(np.abs(ym - (lam * y + (1 - lam) * y[partners])).max()),
        "some sample is the partner of two samples (1 = yes; a permutation pairs each once)":
            _partner_counts(partners) if decodable else 0.0,
    }


def _beta_moments(alpha: float) -> tuple[float, float]:
    """Variance and fourth central moment of Beta(α, α) (mean 1/2)."""
    return 1.0 / (4.0 * (2.0 * alpha + 1.0)), 3.0 / (16.0 * (2.0 * alpha + 1.0) * (2.0 * alpha + 3.0))


_MIX_DRAWS = ("mean of λ over the draws", "variance of λ over the draws",
              "share of the draws with the most frequent pairing (a random permutation seldom repeats)")


def _mixup_draw_statistics(outputs, case):
    lams = np.array([float(o[2]) for o in outputs])
    pairings = [tuple(p) for p, decodable, _ in (_mixup_partners(o, case) for o in outputs) if decodable]
    most = max(pairings.count(p) for p in set(pairings)) / len(pairings) if pairings else 0.0
    return dict(zip(_MIX_DRAWS, (float(lams.mean()), float(lams.var()), float(most))))


def _mixup_draw_tolerance(case):
    """Six standard errors of the difference of two independent samples' mean and variance
    of λ ~ Beta(α, α) (a correct version fails about once in 10⁸ gradings); a pairing that
    comes back in a quarter of the draws is no random permutation."""
    count = case.kwargs["draws"][1]
    variance, fourth = _beta_moments(float(_arg(case, 2, "alpha", 0.2)))
    return dict(zip(_MIX_DRAWS, (6.0 * math.sqrt(2.0 * variance / count),
                                 6.0 * math.sqrt(2.0 * (fourth - variance ** 2) / count), 0.25)))


def _mix_tolerance(case):
    return {
        "largest |x_mixed − (λ·x + (1 − λ)·x[partner])|": 1e-9,
        "largest |y_mixed − (λ·y + (1 − λ)·y[partner])|": 1e-9,
        "some sample is the partner of two samples (1 = yes; a permutation pairs each once)": 0.0,
        "largest |x_mixed − (x with the box pasted from x[partner])|": 1e-12,
        "|λ − (1 − pasted area / (H·W))|": 1e-9,
        "the pasted pixels are not one box shared by the batch (1 = yes)": 0.0,
    }


def _mixup_variant(x, y_onehot, alpha=0.2, rng=None, *, labels="mixed", per_sample=False, replace=False,
                   return_complement=False, law="beta", reverse=False):
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y_onehot, dtype=np.float64)
    gen = np.random.default_rng(rng)
    n = x.shape[0]
    if law == "half":
        lam = 0.5
    elif law == "uniform":
        lam = float(gen.random())
    else:
        lam = gen.beta(alpha, alpha, n) if per_sample else float(gen.beta(alpha, alpha))
    perm = np.arange(n)[::-1] if reverse else gen.integers(0, n, n) if replace else gen.permutation(n)
    lam_x = lam.reshape((-1,) + (1,) * (x.ndim - 1)) if per_sample else lam
    lam_y = lam[:, None] if per_sample else lam
    xm = lam_x * x + (1 - lam_x) * x[perm]
    if labels == "mixed":
        ym = lam_y * y + (1 - lam_y) * y[perm]
    elif labels == "swapped":
        ym = (1 - lam_y) * y + lam_y * y[perm]
    else:
        ym = y.copy()
    lam_out = float(np.mean(lam)) if per_sample else lam
    return xm, ym, (1 - lam_out) if return_complement else lam_out


_mx_swapped = variant(_mixup_variant, labels="swapped")
_mx_unmixed = variant(_mixup_variant, labels="unmixed")
_mx_per_sample = variant(_mixup_variant, per_sample=True)
_mx_replace = variant(_mixup_variant, replace=True)
_mx_complement = variant(_mixup_variant, return_complement=True)
_mx_half = variant(_mixup_variant, law="half")
_mx_uniform = variant(_mixup_variant, law="uniform")
_mx_reverse = variant(_mixup_variant, reverse=True)


def _onehot(rng, n, c):
    return np.eye(c)[rng.integers(0, c, n)]


def _mixup_hidden(rng):
    cases = []
    n, c = _size(rng, 16, 32), _size(rng, 3, 10)
    cases.append(Case((rng.random((n, 8, 8)), _onehot(rng, n, c)), {"alpha": 1.0, "rng": _seed(rng)}, "images (N, 8, 8), α = 1"))
    n, c = _size(rng, 16, 32), _size(rng, 3, 10)
    cases.append(Case((rng.normal(size=(n, _size(rng, 5, 20))), _onehot(rng, n, c)), {"alpha": 2.0, "rng": _seed(rng)},
                      "feature vectors, α = 2 (λ near 1/2)"))
    n, c = _size(rng, 20, 40), 10
    cases.append(Case((rng.random((n, 3, 6, 6)), _onehot(rng, n, c)), {"alpha": 0.4, "rng": _seed(rng)}, "(N, C, H, W) batch"))
    n, c = _size(rng, 16, 24), _size(rng, 3, 6)
    cases.append(Case((rng.random((n, 6)), _onehot(rng, n, c)), {"rng": _seed(rng)}, "default α = 0.2"))
    n, c = _size(rng, 16, 24), _size(rng, 3, 6)
    cases.append(Case((rng.random((n, 4)), _onehot(rng, n, c), 1.5), {"rng": np.random.default_rng(_seed(rng))},
                      "α positional, rng given as a numpy Generator"))
    n, c = _size(rng, 16, 24), 4
    soft = rng.dirichlet(np.ones(c), n)
    cases.append(Case((rng.random((n, 5)), soft), {"alpha": 1.0, "rng": _seed(rng)}, "soft targets (already smoothed)"))
    n = _size(rng, 16, 24)
    cases.append(Case((rng.integers(0, 256, (n, 6, 6)).astype(np.uint8), _onehot(rng, n, 5)), {"alpha": 1.0, "rng": _seed(rng)},
                      "uint8 images (the result is float)"))
    n = _size(rng, 20, 30)
    cases.append(Case((rng.uniform(-1e6, 1e6, (n, 7)), _onehot(rng, n, 3)), {"alpha": 3.0, "rng": _seed(rng)}, "±1e6 values"))
    n = _size(rng, 20, 30)
    cases.append(Case((rng.random((n, 3)), _onehot(rng, n, 2)), {"alpha": 5.0, "rng": _seed(rng)}, "α = 5, two classes"))
    cases.append(Case((rng.random((2, 4)), np.eye(2)), {"alpha": 1.0, "rng": _seed(rng)}, "a batch of two"))
    alpha = float(rng.choice([0.3, 0.5, 4.0, 6.0]))
    cases.append(Case((rng.random((6, 2)), np.eye(3)[[0, 1, 2, 0, 1, 2]]), {"alpha": alpha, "draws": (_seed(rng), 400)},
                      f"400 calls, one seed each: λ ~ Beta({alpha:g}, {alpha:g}), a fresh permutation each time"))
    return cases


def _mixup_public():
    g = np.random.default_rng(150)
    return [
        Case((g.random((20, 8, 8)), np.eye(10)[g.integers(0, 10, 20)]), {"alpha": 1.0, "rng": 0}, "20 images 8×8, 10 classes, α = 1"),
        Case((g.random((16, 5)), np.eye(4)[g.integers(0, 4, 16)]), {"alpha": 2.0, "rng": 1}, "16 feature vectors, α = 2"),
        Case((g.random((24, 3)), np.eye(3)[g.integers(0, 3, 24)]), {"rng": 7}, "default α = 0.2"),
        Case((g.random((6, 2)), np.eye(3)[[0, 1, 2, 0, 1, 2]]), {"alpha": 0.3, "draws": (1000, 400)},
             "400 calls, rng = 1000, 1001, …: λ ~ Beta(0.3, 0.3), a fresh permutation each time"),
    ]


mixup = Check(
    public=_mixup_public,
    hidden=_mixup_hidden,
    compare=Drawn(single=StructuredStatistics(structure=_triple_structure, statistics=_mixup_statistics,
                                              tolerance=_mix_tolerance),
                  statistics=_mixup_draw_statistics, tolerance=_mixup_draw_tolerance),
    call=call_draws,
    mistakes=[
        Mistake("labels mixed with λ and 1 − λ swapped", _mx_swapped,
                "Mix the labels exactly like the inputs: λ·y + (1 − λ)·y[perm]"),
        Mistake("labels not mixed", _mx_unmixed,
                "The target of a mixed input is the mixed target: λ·y + (1 − λ)·y[perm]"),
        Mistake("λ fixed at 1/2", _mx_half, "Draw λ ~ Beta(α, α) anew for every batch: rng.beta(alpha, alpha)"),
        Mistake("one λ per sample instead of one per batch", _mx_per_sample,
                "Draw a single λ ~ Beta(α, α) for the whole batch (and return it)"),
        Mistake("partners drawn with replacement", _mx_replace,
                "Pair the batch with a random permutation of itself: rng.permutation(N)"),
        Mistake("returns 1 − λ instead of λ", _mx_complement,
                "Return the λ that multiplies x (and y), the weight of the sample itself"),
        Mistake("α ignored: λ uniform on [0, 1]", _mx_uniform,
                "λ follows Beta(α, α): rng.beta(alpha, alpha) (α = 1 alone gives the uniform law)"),
        Mistake("partners always the batch reversed", _mx_reverse,
                "Pair the batch with a random permutation, drawn anew each call: rng.permutation(N)"),
    ],
    seeded=True,  # tuples, lists and dicts: the seeded re-run compares them element by element
)


def _cutmix_box(output, case):
    """``(t, b, l, r, partners, pasted_any)``: the box that holds every pasted pixel and, for
    each sample, the partner whose pixels best explain the box."""
    x, _ = _mix_inputs(case)
    xm = np.asarray(output[0], np.float64)
    n = x.shape[0]
    height, width = x.shape[-2:]
    changed = (xm != x).reshape(n, -1, height, width).any(axis=1)
    union = changed.any(axis=0)
    if union.any():
        rows, cols = np.flatnonzero(union.any(axis=1)), np.flatnonzero(union.any(axis=0))
        t, b, l, r = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    else:
        return 0, 0, 0, 0, np.arange(n), False
    box = (Ellipsis, slice(t, b), slice(l, r))
    d = ((xm[box].reshape(n, -1)[:, None, :] - x[box].reshape(n, -1)[None, :, :]) ** 2).sum(axis=2)
    return int(t), int(b), int(l), int(r), np.argmin(d, axis=1), True


_CUTMIX_DRAWS = ("share of the draws with the most frequent box centre (a uniform centre seldom repeats)",
                 "share of the draws with the most frequent pairing (a random permutation seldom repeats)")


def _cutmix_draw_statistics(outputs, case):
    centres, pairings = [], []
    for output in outputs:
        t, b, l, r, partners, pasted = _cutmix_box(output, case)
        if pasted:
            centres.append((t + b, l + r))
            pairings.append(tuple(partners))

    def most(values):
        return max(values.count(v) for v in set(values)) / len(values) if values else 0.0

    return dict(zip(_CUTMIX_DRAWS, (most(centres), most(pairings))))


def _cutmix_draw_tolerance(case):
    return dict.fromkeys(_CUTMIX_DRAWS, 0.25)


def _cutmix_statistics(output, case):
    x, y = _mix_inputs(case)
    xm, ym, lam = np.asarray(output[0], np.float64), np.asarray(output[1], np.float64), float(output[2])
    n = x.shape[0]
    height, width = x.shape[-2:]
    scale = max(1.0, float(np.abs(x).max()))
    changed = (xm != x).reshape(n, -1, height, width).any(axis=1)
    union = changed.any(axis=0)
    if union.any():
        rows, cols = np.flatnonzero(union.any(axis=1)), np.flatnonzero(union.any(axis=0))
        t, b, l, r = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    else:  # nothing pasted: an empty box (or every sample its own partner)
        t = b = l = r = 0
    box = (Ellipsis, slice(t, b), slice(l, r))
    flat_box = x[box].reshape(n, -1)
    flat_got = xm[box].reshape(n, -1)
    d = ((flat_got[:, None, :] - flat_box[None, :, :]) ** 2).sum(axis=2)
    partners = np.argmin(d, axis=1) if union.any() else np.arange(n)
    pasted = np.array(x, dtype=np.float64, copy=True)
    pasted[box] = x[partners][box]
    area = (b - t) * (r - l)
    return {
        "largest |x_mixed − (x with the box pasted from x[partner])|": float(np.abs(xm - pasted).max()) / scale,
        "the pasted pixels are not one box shared by the batch (1 = yes)": float(not union[t:b, l:r].all()),
        "|λ − (1 − pasted area / (H·W))|": abs(lam - (1.0 - area / (height * width))),
        "largest |y_mixed − (λ·y + (1 − λ)·y[partner])|": float(np.abs(ym - (lam * y + (1 - lam) * y[partners])).max()),
        "some sample is the partner of two samples (1 = yes; a permutation pairs each once)":
            _partner_counts(partners) if union.any() else 0.0,
    }


def _cutmix_variant(x, y_onehot, alpha=1.0, rng=None, *, lam_rule="area", labels="mixed", replace=False, per_sample=False,
                    centred=False, reverse=False):
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y_onehot, dtype=np.float64)
    gen = np.random.default_rng(rng)
    n = x.shape[0]
    height, width = x.shape[-2:]
    lam0 = float(gen.beta(alpha, alpha))
    perm = np.arange(n)[::-1] if reverse else gen.integers(0, n, n) if replace else gen.permutation(n)
    cut = math.sqrt(1 - lam0)
    ch, cw = int(height * cut), int(width * cut)
    out = x.copy()
    boxes = []
    for k in range(n if per_sample else 1):
        cy, cx = int(gen.integers(0, height)), int(gen.integers(0, width))
        if centred:
            cy, cx = height // 2, width // 2
        y1, y2 = min(max(cy - ch // 2, 0), height), min(max(cy + ch // 2, 0), height)
        x1, x2 = min(max(cx - cw // 2, 0), width), min(max(cx + cw // 2, 0), width)
        boxes.append((y1, y2, x1, x2))
        if per_sample:
            out[k, ..., y1:y2, x1:x2] = x[perm[k], ..., y1:y2, x1:x2]
        else:
            out[..., y1:y2, x1:x2] = x[perm][..., y1:y2, x1:x2]
    y1, y2, x1, x2 = boxes[0]
    if lam_rule == "area":
        lam = 1 - (y2 - y1) * (x2 - x1) / (height * width)
    elif lam_rule == "side":
        lam = 1 - (y2 - y1) / height
    else:
        lam = lam0
    ym = (lam * y + (1 - lam) * y[perm]) if labels == "mixed" else ((1 - lam) * y + lam * y[perm])
    return out, ym, float(lam)


_cm_side = variant(_cutmix_variant, lam_rule="side")
_cm_lam0 = variant(_cutmix_variant, lam_rule="draw")
_cm_swapped = variant(_cutmix_variant, labels="swapped")
_cm_replace = variant(_cutmix_variant, replace=True)
_cm_per_sample = variant(_cutmix_variant, per_sample=True)
_cm_centred = variant(_cutmix_variant, centred=True)
_cm_reverse = variant(_cutmix_variant, reverse=True)


def _cutmix_hidden(rng):
    cases = []
    n, c = _size(rng, 16, 28), _size(rng, 3, 10)
    cases.append(Case((rng.random((n, 16, 16)), _onehot(rng, n, c)), {"rng": _seed(rng)}, "(N, 16, 16), default α = 1"))
    n, c = _size(rng, 16, 24), _size(rng, 3, 10)
    cases.append(Case((rng.random((n, 3, 12, _size(rng, 14, 20))), _onehot(rng, n, c)), {"alpha": 0.5, "rng": _seed(rng)},
                      "(N, C, H, W) batch, non-square images"))
    n, c = _size(rng, 16, 24), _size(rng, 3, 8)
    cases.append(Case((rng.random((n, _size(rng, 10, 14), 9)), _onehot(rng, n, c), 2.0), {"rng": _seed(rng)},
                      "α positional (2)"))
    n, c = _size(rng, 16, 24), _size(rng, 3, 8)
    cases.append(Case((rng.random((n, 20, 20)), _onehot(rng, n, c)), {"alpha": 0.3, "rng": np.random.default_rng(_seed(rng))},
                      "α = 0.3, rng given as a numpy Generator"))
    n = _size(rng, 16, 24)
    cases.append(Case((rng.random((n, 8, 8)), rng.dirichlet(np.ones(4), n)), {"rng": _seed(rng)}, "soft targets"))
    n = _size(rng, 16, 24)
    cases.append(Case((rng.integers(0, 256, (n, 10, 10)).astype(np.uint8), _onehot(rng, n, 6)), {"rng": _seed(rng)},
                      "uint8 images (the result is float)"))
    n = _size(rng, 16, 24)
    cases.append(Case((rng.uniform(-1e6, 1e6, (n, 12, 12)), _onehot(rng, n, 3)), {"alpha": 1.0, "rng": _seed(rng)}, "±1e6 values"))
    n = _size(rng, 20, 30)
    cases.append(Case((rng.random((n, 2, 9, 11)), _onehot(rng, n, 5)), {"alpha": 4.0, "rng": _seed(rng)}, "α = 4, two channels"))
    for _ in range(3):
        n = _size(rng, 16, 24)
        cases.append(Case((rng.random((n, _size(rng, 10, 16), _size(rng, 10, 16))), _onehot(rng, n, 4)),
                          {"alpha": 1.0, "rng": _seed(rng)}, "random box and batch"))
    size = _size(rng, 12, 16)
    # a batch of 16: a permutation that leaves every sample in place (nothing pasted) is then
    # too rare to meet in 400 draws, so each draw's own properties can be checked as well
    cases.append(Case((rng.random((16, size, size)), np.eye(4)[np.arange(16) % 4]), {"alpha": 1.0, "draws": (_seed(rng), 400)},
                      "400 calls, one seed each: the box's centre uniform, a fresh permutation each time"))
    return cases


def _cutmix_public():
    g = np.random.default_rng(160)
    return [
        Case((g.random((20, 16, 16)), np.eye(10)[g.integers(0, 10, 20)]), {"rng": 0}, "20 images 16×16, α = 1"),
        Case((g.random((16, 3, 10, 12)), np.eye(4)[g.integers(0, 4, 16)]), {"alpha": 0.5, "rng": 2}, "(16, 3, 10, 12) batch, α = 0.5"),
        Case((g.random((18, 12, 12)), np.eye(5)[g.integers(0, 5, 18)]), {"rng": 4}, "18 images 12×12"),
        Case((g.random((16, 9, 14)), np.eye(3)[g.integers(0, 3, 16)]), {"alpha": 2.0, "rng": 5}, "16 images 9×14, α = 2"),
        Case((g.random((16, 12, 14)), np.eye(4)[np.arange(16) % 4]), {"alpha": 1.0, "draws": (3000, 400)},
             "400 calls, rng = 3000, 3001, …: the box's centre uniform, a fresh permutation each time"),
    ]


cutmix = Check(
    public=_cutmix_public,
    hidden=_cutmix_hidden,
    compare=Drawn(single=StructuredStatistics(structure=_triple_structure, statistics=_cutmix_statistics,
                                              tolerance=_mix_tolerance),
                  statistics=_cutmix_draw_statistics, tolerance=_cutmix_draw_tolerance),
    call=call_draws,
    mistakes=[
        Mistake("λ from the side of the box, not its area", _cm_side,
                "Weight the labels by AREA: λ = 1 − (y2 − y1)·(x2 − x1) / (H·W)"),
        Mistake("λ taken from the Beta draw, not from the clipped box", _cm_lam0,
                "After clipping the box at the border, recompute λ = 1 − (pasted area)/(H·W): the labels must match the pixels"),
        Mistake("labels mixed with λ and 1 − λ swapped", _cm_swapped,
                "λ is the share of the sample's OWN pixels: y_mixed = λ·y + (1 − λ)·y[perm]"),
        Mistake("partners drawn with replacement", _cm_replace,
                "Pair the batch with a random permutation of itself: rng.permutation(N)"),
        Mistake("a different box for every sample", _cm_per_sample,
                "Draw one box for the whole batch (one λ): every sample gets the same box from its partner"),
        Mistake("box always at the image's centre", _cm_centred,
                "Draw the box's centre anew each call, uniform over the image: rng.integers(0, H), rng.integers(0, W)"),
        Mistake("partners always the batch reversed", _cm_reverse,
                "Pair the batch with a random permutation, drawn anew each call: rng.permutation(N)"),
    ],
    seeded=True,  # tuples, lists and dicts: the seeded re-run compares them element by element
)


# --------------------------------------------------------------------------------------------
# train.random_search (§12.5.1)
# --------------------------------------------------------------------------------------------
def _rs_structure(got, expected, case):
    space = case.args[0]
    trials = int(_arg(case, 1, "trials"))
    if not isinstance(got, list):
        return f"expected a list of {trials} dicts, got {type(got).__name__}"
    if len(got) != trials:
        return f"expected {trials} settings (one per trial), got {len(got)}"
    for i, setting in enumerate(got):
        if not isinstance(setting, dict):
            return f"setting [{i}] must be a dict {{name: value}}, got {type(setting).__name__}"
        if set(setting) != set(space):
            return f"setting [{i}] must have the keys {sorted(space)}, got {sorted(setting)}"
    return None


def _choice_key(value):
    """A hashable key telling choices apart like ``==`` does, but keeping True ≠ 1 and
    treating NumPy scalars (what ``rng.choice`` returns) like the Python values they hold."""
    if isinstance(value, np.generic):
        value = value.item()
    try:
        hash(value)
    except TypeError:
        return ("unhashable", repr(value))
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return (type(value).__name__, value)
    if isinstance(value, numbers.Number):
        return ("number", value)
    return (type(value).__name__, value)


def _rs_statistics(output, case):
    space = case.args[0]
    stats = {}
    if not output:
        return stats  # no trials: nothing to measure (the structure was checked)
    for name, spec in space.items():
        values = [s[name] for s in output]
        if isinstance(spec, dict):
            low, high, log = float(spec["low"]), float(spec["high"]), bool(spec.get("log", False))
            try:
                v = np.array(values, dtype=np.float64)
            except (TypeError, ValueError):
                stats[f"{name}: fraction of values that are not numbers"] = 1.0
                continue
            stats[f"{name}: fraction of values outside [low, high]"] = float(np.mean((v < low * (1 - 1e-12)) | (v > high * (1 + 1e-12)) | ~np.isfinite(v)))
            with np.errstate(all="ignore"):
                u = (np.log(v) - math.log(low)) / (math.log(high) - math.log(low)) if log else (v - low) / (high - low)
            where = "log-scale " if log else ""
            stats[f"{name}: mean {where}position in the range (0 = low, 1 = high)"] = float(np.mean(u))
            stats[f"{name}: standard deviation of the {where}position"] = float(np.std(u))
            stats[f"{name}: fraction in the lowest tenth of the {where}range"] = float(np.mean(u < 0.1))
        else:
            index = {}
            for k, choice in enumerate(spec):
                index.setdefault(_choice_key(choice), k)
            picked = np.array([index.get(_choice_key(v), -1) for v in values])
            stats[f"{name}: fraction of values that are not one of the choices"] = float(np.mean(picked < 0))
            counts = np.bincount(picked[picked >= 0], minlength=len(spec)) / len(values)
            for k, choice in enumerate(spec):
                stats[f"{name}: fraction of trials with choice [{k}] = {choice!r}"] = float(counts[k])
    return stats


def _rs_tolerance(case):
    space = case.args[0]
    trials = max(1, int(_arg(case, 1, "trials")))
    tol = {}
    for name, spec in space.items():
        if isinstance(spec, dict):
            where = "log-scale " if spec.get("log", False) else ""
            tol[f"{name}: fraction of values outside [low, high]"] = 0.0
            tol[f"{name}: fraction of values that are not numbers"] = 0.0
            tol[f"{name}: mean {where}position in the range (0 = low, 1 = high)"] = 6 * math.sqrt(2 / 12 / trials)
            # the SD of a sample standard deviation of U(0, 1) values is ≈ 0.0745/√n
            tol[f"{name}: standard deviation of the {where}position"] = 6 * _SQRT2 * 0.0745 / math.sqrt(trials)
            tol[f"{name}: fraction in the lowest tenth of the {where}range"] = 6 * math.sqrt(2 * 0.09 / trials)
        else:
            q = 1.0 / len(spec)
            tol[f"{name}: fraction of values that are not one of the choices"] = 0.0
            for k, choice in enumerate(spec):
                tol[f"{name}: fraction of trials with choice [{k}] = {choice!r}"] = 6 * math.sqrt(2 * q * (1 - q) / trials)
    return tol


def _rs_variant(space, trials, rng=None, *, log_as_uniform=False, exponents=False, shared=False, last_missing=False,
                uniform_as_log=False, fixed_seed=False):
    gen = np.random.default_rng(0 if fixed_seed else rng)
    draws = 1 if shared else trials
    columns = {}
    for name, spec in space.items():
        if isinstance(spec, dict):
            low, high, log = spec["low"], spec["high"], spec.get("log", False)
            if log and exponents:
                values = 10.0 ** gen.uniform(low, high, draws)
            elif (log and not log_as_uniform) or (not log and uniform_as_log and low > 0):
                values = np.exp(gen.uniform(math.log(low), math.log(high), draws))
            else:
                values = gen.uniform(low, high, draws)
            columns[name] = [float(v) for v in values]
        else:
            picks = gen.integers(0, max(1, len(spec) - 1) if last_missing else len(spec), draws)
            columns[name] = [spec[int(i)] for i in picks]
    return [{name: columns[name][0 if shared else t] for name in space} for t in range(trials)]


_rs_log_uniform = variant(_rs_variant, log_as_uniform=True)
_rs_exponents = variant(_rs_variant, exponents=True)
_rs_shared = variant(_rs_variant, shared=True)
_rs_last_missing = variant(_rs_variant, last_missing=True)
_rs_uniform_log = variant(_rs_variant, uniform_as_log=True)
_rs_fixed_seed = variant(_rs_variant, fixed_seed=True)


def _rs_hidden(rng):
    def lr_range():
        lo = float(10.0 ** -int(rng.integers(4, 6)))
        return {"low": lo, "high": float(10.0 ** -int(rng.integers(0, 2))), "log": True}

    cases = []
    cases.append(Case(({"lr": lr_range(), "dropout": {"low": 0.0, "high": 0.5}}, 1000), {"rng": _seed(rng)},
                      "a log-uniform and a uniform range"))
    cases.append(Case(({"batch": [16, 32, 64, 128], "wd": {"low": 1e-6, "high": 1e-2, "log": True}}, 1000), {"rng": _seed(rng)},
                      "choices and a log range"))
    cases.append(Case(({"optimizer": ["sgd", "adam", "adamw"], "momentum": {"low": 0.8, "high": 0.99, "log": False}}, 1000),
                      {"rng": np.random.default_rng(_seed(rng))}, "string choices, 'log': False, rng as a Generator"))
    cases.append(Case(({"act": ("relu", "gelu"), "scale": {"low": 0.5, "high": 4.0}}, 1000), {"rng": _seed(rng)},
                      "choices as a tuple, uniform range with low > 0"))
    cases.append(Case(({"lr": lr_range()}, 1200), {"rng": _seed(rng)}, "a single log-uniform hyper-parameter"))
    cases.append(Case(({"k": [1, 3, 5, 7, 9, 11], "eps": {"low": 0.0, "high": 0.3}, "lr": lr_range()}, 1200), {"rng": _seed(rng)},
                      "three hyper-parameters"))
    cases.append(Case(({"flag": [True, False], "aug": [None, "crop"]}, 1000), {"rng": _seed(rng)}, "booleans and None as choices"))
    cases.append(Case(({"x": {"low": -3.0, "high": 2.0}}, 1000), {"rng": _seed(rng)}, "a uniform range with negative low"))
    cases.append(Case(({"only": ["a"], "lr": lr_range()}, 500), {"rng": _seed(rng)}, "a single choice"))
    cases.append(Case(({"lr": lr_range(), "m": [0.0, 0.9]}, 0), {"rng": _seed(rng)}, "zero trials: an empty list"))
    cases.append(Case(({"lr": lr_range(), "width": [32, 64, 128]}, 4), {"draws": (_seed(rng), 20)},
                      "20 searches of 4 trials, rng = r, r + 1, …: other settings for another seed"))
    return cases


random_search = Check(
    public=[
        Case(({"lr": {"low": 1e-4, "high": 1e-1, "log": True}, "batch": [16, 32, 64]}, 1000), {"rng": 0},
             "log-uniform lr and a choice of batch size, 1000 trials"),
        Case(({"dropout": {"low": 0.0, "high": 0.5}, "wd": {"low": 1e-5, "high": 1e-2, "log": True}}, 1000), {"rng": 1},
             "a uniform and a log-uniform range"),
        Case(({"opt": ["sgd", "adam"], "scale": {"low": 1.0, "high": 10.0, "log": False}}, 1000), {"rng": 2},
             "string choices and a range with 'log': False"),
        Case(({"lr": {"low": 1e-4, "high": 1e-1, "log": True}, "batch": [16, 32, 64]}, 4), {"draws": (500, 20)},
             "20 searches of 4 trials, rng = 500, 501, …: other settings for another seed"),
    ],
    hidden=_rs_hidden,
    compare=Drawn(single=StructuredStatistics(structure=_rs_structure, statistics=_rs_statistics, tolerance=_rs_tolerance)),
    call=call_draws,
    mistakes=[
        Mistake("log-uniform range sampled uniformly", _rs_log_uniform,
                "With 'log': True draw the LOGARITHM uniformly: exp(rng.uniform(log(low), log(high)))"),
        Mistake("low and high taken as exponents (10 ** uniform(low, high))", _rs_exponents,
                "low and high are the values themselves: exp(rng.uniform(log(low), log(high))) stays in [low, high]"),
        Mistake("one setting repeated for every trial", _rs_shared,
                "Draw new values for every trial"),
        Mistake("last choice never drawn (integers(0, len − 1))", _rs_last_missing,
                "rng.integers(0, n) already excludes n: use rng.integers(0, len(choices)) (or rng.choice)"),
        Mistake("uniform range sampled log-uniformly", _rs_uniform_log,
                "Without 'log' (or with 'log': False) the value is uniform on [low, high]: rng.uniform(low, high)"),
        Mistake("rng ignored: the same search for every seed", _rs_fixed_seed,
                "Draw from the generator the caller gives, np.random.default_rng(rng): a generator made with a "
                "fixed seed inside the function returns the same settings on every call"),
    ],
    seeded=True,  # tuples, lists and dicts: the seeded re-run compares them element by element
)


# --------------------------------------------------------------------------------------------
# train.ensemble_predict (§12.5.2)
# --------------------------------------------------------------------------------------------
def _stack(logits_list):
    return np.stack([np.asarray(v, dtype=np.float64) for v in logits_list]) if isinstance(logits_list, (list, tuple)) \
        else np.asarray(logits_list, dtype=np.float64)


@mistake("summed instead of averaged",
         "Average the logits: divide the sum by the number of models (np.mean(..., axis=0))")
def _ep_sum(logits_list):
    return _stack(logits_list).sum(axis=0)


@mistake("averaged softmax probabilities instead of logits",
         "This ensemble averages the LOGITS (scores before the softmax)")
def _ep_probs(logits_list):
    s = _stack(logits_list)
    e = np.exp(s - s.max(axis=-1, keepdims=True))
    return (e / e.sum(axis=-1, keepdims=True)).mean(axis=0)


@mistake("only the first model", "Average over all the models of the list")
def _ep_first(logits_list):
    return _stack(logits_list)[0]


@mistake("maximum over the models", "Average the models' logits, do not take their maximum")
def _ep_max(logits_list):
    return _stack(logits_list).max(axis=0)


@mistake("median over the models", "Use the mean of the logits, not their median")
def _ep_median(logits_list):
    return np.median(_stack(logits_list), axis=0)


def _ep_hidden(rng):
    def member(n, c, scale=3.0):
        return np.round(rng.normal(0, scale, (n, c)), 3)

    cases = []
    n, c, m = _size(rng, 3, 12), _size(rng, 2, 10), _size(rng, 3, 7)
    cases.append(Case(([member(n, c) for _ in range(m)],), {}, f"{m} models, (N, C) logits"))
    n, c = _size(rng, 3, 12), _size(rng, 2, 10)
    cases.append(Case(([member(n, c) for _ in range(2)],), {}, "two models"))
    n, c = _size(rng, 3, 8), _size(rng, 2, 6)
    cases.append(Case((tuple(member(n, c) for _ in range(4)),), {}, "a tuple of four"))
    n, c = _size(rng, 3, 8), _size(rng, 2, 6)
    cases.append(Case((np.stack([member(n, c) for _ in range(5)]),), {}, "an (M, N, C) array"))
    c = _size(rng, 3, 10)
    cases.append(Case(([np.round(rng.normal(0, 2, c), 3) for _ in range(3)],), {}, "one input: (C,) logits"))
    n, c = _size(rng, 3, 8), _size(rng, 2, 6)
    cases.append(Case(([member(n, c, 1e6) for _ in range(3)],), {}, "huge logits (±1e6)"))
    n, c = _size(rng, 3, 8), _size(rng, 2, 6)
    cases.append(Case(([member(n, c).astype(np.float32) for _ in range(3)],), {}, "float32 logits"))
    n, c = _size(rng, 3, 8), _size(rng, 2, 6)
    cases.append(Case(([member(n, c).tolist() for _ in range(3)],), {}, "nested lists"))
    n, c = _size(rng, 3, 8), _size(rng, 2, 6)
    base = member(n, c)
    cases.append(Case(([base + k for k in (0.0, 5.0, -2.0, 1.0)],), {}, "members that differ by a constant"))
    n, c = _size(rng, 2, 5), _size(rng, 2, 4)
    cases.append(Case(([member(n, c) for _ in range(6)],), {}, "six models"))
    return cases


ensemble_predict = Check(
    public=[
        Case(([np.array([[2.0, 0.0, -1.0], [0.5, 0.5, 3.0]]), np.array([[0.0, 1.0, 1.0], [1.0, -1.0, 0.0]]),
               np.array([[1.0, 4.0, 0.0], [-2.0, 0.0, 0.0]])],), {}, "three models, two inputs, three classes"),
        Case(([np.array([[10.0, 0.0], [0.0, 1.0]]), np.array([[0.0, 3.0], [2.0, 0.0]])],), {}, "two models"),
    ],
    hidden=_ep_hidden,
    compare=close(rtol=1e-9, atol=1e-12, kind="f", scaled=True),
    mistakes=[_ep_sum, _ep_probs, _ep_first, _ep_max, _ep_median],
)


# --------------------------------------------------------------------------------------------
# train.ema_update (§12.5.3)
# --------------------------------------------------------------------------------------------
def _ema_apply(ema_params, params, rule):
    if isinstance(ema_params, (list, tuple)):
        return type(ema_params)(rule(np.asarray(a, dtype=np.float64), np.asarray(p, dtype=np.float64))
                                for a, p in zip(ema_params, params))
    return rule(np.asarray(ema_params, dtype=np.float64), np.asarray(params, dtype=np.float64))


@mistake("decay applied inverted ((1 − β)·ema + β·params)",
         "β weighs the PAST: ema_new = β·ema + (1 − β)·params (β = 0.999 moves the average slowly)")
def _ema_inverted(ema_params, params, decay=0.999):
    return _ema_apply(ema_params, params, lambda a, p: (1 - decay) * a + decay * p)


@mistake("plain mean of the two (decay ignored)", "Weigh the two by the decay: β·ema + (1 − β)·params")
def _ema_plain_mean(ema_params, params, decay=0.999):
    return _ema_apply(ema_params, params, lambda a, p: 0.5 * (a + p))


@mistake("current weights not scaled by (1 − β)", "The two weights must sum to 1: β·ema + (1 − β)·params")
def _ema_no_complement(ema_params, params, decay=0.999):
    return _ema_apply(ema_params, params, lambda a, p: decay * a + p)


@mistake("returns the current weights (no averaging)", "Return the new running average, not the current weights")
def _ema_params_only(ema_params, params, decay=0.999):
    return _ema_apply(ema_params, params, lambda a, p: p.copy())


def _ema_hidden(rng):
    def arr(*shape, scale=1.0):
        return np.round(rng.normal(0, scale, shape), 4)

    def decay_():
        return _round(rng.uniform(0.8, 0.999), 4)

    cases = []
    n = _size(rng, 3, 9)
    cases.append(Case((arr(n), arr(n), decay_()), {}, "a vector of parameters"))
    h, w = _size(rng, 2, 5), _size(rng, 2, 5)
    cases.append(Case(([arr(h, w), arr(w)], [arr(h, w), arr(w)]), {"decay": decay_()}, "a list [W, b]"))
    cases.append(Case(((arr(3, 2), arr(2)), (arr(3, 2), arr(2)), decay_()), {}, "a tuple (W, b)"))
    cases.append(Case((arr(4), arr(4)), {}, "default decay 0.999"))
    cases.append(Case((arr(5), arr(5), 0.0), {}, "decay 0: the current weights"))
    cases.append(Case((arr(5), arr(5), 1.0), {}, "decay 1: the average never moves"))
    cases.append(Case((arr(2, 3, scale=1e6), arr(2, 3, scale=1e6), decay_()), {}, "±1e6 values"))
    cases.append(Case((arr(6), arr(6), _round(rng.uniform(0.1, 0.4), 3)), {}, "a small decay"))
    cases.append(Case(([np.float64(rng.normal())], [np.float64(rng.normal())], 0.9), {}, "a single number"))
    cases.append(Case((arr(3, 3).astype(np.float32), arr(3, 3).astype(np.float32), decay_()), {}, "float32 arrays"))
    return cases


ema_update = Check(
    public=[
        Case((np.array([1.0, 1.0, -2.0]), np.array([0.0, 2.0, 4.0]), 0.9), {}, "three parameters, decay 0.9"),
        Case(([np.array([[1.0, 2.0], [3.0, 4.0]]), np.array([0.5, -0.5])],
              [np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([1.5, 0.5])], 0.75), {}, "a list [W, b], decay 0.75"),
        Case((np.array([10.0, -10.0]), np.array([0.0, 0.0])), {}, "default decay 0.999"),
    ],
    hidden=_ema_hidden,
    compare=_UPDATE,
    mistakes=[_ema_inverted, _ema_plain_mean, _ema_no_complement, _ema_params_only],
)


# --------------------------------------------------------------------------------------------
# §12.5.4 the measured exercise: a CNN trained on the digits, graded by its held-out accuracy
# --------------------------------------------------------------------------------------------
from ..grading.runtime.adapters import train_then_predict  # noqa: E402
from ..grading.measured import MeasuredCase, Scale  # noqa: E402
from ._digits import ACCURACY_SCALE, BUDGET_SECONDS, held_out_split, public_split  # noqa: E402
from ._digits import train_cnn as _train_cnn  # noqa: E402

#: the published scale the grader applies (its corners: :data:`cvkit.train._digits.ACCURACY_SCALE`)
ACCURACY = Scale(ACCURACY_SCALE)


def _digits_public() -> list[Case]:
    x_train, y_train, x_eval, y_eval = public_split()
    return [MeasuredCase((x_train, y_train, x_eval, 0), {},
                         f"cvkit.data.digits' split in 8-bit grey levels: {len(y_train)} to train, "
                         f"{len(y_eval)} to predict", truth=y_eval)]


def _digits_hidden(rng: np.random.Generator) -> list[Case]:
    seed = _seed(rng)
    x_train, y_train, x_eval, y_eval = held_out_split(seed)
    return [MeasuredCase((x_train, y_train, x_eval, _seed(rng)), {},
                         f"your own split of the digits, in the grey levels of an unknown camera: {len(y_train)} to "
                         f"train, {len(y_eval)} perturbed digits to predict", truth=y_eval)]


class HeldOutAccuracy(Comparator):
    """Passes when the predicted labels reach the top of :data:`ACCURACY` on the case's
    ``truth``; the case's credit follows the scale below it. The
    ``expected`` output (the reference recipe's predictions) only serves for comparison in
    the message: the answer is judged by what it achieves, not by its agreement."""

    judges_alone = True  # the verdict is what the output achieves on the case's truth

    top = ACCURACY.top

    @staticmethod
    def accuracy(got: Any, case: Any) -> float:
        truth = np.asarray(getattr(case, "truth", np.zeros(0)))
        labels = np.asarray(got)
        if labels.shape != truth.shape or truth.size == 0:
            return 0.0
        return float(np.mean(labels == truth))

    def __call__(self, got: Any, expected: Any, case: Any = None) -> Mismatch | None:
        achieved = self.accuracy(got, case)
        if achieved >= self.top:
            return None
        truth = np.asarray(getattr(case, "truth", np.zeros(0)))
        labels = np.asarray(got)
        if labels.shape != truth.shape:
            return Mismatch(f"predict returned shape {labels.shape}; expected one label per image, {truth.shape}")
        words = ACCURACY.shortfall(achieved, "accuracy", f" on {truth.size} digits")
        reference = self.accuracy(expected, case)
        if reference:
            words += f" The reference recipe reached {100 * reference:.2f} % on the same digits."
        if labels.size and np.bincount(labels.astype(np.int64).clip(0), minlength=1).max() > 0.5 * labels.size:
            words += (" Most predictions are one class: the training diverged or never started — normalise "
                      "the inputs (their grey levels can be in the hundreds) and try a smaller learning rate.")
        return Mismatch(words)


def _digits_credit(got: Any, case: Any) -> float:
    return ACCURACY.credit(HeldOutAccuracy.accuracy(got, case))


def _digits_accuracy(got: Any, case: Any) -> float:
    return 100.0 * HeldOutAccuracy.accuracy(got, case)


@mistake("no normalisation (raw grey levels, no batch norm)",
         "Standardise the inputs with the training set's mean and standard deviation, and keep the batch norm "
         "layers: with grey levels in the hundreds the first steps blow the weights up")
def _digits_no_normalisation(x_train, y_train, rng=None):
    return _train_cnn(x_train, y_train, rng, normalise=False)


@mistake("learning rate 100 times too large",
         "Divide the learning rate: a sweep on a validation split (§12.2) finds the largest rate that still "
         "decreases the loss steadily")
def _digits_lr_times_100(x_train, y_train, rng=None):
    return _train_cnn(x_train, y_train, rng, lr=100 * 0.3)


train_digits = Check(
    public=_digits_public,
    hidden=_digits_hidden,
    compare=HeldOutAccuracy(),
    mistakes=[_digits_no_normalisation, _digits_lr_times_100],
    call=train_then_predict,
    arg_names=("x_train", "y_train", "x_eval", "seed"),
    output_names=("labels",),
    time_limit=BUDGET_SECONDS,
    credit=_digits_credit,
    measure=Measure("accuracy", _digits_accuracy, "%"),
)
