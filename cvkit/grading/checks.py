"""How an algorithm is graded: its cases, comparator and bank of known mistakes."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Sequence, TypeVar

import numpy as np

from .compare import Comparator
from .runtime.adapters import bind_call, instance_call  # noqa: F401  (re-exported)
from .runtime.guard import ERROR_KINDS
from .runtime.wire import DEFAULT_TIME_LIMIT

#: libraries that would do a Chapter's exercise for the student (module-name prefixes)
FORBIDDEN_LIBRARIES = (
    "skimage",
    "scipy.ndimage",
    "scipy.signal",
    "scipy.spatial",
    "scipy.optimize",
    "cv2",
    "sklearn",
    "torch",
)


def _describe_value(value: Any) -> str:
    if isinstance(value, np.ndarray):
        if value.size <= 6:
            return np.array2string(value, precision=4, separator=", ").replace("\n", "")
        return f"array{value.shape} {value.dtype}"
    if isinstance(value, np.random.Generator):
        return "Generator"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)) and len(value) > 6:
        return f"{type(value).__name__} of {len(value)}"
    return repr(value)


#: what :attr:`Check.rules` may name (see there)
RULES = frozenset({"integer", "narrow integer", "uint8", "single point", "single row", "no warnings"})


@dataclass
class Case:
    """One call of the algorithm: positional ``args`` and keyword ``kwargs``.

    ``label`` says in a few words what the case probes ("asymmetric kernel, zero border").
    ``raises`` (``"ValueError"`` or ``"TypeError"``) makes it a case of bad input, which the
    contract says the function refuses: the call must raise that error (or a subclass of it),
    whatever it says; its label says what is wrong with the input ("k larger than the number
    of distinct points"). See :attr:`Check.refusals`.
    """

    args: tuple = ()
    kwargs: dict = field(default_factory=dict)
    label: str = ""
    raises: str | None = None

    def describe(self, names: Sequence[str] = ()) -> str:
        parts = []
        for i, value in enumerate(self.args):
            name = names[i] if i < len(names) else f"arg{i}"
            parts.append(f"{name}={_describe_value(value)}")
        parts += [f"{k}={_describe_value(v)}" for k, v in self.kwargs.items()]
        return ", ".join(parts)


@dataclass
class Mistake:
    """A named wrong variant of an algorithm, with the advice that fixes it."""

    name: str
    function: Callable
    hint: str

    @classmethod
    def of(cls, function: Callable) -> Mistake:
        """The mistake a function was marked as with :func:`mistake`."""
        recorded = getattr(function, MISTAKE_ATTRIBUTE, None)
        if recorded is None:
            raise TypeError(f"a check's mistakes must be Mistake objects or functions marked with @mistake(name, hint); "
                            f"got {function!r}")
        name, hint = recorded
        return cls(name, function, hint)


MISTAKE_ATTRIBUTE = "__cvkit_mistake__"
_F = TypeVar("_F", bound=Callable)


def mistake(name: str, hint: str) -> Callable[[_F], _F]:
    """Mark a function as a typical wrong version of an algorithm, with the advice that fixes it.

    Metadata only: the function comes back unchanged, with ``name`` and ``hint`` recorded on
    it, so the wrong version, its name and its advice stand together. A :class:`Check` lists
    it in its bank (``mistakes=[...]``, in the order the feedback tries them), where it becomes
    ``Mistake(name, function, hint)``.

    Examples
    --------
    >>> @mistake("absolute value instead of max(0, x)", "Negative inputs become 0: np.maximum(x, 0)")
    ... def relu_abs(x):
    ...     return abs(x)
    >>> Mistake.of(relu_abs).name
    'absolute value instead of max(0, x)'
    """
    if not isinstance(name, str) or not name.strip():
        raise TypeError(f"mistake name must be a non-empty string, got {name!r}")
    if not isinstance(hint, str) or not hint.strip():
        raise TypeError(f"mistake hint must be a non-empty string, got {hint!r}")

    def record(function: _F) -> _F:
        if not callable(function):
            raise TypeError(f"@mistake({name!r}, ...) must decorate a function, got {function!r}")
        setattr(function, MISTAKE_ATTRIBUTE, (name, hint))
        return function
    return record


@dataclass(frozen=True)
class Measure:
    """What a measured check (:attr:`Check.credit`) measures, for the reports and the course's
    leaderboards (:mod:`cvkit.course.leaderboard`): ``of(output, case) -> float`` is the value of
    one case in ``unit`` (an accuracy in ``"%"``), and ``higher_is_better`` says which way ranks
    first. It only describes; the points come from :attr:`Check.credit`.

    >>> Measure("accuracy", lambda got, case: 97.5, "%").on(None, None)
    {'name': 'accuracy', 'value': 97.5, 'unit': '%', 'better': 'higher'}
    """

    name: str
    of: Callable[[Any, Any], float]
    unit: str = ""
    higher_is_better: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise TypeError(f"Measure name must be a non-empty string, got {self.name!r}")
        if not callable(self.of):
            raise TypeError(f"Measure of must be a function (output, case) -> float, got {self.of!r}")
        if not isinstance(self.unit, str):
            raise TypeError(f"Measure unit must be a string, got {self.unit!r}")

    def on(self, output: Any, case: Any) -> dict[str, Any] | None:
        """The measured value of one case as report data (JSON-ready), or None when it cannot be
        measured (the function raised, or gave no finite number)."""
        try:
            value = float(self.of(output, case))
        except Exception:
            return None
        if not np.isfinite(value):
            return None
        # + 0.0: a value that rounds to zero is 0, never -0 (which a table would print as "-0.00")
        return {"name": self.name, "value": round(value, 6) + 0.0, "unit": self.unit,
                "better": "higher" if self.higher_is_better else "lower"}


@dataclass
class Check:
    """Everything the grader needs for one algorithm.

    Parameters
    ----------
    public : list of Case, or a function returning one
        Small fixed cases students see in the visible test.
    hidden : function ``rng -> list of Case``
        Cases drawn at grading time from a seed nobody knows in advance. They must contain the
        inputs that separate each mistake of the bank from the right answer.
    compare : Comparator
        Decides whether an output is right (``cvkit.grading.compare``).
    mistakes : list of Mistake, or of functions marked with :func:`mistake`
        Typical wrong versions, in the order the feedback tries them; a failing candidate
        whose output matches one is told which. Stored as :class:`Mistake` objects (:attr:`bank`).
    allowed : tuple of algorithm ids
        Reference building blocks the candidate may call (e.g. ``"filters.pad"``).
    allowed_libraries : tuple of module prefixes
        Exceptions to :data:`FORBIDDEN_LIBRARIES`.
    forbidden : tuple of ``"module.function"``
        Extra functions the candidate must not call (``"numpy.pad"`` for the padding exercise).
    seeded : bool
        The algorithm draws random numbers from an ``rng`` argument: two calls with the same
        seed must agree, and outputs are compared by their statistics, not draw by draw.
    time_limit : float
        Seconds per case before the candidate is stopped.
    call : callable, optional
        How a case calls the candidate when it is not a plain function: the output of a case is
        ``call(candidate, *case.args, **case.kwargs)`` instead of
        ``candidate(*case.args, **case.kwargs)``, for the candidate, the reference and every
        mistake alike. It must be a function of :mod:`cvkit.grading.runtime.adapters` (it runs in
        the grading sandbox, which holds NumPy and that package only; the trusted grader sends
        its name) that only passes plain data in and out, e.g.
        :func:`instance_call` to grade a class by building it and calling one of its methods.
    rules : tuple of str, optional
        The rules of the exercise's statement about inputs and side effects, each of which some
        case (visible or hidden) exercises (``tests/grading/test_statement_rules.py`` proves it), from
        :data:`RULES`: ``"integer"`` (integer arrays are valid input), ``"narrow integer"``
        (integer input in a dtype that overflows when squared or multiplied: int16),
        ``"uint8"``, ``"single point"`` (one point of shape ``(d,)`` besides ``(N, d)``),
        ``"single row"``, ``"no warnings"`` (a right value that raised a warning fails its case,
        with a sentence naming the warning).
    credit : callable, optional
        A **measured** check: ``credit(output, case) -> float`` in [0, 1] is the share of a
        case's points the candidate's output earns (e.g. an accuracy put through a published
        scale), whether or not the comparator passes it; a case that passes earns 1. Without
        it a case earns 1 when it passes and 0 otherwise.
    measure : Measure, optional
        What a measured check measures (an accuracy in %): each case's value goes into the
        report's data (:attr:`~cvkit.grading.report.CaseResult.measure`), which the course's
        opt-in leaderboards rank (:mod:`cvkit.course.leaderboard`).
    refusals : list of Case, optional
        Bad inputs the catalog's contract says the algorithm refuses, each a :class:`Case` with
        ``raises`` (k larger than the number of distinct points: ``ValueError``). They are
        graded with the hidden cases, after them (one case of the partial credit each), never
        in the visible test; the reference must raise on each (a case it does not refuse is
        dropped, as a case the reference cannot compute). Only for the errors the exercise's
        statement asks for.
    output_names : tuple of str, optional
        The names of the results when the algorithm returns a tuple (``("gx", "gy")``), as
        reports name them ("`gx`: 12 of 48 values differ"); by default they are read from the
        *Returns* section of the reference's docstring (:func:`cvkit.grading.engine.output_names`).
    """

    public: Sequence[Case] | Callable[[], Sequence[Case]]
    hidden: Callable[[np.random.Generator], Sequence[Case]]
    compare: Comparator
    mistakes: Sequence[Mistake | Callable[..., Any]] = ()
    allowed: tuple = ()
    allowed_libraries: tuple = ()
    forbidden: tuple = ()
    seeded: bool = False
    time_limit: float = DEFAULT_TIME_LIMIT
    arg_names: tuple = ()
    call: Callable | None = None
    output_names: tuple = ()
    rules: tuple = ()
    credit: Callable[[Any, Case], float] | None = None
    measure: Measure | None = None
    refusals: Sequence[Case] = ()

    def __post_init__(self) -> None:
        unknown = [r for r in self.rules if r not in RULES]
        if isinstance(self.rules, str) or unknown:
            raise ValueError(f"Check.rules must be a tuple of {sorted(RULES)}; got {self.rules!r}")
        if self.measure is not None and not isinstance(self.measure, Measure):
            raise TypeError(f"Check.measure must be a Measure, got {self.measure!r}")
        for case in self.refusals:
            if not isinstance(case, Case) or case.raises not in ERROR_KINDS:
                raise ValueError(f"Check.refusals must be Cases with raises one of {sorted(ERROR_KINDS)}; got {case!r}")
        # functions marked with @mistake stand for their Mistake; the bank keeps the listed order
        self.mistakes = [m if isinstance(m, Mistake) else Mistake.of(m) for m in self.mistakes]

    def public_cases(self) -> list[Case]:
        cases = self.public() if callable(self.public) else self.public
        return list(cases)

    def hidden_cases(self, rng: np.random.Generator) -> list[Case]:
        return list(self.hidden(rng))

    def graded_hidden_cases(self, rng: np.random.Generator) -> list[Case]:
        """What the hidden test grades: the hidden cases drawn from ``rng``, then the refusals."""
        return self.hidden_cases(rng) + list(self.refusals)

    @property
    def bank(self) -> list[Mistake]:
        """The mistakes as :class:`Mistake` objects, in the order the feedback tries them."""
        return [m if isinstance(m, Mistake) else Mistake.of(m) for m in self.mistakes]

    def mistake(self, name: str) -> Mistake:
        for m in self.bank:
            if m.name == name:
                return m
        raise KeyError(f"no mistake called {name!r}; known: {[m.name for m in self.bank]}")

    @property
    def forbidden_libraries(self) -> tuple:
        return tuple(p for p in FORBIDDEN_LIBRARIES if p not in self.allowed_libraries)


def call_target(call: Callable | None) -> str | None:
    """``"module:qualname"`` of a :attr:`Check.call` (how the worker imports it), or None."""
    if call is None:
        return None
    module, name = getattr(call, "__module__", None), getattr(call, "__qualname__", "")
    if not module or not name or "<" in name or not module.startswith("cvkit.grading.runtime."):
        raise ValueError(f"Check.call must be a function of cvkit.grading.runtime (it runs in the grading "
                         f"sandbox, where only NumPy and that package exist), got {call!r}")
    return f"{module}:{name}"
