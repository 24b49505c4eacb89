"""Grade a candidate implementation against an algorithm's check.

:func:`evaluate` never raises because of the candidate: every failure ends up in the
:class:`~cvkit.grading.report.Report`. :func:`check` is what notebook test cells call.
"""
from __future__ import annotations

import contextlib
import copy
import enum
import hashlib
import inspect
import os
import re
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from .. import registry
from .checks import Case, Check, Mistake, bind_call
from .compare import Mismatch, Statistics
from .diagnose import CONVENTION, diagnose, explain_exception, image_variants
from .served import DATA_TRANSFORMS
from .runtime.guard import ERROR_KINDS, Outcome, run_guarded, use_reference_functions
from .report import MIME_TYPE, CaseResult, Report, cascade_report, headline
from . import probes

try:  # installed with scikit-learn (cvkit[course])
    from threadpoolctl import threadpool_limits
except ImportError:  # pragma: no cover - the library alone, without the course's packages
    threadpool_limits = None

SALT_VARIABLE = "CVKIT_GRADING_SALT"
STUDENT_VARIABLE = "CVKIT_STUDENT_ID"

# the guard reports calls into cvkit's references; it learns them from here (it never imports
# the registry itself: the runtime must stay free of cvkit's library, docs/architecture.md)
use_reference_functions(registry.reference_functions)


def hidden_seed(algorithm_id: str, student: str | None = None, salt: str | None = None,
                version: str | None = None) -> int:
    """The seed of an algorithm's hidden cases for one student.

    It mixes a salt chosen at grading time (environment variable ``CVKIT_GRADING_SALT``,
    kept by the course for regrading) with the student id (``CVKIT_STUDENT_ID``) and the
    algorithm id, so it is reproducible for the grader and unknowable to students beforehand;
    and, at grading time, the ``version`` of the student's code
    (:func:`cvkit.course.trusted.submission_version`), so that every new version of a
    submission meets new cases: answers learned from one attempt are worth nothing on the next.
    """
    salt = salt if salt is not None else os.environ.get(SALT_VARIABLE, "practice")
    student = student if student is not None else os.environ.get(STUDENT_VARIABLE, "student")
    mixed = f"{salt}\x1f{student}\x1f{algorithm_id}" + (f"\x1f{version}" if version else "")
    digest = hashlib.sha256(mixed.encode("utf-8", "surrogatepass")).digest()
    return int.from_bytes(digest[:8], "little")


def watched_functions() -> dict:
    """What a candidate may not call unless its check allows it (code object → id): cvkit's
    reference functions, and the data loaders that compute from an image
    (:data:`~cvkit.grading.served.DATA_TRANSFORMS`: ``data.with_gaussian_noise`` is
    the answer of ``noise.add_gaussian``), which grading never serves either."""
    from .. import data

    codes = registry.reference_functions()
    for name in DATA_TRANSFORMS:
        code = getattr(inspect.unwrap(getattr(data, name)), "__code__", None)
        if code is not None:
            codes[code] = f"data.{name}"
    return codes


def arg_names(function: Callable, check: Check) -> tuple:
    """The names of a case's positional arguments, as reports show them.

    Parameters
    ----------
    function : callable
        The function whose signature names the arguments (the reference implementation).
    check : Check
        Its :attr:`Check.arg_names`, when given, win over the signature.

    Returns
    -------
    tuple of str
        One name per positional parameter; empty when ``function`` has no readable signature.
    """
    if check.arg_names:
        return tuple(check.arg_names)
    try:
        return tuple(
            p.name for p in inspect.signature(function).parameters.values()
            if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
        )
    except (TypeError, ValueError):
        return ()




_RETURNS = re.compile(r"^Returns\n-+\n(.*?)(?=^\S[^\n]*\n-+\n|\Z)", re.S | re.M)


def output_names(function: Callable, check: Check) -> tuple:
    """The names of an algorithm's results when it returns a tuple, as reports show them.

    Parameters
    ----------
    function : callable
        The reference implementation, whose docstring's *Returns* section names the results
        (``(gx, gy) : tuple of ...`` on one line, or one ``name : type`` line per result).
    check : Check
        Its :attr:`Check.output_names`, when given, win over the docstring; a check with a
        :attr:`Check.call` adapter (whose results may differ from the reference's) names its
        results there or not at all.

    Returns
    -------
    tuple of str
        Empty when the results have no names (a single result, or an unreadable docstring).

    >>> import cvkit.edges
    >>> from cvkit import registry
    >>> output_names(cvkit.edges.sobel, registry.get("edges.sobel").check)
    ('gx', 'gy')
    """
    if check.output_names:
        return tuple(check.output_names)
    if check.call is not None:
        return ()
    found = _RETURNS.search(inspect.getdoc(getattr(function, "__wrapped__", function)) or "")
    if not found:
        return ()
    body = found.group(1)
    together = re.match(r"\(\s*([A-Za-z_]\w*(?:\s*,\s*[A-Za-z_]\w*)+)\s*\)\s*:", body)
    if together:
        return tuple(name.strip() for name in together.group(1).split(","))
    names = re.findall(r"^([A-Za-z_]\w*)\s*:", body, re.M)
    return tuple(names) if len(names) > 1 else ()


_RESULT_INDEX = re.compile(r"\b([Rr])esult \[(\d+)\]")


def _name_results(text: str | None, names: Sequence[str], count: int | None, listed: bool = False) -> str | None:
    """``text`` with the comparators' ``result [i]`` replaced by the result's name (`` `gx` ``),
    or, when the names do not fit the ``count`` results, by "output i+1" (of a tuple) or "item
    i of the list" (``listed``: the output is a list, such as a pyramid's octaves)."""
    if not text or "esult [" not in text:
        return text
    fits = count is not None and len(names) == count

    def name(match: re.Match) -> str:
        i = int(match.group(2))
        if fits and i < len(names):
            return f"`{names[i]}`"
        capital = match.group(1) == "R"
        if listed:
            return f"{'I' if capital else 'i'}tem {i} of the list"
        return f"{'O' if capital else 'o'}utput {i + 1}"

    return _RESULT_INDEX.sub(name, text)


def _reference_output(function: Callable, case, call: Callable | None = None) -> Any:
    # the reference's own warnings (a case chosen to be hard, e.g. too few iterations) are not
    # the student's business and must never reach stderr: nbgrader zeroes a test cell that writes there
    with registry.use("reference"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return bind_call(call, function)(*copy.deepcopy(case.args), **copy.deepcopy(case.kwargs))


def refusal_words(raises: str, label: str) -> str:
    """What a case of bad input asks for, in the words of its failure message."""
    return f"this input must raise {raises} ({label}), with a message that names the argument"


def _reference_refusal(function: Callable, case, call: Callable | None = None) -> str | None:
    """None when the reference raises the error a case of bad input names (:attr:`Case.raises`),
    else what it did instead (the case is then the check's mistake)."""
    try:
        _reference_output(function, case, call)
    except ERROR_KINDS[case.raises]:
        return None
    except Exception as error:
        return f"the reference raises {type(error).__name__}, not {case.raises}, on this case of bad input"
    return f"the reference does not raise {case.raises} on this case of bad input"


def _mistake_output(mistake: Mistake, case, call: Callable | None = None) -> tuple[bool, Any]:
    try:
        with registry.use("reference"), np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return True, bind_call(call, mistake.function)(*copy.deepcopy(case.args), **copy.deepcopy(case.kwargs))
    except Exception:
        return False, None


def _mistake_error(mistake: Mistake, case, call: Callable | None = None) -> str | None:
    """``"IndexError: <first line>"`` when the mistake raises on the case, else None."""
    try:
        with registry.use("reference"), np.errstate(all="ignore"):
            bind_call(call, mistake.function)(*copy.deepcopy(case.args), **copy.deepcopy(case.kwargs))
    except Exception as error:
        text = str(error).strip().splitlines()[0] if str(error).strip() else ""
        return f"{type(error).__name__}: {text}"
    return None


def _normalised(compare, value):
    try:
        return compare.normalise(value)
    except Exception:
        return value


def _matching_mistakes(spec: Check, case, got: Any, expected: Any) -> list[Mistake]:
    """The bank's mistakes that reproduce ``got`` on ``case`` (and differ from ``expected``
    there), exactly or, when the comparator has a normal form, up to it: a structural mistake
    (A⁻¹·R·A) is named whether or not the candidate also normalised its result."""
    compare = spec.compare
    if getattr(compare, "judges_alone", False):
        return []  # compare(got, wrong) fails as compare(got, expected) does (Comparator.judges_alone)
    normalises = bool(getattr(compare, "normalises", False))
    found = []
    if normalises:
        ng, ne = _normalised(compare, got), _normalised(compare, expected)
    for mistake in spec.bank:
        produced, wrong = _mistake_output(mistake, case, spec.call)
        if not produced:
            continue
        with np.errstate(all="ignore"):
            try:
                if compare(wrong, expected, case) is None:
                    continue  # this case does not tell the mistake from the right answer
                if compare(got, wrong, case) is None:
                    found.append(mistake)
                    continue
                if normalises:
                    nw = _normalised(compare, wrong)
                    if compare(nw, ne, case) is not None and compare(ng, nw, case) is None:
                        found.append(mistake)
            except Exception:
                continue
    return found


def _diagnosable(spec: Check) -> bool:
    """Outputs compared value by value (allclose-like comparators), not random draws."""
    compare = spec.compare
    return not spec.seeded and not isinstance(compare, Statistics) and bool(getattr(compare, "elementwise", False))


def _input_image(case: Case | None) -> bool | tuple[int, ...]:
    """The shape of the case's first argument when it is an array of two or more dimensions
    (perhaps an image: :func:`cvkit.grading.diagnose.diagnose` decides), else False."""
    first = case.args[0] if case is not None and case.args else None
    return tuple(first.shape) if isinstance(first, np.ndarray) and first.ndim >= 2 else False


def _diagnosis(spec: Check, got: Any, expected: Any, case: Case | None = None) -> str | None:
    """The shape of the error of a failing output (:func:`cvkit.grading.diagnose.diagnose`)."""
    if not _diagnosable(spec):
        return None
    image = _input_image(case)
    compare = spec.compare
    if getattr(compare, "normalises", False):
        got, expected = _normalised(compare, got), _normalised(compare, expected)
    rtol = getattr(compare, "rtol", 1e-7)
    atol = getattr(compare, "atol", 1e-10)
    rtol = float(rtol) if isinstance(rtol, (int, float)) else 1e-7
    atol = float(atol) if isinstance(atol, (int, float)) else 1e-10
    try:
        with np.errstate(all="ignore"):
            if isinstance(expected, (tuple, list)) and not isinstance(expected, np.ndarray):
                found = diagnose(got, expected, rtol=rtol, image=image)
            else:
                e = np.asarray(expected, dtype=np.float64)
                finite = np.abs(e[np.isfinite(e)])
                scale = max(1.0, float(finite.max())) if finite.size else 1.0
                found = diagnose(got, expected, rtol=rtol, atol=atol * scale, image=image)
    except Exception:
        return None
    return str(found) if found is not None else None


#: words of the numpy.testing vocabulary that students should not have to read first
_TECHNICAL = re.compile(r"\b(rtol|atol)\b|to tolerance|^Mismatched elements|^Max relative difference")
_TECHNICAL_ASIDE = re.compile(r"\s*\((?:[^()]*\b(?:rtol|atol)\b[^()]*)\)")


def _plain_words(mismatch: Mismatch) -> tuple[str, str]:
    """(message, details) of a comparator's mismatch with plain words first: lines in the
    numpy.testing vocabulary (tolerances, "Mismatched elements") move to the details."""
    if mismatch.details is not None or not _TECHNICAL.search(mismatch.message or ""):
        return mismatch.message, mismatch.details or ""
    lines = mismatch.message.splitlines()
    plain: list[str] = []
    technical: list[str] = []
    for i, line in enumerate(lines):
        prefix = ""
        match = re.match(r"^(result \[\d+\]: |[\w.\[\]' ]{1,40}: )(?=Not equal|Mismatched)", line)
        if match:
            prefix, line = match.group(1), line[match.end():]
        if _TECHNICAL.search(line) and not _TECHNICAL_ASIDE.search(line):
            technical.append(prefix + line)
            if i == 0 or not plain:
                lead = prefix
                if mismatch.mismatched is not None and mismatch.total:
                    lead += (f"all {mismatch.total} values differ" if mismatch.mismatched == mismatch.total
                             else f"{mismatch.mismatched} of {mismatch.total} values differ")
                    plain.append(lead[0].upper() + lead[1:] + ".")
            continue
        stripped = _TECHNICAL_ASIDE.sub("", line)
        if stripped != line:
            technical += [m.strip(" ()") for m in _TECHNICAL_ASIDE.findall(line)]
        plain.append(prefix + stripped)
    if not plain:
        return mismatch.message, ""
    return "\n".join(plain), "\n".join(technical)


def _passes(spec: Check, got: Any, expected: Any, case) -> bool:
    try:
        with np.errstate(all="ignore"):
            return spec.compare(got, expected, case) is None
    except Exception:
        return False


def _swapped(value: Any) -> Any:
    arr = np.asarray(value) if isinstance(value, np.ndarray) else None
    return np.swapaxes(arr, 0, 1) if arr is not None and arr.ndim >= 2 else value


_CRASHES = ("IndexError", "ValueError")
#: seconds a candidate may run on a variant of a case that made it crash (visible cases only)
_VARIANT_TIME_LIMIT = 5.0


def _explain_crash(spec: Check, reference: Callable, case, outcome: Outcome, expected: Any,
                   run_here: Callable | None) -> tuple[str | None, Mistake | None]:
    """Why a candidate raised an index or shape error, in words, and the mistake of the bank
    behind it if one can be found.

    In this process (``run_here``, the notebook's ``check()``) the candidate is run again on a
    square crop and on a transposed copy of the case's image: if it then runs and matches a
    mistake ("x and y swapped"), or gives the right answer, the crash came from mixing up rows
    and columns. Wherever it runs (also for outcomes computed in the sandbox), the bank's
    mistakes are tried for the same error on the case, and the error message is read against
    the case's inputs (:func:`cvkit.grading.diagnose.explain_exception`).
    """
    text, mistake = None, None
    image = case.args[0] if case.args else None
    swap_plausible = True
    if run_here is not None and isinstance(image, np.ndarray):  # (image_variants needs one)
        for kind, args in image_variants(case.args):
            H, W = image.shape[:2]
            variant = copy.copy(case)
            variant.args, variant.kwargs = args, dict(case.kwargs)
            try:
                expected_v = _reference_output(reference, variant, spec.call)
            except Exception:
                continue
            again = run_here(variant)
            if again is None or not again.ok:
                if kind == "square" and again is not None and again.exception == outcome.exception:
                    swap_plausible = False  # it crashes on a square image too: not a rows/columns mix-up
                continue
            got_v = again.value
            crop = f"a square {min(H, W)}×{min(H, W)} crop" if kind == "square" else "the transposed image"
            why = (f"it crashes only on the {H}×{W} image (not square), so rows and columns are mixed up somewhere: "
                   f"{CONVENTION}")
            if kind == "transposed" and (_passes(spec, got_v, expected, case)
                                         or _passes(spec, _swapped(got_v), expected, case)):
                return (f"Given the transposed image (rows and columns swapped) your code runs and gives the right "
                        f"answer: somewhere it treats the image as image[x, y]. "
                        f"{CONVENTION[0].upper() + CONVENTION[1:]}."), mistake
            matches = _matching_mistakes(spec, variant, got_v, expected_v)
            if matches:
                mistake = matches[0]
                return (f"On {crop} of this image your code runs, and its output matches the mistake "
                        f"“{mistake.name}”: {why}."), mistake
            if text is None:
                right = _passes(spec, got_v, expected_v, variant)
                text = (f"On {crop} of this image your code runs{' and gives the right answer' if right else ''}: "
                        f"{why}.")
    if mistake is None:
        error = outcome.error or ""
        for candidate in spec.bank:
            raised = _mistake_error(candidate, case, spec.call)
            if raised and outcome.exception and raised.startswith(outcome.exception + ":") \
                    and raised.partition(": ")[2] == error.partition(": ")[2]:
                mistake = candidate
                text = text or f"The mistake “{candidate.name}” raises the same error on this case."
                break
    if text is None:
        reading = explain_exception((outcome.error or "").partition(": ")[2], case.args,
                                    swap_plausible=swap_plausible)
        if reading:
            text = reading[0].upper() + reading[1:] + ("" if reading.endswith(".") else ".")
    return text, mistake


def evaluate(
    algorithm_id: str,
    candidate: Callable | None = None,
    *,
    hidden: bool = False,
    seed: int | None = None,
    check: Check | None = None,
    runner: Callable | None = None,
    cases: Sequence[Case] | None = None,
) -> Report:
    """Grade ``candidate`` on the public (or hidden) cases of ``algorithm_id``.

    Parameters
    ----------
    algorithm_id : str
        A catalog id such as ``"filters.gaussian"``.
    candidate : callable
        The implementation to grade (a student's function, a mistake, the reference...).
        Not needed when a ``runner`` gives the outcomes.
    hidden : bool
        Grade on the hidden cases drawn from ``seed`` instead of the public ones.
    seed : int, optional
        Seed of the hidden cases; default :func:`hidden_seed` of the algorithm.
    check : Check, optional
        Use this check instead of the registered one.
    runner : callable, optional
        ``runner(index, case, attempt) -> Outcome`` producing the candidate's outcome for a
        case (attempt 1 is the seeded re-run) — e.g. outcomes computed in an isolated worker
        (:mod:`cvkit.course.trusted`). Default: call ``candidate`` here, under the guard.
    cases : sequence of Case, optional
        Grade on these cases, already drawn by the caller (the trusted path draws a notebook's
        cases once and sends them to the sandbox), instead of drawing them here; ``hidden`` and
        ``seed`` then only label the report.

    Returns
    -------
    Report
        ``.passed``, ``.score`` (fraction of cases passed), per-case results and the mistake
        of the bank the candidate's output matches, if any.

    Notes
    -----
    **Feedback on a failing case.** The message starts with plain words (how many values
    differ and where, the first one with yours vs expected, the largest error; the comparator's
    tolerances are in ``CaseResult.details``). The bank's mistakes are matched exactly and, when
    the comparator has a normal form (:meth:`~cvkit.grading.compare.Comparator.normalise`), up
    to it. When no mistake fits, an output compared value by value gets a
    :func:`~cvkit.grading.diagnose.diagnose` (``CaseResult.diagnosis``: shifted, transposed,
    flipped, scaled, offset, only the border wrong, colour channels swapped, NaN...). An
    ``IndexError``/``ValueError`` is explained: on the visible cases run here, the candidate is
    run again on a square crop and on a transposed copy of the image (if it then matches a
    mistake, that mistake is named); everywhere, the bank's mistakes are tried for the same
    error and the message is read against the inputs
    (:func:`~cvkit.grading.diagnose.explain_exception`).

    **Rules of the statement.** A check whose :attr:`~cvkit.grading.Check.rules` include
    ``"no warnings"`` fails a case whose values are right but whose code raised a warning, with
    a sentence naming it. A failing case that no mistake of the bank reproduces is marked
    ``CaseResult.unexplained`` (course tools count them, to find the next mistakes to bank).

    **Notes on a passing visible test.** When the candidate runs here and passes every visible
    case, :func:`cvkit.grading.probes.notes` runs it on the public inputs in the dtypes,
    containers and shapes the hidden cases use (int16, uint8, a list, a single point...) and
    looks for float32 results; what differs becomes ``report.notes`` ("passes the shown cases,
    but …"), one line each in the report. Notes never change the verdict or the score.

    **A case that does not return stops the check.** The first case that runs out of its time
    limit (``Check.time_limit``) fails with advice that fits where the candidate was stopped
    (:func:`cvkit.grading.runtime.guard.loop_evidence`: in a ``while`` loop, its exit
    condition; in ``for`` loops, vectorize); the remaining cases are not run (their outcome:
    "not run: case N did not return …"), so an endless loop costs one time limit per call.

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
    mode = _Mode.of(hidden, cases, runner)
    record = registry.get(algorithm_id)
    spec = check if check is not None else record.check
    if spec is None:
        raise ValueError(f"algorithm {algorithm_id!r} has no check")
    drawn, seed = _cases_and_seed(mode, algorithm_id, spec, cases, seed)
    report = Report(algorithm_id, record.cited, hidden, seed, [])
    if mode.runs_here and not callable(candidate):
        report.problem = f"expected a function to grade, got {type(candidate).__name__}"
        return report
    with one_blas_thread() if mode.runs_here else contextlib.nullcontext():
        evaluation = _Evaluation.start(record, spec, mode, report, candidate, runner)
        for index, case in enumerate(drawn):
            evaluation.grade_case(index, case)
        if report.dropped and not report.cases:
            return _nothing_counted(report, algorithm_id, candidate, spec, mode.falls_back_to_visible)
        evaluation.add_notes(drawn)
        evaluation.name_the_mistake()
    return report


def one_blas_thread() -> contextlib.AbstractContextManager:
    """NumPy's BLAS on one thread while a candidate runs here, as it runs in the grader's sandbox
    (``OMP_NUM_THREADS=1``): a case's time limit then means the same in a student's kernel as on the
    grader (one core). With BLAS threads on a busy machine, small products mostly wait for each
    other: Chapter 12's model network took 17 s of CPU with them and 3 s without."""
    return threadpool_limits(1) if threadpool_limits is not None else contextlib.nullcontext()


class _Cases(enum.Enum):
    """Where the cases of an evaluation come from."""

    PUBLIC = "the check's public cases"
    HIDDEN = "the hidden cases drawn from the seed"
    GIVEN = "cases the caller drew (the trusted grader)"


@dataclass(frozen=True)
class _Mode:
    """How one :func:`evaluate` runs, resolved once from its arguments: its cases (public,
    hidden or given) × where the candidate runs (here, under the guard, or elsewhere, its
    outcomes given by a ``runner``) — six modes; what depends on them has a name below."""

    cases: _Cases
    hidden: bool       # the report is about hidden cases (given cases carry the caller's word)
    runs_here: bool    # the candidate is called in this process, under the guard

    @classmethod
    def of(cls, hidden: bool, cases: Sequence[Case] | None, runner: Callable | None) -> "_Mode":
        """The mode of ``evaluate(hidden=…, cases=…, runner=…)``."""
        source = _Cases.GIVEN if cases is not None else _Cases.HIDDEN if hidden else _Cases.PUBLIC
        return cls(source, hidden, runner is None)

    @property
    def reruns_variants(self) -> bool:
        """A crash is explained by running the candidate again on variants of its case (visible cases, run here)."""
        return self.runs_here and not self.hidden

    @property
    def adds_notes(self) -> bool:
        """A passing report gets the notes of the visible probes (visible cases, run here)."""
        return self.runs_here and not self.hidden

    @property
    def falls_back_to_visible(self) -> bool:
        """No hidden case computed: the candidate is graded on the visible ones (hidden cases, run here)."""
        return self.runs_here and self.hidden


def _cases_and_seed(mode: _Mode, algorithm_id: str, spec: Check, cases: Sequence[Case] | None,
                    seed: int | None) -> tuple[list[Case], int | None]:
    """The cases to grade on and the seed the report names (None for public cases)."""
    if mode.cases is _Cases.GIVEN:
        assert cases is not None
        return list(cases), int(seed) if mode.hidden and seed is not None else None
    if mode.cases is _Cases.HIDDEN:
        seed = hidden_seed(algorithm_id) if seed is None else int(seed)
        return spec.graded_hidden_cases(np.random.default_rng(seed)), seed
    return spec.public_cases(), None


#: ``runner(index, case, attempt)``: the candidate's outcome on a case (attempt 1: the seeded re-run)
_Runner = Callable[[int, Case, int], Outcome | None]


def _guarded_runners(spec: Check, candidate: Callable, names: tuple) -> tuple[_Runner, Callable[[Case], Outcome]]:
    """The candidate called here under the guard: on a case, and on a variant of a case (to explain a crash)."""
    graded = bind_call(spec.call, candidate)

    def runner(index: int, case: Case, attempt: int) -> Outcome:
        return run_guarded(
            graded, case.args, case.kwargs,
            arg_names=names,
            time_limit=spec.time_limit,
            forbidden_libraries=spec.forbidden_libraries if attempt == 0 else (),
            forbidden_functions=spec.forbidden if attempt == 0 else (),
            allowed_ids=tuple(spec.allowed),
            watch_reference=attempt == 0,
            reference_codes=watched_functions() if attempt == 0 else None,
        )

    def run_here(case: Case) -> Outcome:  # short: it is only feedback
        return run_guarded(
            graded, case.args, case.kwargs,
            arg_names=names,
            time_limit=min(spec.time_limit, _VARIANT_TIME_LIMIT),
            forbidden_libraries=spec.forbidden_libraries,
            forbidden_functions=spec.forbidden,
            allowed_ids=tuple(spec.allowed),
            watch_reference=True,
            reference_codes=watched_functions(),
        )

    return runner, run_here


@dataclass
class _Evaluation:
    """One evaluation under way: the check, how the candidate runs, and what its cases found."""

    record: registry.Algorithm
    spec: Check
    mode: _Mode
    report: Report
    names: tuple                                 # the names of a case's arguments
    results: tuple                               # the names of the algorithm's results
    runner: _Runner
    run_here: Callable[[Case], Outcome] | None   # a variant of a case, run here (the candidate runs here)
    votes: dict[str, int] = field(default_factory=dict)             # mistake → failing cases it reproduces
    matching: list[list[Mistake]] = field(default_factory=list)     # per counted case, the mistakes reproducing it
    crashes_explained: int = 0
    stalled: int | None = None                   # the first case that did not return within its time limit

    @classmethod
    def start(cls, record: registry.Algorithm, spec: Check, mode: _Mode, report: Report,
              candidate: Callable | None, runner: _Runner | None) -> "_Evaluation":
        """The evaluation before its first case: names, and the runners of the candidate."""
        names = arg_names(record.reference, spec)
        results = output_names(record.reference, spec)
        run_here = None
        if runner is None:
            assert candidate is not None  # checked by evaluate: no runner needs a candidate
            runner, run_here = _guarded_runners(spec, candidate, names)
        return cls(record, spec, mode, report, names, results, runner, run_here)

    def grade_case(self, index: int, case: Case) -> None:
        """Run the candidate on one case and record its verdict (or drop the case the reference cannot compute)."""
        outcome = self._outcome(index, case)
        label = case.label or f"case {index + 1}"
        if case.raises is not None:
            self._grade_refusal(index, case, outcome, label)
            return
        # computed only after the candidate ran: it cannot be read from the grader's frames
        try:
            expected = _reference_output(self.record.reference, case, self.spec.call)
        except Exception as error:  # the check's fault, not the candidate's: drop the case
            self.report.dropped.append(_dropped_entry(index, label, error))
            return
        result = CaseResult(
            index=index,
            label=label,
            description=case.describe(self.names),
            passed=False,
            elapsed=outcome.elapsed,
            warnings=outcome.warnings,
            stdout=outcome.stdout,
            stderr=outcome.stderr,
            traceback=outcome.traceback,
            expected=expected,
            timed_out=outcome.timed_out,
        )
        found: list[Mistake] = []
        mismatch, warned = self._judge(index, case, outcome, expected, result, found)
        if not result.passed and result.got is not None and not warned:
            self._explain_output(case, outcome, expected, result, found, mismatch)
        if not result.passed and not found and not warned and not result.timed_out \
                and outcome.exception != "NotImplementedError":
            result.unexplained = True  # a failure no mistake of the bank names: counted by course tools
        self._name_outputs(result, expected)
        self.report.cases.append(result)
        self.matching.append(found)

    def _grade_refusal(self, index: int, case: Case, outcome: Outcome, label: str) -> None:
        """A case of bad input (:attr:`Check.refusals`): passed when the candidate raised the
        error the case names; dropped when the reference itself does not raise it."""
        assert case.raises is not None
        wrong = _reference_refusal(self.record.reference, case, self.spec.call)
        if wrong is not None:  # the check's fault, not the candidate's
            self.report.dropped.append(f"case {index + 1} ({label}): {wrong}")
            return
        result = CaseResult(index=index, label=label, description=case.describe(self.names), passed=False,
                            elapsed=outcome.elapsed, warnings=outcome.warnings, stdout=outcome.stdout,
                            stderr=outcome.stderr, timed_out=outcome.timed_out)
        wanted = refusal_words(case.raises, label)
        if outcome.forbidden_calls:
            result.message = ("calls " + ", ".join(outcome.forbidden_calls)
                              + ", which would do the exercise for you: write it with NumPy")
        elif outcome.error is None:
            result.message = f"returned a result, but {wanted}"
        elif case.raises in outcome.raised_as and not outcome.timed_out:
            result.passed = True
        elif outcome.timed_out or outcome.exception in ("NotImplementedError", "NotRun") or outcome.from_grader:
            result.message, result.traceback = outcome.error or "", outcome.traceback
        else:  # the error's type only: its message is the student's text (hidden reports show none)
            result.message, result.traceback = f"raised {outcome.exception}, but {wanted}", outcome.traceback
        self.report.cases.append(result)
        self.matching.append([])

    def _outcome(self, index: int, case: Case) -> Outcome:
        """The candidate's outcome on a case, unless an earlier case did not return (then: not run)."""
        if self.stalled is not None:
            # an endless loop costs one time limit per check call, not one per case
            outcome = Outcome(error=(f"not run: case {self.stalled + 1} did not return within "
                                     f"{self.spec.time_limit:g} s, so the rest of this check was skipped (see that "
                                     "case)"),
                              exception="NotRun", from_grader=True)
        else:
            found = self.runner(index, case, 0)
            # None: e.g. the isolated worker died before this case
            outcome = found if found is not None else Outcome(
                error="no result: the grading worker stopped before this case (exit, crash or memory)")
        if outcome.timed_out and self.stalled is None:
            self.stalled = index
        return outcome

    def _judge(self, index: int, case: Case, outcome: Outcome, expected: Any, result: CaseResult,
               found: list[Mistake]) -> tuple[Mismatch | None, bool]:
        """The verdict on an outcome: an error, a forbidden call, a modified input, or the output compared."""
        if outcome.error is not None:
            self._crashed(case, outcome, expected, result, found)
        elif outcome.forbidden_calls:
            result.message = (
                "calls " + ", ".join(outcome.forbidden_calls)
                + ", which would do the exercise for you: write it with NumPy"
            )
        elif outcome.modified:
            result.message = (
                f"modified its input {', '.join(map(repr, outcome.modified))}: do not overwrite an "
                "input; work on a copy or write the result to a new array"
            )
        else:
            return self._compared(index, case, outcome, expected, result)
        return None, False

    def _crashed(self, case: Case, outcome: Outcome, expected: Any, result: CaseResult,
                 found: list[Mistake]) -> None:
        """The error as the case's message, explained for the first three index and shape errors."""
        result.message = outcome.error or ""
        if outcome.exception in _CRASHES and self.crashes_explained < 3:
            self.crashes_explained += 1
            text, culprit = _explain_crash(self.spec, self.record.reference, case, outcome, expected,
                                           self.run_here if self.mode.reruns_variants else None)
            result.diagnosis = text
            if culprit is not None:
                self._vote(found, culprit)

    def _compared(self, index: int, case: Case, outcome: Outcome, expected: Any,
                  result: CaseResult) -> tuple[Mismatch | None, bool]:
        """The output against the expected one, the statement's rules and a measured check's credit."""
        spec = self.spec
        result.got = outcome.value
        with np.errstate(all="ignore"):
            mismatch = spec.compare(outcome.value, expected, case)
        warned = False
        if mismatch is None and spec.seeded:
            self._rerun_seeded(index, case, outcome, result)
        elif mismatch is None and "no warnings" in spec.rules and outcome.warnings:
            warned = True  # right values: no mistake of the bank to look for
            result.message = (f"right values, but your code raised a warning ({outcome.warnings[0]}): the "
                              "statement asks for no warning — find the operation that overflows or divides "
                              "by zero and compute it another way")
        elif mismatch is None:
            result.passed = True
        else:
            result.message, result.details = _plain_words(mismatch)
            result.worst = mismatch.worst
        if spec.credit is not None:
            try:
                result.credit = 1.0 if result.passed else min(1.0, max(0.0, float(spec.credit(outcome.value, case))))
            except Exception:
                result.credit = 0.0
        if spec.measure is not None:
            result.measure = spec.measure.on(outcome.value, case)
        return mismatch, warned

    def _rerun_seeded(self, index: int, case: Case, outcome: Outcome, result: CaseResult) -> None:
        """A random function passes only if a second call with the same seed gives the same result."""
        spec = self.spec
        again = self.runner(index, case, 1)
        if again is not None and again.timed_out:
            result.message, result.timed_out, result.traceback = again.error or "", True, again.traceback
            self.stalled = index
        elif again is None or again.error is not None or spec.compare(again.value, outcome.value, case) is not None \
                or not identical(again.value, outcome.value):
            result.message = (
                "two calls with the same rng seed gave different results: draw every random "
                "number from np.random.default_rng(rng), never from np.random.* directly"
            )
        else:
            result.passed = True

    def _explain_output(self, case: Case, outcome: Outcome, expected: Any, result: CaseResult,
                        found: list[Mistake], mismatch: Mismatch | None) -> None:
        """The bank's mistakes that reproduce a wrong output, else what the output looks like."""
        # every known mistake that reproduces this wrong output gets this case's vote (one
        # case may not tell two mistakes apart; the other cases then decide)
        for mistake in _matching_mistakes(self.spec, case, outcome.value, expected):
            self._vote(found, mistake)
        if not found and mismatch is not None:
            # no named mistake fits: say what the wrong output looks like (shifted, transposed...)
            result.diagnosis = _diagnosis(self.spec, outcome.value, expected, case)

    def _vote(self, found: list[Mistake], mistake: Mistake) -> None:
        """One case's vote for a mistake of the bank."""
        found.append(mistake)
        self.votes[mistake.name] = self.votes.get(mistake.name, 0) + 1

    def _name_outputs(self, result: CaseResult, expected: Any) -> None:
        """The comparators' ``result [i]`` in the case's texts replaced by the names of the results."""
        count = len(expected) if isinstance(expected, (tuple, list)) else None
        listed = isinstance(expected, list)
        result.message = _name_results(result.message, self.results, count, listed) or ""
        result.details = _name_results(result.details, self.results, count, listed) or ""
        result.diagnosis = _name_results(result.diagnosis, self.results, count, listed)

    def add_notes(self, cases: Sequence[Case]) -> None:
        """A passing visible test run here: what the hidden cases will check besides (never the verdict)."""
        report, spec = self.report, self.spec
        if not (self.mode.adds_notes and report.passed and not report.dropped):
            return
        assert self.run_here is not None  # the candidate runs here
        passed = [(c.got, c.expected) for c in report.cases]
        try:  # the notes are a courtesy: they never change the verdict, nor stop the report
            report.notes = probes.notes(spec, list(cases), passed, self.run_here,
                                        lambda probe: _reference_output(self.record.reference, probe, spec.call),
                                        headline, budget=max(2.0, sum(c.elapsed for c in report.cases)))
        except Exception:
            report.notes = []

    def name_the_mistake(self) -> None:
        """The mistake most failing cases reproduce (ties: the bank's order), and each case's own."""
        report = self.report
        if self.votes:
            best = max(self.votes, key=lambda name: self.votes[name])
            report.mistake = best
            report.hint = self.spec.mistake(best).hint
        for result, found in zip(report.cases, self.matching):
            if found:  # each case names the overall mistake when it fits, else its first match
                chosen = next((m for m in found if m.name == report.mistake), found[0])
                result.mistake, result.hint = chosen.name, chosen.hint


def _dropped_entry(index: int, label: str, error: BaseException, limit: int = 300) -> str:
    """``"case N (label): reference raised ValueError: <first line>"`` for ``report.dropped``."""
    message = str(error).strip().splitlines()[0] if str(error).strip() else ""
    if len(message) > limit:
        message = message[: limit - 1] + "…"
    return f"case {index + 1} ({label}): reference raised {type(error).__name__}" + (f": {message}" if message else "")


def _nothing_counted(report: Report, algorithm_id: str, candidate: Callable | None, spec: Check,
                     fall_back: bool) -> Report:
    """The reference raised on every case (see :func:`evaluate`, Notes): grade on the visible
    cases instead when possible (``fall_back``: hidden cases, the candidate run here), else
    mark the report as not graded."""
    n = len(report.dropped)
    kind = "hidden" if report.hidden else "visible"
    what = f"the reference could not compute any of the {n} {kind} case{'s' if n != 1 else ''}"
    if fall_back:
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


def identical(a: Any, b: Any) -> bool:
    """Exactly the same result (the seeded re-run of a random function must reproduce it).

    Arrays, numbers and strings are compared by value (NaN equals NaN); tuples, lists and dicts
    of them element by element, their types and lengths (keys) included.

    >>> identical((np.zeros(2), [{"k": 1.5}]), (np.zeros(2), [{"k": 1.5}]))
    True
    >>> identical((1, 2), [1, 2])
    False
    """
    if isinstance(a, (tuple, list)) or isinstance(b, (tuple, list)):
        return (type(a) is type(b) and len(a) == len(b)
                and all(identical(x, y) for x, y in zip(a, b)))
    if isinstance(a, dict) or isinstance(b, dict):
        return isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys() \
            and all(identical(a[k], b[k]) for k in a)
    if isinstance(a, str) or isinstance(b, str) or a is None or b is None:
        return a == b
    try:
        return bool(np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True))
    except Exception:
        return False


#: algorithm id → runs of its visible test in this kernel (:func:`check`), saved with each report
#: the notebook shows (``visible_runs`` in the output's metadata) for the item analysis
_VISIBLE_RUNS: dict[str, int] = {}


def _show(report: Report, visible_runs: int | None = None) -> None:
    """Display the report in a Jupyter kernel (HTML + text + JSON; ``visible_runs`` in the
    output's metadata), else print the text."""
    try:
        from IPython import get_ipython

        shell = get_ipython()
    except Exception:
        shell = None
    if shell is not None and getattr(shell, "kernel", None) is not None:
        from IPython.display import display

        metadata = {MIME_TYPE: {"visible_runs": visible_runs}} if visible_runs else None
        display(report.mime_bundle(), raw=True, metadata=metadata)
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
    if _not_answered(report):
        # the released stub: one line instead of a report of identical failures
        name = getattr(getattr(candidate, "__wrapped__", candidate), "__name__", "your function")
        line = (f"{algorithm_id}: not answered yet — `{name}` still raises NotImplementedError. Write your "
                f"version in the answer cell above, run it, then run this cell again.")
        if hidden:
            print(line)
            return 0.0
        __tracebackhide__ = True  # noqa: F841
        raise CheckFailed(line) from None  # shown once, as the cell's error (not printed as well)
    if not report.passed and not any(case.timed_out for case in report.cases):
        # (not after a timeout: grading again would cost another time limit)
        report = _with_reference_building_blocks(algorithm_id, candidate, report, hidden, seed)
    if not hidden:  # analytics for the instructor (the item analysis): never part of a grade
        _VISIBLE_RUNS[algorithm_id] = _VISIBLE_RUNS.get(algorithm_id, 0) + 1
    _show(report, None if hidden else _VISIBLE_RUNS[algorithm_id])
    if hidden:
        value = report.score if points is None else report.score * float(points)
        return round(float(value), 6)
    if not report.passed:
        __tracebackhide__ = True  # noqa: F841  (pytest and IPython skip this frame)
        raise CheckFailed(report.summary()) from None
    return None


NOT_IMPLEMENTED = "not implemented yet (the function raises NotImplementedError)"


def _not_answered(report: Report) -> bool:
    """Every case failed because the candidate raised NotImplementedError (the released stub)."""
    return bool(report.cases) and all(not c.passed and c.message.startswith(NOT_IMPLEMENTED) for c in report.cases)


def needs_answer(exercise: str):
    """Context manager for a demo that runs a student's answer: while the answer is still the
    released stub (it raises ``NotImplementedError``), print one line saying which exercise the
    demo waits for, instead of stopping *Run All* with a traceback.

    >>> with needs_answer("Exercise 3.9b"):
    ...     raise NotImplementedError()
    This demo uses your answer to Exercise 3.9b; it runs once you have written it.
    """
    return _NeedsAnswer(exercise)


class _NeedsAnswer:
    def __init__(self, exercise: str):
        if not isinstance(exercise, str) or not exercise:
            raise TypeError("exercise must be a non-empty string naming the exercise, e.g. 'Exercise 3.9b'")
        self.exercise = exercise

    def __enter__(self):
        return self

    def __exit__(self, kind, error, traceback):
        if kind is not None and issubclass(kind, NotImplementedError):
            print(f"This demo uses your answer to {self.exercise}; it runs once you have written it.")
            return True
        return False


def _with_reference_building_blocks(algorithm_id: str, candidate: Callable, report: Report, hidden: bool,
                                    seed: int | None) -> Report:
    """One mistake costs points once (as in trusted grading, :mod:`cvkit.course.trusted`): when
    ``candidate`` fails and calls, by name, the student's own version of a building block its
    check allows (registered with ``@student``) that fails its own visible check, grade it
    again with the reference building block under that name. Returns the better report, with
    ``cascade`` saying which function is to blame."""
    spec = registry.get(algorithm_id).check
    own_code = getattr(candidate, "__wrapped__", candidate)
    namespace = getattr(own_code, "__globals__", None)
    if not isinstance(namespace, dict) or not spec.allowed:
        return report
    student = registry.provider("student").functions
    culprits = {}
    for block in spec.allowed:
        own = student.get(block)
        if own is None or own is candidate or own is own_code:
            continue
        names = [name for name, value in list(namespace.items()) if value is own]
        if names and not evaluate(block, own).passed:
            culprits[block] = (names, own)
    if not culprits:
        return report
    saved = {}
    try:
        for block, (names, _) in culprits.items():
            for name in names:
                saved[name] = namespace[name]
                namespace[name] = registry.get(block).reference
        again = evaluate(algorithm_id, candidate, hidden=hidden, seed=seed)
    finally:
        namespace.update(saved)
    return cascade_report(report, again, functions=[names[0] for names, _ in culprits.values()],
                          blocks=list(culprits), caller=getattr(own_code, "__name__", "function"))


class CheckFailed(AssertionError):
    """A visible :func:`check` failed; the report shown above says why.

    In IPython and JupyterLab it is shown as the single line ``AssertionError: <summary>``,
    without the grader's frames (IPython uses ``_render_traceback_`` instead of the
    traceback): the only frame of the student's code would be the test cell's ``check(...)``
    line, and the report above already shows where the student's function went wrong."""

    def _render_traceback_(self) -> list[str]:
        lines = str(self).splitlines() or [""]
        return [f"\x1b[0;31mAssertionError\x1b[0m: {lines[0]}"] + lines[1:]
