"""Comparators: is a candidate's output right, and if not, how exactly does it differ?

A :class:`Mismatch` message starts with plain words a student understands (how many values
differ and where, the first one with yours vs expected, the largest error; see
:func:`cvkit.grading.diagnose.describe_difference`); the ``numpy.testing``-style lines with the
tolerances go to ``Mismatch.details``, shown on demand.

Comparators written elsewhere (the chapter checks) share the first steps through public
helpers: :func:`as_numeric` and :func:`as_float_array` (the output as an array, or why it is
not one), :func:`tuple_problem`, :func:`shape_mismatch` with :func:`shape_advice`,
:func:`kind_words`; :class:`FloatArrayComparator` does those steps for one float array, and
:meth:`Statistics.judge` compares named statistics within tolerances.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from .diagnose import describe_difference


@dataclass
class Mismatch:
    """Why an output was judged wrong.

    ``message`` is for the student (plain words first); ``details`` holds the technical part
    (tolerances, ``numpy.testing``-style counts), shown in an expandable section."""

    message: str
    max_abs: float | None = None
    max_rel: float | None = None
    worst: tuple | None = None
    mismatched: int | None = None
    total: int | None = None
    details: str | None = None


def _get_message(self) -> str:
    text = self.__dict__["_message"]
    if callable(text):  # written on first use: matching a bank's mistakes only asks "None or not?"
        text = self.__dict__["_message"] = text()
    return text


def _set_message(self, value) -> None:
    self.__dict__["_message"] = value


setattr(Mismatch, "message", property(_get_message, _set_message, doc="The message for the student (a str; a "
                                      "comparator may pass a function returning it, called the first time it is read)."))


class Comparator:
    """Base class: ``comparator(got, expected, case)`` returns ``None`` or a :class:`Mismatch`.

    A comparator that accepts outputs only in one normalised form (a homography with
    H[2, 2] = 1, an eigenvector of one sign, ...) overrides :meth:`normalise`: the grader then
    also matches the bank's mistakes *up to* that normalisation, so a structural mistake is
    named whether or not the candidate normalised its result."""

    #: outputs are judged value by value (allclose-like), so a failing output's difference can be
    #: diagnosed value by value too (shifted, transposed, scaled...; :mod:`cvkit.grading.diagnose`)
    elementwise = False
    #: the verdict depends on the output and the case only (a measured exercise: what the output
    #: achieves against the case's truth); ``expected`` serves the message alone. The grader then
    #: never runs the bank's mistakes to match a failing output: measured against the case, a
    #: mistake's output could only "match" an output that passes
    judges_alone = False

    def __call__(self, got: Any, expected: Any, case: Any = None) -> Mismatch | None:  # pragma: no cover
        raise NotImplementedError

    def describe(self) -> str:
        return type(self).__name__

    def normalise(self, value: Any) -> Any:
        """The canonical form of an output for matching mistakes (default: the output itself)."""
        return value

    @property
    def normalises(self) -> bool:
        """True when :meth:`normalise` is overridden."""
        return type(self).normalise is not Comparator.normalise


#: words for NumPy dtype kinds in messages ("expected a float array")
KIND_NAMES = {"f": "float", "b": "bool", "i": "integer", "u": "unsigned integer"}


def kind_words(kinds: str) -> str:
    """``"float or integer"`` for the dtype kinds ``"fi"`` (see :data:`KIND_NAMES`).

    >>> kind_words("fi")
    'float or integer'
    """
    return " or ".join(KIND_NAMES.get(k, k) for k in kinds)


def as_numeric(got: Any, what: str = "your output") -> tuple[np.ndarray | None, str | None]:
    """A candidate's output as a numeric (bool, integer or float) array, or why it is not one.

    Parameters
    ----------
    got : object
        The output (or one part of it) to judge.
    what : str
        How messages name it (``"your output"``, ``"your indices"``, ...).

    Returns
    -------
    (array, None) or (None, problem)
        ``problem`` is a message for the student: the output is ``None`` (a forgotten
        ``return``), cannot be turned into an array (ragged lists), or is not numeric.
    """
    if got is None:
        return None, f"{what} is None: did you forget to `return` the result?"
    try:
        with np.errstate(all="ignore"):
            arr = np.asarray(got)
    except Exception as exc:  # ragged lists and the like
        return None, f"{what} could not be turned into an array ({type(exc).__name__}: {exc})"
    if arr.dtype == object or arr.dtype.kind not in "biuf":
        return None, f"{what} must be a numeric array, got {type(got).__name__} of dtype {arr.dtype}"
    return arr, None


def as_float_array(got: Any, what: str = "your output", shape: tuple | None = None, layout: str = "",
                   nonfinite: str | None = None) -> tuple[np.ndarray | None, str | None]:
    """A candidate's output as a float64 array of the expected shape, or why it is not one.

    Parameters
    ----------
    got : object
        The output to judge.
    what : str
        How messages name it.
    shape : tuple, optional
        The shape it must have (not checked when None).
    layout : str
        Words after the expected shape in the message, e.g. ``" (one value per pixel)"``.
    nonfinite : str, optional
        When given, NaN or ±inf anywhere is a problem and this is its message.

    Returns
    -------
    (array, None) or (None, problem)
        ``problem``, a message for the student, in this order: ``got`` is None, cannot be
        converted to float, has another shape, has NaN or inf.
    """
    if got is None:
        return None, f"{what} is None: did you forget to `return` the result?"
    try:
        with np.errstate(all="ignore"):
            arr = np.asarray(got, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        return None, f"{what} could not be turned into a float array ({exc})"
    if shape is not None and arr.shape != tuple(shape):
        return None, f"shape mismatch: expected {tuple(shape)}{layout}, got {arr.shape}"
    if nonfinite is not None and not np.all(np.isfinite(arr)):
        return None, nonfinite
    return arr, None


def tuple_problem(got: Any, names: Sequence[str]) -> str | None:
    """Why ``got`` is not a tuple (or list) of ``len(names)`` results, or None when it is.

    >>> tuple_problem((1, 2), ("x", "info")) is None
    True
    >>> tuple_problem(3.0, ("x", "info"))
    'expected a tuple (x, info), got float'
    """
    if isinstance(got, np.ndarray) or not isinstance(got, (tuple, list)) or len(got) != len(names):
        what = f"a tuple of {len(got)}" if isinstance(got, (tuple, list)) else type(got).__name__
        return f"expected a tuple ({', '.join(names)}), got {what}"
    return None


def shape_advice(got: tuple, expected: tuple) -> str:
    """Words after a shape mismatch that guess its cause: rows and columns swapped, padding
    kept or missing, another number of dimensions (empty when nothing fits).

    >>> shape_advice((6, 4), (4, 6))
    ' (rows and columns swapped? images are indexed [row, col])'
    """
    if len(got) == len(expected) >= 2 and got[:2] == expected[:2][::-1] and got != expected:
        return " (rows and columns swapped? images are indexed [row, col])"
    if len(got) == len(expected) and len(got) >= 2:
        dr, dc = got[0] - expected[0], got[1] - expected[1]
        if dr > 0 and dc >= 0 or dr >= 0 and dc > 0:
            return f" (yours is larger by {dr} rows and {dc} columns: crop the padding you added)"
        if dr < 0 and dc <= 0 or dr <= 0 and dc < 0:
            return f" (yours is smaller by {-dr} rows and {-dc} columns: pad the input so the output keeps its size)"
    if len(got) != len(expected):
        return f" (yours has {len(got)} dimensions, expected {len(expected)})"
    return ""


def shape_mismatch(got: tuple, expected: tuple) -> str:
    """``"shape mismatch: expected (4, 6), got (6, 4) (rows and columns swapped? ...)"``."""
    return f"shape mismatch: expected {expected}, got {got}{shape_advice(got, expected)}"


def _index(flat: int, shape: tuple) -> tuple:
    return tuple(int(i) for i in np.unravel_index(flat, shape)) if shape else ()


class FloatArrayComparator(Comparator):
    """Base class of comparators that judge one float array of the expected shape.

    ``comparator(got, expected, case)`` turns ``got`` into a float64 array of ``expected``'s
    shape without NaN or inf, or says what is wrong (:func:`as_float_array` with the class's
    :attr:`layout` and :attr:`nonfinite`), then returns :meth:`judge_array` of the two arrays.
    """

    #: words after the expected shape in a shape mismatch, e.g. ``" (one value per pixel)"``
    layout: ClassVar[str] = ""
    #: the message when the output holds NaN or inf (None: allowed)
    nonfinite: ClassVar[str | None] = "your output contains NaN or inf"

    def __call__(self, got: Any, expected: Any, case: Any = None) -> Mismatch | None:
        exp = np.asarray(expected, dtype=np.float64)
        arr, problem = as_float_array(got, shape=exp.shape, layout=self.layout, nonfinite=self.nonfinite)
        if problem or arr is None:
            return Mismatch(problem or "your output could not be read")
        return self.judge_array(arr, exp, case)

    def judge_array(self, got: np.ndarray, expected: np.ndarray, case: Any = None) -> Mismatch | None:
        """The verdict on a well-formed output (float64, the expected shape): None when right."""
        raise NotImplementedError  # pragma: no cover


@dataclass
class Close(Comparator):
    """``allclose`` with stated tolerances: ``|got − expected| ≤ atol + rtol·|expected|``.

    NaN and ±inf must appear at the same places. ``kind`` optionally requires the dtype kind
    (``"f"`` float, ``"b"`` bool, ``"i"`` integer). A bool output where numbers are expected is
    compared as the numbers 0 and 1; where a mask is expected, numbers must be 0 or 1. Tuples
    and lists are compared element by element.
    """

    rtol: float = 1e-7
    atol: float = 1e-10
    kind: str | None = None
    scaled: bool = False
    elementwise = True

    def describe(self) -> str:
        atol = f"{self.atol:g}·max(1, max|expected|)" if self.scaled else f"{self.atol:g}"
        return f"allclose(rtol={self.rtol:g}, atol={atol})"

    def __call__(self, got, expected, case=None):
        if isinstance(expected, (tuple, list)) and not isinstance(expected, np.ndarray):
            if not isinstance(got, (tuple, list)) or len(got) != len(expected):
                n = len(got) if isinstance(got, (tuple, list)) else "not a tuple"
                return Mismatch(f"expected a tuple of {len(expected)} results, got {n}")
            for i, (g, e) in enumerate(zip(got, expected)):
                mismatch = self(g, e, case)
                if mismatch is not None:
                    mismatch.message = f"result [{i}]: {mismatch.message}"
                    return mismatch
            return None
        exp = np.asarray(expected)
        arr, problem = as_numeric(got)
        if problem:
            return Mismatch(problem)
        atol = self.atol
        if self.scaled and exp.dtype.kind in "iuf" and exp.size:
            # round-off of a filter is relative to the image's values, not to each output
            # value: where a ±1e6 image cancels to ~0, correct loop/FFT versions differ by ~1e-10
            with np.errstate(all="ignore"):
                magnitudes = np.abs(exp[np.isfinite(exp)].astype(np.float64))
            atol *= max(1.0, float(magnitudes.max())) if magnitudes.size else 1.0
        if self.kind is not None and arr.dtype.kind not in self.kind:
            return Mismatch(f"dtype mismatch: expected a {kind_words(self.kind)} array, got {arr.dtype}")
        if arr.shape != exp.shape:
            return Mismatch(shape_mismatch(arr.shape, exp.shape))
        if exp.dtype.kind == "b":
            if arr.dtype.kind != "b":
                # a mask may come as 0/1 numbers, but not as any numbers (x itself for x != 0)
                with np.errstate(all="ignore"):
                    binary = (arr == 0) | (arr == 1)
                if not binary.all():
                    return Mismatch(f"expected a True/False mask, got {arr.dtype} values other than 0 and 1")
            bad = arr.astype(bool) != exp
            n = int(bad.sum())
            if n == 0:
                return None
            worst = _index(int(np.flatnonzero(bad)[0]), exp.shape)
            return Mismatch(
                lambda: describe_difference(arr, exp, bad),
                worst=worst, mismatched=n, total=exp.size,
                details=f"Mismatched elements: {n} / {exp.size} ({100 * n / exp.size:.3g}%), first at {list(worst)}",
            )
        a = arr.astype(np.float64)
        e = exp.astype(np.float64)
        if np.array_equal(a, e):  # the same numbers (NaN never equals): within any tolerance
            return None
        with np.errstate(all="ignore"):
            nan_bad = np.isnan(a) != np.isnan(e)
            inf_bad = (np.isinf(a) | np.isinf(e)) & ~(a == e) & ~np.isnan(a) & ~np.isnan(e)
            finite = np.isfinite(a) & np.isfinite(e)
            diff = np.where(finite, np.abs(a - e), 0.0)
            tol = atol + self.rtol * np.abs(np.where(finite, e, 0.0))
            bad = (diff > tol) | nan_bad | inf_bad
        n = int(bad.sum())
        if n == 0:
            return None
        lines = [
            f"Not equal to tolerance rtol={self.rtol:g}, atol={atol:g}",
            f"Mismatched elements: {n} / {e.size} ({100 * n / e.size:.3g}%)",
        ]
        max_abs = max_rel = None
        worst = None
        if (nan_bad | inf_bad).any():
            flat = int(np.flatnonzero(nan_bad | inf_bad)[0])
            worst = _index(flat, e.shape)
            lines.append(f"NaN/inf where not expected (or missing) first at {list(worst)}: yours {a.flat[flat]!r}, expected {e.flat[flat]!r}")
        if finite.any():
            with np.errstate(all="ignore"):
                rel = np.where(finite & (e != 0), diff / np.abs(e), np.where(diff > 0, np.inf, 0.0))
            flat = int(np.argmax(np.where(finite, diff - tol, -np.inf)))
            max_abs = float(diff.max())
            max_rel = float(rel[finite].max())
            if worst is None:
                worst = _index(flat, e.shape)
            where = f" at {list(_index(flat, e.shape))}" if e.ndim else ""
            lines.append(f"Max absolute difference: {max_abs:.6g}{where} (yours {a.flat[flat]:.6g}, expected {e.flat[flat]:.6g})")
            lines.append(f"Max relative difference: {max_rel:.6g}")
        return Mismatch(lambda: describe_difference(arr, exp, bad), max_abs=max_abs, max_rel=max_rel, worst=worst,
                        mismatched=n, total=int(e.size), details="\n".join(lines))


def close(rtol: float = 1e-7, atol: float = 1e-10, kind: str | None = None, scaled: bool = False) -> Close:
    """A :class:`Close` comparator (``numpy.allclose`` semantics, NaN-aware).

    With ``scaled=True`` the absolute tolerance is ``atol·max(1, max|expected|)``.
    """
    return Close(rtol=rtol, atol=atol, kind=kind, scaled=scaled)


@dataclass
class Statistics(Comparator):
    """Random outputs, judged by properties and statistics instead of exact draws.

    ``statistics(output, case)`` returns named numbers (noise standard deviation, fraction of
    pixels replaced, fraction of replaced values that are neither ``low`` nor ``high``...);
    ``tolerance(case)`` says how far the candidate's may be from the reference draw's (0 for
    properties that must hold exactly). Because a mistake is judged by the same numbers, the
    grader can tell a candidate "your noise has the spread of σ², not σ".
    ``dtype_kind`` optionally requires the output's dtype kind (``"f"``: float).
    """

    statistics: Callable[[Any, Any], Mapping[str, float]]
    tolerance: Callable[[Any], Mapping[str, float]]
    dtype_kind: str | None = None
    #: the first line of the message when statistics differ
    heading: ClassVar[str] = "Statistics differ from the expected distribution"

    def describe(self) -> str:
        return "statistics of the output (two correct versions may draw differently)"

    def __call__(self, got, expected, case=None):
        arr, problem = as_numeric(got)
        if problem:
            return Mismatch(problem)
        exp = np.asarray(expected)
        if arr.shape != exp.shape:
            return Mismatch(shape_mismatch(arr.shape, exp.shape))
        if self.dtype_kind is not None and arr.dtype.kind not in self.dtype_kind:
            return Mismatch(f"dtype mismatch: expected a {kind_words(self.dtype_kind)} array, got {arr.dtype}"
                            + (" (do not cast back to the input's integer type)" if "f" in self.dtype_kind else ""))
        return self.judge(arr, exp, case)

    def judge(self, got: Any, expected: Any, case: Any = None) -> Mismatch | None:
        """Compare the :attr:`statistics` of ``got`` with those of ``expected`` within
        :attr:`tolerance` (NaN matches NaN); a :class:`Mismatch` lists every one that differs."""
        with np.errstate(all="ignore"):
            got_stats = dict(self.statistics(got, case))
            exp_stats = dict(self.statistics(expected, case))
        tolerances = self.tolerance(case)
        wrong = []
        for name, expected_value in exp_stats.items():
            value = got_stats.get(name, np.nan)
            tol = tolerances.get(name, 0.0)
            if not (abs(value - expected_value) <= tol) and not (np.isnan(value) and np.isnan(expected_value)):
                wrong.append(f"{name}: yours {value:.6g}, expected {expected_value:.6g} ± {tol:.3g}")
        if wrong:
            return Mismatch(f"{self.heading}:\n" + "\n".join(wrong))
        return None


def _output_key(value: Any) -> Any:
    """A hashable stand-in for an output, equal for equal outputs (arrays by dtype, shape and
    bytes; tuples, lists and dicts element by element)."""
    if isinstance(value, np.ndarray) or isinstance(value, np.generic):
        arr = np.asarray(value)
        return ("array", arr.dtype.str, arr.shape, arr.tobytes())
    if isinstance(value, (tuple, list)):
        return (type(value).__name__, tuple(_output_key(v) for v in value))
    if isinstance(value, dict):
        return ("dict", tuple((repr(k), _output_key(v)) for k, v in value.items()))
    return ("value", repr(value))


#: the statistic every ``draws`` case has: how often one output comes back
REPEATS = "share of the calls that gave the most frequent result"


def repeat_share(outputs: Sequence[Any]) -> float:
    """The share of ``outputs`` equal to the most frequent one: about 1/len for a function that
    draws afresh on every call, 1 for one that ignores ``rng`` (a generator with a fixed seed)."""
    keys = [_output_key(output) for output in outputs]
    counts: dict[Any, int] = {}
    for key in keys:
        counts[key] = counts.get(key, 0) + 1
    return max(counts.values()) / len(keys) if keys else 0.0


def binomial_variance_tolerance(n: int, p: float, calls: int) -> float:
    """How far the variance of m = ``calls`` kept counts may be from the reference's when each of
    ``n`` items is kept with probability ``p``: six standard errors of the difference of two
    sample variances (σ² = n·p(1−p), each with a standard error of about σ²·√(2/m))."""
    return 6 * 2 * n * p * (1 - p) / math.sqrt(calls)


@dataclass
class Drawn(Comparator):
    """A random algorithm's outputs: one call judged by ``single``; a case with ``draws``
    (many calls, one seed each, :func:`~cvkit.grading.runtime.adapters.call_draws`) judged
    draw by draw by ``single`` too, then by the distribution over its draws: always
    :data:`REPEATS` (within 0.25 of the reference's: a function that ignores ``rng`` gives one
    output every time), and ``statistics(draws, case)``, named numbers of the whole list whose
    ``tolerance(case)`` says how far they may be from those of the reference's draws."""

    single: Comparator
    statistics: Callable[[Any, Any], Any] | None = None
    tolerance: Callable[[Any], Any] | None = None

    def describe(self) -> str:
        return self.single.describe() + "; over many calls: the distribution of the draws"

    def _statistics(self, outputs: Any, case: Any) -> dict[str, float]:
        found = {REPEATS: repeat_share(outputs)}
        if self.statistics is not None:
            found.update(self.statistics(outputs, case))
        return found

    def _tolerance(self, case: Any) -> dict[str, float]:
        allowed = {REPEATS: 0.25}
        if self.tolerance is not None:
            allowed.update(self.tolerance(case))
        return allowed

    def __call__(self, got, expected, case=None):
        if case is None or case.kwargs.get("draws") is None:
            return self.single(got, expected, case)
        count = len(expected)
        if not isinstance(got, (list, tuple)) or len(got) != count:
            return Mismatch(f"expected the outputs of {count} calls, got {type(got).__name__}")
        for index, (draw, reference) in enumerate(zip(got, expected)):
            mismatch = self.single(draw, reference, case)
            if mismatch is not None:
                mismatch.message = f"call {index + 1} of {count} (rng = {case.kwargs['draws'][0] + index}): " \
                    + mismatch.message
                return mismatch
        mismatch = Statistics(statistics=self._statistics, tolerance=self._tolerance).judge(got, expected, case)
        if mismatch is not None and count > 1 and repeat_share(got) == 1.0 and repeat_share(expected) < 0.5:
            mismatch.message += (f"\nAll {count} calls returned the same result, whatever the seed: draw every random "
                                 "number from np.random.default_rng(rng), not from a generator with a fixed seed "
                                 "(nor from np.random.seed)")
        return mismatch
