"""Shared scaffolding of the chapter checks (``cvkit/<topic>/checks.py``).

The checks of every chapter draw hidden cases from a grading seed, read a case's arguments
back in their comparators and statistics, and build their mistake banks from parametrised
wrong implementations. The helpers they have in common live here:

- drawing: :func:`size`, :func:`seed`, :func:`uniform`, :func:`sigma`, :func:`random_image`;
- fixed inputs: :func:`distinct` (shuffled distinct integers: every flip, shift and swap
  shows), :func:`rounded` (values readable in reports), :data:`BORDERS`,
  :data:`SWAPPED_REFLECT` and :func:`swap_reflect`;
- reading a case: :func:`argument`;
- mistakes: :func:`variant` (one named wrong version out of a parametrised one),
  :func:`with_border` and the border mistakes of the filters :func:`border_zero`,
  :func:`reflect_swapped` and :func:`border_mistakes`.

**Reproducibility.** Hidden cases must be the same for the same seed forever (a regrade must
not change a grade), so each helper draws from the generator with exactly the calls written in
its docstring, in that order, and nothing else; its argument checks never draw.

Comparators' helpers (a candidate's output as an array, shape advice, statistics) are in
:mod:`cvkit.grading.compare`.
"""
from __future__ import annotations

import inspect
import math
from typing import Any, Callable, Sequence

import numpy as np

from .checks import Case, Mistake

__all__ = [
    "BORDERS", "SWAPPED_REFLECT", "argument", "distinct", "random_image", "rounded", "seed", "sigma",
    "size", "swap_reflect", "uniform", "variant", "with_border", "border_zero", "reflect_swapped",
    "border_mistakes", "SWAPPED_REFLECT_HINT",
]

#: the border modes of the filters (``border=`` of ``filters.pad`` and its callers)
BORDERS = ("zero", "replicate", "reflect", "reflect101")
#: each reflecting border mode and the one it is confused with (the edge pixel repeated or not)
SWAPPED_REFLECT = {"reflect": "reflect101", "reflect101": "reflect"}

def swap_reflect(border: Any) -> Any:
    """The border mode a "reflect and reflect101 swapped" mistake uses instead of ``border``
    (:data:`SWAPPED_REFLECT`; any other mode unchanged).

    >>> swap_reflect("reflect"), swap_reflect("zero")
    ('reflect101', 'zero')
    """
    return SWAPPED_REFLECT.get(border, border)


#: the hint of the "reflect and reflect101 swapped" mistake (:func:`reflect_swapped`)
SWAPPED_REFLECT_HINT = "`reflect` repeats the edge pixel (dcb|abcd|cba); `reflect101` does not (dc|abcd|cb)"


#: what :func:`random_image` can draw
IMAGE_KINDS = ("unit", "uint8", "big", "normal", "const")


def _generator(rng: Any, where: str) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"{where}: rng must be a numpy.random.Generator (np.random.default_rng(seed)), "
                        f"got {type(rng).__name__}")
    return rng


def _integer(value: Any, name: str, where: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{where}: {name} must be an integer, got {type(value).__name__} {value!r}")
    return int(value)


def size(rng: np.random.Generator, lo: int, hi: int) -> int:
    """A random integer in ``[lo, hi]``, both ends included (an image side, a count).

    Draws ``rng.integers(lo, hi + 1)``, once.

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator of the hidden cases.
    lo, hi : int
        The smallest and the largest value, ``lo <= hi``.

    Returns
    -------
    int

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> all(3 <= size(rng, 3, 5) <= 5 for _ in range(20))
    True
    """
    _generator(rng, "size")
    lo, hi = _integer(lo, "lo", "size"), _integer(hi, "hi", "size")
    if hi < lo:
        raise ValueError(f"size: hi must be at least lo, got lo={lo}, hi={hi}")
    return int(rng.integers(lo, hi + 1))


def seed(rng: np.random.Generator, high: int = 2**32) -> int:
    """A seed for a random function's ``rng`` argument, in ``[0, high)``.

    Draws ``rng.integers(0, high)``, once.

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator of the hidden cases.
    high : int
        One more than the largest seed (``2**32``; ``2**31`` where a case wants 31 bits).

    Returns
    -------
    int
    """
    _generator(rng, "seed")
    high = _integer(high, "high", "seed")
    if high < 1:
        raise ValueError(f"seed: high must be at least 1, got {high}")
    return int(rng.integers(0, high))


def uniform(rng: np.random.Generator, lo: float, hi: float, digits: int = 3) -> float:
    """A random number in ``[lo, hi)`` rounded to ``digits`` decimals (readable in reports).

    Draws ``rng.uniform(lo, hi)``, once.

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator of the hidden cases.
    lo, hi : float
        The range.
    digits : int
        Decimals kept (``np.round``).

    Returns
    -------
    float
    """
    _generator(rng, "uniform")
    return float(np.round(rng.uniform(lo, hi), _integer(digits, "digits", "uniform")))


def sigma(rng: np.random.Generator, lo: float, hi: float, *, frac: tuple[float, float] = (0.1, 0.9)) -> float:
    """A Gaussian σ in ``[lo, hi]`` that no rounding rule can hide: σ ≠ 1 (by more than 0.05)
    and the fractional part of 3σ in ``frac`` (far from an integer, so ceil, floor and round
    of the kernel radius 3σ disagree and 3σ never sits on a rounding edge).

    Draws ``rng.uniform(lo, hi)`` (rounded to 3 decimals) until one fits, at most 1000 times.

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator of the hidden cases.
    lo, hi : float
        The range of σ.
    frac : (float, float)
        The allowed range of the fractional part of 3σ.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        When no σ of the range fits after 1000 draws (a range too narrow for ``frac``).
    """
    _generator(rng, "sigma")
    for _ in range(1000):
        s = float(np.round(rng.uniform(lo, hi), 3))
        f = 3 * s - math.floor(3 * s)
        if frac[0] <= f <= frac[1] and abs(s - 1.0) > 0.05:
            return s
    raise ValueError(f"sigma: no σ in [lo, hi] = [{lo}, {hi}] has 3σ with a fractional part in frac = {frac}")


def random_image(rng: np.random.Generator, shape: Sequence[int], kind: str = "unit") -> np.ndarray:
    """A random image of one of the awkward kinds hidden cases need.

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator of the hidden cases.
    shape : tuple of int
        ``(H, W)`` or ``(H, W, C)``.
    kind : str
        What it draws (once):

        - ``"unit"``: floats in [0, 1), ``rng.random(shape)``;
        - ``"uint8"``: ``rng.integers(0, 256, shape, dtype=np.uint8)`` (integer input must not be
          rescaled);
        - ``"big"``: ±1e6 values, ``rng.uniform(-1e6, 1e6, shape)`` (round-off relative to the scale);
        - ``"normal"``: negative values too, ``rng.normal(0.0, 3.0, shape)``;
        - ``"const"``: one value everywhere, ``rng.uniform(-5, 5)`` rounded to 3 decimals.

    Returns
    -------
    numpy.ndarray
    """
    _generator(rng, "random_image")
    shape = tuple(int(n) for n in shape)
    if kind == "unit":
        return rng.random(shape)
    if kind == "uint8":
        return rng.integers(0, 256, shape, dtype=np.uint8)
    if kind == "big":
        return rng.uniform(-1e6, 1e6, shape)
    if kind == "normal":
        return rng.normal(0.0, 3.0, shape)
    if kind == "const":
        return np.full(shape, float(np.round(rng.uniform(-5, 5), 3)))
    raise ValueError(f"random_image: kind must be one of {', '.join(map(repr, IMAGE_KINDS))}, got {kind!r}")


def distinct(shape: int | Sequence[int], *, seed: int = 7, scale: float = 1.0, dtype: Any = np.float64) -> np.ndarray:
    """Distinct integers ``0 .. n−1`` (times ``scale``) in a fixed shuffled order: a small input
    on which every flip, shift, transposition and border rule shows in the output.

    The order is ``np.random.default_rng(seed).permutation(n)``: it does not touch the hidden
    cases' generator.

    Parameters
    ----------
    shape : int or tuple of int
        The array's shape (``n`` is its number of elements).
    seed : int
        Seed of the shuffle.
    scale : float
        Factor applied to the integers.
    dtype : numpy dtype
        The result's dtype (``(values * scale).astype(dtype)``).

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> a = distinct((2, 3))
    >>> sorted(a.ravel().tolist())
    [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    """
    shape = (int(shape),) if isinstance(shape, (int, np.integer)) else tuple(int(n) for n in shape)
    if any(n < 0 for n in shape):
        raise ValueError(f"distinct: shape must not have negative sides, got {shape}")
    values = np.random.default_rng(seed).permutation(math.prod(shape)).reshape(shape)
    return (values * scale).astype(dtype)


def rounded(values: Any, decimals: int = 3) -> np.ndarray:
    """``values`` as a float64 array rounded to ``decimals`` decimals (readable in reports).

    >>> rounded([1.23456, 2], 2)
    array([1.23, 2.  ])
    """
    return np.round(np.asarray(values, dtype=np.float64), _integer(decimals, "decimals", "rounded"))


def argument(case: Case, index: int, name: str, default: Any = None) -> Any:
    """The value of one argument of ``case``: the keyword ``name`` if the case passes it so,
    else its ``index``-th positional argument, else ``default``.

    Parameters
    ----------
    case : Case
        A case of a check.
    index : int
        The argument's position in the reference's signature.
    name : str
        Its name there.
    default : object
        Its default value there.

    Returns
    -------
    object

    Examples
    --------
    >>> argument(Case((1.0,), {"border": "zero"}), 2, "border", "reflect101")
    'zero'
    >>> argument(Case((1.0,)), 1, "sigma", 2.0)
    2.0
    """
    if not (hasattr(case, "args") and hasattr(case, "kwargs")):
        raise TypeError(f"argument: case must be a cvkit.grading.Case (with args and kwargs), got {type(case).__name__}")
    if name in case.kwargs:
        return case.kwargs[name]
    if len(case.args) > index:
        return case.args[index]
    return default


def variant(function: Callable, /, **knobs: Any) -> Callable:
    """A mistake of a bank: ``function`` called with a case's arguments and the keyword
    arguments ``knobs`` that select one wrong behaviour.

    A bank often holds one parametrised wrong implementation (``_blur_variant(image, sigma,
    *, swap=False, squared=False)``) and names its settings; ``variant(_blur_variant,
    swap=True)`` is the mistake "x and y swapped". Its signature is ``function``'s without the
    knobs, so it is called like the reference.

    Parameters
    ----------
    function : callable
        The parametrised implementation; it must accept every key of ``knobs`` as a keyword.
    **knobs
        The settings of this mistake.

    Returns
    -------
    callable

    Examples
    --------
    >>> def power(x, *, squared=False):
    ...     return x * x if squared else x
    >>> squared = variant(power, squared=True)
    >>> squared(3), squared.__name__
    (9, 'power[squared=True]')
    """
    if not callable(function):
        raise TypeError(f"variant: function must be callable, got {type(function).__name__}")
    try:
        signature: inspect.Signature | None = inspect.signature(function)
    except (TypeError, ValueError):
        signature = None
    if signature is not None:
        accepts_any = any(p.kind is p.VAR_KEYWORD for p in signature.parameters.values())
        unknown = [k for k in knobs if k not in signature.parameters and not accepts_any]
        if unknown:
            raise TypeError(f"variant: {getattr(function, '__name__', function)!r} has no keyword "
                            f"argument {', '.join(map(repr, unknown))}")

    def wrong(*args: Any, **kwargs: Any) -> Any:
        return function(*args, **kwargs, **knobs)

    label = ", ".join(f"{k}={v!r}" for k, v in knobs.items())
    wrong.__name__ = f"{getattr(function, '__name__', 'variant')}[{label}]"
    wrong.__qualname__ = f"{getattr(function, '__qualname__', wrong.__name__)}[{label}]"
    wrong.__module__ = getattr(function, "__module__", __name__)
    wrong.__doc__ = f"{getattr(function, '__name__', 'variant')} with {label}."
    if signature is not None:
        setattr(wrong, "__signature__", signature.replace(
            parameters=[p for p in signature.parameters.values() if p.name not in knobs]))
    return wrong


def with_border(function: Callable, border: str | Callable[[Any], Any]) -> Callable:
    """``function`` run with another ``border`` than the case asks for: a wrong border rule.

    The result takes ``function``'s arguments (positional or keyword, ``border`` with its
    default when the case leaves it out) and calls ``function`` with ``border`` replaced by
    ``border`` itself (a mode such as ``"zero"``) or, when ``border`` is callable, by
    ``border(the case's border)`` (:func:`swap_reflect`).

    Parameters
    ----------
    function : callable
        A correct filter with a parameter named ``border``.
    border : str or callable
        The mode used instead, or how it follows from the case's mode.

    Returns
    -------
    callable

    Examples
    --------
    >>> def pad_name(image, border="reflect101"):
    ...     return border
    >>> with_border(pad_name, swap_reflect)(None), with_border(pad_name, "zero")(None, "reflect")
    ('reflect', 'zero')
    """
    if not callable(function):
        raise TypeError(f"with_border: function must be callable, got {type(function).__name__}")
    signature = inspect.signature(function)
    if "border" not in signature.parameters:
        raise TypeError(f"with_border: {getattr(function, '__name__', function)!r} has no argument 'border'")

    def wrong(*args: Any, **kwargs: Any) -> Any:
        bound = signature.bind(*args, **kwargs)
        bound.apply_defaults()
        given = bound.arguments["border"]
        bound.arguments["border"] = border(given) if callable(border) else border
        return function(*bound.args, **bound.kwargs)

    label = getattr(border, "__name__", repr(border))
    wrong.__name__ = f"{getattr(function, '__name__', 'filter')}[border={label}]"
    wrong.__qualname__ = wrong.__name__
    wrong.__module__ = getattr(function, "__module__", __name__)
    setattr(wrong, "__signature__", signature)
    return wrong


def border_zero(function: Callable, hint: str) -> Mistake:
    """The mistake "border ignored (always zero)": ``function`` with ``border="zero"``
    whatever the case asks (:func:`with_border`); ``hint`` says how to read outside the image."""
    return Mistake("border ignored (always zero)", with_border(function, "zero"), hint)


def reflect_swapped(function: Callable) -> Mistake:
    """The mistake "reflect and reflect101 swapped": ``function`` with the case's border
    through :func:`swap_reflect` (:func:`with_border`), hint :data:`SWAPPED_REFLECT_HINT`."""
    return Mistake("reflect and reflect101 swapped", with_border(function, swap_reflect), SWAPPED_REFLECT_HINT)


def border_mistakes(function: Callable, zero_hint: str) -> list[Mistake]:
    """The two border mistakes of a filter, in this order: :func:`border_zero` (with
    ``zero_hint``) and :func:`reflect_swapped`."""
    return [border_zero(function, zero_hint), reflect_swapped(function)]
