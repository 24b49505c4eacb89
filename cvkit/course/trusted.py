"""Trusted grading of a notebook: decide every check outside the student's kernel.

:func:`grade_notebook` takes an executed (or not) student notebook, finds the ``check(...)``
calls of its test cells (taken from the instructor's source notebook when given, as nbgrader's
autograde does), runs the student's code once in an isolated worker
(:mod:`cvkit.sandbox.session`) on all the cases, and builds the reports here, comparing with
the reference in this trusted process. :func:`scan` flags code that tries to tamper with the
grader, for the instructor to look at. :func:`apply_trusted_checks` puts the verdicts into the
notebook (the test cells' outputs and credit, which nbgrader records, and the same as data in
``metadata.cvkit``); it needs nbformat only, not nbgrader's pipeline.
"""
from __future__ import annotations

import ast
import copy
import dataclasses
import hashlib
import re
import time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from nbformat.v4 import new_output

from .. import registry
from ..grading.checks import FORBIDDEN_LIBRARIES, Case, Check, call_target
from ..grading.engine import arg_names, evaluate, hidden_seed, refusal_words
from ..grading.served import served_helpers
from ..grading.report import CaseResult, Report, cascade_report
from ..grading.runtime.cells import cell_source, cells_of, is_code, is_solution, is_test_cell, nbgrader_metadata
from ..grading.runtime.guard import Outcome, timeout_message
from ..grading.runtime.wire import BoxCall
from ..sandbox.session import notebook_seconds, run_calls


@dataclass
class CheckCall:
    """One ``check("<id>", <function>, hidden=..., points=...)`` in a test cell."""

    grade_id: str
    algorithm_id: str
    function: str
    hidden: bool
    points: float | None


@dataclass
class NotebookGrade:
    """Trusted reports per test cell, plus the flags raised by the static scan."""

    reports: dict = field(default_factory=dict)       # grade_id -> list[(CheckCall, Report)]
    flags: list = field(default_factory=list)
    worker_problem: str | None = None
    cell_errors: list = field(default_factory=list)
    sandboxed: bool = True

    def credit(self, grade_id: str, points: float) -> tuple[float, list[str]]:
        """Points of a test cell and the reasons it lost points."""
        total, reasons = points, []
        for call, report in self.reports.get(grade_id, []):
            if call.hidden:
                value = report.score * float(call.points if call.points is not None else points)
                total = min(total, value)
            elif not report.passed:
                total = 0.0
                reasons.append(report.summary().splitlines()[0])
        return round(float(total), 6), reasons


def check_calls(source: str, grade_id: str) -> list[CheckCall]:
    """The ``check(...)`` calls of a test cell's source."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return []
    calls = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", None)) == "check"):
            continue
        if len(node.args) < 2 or not isinstance(node.args[1], ast.Name):
            continue
        try:
            algorithm_id = ast.literal_eval(node.args[0])
            keywords = {k.arg: ast.literal_eval(k.value) for k in node.keywords if k.arg in ("hidden", "points")}
        except ValueError:
            continue
        calls.append(CheckCall(grade_id, str(algorithm_id), node.args[1].id,
                               bool(keywords.get("hidden", False)), keywords.get("points")))
    return calls


def worker_cells(notebook: Any, source_notebook: Any = None) -> list[str]:
    """The code the worker executes: the setup cell, every answer cell and every code cell
    the student added or changed — never the test cells, nor the instructor's demo cells."""
    original: set[str] = set()
    if source_notebook is not None:
        original = {cell_source(cell).strip() for cell in cells_of(source_notebook)
                    if is_code(cell) and not is_solution(cell)}
    cells = []
    for cell in cells_of(notebook):
        if not is_code(cell) or is_test_cell(cell):
            continue  # test cells run only in the trusted process
        source = cell_source(cell)
        setup_or_answer = nbgrader_metadata(cell).get("grade_id") == "setup" or is_solution(cell)
        if setup_or_answer or source.strip() not in original:
            if source_notebook is None and not setup_or_answer:
                continue  # without the source we cannot tell demos from student cells: answers only
            cells.append(source)
    return cells


# ---------------------------------------------------------------------------- static scan
_SUSPICIOUS_CALLS = {
    "sys.setprofile": "switches the grader's profiler", "sys.settrace": "installs a tracer",
    "sys.getprofile": "reads the grader's profiler", "sys._getframe": "reads interpreter frames",
    "sys.exit": "exits the interpreter", "os._exit": "kills the interpreter", "exit": "exits the interpreter",
    "quit": "exits the interpreter", "os.remove": "deletes files", "os.unlink": "deletes files",
    "os.rmdir": "deletes folders", "shutil.rmtree": "deletes folders", "os.system": "runs shell commands",
    "os.kill": "sends signals", "os.chmod": "changes permissions", "os.rename": "moves files",
    "open": "opens files", "exec": "executes generated code", "eval": "evaluates generated code",
    "compile": "compiles generated code", "__import__": "imports dynamically",
    "importlib.import_module": "imports dynamically", "gc.get_objects": "walks the interpreter's objects",
    "gc.get_referrers": "walks the interpreter's objects", "setattr": "sets attributes dynamically",
    "globals": "reads the global namespace",
}
_SUSPICIOUS_MODULES = ("ctypes", "subprocess", "importlib", "inspect", "gc", "signal", "multiprocessing",
                       "threading", "socket", "shutil", "pickle", "builtins", "cvkit.grading", "cvkit.registry")
_SUSPICIOUS_ATTRIBUTES = ("__globals__", "__code__", "__builtins__", "__subclasses__", "__closure__",
                          "f_back", "f_locals", "f_globals", "tb_frame", "meta_path", "path_hooks", "__dict__",
                          "__mro__", "__bases__", "__base__", "gi_frame", "cr_frame", "__import__", "__loader__",
                          "__spec__")
_REFLECTION = ("getattr", "setattr", "delattr", "vars", "dir")
_GRADER_NAMES = ("check", "evaluate", "student")


def _dotted(node) -> str:
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
    return ".".join(reversed(parts))


def scan(source: str, where: str = "") -> list[str]:
    """Flags for constructs that have no business in an answer cell (for the instructor).

    Among them, imports of the libraries that would do an exercise
    (:data:`~cvkit.grading.checks.FORBIDDEN_LIBRARIES`) and of cvkit's algorithm modules
    (:func:`cvkit.registry.topic_modules`, the same modules the sandbox worker replaces by
    stand-ins that refuse them).
    """
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return []
    forbidden = tuple(FORBIDDEN_LIBRARIES) + tuple(f"cvkit.{topic}" for topic in registry.topic_modules())
    prefix = f"{where}: " if where else ""
    flags = []

    def add(text):
        if prefix + text not in flags:
            flags.append(prefix + text)

    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            names += [a.name if isinstance(node, ast.Import) else f"{node.module}.{a.name}" for a in node.names]
            for name in names:
                if name.startswith(_SUSPICIOUS_MODULES):
                    add(f"imports {name}")
                if name.startswith(forbidden):
                    add(f"imports {name} (not allowed in exercises)")
        elif isinstance(node, ast.Call):
            name = _dotted(node.func)
            if name in _SUSPICIOUS_CALLS:
                add(f"calls {name} ({_SUSPICIOUS_CALLS[name]})")
            if name in _REFLECTION and len(node.args) >= 2:
                key = node.args[1]
                if not isinstance(key, ast.Constant):
                    add(f"calls {name} with a computed attribute name")
                elif isinstance(key.value, str) and key.value.startswith("_"):
                    add(f"calls {name}(…, {key.value!r}) (reaches into internals)")
            if isinstance(node.func, ast.Attribute) and node.func.attr in ("remove", "clear", "pop", "insert") \
                    and _dotted(node.func.value).endswith(("meta_path", "path_hooks", "modules")):
                add(f"changes {_dotted(node.func.value)} (the import machinery)")
        elif isinstance(node, ast.Subscript) and _dotted(node.value).endswith(("sys.modules", "__builtins__")):
            add(f"indexes {_dotted(node.value)}")
        elif isinstance(node, ast.Attribute) and node.attr in _SUSPICIOUS_ATTRIBUTES:
            add(f"uses .{node.attr}")
        elif isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                if isinstance(target, ast.Attribute):
                    owner = _dotted(target.value)
                    if owner.split(".")[0] in ("np", "numpy", "cvkit", "sys", "os", "builtins", "math"):
                        add(f"monkeypatches {owner}.{target.attr}")
                if isinstance(target, ast.Name) and target.id in _GRADER_NAMES:
                    add(f"rebinds the grader's name {target.id!r}")
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.name in _GRADER_NAMES:
            add(f"redefines the grader's {node.name}()")
        elif isinstance(node, ast.Global) and any(n in _GRADER_NAMES for n in node.names):
            add("rebinds a grader name through `global`")
    return flags


# ---------------------------------------------------------------------------- grading
def submission_version(notebook: Any, source_notebook: Any = None) -> str:
    """A digest of the code a student wrote in ``notebook`` (:func:`worker_cells`): the
    *version* of a submission that its hidden cases are drawn for. Regrading the same code
    draws the same cases; any change to it draws new ones."""
    digest = hashlib.sha256()
    for source in worker_cells(notebook, source_notebook):
        digest.update(source.encode("utf-8", "surrogatepass"))
        digest.update(b"\x1e")
    return digest.hexdigest()[:32]


def grade_notebook(notebook: Any, *, student: str, salt: str, source_notebook: Any = None,
                   memory_mb: int = 3072, total_seconds: float | None = None) -> NotebookGrade:
    """Decide every check of ``notebook`` in an isolated worker; see the module docstring.

    Each check call's cases are drawn once (:func:`_draw_cases`), for this student and this
    version of their code (:func:`submission_version`); the sandbox runs them, and the same
    cases are evaluated here, run again for a cascade and read by the hard-coding rule. The
    visible cases of every exercise run before any hidden case, and what a student sees of a
    hidden case is cut to what is theirs (:func:`hidden_view`). The whole deciding run, the
    cascade included, has ``total_seconds`` (default
    :func:`~cvkit.sandbox.session.notebook_seconds`).
    """
    deadline = time.monotonic() + (notebook_seconds() if total_seconds is None else float(total_seconds))
    tests_from = source_notebook if source_notebook is not None else notebook
    calls: list[CheckCall] = []
    for cell in cells_of(tests_from):
        if is_test_cell(cell):
            calls += check_calls(cell_source(cell), nbgrader_metadata(cell).get("grade_id", ""))
    result = NotebookGrade()
    original: set[str] = set()
    if source_notebook is not None:
        original = {cell_source(c).strip() for c in cells_of(source_notebook)}
    for cell in cells_of(notebook):  # the student's code only: answers and cells they added
        meta = nbgrader_metadata(cell)
        if not is_code(cell):
            continue
        if is_solution(cell) or (not meta and source_notebook is not None and cell_source(cell).strip() not in original):
            result.flags += scan(cell_source(cell), meta.get("grade_id") or "added cell")
    if not calls:
        return result

    cells = worker_cells(notebook, source_notebook)
    version = submission_version(notebook, source_notebook)
    plans = [_plan(call, student, salt, version, cells) for call in _public_first(_building_blocks_first(calls))]
    blocks = tuple(sorted({block for plan in plans for block in plan.spec.allowed}))
    outcome = run_calls(cells, [request for plan in plans for request in plan.requests], blocks=blocks,
                        memory_mb=memory_mb, deadline=deadline)
    result.worker_problem = outcome.crashed
    result.cell_errors = outcome.cell_errors
    result.sandboxed = outcome.sandboxed
    result.flags += [f"(notebook): {refused}" for refused in outcome.refused]
    result.flags += [f"(notebook): {error}" for error in outcome.cell_errors
                     if "was stopped" in error or "ended early" in error or "killed" in error or "out of turn" in error]
    reports = _evaluate_plans(plans, outcome.outcomes)
    exhausted = outcome.exhausted or _cascades(plans, reports, result, cells, blocks, memory_mb, deadline)
    if exhausted:
        seconds = notebook_seconds() if total_seconds is None else float(total_seconds)
        result.flags.append(f"(notebook): grading stopped after {seconds:g} s in all (the notebook's limit); "
                            "the cases not run by then count as failed")
    telling: dict[str, bool] = {}   # algorithm id -> passes a hidden case that tells something
    for plan, report in zip(plans, reports):
        call = plan.call
        result.reports.setdefault(call.grade_id, []).append((call, report))
        if report.dropped:  # the reference could not compute these cases: never scored, reported
            result.flags.append(f"{call.grade_id}: {len(report.dropped)} case(s) dropped, the reference could not "
                                f"compute them ({report.dropped[0]})")
        if not report.gradable:
            result.flags.append(f"{call.grade_id}: not graded, the reference could not compute any case; "
                                "regrade after fixing the check")
        if call.hidden:
            for case_result in report.cases:
                case = plan.cases[case_result.index] if case_result.index < len(plan.cases) else None
                if case is not None and not _trivial(case, case_result.expected):
                    # a measured case that earned part of its points (Check.credit) did real work
                    # on data the student never saw: that tells too
                    earned = case_result.passed or bool(case_result.credit)
                    telling[call.algorithm_id] = telling.get(call.algorithm_id, False) or earned
    _hard_coding_rule(result, telling)
    return result


@dataclass
class _Plan:
    """One check call: its check, its cases and the sandbox requests that run them."""

    call: CheckCall
    spec: Check
    seed: int | None
    cases: list[Case]               # drawn once (:func:`_draw_cases`)
    keys: list[tuple[int, int]]     # (case index, attempt) of each request
    requests: list[BoxCall]
    cells: list[str] = field(default_factory=list)   # the code the worker ran (for hidden tracebacks)

    def with_reference_blocks(self, substitute: dict[str, str]) -> "_Plan":
        """The same cases, the student's functions named in ``substitute`` (name → algorithm
        id) replaced in the sandbox by the reference building block."""
        return dataclasses.replace(self, requests=[dataclasses.replace(r, substitute=dict(substitute))
                                                   for r in self.requests])

    def report(self, outcomes: Sequence[Outcome | None]) -> Report:
        """The trusted report of these cases, whose requests' outcomes are ``outcomes`` (in order)."""
        found = dict(zip(self.keys, outcomes))

        def runner(index: int, case: Case, attempt: int) -> Outcome | None:
            return found.get((index, attempt))

        # the cases drawn for this plan (a copy: nothing done to them there reaches the
        # requests a cascade sends again); the candidate lives in the sandbox
        report = evaluate(self.call.algorithm_id, hidden=self.call.hidden, seed=self.seed, check=self.spec,
                          runner=runner, cases=copy.deepcopy(self.cases))
        if self.call.hidden:
            names = set(self.requests[0].arg_names) if self.requests else set()
            for case in report.cases:
                outcome = found.get((case.index, 0))
                if outcome is not None:
                    hidden_view(case, outcome, self.cells, self.spec.time_limit, names,
                                refusal=self.cases[case.index].raises)
        return report


def _draw_cases(spec: Check, hidden: bool, seed: int | None) -> list[Case]:
    """The one place where trusted grading draws a check call's cases: the public cases, or
    the hidden cases drawn from ``seed`` and the check's refusals."""
    return spec.graded_hidden_cases(np.random.default_rng(seed)) if hidden else spec.public_cases()


def _plan(call: CheckCall, student: str, salt: str, version: str | None = None, cells: Sequence[str] = ()) -> _Plan:
    record = registry.get(call.algorithm_id)
    spec = record.check
    if spec is None:
        raise ValueError(f"a test cell checks {call.algorithm_id!r}, which has no check")
    seed = hidden_seed(call.algorithm_id, student=student, salt=salt, version=version) if call.hidden else None
    cases = _draw_cases(spec, call.hidden, seed)
    names = tuple(arg_names(record.reference, spec))
    helpers = tuple(served_helpers(call.algorithm_id, tuple(spec.allowed)))
    keys: list[tuple[int, int]] = []
    requests: list[BoxCall] = []
    for index, case in enumerate(cases):
        for attempt in ((0, 1) if spec.seeded and case.raises is None else (0,)):
            keys.append((index, attempt))
            requests.append(BoxCall(
                # one check call: after a case that does not return in time, the sandbox runs none
                # of the call's other cases (the visible and the hidden call are two groups)
                function=call.function,
                group=f"{call.function}:{call.algorithm_id}:{'hidden' if call.hidden else 'visible'}",
                args=case.args, kwargs=case.kwargs,
                time_limit=spec.time_limit, allowed=helpers, arg_names=names,
                forbidden_libraries=tuple(spec.forbidden_libraries) if attempt == 0 else (),
                forbidden_functions=tuple(spec.forbidden) if attempt == 0 else (),
                adapter=(call_target(spec.call) or "").rpartition(":")[2] or None,
            ))
    return _Plan(call, spec, seed, cases, keys, requests, list(cells))


def _evaluate_plans(plans: list[_Plan], outcomes: Sequence[Outcome | None]) -> list[Report]:
    """The reports of ``plans``, whose requests' outcomes are ``outcomes`` (in order)."""
    reports, offset = [], 0
    for plan in plans:
        reports.append(plan.report(outcomes[offset:offset + len(plan.requests)]))
        offset += len(plan.requests)
    return reports


def _cascades(plans: list[_Plan], reports: list[Report], result: NotebookGrade, cells: list[str],
              blocks: tuple[str, ...], memory_mb: int, deadline: float | None = None) -> bool:
    """One mistake costs points once: an exercise that fails while one of its building blocks
    (``filters.pad`` for ``filters.correlate``) is the student's own and fails its own check is
    graded again with the reference building block in its place (the sandbox serves it under
    the student's function name); the better of the two grades counts, and the report says
    which function is to blame."""
    function_of: dict[str, str] = {}
    failing: set[str] = set()
    for plan, report in zip(plans, reports):
        function_of.setdefault(plan.call.algorithm_id, plan.call.function)
        if not report.passed:
            failing.add(plan.call.algorithm_id)
    again = []
    for index, (plan, report) in enumerate(zip(plans, reports)):
        if report.passed or any(case.timed_out for case in report.cases):
            continue  # (a check that did not return is not run again: one time limit per check call)
        culprits = {function_of[block]: block for block in plan.spec.allowed
                    if block in failing and block in function_of and function_of[block] != plan.call.function}
        if culprits:
            again.append((index, culprits))
    if not again:
        return False
    again.sort(key=lambda item: plans[item[0]].call.hidden)  # visible cases first, as in the first run
    student_plans = [plans[i].with_reference_blocks(culprits) for i, culprits in again]  # the same cases
    outcome = run_calls(cells, [r for p in student_plans for r in p.requests], blocks=blocks, memory_mb=memory_mb,
                        deadline=deadline)
    for new_report, (i, culprits) in zip(_evaluate_plans(student_plans, outcome.outcomes), again):
        reports[i] = cascade_report(reports[i], new_report, functions=list(culprits), blocks=list(culprits.values()),
                                    caller=plans[i].call.function)
    return outcome.exhausted


def _building_blocks_first(calls: list[CheckCall]) -> list[CheckCall]:
    """The check calls in notebook order, except that an exercise another one may use as a
    building block is graded first: by the time the sandbox serves ``filters.pad`` to the
    correlation exercise, the padding exercise's own cases are all decided."""
    ordered: list[CheckCall] = []
    remaining = list(calls)
    while remaining:
        for call in remaining:
            allowed = registry.get(call.algorithm_id).check.allowed
            if not any(o.algorithm_id != call.algorithm_id and o.algorithm_id in allowed for o in remaining):
                ordered.append(call)
                remaining.remove(call)
                break
        else:  # a cycle (no check allows its own users): keep the notebook's order
            ordered += remaining
            break
    return ordered


def _public_first(calls: list[CheckCall]) -> list[CheckCall]:
    """The visible checks before every hidden one (each group in its order): code that records
    a hidden case's inputs cannot show them in a visible case's message, which is shown in full."""
    return [call for call in calls if not call.hidden] + [call for call in calls if call.hidden]


_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_.]{0,79}")
_STUDENT_FRAME = re.compile(r'File "<cell (\d+)>", line (\d+), in ([A-Za-z_][A-Za-z0-9_]{0,79}|<module>)')
HIDDEN_MESSAGE_NOTE = ("the message is not shown for hidden cases; the line above is where it was raised — try your "
                       "function on a similar input of your own")


def _safe_name(text: Any, default: str) -> str:
    return text if isinstance(text, str) and _IDENTIFIER.fullmatch(text) else default


_REFERENCE_CALL = re.compile(r"cvkit reference implementation of '([A-Za-z_][A-Za-z0-9_.]{0,79})'")


def _safe_call(text: str) -> str:
    """A forbidden call as the guard names it, if it is a plain dotted name; else a placeholder."""
    found = _REFERENCE_CALL.fullmatch(text)
    if found:
        return f"cvkit reference implementation of {found.group(1)!r}"
    name = text.removeprefix("import ").split(" (")[0]
    return ("import " if text.startswith("import ") else "") + _safe_name(name, "a refused name")


def _own_traceback(text: str | None, cells: Sequence[str], exception: str, timed_out: bool = False) -> str | None:
    """The student's frames of a traceback (cell, line, function and the line's code, taken
    from the cells the grader ran) and the exception's type: nothing the code printed or put in
    a message."""
    frames = _STUDENT_FRAME.findall(text or "")[-6:]
    if not frames:
        return None
    lines = []
    for cell, line, function in frames:
        lines.append(f"  cell {int(cell)}, line {int(line)}, in {function}")
        index, number = int(cell), int(line)
        if 0 <= index < len(cells):
            code = cells[index].splitlines()
            if 1 <= number <= len(code):
                lines.append(f"    {code[number - 1].strip()[:160]}")
    lines.append("stopped here: the time limit was reached" if timed_out else f"{exception} ({HIDDEN_MESSAGE_NOTE})")
    return "\n".join(lines)


def hidden_view(case: CaseResult, outcome: Outcome, cells: Sequence[str], time_limit: float,
                arg_names: set, refusal: str | None = None) -> None:
    """What a student is shown of a failing hidden case, cut to what is theirs: the type of
    their error and the line of their code that raised it, never a message, a print, a
    warning's text or a name their code made up — each could carry a hidden input recorded
    by another exercise. Texts the grader wrote itself (``outcome.from_grader``: a time limit
    measured outside, a worker that died) stay; so do the comparison's own words. A case of
    bad input (``refusal``: the error it requires) that raised another error says which, by a
    safe name."""
    case.stdout = case.stderr = ""
    case.warnings = sorted({_safe_name(str(w).partition(":")[0], "Warning") for w in case.warnings})
    exception = _safe_name(outcome.exception, "an exception")
    if outcome.error is not None and case.message == outcome.error and not outcome.from_grader:
        if outcome.timed_out or outcome.exception == "Timeout":
            # the evidence crossed the boundary as a word of a fixed set and line numbers only,
            # kept to numbers a line of the student's cells can have
            longest = max((len(cell.splitlines()) for cell in cells), default=0)
            lines = [n for n in outcome.loop_lines if 1 <= n <= longest]
            case.message = timeout_message(time_limit, outcome.loop if lines else None, lines)
        elif outcome.exception == "NotImplementedError":
            case.message = "not implemented yet (the function raises NotImplementedError)"
        elif outcome.exception is None:
            case.message = "returned something the grader cannot read (details are not shown for hidden cases)"
        else:
            case.message = f"raised {exception} ({HIDDEN_MESSAGE_NOTE})"
    elif refusal is not None and outcome.error is not None and not case.passed and not outcome.from_grader \
            and not outcome.forbidden_calls:
        case.message = f"raised {exception}, but {refusal_words(refusal, case.label)}"
    elif outcome.forbidden_calls and case.message.startswith("calls "):  # an error too, on a refusal
        names = sorted({_safe_call(str(call)) for call in outcome.forbidden_calls})
        case.message = "calls " + ", ".join(names) + ", which would do the exercise for you: write it with NumPy"
    elif outcome.error is None and outcome.modified and case.message.startswith("modified its input"):
        names = sorted({name for name in outcome.modified if name in arg_names or _IDENTIFIER.fullmatch(str(name))})
        case.message = (f"modified its input {', '.join(map(repr, names)) or 'arguments'}: do not overwrite an "
                        "input; work on a copy or write the result to a new array")
    case.traceback = (_own_traceback(case.traceback, cells, exception, bool(outcome.timed_out))
                      if case.traceback else None)


def _trivial(case, expected) -> bool:
    """A case whose answer can be given without computing anything: ``None`` ("no board
    found"), a zero or ``False``, an all-zero output, or an output equal to one of the inputs (a
    flat image, a size-1 filter)."""
    def same(a, b) -> bool:
        try:
            a, b = np.asarray(a), np.asarray(b)
            return a.shape == b.shape and a.dtype.kind in "biuf" and b.dtype.kind in "biuf" and bool(np.array_equal(a, b))
        except Exception:  # noqa: BLE001 - objects that do not compare are not trivial
            return False

    if expected is None:
        return True
    if isinstance(expected, (bool, int, float, np.bool_, np.integer, np.floating)) and expected == 0:
        return True
    if isinstance(expected, np.ndarray) and expected.dtype.kind in "biuf" and expected.size > 0:
        if not np.any(expected):
            return True
        return any(same(expected, arg) for arg in list(case.args) + list(case.kwargs.values())
                   if isinstance(arg, np.ndarray))
    return False


def _hard_coding_rule(result: NotebookGrade, telling: dict[str, bool]) -> None:
    """A function that passes the public cases but none of the hidden cases that tell anything
    (see :func:`_trivial`; a hidden case of a measured check that earned part of its credit
    counts as passed here) has most likely memorised the public answers: its visible test gets
    no credit either, nor do the trivial hidden cases it passed, and it is flagged. Trivial hidden
    cases count only beside one that tells something in any case: ``return None`` passes every
    "no board found" case of a corner finder, and proves nothing."""
    memorised = {call.algorithm_id for entries in result.reports.values() for call, report in entries
                 if not call.hidden and report.passed and telling.get(call.algorithm_id) is False}
    for entries in result.reports.values():
        for call, report in entries:
            if call.algorithm_id not in memorised:
                continue
            for case in report.cases:
                if case.passed:
                    case.passed = False
                    case.message = ("passes the shown cases but none of the hidden ones that tell anything: the "
                                    "answers of the shown cases look memorised")
            if not call.hidden:
                result.flags.append(f"{call.grade_id}: passes only the public cases ({call.algorithm_id})")
    for entries in result.reports.values():
        for call, report in entries:
            if not call.hidden or call.algorithm_id in memorised or telling.get(call.algorithm_id) is not False:
                continue
            for case in report.cases:  # every case passed here is a trivial one
                if case.passed:
                    case.passed = False
                    case.message = ("passes, but its answer needs no computing (None, zero or one of the inputs): "
                                    "such a case counts only beside a hidden case that tells something, and this "
                                    "function passes none")


_HIDDEN_BLOCK = re.compile(r"### BEGIN HIDDEN TESTS.*?### END HIDDEN TESTS\n?", re.S)


def hide_hidden_tests(source: str) -> str:
    """Test-cell source as shown in feedback: the hidden block replaced by a note."""
    return _HIDDEN_BLOCK.sub("# (hidden tests: their results are shown below)\n", source)


__all__ = ["CheckCall", "NotebookGrade", "check_calls", "worker_cells", "scan", "grade_notebook",
           "hide_hidden_tests", "hidden_view", "submission_version", "Report"]


# ------------------------------------------------------------------ the verdicts in the notebook
def cell_report(grade_id: str, entries: list[tuple[CheckCall, Report]], points: float, credit: float,
                flags: list[str]) -> dict[str, Any]:
    """The trusted verdicts of one test cell as data: what :func:`apply_trusted_checks` stores in
    the cell's ``metadata.cvkit.report`` and the course's results read (JSON-ready).

    Parameters
    ----------
    grade_id : str
        The test cell's grade id.
    entries : list of (CheckCall, Report)
        Its ``check(...)`` calls and their trusted reports, in order.
    points, credit : float
        The cell's points and the credit it earned.
    flags : list of str
        The notebook's flags (``"<grade id>: <what>"``); the cell keeps its own.

    Returns
    -------
    dict
        ``points``, ``credit``, ``checks`` (per call: :meth:`Report.verdict` and the graded
        ``function``) and ``flags`` (what was flagged on this cell).
    """
    own = f"{grade_id}: "
    return {
        "points": points,
        "credit": credit,
        "checks": [dict(report.verdict(), function=call.function) for call, report in entries],
        "flags": [flag[len(own):] for flag in flags if flag.startswith(own)],
    }


def apply_trusted_checks(nb: Any, *, student: str, salt: str, source_notebook: Any = None,
                         memory_mb: int = 3072) -> list[str]:
    """Decide every check of ``nb`` (a NotebookNode) outside the student's kernel and put the
    verdicts in place: each test cell's outputs become the trusted reports and its credit
    (an error for a failed visible test, the partial credit of a hidden one), which is what
    nbgrader's ``SaveAutoGrades`` records. The same verdicts travel as data in the cell's
    ``metadata.cvkit.report`` (:func:`cell_report`; any ``cvkit`` metadata a cell brought along
    is dropped first), which the course's results read; the notebook is marked
    ``metadata.cvkit.reports_in_cells``. Returns the flags of the static scan, which also go
    into ``nb.metadata.cvkit``. Used by the parallel phase of :meth:`cvkit.course.Course.grade`
    and by :class:`~cvkit.course.nbgrader_plugins.TrustedChecks` in nbgrader's own autograde."""
    # only the trusted grader writes cvkit metadata: whatever the submission brought along
    # (a forged report, flags, an "unsandboxed_note" that would hide the banner) is dropped
    nb.metadata.pop("cvkit", None)
    nb.cells = [cell for cell in nb.cells if not _is_banner(cell)]
    grade = grade_notebook(nb, student=student, salt=salt, source_notebook=source_notebook, memory_mb=memory_mb)
    for cell in nb.cells:
        cell.metadata.pop("cvkit", None)  # only the trusted grader writes there
        grade_id = cell.metadata.get("nbgrader", {}).get("grade_id")
        if not is_test_cell(cell) or grade_id not in grade.reports:
            continue
        entries = grade.reports[grade_id]
        outputs = [new_output("display_data", data=report.mime_bundle()) for _, report in entries]
        points = float(cell.metadata["nbgrader"].get("points", 0))
        credit, reasons = grade.credit(grade_id, points)
        hidden = any(call.hidden for call, _ in entries)
        if hidden:
            outputs.append(new_output("execute_result", data={"text/plain": repr(credit)},
                                      execution_count=cell.get("execution_count")))
        elif credit <= 0:
            message = "; ".join(reasons) or "failed"
            outputs.append(new_output("error", ename="AssertionError", evalue=message,
                                      traceback=[f"AssertionError: {message}"]))
        cell.outputs = outputs
        cell.metadata["cvkit"] = {"report": cell_report(grade_id, entries, points, credit, grade.flags)}
    if not grade.sandboxed:
        from nbformat.v4 import new_markdown_cell

        nb.cells.insert(0, new_markdown_cell(UNSANDBOXED_BANNER))
    nb.metadata["cvkit"] = dict(trusted=True, flags=grade.flags, worker_problem=grade.worker_problem,
                                cell_errors=grade.cell_errors[:20], sandboxed=grade.sandboxed,
                                unsandboxed_note=not grade.sandboxed, reports_in_cells=True)
    return list(grade.flags)


#: the first cell of a notebook graded with ``--no-sandbox`` (put there by :func:`apply_trusted_checks`)
UNSANDBOXED_BANNER = (
    "**⚠ Graded without the sandbox** (`cvkit course grade --no-sandbox`): your code ran with the "
    "grader's rights on the grading machine. Ask your instructor if this is unexpected.")


def _is_banner(cell: Any) -> bool:
    """The banner of an earlier grading (or the student's copy of it): replaced by a fresh one."""
    return cell.get("cell_type") == "markdown" and cell_source(cell).strip() == UNSANDBOXED_BANNER
