"""Checks of Chapters 10–11 (``cvkit.nn``): cases, comparators and mistake banks.

One module-level :class:`~cvkit.grading.Check` per algorithm, named like the reference function
(``cvkit.nn.checks:conv2d_forward`` grades ``nn.conv2d_forward``).

*Forward passes* return ``(out, cache)``. Their checks compare ``out`` and the entries of the
cache the catalog names: the forward's arguments under their own names (defaults included)
and what the layer adds (``out`` for the sigmoid, the new running statistics of batch norm,
the dropout ``mask``). Extra cache entries are allowed and ignored: the check's ``call``
(e.g. :func:`call_conv2d_forward`) keeps only the named ones, so only plain data leaves the
student's process.

*Backward passes* are graded on caches made by the **reference** forward, exactly as the
catalog specifies them: a student's backward may read only the named entries (and must
recompute anything else, such as batch statistics or the arg-max of a pooling window).

Public cases are tiny and fixed, with distinct, asymmetric values, and already tell every
mistake of a bank from the right answer. Hidden cases (8–14 per check, drawn from the grading
seed) add the awkward inputs: exact zeros for the ReLU gradient at 0, ties inside pooling
windows, overlapping windows, sizes the stride does not divide, padding on non-square inputs
and kernels, uint8 inputs, evaluation mode, extreme values (σ(±1000)), momentum ≠ ½,
low-variance channels where ε matters, square weight matrices on which a transposed ``W``
still runs... so that each mistake fails even where it is right on ordinary data.

``nn.dropout_forward`` draws random numbers: it is ``seeded`` and judged by
:class:`DropoutStatistics` (the kept fraction within binomial limits, the kept units exactly
``x / p_keep``, the dropped ones 0, the mask matching, identity in evaluation).
``nn.architecture_spec`` is judged by :class:`SpecAccounting`, which measures the returned
spec (parameters, FLOPs, output shape, number of layers of each type) with the reference
accounting, so any spec with the right structure passes. The spec itself (plain lists and
dicts) is what crosses the grading sandbox; the accounting runs outside it.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..grading import Case, Check, Comparator, Drawn, Mismatch, Mistake, close, mistake
from ..grading.casekit import distinct, variant
from ..grading.compare import binomial_variance_tolerance
from ..grading.casekit import rounded as _round
from ..grading.casekit import seed as _any_seed
from ..grading.casekit import size as _size
from ..grading.casekit import uniform as _u
from ..grading.runtime.adapters import (  # noqa: F401  (CACHE_KEYS is part of this module's API)
    CACHE_KEYS, call_batchnorm2d_forward, call_conv2d_forward, call_dropout_forward, call_global_avg_pool_forward,
    call_leaky_relu_forward, call_linear_forward, call_maxpool2d_forward, call_relu_forward,
    call_residual_block_forward, call_sigmoid_forward,
)
from . import _architectures as _arch
from ._activations import leaky_relu_forward as _leaky_forward
from ._activations import relu_forward as _relu_forward
from ._activations import sigmoid_forward as _sigmoid_forward
from ._conv import conv2d_backward as _conv_backward
from ._conv import conv2d_forward as _conv_forward
from ._linear import linear_forward as _linear_forward
from ._norm import batchnorm2d_backward as _bn_backward
from ._norm import batchnorm2d_forward as _bn_forward
from ._norm import dropout_forward as _dropout_forward
from ._pool import global_avg_pool_forward as _gap_forward
from ._pool import maxpool2d_forward as _pool_forward
from ._residual import residual_block_backward as _res_backward
from ._residual import residual_block_forward as _res_forward

__all__ = [
    "relu_forward", "relu_backward", "sigmoid_forward", "sigmoid_backward",
    "leaky_relu_forward", "leaky_relu_backward", "linear_forward", "linear_backward",
    "conv_output_size", "receptive_field", "conv2d_forward", "conv2d_backward",
    "maxpool2d_forward", "maxpool2d_backward", "global_avg_pool_forward", "global_avg_pool_backward",
    "batchnorm2d_forward", "batchnorm2d_backward", "dropout_forward", "dropout_backward",
    "residual_block_forward", "residual_block_backward", "architecture_spec", "count_parameters",
    "count_flops", "Nested", "IntegerResult", "DropoutStatistics", "CACHE_KEYS",
]

#: the cache entries each forward must hold (its arguments and what the layer adds)

_LAYERS = (
    "nn.conv2d_forward", "nn.conv2d_backward", "nn.batchnorm2d_forward", "nn.batchnorm2d_backward",
    "nn.relu_forward", "nn.relu_backward",
)


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
def _kind(value) -> str:
    if isinstance(value, dict):
        return "a dict"
    if isinstance(value, (tuple, list)):
        return f"a {type(value).__name__} of {len(value)}"
    if value is None:
        return "None"
    return type(value).__name__


@dataclass
class Nested(Comparator):
    """Tuples, lists and dicts compared entry by entry, arrays and numbers with ``leaf``.

    A dict must hold every key of the expected dict (extra keys are ignored). ``names`` label
    the entries of a top-level tuple in messages (``"dx"``, ``"dw"``, ...).
    """

    leaf: Comparator
    names: tuple = ()

    def describe(self) -> str:
        return self.leaf.describe()

    def __call__(self, got, expected, case=None):
        return self._compare(got, expected, case, "", top=True)

    def _compare(self, got, expected, case, path, top=False):
        if isinstance(expected, dict):
            if not isinstance(got, dict):
                what = path or "your result"
                return Mismatch(f"{what} must be a dict, got {_kind(got)}")
            for key, value in expected.items():
                where = f"{path}[{key!r}]" if path else f"[{key!r}]"
                if key not in got:
                    return Mismatch(f"{path or 'the dict'} lacks the key {key!r}")
                mismatch = self._compare(got[key], value, case, where)
                if mismatch is not None:
                    return mismatch
            return None
        if isinstance(expected, (tuple, list)):
            if not isinstance(got, (tuple, list)) or len(got) != len(expected):
                what = path or "your function"
                if top and self.names:
                    want = f"a tuple ({', '.join(self.names)})"
                else:
                    want = f"a tuple of {len(expected)}"
                return Mismatch(f"{what} must return {want}, got {_kind(got)}")
            for i, (g, e) in enumerate(zip(got, expected)):
                name = self.names[i] if top and i < len(self.names) else f"{path}[{i}]"
                mismatch = self._compare(g, e, case, name)
                if mismatch is not None:
                    return mismatch
            return None
        if isinstance(got, (dict, tuple, list)) and not isinstance(expected, (tuple, list, dict)):
            if not (isinstance(got, (tuple, list)) and np.ndim(expected) > 0):
                return Mismatch(f"{path or 'your result'} must be {'an array' if np.ndim(expected) else 'a number'}, "
                                f"got {_kind(got)}")
        mismatch = self.leaf(got, expected, case)
        if mismatch is not None and path:
            mismatch.message = f"{path}: {mismatch.message}"
        return mismatch


@dataclass
class IntegerResult(Comparator):
    """An exact integer: the value must match, and a right value must be an int."""

    def describe(self) -> str:
        return "exact integer"

    def __call__(self, got, expected, case=None):
        if isinstance(got, (bool, np.bool_)) or not isinstance(got, (int, float, np.integer, np.floating)):
            return Mismatch(f"expected a single number, got {_kind(got)}")
        if not math.isfinite(float(got)) or float(got) != float(expected):
            return Mismatch(f"yours {got!r}, expected {expected!r}")
        if isinstance(expected, (int, np.integer)) and not isinstance(got, (int, np.integer)):
            return Mismatch(f"the value {got!r} is right but must be an int (use // for the floor division), "
                            f"not {type(got).__name__}")
        return None


#: element-wise layers: loop and vectorised versions agree to round-off
_TIGHT = close(rtol=1e-9, atol=1e-12, scaled=True)
#: sums of products (convolutions, batch norm): round-off relative to the data's scale
_SUMS = close(rtol=1e-7, atol=1e-9, scaled=True)


# --------------------------------------------------------------------------------------------
# how cases call forward passes: (out, the named cache entries)
# --------------------------------------------------------------------------------------------
def _forward_compare(leaf):
    return Nested(leaf, names=("out", "cache"))


# --------------------------------------------------------------------------------------------
# case helpers
# --------------------------------------------------------------------------------------------
class CacheDict(dict):
    """A cache or parameter dict with a short description in reports (plain dict otherwise)."""

    def __repr__(self):
        parts = []
        for k, v in self.items():
            if isinstance(v, np.ndarray):
                parts.append(f"{k}: {v.shape}" if v.size > 4 else f"{k}: {np.round(v, 4).tolist()}")
            elif isinstance(v, dict):
                parts.append(f"{k}: dict of {len(v)}")
            else:
                parts.append(f"{k}: {v!r}")
        return "{" + ", ".join(parts) + "}"

    def __deepcopy__(self, memo):
        return CacheDict({k: copy.deepcopy(v, memo) for k, v in self.items()})


class SpecList(list):
    """A spec (list of layer dicts) with a short description in reports."""

    def __repr__(self):
        kinds = [layer.get("type", "?") if isinstance(layer, dict) else "?" for layer in self]
        shown = ", ".join(kinds[:8]) + (", ..." if len(kinds) > 8 else "")
        return f"spec of {len(self)} layers ({shown})"

    def __deepcopy__(self, memo):
        return SpecList(copy.deepcopy(list(self), memo))


#: seeds of the random layers' cases: 31 bits
_seed = partial(_any_seed, high=2**31)


def _normal(rng, shape, scale: float = 1.0, decimals: int = 3) -> np.ndarray:
    return _round(rng.normal(0.0, scale, shape), decimals)


def _distinct(shape, seed: int = 3, offset: float = 0.0, scale: float = 0.25) -> np.ndarray:
    """Distinct values (a shuffled ramp, centred near 0): every position shows in the output."""
    values = distinct(shape, seed=seed, dtype=np.int64)
    return (values - values.size // 2) * scale + offset


def _with_zeros(rng, shape, fraction: float = 0.3) -> np.ndarray:
    x = _normal(rng, shape, 2.0, 1)
    x[rng.random(shape) < fraction] = 0.0
    return x


def _cache(c: dict) -> CacheDict:
    return CacheDict(c)


def _backward_cases(forward, cases, rng, fixed, drawn) -> list[Case]:
    """The cases of a layer's backward pass: each case of its forward pass run through the
    reference ``forward``, with an upstream gradient of the output's shape, ``fixed(shape, i)``
    for the i-th public case (``rng`` is None) or ``drawn(rng, shape)`` for a hidden one."""
    out = []
    for i, case in enumerate(cases):
        y, cache = forward(*case.args, **case.kwargs)
        dout = fixed(y.shape, i) if rng is None else drawn(rng, y.shape)
        out.append(Case((dout, _cache(cache)), {}, case.label))
    return out


def _f(a) -> np.ndarray:
    return np.asarray(a, dtype=np.float64)


# ============================================================================================
# activations (§10.5.3–10.5.4)
# ============================================================================================
@mistake("returns the mask x > 0 instead of max(0, x)",
         "ReLU keeps the positive values themselves: out = np.maximum(x, 0)")
def _relu_mask_only(x):
    x = _f(x)
    return (x > 0).astype(np.float64), {"x": x}


@mistake("absolute value instead of max(0, x)", "Negative inputs become 0, not their magnitude: np.maximum(x, 0)")
def _relu_abs(x):
    x = _f(x)
    return np.abs(x), {"x": x}


@mistake("leaky slope for negatives (that is leaky ReLU)", "Plain ReLU sets every negative input to exactly 0")
def _relu_leaky(x):
    x = _f(x)
    return np.where(x >= 0, x, 0.01 * x), {"x": x}


@mistake("no cache returned (out only)",
         "Return the pair (out, cache) with cache = {'x': x}: the backward pass needs x")
def _relu_no_cache(x):
    return np.maximum(_f(x), 0.0)


def _activation_hidden(rng, positive_only_ok=True):
    """Inputs for element-wise layers: every shape and dtype, zeros, extremes."""
    n, d = _size(rng, 3, 7), _size(rng, 4, 9)
    return [
        Case((_normal(rng, (n, d), 2.0),), {}, "(N, D) batch of vectors"),
        Case((_normal(rng, (2, _size(rng, 2, 3), _size(rng, 3, 5), _size(rng, 4, 6)), 2.0),), {},
             "(N, C, H, W) feature maps"),
        Case((_with_zeros(rng, (n, d)),), {}, "exact zeros among the inputs"),
        Case((_normal(rng, _size(rng, 5, 12), 3.0),), {}, "1-D input"),
        Case((-np.abs(_normal(rng, (n, 3), 2.0)) - 0.5,), {}, "all negative"),
        Case((np.abs(_normal(rng, (2, 5), 4.0)) + 1.5,), {}, "all positive, > 1"),
        Case((rng.integers(0, 256, (4, 6), dtype=np.uint8),), {}, "uint8 input (not rescaled)"),
        Case((rng.integers(-5, 6, (3, 7)),), {}, "integer input with zeros"),
        Case((_normal(rng, (3, 4), 1e3, 1),), {}, "large values (±1e3)"),
        Case((np.array([[0.0]]),), {}, "a single zero"),
    ]


_X_PUBLIC = np.array([[-2.0, -0.5, 0.0, 0.25, 1.5, 3.0], [4.0, -1.0, 0.0, 2.0, -3.0, 0.75]])


relu_forward = Check(
    rules=("no warnings",),
    public=[
        Case((_X_PUBLIC,), {}, "negatives, zeros and positives"),
        Case((_distinct((2, 2, 3, 3), seed=1),), {}, "(N, C, H, W) feature maps"),
    ],
    hidden=_activation_hidden,
    compare=_forward_compare(_TIGHT),
    call=call_relu_forward,
    mistakes=[_relu_mask_only, _relu_abs, _relu_leaky, _relu_no_cache],
)


# --- relu backward ------------------------------------------------------------------------------
@mistake("gradient 0 at x = 0 (PyTorch's convention, not the notes')",
         "The notes take ReLU'(0) = 1: pass the gradient where x >= 0, not only where x > 0")
def _relu_b_pytorch(dout, cache):
    return np.where(_f(cache["x"]) > 0, _f(dout), 0.0)


@mistake("mask taken from dout instead of x",
         "The gate depends on the forward's input: dx = dout where cache['x'] >= 0, else 0")
def _relu_b_mask_of_dout(dout, cache):
    d = _f(dout)
    return np.where(d >= 0, d, 0.0)


@mistake("mask returned without multiplying by dout",
         "Chain rule: dx = dout * [x >= 0], the upstream gradient times the local derivative")
def _relu_b_mask_only(dout, cache):
    return (_f(cache["x"]) >= 0).astype(np.float64)


@mistake("gradient passed through unchanged", "Where x < 0 the output does not depend on x: set dx to 0 there")
def _relu_b_identity(dout, cache):
    return _f(dout).copy()


def _backward_case(forward, rng_or_x, label, dout=None, rng=None, **kwargs):
    x = rng_or_x
    out, cache = forward(x, **kwargs)
    if dout is None:
        dout = _normal(rng, np.shape(out), 1.5)
    return Case((dout, _cache(cache)), {}, label)


def _elementwise_backward_hidden(forward, kwargs_of=lambda rng: {}):
    def hidden(rng):
        return [_backward_case(forward, case.args[0], case.label, rng=rng, **kwargs_of(rng))
                for case in _activation_hidden(rng)]
    return hidden


_DOUT_PUBLIC = np.array([[1.5, -2.0, 3.0, -0.5, 2.5, -1.25], [-1.0, 2.0, -4.0, 1.0, 0.5, -3.0]])

relu_backward = Check(
    public=[
        Case((_DOUT_PUBLIC, _cache(_relu_forward(_X_PUBLIC)[1])), {}, "negatives, zeros and positives"),
        Case((_distinct((2, 2, 3, 3), seed=2), _cache(_relu_forward(_distinct((2, 2, 3, 3), seed=1, offset=0.125))[1])),
             {}, "(N, C, H, W) feature maps"),
    ],
    hidden=_elementwise_backward_hidden(_relu_forward),
    compare=_TIGHT,
    mistakes=[_relu_b_pytorch, _relu_b_mask_of_dout, _relu_b_mask_only, _relu_b_identity],
)


# --- sigmoid --------------------------------------------------------------------------------
@mistake("exp(+x) instead of exp(−x): that is σ(−x)",
         "σ(a) = 1 / (1 + exp(−a)): large positive inputs must give values near 1")
def _sigmoid_sign(x):
    x = _f(x)
    with np.errstate(over="ignore"):
        out = 1.0 / (1.0 + np.exp(x))
    return out, {"x": x, "out": out}


@mistake("exp(x)/(1+exp(x)) overflows to NaN for large x",
         "Only ever exponentiate −|x|: 1/(1+e^(−x)) for x ≥ 0 and e^x/(1+e^x) for x < 0 (np.where)")
def _sigmoid_overflow(x):
    x = _f(x)
    with np.errstate(over="ignore", invalid="ignore"):
        out = np.exp(x) / (1.0 + np.exp(x))
    return out, {"x": x, "out": out}


@mistake("tanh instead of the logistic sigmoid",
         "The logistic sigmoid maps to (0, 1): 1/(1+exp(−x)); tanh maps to (−1, 1)")
def _sigmoid_tanh(x):
    x = _f(x)
    out = np.tanh(x)
    return out, {"x": x, "out": out}


@mistake("cache lacks 'out'", "Store the output too: cache = {'x': x, 'out': out}; the backward uses σ(x)(1 − σ(x))")
def _sigmoid_no_out(x):
    out, _ = _sigmoid_forward(x)
    return out, {"x": _f(x)}


def _sigmoid_hidden(rng):
    cases = _activation_hidden(rng)
    cases[-2] = Case((np.array([[-1000.0, -50.0, -1.0, 0.0, 1.0, 50.0, 710.0, 1000.0]]),), {},
                     "extreme inputs ±1000 (no NaN)")
    cases.append(Case((np.concatenate([_normal(rng, 5, 2.0), [800.0, -800.0]]),), {}, "overflow-prone inputs ±800"))
    return cases


_X_SIGMOID = np.array([[-1000.0, -3.0, -0.5, 0.0, 0.5, 2.0, 1000.0], [1.0, -1.0, 4.0, -6.0, 0.25, 3.0, -2.0]])

sigmoid_forward = Check(
    public=[
        Case((_X_SIGMOID,), {}, "values from −1000 to 1000"),
        Case((_distinct((2, 1, 2, 3), seed=4),), {}, "(N, C, H, W) feature maps"),
    ],
    hidden=_sigmoid_hidden,
    compare=_forward_compare(_TIGHT),
    call=call_sigmoid_forward,
    mistakes=[_sigmoid_sign, _sigmoid_overflow, _sigmoid_tanh, _sigmoid_no_out],
    rules=("no warnings",),
)


@mistake("σ' computed from x instead of σ(x): x(1 − x)",
         "The derivative is σ(x)(1 − σ(x)): use cache['out'], not cache['x']")
def _sigmoid_b_from_x(dout, cache):
    x = _f(cache["x"])
    return _f(dout) * x * (1.0 - x)


@mistake("dout not multiplied in", "Chain rule: dx = dout * σ(x) * (1 − σ(x))")
def _sigmoid_b_no_dout(dout, cache):
    out = _f(cache["out"])
    return out * (1.0 - out)


@mistake("only 1 − σ(x)", "σ'(a) = σ(a)(1 − σ(a)): both factors")
def _sigmoid_b_one_minus(dout, cache):
    return _f(dout) * (1.0 - _f(cache["out"]))


@mistake("tanh's derivative 1 − out²", "For the logistic sigmoid σ' = σ(1 − σ), not 1 − σ²")
def _sigmoid_b_tanh(dout, cache):
    out = _f(cache["out"])
    return _f(dout) * (1.0 - out ** 2)


sigmoid_backward = Check(
    public=[
        Case((np.array([[1.0, -2.0, 0.5, 3.0, -1.0, 2.0, 1.0], [2.0, 1.0, -1.0, 0.5, 4.0, -3.0, 1.5]]),
              _cache(_sigmoid_forward(_X_SIGMOID)[1])), {}, "values from −1000 to 1000"),
        Case((_distinct((2, 1, 2, 3), seed=5), _cache(_sigmoid_forward(_distinct((2, 1, 2, 3), seed=4))[1])), {},
             "(N, C, H, W) feature maps"),
    ],
    hidden=_elementwise_backward_hidden(_sigmoid_forward),
    compare=_TIGHT,
    mistakes=[_sigmoid_b_from_x, _sigmoid_b_no_dout, _sigmoid_b_one_minus, _sigmoid_b_tanh],
)


# --- leaky ReLU -----------------------------------------------------------------------------
@mistake("alpha ignored (plain ReLU)", "Negative inputs are multiplied by alpha, not set to 0")
def _leaky_plain(x, alpha=0.01):
    x = _f(x)
    return np.maximum(x, 0.0), {"x": x, "alpha": alpha}


@mistake("slope alpha applied to the positive side", "x where x >= 0, alpha * x where x < 0")
def _leaky_wrong_side(x, alpha=0.01):
    x = _f(x)
    return np.where(x >= 0, alpha * x, x), {"x": x, "alpha": alpha}


@mistake("alpha instead of alpha·x for negatives",
         "The negative side is a line of slope alpha: np.where(x >= 0, x, alpha * x)")
def _leaky_constant(x, alpha=0.01):
    x = _f(x)
    return np.where(x >= 0, x, alpha), {"x": x, "alpha": alpha}


@mistake("cache lacks 'alpha'",
         "Store the slope with the input: cache = {'x': x, 'alpha': alpha} (also when it is the default)")
def _leaky_no_alpha(x, alpha=0.01):
    x = _f(x)
    return np.where(x >= 0, x, alpha * x), {"x": x}


def _alpha(rng) -> float:
    return _u(rng, 0.05, 0.4)


def _leaky_hidden(rng):
    cases = _activation_hidden(rng)
    for i, case in enumerate(cases):
        if i % 3 == 1:
            cases[i] = Case(case.args, {}, case.label + ", default alpha")
        else:
            cases[i] = Case(case.args, {"alpha": _alpha(rng)}, case.label)
    cases.append(Case((_normal(rng, (3, 5), 2.0),), {"alpha": _u(rng, 1.5, 3.0, 2)},
                      "alpha > 1 (np.maximum(x, alpha * x) is not leaky ReLU then)"))
    cases.append(Case((_normal(rng, (2, 6), 2.0),), {"alpha": -0.5}, "negative alpha"))
    return cases


leaky_relu_forward = Check(
    rules=("no warnings",),
    public=[
        Case((_X_PUBLIC,), {"alpha": 0.1}, "alpha 0.1"),
        Case((_distinct((2, 2, 2, 2), seed=6),), {}, "default alpha 0.01"),
        Case((_X_PUBLIC,), {"alpha": 2.0}, "alpha 2 (steeper than 1)"),
    ],
    hidden=_leaky_hidden,
    compare=_forward_compare(_TIGHT),
    call=call_leaky_relu_forward,
    mistakes=[_leaky_plain, _leaky_wrong_side, _leaky_constant, _leaky_no_alpha],
)


@mistake("gradient 0 for negatives (ReLU's)", "For x < 0 the slope is alpha: dx = alpha * dout there")
def _leaky_b_relu(dout, cache):
    return np.where(_f(cache["x"]) >= 0, _f(dout), 0.0)


@mistake("alpha·x instead of alpha·dout for negatives",
         "The local derivative for x < 0 is alpha; multiply it by the upstream gradient dout")
def _leaky_b_alpha_x(dout, cache):
    x = _f(cache["x"])
    return np.where(x >= 0, _f(dout), cache["alpha"] * x)


@mistake("slope alpha at x = 0", "As in the notes, the slope is 1 for x >= 0 (including 0)")
def _leaky_b_zero_side(dout, cache):
    x = _f(cache["x"])
    return np.where(x > 0, _f(dout), cache["alpha"] * _f(dout))


@mistake("dout not multiplied in (returns the slopes)", "Chain rule: dx = dout * slope")
def _leaky_b_slopes(dout, cache):
    return np.where(_f(cache["x"]) >= 0, 1.0, cache["alpha"])


def _leaky_backward_hidden(rng):
    cases = []
    for i, case in enumerate(_activation_hidden(rng)):
        kwargs = {} if i % 3 == 1 else {"alpha": _alpha(rng)}
        cases.append(_backward_case(_leaky_forward, case.args[0], case.label, rng=rng, **kwargs))
    return cases


leaky_relu_backward = Check(
    public=[
        Case((_DOUT_PUBLIC, _cache(_leaky_forward(_X_PUBLIC, 0.1)[1])), {}, "alpha 0.1, zeros in x"),
        Case((_distinct((2, 2, 2, 2), seed=7), _cache(_leaky_forward(_distinct((2, 2, 2, 2), seed=6))[1])), {},
             "default alpha"),
    ],
    hidden=_leaky_backward_hidden,
    compare=_TIGHT,
    mistakes=[_leaky_b_relu, _leaky_b_alpha_x, _leaky_b_zero_side, _leaky_b_slopes],
)


# ============================================================================================
# linear layer (§10.5.1)
# ============================================================================================
@mistake("bias missing", "The layer is affine: out = x @ W + b")
def _linear_no_bias(x, W, b):
    x, W, b = _f(x), _f(W), _f(b)
    return x @ W, {"x": x, "W": W, "b": b}


@mistake("W used as (C, D): x @ W.T",
         "In the layer convention W is (D, C): out = x @ W + b (Chapter 9's learn.* used (C, D))")
def _linear_transposed(x, W, b):
    x, W, b = _f(x), _f(W), _f(b)
    return x @ W.T + b, {"x": x, "W": W, "b": b}


@mistake("no cache returned (out only)", "Return (out, cache) with cache = {'x': x, 'W': W, 'b': b}")
def _linear_no_cache(x, W, b):
    return _f(x) @ _f(W) + _f(b)


def _linear_case(rng, n, d, c, kind="normal", label=""):
    if kind == "uint8":
        x = rng.integers(0, 256, (n, d), dtype=np.uint8)
    else:
        x = _normal(rng, (n, d), 2.0)
    W = _normal(rng, (d, c))
    b = _normal(rng, c, 2.0) + 0.5
    return Case((x, W, b), {}, label)


def _linear_hidden(rng):
    c = _size(rng, 2, 5)
    return [
        _linear_case(rng, _size(rng, 4, 9), _size(rng, 6, 12), _size(rng, 2, 5), label="N, D, C all different"),
        _linear_case(rng, _size(rng, 3, 6), c, c, label="D = C (square W: a transpose still runs)"),
        _linear_case(rng, c, c, c, label="N = D = C"),
        _linear_case(rng, 1, _size(rng, 3, 8), _size(rng, 2, 4), label="a single sample"),
        _linear_case(rng, _size(rng, 3, 6), _size(rng, 3, 6), 1, label="a single output"),
        _linear_case(rng, _size(rng, 3, 6), 1, _size(rng, 2, 5), label="one input feature"),
        _linear_case(rng, _size(rng, 3, 6), _size(rng, 8, 20), _size(rng, 2, 6), "uint8",
                     label="uint8 inputs (not rescaled)"),
        Case((_normal(rng, (4, 3)), _normal(rng, (3, 3)), np.zeros(3)), {}, "zero bias, square W"),
        _linear_case(rng, _size(rng, 5, 10), _size(rng, 2, 4), _size(rng, 6, 10), label="C > D (widening layer)"),
    ]


_LIN_X = np.array([[1.0, 2.0, -1.0], [0.5, -1.5, 2.0], [3.0, 0.0, 1.0], [-2.0, 1.0, 0.25]])
_LIN_W = np.array([[1.0, -0.5], [2.0, 0.25], [-1.0, 1.5]])
_LIN_B = np.array([0.5, -2.0])
_LIN_WSQ = np.array([[1.0, 2.0, 0.0], [-1.0, 0.5, 3.0], [0.25, -2.0, 1.0]])
_LIN_BSQ = np.array([1.0, -1.0, 0.5])

linear_forward = Check(
    public=[
        Case((_LIN_X, _LIN_W, _LIN_B), {}, "N = 4, D = 3, C = 2"),
        Case((_LIN_X, _LIN_WSQ, _LIN_BSQ), {}, "square W (D = C = 3)"),
    ],
    hidden=_linear_hidden,
    compare=_forward_compare(_SUMS),
    call=call_linear_forward,
    mistakes=[_linear_no_bias, _linear_transposed, _linear_no_cache],
)


@mistake("db averaged over the batch", "db = dout.sum(axis=0): the 1/N of a mean loss is already inside dout")
def _linear_b_db_mean(dout, cache):
    d = _f(dout)
    return d @ _f(cache["W"]).T, _f(cache["x"]).T @ d, d.mean(axis=0)


@mistake("dW = dout.T @ x (the (C, D) layout)", "dW must have W's shape (D, C): dW = x.T @ dout")
def _linear_b_dw_transposed(dout, cache):
    d = _f(dout)
    return d @ _f(cache["W"]).T, d.T @ _f(cache["x"]), d.sum(axis=0)


@mistake("dx = dout @ W (W not transposed)", "dx = dout @ W.T, shape (N, D) like x")
def _linear_b_dx_not_transposed(dout, cache):
    d = _f(dout)
    return d @ _f(cache["W"]), _f(cache["x"]).T @ d, d.sum(axis=0)


@mistake("dW averaged over the batch", "dW = x.T @ dout, a sum over the batch (dout already carries the 1/N)")
def _linear_b_dw_mean(dout, cache):
    d = _f(dout)
    x = _f(cache["x"])
    return d @ _f(cache["W"]).T, x.T @ d / len(x), d.sum(axis=0)


def _linear_backward_hidden(rng):
    cases = []
    for case in _linear_hidden(rng):
        out, cache = _linear_forward(*case.args)
        cases.append(Case((_normal(rng, out.shape, 1.5), _cache(cache)), {}, case.label))
    return cases


_LIN_OUT = _linear_forward(_LIN_X, _LIN_W, _LIN_B)
linear_backward = Check(
    public=[
        Case((np.array([[1.0, -2.0], [0.5, 1.0], [-1.0, 3.0], [2.0, 0.5]]), _cache(_LIN_OUT[1])), {},
             "N = 4, D = 3, C = 2"),
        Case((np.array([[1.0, -2.0, 0.5], [0.5, 1.0, 2.0], [-1.0, 3.0, 1.0], [2.0, 0.5, -1.0]]),
              _cache(_linear_forward(_LIN_X, _LIN_WSQ, _LIN_BSQ)[1])), {}, "square W (D = C = 3)"),
    ],
    hidden=_linear_backward_hidden,
    compare=Nested(_SUMS, names=("dx", "dW", "db")),
    mistakes=[_linear_b_db_mean, _linear_b_dw_transposed, _linear_b_dx_not_transposed, _linear_b_dw_mean],
)


# ============================================================================================
# output size and receptive field (§10.7.4)
# ============================================================================================
@mistake("padding counted once (H − K + P)", "P zeros are added on each side: H − K + 2P")
def _size_padding_once(size, kernel, padding=0, stride=1):
    return (size - kernel + padding) // stride + 1


@mistake("rounded up (ceil) instead of down",
         "A window that does not fit entirely in the padded input is dropped: use floor (//)")
def _size_ceil(size, kernel, padding=0, stride=1):
    return -(-(size - kernel + 2 * padding) // stride) + 1


@mistake("+1 missing", "(H − K + 2P) // S counts the steps; the number of positions is one more")
def _size_no_plus_one(size, kernel, padding=0, stride=1):
    return (size - kernel + 2 * padding) // stride


@mistake("true division (a float, not floored)", "Use integer floor division //: sizes are whole numbers")
def _size_true_division(size, kernel, padding=0, stride=1):
    return (size - kernel + 2 * padding) / stride + 1


def _output_size_hidden(rng):
    k = int(rng.choice([3, 5, 7]))
    cases = [
        Case((_size(rng, 10, 40), k), {}, "no padding, stride 1"),
        Case((_size(rng, 10, 40), k), {"padding": k // 2}, "'same' padding"),
        Case((2 * _size(rng, 8, 30), 3), {"padding": 1, "stride": 2}, "even size, 3×3, padding 1, stride 2"),
        Case((2 * _size(rng, 8, 30) + 1, 3), {"padding": 0, "stride": 2}, "odd size, stride 2, no padding"),
        Case((224, 7), {"padding": 3, "stride": 2}, "ResNet's stem: 224, 7×7, padding 3, stride 2"),
        Case((_size(rng, 20, 60), 2), {"stride": 2}, "2×2 pooling window, stride 2"),
        Case((3 * _size(rng, 5, 15) + 2, 5), {"padding": 1, "stride": 3}, "stride 3 not dividing"),
        Case((_size(rng, 3, 9),), {"kernel": 1, "stride": 2}, "1×1 kernel, stride 2 (keywords)"),
        Case((5, 5), {}, "kernel as large as the input"),
        Case((1, 3), {"padding": 1}, "a single pixel with padding 1"),
        Case((_size(rng, 30, 100), 11), {"padding": 2, "stride": 4}, "AlexNet-like 11×11, stride 4"),
    ]
    return cases


conv_output_size = Check(
    public=[
        Case((7, 3), {}, "7, 3×3"),
        Case((7, 3), {"padding": 1}, "7, 3×3, padding 1"),
        Case((8, 3), {"padding": 1, "stride": 2}, "8, 3×3, padding 1, stride 2"),
        Case((224, 7), {"padding": 3, "stride": 2}, "224, 7×7, padding 3, stride 2"),
        Case((10, 4), {"padding": 1, "stride": 3}, "10, 4×4, padding 1, stride 3"),
    ],
    hidden=_output_size_hidden,
    compare=IntegerResult(),
    mistakes=[_size_padding_once, _size_ceil, _size_no_plus_one, _size_true_division],
)


@mistake("strides ignored: 1 + Σ(K − 1)",
         "After a stride-S layer neighbouring units are S input pixels apart: weight each K − 1 by the "
         "product of the strides of the layers below it")
def _rf_no_strides(layers):
    return 1 + sum(k - 1 for k, _ in layers)


@mistake("the layer's own stride included in its product",
         "A layer's K − 1 is multiplied by the strides of the layers *before* it, not its own")
def _rf_own_stride(layers):
    field, jump = 1, 1
    for k, s in layers:
        jump *= s
        field += (k - 1) * jump
    return field


@mistake("kernel sizes summed (Σ K)",
         "Each layer adds K − 1 (one unit is already counted): r = 1 + Σ (K_l − 1)·∏_{j<l} S_j")
def _rf_sum_kernels(layers):
    return sum(k for k, _ in layers)


@mistake("strides of the layers after each layer used (stack read backwards)",
         "Go from the input up: the strides that matter for layer l are those of layers 1..l−1")
def _rf_reversed(layers):
    field, jump = 1, 1
    for k, s in reversed(list(layers)):
        field += (k - 1) * jump
        jump *= s
    return field


def _layers(rng, count, kernels=(1, 2, 3, 5, 7), strides=(1, 2)):
    return [(int(rng.choice(kernels)), int(rng.choice(strides))) for _ in range(count)]


def _rf_hidden(rng):
    vgg_stage = [(3, 1), (3, 1), (2, 2)]
    mixed = _layers(rng, _size(rng, 3, 5))
    mixed[0] = (mixed[0][0], 2)
    mixed[-1] = (3, mixed[-1][1])
    return [
        Case(([(3, 1)] * _size(rng, 2, 6),), {}, "3×3 convolutions, stride 1 (1 + L(K − 1))"),
        Case(([(int(rng.choice([5, 7])), 1)] * _size(rng, 2, 4),), {}, "larger kernels, stride 1"),
        Case((vgg_stage * _size(rng, 2, 3) + [(3, 1)],), {}, "VGG stages: two 3×3, then 2×2 pooling"),
        Case(([(7, 2), (3, 2)] + [(3, 1)] * _size(rng, 1, 4),), {}, "ResNet stem then 3×3 layers"),
        Case((mixed,), {}, "mixed kernels and strides"),
        Case(([(3, 2)] * _size(rng, 3, 5),), {}, "stride 2 everywhere (exponential growth)"),
        Case(([(5, 1)],), {}, "a single layer"),
        Case(([(1, 1), (3, 3), (1, 1), (3, 1)],), {}, "1×1 convolutions and stride 3"),
        Case(([(2, 2), (2, 2), (2, 2)],), {}, "three 2×2 poolings"),
        Case(([(3, 1), (3, 2), (5, 1), (3, 2), (3, 1)],), {}, "strided layers inside the stack"),
    ]


receptive_field = Check(
    public=[
        Case(([(3, 1), (3, 1)],), {}, "two 3×3 convolutions"),
        Case(([(3, 1), (2, 2), (3, 1), (2, 2), (3, 1)],), {}, "conv, pool, conv, pool, conv"),
        Case(([(7, 2), (3, 2), (3, 1)],), {}, "7×7 stride 2, 3×3 pool stride 2, 3×3 conv"),
    ],
    hidden=_rf_hidden,
    compare=IntegerResult(),
    mistakes=[_rf_no_strides, _rf_own_stride, _rf_sum_kernels, _rf_reversed],
)


# ============================================================================================
# convolution layer (§10.7.3)
# ============================================================================================
def _conv_cache(x, w, b, stride, padding):
    return {"x": _f(x), "w": _f(w), "b": _f(b), "stride": stride, "padding": padding}


@mistake("kernel flipped (true convolution, not correlation)",
         "Deep-learning convolution is correlation (§10.7.1): out[i, j] = Σ w[m, l]·x[i+m, j+l], no flip")
def _conv_flipped(x, w, b, stride=1, padding=0):
    out, _ = _conv_forward(x, _f(w)[:, :, ::-1, ::-1], b, stride, padding)
    return out, _conv_cache(x, w, b, stride, padding)


@mistake("padding on one side only", "Add P zeros on every side: top, bottom, left and right")
def _conv_one_side(x, w, b, stride=1, padding=0):
    x = _f(x)
    xp = np.pad(x, ((0, 0), (0, 0), (padding, 0), (padding, 0)))
    out, _ = _conv_forward(xp, w, b, stride, 0)
    return out, _conv_cache(x, w, b, stride, padding)


@mistake("output size rounded up with stride (ceil)",
         "Keep only windows that fit in the padded input: Ho = (H − kh + 2P) // S + 1")
def _conv_ceil(x, w, b, stride=1, padding=0):
    x = _f(x)
    kh, kw = np.shape(w)[2:]
    extra = []
    for size, k in ((x.shape[2], kh), (x.shape[3], kw)):
        span = size + 2 * padding - k
        extra.append((-span) % stride)
    xp = np.pad(x, ((0, 0), (0, 0), (padding, padding + extra[0]), (padding, padding + extra[1])))
    out, _ = _conv_forward(xp, w, b, stride, 0)
    return out, _conv_cache(x, w, b, stride, padding)


@mistake("bias missing", "Add b[f] to every value of feature map f")
def _conv_no_bias(x, w, b, stride=1, padding=0):
    out, _ = _conv_forward(x, w, np.zeros(np.shape(w)[0]), stride, padding)
    return out, _conv_cache(x, w, b, stride, padding)


@mistake("kernel rows and columns swapped", "w[f, c, m, l]: m runs over rows (kh), l over columns (kw)")
def _conv_transposed_kernel(x, w, b, stride=1, padding=0):
    out, _ = _conv_forward(x, _f(w).transpose(0, 1, 3, 2), b, stride, padding)
    return out, _conv_cache(x, w, b, stride, padding)


def _conv_args(rng, n, c, h, w, f, kh, kw, kind="normal"):
    if kind == "uint8":
        x = rng.integers(0, 256, (n, c, h, w), dtype=np.uint8)
    else:
        x = _normal(rng, (n, c, h, w), 1.0, 2)
    weights = _normal(rng, (f, c, kh, kw), 1.0, 2)
    weights[:, :, 0, 0] += 1.5  # never symmetric under flips
    return x, weights, _normal(rng, f, 1.0, 2) + 0.5


def _conv_hidden(rng):
    s = _size
    return [
        Case(_conv_args(rng, 2, s(rng, 1, 3), s(rng, 5, 8), s(rng, 6, 9), s(rng, 2, 4), 3, 3), {},
             "3×3, no padding, stride 1"),
        Case(_conv_args(rng, 2, s(rng, 2, 3), s(rng, 5, 8), s(rng, 5, 8), s(rng, 2, 3), 3, 3), {"padding": 1},
             "3×3, 'same' padding 1"),
        Case(_conv_args(rng, 1, 2, 2 * s(rng, 3, 4), 2 * s(rng, 3, 4) + 1, 3, 3, 3), {"stride": 2, "padding": 1},
             "stride 2, padding 1, even × odd input"),
        Case(_conv_args(rng, 2, 1, 2 * s(rng, 3, 4) + 1, 2 * s(rng, 3, 4), 2, 3, 3), {"stride": 2},
             "stride 2 not dividing H − K (the last row is dropped)"),
        Case(_conv_args(rng, 1, 2, s(rng, 6, 8), s(rng, 7, 9), 2, 2, 3), {"padding": 1},
             "non-square 2×3 kernel, padding 1"),
        Case(_conv_args(rng, 2, 2, s(rng, 5, 7), s(rng, 5, 7), 3, 1, 1), {}, "1×1 convolution (mixes channels)"),
        Case(_conv_args(rng, 1, 3, 3 * s(rng, 2, 3) + 1, 3 * s(rng, 2, 3) + 2, 2, 3, 2), {"stride": 3, "padding": 2},
             "stride 3, padding 2, 3×2 kernel"),
        Case(_conv_args(rng, 1, 1, 4, 5, 2, 4, 5), {}, "kernel as large as the input (1×1 output)"),
        Case(_conv_args(rng, 2, 2, s(rng, 4, 6), s(rng, 4, 6), 2, 3, 3, "uint8"), {"padding": 1},
             "uint8 input (not rescaled)"),
        Case(_conv_args(rng, 1, 2, s(rng, 5, 7), s(rng, 5, 7), 4, 5, 5), {"padding": 2, "stride": 2},
             "5×5, padding 2, stride 2"),
        Case(_conv_args(rng, 3, 1, 1, s(rng, 6, 9), 2, 1, 3), {"padding": 1},
             "a single input row, padding 1"),
    ]


_CONV_X = _distinct((2, 2, 5, 6), seed=11)
_CONV_W = np.array([[[[1.0, -1.0], [2.0, 0.5], [0.0, 1.5]], [[-0.5, 1.0], [0.25, -2.0], [1.0, 0.0]]],
                    [[[0.5, 0.0], [-1.0, 1.0], [2.0, -0.5]], [[1.0, 1.0], [0.0, -1.0], [0.5, 0.25]]],
                    [[[-1.0, 0.5], [0.0, 0.0], [1.0, 2.0]], [[0.0, -0.5], [1.5, 1.0], [-1.0, 0.5]]]])
_CONV_B = np.array([0.5, -1.0, 2.0])
_CONV_W3 = np.array([[[[1.0, 0.0, -1.0], [2.0, 0.5, 0.0], [0.0, -1.0, 1.5]],
                      [[0.5, -0.5, 1.0], [0.0, 1.0, -2.0], [1.0, 0.25, 0.0]]],
                     [[[0.0, 1.0, 0.5], [-1.0, 0.0, 1.0], [2.0, 0.5, -0.5]],
                      [[1.0, -1.0, 0.0], [0.5, 0.0, -1.0], [0.0, 1.5, 0.25]]]])
_CONV_B3 = np.array([1.0, -0.5])
_CONV_PUBLIC = [
    Case((_CONV_X, _CONV_W, _CONV_B), {}, "3×2 kernels, no padding, stride 1"),
    Case((_CONV_X, _CONV_W3, _CONV_B3), {"stride": 2, "padding": 1}, "3×3, stride 2, padding 1"),
    Case((_CONV_X[:1], _CONV_W, _CONV_B), {"stride": 2, "padding": 2}, "3×2, stride 2, padding 2"),
]

conv2d_forward = Check(
    public=_CONV_PUBLIC,
    hidden=_conv_hidden,
    compare=_forward_compare(_SUMS),
    call=call_conv2d_forward,
    mistakes=[_conv_flipped, _conv_one_side, _conv_ceil, _conv_no_bias, _conv_transposed_kernel],
)


@mistake("dx by correlation with the unflipped filters",
         "The backward of a correlation is a (full) convolution: each window's dout is spread back with "
         "w[m, l] at input position (S·i + m, S·j + l)")
def _conv_b_unflipped(dout, cache):
    _, dw, db = _conv_backward(dout, cache)
    flipped = dict(cache, w=_f(cache["w"])[:, :, ::-1, ::-1])
    dx, _, _ = _conv_backward(dout, flipped)
    return dx, dw, db


@mistake("padding not cropped from dx", "dx must have x's shape: drop the P rows and columns of padding on every side")
def _conv_b_padding_kept(dout, cache):
    dx, dw, db = _conv_backward(dout, cache)
    p = cache["padding"]
    return np.pad(dx, ((0, 0), (0, 0), (p, p), (p, p))), dw, db


@mistake("stride ignored in the backward",
         "Output (i, j) came from the window starting at (S·i, S·j): spread its gradient there")
def _conv_b_stride_ignored(dout, cache):
    """Window (i, j) spread back at (i, j) instead of (S·i, S·j)."""
    _, dw, db = _conv_backward(dout, cache)
    x, w, p = _f(cache["x"]), _f(cache["w"]), cache["padding"]
    d = _f(dout)
    n, c, h, width = x.shape
    kh, kw = w.shape[2:]
    ho, wo = d.shape[2:]
    dxp = np.zeros((n, c, max(h + 2 * p, ho + kh - 1), max(width + 2 * p, wo + kw - 1)))
    dcols = np.tensordot(d, w, axes=([1], [0]))
    for m in range(kh):
        for l in range(kw):
            dxp[:, :, m:m + ho, l:l + wo] += dcols[:, :, :, :, m, l].transpose(0, 3, 1, 2)
    return dxp[:, :, p:p + h, p:p + width], dw, db


@mistake("db averaged instead of summed", "db[f] = dout[:, f].sum(): every output value adds the bias once")
def _conv_b_db_mean(dout, cache):
    dx, dw, _ = _conv_backward(dout, cache)
    return dx, dw, _f(dout).mean(axis=(0, 2, 3))


@mistake("dw divided by the batch size", "dw sums over the batch; a mean loss already put 1/N into dout")
def _conv_b_dw_mean(dout, cache):
    dx, dw, db = _conv_backward(dout, cache)
    return dx, dw / len(cache["x"]), db


def _conv_backward_cases(cases, rng):
    return _backward_cases(_conv_forward, cases, rng, lambda shape, i: _distinct(shape, seed=21, scale=0.125),
                           lambda rng, shape: _normal(rng, shape, 1.0, 2))


conv2d_backward = Check(
    public=_conv_backward_cases(_CONV_PUBLIC, None),
    hidden=lambda rng: _conv_backward_cases(_conv_hidden(rng), rng),
    compare=Nested(_SUMS, names=("dx", "dw", "db")),
    mistakes=[_conv_b_unflipped, _conv_b_padding_kept, _conv_b_stride_ignored, _conv_b_db_mean, _conv_b_dw_mean],
)


# ============================================================================================
# pooling (§10.7.5, §11.3.5)
# ============================================================================================
def _pool_views(x, size, stride):
    x = _f(x)
    v = sliding_window_view(x, (size, size), axis=(2, 3))[:, :, ::stride, ::stride]
    return x, v.reshape(v.shape[:4] + (size * size,))


@mistake("average instead of max", "Max pooling keeps the largest value of each window")
def _pool_average(x, size=2, stride=2):
    x, v = _pool_views(x, size, stride)
    return v.mean(axis=-1), {"x": x, "size": size, "stride": stride}


@mistake("windows step by their size (stride ignored)",
         "Windows start every `stride` pixels; with stride < size they overlap")
def _pool_stride_is_size(x, size=2, stride=2):
    x, v = _pool_views(x, size, size)
    return v.max(axis=-1), {"x": x, "size": size, "stride": stride}


@mistake("partial windows at the border kept (ceil)",
         "Only windows entirely inside the input: Ho = (H − size) // stride + 1")
def _pool_ceil(x, size=2, stride=2):
    x = _f(x)
    h, w = x.shape[2:]
    ph, pw = (-(h - size)) % stride, (-(w - size)) % stride
    xp = np.pad(x, ((0, 0), (0, 0), (0, ph), (0, pw)), constant_values=-np.inf)
    _, v = _pool_views(xp, size, stride)
    return v.max(axis=-1), {"x": x, "size": size, "stride": stride}


@mistake("no cache returned (out only)", "Return (out, cache) with cache = {'x': x, 'size': size, 'stride': stride}")
def _pool_no_cache(x, size=2, stride=2):
    return _pool_forward(x, size, stride)[0]


def _ties(rng, shape, levels: int = 4):
    """Small integers: many ties inside the windows."""
    return rng.integers(0, levels, shape).astype(np.float64)


def _pool_hidden(rng):
    s = _size
    return [
        Case((_normal(rng, (2, 2, 2 * s(rng, 2, 4), 2 * s(rng, 2, 4))),), {}, "2×2, stride 2 (defaults)"),
        Case((_normal(rng, (1, 2, 2 * s(rng, 2, 3) + 1, 2 * s(rng, 2, 4) + 1)),), {},
             "odd sizes: the last row and column are dropped"),
        Case((_normal(rng, (2, 1, s(rng, 5, 8), s(rng, 5, 8))),), {"size": 3, "stride": 2},
             "3×3 windows, stride 2 (overlapping)"),
        Case((_normal(rng, (1, 3, s(rng, 4, 7), s(rng, 4, 7))),), {"size": 2, "stride": 1},
             "2×2 windows, stride 1 (overlapping)"),
        Case((_normal(rng, (1, 2, 3 * s(rng, 2, 3), 3 * s(rng, 2, 3) + 1)),), {"size": 3, "stride": 3},
             "3×3, stride 3, non-square"),
        Case((_ties(rng, (2, 2, 4, 6)),), {}, "small integers: ties inside windows"),
        Case((_ties(rng, (1, 2, 5, 5), 3),), {"size": 3, "stride": 1}, "ties, overlapping 3×3 windows"),
        Case((rng.integers(0, 256, (1, 1, 6, 8), dtype=np.uint8),), {}, "uint8 input"),
        Case((-np.abs(_normal(rng, (1, 2, 4, 4))) - 1.0,), {}, "all negative values"),
        Case((_normal(rng, (2, 1, 2, 2)),), {}, "one window per map"),
        Case((_normal(rng, (1, 1, s(rng, 3, 5), s(rng, 7, 9))),), {"size": 1, "stride": 2}, "1×1 windows, stride 2"),
    ]


_POOL_X = _distinct((2, 2, 5, 6), seed=31)
_POOL_TIES = np.array([[[[1.0, 3.0, 3.0, 0.0, 2.0], [3.0, 2.0, 1.0, 3.0, 2.0], [0.0, 0.0, 2.0, 2.0, 1.0],
                         [1.0, 1.0, 0.0, 2.0, 2.0], [2.0, 0.0, 1.0, 1.0, 3.0]]]])
_POOL_PUBLIC = [
    Case((_POOL_X,), {}, "2×2, stride 2, odd height 5"),
    Case((_POOL_X[:1],), {"size": 3, "stride": 2}, "3×3, stride 2 (overlapping)"),
    Case((_POOL_TIES,), {"size": 2, "stride": 1}, "ties, 2×2 windows, stride 1"),
]

maxpool2d_forward = Check(
    public=_POOL_PUBLIC,
    hidden=_pool_hidden,
    compare=_forward_compare(_TIGHT),
    call=call_maxpool2d_forward,
    mistakes=[_pool_average, _pool_stride_is_size, _pool_ceil, _pool_no_cache],
)


def _pool_winners(cache, rule):
    x, v = _pool_views(cache["x"], cache["size"], cache["stride"])
    best = v.max(axis=-1, keepdims=True)
    if rule == "first":
        w = np.zeros(v.shape, dtype=bool)
        np.put_along_axis(w, v.argmax(axis=-1)[..., None], True, axis=-1)
    elif rule == "last":
        k = v.shape[-1]
        w = np.zeros(v.shape, dtype=bool)
        np.put_along_axis(w, (k - 1 - v[..., ::-1].argmax(axis=-1))[..., None], True, axis=-1)
    elif rule == "all_ties":
        w = v == best
    else:  # every element
        w = np.ones(v.shape, dtype=bool)
    return x, w


def _pool_scatter(cache, weights, dout, add=True):
    x = _f(cache["x"])
    size, stride = cache["size"], cache["stride"]
    d = _f(dout)
    ho, wo = d.shape[2:]
    dx = np.zeros(x.shape)
    for m in range(size):
        for l in range(size):
            sl = (slice(None), slice(None), slice(m, m + stride * (ho - 1) + 1, stride),
                  slice(l, l + stride * (wo - 1) + 1, stride))
            contribution = weights[..., m * size + l] * d
            if add:
                dx[sl] += contribution
            else:
                target = dx[sl]
                np.copyto(target, contribution, where=weights[..., m * size + l] != 0)
                dx[sl] = target
    return dx


def _pool_routed(dout, cache, rule, split=False, add=True):
    """``dout`` sent to the elements :func:`_pool_winners` picks by ``rule``, shared equally over
    the window when ``split``, added (or, not ``add``, written) into ``dx``."""
    _, w = _pool_winners(cache, rule)
    weights = w.astype(float) / (cache["size"] ** 2) if split else w.astype(float)
    return _pool_scatter(cache, weights, dout, add=add)


def _pool_fixed_dout(shape, i):
    dout = _distinct(shape, seed=41 + i, offset=0.5 * (math.prod(shape) % 2 == 0), scale=0.5)
    dout[dout == 0] = 0.75
    return dout


def _pool_backward_cases(cases, rng):
    return _backward_cases(_pool_forward, cases, rng, _pool_fixed_dout,
                           lambda rng, shape: _normal(rng, shape, 1.0, 2) + 0.005)


maxpool2d_backward = Check(
    public=_pool_backward_cases(_POOL_PUBLIC, None),
    hidden=lambda rng: _pool_backward_cases(_pool_hidden(rng), rng),
    compare=_TIGHT,
    mistakes=[
        Mistake("gradient sent to every element of the window", variant(_pool_routed, rule="every"),
                "Only the maximum influenced the output: route dout to the arg-max of each window, 0 elsewhere"),
        Mistake("gradient split evenly over the window (average pooling's)",
                variant(_pool_routed, rule="every", split=True),
                "That is average pooling's gradient; max pooling routes the whole dout to the maximum"),
        Mistake("every tied maximum gets the gradient", variant(_pool_routed, rule="all_ties"),
                "On ties only the first maximum in row-major order (np.argmax's rule) gets dout"),
        Mistake("last maximum instead of the first on ties", variant(_pool_routed, rule="last"),
                "np.argmax over the flattened window picks the first maximum in row-major order"),
        Mistake("overlapping windows overwrite instead of adding", variant(_pool_routed, rule="first", add=False),
                "When one element is the maximum of several windows, their gradients add up (+=)"),
    ],
)


# --- global average pooling -------------------------------------------------------------------
@mistake("sum instead of mean", "Average: divide the sum of each map by H·W (x.mean(axis=(2, 3)))")
def _gap_sum(x):
    x = _f(x)
    return x.sum(axis=(2, 3)), {"x": x}


@mistake("maximum instead of mean (global max pooling)", "Global *average* pooling: the mean")
def _gap_max(x):
    x = _f(x)
    return x.max(axis=(2, 3)), {"x": x}


@mistake("(N, C, 1, 1) kept instead of (N, C)", "Return one vector per sample, shape (N, C), ready for a linear layer")
def _gap_keepdims(x):
    x = _f(x)
    return x.mean(axis=(2, 3), keepdims=True), {"x": x}


@mistake("mean over the channels instead of the positions",
         "Average over the spatial axes H and W (axis=(2, 3)), one value per channel")
def _gap_channels(x):
    x = _f(x)
    return x.mean(axis=1), {"x": x}


def _gap_hidden(rng):
    s = _size
    return [
        Case((_normal(rng, (s(rng, 2, 4), s(rng, 2, 5), s(rng, 2, 5), s(rng, 3, 6)), 2.0),), {}, "random maps"),
        Case((_normal(rng, (1, 3, 7, 7)),), {}, "7×7 maps (as after ResNet's last stage)"),
        Case((_normal(rng, (2, 4, 1, 1)),), {}, "1×1 maps (GAP is the identity)"),
        Case((_normal(rng, (3, 2, 1, s(rng, 4, 7))),), {}, "a single row"),
        Case((rng.integers(0, 256, (2, 2, 3, 4), dtype=np.uint8),), {}, "uint8 input"),
        Case((np.full((2, 3, 2, 2), 1.5),), {}, "constant maps"),
        Case((np.abs(_normal(rng, (2, 3, 3, 5))) + 0.5,), {}, "positive values (after a ReLU)"),
        Case((_normal(rng, (1, s(rng, 2, 4), s(rng, 2, 4), s(rng, 5, 8)), 1e3, 0),), {}, "large values"),
        Case((_normal(rng, (s(rng, 2, 3), 2, 2, 3)),), {}, "N, C small"),
    ]


global_avg_pool_forward = Check(
    public=[
        Case((_distinct((2, 3, 2, 3), seed=51),), {}, "2 samples, 3 channels, 2×3 maps"),
        Case((_distinct((1, 2, 4, 4), seed=52, offset=1.0),), {}, "4×4 maps"),
    ],
    hidden=_gap_hidden,
    compare=_forward_compare(_TIGHT),
    call=call_global_avg_pool_forward,
    mistakes=[_gap_sum, _gap_max, _gap_keepdims, _gap_channels],
)


@mistake("not divided by H·W", "Each position contributed 1/(H·W) of the mean: dx = dout / (H·W) at every position")
def _gap_b_not_divided(dout, cache):
    x = _f(cache["x"])
    return np.broadcast_to(_f(dout)[:, :, None, None], x.shape).copy()


@mistake("divided by N·H·W", "The mean is per sample and channel: divide by H·W only")
def _gap_b_divided_by_batch(dout, cache):
    x = _f(cache["x"])
    n, _, h, w = x.shape
    return np.broadcast_to(_f(dout)[:, :, None, None] / (n * h * w), x.shape).copy()


@mistake("gradient only at one position",
         "Every position of the map took part in the mean: spread dout over all of them")
def _gap_b_one_position(dout, cache):
    x = _f(cache["x"])
    dx = np.zeros(x.shape)
    dx[:, :, 0, 0] = _f(dout)
    return dx


@mistake("divided by H only", "Divide by the number of positions H·W")
def _gap_b_divided_by_h(dout, cache):
    x = _f(cache["x"])
    return np.broadcast_to(_f(dout)[:, :, None, None] / x.shape[2], x.shape).copy()


def _gap_backward_cases(cases, rng):
    return _backward_cases(_gap_forward, cases, rng, lambda shape, i: _distinct(shape, seed=61 + i, offset=0.3, scale=0.5),
                           lambda rng, shape: _normal(rng, shape) + 0.01)


global_avg_pool_backward = Check(
    public=_gap_backward_cases([Case((np.zeros((2, 3, 2, 3)),), {}, "2 samples, 3 channels, 2×3 maps"),
                                Case((np.zeros((1, 2, 4, 4)),), {}, "4×4 maps")], None),
    hidden=lambda rng: _gap_backward_cases(
        [c for c in _gap_hidden(rng) if c.label != "1×1 maps (GAP is the identity)"]
        + [Case((np.zeros((2, 3, 2, 5)),), {}, "2×5 maps"), Case((np.zeros((1, 1, 3, 3)),), {}, "3×3 map")], rng),
    compare=_TIGHT,
    mistakes=[_gap_b_not_divided, _gap_b_divided_by_batch, _gap_b_one_position, _gap_b_divided_by_h],
)


# ============================================================================================
# batch normalisation (§10.7.6)
# ============================================================================================
def _bc(v):
    return _f(v)[None, :, None, None]


def _bn_variant(x, gamma, beta, running_mean, running_var, training, momentum=0.1, eps=1e-5, *,
                norm_stats="batch", norm_ddof=0, run_ddof=1, swap_momentum=False, all_channels=False,
                eps_outside=False, update=True, eval_stats="running"):
    x, gamma, beta, rm, rv = (_f(a) for a in (x, gamma, beta, running_mean, running_var))
    axes = (0, 2, 3)
    n = x.shape[0] * x.shape[2] * x.shape[3]
    if all_channels:
        mean = np.full(x.shape[1], x.mean())
        var_b = np.full(x.shape[1], x.var())
        count = x.size
    else:
        mean, var_b = x.mean(axis=axes), x.var(axis=axes)
        count = n
    var_u = var_b * count / max(count - 1, 1)
    if training:
        use_mean, use_var = (rm, rv) if norm_stats == "running" else (mean, var_u if norm_ddof else var_b)
        m_old, m_new = (momentum, 1.0 - momentum) if swap_momentum else (1.0 - momentum, momentum)
        new_mean = m_old * rm + m_new * mean if update else rm.copy()
        new_var = m_old * rv + m_new * (var_u if run_ddof else var_b) if update else rv.copy()
        if norm_stats == "updated":  # the running statistics updated first, then used to normalise
            use_mean, use_var = new_mean, new_var
    else:
        use_mean, use_var = (mean, var_b) if eval_stats == "batch" else (rm, rv)
        new_mean, new_var = rm.copy(), rv.copy()
    denominator = np.sqrt(_bc(use_var)) + eps if eps_outside else np.sqrt(_bc(use_var) + eps)
    out = _bc(gamma) * (x - _bc(use_mean)) / denominator + _bc(beta)
    cache = {"x": x, "gamma": gamma, "beta": beta, "running_mean": new_mean, "running_var": new_var,
             "training": bool(training), "momentum": momentum, "eps": eps}
    return out, cache


def _bn_args(rng, n, c, h, w, *, low_variance=False, kind="normal"):
    means = _round(rng.normal(0, 3, c), 2)
    scales = _round(rng.uniform(0.5, 3.0, c), 2)
    if low_variance:
        scales[0] = 0.004
    if kind == "uint8":
        x = rng.integers(0, 256, (n, c, h, w), dtype=np.uint8)
    else:
        x = _round(means[None, :, None, None] + scales[None, :, None, None] * rng.standard_normal((n, c, h, w)), 4)
    gamma = _round(rng.uniform(0.5, 2.0, c), 3)
    beta = _round(rng.normal(0, 1, c), 3)
    running_mean = _round(rng.normal(0, 1, c), 3)
    running_var = _round(rng.uniform(0.5, 2.0, c), 3)
    return x, gamma, beta, running_mean, running_var


def _momentum(rng) -> float:
    return float(rng.choice([0.05, 0.1, 0.2, 0.3, 0.9]))


def _bn_hidden(rng):
    s = _size
    return [
        Case(_bn_args(rng, 2, s(rng, 2, 3), s(rng, 2, 4), s(rng, 2, 4)) + (True,), {}, "training, default momentum"),
        Case(_bn_args(rng, s(rng, 2, 4), 2, 3, 3) + (True,), {"momentum": _momentum(rng)}, "training, momentum"),
        Case(_bn_args(rng, 2, 3, 2, 3) + (False,), {}, "evaluation: the running statistics"),
        Case(_bn_args(rng, 1, 2, 2, 2) + (True,), {"momentum": 0.2}, "N = 1: statistics over the positions"),
        Case(_bn_args(rng, 4, 2, 1, 1) + (True,), {"momentum": 0.3}, "1×1 maps: statistics over the batch"),
        Case(_bn_args(rng, 2, 2, 3, 2, low_variance=True) + (True,), {"eps": 1e-4},
             "a channel of tiny variance: ε inside the square root matters"),
        Case(_bn_args(rng, 2, 2, 2, 2) + (False,), {"eps": 0.1, "momentum": 0.3},
             "evaluation with a large ε"),
        Case(_bn_args(rng, 2, 2, 2, 3, kind="uint8") + (True,), {}, "uint8 input"),
        Case(_bn_args(rng, 3, 1, 2, 2) + (True,), {"momentum": 1.0}, "momentum 1: the batch statistics replace"),
        Case(_bn_args(rng, 2, 4, 2, 2) + (False,), {"momentum": 0.2}, "evaluation, 4 channels"),
    ]


_BN_X = np.array([[[[1.0, 2.5], [0.5, -1.0]], [[10.0, 12.0], [11.0, 9.5]]],
                  [[[0.0, 3.0], [2.0, 1.5]], [[8.0, 13.0], [10.5, 12.5]]]])
_BN_PARAMS = (np.array([1.5, 0.5]), np.array([0.25, -1.0]), np.array([0.5, 9.0]), np.array([2.0, 4.0]))
_BN_PUBLIC = [
    Case((_BN_X,) + _BN_PARAMS + (True,), {"momentum": 0.2}, "training, momentum 0.2 (n = 8 values per channel)"),
    Case((_BN_X,) + _BN_PARAMS + (False,), {}, "evaluation"),
    Case((_BN_X * np.array([1.0, 0.001])[None, :, None, None],) + _BN_PARAMS + (True,), {"eps": 1e-4},
         "training, a channel of tiny variance, ε = 1e-4"),
]


_bn_running_in_training = variant(_bn_variant, norm_stats="running")
_bn_updated_running_in_training = variant(_bn_variant, norm_stats="updated")
_bn_unbiased_norm = variant(_bn_variant, norm_ddof=1)
_bn_biased_running = variant(_bn_variant, run_ddof=0)
_bn_swapped_momentum = variant(_bn_variant, swap_momentum=True)
_bn_all_channels = variant(_bn_variant, all_channels=True)
_bn_eps_outside = variant(_bn_variant, eps_outside=True)
_bn_not_updated = variant(_bn_variant, update=False)
_bn_batch_in_eval = variant(_bn_variant, eval_stats="batch")


batchnorm2d_forward = Check(
    public=_BN_PUBLIC,
    hidden=_bn_hidden,
    compare=_forward_compare(_SUMS),
    call=call_batchnorm2d_forward,
    mistakes=[
        Mistake("running statistics used while training", _bn_running_in_training,
                "In training normalise with the mean and variance of this batch (per channel over N, H, W)"),
        Mistake("updated running statistics used to normalise in training", _bn_updated_running_in_training,
                "In training normalise with this batch's mean and (biased) variance; the running statistics are "
                "updated for evaluation, not used on the batch they were just updated with"),
        Mistake("unbiased variance used to normalise", _bn_unbiased_norm,
                "Normalise with the biased batch variance (divide by n = N·H·W, np.var's default)"),
        Mistake("biased variance in the running average", _bn_biased_running,
                "The running variance is updated with the unbiased variance (× n/(n − 1)), as PyTorch does"),
        Mistake("momentum weights swapped: m·old + (1 − m)·batch", _bn_swapped_momentum,
                "new = (1 − momentum)·old + momentum·batch: momentum is the weight of the current batch"),
        Mistake("statistics over all channels together", _bn_all_channels,
                "One mean and one variance per channel: reduce over axes (0, 2, 3) only"),
        Mistake("ε added to the standard deviation", _bn_eps_outside,
                "Divide by sqrt(var + eps), with ε inside the square root"),
        Mistake("running statistics not updated", _bn_not_updated,
                "In training put (1 − m)·old + m·batch into cache['running_mean'] and cache['running_var']"),
        Mistake("batch statistics used in evaluation", _bn_batch_in_eval,
                "With training=False normalise with running_mean and running_var (and leave them unchanged)"),
    ],
)


def _bn_backward_variant(dout, cache, *, constants=False, dgamma_plain=False, no_mean_term=False,
                         running=False, ddof=0):
    x, gamma = _f(cache["x"]), _f(cache["gamma"])
    d = _f(dout)
    eps = cache["eps"]
    axes = (0, 2, 3)
    n = x.shape[0] * x.shape[2] * x.shape[3]
    training = cache["training"]
    if training and not running:
        mean, var = x.mean(axis=axes), x.var(axis=axes, ddof=ddof)
    else:
        mean, var = _f(cache["running_mean"]), _f(cache["running_var"])
    inv = 1.0 / np.sqrt(var + eps)
    x_hat = (x - _bc(mean)) * _bc(inv)
    dbeta = d.sum(axis=axes)
    dgamma = dbeta.copy() if dgamma_plain else (d * x_hat).sum(axis=axes)
    true_dgamma = (d * x_hat).sum(axis=axes)
    if training and not constants:
        mean_term = 0.0 if no_mean_term else _bc(dbeta)
        dx = _bc(gamma * inv / n) * (n * d - mean_term - x_hat * _bc(true_dgamma))
    else:
        dx = d * _bc(gamma * inv)
    return dx, dgamma, dbeta


_bn_b_constants = variant(_bn_backward_variant, constants=True)
_bn_b_dgamma_plain = variant(_bn_backward_variant, dgamma_plain=True)
_bn_b_no_mean_term = variant(_bn_backward_variant, no_mean_term=True)
_bn_b_running = variant(_bn_backward_variant, running=True)
_bn_b_unbiased = variant(_bn_backward_variant, ddof=1)


def _bn_backward_cases(cases, rng):
    return _backward_cases(_bn_forward, cases, rng, lambda shape, i: _distinct(shape, seed=71 + i, offset=0.2, scale=0.3),
                           _normal)


batchnorm2d_backward = Check(
    public=_bn_backward_cases(_BN_PUBLIC[:2], None),
    hidden=lambda rng: _bn_backward_cases(_bn_hidden(rng), rng),
    compare=Nested(_SUMS, names=("dx", "dgamma", "dbeta")),
    mistakes=[
        Mistake("batch statistics treated as constants (dx = γ·dout/σ)", _bn_b_constants,
                "In training μ and σ² depend on every x of the channel: "
                "dx = γ/(nσ)·(n·dout − Σdout − x̂·Σ(dout·x̂))"),
        Mistake("dgamma without x̂ (Σ dout)", _bn_b_dgamma_plain,
                "out = γ·x̂ + β, so dgamma = Σ dout·x̂ and dbeta = Σ dout"),
        Mistake("mean term missing in dx", _bn_b_no_mean_term,
                "Subtract the channel's Σdout too (the gradient through the mean): n·dout − Σdout − x̂·Σ(dout·x̂)"),
        Mistake("running statistics used in the backward while training", _bn_b_running,
                "cache['running_*'] are the *new* running statistics; training normalised with the batch's: "
                "recompute mean and variance from cache['x']"),
        Mistake("unbiased variance in the backward", _bn_b_unbiased,
                "The forward normalised with the biased variance (divide by n): use the same in the backward"),
    ],
)


# ============================================================================================
# dropout (§12.3.6)
# ============================================================================================
def _dropout_arg(case, index, name, default=None):
    if name in case.kwargs:
        return case.kwargs[name]
    return case.args[index] if len(case.args) > index else default


@dataclass
class DropoutStatistics(Comparator):
    """``(out, cache)`` of inverted dropout judged by its properties and the kept fraction.

    Two correct versions may keep different units, so the draws are not compared one by one.
    In training: the cache ``mask`` is a boolean array of x's shape whose True entries are
    exactly the non-zero outputs; every kept unit equals ``x / p_keep`` (the *scale* of the kept
    units); the fraction kept is within 4.5 standard deviations (+ one unit) of the reference
    draw's, the deviation of the difference of two independent binomial fractions (6 for each
    of a ``draws`` case's many calls, whose distribution :func:`_dropout_draw_statistics`
    judges). In evaluation: ``out`` equals ``x``. The numbers are measured on both outputs and
    compared, so a mistake is recognised by the same numbers ("scale 0.8, expected 1.25").
    """

    def describe(self) -> str:
        return "properties and statistics of the dropout mask"

    def statistics(self, result, case):
        x = _f(_dropout_arg(case, 0, "x"))
        training = bool(_dropout_arg(case, 2, "training"))
        out, cache = result
        out = _f(out)
        kept = out != 0
        stats = {}
        if kept.any():
            ratio = out[kept] / x[kept]
            stats["scale of the kept units (out / x)"] = float(np.median(ratio))
            stats["spread of the kept units' scale"] = float(np.ptp(ratio))
        else:
            stats["scale of the kept units (out / x)"] = float("nan")
            stats["spread of the kept units' scale"] = 0.0
        stats["fraction of units kept"] = float(kept.mean())
        if training:
            mask = np.asarray(cache.get("mask")) if isinstance(cache, dict) else None
            if mask is None or mask.shape != x.shape or mask.dtype != bool:
                stats["cache['mask'] is a boolean array of x's shape"] = 0.0
                stats["units where mask and out disagree"] = float("nan")
            else:
                stats["cache['mask'] is a boolean array of x's shape"] = 1.0
                stats["units where mask and out disagree"] = float(np.sum(mask != kept))
        return stats

    def __call__(self, got, expected, case=None):
        x = _f(_dropout_arg(case, 0, "x"))
        if not isinstance(got, (tuple, list)) or len(got) != 2:
            return Mismatch(f"your function must return (out, cache), got {_kind(got)}")
        if not isinstance(got[1], dict):
            return Mismatch(f"cache must be a dict, got {_kind(got[1])}")
        try:
            out = np.asarray(got[0], dtype=np.float64)
        except (TypeError, ValueError):
            return Mismatch(f"out must be a numeric array, got {_kind(got[0])}")
        if out.shape != x.shape:
            return Mismatch(f"out: shape mismatch: expected {x.shape}, got {out.shape}")
        mismatch = Nested(_TIGHT)({k: got[1].get(k) for k in ("x", "p_keep", "training") if k in got[1]},
                                  {k: v for k, v in expected[1].items() if k in ("x", "p_keep", "training")})
        if mismatch is not None:
            mismatch.message = "cache" + mismatch.message if mismatch.message.startswith("[") else \
                f"cache: {mismatch.message}"
            return mismatch
        p = float(_dropout_arg(case, 1, "p_keep"))
        n = x.size
        mine = self.statistics((out, got[1]), case)
        theirs = self.statistics(expected, case)
        deviations = 6.0 if case is not None and case.kwargs.get("draws") else 4.5
        tolerance = {"fraction of units kept": deviations * math.sqrt(2 * p * (1 - p) / n) + 1.0 / n}
        wrong = []
        for name, value in theirs.items():
            have = mine.get(name, float("nan"))
            tol = tolerance.get(name, 1e-9 * max(1.0, abs(value)) if math.isfinite(value) else 0.0)
            same = (math.isnan(have) and math.isnan(value)) or abs(have - value) <= tol
            if not same:
                wrong.append(f"{name}: yours {have:.6g}, expected {value:.6g}" + (f" ± {tol:.3g}" if tol else ""))
        if wrong:
            return Mismatch("The output does not behave like inverted dropout:\n" + "\n".join(wrong))
        return None


@mistake("kept units multiplied by p_keep instead of divided",
         "Inverted dropout divides the kept units by p_keep, so that the expected output equals x")
def _dropout_scaled_by_p(x, p_keep, training, rng=None):
    out, cache = _dropout_forward(x, p_keep, training, rng)
    return (out * p_keep * p_keep if training else out), cache


@mistake("p_keep used as the drop probability",
         "p_keep is the probability of *keeping* a unit: mask = rng.random(x.shape) < p_keep")
def _dropout_p_is_drop(x, p_keep, training, rng=None):
    x = _f(x)
    g = np.random.default_rng(rng)
    if not training:
        return x.copy(), {"x": x, "p_keep": p_keep, "training": training, "mask": np.ones(x.shape, bool)}
    mask = g.random(x.shape) < 1.0 - p_keep
    return np.where(mask, x / p_keep, 0.0), {"x": x, "p_keep": p_keep, "training": training, "mask": mask}


@mistake("kept units not rescaled",
         "Divide the kept units by p_keep in training (inverted dropout); evaluation is then the identity")
def _dropout_not_scaled(x, p_keep, training, rng=None):
    out, cache = _dropout_forward(x, p_keep, training, rng)
    return (out * p_keep if training else out), cache


@mistake("dropout also applied in evaluation", "With training=False return x unchanged (and no random draw is needed)")
def _dropout_in_eval(x, p_keep, training, rng=None):
    return _dropout_forward(x, p_keep, True, rng)


@mistake("evaluation output scaled by p_keep",
         "With inverted dropout the scaling happens in training; evaluation returns x as it is")
def _dropout_scaled_in_eval(x, p_keep, training, rng=None):
    out, cache = _dropout_forward(x, p_keep, training, rng)
    return (out if training else out * p_keep), cache


@mistake("exactly round(p_keep·N) units kept on every call",
         "Keep each unit on its own with probability p_keep, mask = rng.random(x.shape) < p_keep: "
         "the number kept then varies from call to call (Binomial(N, p_keep)), as dropout's noise should")
def _dropout_exact_count(x, p_keep, training, rng=None):
    x = _f(x)
    mask = np.zeros(x.size, dtype=bool)
    if training:
        mask[np.random.default_rng(rng).permutation(x.size)[:int(round(p_keep * x.size))]] = True
    else:
        mask[:] = True
    mask = mask.reshape(x.shape)
    return np.where(mask, x / p_keep, 0.0) if training else x.copy(), \
        {"x": x, "p_keep": p_keep, "training": training, "mask": mask}


@mistake("rng ignored: the same units dropped on every call",
         "Draw the mask from the generator the caller gives, g = np.random.default_rng(rng): a generator "
         "made with a fixed seed inside the function drops the same units in every training step")
def _dropout_fixed_seed(x, p_keep, training, rng=None):
    return _dropout_forward(x, p_keep, training, 0)


#: the statistics of a dropout ``draws`` case (many calls, one seed each)
_DROPOUT_DRAWS = ("variance of the number of units kept per call", "mean fraction of units kept over the calls")


def _dropout_draw_statistics(outputs, case):
    kept = [np.asarray(out, dtype=np.float64) != 0 for out, _ in outputs]
    counts = np.array([mask.sum() for mask in kept], dtype=np.float64)
    return dict(zip(_DROPOUT_DRAWS, (float(counts.var()), float(counts.mean()) / kept[0].size)))


def _dropout_draw_tolerance(case):
    """Six standard errors of the difference between two independent sets of m draws."""
    n = _f(_dropout_arg(case, 0, "x")).size
    p = float(_dropout_arg(case, 1, "p_keep"))
    m = int(case.kwargs["draws"][1])
    return dict(zip(_DROPOUT_DRAWS, (binomial_variance_tolerance(n, p, m), 6 * math.sqrt(2 * p * (1 - p) / (n * m)))))


def _nonzero(rng, shape, scale=1.0):
    x = _normal(rng, shape, scale, 3)
    x[x == 0] = 0.5
    return x


def _p(rng, lo=0.6, hi=0.9) -> float:
    return _u(rng, lo, hi, 2)


def _dropout_single_hidden(rng):
    """The hidden cases of one call each (the backward pass takes them too)."""
    return [
        Case((_nonzero(rng, (20, 40)), _p(rng), True), {"rng": _seed(rng)}, "(N, D) activations, training"),
        Case((_nonzero(rng, (4, 5, 6, 6)), _p(rng), True), {"rng": _seed(rng)}, "feature maps, training"),
        Case((_nonzero(rng, (25, 30)), _p(rng, 0.15, 0.35), True), {"rng": _seed(rng)}, "small p_keep, training"),
        Case((_nonzero(rng, (30, 30)), 0.8, True), {"rng": _seed(rng)}, "p_keep 0.8 (PyTorch's Dropout(0.2))"),
        Case((_nonzero(rng, (10, 12)), _p(rng), False), {"rng": _seed(rng)}, "evaluation: identity"),
        Case((_nonzero(rng, (2, 3, 4, 4)), _p(rng, 0.2, 0.4), False), {"rng": _seed(rng)}, "evaluation, feature maps"),
        Case((_nonzero(rng, (20, 25)), 1.0, True), {"rng": _seed(rng)}, "p_keep 1: nothing dropped"),
        Case((rng.integers(1, 256, (20, 30)).astype(np.uint8), _p(rng), True), {"rng": _seed(rng)}, "uint8 input"),
        Case((_nonzero(rng, 600), _p(rng, 0.65, 0.75), True), {"rng": _seed(rng)}, "1-D input"),
        Case((_nonzero(rng, (40, 20), 100.0), _p(rng), True), {"rng": _seed(rng)}, "large activations"),
    ]


def _dropout_hidden(rng):
    return _dropout_single_hidden(rng) + [
        Case((_nonzero(rng, (5, _size(rng, 6, 10))), _p(rng, 0.4, 0.7), True), {"draws": (_seed(rng), 500)},
             "500 calls, rng = r, r + 1, …: each unit kept on its own, a fresh mask each call"),
    ]


dropout_forward = Check(
    public=[
        Case((_distinct((20, 30), seed=81, offset=0.125), 0.8, True), {"rng": 0}, "p_keep 0.8, training"),
        Case((_distinct((4, 3, 5, 5), seed=82, offset=0.125), 0.3, True), {"rng": 1}, "p_keep 0.3, training"),
        Case((_distinct((4, 6), seed=83, offset=0.125), 0.7, False), {"rng": 2}, "evaluation"),
        Case((_distinct((5, 8), seed=84, offset=0.125), 0.6, True), {"draws": (4000, 500)},
             "500 calls, rng = 4000, 4001, …: each unit kept on its own, a fresh mask each call"),
    ],
    hidden=_dropout_hidden,
    compare=Drawn(single=DropoutStatistics(), statistics=_dropout_draw_statistics, tolerance=_dropout_draw_tolerance),
    call=call_dropout_forward,
    seeded=True,
    mistakes=[_dropout_scaled_by_p, _dropout_p_is_drop, _dropout_not_scaled, _dropout_in_eval, _dropout_scaled_in_eval,
              _dropout_exact_count, _dropout_fixed_seed],
)


@mistake("mask not rescaled (dout·mask)", "The forward divided the kept units by p_keep: dx = dout·mask / p_keep")
def _dropout_b_not_scaled(dout, cache):
    return np.where(cache["mask"], _f(dout), 0.0) if cache["training"] else _f(dout).copy()


@mistake("kept gradients multiplied by p_keep", "Divide by p_keep, as the forward did")
def _dropout_b_times_p(dout, cache):
    return np.where(cache["mask"], _f(dout) * cache["p_keep"], 0.0) if cache["training"] else _f(dout).copy()


@mistake("a mask applied in evaluation", "With training=False the layer is the identity: dx = dout")
def _dropout_b_in_eval(dout, cache):
    mask = np.asarray(cache["mask"])
    if not cache["training"]:
        mask = np.random.default_rng(0).random(mask.shape) < cache["p_keep"]
    return np.where(mask, _f(dout) / cache["p_keep"], 0.0)


@mistake("mask inverted (dropped units get the gradient)", "Only the kept units (mask True) pass the gradient")
def _dropout_b_inverted(dout, cache):
    if not cache["training"]:
        return _f(dout).copy()
    return np.where(~np.asarray(cache["mask"]), _f(dout) / cache["p_keep"], 0.0)


def _dropout_backward_cases(cases, rng):
    return _backward_cases(_dropout_forward, cases, rng,
                           lambda shape, i: _distinct(shape, seed=91 + i, offset=0.125, scale=0.25), _nonzero)


def _dropout_backward_hidden(rng):
    cases = _dropout_backward_cases(_dropout_single_hidden(rng), rng)
    return [c for c in cases if "1-D" not in c.label]


dropout_backward = Check(
    public=_dropout_backward_cases([
        Case((np.ones((4, 6)), 0.75, True), {"rng": 3}, "p_keep 0.75, training"),
        Case((np.ones((2, 2, 3, 3)), 0.5, True), {"rng": 4}, "p_keep 0.5, feature maps"),
        Case((np.ones((3, 4)), 0.6, False), {"rng": 5}, "evaluation"),
    ], None),
    hidden=_dropout_backward_hidden,
    compare=_TIGHT,
    mistakes=[_dropout_b_not_scaled, _dropout_b_times_p, _dropout_b_in_eval, _dropout_b_inverted],
)


# ============================================================================================
# residual block (§11.5.2–11.5.4)
# ============================================================================================
_BN_NAMES = ("gamma", "beta", "running_mean", "running_var")


def _residual_parts(x, params, training=True, momentum=0.1, eps=1e-5, *, relu_before_sum=False,
                    no_final_relu=False, no_shortcut=False, proj_stride=2, proj_bn=True, bn_running=False,
                    stride_in_second=False):
    """A configurable residual block built from the reference layers (for the mistakes)."""
    x = _f(x)
    p = {k: _f(v) for k, v in params.items()}
    projection = "w_proj" in p
    f = p["w1"].shape[0]
    zeros = np.zeros(f)

    def bn(h, suffix):
        args = [p[f"{k}{suffix}"] for k in _BN_NAMES]
        if bn_running and training:
            out, _ = _bn_forward(h, *args, False, momentum=momentum, eps=eps)
            return out
        return _bn_forward(h, *args, training, momentum=momentum, eps=eps)[0]

    if not projection or proj_stride == 1:
        s1, s2 = 1, 1
    elif stride_in_second:
        s1, s2 = 1, 2
    else:
        s1, s2 = 2, 1
    h = _conv_forward(x, p["w1"], zeros, s1, 1)[0]
    h = np.maximum(bn(h, "1"), 0.0)
    h = bn(_conv_forward(h, p["w2"], zeros, s2, 1)[0], "2")
    if relu_before_sum:
        h = np.maximum(h, 0.0)
    if no_shortcut:
        shortcut = 0.0
    elif projection:
        shortcut = _conv_forward(x, p["w_proj"], zeros, proj_stride, 0)[0]
        if proj_bn:
            shortcut = bn(shortcut, "_proj")
    else:
        shortcut = x
    z = h + shortcut
    out = z if (no_final_relu or relu_before_sum) else np.maximum(z, 0.0)
    return out, {"x": x, "params": params, "training": training}


_res_relu_before_sum = variant(_residual_parts, relu_before_sum=True)
_res_no_final_relu = variant(_residual_parts, no_final_relu=True)
_res_no_shortcut = variant(_residual_parts, no_shortcut=True)
_res_projection_no_stride = variant(_residual_parts, proj_stride=1)
_res_projection_no_bn = variant(_residual_parts, proj_bn=False)
_res_bn_running = variant(_residual_parts, bn_running=True)
_res_stride_second = variant(_residual_parts, stride_in_second=True)


def _res_params(rng, c, f, projection, scale=0.4):
    p = {}
    for i, (cin, k) in (("1", (c, 3)), ("2", (f, 3))) + ((("_proj", (c, 1)),) if projection else ()):
        name = "w_proj" if i == "_proj" else f"w{i}"
        p[name] = _normal(rng, (f, cin, k, k), scale, 3)
        p[f"gamma{i}"] = _round(rng.uniform(0.5, 1.5, f), 3)
        p[f"beta{i}"] = _round(rng.normal(0, 0.5, f), 3)
        p[f"running_mean{i}"] = _round(rng.normal(0, 0.5, f), 3)
        p[f"running_var{i}"] = _round(rng.uniform(0.5, 2.0, f), 3)
    return CacheDict(p)


def _res_case(rng, n, c, f, h, w, projection, training, label):
    x = _normal(rng, (n, c, h, w), 1.0, 3)
    kwargs = {} if training else {"training": False}
    return Case((x, _res_params(rng, c, f, projection)), kwargs, label)


def _res_hidden(rng):
    s = _size
    c = s(rng, 2, 3)
    return [
        _res_case(rng, 2, c, c, s(rng, 3, 5), s(rng, 3, 5), False, True, "identity shortcut, training"),
        _res_case(rng, 2, c, 2 * c, 2 * s(rng, 2, 3), 2 * s(rng, 2, 3), True, True, "projection, training"),
        _res_case(rng, 2, c, c, s(rng, 3, 5), s(rng, 4, 6), False, False, "identity shortcut, evaluation"),
        _res_case(rng, 2, c, c + 1, 2 * s(rng, 2, 3) + 1, 2 * s(rng, 2, 3) + 1, True, False,
                  "projection, evaluation, odd size"),
        _res_case(rng, 3, 2, 2, 3, 3, False, True, "small maps, training"),
        _res_case(rng, 2, 1, 3, 5, 4, True, True, "projection from one channel, non-square"),
        _res_case(rng, 2, 3, 3, 4, 4, False, False, "evaluation, 3 channels"),
        _res_case(rng, 2, 2, 4, 3, 6, True, False, "projection, evaluation, 3×6"),
    ]


_RES_PUBLIC = [
    _res_case(np.random.default_rng(101), 2, 2, 2, 4, 4, False, True, "identity shortcut, training"),
    _res_case(np.random.default_rng(102), 2, 2, 3, 5, 4, True, True, "projection (stride 2), training"),
    _res_case(np.random.default_rng(103), 2, 2, 2, 3, 4, False, False, "identity shortcut, evaluation"),
]

residual_block_forward = Check(
    public=_RES_PUBLIC,
    hidden=_res_hidden,
    compare=_forward_compare(_SUMS),
    call=call_residual_block_forward,
    allowed=_LAYERS,
    mistakes=[
        Mistake("residual sum after the ReLU: relu(F(x)) + x", _res_relu_before_sum,
                "Add the shortcut to bn2's output, then apply the ReLU: relu(F(x) + shortcut(x))"),
        Mistake("no ReLU after the sum", _res_no_final_relu,
                "The block ends with a ReLU of the sum"),
        Mistake("shortcut missing (a plain block)", _res_no_shortcut,
                "Add x (or its projection) to the output of the second batch norm"),
        Mistake("projection without stride (the block does not downsample)", _res_projection_no_stride,
                "With w_proj the block halves the resolution: stride 2 in conv1 and in the 1×1 projection"),
        Mistake("projection without its batch norm", _res_projection_no_bn,
                "The shortcut is bn_proj(conv_proj(x)) with the *_proj batch-norm parameters"),
        Mistake("batch norm with running statistics while training", _res_bn_running,
                "Pass `training` to every batch norm: in training they use the batch statistics"),
        Mistake("stride 2 in the second convolution instead of the first", _res_stride_second,
                "The first 3×3 convolution (and the projection) carry the stride 2; the second has stride 1"),
    ],
)


def _res_b(dout, cache, *, drop_identity=False, ignore_relu=False, drop_projection=False,
           bn_constants=False, no_proj_grads=False):
    dx, grads = _res_backward(dout, cache)
    x = _f(cache["x"])
    params = cache["params"]
    projection = "w_proj" in params
    out, rc = _res_forward(x, params, cache["training"])
    z_positive = out > 0
    dz = _f(dout) if ignore_relu else np.where(z_positive, _f(dout), 0.0)
    if ignore_relu or bn_constants:
        # recompute the body's gradient with the altered upstream / BN rule
        dx, grads = _res_backward_variant(dz, cache, bn_constants=bn_constants)
    if drop_identity and not projection:
        dx = dx - dz
    if drop_projection and projection:
        dx = dx - _res_projection_dx(dz, cache)
    if no_proj_grads and projection:
        grads = {k: v for k, v in grads.items() if not k.endswith("_proj")}
    return dx, grads


def _res_projection_dx(dz, cache):
    x = _f(cache["x"])
    p = {k: _f(v) for k, v in cache["params"].items()}
    zeros = np.zeros(p["w_proj"].shape[0])
    h, conv_cache = _conv_forward(x, p["w_proj"], zeros, 2, 0)
    _, bn_cache = _bn_forward(h, *(p[f"{k}_proj"] for k in _BN_NAMES), cache["training"])
    ds, _, _ = _bn_backward(dz, bn_cache)
    return _conv_backward(ds, conv_cache)[0]


def _res_backward_variant(dz, cache, bn_constants=False):
    """The block's backward from dz (the gradient after the final ReLU), optionally with batch
    norms whose statistics are treated as constants."""
    x = _f(cache["x"])
    p = {k: _f(v) for k, v in cache["params"].items()}
    training = cache["training"]
    projection = "w_proj" in p
    f = p["w1"].shape[0]
    zeros = np.zeros(f)
    stride = 2 if projection else 1
    bn_b = _bn_b_constants if bn_constants else _bn_backward
    h1, c1 = _conv_forward(x, p["w1"], zeros, stride, 1)
    a1, b1 = _bn_forward(h1, *(p[f"{k}1"] for k in _BN_NAMES), training)
    r1, rc1 = _relu_forward(a1)
    h2, c2 = _conv_forward(r1, p["w2"], zeros, 1, 1)
    _, b2 = _bn_forward(h2, *(p[f"{k}2"] for k in _BN_NAMES), training)
    g = {}
    dh, g["gamma2"], g["beta2"] = bn_b(dz, b2)
    dh, g["w2"], _ = _conv_backward(dh, c2)
    dh = np.where(_f(rc1["x"]) >= 0, dh, 0.0)
    dh, g["gamma1"], g["beta1"] = bn_b(dh, b1)
    dx, g["w1"], _ = _conv_backward(dh, c1)
    if projection:
        hp, cp = _conv_forward(x, p["w_proj"], zeros, 2, 0)
        _, bp = _bn_forward(hp, *(p[f"{k}_proj"] for k in _BN_NAMES), training)
        ds, g["gamma_proj"], g["beta_proj"] = bn_b(dz, bp)
        ds, g["w_proj"], _ = _conv_backward(ds, cp)
        dx = dx + ds
    else:
        dx = dx + dz
    order = ("w1", "gamma1", "beta1", "w2", "gamma2", "beta2") + (
        ("w_proj", "gamma_proj", "beta_proj") if projection else ())
    return dx, {k: g[k] for k in order}


_res_b_no_identity = variant(_res_b, drop_identity=True)
_res_b_ignore_relu = variant(_res_b, ignore_relu=True)
_res_b_no_projection_dx = variant(_res_b, drop_projection=True)
_res_b_bn_constants = variant(_res_b, bn_constants=True)
_res_b_no_proj_grads = variant(_res_b, no_proj_grads=True)


def _res_backward_cases(cases, rng):
    out = []
    for i, case in enumerate(cases):
        y, cache = _res_forward(*case.args, **case.kwargs)
        cache = CacheDict(cache)
        cache["params"] = CacheDict(cache["params"])
        g = np.random.default_rng(111 + i) if rng is None else rng
        out.append(Case((_normal(g, y.shape, 1.0, 3), cache), {}, case.label))
    return out


residual_block_backward = Check(
    public=_res_backward_cases(_RES_PUBLIC, None),
    hidden=lambda rng: _res_backward_cases(_res_hidden(rng), rng),
    compare=Nested(_SUMS, names=("dx", "grads")),
    allowed=_LAYERS,
    mistakes=[
        Mistake("identity shortcut's gradient missing in dx", _res_b_no_identity,
                "y = F(x) + x: x also receives the gradient through the shortcut, dx = dx_F + dz"),
        Mistake("final ReLU ignored in the backward", _res_b_ignore_relu,
                "Pass dout through the last ReLU's gradient first: dz = dout · [z ≥ 0]"),
        Mistake("projection's gradient not added to dx", _res_b_no_projection_dx,
                "With a projection, x also gets the gradient through bn_proj and the 1×1 convolution"),
        Mistake("batch-norm statistics treated as constants", _res_b_bn_constants,
                "In training use the full batch-norm backward (the batch mean and variance depend on x)"),
        Mistake("gradients of the projection missing", _res_b_no_proj_grads,
                "grads needs w_proj, gamma_proj and beta_proj when the block has a projection"),
    ],
)


# ============================================================================================
# architectures as data (§11.2–11.5)
# ============================================================================================
def _count_types(spec, counts):
    for layer in spec:
        kind = layer.get("type") if isinstance(layer, dict) else None
        counts[kind] = counts.get(kind, 0) + 1
        if kind == "residual":
            _count_types(layer.get("body", []), counts)
            _count_types(layer.get("shortcut", []), counts)
        elif kind == "concat":
            for branch in layer.get("branches", []):
                _count_types(branch, counts)
    return counts


def spec_summary(spec, name):
    """What a spec is graded on: ``{"parameters", "flops", "output_shape", "layers"}`` measured
    with the reference accounting on ``spec``, the layers of architecture ``name`` (its input
    is the architecture's usual input, :data:`cvkit.nn.ARCHITECTURES`). Anything but a list is
    returned as it is (a tuple as a list), for the comparator to reject."""
    if not isinstance(spec, list):
        return spec if not isinstance(spec, tuple) else list(spec)
    shape = _arch.ARCHITECTURES[name][0]
    out_shape, flops = _arch._walk(spec, shape)
    counts = _count_types(spec, {})
    layers = {kind: int(counts.get(kind, 0)) for kind in ("conv", "bn", "linear", "residual", "concat", "maxpool", "relu")}
    bodies = {}
    for layer in spec:
        if isinstance(layer, dict) and layer.get("type") == "residual":
            _count_types(layer.get("body", []), bodies)
    layers["relu inside residual bodies"] = int(bodies.get("relu", 0))  # the ReLU after the sum is not
    return {"parameters": int(_arch._parameters(spec)), "flops": int(flops),
            "output_shape": tuple(int(v) for v in out_shape), "layers": layers}


class SpecAccounting(Comparator):
    """Architecture specs compared by what they describe: parameters, FLOPs, output shape and
    the number of layers of each type, all exactly (:func:`spec_summary` on both sides; the
    architecture's name is the case's first argument)."""

    def __init__(self):
        self.inner = Nested(close(rtol=0.0, atol=0.0))

    def describe(self) -> str:
        return "parameters, FLOPs, output shape and layers of each type, exactly"

    def __call__(self, got, expected, case=None):
        name = case.args[0] if case is not None and getattr(case, "args", None) else None
        if name not in _arch.ARCHITECTURES:
            return self.inner(got, expected, case)
        try:
            mine = spec_summary(got, name)
        except Exception as error:  # noqa: BLE001 - a malformed spec is a wrong answer, said in words
            return Mismatch(f"your spec cannot be measured: {type(error).__name__}: {str(error)[:200]}")
        return self.inner(mine, spec_summary(expected, name), case)


def _walk_layers(spec, fn):
    for layer in spec:
        fn(layer)
        if layer["type"] == "residual":
            _walk_layers(layer["body"], fn)
            _walk_layers(layer["shortcut"], fn)
        elif layer["type"] == "concat":
            for branch in layer["branches"]:
                _walk_layers(branch, fn)


def _spec_variant(name, num_classes=1000, *, conv_bias=None, family="", replaced=None, projection_bn=True,
                  relus=True, relu_in_body=False):
    """The reference spec of ``name``, wrong in one way: for a ``name`` starting with
    ``family``, every convolution's bias set to ``conv_bias`` (when not None); ``replaced`` =
    (name, other) builds ``other`` in place of ``name``; no batch norm in the projection
    shortcuts unless ``projection_bn``."""
    if replaced is not None and name == replaced[0]:
        spec = _arch.architecture_spec(replaced[1], num_classes)
    else:
        spec = _arch.architecture_spec(name, num_classes)

    def change(layer):
        if conv_bias is not None and name.startswith(family) and layer["type"] == "conv":
            layer["bias"] = conv_bias
        if not projection_bn and layer["type"] == "residual":
            layer["shortcut"] = [l for l in layer["shortcut"] if l["type"] != "bn"]
    _walk_layers(spec, change)
    if relu_in_body:  # the ReLU after the sum moved to the end of the body (before the sum)
        moved = []
        for layer in spec:
            if layer["type"] == "relu" and moved and moved[-1]["type"] == "residual":
                moved[-1]["body"].append(dict(layer))
            else:
                moved.append(layer)
        spec = moved
    if not relus:
        def strip(layers):
            kept = []
            for layer in layers:
                if layer["type"] == "relu":
                    continue
                if layer["type"] == "residual":
                    layer["body"], layer["shortcut"] = strip(layer["body"]), strip(layer["shortcut"])
                elif layer["type"] == "concat":
                    layer["branches"] = [strip(branch) for branch in layer["branches"]]
                kept.append(layer)
            return kept
        spec = strip(spec)
    return spec


_spec_vgg_no_bias = variant(_spec_variant, family="vgg", conv_bias=False)
_spec_resnet50_v1 = variant(_spec_variant, replaced=("resnet50", "resnet50_v1"))
_spec_projection_no_bn = variant(_spec_variant, projection_bn=False)
_spec_resnet_conv_bias = variant(_spec_variant, family="resnet", conv_bias=True)
_spec_inception_naive = variant(_spec_variant, replaced=("inception_3a", "inception_3a_naive"))
_spec_no_relu = variant(_spec_variant, relus=False)
_spec_relu_in_body = variant(_spec_variant, relu_in_body=True)


_SPEC_NAMES = ("vgg16", "resnet18", "resnet50", "inception_3a")


def _spec_hidden(rng):
    cases = []
    for name in _SPEC_NAMES:
        cases.append(Case((name,), {}, f"{name}, 1000 classes"))
        if name != "inception_3a":
            cases.append(Case((name,), {"num_classes": _size(rng, 2, 200)}, f"{name}, another number of classes"))
    cases.append(Case(("resnet18",), {"num_classes": 10}, "resnet18, 10 classes"))
    cases.append(Case(("vgg16",), {"num_classes": int(rng.choice([2, 37, 100]))}, "vgg16, few classes"))
    return cases


architecture_spec = Check(
    public=[Case((name,), {}, name) for name in _SPEC_NAMES],
    hidden=_spec_hidden,
    compare=SpecAccounting(),
    mistakes=[
        Mistake("VGG convolutions without bias", _spec_vgg_no_bias,
                "VGG's convolutions have a bias (there is no batch norm in VGG-16)"),
        Mistake("ResNet-50 with the stride in the first 1×1 (v1, not v1.5)", _spec_resnet50_v1,
                "torchvision's ResNet-50 (v1.5 = ResNet-B) puts the stride 2 of a downsampling bottleneck in its 3×3 "
                "convolution; same parameters, more FLOPs"),
        Mistake("projection shortcuts without batch norm", _spec_projection_no_bn,
                "A projection shortcut is a 1×1 convolution with stride, followed by batch norm"),
        Mistake("ResNet convolutions with bias", _spec_resnet_conv_bias,
                "ResNet's convolutions have no bias (the batch norm after them has β)"),
        Mistake("Inception 3a without the 1×1 reductions (the naive module)", _spec_inception_naive,
                "Put 1×1 convolutions (96 and 16 channels) before the 3×3 and 5×5 branches, and a 1×1 (32) after "
                "the pooling"),
        Mistake("block's last ReLU inside the body (before the sum)", _spec_relu_in_body,
                "A residual block adds the shortcut first, then applies the ReLU: put {'type': 'relu'} after the "
                "residual layer, not at the end of its body"),
        Mistake("no ReLU layers", _spec_no_relu,
                "Activations are layers of the spec too: a {'type': 'relu'} after every convolution (or its batch "
                "norm) and hidden linear layer, as the exercise lists them"),
    ],
)


# --- count_parameters / count_flops --------------------------------------------------------
def _param_variant(spec, *, no_bias=False, no_bn=False, bn_four=False, no_in=False, no_shortcut=False,
                   first_branch=False):
    total = 0
    for layer in spec:
        kind = layer["type"]
        if kind in ("conv", "linear"):
            k = layer.get("kernel", 1) if kind == "conv" else 1
            kh, kw = (k, k) if isinstance(k, int) else tuple(k)
            cin = 1 if no_in else layer["in"]
            total += layer["out"] * cin * kh * kw
            if layer.get("bias", True) and not no_bias:
                total += layer["out"]
        elif kind == "bn":
            total += 0 if no_bn else (4 if bn_four else 2) * layer["channels"]
        elif kind == "residual":
            flags = dict(no_bias=no_bias, no_bn=no_bn, bn_four=bn_four, no_in=no_in, no_shortcut=no_shortcut,
                         first_branch=first_branch)
            total += _param_variant(layer["body"], **flags)
            if not no_shortcut:
                total += _param_variant(layer.get("shortcut", []), **flags)
        elif kind == "concat":
            flags = dict(no_bias=no_bias, no_bn=no_bn, bn_four=bn_four, no_in=no_in, no_shortcut=no_shortcut,
                         first_branch=first_branch)
            branches = layer["branches"][:1] if first_branch else layer["branches"]
            total += sum(_param_variant(b, **flags) for b in branches)
    return total


_params_no_bias = variant(_param_variant, no_bias=True)
_params_no_bn = variant(_param_variant, no_bn=True)
_params_bn_four = variant(_param_variant, bn_four=True)
_params_no_in = variant(_param_variant, no_in=True)
_params_no_shortcut = variant(_param_variant, no_shortcut=True)
_params_first_branch = variant(_param_variant, first_branch=True)


def _random_conv(rng, cin, cout=None, *, kernel=None, bias=None, stride=None, padding=None):
    k = kernel if kernel is not None else int(rng.choice([1, 3, 5]))
    layer = {"type": "conv", "in": cin, "out": cout or _size(rng, 2, 16), "kernel": k}
    if stride is not None:
        layer["stride"] = stride
    if padding is not None:
        layer["padding"] = padding
    if bias is not None:
        layer["bias"] = bias
    return layer


def _small_resnet_like(rng, cin=3):
    c = _size(rng, 4, 8)
    f = 2 * c
    return SpecList([
        {"type": "conv", "in": cin, "out": c, "kernel": 3, "stride": 1, "padding": 1, "bias": False},
        {"type": "bn", "channels": c}, {"type": "relu"},
        {"type": "residual",
         "body": [{"type": "conv", "in": c, "out": f, "kernel": 3, "stride": 2, "padding": 1, "bias": False},
                  {"type": "bn", "channels": f}, {"type": "relu"},
                  {"type": "conv", "in": f, "out": f, "kernel": 3, "stride": 1, "padding": 1, "bias": False},
                  {"type": "bn", "channels": f}],
         "shortcut": [{"type": "conv", "in": c, "out": f, "kernel": 1, "stride": 2, "padding": 0, "bias": False},
                      {"type": "bn", "channels": f}]},
        {"type": "relu"},
        {"type": "residual",
         "body": [{"type": "conv", "in": f, "out": f, "kernel": 3, "padding": 1, "bias": False},
                  {"type": "bn", "channels": f}, {"type": "relu"},
                  {"type": "conv", "in": f, "out": f, "kernel": 3, "padding": 1, "bias": False},
                  {"type": "bn", "channels": f}],
         "shortcut": []},
        {"type": "relu"}, {"type": "gap"}, {"type": "linear", "in": f, "out": _size(rng, 2, 10)},
    ])


def _small_vgg_like(rng, cin=3, side=16):
    c1, c2 = _size(rng, 3, 8), _size(rng, 6, 12)
    return SpecList([
        {"type": "conv", "in": cin, "out": c1, "kernel": 3, "padding": 1}, {"type": "relu"},
        {"type": "maxpool", "kernel": 2, "stride": 2},
        {"type": "conv", "in": c1, "out": c2, "kernel": 3, "padding": 1, "bias": True}, {"type": "relu"},
        {"type": "maxpool", "kernel": 2},
        {"type": "flatten"},
        {"type": "linear", "in": c2 * (side // 4) ** 2, "out": _size(rng, 8, 20)}, {"type": "relu"},
        {"type": "linear", "in": 0, "out": _size(rng, 2, 10), "bias": True},
    ])


def _fix_linear_chain(spec):
    prev = None
    for layer in spec:
        if layer["type"] == "linear":
            if prev is not None and layer["in"] == 0:
                layer["in"] = prev
            prev = layer["out"]
    return spec


def _small_inception(rng, cin=None):
    cin = cin or _size(rng, 6, 12)
    r3, r5 = _size(rng, 2, 5), _size(rng, 1, 3)
    branches = [
        [_random_conv(rng, cin, _size(rng, 2, 6), kernel=1, padding=0, bias=True), {"type": "relu"}],
        [_random_conv(rng, cin, r3, kernel=1), {"type": "relu"},
         _random_conv(rng, r3, _size(rng, 3, 8), kernel=3, padding=1), {"type": "relu"}],
        [_random_conv(rng, cin, r5, kernel=1, bias=False), {"type": "bn", "channels": r5}, {"type": "relu"},
         _random_conv(rng, r5, _size(rng, 2, 4), kernel=5, padding=2)],
        [{"type": "maxpool", "kernel": 3, "stride": 1, "padding": 1},
         _random_conv(rng, cin, _size(rng, 2, 4), kernel=1)],
    ]
    return SpecList([{"type": "concat", "branches": branches}]), cin


def _params_hidden(rng):
    inception, _ = _small_inception(rng)
    return [
        Case((SpecList(_arch.architecture_spec("vgg16")),), {}, "VGG-16"),
        Case((SpecList(_arch.architecture_spec("resnet18", _size(rng, 2, 100))),), {}, "ResNet-18, other classes"),
        Case((SpecList(_arch.architecture_spec("resnet50")),), {}, "ResNet-50"),
        Case((SpecList(_arch.architecture_spec("inception_3a")),), {}, "Inception 3a"),
        Case((_small_resnet_like(rng),), {}, "small ResNet: projection and identity blocks"),
        Case((SpecList(_fix_linear_chain(_small_vgg_like(rng))),), {}, "small VGG: default biases"),
        Case((inception,), {}, "small Inception module"),
        Case((SpecList([_random_conv(rng, 3, 8, kernel=[1, 3], padding=[0, 1], bias=False),
                        {"type": "bn", "channels": 8},
                        _random_conv(rng, 8, 8, kernel=[3, 1], padding=[1, 0], bias=True)]),), {},
             "asymmetric 1×3 and 3×1 kernels (Inception v3)"),
        Case((SpecList([{"type": "linear", "in": _size(rng, 10, 100), "out": _size(rng, 2, 10), "bias": False}]),),
             {}, "one linear layer without bias"),
        Case((SpecList([{"type": "bn", "channels": _size(rng, 3, 64)}, {"type": "relu"}]),), {}, "batch norm only"),
    ]


_PARAMS_PUBLIC_SPEC = SpecList([
    {"type": "conv", "in": 3, "out": 8, "kernel": 3, "stride": 1, "padding": 1},
    {"type": "bn", "channels": 8}, {"type": "relu"},
    {"type": "residual",
     "body": [{"type": "conv", "in": 8, "out": 16, "kernel": 3, "stride": 2, "padding": 1, "bias": False},
              {"type": "bn", "channels": 16}],
     "shortcut": [{"type": "conv", "in": 8, "out": 16, "kernel": 1, "stride": 2, "bias": False},
                  {"type": "bn", "channels": 16}]},
    {"type": "relu"}, {"type": "gap"}, {"type": "linear", "in": 16, "out": 10},
])
_INCEPTION_PUBLIC = SpecList([{"type": "concat", "branches": [
    [{"type": "conv", "in": 6, "out": 4, "kernel": 1}, {"type": "relu"}],
    [{"type": "conv", "in": 6, "out": 3, "kernel": 1}, {"type": "relu"},
     {"type": "conv", "in": 3, "out": 5, "kernel": 3, "padding": 1}],
    [{"type": "maxpool", "kernel": 3, "stride": 1, "padding": 1}, {"type": "conv", "in": 6, "out": 2, "kernel": 1}],
]}])

count_parameters = Check(
    public=[
        Case((_PARAMS_PUBLIC_SPEC,), {}, "conv, bn, a residual block with projection, gap, linear"),
        Case((_INCEPTION_PUBLIC,), {}, "a small Inception module"),
        Case((SpecList(_arch.architecture_spec("resnet18")),), {}, "ResNet-18"),
    ],
    hidden=_params_hidden,
    compare=IntegerResult(),
    mistakes=[
        Mistake("biases not counted", _params_no_bias,
                "A layer with bias (the default) has one more parameter per output channel"),
        Mistake("batch norm's γ and β not counted", _params_no_bn, "Each batch norm learns γ and β: 2 per channel"),
        Mistake("running statistics counted as parameters", _params_bn_four,
                "Running mean and variance are buffers, not learned: count 2 per channel (γ, β)"),
        Mistake("input channels forgotten (out·kh·kw)", _params_no_in,
                "Each filter is as deep as its input: out·in·kh·kw weights (§10.7.3)"),
        Mistake("shortcut layers not counted", _params_no_shortcut,
                "The projection shortcut (1×1 conv + BN) of a residual layer has parameters too"),
        Mistake("only the first branch of a concat counted", _params_first_branch,
                "Add up the parameters of every branch of a concat"),
    ],
)


def _flops_variant(spec, shape, *, single=False, no_stride=False, no_padding=False, no_linear=False,
                   no_shortcut=False, no_in=False, pool_stride_one=False):
    flags = dict(single=single, no_stride=no_stride, no_padding=no_padding, no_linear=no_linear,
                 no_shortcut=no_shortcut, no_in=no_in, pool_stride_one=pool_stride_one)
    flops = 0
    for layer in spec:
        kind = layer["type"]
        if kind in ("conv", "maxpool", "avgpool"):
            c, h, w = shape
            kh, kw = _arch._pair(layer["kernel"], "kernel", 1)
            sh, sw = _arch._pair(layer.get("stride", 1 if kind == "conv" or pool_stride_one else layer["kernel"]), "stride", 1)
            ph, pw = _arch._pair(layer.get("padding", 0), "padding", 0)
            true_h, true_w = (h + 2 * ph - kh) // sh + 1, (w + 2 * pw - kw) // sw + 1
            if kind == "conv":
                ch = h if no_stride else ((h - kh) // sh + 1 if no_padding else true_h)
                cw = w if no_stride else ((w - kw) // sw + 1 if no_padding else true_w)
                cin = 1 if no_in else layer["in"]
                flops += (1 if single else 2) * layer["out"] * ch * cw * cin * kh * kw
                shape = (layer["out"], true_h, true_w)
            else:
                shape = (c, true_h, true_w)
        elif kind == "gap":
            shape = (shape[0],)
        elif kind == "flatten":
            shape = (int(np.prod(shape)),)
        elif kind == "linear":
            if not no_linear:
                flops += (1 if single else 2) * layer["in"] * layer["out"]
            shape = (layer["out"],)
        elif kind == "residual":
            s, f = _flops_variant(layer["body"], shape, **flags)
            if not no_shortcut:
                f += _flops_variant(layer.get("shortcut", []), shape, **flags)[1]
            shape, flops = s, flops + f
        elif kind == "concat":
            outs = [_flops_variant(b, shape, **flags) for b in layer["branches"]]
            flops += sum(f for _, f in outs)
            shape = (sum(s[0] for s, _ in outs),) + outs[0][0][1:]
    return shape, flops


def _flops_mistake(flag):
    """A mistake of model_flops: :func:`_flops_variant` with ``flag`` set, its count only."""
    def wrong(spec, input_shape):
        return _flops_variant(spec, tuple(input_shape), **{flag: True})[1]
    wrong.__name__ = wrong.__qualname__ = f"_flops_{flag}"
    return wrong


_flops_single, _flops_no_stride, _flops_no_padding, _flops_no_linear, _flops_no_shortcut, _flops_no_in, \
    _flops_pool_stride_one = (_flops_mistake(flag) for flag in ("single", "no_stride", "no_padding", "no_linear",
                                                                "no_shortcut", "no_in", "pool_stride_one"))


def _flops_hidden(rng):
    inception, cin = _small_inception(rng)
    side = 4 * _size(rng, 3, 6)
    return [
        Case((SpecList(_arch.architecture_spec("vgg16")), (3, 224, 224)), {}, "VGG-16 at 224×224"),
        Case((SpecList(_arch.architecture_spec("resnet18")), (3, 224, 224)), {}, "ResNet-18 at 224×224"),
        Case((SpecList(_arch.architecture_spec("resnet50")), (3, 160, 160)), {}, "ResNet-50 at 160×160"),
        Case((SpecList(_arch.architecture_spec("inception_3a")), (192, 28, 28)), {}, "Inception 3a"),
        Case((_small_resnet_like(rng), (3, side, side + 4)), {}, "small ResNet on a non-square input"),
        Case((SpecList(_fix_linear_chain(_small_vgg_like(rng, side=side))), (3, side, side)), {}, "small VGG"),
        Case((inception, (cin, _size(rng, 5, 12), _size(rng, 5, 12))), {}, "small Inception module"),
        Case((SpecList([_random_conv(rng, 2, 6, kernel=3, stride=2, padding=1),
                        _random_conv(rng, 6, 4, kernel=[1, 3], padding=[0, 1])]), (2, 2 * _size(rng, 4, 8) + 1, 9)),
             {}, "stride 2 on an odd size, asymmetric kernel"),
        Case((SpecList([{"type": "conv", "in": 3, "out": 4, "kernel": 5, "stride": 3},
                        {"type": "maxpool", "kernel": 3, "stride": 2}, {"type": "flatten"},
                        {"type": "linear", "in": 0, "out": 7}]), (3, 29, 29)), {},
         "stride 3, pooling, linear"),
        Case((SpecList([_random_conv(rng, 3, 5, kernel=3, padding=1), {"type": "maxpool", "kernel": int(rng.choice([2, 3]))},
                        _random_conv(rng, 5, 4, kernel=3, padding=1)]), (3, _size(rng, 12, 20), _size(rng, 12, 20))),
             {}, "pooling without a stride (it defaults to the kernel), then a convolution"),
    ]


def _patch_flatten(cases):
    """Fill the ``in`` of a linear layer after ``flatten`` (left 0 by the generators)."""
    for case in cases:
        spec, shape = case.args
        if any(l.get("type") == "linear" and l.get("in") == 0 for l in spec):
            current = tuple(shape)
            for layer in spec:
                if layer["type"] == "linear" and layer["in"] == 0:
                    layer["in"] = int(np.prod(current))
                current, _ = _arch._walk([layer], current)
    return cases


count_flops = Check(
    public=[
        Case((_PARAMS_PUBLIC_SPEC, (3, 8, 8)), {}, "conv, bn, residual with projection, gap, linear on 8×8"),
        Case((_INCEPTION_PUBLIC, (6, 5, 7)), {}, "a small Inception module on 5×7"),
        Case((SpecList([{"type": "conv", "in": 3, "out": 4, "kernel": 3, "stride": 2, "padding": 1},
                        {"type": "maxpool", "kernel": 2}, {"type": "flatten"},
                        {"type": "linear", "in": 64, "out": 5}]), (3, 16, 16)), {},
             "stride 2 and padding, pooling, linear"),
        Case((SpecList([{"type": "conv", "in": 3, "out": 4, "kernel": 3, "padding": 1}, {"type": "maxpool", "kernel": 2},
                        {"type": "conv", "in": 4, "out": 6, "kernel": 3, "padding": 1}]), (3, 12, 12)), {},
             "pooling without a stride (it defaults to the kernel), then a convolution"),
    ],
    hidden=lambda rng: _patch_flatten(_flops_hidden(rng)),
    compare=IntegerResult(),
    allowed=("nn.conv_output_size",),
    mistakes=[
        Mistake("multiply-adds not doubled", _flops_single,
                "Count 2 FLOPs per multiply-add (one multiplication, one addition)"),
        Mistake("output size computed without the stride", _flops_no_stride,
                "A strided layer computes only Ho·Wo = ((H − K + 2P)//S + 1)² positions"),
        Mistake("padding ignored in the output size", _flops_no_padding,
                "Padded layers compute (H − K + 2P)//S + 1 positions along each axis"),
        Mistake("linear layers not counted", _flops_no_linear, "A linear layer costs 2·in·out FLOPs"),
        Mistake("shortcut layers not counted", _flops_no_shortcut,
                "The projection shortcut's 1×1 convolution costs FLOPs too"),
        Mistake("input channels forgotten", _flops_no_in,
                "Each output value is a dot product over in·kh·kw inputs: 2·out·Ho·Wo·in·kh·kw"),
        Mistake("pooling stride defaults to 1", _flops_pool_stride_one,
                "A pooling layer without a stride moves by its kernel (PyTorch's default): a 2×2 pooling halves H and W"),
    ],
)
