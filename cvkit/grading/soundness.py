"""Is a check sound: do its cases grade what its bank of mistakes says they grade?

:func:`cvkit.registry.validate` runs a reference on its own public cases; this module goes
further, for ``cvkit list --validate`` (:func:`soundness`):

- every hidden case the generator draws, over ``seeds`` seeds drawn as grading draws them
  (:func:`~cvkit.grading.engine.hidden_seed` of a fixed salt and one student id per seed), is
  computable by the reference — grading drops a case the reference cannot compute, so the
  student would be graded on fewer cases than the others;
- the reference's warnings on a case (public or hidden) are caught and reported naming the
  case, never written to standard error. They are *notes*, not problems: grading silences
  them, and a case may ask for a warned condition on purpose (``camera.undistort_points``
  with too few iterations); a warning the author did not mean (a division by zero) shows
  there;
- every mistake of the bank differs from the reference on some public or hidden case (a
  mistake that gives the right answer everywhere can never be named, and a student who makes
  it scores full marks);
- every pair of mistakes is told apart by some case (else a student who makes the second is
  told the name and hint of the first).

A mistake or a pair is settled by the first case that tells it apart: the public cases, then
the hidden cases seed after seed, so a sound bank costs little beyond the reference's sweep.
"""
from __future__ import annotations

import copy
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .. import registry
from .checks import Case, Check, Mistake, bind_call
from .engine import hidden_seed

__all__ = ["DEFAULT_SEEDS", "SALT", "Soundness", "soundness"]

#: how many seeds of hidden cases ``cvkit list --validate`` draws by default
DEFAULT_SEEDS = 200
#: the salt of the validation's seeds (any fixed text: the point is many different draws)
SALT = "cvkit-validate"

_FAILED = object()  # a mistake's outcome when it raised


@dataclass
class Soundness:
    """What :func:`soundness` found: ``problems`` make the check refused by
    ``cvkit list --validate``; ``notes`` (the reference's warnings) are shown, not refused."""

    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def __bool__(self) -> bool:
        return not self.problems


def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    return f"{type(error).__name__}: {text.splitlines()[0] if text else ''}".rstrip(": ")


def _label(where: str, index: int, case: Case) -> str:
    return f"{where} case {index + 1}" + (f" ({case.label})" if getattr(case, "label", "") else "")


def _reference(function: Callable, spec: Check, case: Case) -> tuple[Any, list[str]]:
    """The reference's output on ``case`` and the warnings it raised (as text), recorded
    here instead of reaching standard error."""
    with registry.use(registry.REFERENCE), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = bind_call(spec.call, function)(*copy.deepcopy(case.args), **copy.deepcopy(case.kwargs))
    return value, _said(caught)


def _said(caught: list) -> list[str]:
    """Caught warnings as ``"<category>: <first line>"``, without repeats."""
    said: list[str] = []
    for warning in caught:
        message = str(warning.message).strip()
        text = f"{warning.category.__name__}: {message.splitlines()[0] if message else ''}".rstrip(": ")
        if text not in said:
            said.append(text)
    return said


def _mistake(mistake: Mistake, spec: Check, case: Case) -> Any:
    """A mistake's output on ``case`` as grading computes it (warnings silenced), or
    ``_FAILED`` when it raises."""
    try:
        with registry.use(registry.REFERENCE), np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return bind_call(spec.call, mistake.function)(*copy.deepcopy(case.args), **copy.deepcopy(case.kwargs))
    except Exception:  # noqa: BLE001 - a mistake that raises fails the case, as a student would
        return _FAILED


def _differs(spec: Check, got: Any, expected: Any, case: Case) -> bool:
    """``got`` fails the check's comparator against ``expected`` on ``case`` (a comparator that
    raises counts as a failure, as in grading)."""
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return spec.compare(got, expected, case) is not None
    except Exception:  # noqa: BLE001
        return True


def _apart(spec: Check, a: Any, b: Any, case: Case) -> bool:
    """Two mistakes' outputs tell them apart on ``case``: exactly one raised, or either fails
    the comparator against the other (a candidate making one is not matched to the other)."""
    if a is _FAILED or b is _FAILED:
        return (a is _FAILED) != (b is _FAILED)
    return _differs(spec, a, b, case) or _differs(spec, b, a, case)


def soundness(algorithm_id: str, *, seeds: int = DEFAULT_SEEDS, salt: str = SALT) -> Soundness:
    """What is wrong with the check of ``algorithm_id``, beyond its public cases.

    Parameters
    ----------
    algorithm_id : str
        A registered id with a check (``"filters.gaussian"``, ``"mycourse.gamma_correction"``).
    seeds : int
        How many draws of hidden cases to examine (each as one student's, ``hidden_seed`` of
        ``salt`` and the student ``"validate-<n>"``); at least 1.
    salt : str
        The salt of those draws.

    Returns
    -------
    Soundness
        ``problems``, one sentence each (none: sound): a hidden case the generator cannot draw
        or the reference cannot compute (naming the seed and the case, the first 5 of each
        kind), a mistake no case tells from the reference, a pair of mistakes no case tells
        apart; ``notes``: the cases on which the reference warned (the first 5), with the
        warnings.

    Raises
    ------
    TypeError
        When ``seeds`` is not an integer or ``salt`` not a string.
    ValueError
        When ``seeds`` < 1, or the algorithm has no check.
    KeyError
        When no algorithm is registered as ``algorithm_id``.
    """
    if isinstance(seeds, bool) or not isinstance(seeds, (int, np.integer)):
        raise TypeError(f"seeds must be an integer, got {type(seeds).__name__}")
    if seeds < 1:
        raise ValueError(f"seeds must be at least 1, got {seeds}")
    if not isinstance(salt, str):
        raise TypeError(f"salt must be a string, got {type(salt).__name__}")
    record = registry.get(algorithm_id)
    spec = record.resolve_check()
    if spec is None:
        raise ValueError(f"{record.package}: algorithm {algorithm_id!r} has no check to validate")
    bank = list(spec.bank)
    unmatched = set(range(len(bank)))  # mistakes not yet told from the reference
    together = {(i, j) for i in range(len(bank)) for j in range(i + 1, len(bank))}  # pairs not yet told apart
    uncomputable: list[str] = []
    warned: list[str] = []
    undrawable: list[str] = []
    counts = {"uncomputable": 0, "warned": 0, "undrawable": 0}

    def examine(where: str, index: int, case: Case) -> None:
        label = _label(where, index, case)
        try:
            expected, said = _reference(record.reference, spec, case)
        except Exception as error:  # noqa: BLE001 - the finding
            counts["uncomputable"] += 1
            if len(uncomputable) < 5:
                uncomputable.append(f"{label}: the reference raised {_first_line(error)}")
            return
        if said:
            counts["warned"] += 1
            if len(warned) < 5:
                warned.append(f"{label}: the reference warned {'; '.join(said)}")
        needed = set(unmatched) | {i for pair in together for i in pair}
        if not needed:
            return
        outputs = {i: _mistake(bank[i], spec, case) for i in sorted(needed)}
        for i in list(unmatched):
            if outputs[i] is _FAILED or _differs(spec, outputs[i], expected, case):
                unmatched.discard(i)
        for pair in list(together):
            if _apart(spec, outputs[pair[0]], outputs[pair[1]], case):
                together.discard(pair)

    try:
        public = list(spec.public_cases())
    except Exception as error:  # noqa: BLE001
        return Soundness([f"its public cases cannot be built ({_first_line(error)})"])
    for index, case in enumerate(public):
        examine("public", index, case)
    for n in range(int(seeds)):
        student = f"validate-{n}"
        seed = hidden_seed(algorithm_id, student=student, salt=salt)
        where = f"seed {seed} (student {student!r}, salt {salt!r}): hidden"
        try:
            with warnings.catch_warnings(record=True) as caught:  # the generator's: never on stderr
                warnings.simplefilter("always")
                cases = spec.hidden_cases(np.random.default_rng(seed))
            if caught:
                counts["warned"] += 1
                if len(warned) < 5:
                    warned.append(f"seed {seed} (student {student!r}, salt {salt!r}): drawing the hidden cases "
                                  f"warned {_said(caught)[0]}")
        except Exception as error:  # noqa: BLE001
            counts["undrawable"] += 1
            if len(undrawable) < 5:
                undrawable.append(f"seed {seed} (student {student!r}, salt {salt!r}): the hidden cases cannot "
                                  f"be drawn ({_first_line(error)})")
            continue
        for index, case in enumerate(cases):
            examine(where, index, case)

    def more(kind: str, shown: list[str]) -> list[str]:
        extra = counts[kind] - len(shown)
        return shown + ([f"... and {extra} more such case{'s' * (extra != 1)}"] if extra > 0 else [])

    examined = f"the public cases or the hidden cases of {seeds} seed{'s' * (seeds != 1)}"
    problems = more("undrawable", undrawable) + more("uncomputable", uncomputable)
    problems += [f"mistake “{bank[i].name}” gives the reference's answer on every case ({examined}): "
                 "no case tells it from a right answer" for i in sorted(unmatched)]
    problems += [f"mistakes “{bank[i].name}” and “{bank[j].name}” give the same answers on every case "
                 f"({examined}): no case tells them apart" for i, j in sorted(together)
                 if i not in unmatched and j not in unmatched]
    return Soundness(problems, more("warned", warned))
