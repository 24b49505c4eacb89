"""Shared assertions for the **measured** checks (``Check(credit=...)``, cases of
:class:`cvkit.grading.measured.MeasuredCase`): the notebook publishes the scale and the budget
the check applies, the reference clears the top of the scale, each mistake of the bank earns
less than full credit, a stub earns nothing, a result between the corners earns the scale's
share, and the hidden data differ per student while their truth never enters the sandbox.

Every function takes what differs between exercises (the scale, the measure, the seeds) as an
argument. ``tests/`` is not a package: import this module as the test files import
``checks_harness``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from cvkit.grading import evaluate, hidden_seed
from cvkit.grading.measured import MeasuredCase

try:
    from . import checks_harness as harness
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    import checks_harness as harness

LECTURES = Path(__file__).resolve().parents[2] / "lectures"


def notebook_of(chapter):
    """The source notebook of ``chapter`` ("ch04_edges")."""
    return LECTURES / chapter / f"{chapter}.ipynb"


def case_of(algorithm_id, report, result):
    """The case a result of ``report`` was computed on (its truth included)."""
    spec = harness.check_of(algorithm_id)
    cases = spec.hidden_cases(np.random.default_rng(report.seed)) if report.hidden else spec.public_cases()
    return cases[result.index]


def measured(algorithm_id, candidate, seeds, measure):
    """``[(report, [measurement of each case])]`` of ``candidate`` graded on the public cases and
    the hidden cases of every seed."""
    return [(report, [measure(result.got, case_of(algorithm_id, report, result)) for result in report.cases])
            for report in harness.grade_everywhere(algorithm_id, candidate, seeds)]


def assert_notebook_publishes(chapter, algorithm_id, function, scale, measured_words, budget):
    """The statement of ``function`` in the chapter's notebook gives the check's scale (its
    table, with the hidden test's points) and the check's time budget in seconds."""
    spec = harness.check_of(algorithm_id)
    assert spec.time_limit == budget
    cells = json.loads(notebook_of(chapter).read_text())["cells"]
    name = function.split("(")[0]
    statements = ["".join(c["source"]) for c in cells
                  if c["cell_type"] == "markdown" and f"`{function}`" in "".join(c["source"])]
    assert len(statements) == 1, f"one statement names `{function}`"
    (hidden,) = [c for c in cells if c.get("metadata", {}).get("nbgrader", {}).get("grade_id") == f"{name}_hidden"]
    points = hidden["metadata"]["nbgrader"]["points"]
    assert f"points={points})" in "".join(hidden["source"])
    lines = [line.strip() for line in statements[0].splitlines()]
    for row in scale.table(measured_words, points).splitlines():
        assert row in lines, f"the statement lacks the scale's row {row!r}"
    assert f"**{budget:g} seconds**" in statements[0]


def assert_clears_the_top(algorithm_id, seeds, measure, scale, candidate=None):
    """``candidate`` (default: the reference) passes every case with full credit, at or above
    the top of the scale."""
    candidate = harness.reference_of(algorithm_id) if candidate is None else candidate
    for report, values in measured(algorithm_id, candidate, seeds, measure):
        assert report.passed and report.score == 1.0, report.text()
        assert [case.credit for case in report.cases] == [1.0] * len(report.cases)
        assert min(values) >= scale.top, values


def assert_reports_advise(algorithm_id, advice, seed=101):
    """``advice``: mistake name → words that every hidden case's report of that mistake holds."""
    for name, words in advice.items():
        report = evaluate(algorithm_id, harness.check_of(algorithm_id).mistake(name).function, hidden=True, seed=seed)
        assert all(words in case.message for case in report.cases), report.text()


def same_input_and_truth(a, b):
    """Whether two cases of one input argument hold the same input and the same truth."""
    return np.array_equal(a.args[0], b.args[0]) and np.array_equal(a.truth, b.truth)


def shifting_labels(train, share):
    """A candidate that trains like ``train`` and moves the first ``share`` of its predicted
    labels to the next class (between the corners of an accuracy scale)."""
    def candidate(x_train, y_train, rng=None):
        predict = train(x_train, y_train, rng)

        def spoiled(x):
            labels = np.array(predict(x))
            labels[:int(share * len(labels))] += 1
            return labels % 10
        return spoiled
    return candidate


def assert_below_full_credit(algorithm_id, candidate, seeds, measure, scale, words):
    """``candidate`` fails every hidden case below the top of the scale and earns less than
    full credit there; its reports say where the top is (``words``: the measurement's name)."""
    for report, values in measured(algorithm_id, candidate, seeds, measure):
        if not report.hidden:
            continue
        assert not report.passed and report.score < 1.0, report.text()
        for case, value in zip(report.cases, values):
            assert value < scale.top and np.isclose(case.credit, scale.credit(value)) and case.credit < 1.0, (value, case.message)
            assert f"{words} " in case.message and f"below {scale.show(scale.top)}, the top of the scale" in case.message


def assert_measures_what_it_should(algorithm_id, seeds, measure, scale, words, alternatives=()):
    """The whole bar of a measured check: the reference and each correct alternative clear the
    top of the scale, each mistake of the bank earns less than full credit (``words``: the
    measurement's name in the reports), and a stub earns nothing."""
    for candidate in (None, *alternatives):
        assert_clears_the_top(algorithm_id, seeds, measure, scale, candidate)
    for wrong in harness.check_of(algorithm_id).bank:
        assert_below_full_credit(algorithm_id, wrong.function, seeds, measure, scale, words)
    harness.assert_stub_scores_zero(algorithm_id, seeds)


def assert_partial_credit_follows_the_scale(algorithm_id, candidate, seed, measure, scale):
    """A hidden case between the corners earns the scale's share of its measurement."""
    (report, values), = measured(algorithm_id, candidate, (seed,), measure)[1:]
    for case, value in zip(report.cases, values):
        assert scale.bottom < value < scale.top, value
        assert 0.0 < case.credit < 1.0 and np.isclose(case.credit, scale.credit(value)), case.message
    assert np.isclose(report.score, np.mean([scale.credit(v) for v in values]))


def assert_hidden_data_differ_and_truth_stays_outside(algorithm_id, same_data):
    """Two students draw different hidden data, each reproducibly; every hidden case is a
    :class:`MeasuredCase` whose truth is nowhere among the arguments the candidate receives.
    ``same_data(case_a, case_b)`` says whether two cases hold the same data."""
    spec = harness.check_of(algorithm_id)
    drawn = []
    for student in ("student-a", "student-b"):
        seed = hidden_seed(algorithm_id, student=student, salt="course-salt")
        cases, again = spec.hidden_cases(np.random.default_rng(seed)), spec.hidden_cases(np.random.default_rng(seed))
        assert all(same_data(a, b) for a, b in zip(cases, again))
        for case in cases:
            assert isinstance(case, MeasuredCase) and not case.kwargs
            truth = np.asarray(case.truth)
            assert truth.size
            assert not any(isinstance(arg, np.ndarray) and arg.shape == truth.shape and np.array_equal(arg, truth)
                           for arg in case.args)
        drawn.append(cases)
    assert not any(same_data(a, b) for a, b in zip(*drawn))
