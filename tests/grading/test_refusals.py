"""Cases of bad input (``Check.refusals``): a hidden case passes only when the function raises
the error the catalog names for that input.

Proved here: in the student's kernel (:func:`evaluate`) and in trusted grading (the candidate in
the sandbox, the verdict outside), a function that raises the error (or a subclass: NumPy's
``LinAlgError`` is a ``ValueError``) passes; one that returns a result, raises another error or
is still the stub fails, with the case's label in the message and nothing of the student's own
error text in a hidden report; the visible test never runs them; a refusal the reference does
not raise is dropped as the check's fault; the outcome carries the error's kinds across the
sandbox boundary and nothing else. Every check's refusals are raised by its reference and fail
the released stub.
"""
import dataclasses
import textwrap

import numpy as np
import pytest

from cvkit import registry
from cvkit.grading import Case
from cvkit.grading.engine import evaluate
from cvkit.grading.runtime.guard import Outcome
from cvkit.course.trusted import grade_notebook, hidden_view
from test_trusted import _code  # a notebook cell with nbgrader's metadata

TOP_K = "learn.top_k_accuracy"


def _top_k(scores, y, k):
    s = np.asarray(scores, dtype=float)
    y = np.asarray(y)
    kth = -np.sort(-s, axis=1)[:, k - 1]
    return float(np.mean(s[np.arange(len(y)), y] >= kth))


def refuses(scores, y, k=5):
    if k > np.asarray(scores).shape[1]:
        raise ValueError(f"k must be at most the number of classes, got {k}")
    return _top_k(scores, y, k)


def refuses_by_subclass(scores, y, k=5):
    if k > np.asarray(scores).shape[1]:
        raise np.linalg.LinAlgError("k too large")  # a ValueError
    return _top_k(scores, y, k)


def clips_k(scores, y, k=5):
    return _top_k(scores, y, min(k, np.asarray(scores).shape[1]))


def wrong_error(scores, y, k=5):
    if k > np.asarray(scores).shape[1]:
        raise IndexError("secret 1234 from another exercise")
    return _top_k(scores, y, k)


def stub(scores, y, k=5):
    raise NotImplementedError


def _hidden(function):
    report = evaluate(TOP_K, function, hidden=True, seed=7)
    refusal = [c for c in report.cases if "classes" in c.label and c.label.startswith("k = ")]
    assert len(refusal) == 1, [c.label for c in report.cases]
    return report, refusal[0]


@pytest.mark.parametrize("function", [refuses, refuses_by_subclass])
def test_raising_the_named_error_passes(function):
    report, refusal = _hidden(function)
    assert refusal.passed and report.passed and not report.dropped


@pytest.mark.parametrize("function, words", [
    (clips_k, "returned a result, but this input must raise ValueError (k = 5 with 4 classes)"),
    (wrong_error, "raised IndexError, but this input must raise ValueError (k = 5 with 4 classes)"),
])
def test_returning_or_raising_another_error_fails_that_case_only(function, words):
    report, refusal = _hidden(function)
    assert not refusal.passed and refusal.message.startswith(words), refusal.message
    assert "secret" not in refusal.message
    others = [c for c in report.cases if c is not refusal]
    assert others and all(c.passed for c in others)
    assert report.score == pytest.approx(len(others) / len(report.cases))


def test_the_stub_fails_the_refusal_too():
    _, refusal = _hidden(stub)
    assert not refusal.passed and "NotImplementedError" in refusal.message


def test_the_visible_test_never_runs_a_refusal():
    report = evaluate(TOP_K, clips_k)
    assert report.passed and not any(c.label.startswith("k = 5 with") for c in report.cases)


def test_a_refusal_the_reference_does_not_raise_is_dropped():
    fine = Case((np.eye(3), np.arange(3)), {"k": 1}, "a valid input", raises="ValueError")
    report = evaluate(TOP_K, refuses, hidden=True, seed=1, cases=[fine, Case((np.eye(3), np.arange(3)), {"k": 2})])
    assert report.dropped == ["case 1 (a valid input): the reference does not raise ValueError on this case of "
                              "bad input"]
    assert [c.passed for c in report.cases] == [True]


def test_a_check_refuses_refusals_without_a_known_error():
    spec = registry.get(TOP_K).check
    with pytest.raises(ValueError, match="refusals"):
        dataclasses.replace(spec, refusals=[Case((np.eye(3), np.arange(3)), {"k": 4})])
    with pytest.raises(ValueError, match="refusals"):
        dataclasses.replace(spec, refusals=[Case((np.eye(3), np.arange(3)), {"k": 4}, raises="KeyError")])


def test_the_error_kinds_cross_the_boundary_and_nothing_else():
    sent = Outcome(error="raised LinAlgError: x", exception="LinAlgError", raised_as=["ValueError"])
    assert Outcome.from_json(sent.to_json()).raised_as == ["ValueError"]
    forged = {**sent.to_json(), "raised_as": ["ValueError", "KeyError", {"x": 1}, "TypeError" * 3]}
    assert Outcome.from_json(forged).raised_as == ["ValueError"]
    assert Outcome.from_json({**sent.to_json(), "raised_as": "ValueError"}).raised_as == []


def test_a_hidden_report_names_the_wrong_error_safely():
    from cvkit.grading.report import CaseResult

    case = CaseResult(index=0, label="k = 5 with 4 classes", description="", passed=False,
                      message="raised Secret_1234, but …")
    outcome = Outcome(error="raised Secret_1234: the hidden image was 0.25", exception="Secret_1234", raised_as=[])
    hidden_view(case, outcome, cells=[], time_limit=1.0, arg_names=set(), refusal="ValueError")
    assert "0.25" not in case.message and case.message.endswith(
        "but this input must raise ValueError (k = 5 with 4 classes), with a message that names the argument")


def _checks_with_refusals():
    return [(a.id, a.check) for a in registry.algorithms() if a.check is not None and a.check.refusals]


def test_the_catalog_errors_are_graded():
    assert {aid for aid, _ in _checks_with_refusals()} >= {
        "edges.hysteresis", "features.gaussian_pyramid", "features.refine_extremum", "features.match_ratio",
        "detection.shape_model", "camera.decompose_projection", "calibration.intrinsics_from_homographies",
        "learn.top_k_accuracy", "learn.kmeans"}


@pytest.mark.parametrize("algorithm_id", [aid for aid, _ in _checks_with_refusals()])
def test_every_refusal_is_raised_by_the_reference_and_failed_by_the_stub(algorithm_id):
    record = registry.get(algorithm_id)
    spec = record.check
    report = evaluate(algorithm_id, record.reference, hidden=True, seed=3, cases=list(spec.refusals))
    assert not report.dropped and len(report.cases) == len(spec.refusals) and report.passed

    def released_stub(*args, **kwargs):
        raise NotImplementedError

    report = evaluate(algorithm_id, released_stub, hidden=True, seed=3, cases=list(spec.refusals))
    assert not any(c.passed for c in report.cases)


# ---------------------------------------------------------------------------------------------
# trusted grading: the candidate runs in the sandbox, the verdict is made outside
# ---------------------------------------------------------------------------------------------
SETUP = textwrap.dedent("""\
    import numpy as np
    from cvkit.grading import check
    from cvkit.registry import student
    """)


def _answer(function):
    import inspect

    helper = inspect.getsource(_top_k)
    body = inspect.getsource(function).replace(f"def {function.__name__}(", "def top_k_accuracy(")
    return f'{helper}\n\n@student("{TOP_K}")\n{body}'


def _notebook(answer):
    cells = [_code(SETUP, "setup"), _code(answer, "top_k_answer", solution=True),
             _code(f'check("{TOP_K}", top_k_accuracy)', "top_k_visible", grade=True, points=1),
             _code(f'### BEGIN HIDDEN TESTS\ncheck("{TOP_K}", top_k_accuracy, hidden=True, points=2)\n'
                   '### END HIDDEN TESTS', "top_k_hidden", grade=True, points=2)]
    return {"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5}


def test_trusted_grading_judges_refusals_in_the_sandbox():
    source = _notebook(_answer(refuses))
    credits = {}
    for function in (refuses, refuses_by_subclass, clips_k, wrong_error):
        result = grade_notebook(_notebook(_answer(function)), student="ada", salt="refusals", source_notebook=source)
        credits[function.__name__] = (result.credit("top_k_visible", 1)[0], result.credit("top_k_hidden", 2)[0])
        hidden = [c for _, r in result.reports["top_k_hidden"] for c in r.cases]
        refusal = [c for c in hidden if c.label == "k = 5 with 4 classes"]
        assert len(refusal) == 1
        assert refusal[0].passed == (function in (refuses, refuses_by_subclass)), refusal[0].message
        # the student's own line may show (it is theirs), the error's message never does
        assert "secret" not in refusal[0].message and ": secret" not in (refusal[0].traceback or "")
    count = len(hidden)
    assert credits["refuses"] == credits["refuses_by_subclass"] == (1, 2)
    assert credits["clips_k"] == credits["wrong_error"] == (1, pytest.approx(2 * (count - 1) / count))


def test_a_passing_visible_test_notes_a_missing_refusal_without_failing():
    report = evaluate(TOP_K, clips_k)
    assert report.passed
    assert any(note.startswith("passes the shown cases, but the hidden test also gives k = 5 with 4 classes, where "
                               "your function must raise ValueError; it returns a result") for note in report.notes), \
        report.notes
    assert not any("k = 5 with 4 classes" in note for note in evaluate(TOP_K, refuses).notes)
    assert any("it raises IndexError" in note for note in evaluate(TOP_K, wrong_error).notes)


def test_a_hidden_refusal_that_called_a_forbidden_function_names_it_safely():
    from cvkit.grading.report import CaseResult

    case = CaseResult(index=0, label="k = 5 with 4 classes", description="", passed=False,
                      message="calls sklearn.metrics.top_k_accuracy_score, secret 0.25, which would do …")
    outcome = Outcome(error="raised ValueError: bad k", exception="ValueError", raised_as=["ValueError"],
                      forbidden_calls=["sklearn.metrics.top_k_accuracy_score, secret 0.25"])
    hidden_view(case, outcome, cells=[], time_limit=1.0, arg_names=set(), refusal="ValueError")
    assert case.message.startswith("calls ") and "0.25" not in case.message, case.message
