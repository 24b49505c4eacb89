"""A function that does not return (issue #35, item 3): the check stops at the first case that
runs out of time, says where the code was stopped and gives the advice that fits what it saw,
and runs none of the remaining cases to their limits — in the student's kernel and in the
sandbox of the trusted grader.

What the grader saw decides the advice: stopped inside a ``while`` loop (a loop that may never
end) → "look at your loop's exit condition"; stopped inside ``for`` loops only (they always end:
the code is merely slow, a loop over pixels) → "vectorize". No assertion here is about time:
every test counts calls and reads messages (the limits are shortened so the suite stays fast).
"""
import dataclasses
import textwrap

import numpy as np
import pytest

from cvkit import registry
from cvkit.grading import CheckFailed, check
from cvkit.sandbox import session as sandbox
from cvkit.grading.engine import evaluate
from cvkit.grading.runtime.guard import Outcome, run_guarded, timeout_message
from cvkit.grading.runtime.wire import BoxCall

CALLS: list = []


def endless_gaussian(image, sigma, border="reflect101"):
    """A vectorised loop that never ends (its exit condition is never met)."""
    CALLS.append("gaussian")
    out = np.asarray(image, dtype=float).copy()
    change = 1.0
    while change > -1.0:  # always true
        smoothed = 0.5 * (out + np.roll(out, 1, axis=0))
        change = float(np.abs(smoothed - out).max())
        out = smoothed
    return out


def slow_gaussian(image, sigma, border="reflect101"):
    """A loop over pixels that ends, but far too late."""
    CALLS.append("gaussian")
    image = np.asarray(image, dtype=float)
    out = np.zeros_like(image)
    for r in range(image.shape[0]):
        for c in range(image.shape[1]):
            for _ in range(10**7):  # a huge window, one product at a time
                out[r, c] += 0.0
    return out


def _line(function, text):
    """The line number of the line of ``function``'s source starting with ``text``."""
    import inspect

    lines, first = inspect.getsourcelines(function)
    return first + next(i for i, line in enumerate(lines) if line.strip().startswith(text))


@pytest.fixture
def quick_gaussian():
    """The Gaussian check with a 1-second limit per case (the loops below never end or take hours)."""
    record = registry.get("filters.gaussian")
    original = record.check
    record._check = dataclasses.replace(original, time_limit=1.0)
    CALLS.clear()
    yield record._check
    record._check = original


def test_an_endless_loop_stops_the_check_at_the_first_timeout(quick_gaussian):
    report = evaluate("filters.gaussian", endless_gaussian)
    assert CALLS == ["gaussian"], "the candidate ran once: the other cases were not run to their limits"
    assert len(report.cases) >= 3 and report.score == 0
    first, rest = report.cases[0], report.cases[1:]
    line = _line(endless_gaussian, "while change")
    assert first.timed_out and first.message == (
        f"did not return within 1 s: look at your loop's exit condition (it was still in the `while` loop of "
        f"line {line} when it was stopped)")
    assert "vectorize" not in first.message
    # where it was stopped: the student's own line ends the traceback's frames
    frames = [l for l in first.traceback.splitlines() if l.strip().startswith("File ")]
    assert frames and "in endless_gaussian" in frames[-1]
    for case in rest:
        assert not case.passed and not case.timed_out
        assert case.message.startswith("not run: case 1 did not return within 1 s"), case.message


def test_a_slow_loop_over_pixels_is_told_to_vectorize(quick_gaussian):
    report = evaluate("filters.gaussian", slow_gaussian)
    assert CALLS == ["gaussian"]
    message = report.cases[0].message
    lines = [_line(slow_gaussian, text) for text in ("for r in", "for c in", "for _ in")]
    assert message.startswith("did not return within 1 s: it was still in the `for` loops of lines "
                              f"{lines[0]}, {lines[1]} and {lines[2]}"), message
    assert "vectorize with NumPy" in message and "exit condition" not in message
    assert all(c.message.startswith("not run:") for c in report.cases[1:])


def test_the_notebooks_check_blocks_the_kernel_for_one_time_limit_only(quick_gaussian, monkeypatch):
    """``check()`` as a test cell calls it: one call of the candidate, even when the candidate
    uses the student's own (wrong) building block, which would otherwise have it graded again
    with the reference block (:func:`cvkit.grading.engine._with_reference_building_blocks`)."""
    def wrong_kernel(sigma, radius=None):
        return np.ones(3)

    monkeypatch.setitem(registry.provider("student").functions, "filters.gaussian_kernel", wrong_kernel)
    monkeypatch.setitem(globals(), "gaussian_kernel", wrong_kernel)

    def gaussian(image, sigma, border="reflect101"):
        gaussian_kernel(sigma)  # noqa: F821  (the student's own building block, a global of this module)
        return endless_gaussian(image, sigma, border)

    assert not evaluate("filters.gaussian_kernel", wrong_kernel).passed  # the cascade's condition holds
    with pytest.raises(CheckFailed):
        check("filters.gaussian", gaussian)
    assert CALLS == ["gaussian"]
    assert check("filters.gaussian", gaussian, hidden=True) == 0.0
    assert CALLS == ["gaussian", "gaussian"]


def test_the_evidence_crosses_the_wire_as_data_only():
    outcome = Outcome(error="did not return", exception="Timeout", timed_out=True, loop="while", loop_lines=[4])
    back = Outcome.from_json(outcome.to_json())
    assert (back.loop, back.loop_lines) == ("while", [4])
    forged = dict(outcome.to_json(), loop="<script>", loop_lines=[4])
    assert Outcome.from_json(forged).loop is None
    forged = dict(outcome.to_json(), loop="for", loop_lines=["line 4; rm -rf", 3.5, -1, 10**9, 7])
    assert Outcome.from_json(forged).loop_lines == [7]


def test_no_loop_around_the_line_gives_both_pieces_of_advice():
    def sleepy():
        import time

        time.sleep(30)

    outcome = run_guarded(sleepy, (), {}, time_limit=0.3, watch_reference=False)
    assert outcome.timed_out and outcome.loop is None
    assert outcome.error == timeout_message(0.3) and "exit condition" in outcome.error and "vectorize" in outcome.error


def test_the_sandbox_runs_no_other_case_of_a_check_after_a_timeout():
    cells = [textwrap.dedent("""\
        import numpy as np

        def f(x):
            while x.sum() >= 0:
                x = x + 1
            return x

        def g(x):
            return x * 2
        """)]
    one = BoxCall("f", group="f:visible", args=(np.ones(2),), time_limit=1.0)
    calls = [one, one, one, dataclasses.replace(one, group="f:hidden"),
             dataclasses.replace(one, function="g", group="g:visible")]
    result = sandbox.run_calls(cells, calls)
    first, skipped, other_call, other_function = result.outcomes[0], result.outcomes[1:3], *result.outcomes[3:]
    assert first.timed_out and (first.loop, first.loop_lines) == ("while", [4]), (first.error, first.loop)
    assert "exit condition" in first.error and "line 4" in first.error
    lines = first.traceback.splitlines()
    last_frame = max(i for i, line in enumerate(lines) if line.strip().startswith("File "))
    assert lines[last_frame].strip() == 'File "<cell 0>", line 4, in f' and lines[last_frame + 1].strip() == \
        "while x.sum() >= 0:", first.traceback
    for outcome in skipped:
        assert outcome.exception == "NotRun" and outcome.error.startswith("not run: an earlier case did not return")
    assert other_call.timed_out  # the hidden check of the same function has its own (one) time limit
    assert other_function.ok and list(other_function.value) == [2.0, 2.0]



def test_a_hidden_case_that_did_not_return_gets_the_same_advice():
    """What crosses the sandbox's boundary of a hidden case is cut to what is the student's;
    the advice is rebuilt from the evidence (a word of a fixed set and line numbers)."""
    from cvkit.grading.report import CaseResult
    from cvkit.course.trusted import hidden_view

    cells = ["import numpy as np", "def f(a):\n    while True:\n        a = a + 1"]
    outcome = Outcome(error="did not return within 20 s: …", exception="Timeout", timed_out=True, loop="while",
                      loop_lines=[2], traceback='  File "<cell 1>", line 3, in f\nstopped here: the time limit was reached')
    case = CaseResult(0, "case", "input", False, message=outcome.error, traceback=outcome.traceback)
    hidden_view(case, outcome, cells, 20.0, {"a"})
    assert case.message == timeout_message(20.0, "while", [2])
    assert case.traceback.splitlines() == ["  cell 1, line 3, in f", "    a = a + 1",
                                           "stopped here: the time limit was reached"]
