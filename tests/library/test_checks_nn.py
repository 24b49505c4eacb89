"""The Chapter 10–11 checks (``cvkit.nn``) are worth their points (the tests every chapter owes:
``checks_harness.ChapterChecks``; a mistake may call every ``nn`` id), and the special
comparators (nested caches, integers, dropout statistics) say what is wrong."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import cvkit.nn
from cvkit import registry
from cvkit.grading import evaluate
from cvkit.grading.runtime.wire import dumps

import alternatives_nn as alt
import checks_harness as harness
from checks_harness import SEEDS, check_of, reference_of

NN = [
    "nn.relu_forward", "nn.relu_backward", "nn.sigmoid_forward", "nn.sigmoid_backward",
    "nn.leaky_relu_forward", "nn.leaky_relu_backward", "nn.linear_forward", "nn.linear_backward",
    "nn.conv_output_size", "nn.receptive_field", "nn.conv2d_forward", "nn.conv2d_backward",
    "nn.maxpool2d_forward", "nn.maxpool2d_backward", "nn.global_avg_pool_forward",
    "nn.global_avg_pool_backward", "nn.batchnorm2d_forward", "nn.batchnorm2d_backward",
    "nn.dropout_forward", "nn.dropout_backward", "nn.residual_block_forward", "nn.residual_block_backward",
    "nn.architecture_spec", "nn.count_parameters", "nn.count_flops",
]


class TestChapterNN(harness.ChapterChecks):
    IDS = NN
    MIN_MISTAKES = 3
    MAX_NAME_LENGTH = 75
    ALTERNATIVES = alt.ALTERNATIVES
    EXTRA_ALTERNATIVES = list(alt.EXTRA_ALTERNATIVES.items())

    def fingerprint(self, case):
        """A case's arguments as sent to the isolated grading worker: the cases are plain data
        that can travel there."""
        return (dumps((case.args, case.kwargs)),)

    def reference_check(self, algorithm_id):
        # with a ``call`` the guard sees the call wrapper (not the candidate) as the student's code,
        # so grading the reference itself would be reported as a call into the reference
        return harness.allowing_itself(check_of(algorithm_id), algorithm_id)


def test_every_catalog_id_is_checked():
    ids = {a.id for a in registry.algorithms() if a.id.startswith("nn.")}
    assert ids == set(NN)


# --------------------------------------------------------------------------------------------
# what the comparators and the guard tell a student
# --------------------------------------------------------------------------------------------
def test_a_cache_without_the_named_entries_is_reported():
    def relu_forward(x):
        x = np.asarray(x, dtype=float)
        return np.maximum(x, 0), {"input": x}

    report = evaluate("nn.relu_forward", relu_forward)
    assert not report.passed
    assert "lacks the key 'x'" in report.cases[0].message

    def relu_forward_extra(x):
        x = np.asarray(x, dtype=float)
        return np.maximum(x, 0), {"x": x, "mask": x >= 0, "note": "extra entries are fine"}

    assert all(r.passed for r in harness.grade_everywhere("nn.relu_forward", relu_forward_extra, SEEDS))


def test_a_float_size_is_right_in_value_but_refused():
    def conv_output_size(size, kernel, padding=0, stride=1):
        return float((size - kernel + 2 * padding) // stride + 1)

    report = evaluate("nn.conv_output_size", conv_output_size)
    assert not report.passed
    assert "must be an int" in report.cases[0].message


def test_a_backward_may_only_read_the_catalog_entries_of_the_cache():
    def relu_backward(dout, cache):
        return dout * cache["mask"]       # an entry its own forward stored, not in the catalog

    harness.assert_scores_zero("nn.relu_backward", relu_backward, "KeyError")


def test_a_backward_that_writes_into_the_cache_is_caught():
    def maxpool2d_backward(dout, cache):
        cache["x"] = np.asarray(cache["x"]) * 1.0 + 0.0
        cache["x"][0, 0, 0, 0] += 1.0     # modifies the grader's input
        return alt.maxpool2d_backward(dout, cache)

    harness.assert_scores_zero("nn.maxpool2d_backward", maxpool2d_backward, "modified its input")


def test_dropout_from_the_global_generator_fails_the_seeded_check():
    def dropout_forward(x, p_keep, training, rng=None):
        x = np.asarray(x, dtype=float)
        if not training:
            return x.copy(), {"x": x, "p_keep": p_keep, "training": training, "mask": np.ones(x.shape, bool)}
        mask = np.random.random(x.shape) < p_keep
        return np.where(mask, x / p_keep, 0.0), {"x": x, "p_keep": p_keep, "training": training, "mask": mask}

    report = evaluate("nn.dropout_forward", dropout_forward)
    assert not report.passed
    assert any("same rng seed" in c.message for c in report.cases)


def test_dropout_statistics_say_what_is_off():
    report = evaluate("nn.dropout_forward", check_of("nn.dropout_forward").mistake(
        "kept units multiplied by p_keep instead of divided").function,
        check=dataclasses.replace(check_of("nn.dropout_forward"), allowed=tuple(NN)))
    message = report.cases[0].message
    assert "scale of the kept units" in message and "expected 1.25" in message


def test_conv2d_by_scipy_signal_is_forbidden():
    import scipy.signal

    def conv2d_forward(x, w, b, stride=1, padding=0):
        x, w, b = (np.asarray(a, dtype=float) for a in (x, w, b))
        xp = np.pad(x, ((0, 0), (0, 0), (padding, padding), (padding, padding)))
        out = np.array([[sum(scipy.signal.correlate(xp[n, c], w[f, c], mode="valid") for c in range(x.shape[1])) + b[f]
                         for f in range(w.shape[0])] for n in range(x.shape[0])])
        return out[:, :, ::stride, ::stride], {"x": x, "w": w, "b": b, "stride": stride, "padding": padding}

    harness.assert_scores_zero("nn.conv2d_forward", conv2d_forward, "scipy.signal")


def test_the_residual_block_may_use_the_reference_layers():
    def residual_block_forward(x, params, training=True):
        out, _ = cvkit.nn.residual_block_forward(x, params, training)
        return out, {"x": x, "params": params, "training": training}

    report = evaluate("nn.residual_block_forward", residual_block_forward)
    assert report.score == 0.0 and "'nn.residual_block_forward'" in report.cases[0].message

    def from_layers(x, params, training=True):
        nnm = cvkit.nn
        x = np.asarray(x, dtype=float)
        f = params["w1"].shape[0]
        s = 2 if "w_proj" in params else 1

        def bn(h, k):
            return nnm.batchnorm2d_forward(h, params["gamma" + k], params["beta" + k], params["running_mean" + k],
                                           params["running_var" + k], training)[0]

        h = nnm.relu_forward(bn(nnm.conv2d_forward(x, params["w1"], np.zeros(f), s, 1)[0], "1"))[0]
        h = bn(nnm.conv2d_forward(h, params["w2"], np.zeros(f), 1, 1)[0], "2")
        short = bn(nnm.conv2d_forward(x, params["w_proj"], np.zeros(f), 2, 0)[0], "_proj") if s == 2 else x
        return nnm.relu_forward(h + short)[0], {"x": x, "params": params, "training": training}

    for report in harness.grade_everywhere("nn.residual_block_forward", from_layers, SEEDS):
        assert report.passed, report.text()


@pytest.mark.parametrize("algorithm_id", [i for i in NN if check_of(i).call is not None])
def test_what_crosses_to_the_grader_is_plain_data(algorithm_id):
    spec = check_of(algorithm_id)
    for case in spec.public_cases():
        value = spec.call(reference_of(algorithm_id), *case.args, **case.kwargs)
        dumps(value)  # raises WireError for anything but plain data
