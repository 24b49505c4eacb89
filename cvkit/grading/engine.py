"""Grade a candidate implementation against an algorithm's check.

:func:`evaluate` never raises because of the candidate: every failure ends up in the
:class:`~cvkit.grading.report.Report`. :func:`check` is what notebook test cells call.
"""
from __future__ import annotations

import copy
import hashlib
import inspect
import json
import os
from typing import Any, Callable

import numpy as np

from .. import registry
from .checks import Check, Mistake, bind_call
from .runtime.guard import Outcome, run_guarded
from .report import MIME_TYPE, CaseResult, Report

SALT_VARIABLE = "CVKIT_GRADING_SALT"
STUDENT_VARIABLE = "CVKIT_STUDENT_ID"


def hidden_seed(algorithm_id: str, student: str | None = None, salt: str | None = None) -> int:
    """The seed of an algorithm's hidden cases for one student.

    It mixes a salt chosen at grading time (environment variable ``CVKIT_GRADING_SALT``,
    kept by the course for regrading) with the student id (``CVKIT_STUDENT_ID``) and the
    algorithm id, so it is reproducible for the grader and unknowable to students beforehand.
    """
    salt = salt if salt is not None else os.environ.get(SALT_VARIABLE, "practice")
    student = student if student is not None else os.environ.get(STUDENT_VARIABLE, "student")
    digest = hashlib.sha256(f"{salt}\x1f{student}\x1f{algorithm_id}".encode()).digest()
    return int.from_bytes(digest[:8], "little")


def _arg_names(function: Callable, check: Check) -> tuple:
    if check.arg_names:
        return tuple(check.arg_names)
    try:
        return tuple(
            p.name for p in inspect.signature(function).parameters.values()
            if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
        )
    except (TypeError, ValueError):
        return ()


def _reference_output(function: Callable, case, call: Callable | None = None) -> Any:
    with registry.use("reference"):
        return bind_call(call, function)(*copy.deepcopy(case.args), **copy.deepcopy(case.kwargs))


def _mistake_output(mistake: Mistake, case, call: Callable | None = None) -> tuple[bool, Any]:
    try:
        with registry.use("reference"), np.errstate(all="ignore"):
            return True, bind_call(call, mistake.function)(*copy.deepcopy(case.args), **copy.deepcopy(case.kwargs))
    except Exception:
        return False, None


def evaluate(
    algorithm_id: str,
    candidate: Callable,
    *,
    hidden: bool = False,
    seed: int | None = None,
    check: Check | None = None,
    runner: Callable | None = None,
) -> Report:
    """Grade ``candidate`` on the public (or hidden) cases of ``algorithm_id``.

    Parameters
    ----------
    algorithm_id : str
        A catalog id such as ``"filters.gaussian"``.
    candidate : callable
        The implementation to grade (a student's function, a mistake, the reference...).
    hidden : bool
        Grade on the hidden cases drawn from ``seed`` instead of the public ones.
    seed : int, optional
        Seed of the hidden cases; default :func:`hidden_seed` of the algorithm.
    check : Check, optional
        Use this check instead of the registered one.
    runner : callable, optional
        ``runner(index, case, attempt) -> Outcome`` producing the candidate's outcome for a
        case (attempt 1 is the seeded re-run) — e.g. outcomes computed in an isolated worker
        (:mod:`cvkit.grading.trusted`). Default: call ``candidate`` here, under the guard.

    Returns
    -------
    Report
        ``.passed``, ``.score`` (fraction of cases passed), per-case results and the mistake
        of the bank the candidate's output matches, if any.

    Notes
    -----
    **Cases the reference cannot compute are dropped, never scored.** When the reference
    implementation raises on a case (a bug of the check or of the reference, not of the
    candidate), that case is left out: it counts neither as passed nor as failed
    (``score = passed / counted cases``), it is not shown as a failure, and it is recorded in
    ``report.dropped`` (``"case N (label): reference raised ValueError: ..."``) for the
    instructor; the student sees one line, "N hidden case(s) dropped: the reference could not
    compute them (reported to the instructor)".

    When *every* case is dropped there is nothing left to compare with, and neither a free
    1.0 (a blank answer would earn the points) nor a silent 0 (a correct answer would lose
    them) is fair:

    - hidden cases, candidate run here (no ``runner``): the candidate is graded on the
      **visible** cases instead, which the reference computes; the score is their fraction
      passed, so the hidden points follow what can still be verified (1.0 only for a
      candidate that passes the visible cases, 0 for a blank one). ``report.fallback`` says
      so and ``report.dropped`` still lists the hidden cases.
    - otherwise (visible cases, or an external ``runner`` whose outcomes exist only for the
      hidden cases, or visible cases that cannot be computed either): the report is **not
      graded** — ``report.gradable`` is False, ``report.problem`` says why, ``score`` is 0
      and ``passed`` False — so that the instructor, who sees ``report.dropped``, fixes the
      check and regrades; nothing is awarded that was not checked.
    """
    record = registry.get(algorithm_id)
    spec = check if check is not None else record.check
    if spec is None:
        raise ValueError(f"algorithm {algorithm_id!r} has no check")
    if hidden:
        seed = hidden_seed(algorithm_id) if seed is None else int(seed)
        cases = spec.hidden_cases(np.random.default_rng(seed))
    else:
        cases = spec.public_cases()
        seed = None
    report = Report(algorithm_id, record.section, hidden, seed, [])
    if not callable(candidate):
        report.problem = f"expected a function to grade, got {type(candidate).__name__}"
        return report

    names = _arg_names(record.reference, spec)
    mistake_votes: dict[str, int] = {}
    matching: list[list[Mistake]] = []  # per counted case, the known mistakes that reproduce its output
    runs_here = runner is None  # the candidate is called in this process (it can run other cases)
    if runner is None:
        graded = bind_call(spec.call, candidate)

        def runner(index, case, attempt):
            return run_guarded(
                graded, case.args, case.kwargs,
                arg_names=names,
                time_limit=spec.time_limit,
                forbidden_libraries=spec.forbidden_libraries if attempt == 0 else (),
                forbidden_functions=spec.forbidden if attempt == 0 else (),
                allowed_ids=tuple(spec.allowed),
                watch_reference=attempt == 0,
            )

    for index, case in enumerate(cases):
        found: list[Mistake] = []
        outcome = runner(index, case, 0)
        if outcome is None:  # e.g. the isolated worker died before this case
            outcome = Outcome(error="no result: the grading worker stopped before this case (exit, crash or memory)")
        label = case.label or f"case {index + 1}"
        # computed only after the candidate ran: it cannot be read from the grader's frames
        try:
            expected = _reference_output(record.reference, case, spec.call)
        except Exception as error:  # the check's fault, not the candidate's: drop the case
            report.dropped.append(_dropped_entry(index, label, error))
            continue
        result = CaseResult(
            index=index,
            label=label,
            description=case.describe(names),
            passed=False,
            elapsed=outcome.elapsed,
            warnings=outcome.warnings,
            stdout=outcome.stdout,
            stderr=outcome.stderr,
            traceback=outcome.traceback,
            expected=expected,
        )
        mismatch = None
        if outcome.error is not None:
            result.message = outcome.error
        elif outcome.forbidden_calls:
            result.message = (
                "calls " + ", ".join(outcome.forbidden_calls)
                + ", which would do the exercise for you: write it with NumPy"
            )
        elif outcome.modified:
            result.message = (
                f"modified its input {', '.join(map(repr, outcome.modified))}: do not overwrite the "
                "input image (§3.7); work on a copy or write the result to a new array"
            )
        else:
            result.got = outcome.value
            with np.errstate(all="ignore"):
                mismatch = spec.compare(outcome.value, expected, case)
            if mismatch is None and spec.seeded:
                again = runner(index, case, 1)
                if again is None or again.error is not None or spec.compare(again.value, outcome.value, case) is not None \
                        or not _identical(again.value, outcome.value):
                    result.message = (
                        "two calls with the same rng seed gave different results: draw every random "
                        "number from np.random.default_rng(rng), never from np.random.* directly"
                    )
                else:
                    result.passed = True
            elif mismatch is None:
                result.passed = True
            else:
                result.message = mismatch.message
                result.worst = mismatch.worst
        if not result.passed and result.got is not None:
            # every known mistake that reproduces this wrong output gets this case's vote (one
            # case may not tell two mistakes apart; the other cases then decide)
            for mistake in spec.mistakes:
                produced, wrong = _mistake_output(mistake, case, spec.call)
                if not produced:
                    continue
                with np.errstate(all="ignore"):
                    if spec.compare(wrong, expected, case) is None:
                        continue  # this case does not tell the mistake from the right answer
                    if spec.compare(outcome.value, wrong, case) is None:
                        found.append(mistake)
                        mistake_votes[mistake.name] = mistake_votes.get(mistake.name, 0) + 1
        report.cases.append(result)
        matching.append(found)
    if report.dropped and not report.cases:
        return _nothing_counted(report, algorithm_id, candidate, spec, runs_here)
    if mistake_votes:
        # the mistake consistent with the most failing cases; ties go to the bank's order
        best = max(mistake_votes, key=mistake_votes.get)
        report.mistake = best
        report.hint = spec.mistake(best).hint
    for result, found in zip(report.cases, matching):
        if found:  # each case names the overall mistake when it fits, else its first match
            chosen = next((m for m in found if m.name == report.mistake), found[0])
            result.mistake, result.hint = chosen.name, chosen.hint
    return report


def _dropped_entry(index: int, label: str, error: BaseException, limit: int = 300) -> str:
    """``"case N (label): reference raised ValueError: <first line>"`` for ``report.dropped``."""
    message = str(error).strip().splitlines()[0] if str(error).strip() else ""
    if len(message) > limit:
        message = message[: limit - 1] + "…"
    return f"case {index + 1} ({label}): reference raised {type(error).__name__}" + (f": {message}" if message else "")


def _nothing_counted(report: Report, algorithm_id: str, candidate: Callable, spec: Check, runs_here: bool) -> Report:
    """The reference raised on every case (see :func:`evaluate`, Notes): grade on the visible
    cases instead when possible, else mark the report as not graded."""
    n = len(report.dropped)
    kind = "hidden" if report.hidden else "visible"
    what = f"the reference could not compute any of the {n} {kind} case{'s' if n != 1 else ''}"
    if report.hidden and runs_here:
        visible = evaluate(algorithm_id, candidate, hidden=False, check=spec)
        if visible.cases:
            report.cases = visible.cases
            report.mistake, report.hint = visible.mistake, visible.hint
            report.dropped += [f"visible {entry}" for entry in visible.dropped]
            report.fallback = (f"{what} (reported to the instructor): you were graded on the visible "
                               "cases instead")
            return report
        report.dropped += [f"visible {entry}" for entry in visible.dropped]
        what += " nor any visible case"
    report.problem = f"not graded: {what} (reported to the instructor, who will regrade)"
    return report


def _identical(a, b) -> bool:
    """Exactly the same result (for the seeded re-run): arrays, numbers, strings, and tuples,
    lists and dicts of them, compared element by element."""
    if isinstance(a, (tuple, list)) or isinstance(b, (tuple, list)):
        return (type(a) is type(b) and len(a) == len(b)
                and all(_identical(x, y) for x, y in zip(a, b)))
    if isinstance(a, dict) or isinstance(b, dict):
        return isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys() \
            and all(_identical(a[k], b[k]) for k in a)
    if isinstance(a, str) or isinstance(b, str) or a is None or b is None:
        return a == b
    try:
        return bool(np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True))
    except Exception:
        return False


def _show(report: Report) -> None:
    """Display the report in a Jupyter kernel (HTML + text + JSON), else print the text."""
    try:
        from IPython import get_ipython

        shell = get_ipython()
    except Exception:
        shell = None
    if shell is not None and getattr(shell, "kernel", None) is not None:
        from IPython.display import display

        bundle = {"text/plain": report.text(), MIME_TYPE: json.loads(json.dumps(report.to_dict(), default=str))}
        try:
            bundle["text/html"] = report._repr_html_()
        except Exception:
            pass
        display(bundle, raw=True)
    else:
        print(report.text())


def check(algorithm_id: str, candidate: Callable, hidden: bool = False, points: float | None = None, *, seed: int | None = None):
    """Grade ``candidate`` in a notebook test cell.

    Shows the report (HTML with images in JupyterLab, text elsewhere). A visible test
    (``hidden=False``) raises ``AssertionError`` when any case fails. A hidden test returns the
    partial credit ``score × points`` (or the score in 0..1 without ``points``) as the cell's
    value, which nbgrader records as the cell's grade.

    >>> import cvkit.filters
    >>> check("filters.mean_kernel", cvkit.filters.mean_kernel)  # doctest: +ELLIPSIS
    filters.mean_kernel (§3.8), visible tests: ... passed — passed
    """
    if os.environ.get("CVKIT_TRUSTED_GRADING") == "1":
        # autograding: the verdict is computed outside this kernel and replaces this output
        print(f"{algorithm_id}: checked by the trusted grader outside the notebook")
        return 0.0 if hidden else None
    report = evaluate(algorithm_id, candidate, hidden=hidden, seed=seed)
    _show(report)
    if hidden:
        value = report.score if points is None else report.score * float(points)
        return round(float(value), 6)
    if not report.passed:
        raise AssertionError(report.summary())
    return None
