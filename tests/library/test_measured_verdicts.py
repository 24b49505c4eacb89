"""A measured check judges what an output achieves on its case, never its agreement with the
reference (``Comparator.judges_alone``); so the grader runs no mistake of the bank to name a
failing output of a measured exercise (the bank of ``train.train_digits`` is two trainings)."""
import numpy as np
import pytest

from cvkit import registry
from cvkit.grading import engine, evaluate

MEASURED = [a.id for a in registry.algorithms() if a.check is not None and a.check.credit is not None]


def test_every_measured_check_judges_its_outputs_alone():
    assert len(MEASURED) >= 7, MEASURED
    assert [a for a in MEASURED if not registry.get(a).check.compare.judges_alone] == []
    plain = [a.id for a in registry.algorithms() if a.check is not None and a.check.credit is None
             and a.check.compare.judges_alone]
    assert plain == []  # an exercise graded by agreement with the reference keeps its mistakes named


def _outputs(algorithm_id, case):
    """Outputs to judge on ``case``: the reference's and each mistake's (for the digits' network,
    whose every output is a training, labels made up: the truth, shifted by one, all zeros)."""
    spec = registry.get(algorithm_id).check
    if algorithm_id == "train.train_digits":
        truth = np.asarray(case.truth)
        return [truth.copy(), (truth + 1) % 10, np.zeros_like(truth)]
    outputs = [engine._reference_output(registry.get(algorithm_id).reference, case, spec.call)]
    for mistake in spec.bank:
        produced, value = engine._mistake_output(mistake, case, spec.call)
        if produced:
            outputs.append(value)
    return outputs


@pytest.mark.parametrize("algorithm_id", MEASURED)
def test_the_verdict_does_not_depend_on_the_expected_output(algorithm_id):
    spec = registry.get(algorithm_id).check
    case = spec.public_cases()[0]
    outputs = _outputs(algorithm_id, case)
    with np.errstate(all="ignore"):
        verdicts = [[spec.compare(got, expected, case) is None for expected in outputs] for got in outputs]
    assert all(len(set(row)) == 1 for row in verdicts), verdicts
    assert {row[0] for row in verdicts} == {True, False}, verdicts  # one output passes, another fails


def test_a_failing_measured_output_runs_no_mistake(monkeypatch):
    ran = []
    original = engine._mistake_output
    monkeypatch.setattr(engine, "_mistake_output", lambda *a, **k: ran.append(a[0].name) or original(*a, **k))

    def one_class(x_train, y_train, rng=None):
        return lambda x: np.zeros(len(x), dtype=np.int64)

    report = evaluate("learn.train_digit_classifier", one_class)
    assert not report.passed and report.mistake is None and "one class" in report.text()
    assert ran == []
