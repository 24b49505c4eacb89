"""A mask is not a number (the third round of attacks): where a check expects numbers, an
output of booleans is compared as the numbers 0 and 1, and where it expects a mask, numbers
other than 0 and 1 are refused. Before, ``Close`` compared *both* sides as booleans as soon as
one of them was boolean: ``return True`` passed ``train.step_decay``, and ``dout != 0`` passed
every ``nn.*_backward`` check, all their cases hidden ones included.
"""
from __future__ import annotations

import numpy as np
import pytest

from cvkit import registry
from cvkit.grading import engine, evaluate
from cvkit.grading.compare import close

try:
    from . import checks_harness as harness
except ImportError:  # pragma: no cover
    import checks_harness as harness

CHECKED = [r.id for r in registry.algorithms() if r.check is not None]
SEED = 53


def _as_mask(value):
    """``value`` with every float turned into ``value != 0`` (containers kept)."""
    if isinstance(value, (float, np.floating)):
        return bool(value != 0)
    if isinstance(value, np.ndarray) and value.dtype.kind in "fc":
        return value != 0
    if isinstance(value, (tuple, list)):
        return type(value)(_as_mask(v) for v in value)
    if isinstance(value, dict):
        return {k: _as_mask(v) for k, v in value.items()}
    return value


def _floats_beyond_0_and_1(value) -> bool:
    """Whether the mask of ``value`` has other numbers than ``value`` (a float not 0 or 1)."""
    if isinstance(value, (float, np.floating)):
        return value not in (0.0, 1.0)
    if isinstance(value, np.ndarray) and value.dtype.kind in "fc":
        return bool(np.any((value != 0) & (value != 1)))
    if isinstance(value, (tuple, list)):
        return any(_floats_beyond_0_and_1(v) for v in value)
    if isinstance(value, dict):
        return any(_floats_beyond_0_and_1(v) for v in value.values())
    return False


def _masks_as_numbers(value):
    """``value`` with every boolean array turned into numbers other than 0 and 1 (True → 3.0),
    as "the strength instead of the mask" would give. A cache (a dict) is left as it is: it may
    hold what a comparator does not judge in every mode (dropout's mask in evaluation)."""
    if isinstance(value, np.ndarray) and value.dtype.kind == "b":
        return value * 3.0
    if isinstance(value, (tuple, list)):
        return type(value)(_masks_as_numbers(v) for v in value)
    return value


def _has_a_true_mask(value) -> bool:
    """Whether :func:`_masks_as_numbers` changes ``value`` (a boolean array with a True)."""
    if isinstance(value, np.ndarray) and value.dtype.kind == "b":
        return bool(value.any())
    if isinstance(value, (tuple, list)):
        return any(_has_a_true_mask(v) for v in value)
    return False


@pytest.mark.parametrize("algorithm_id", CHECKED)
def test_a_mask_is_not_a_number_and_a_number_is_not_a_mask(algorithm_id):
    """Where the expected output has numbers other than 0 and 1, its mask fails; where it is a
    mask with a True, the same mask as numbers 3 and 0 fails."""
    record = registry.get(algorithm_id)
    spec = record.check
    compared = 0
    for case in list(spec.public_cases()) + list(spec.hidden_cases(np.random.default_rng(SEED))):
        try:
            expected = engine._reference_output(record.reference, case, spec.call)
        except Exception:  # noqa: BLE001 - a case the reference refuses tells nothing here
            continue
        for applies, wrong, what in ((_floats_beyond_0_and_1, _as_mask, "its mask"),
                                     (_has_a_true_mask, _masks_as_numbers, "its mask as numbers 3 and 0")):
            if not applies(expected):
                continue
            compared += 1
            with np.errstate(all="ignore"):
                try:
                    verdict = spec.compare(wrong(expected), expected, case)
                except Exception:  # noqa: BLE001 - a comparator that cannot read it rejects it too
                    continue
            assert verdict is not None, f"{case.label}: {what} passes for the expected output"
    if not compared:
        pytest.skip("its outputs are integers or None: nothing a mask could stand for")


def test_return_true_earns_nothing_for_a_learning_rate():
    def step_decay(epoch, lr0, drop=0.1, every=30):
        return True

    assert not evaluate("train.step_decay", step_decay).passed
    assert evaluate("train.step_decay", step_decay, hidden=True, seed=SEED).score == 0


def test_a_mask_for_a_gradient_earns_nothing_but_the_gradient_passes():
    reference = registry.get("nn.relu_backward").reference

    def relu_backward(dout, cache):
        return (np.asarray(cache["x"]) > 0) & (np.asarray(dout) != 0)

    assert not evaluate("nn.relu_backward", relu_backward).passed
    # it is right only on the hidden cases whose gradient is itself made of 0 and 1 (dout = 1)
    record = registry.get("nn.relu_backward")
    hidden = list(record.check.hidden_cases(np.random.default_rng(SEED)))
    mask_like = sum(not _floats_beyond_0_and_1(engine._reference_output(record.reference, case, record.check.call))
                    for case in hidden)
    assert mask_like < len(hidden) / 2
    report = evaluate("nn.relu_backward", relu_backward, hidden=True, seed=SEED)
    assert report.score == pytest.approx(mask_like / len(hidden))
    check = harness.allowing_itself(registry.get("nn.relu_backward").check, "nn.relu_backward")
    assert evaluate("nn.relu_backward", reference, check=check).passed


def test_a_mask_may_come_as_zeros_and_ones_but_not_as_other_numbers():
    expected = np.array([True, False, True])
    assert close()(np.array([1, 0, 1]), expected) is None
    assert close()(np.array([1.0, 0.0, 1.0]), expected) is None
    refused = close()(np.array([0.7, 0.0, 2.0]), expected)
    assert refused is not None and "0 and 1" in refused.message
    assert close()(np.array([True, False]), np.array([1.0, 0.0])) is None
    assert close()(np.array([True, False]), np.array([0.5, 0.0])) is not None
