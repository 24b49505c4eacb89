"""Every rule an exercise's statement states is tested by a case (issue #35, item 1).

The rules a statement states (integer or uint8 input allowed, a single point of shape ``(d,)``,
no warning) are read from the notebooks (``statement_rules``); each must be declared on the
check (:attr:`cvkit.grading.Check.rules`), and each declared rule must be exercised by a visible
or hidden case: an integer array, an int16 array whose squares overflow int16, a uint8 array,
a 1-D array where other cases give ``(N, d)``, a single row; "no warnings" is enforced by the
engine (a right value that raised a warning fails its case, and says which warning).
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from cvkit import registry
from cvkit.grading import evaluate
from cvkit.grading.checks import RULES

try:
    from . import statement_rules as S
    from . import checks_harness as harness
except ImportError:  # pragma: no cover - run as a plain module
    import statement_rules as S
    import checks_harness as harness

STATEMENTS = S.statements()
CHECKED = [r.id for r in registry.algorithms() if r.check is not None]
DECLARED = [(aid, rule) for aid in CHECKED for rule in registry.get(aid).check.rules]
SEEDS = (0, 1, 2)


def _arrays(algorithm_id):
    """``(key, array)`` of every array argument of the public cases and of the hidden cases
    drawn from :data:`SEEDS`."""
    spec = registry.get(algorithm_id).check
    cases = spec.public_cases() + [c for s in SEEDS for c in spec.hidden_cases(np.random.default_rng(s))]
    for case in cases:
        for key, value in list(enumerate(case.args)) + list(case.kwargs.items()):
            if isinstance(value, np.ndarray):
                yield key, value


def _squares_overflow(a):
    if a.dtype.kind not in "iu" or a.dtype.itemsize > 2 or not a.size:
        return False
    return float(np.abs(a.astype(np.float64)).max()) ** 2 > np.iinfo(a.dtype).max


def exercised(algorithm_id, rule):
    arrays = list(_arrays(algorithm_id))
    if rule == "integer":
        return any(a.dtype.kind in "iu" for _, a in arrays)
    if rule == "narrow integer":
        return any(_squares_overflow(a) for _, a in arrays)
    if rule == "uint8":
        return any(a.dtype == np.uint8 for _, a in arrays)
    if rule == "single point":
        wide = {k for k, a in arrays if a.ndim == 2}
        return any(a.ndim == 1 and k in wide for k, a in arrays)
    if rule == "single row":
        return any(a.ndim >= 2 and a.shape[0] == 1 for _, a in arrays)
    if rule == "no warnings":
        return _warning_fails(algorithm_id)
    raise AssertionError(f"unknown rule {rule!r}")


def _warning_fails(algorithm_id):
    """The reference, plus a RuntimeWarning, fails the visible test with a sentence naming it."""
    record = registry.get(algorithm_id)

    def warns(*args, **kwargs):
        warnings.warn("overflow encountered in exp", RuntimeWarning)
        return record.reference(*args, **kwargs)

    report = evaluate(algorithm_id, warns, check=harness.allowing_itself(record.check, algorithm_id))
    return (not report.passed and all(not c.passed for c in report.cases)
            and all("raised a warning (RuntimeWarning: overflow encountered in exp)" in c.message
                    for c in report.cases))


def test_every_check_has_a_statement():
    assert not [aid for aid in CHECKED if aid not in STATEMENTS]


@pytest.mark.parametrize("algorithm_id", sorted(STATEMENTS))
def test_every_stated_rule_is_declared(algorithm_id):
    stated = S.stated_rules(STATEMENTS[algorithm_id])
    declared = set(registry.get(algorithm_id).check.rules)
    assert stated <= declared, f"the statement states {sorted(stated - declared)}, which the check does not declare"


@pytest.mark.parametrize("algorithm_id,rule", DECLARED, ids=[f"{a}:{r}" for a, r in DECLARED])
def test_every_declared_rule_is_exercised_by_a_case(algorithm_id, rule):
    assert exercised(algorithm_id, rule), f"no visible or hidden case of {algorithm_id} exercises {rule!r}"


def test_the_rule_list_is_known():
    assert {rule for _, rule in DECLARED} <= RULES
    assert set(S.PHRASES) <= RULES


def test_the_phrases_catch_their_rules():
    assert S.stated_rules("`ix`, `iy`: real arrays (any shape, possibly integer)") == {"integer"}
    assert S.stated_rules("a `uint8` image") == {"uint8"}
    assert S.stated_rules("or a single point of shape `(d,)`") == {"single point"}
    assert S.stated_rules("correct values (no overflow\n  warning, no NaN)") == {"no warnings"}
    assert S.stated_rules("return an integer array of labels") == set()


def test_an_unexercised_rule_is_caught():
    # the hidden cases of edges.magnitude before issue #35: int64 values ±1020 (nothing overflows)
    assert exercised("edges.magnitude", "narrow integer")
    assert not _squares_overflow(np.array([-1020, 1020], dtype=np.int64))
    assert not _squares_overflow(np.array([100, -100], dtype=np.int16))
    assert _squares_overflow(np.array([1020], dtype=np.int16))
    assert not exercised("filters.mean_kernel", "uint8")
