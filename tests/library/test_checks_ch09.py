"""The Chapter 9–10 checks (``cvkit.learn``) are worth their points (the tests every chapter
owes: ``checks_harness.ChapterChecks``; a mistake may call every learn id), the random
algorithms are judged by their results (another correct run with other draws passes), and the
guard catches what it should."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import cvkit.learn
from cvkit import registry
from cvkit.grading import evaluate
from cvkit.learn import checks

import alternatives_ch09 as alt
import checks_harness as harness
import measured_harness
from checks_harness import SEEDS, check_of, reference_of

LEARN = [
    "learn.linear_scores", "learn.softmax", "learn.cross_entropy", "learn.linear_loss_and_grad",
    "learn.numerical_gradient", "learn.sgd_train", "learn.top_k_accuracy", "learn.knn_predict",
    "learn.kmeans", "learn.bovw_histogram",
]
#: the measured exercise (§9.8.5): graded by the accuracy it reaches, not value by value
MEASURED = ["learn.train_digit_classifier"]


class TestChapter09(harness.ChapterChecks):
    IDS = LEARN
    TRIVIAL = frozenset({"learn.linear_scores"})
    ALTERNATIVES = alt.ALTERNATIVES
    EXTRA_ALTERNATIVES = list(alt.EXTRA_ALTERNATIVES.items())

    def fingerprint(self, case):
        return harness.describe_and_arrays(case)

    def reference_check(self, algorithm_id):
        # graded through the check's ``call`` adapter, the guard sees the adapter (not the
        # candidate) as the student's code: the reference may call only itself
        spec = check_of(algorithm_id)
        return spec if spec.call is None else harness.allowing(spec, (algorithm_id,))


# --------------------------------------------------------------------------------------------
# the shape of every check
# --------------------------------------------------------------------------------------------
def test_every_learn_id_is_registered_with_its_check():
    harness.assert_ids_are_the_module(LEARN + MEASURED, "learn")
    for aid in LEARN + MEASURED:
        name = aid.split(".")[1]
        assert registry.get(aid).check is getattr(checks, name)
        assert registry.get(aid).reference is getattr(cvkit.learn, name)


def test_the_issue_s_separating_inputs_are_in_the_hidden_cases():
    """Huge scores for softmax/cross-entropy, ties for top-k and kNN, empty clusters for k-means."""
    for seed in SEEDS:
        rng = lambda: np.random.default_rng(seed)  # noqa: E731
        soft = checks.softmax.hidden_cases(rng())
        assert any(np.abs(np.asarray(c.args[0])).max() >= 1e4 for c in soft)
        ce = checks.cross_entropy.hidden_cases(rng())
        assert any(np.abs(np.asarray(c.args[0])).max() >= 1e4 for c in ce)
        assert any("reg" in c.kwargs and c.kwargs["reg"] > 0 for c in checks.linear_loss_and_grad.hidden_cases(rng()))
        topk = checks.top_k_accuracy.hidden_cases(rng())
        assert any(len(np.unique(np.asarray(c.args[0]))) < np.size(c.args[0]) for c in topk)
        km = checks.kmeans.hidden_cases(rng())
        assert sum("empty" in c.label for c in km) >= 2
        assert {c.kwargs.get("iterations", 50) for c in km} >= {0, 1, 50}
        knn = checks.knn_predict.hidden_cases(rng())
        assert {c.kwargs["metric"] for c in knn} == {"l1", "l2"}
        assert {c.kwargs["k"] for c in knn} >= {1, 2, 3, 4, 5, 7}
        assert {c.kwargs["normalize"] for c in checks.bovw_histogram.hidden_cases(rng())} == {True, False}


# --------------------------------------------------------------------------------------------
# random algorithms are judged by their results
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("algorithm_id", ["learn.sgd_train", "learn.kmeans"])
def test_random_algorithms_are_judged_by_results_not_draws(algorithm_id):
    """The reference run with another seed than the case's (other shuffles, other seeding) and
    the alternative (other sampling scheme) pass on many hidden draws."""
    reference = reference_of(algorithm_id)

    def other_draws(*args, **kwargs):
        kwargs = dict(kwargs)
        kwargs["rng"] = np.random.default_rng(None if kwargs.get("rng") is None else int(kwargs["rng"]) + 12345)
        return reference(*args, **kwargs)

    allowing = dataclasses.replace(check_of(algorithm_id), allowed=(algorithm_id,))
    for seed in range(10):
        for candidate in (other_draws, alt.ALTERNATIVES[algorithm_id]):
            report = evaluate(algorithm_id, candidate, hidden=True, seed=5000 + seed, check=allowing)
            assert report.passed, report.text()


def test_sgd_tolerance_is_far_below_the_mistakes_gap():
    """On the stochastic cases, two correct runs differ by < 40 % of the tolerance."""
    for seed in SEEDS:
        for case in checks.sgd_train.hidden_cases(np.random.default_rng(seed)):
            if not isinstance(case, checks._SGDCase):
                continue
            X, y, c, lr, epochs, batch = case.args
            reg = case.kwargs["reg"]
            values = [checks._objective(*cvkit.learn.sgd_train(X, y, c, lr, epochs, batch, reg, rng=r)[:2], X, y, reg)
                      for r in range(6)]
            assert np.ptp(values) < 0.4 * case.tolerance, (case.label, values)


# --------------------------------------------------------------------------------------------
# comparators and the guard
# --------------------------------------------------------------------------------------------
def test_sgd_comparator_messages():
    case = checks.sgd_train.public_cases()[2]  # many small batches
    expected = cvkit.learn.sgd_train(*case.args, **case.kwargs)
    cmp = checks.SGDResult()
    assert cmp(expected, expected, case) is None
    assert "tuple" in cmp(expected[0], expected, case).message
    short = (expected[0], expected[1], expected[2][:-1])
    assert "losses" in cmp(short, expected, case).message
    nan = (expected[0] * np.nan, expected[1], expected[2])
    assert "NaN" in cmp(nan, expected, case).message
    worse = (np.zeros_like(expected[0]), np.zeros_like(expected[1]), expected[2] + 1.0)
    message = cmp(worse, expected, case).message
    assert "training objective" in message and "last epoch" in message
    full = checks.sgd_train.public_cases()[0]
    exact = cvkit.learn.sgd_train(*full.args, **full.kwargs)
    assert "full-batch" in cmp((exact[0] + 1e-3, exact[1], exact[2]), exact, full).message


def test_kmeans_comparator_messages():
    case = checks.kmeans.public_cases()[2]  # k-means++
    X = case.args[0]
    centers, labels = cvkit.learn.kmeans(*case.args, **case.kwargs)
    cmp = checks.KMeansResult()
    assert cmp((centers, labels), (centers, labels), case) is None
    permuted = np.array([2, 0, 1])
    relabel = np.argsort(permuted)[labels]
    assert cmp((centers[permuted], relabel), (centers, labels), case) is None  # cluster order is free
    wrong_labels = labels.copy()
    wrong_labels[0] = (labels[0] + 1) % 3
    assert "nearest" in cmp((centers, wrong_labels), (centers, labels), case).message
    assert "integer" in cmp((centers, labels.astype(float)), (centers, labels), case).message
    shifted = centers.copy()
    shifted[0] += 0.01
    assert cmp((shifted, labels), (centers, labels), case) is not None
    nan = centers.copy()
    nan[1] = np.nan
    assert "NaN" in cmp((nan, labels), (centers, labels), case).message
    assert X.shape[0] == labels.shape[0]


def test_calling_the_reference_is_forbidden_and_named():
    def softmax(scores):
        return cvkit.learn.softmax(scores)

    harness.assert_scores_zero("learn.softmax", softmax, "'learn.softmax'")


def test_sklearn_is_forbidden_and_named():
    from sklearn.neighbors import KNeighborsClassifier

    def knn_predict(X_train, y_train, X_test, k=1, metric="l2"):
        p = 2 if metric == "l2" else 1
        return KNeighborsClassifier(k, p=p).fit(X_train, y_train).predict(X_test)

    harness.assert_scores_zero("learn.knn_predict", knn_predict, "sklearn", every_case=True)


def test_building_blocks_may_be_called_in_the_loss_and_in_sgd():
    def linear_loss_and_grad(W, b, X, y, reg=0.0):
        loss, g = cvkit.learn.cross_entropy(cvkit.learn.linear_scores(X, W, b), y)
        W = np.asarray(W, dtype=float)
        return loss + reg * np.sum(W * W), g.T @ np.asarray(X, dtype=float) + 2 * reg * W, g.sum(axis=0)

    harness.assert_passes_everywhere("learn.linear_loss_and_grad", linear_loss_and_grad, SEEDS)

    def sgd_train(X, y, classes, lr, epochs, batch_size, reg=0.0, rng=None):
        gen = np.random.default_rng(rng)
        X = np.asarray(X, dtype=float)
        W, b, losses = np.zeros((classes, X.shape[1])), np.zeros(classes), []
        for _ in range(epochs):
            order, total = gen.permutation(len(X)), 0.0
            for s in range(0, len(X), batch_size):
                idx = order[s:s + batch_size]
                loss, dW, db = cvkit.learn.linear_loss_and_grad(W, b, X[idx], y[idx], reg)
                W, b, total = W - lr * dW, b - lr * db, total + loss * len(idx)
            losses.append(total / len(X))
        return W, b, np.array(losses)

    assert evaluate("learn.sgd_train", sgd_train, hidden=True, seed=SEEDS[0]).passed


def test_modifying_the_input_fails():
    def numerical_gradient(f, x, eps=1e-5):
        grad = np.zeros(np.shape(x))
        flat = x.reshape(-1)  # a view on the caller's array
        for i in range(flat.size):
            flat[i] += eps
            plus = f(x)
            flat[i] -= 2 * eps
            minus = f(x)
            flat[i] += eps  # round-off: not exactly the old value
            grad.flat[i] = (plus - minus) / (2 * eps)
        return grad

    report = evaluate("learn.numerical_gradient", numerical_gradient)
    assert report.score < 1.0
    assert any("modified its input" in c.message and "'x'" in c.message for c in report.cases), report.text()


def test_drawing_from_np_random_fails_the_seeded_checks():
    calls = iter(range(10**6))

    def kmeans(X, k, iterations=50, rng=None, init=None):
        # ignores rng: consecutive calls relabel the clusters differently (as a global
        # generator would, without depending on NumPy's global state in this test run)
        centers, labels = alt.kmeans(X, k, iterations, 0, init)
        if next(calls) % 2:
            centers, labels = centers[::-1], (len(centers) - 1) - labels
        return centers, labels

    report = evaluate("learn.kmeans", kmeans)
    assert any("same rng seed" in c.message for c in report.cases)

    def sgd_train(X, y, classes, lr, epochs, batch_size, reg=0.0, rng=None):
        return alt.sgd_train(X, y, classes, lr, epochs, batch_size, reg, np.random.randint(1 << 30))

    report = evaluate("learn.sgd_train", sgd_train, hidden=True, seed=SEEDS[0])
    assert not report.passed and any("same rng seed" in c.message for c in report.cases)
    assert checks.sgd_train.seeded and checks.kmeans.seeded


def test_numerical_gradient_cases_are_plain_data_for_the_isolated_worker():
    """Its cases name a test function and its coefficients; the check's ``call`` builds it."""
    from cvkit.grading import wire

    for case in checks.numerical_gradient.public_cases() + checks.numerical_gradient.hidden_cases(np.random.default_rng(1)):
        back = wire.loads(wire.dumps((case.args, case.kwargs)))
        function = checks.TestFunction(back[0][0], back[0][1])
        x = np.asarray(back[0][2], dtype=float)
        assert np.isfinite(function(x)) and repr(function).startswith("f(x) = ")
    f = checks.TestFunction("quadratic", np.vstack([np.eye(2) * 2, [1.0, -1.0]]))   # x·x + x0 − x1
    assert f(np.array([1.0, 2.0])) == pytest.approx(5.0 + 1.0 - 2.0)
    report = evaluate("learn.numerical_gradient", cvkit.learn.numerical_gradient,
                      check=dataclasses.replace(checks.numerical_gradient, allowed=("learn.numerical_gradient",)))
    assert report.passed and "function='cubic'" in report.cases[0].description


def test_labels_must_be_integers():
    def knn_predict(X_train, y_train, X_test, k=1, metric="l2"):
        return alt.knn_predict(X_train, y_train, X_test, k, metric).astype(float)

    report = evaluate("learn.knn_predict", knn_predict)
    assert not report.passed
    assert any("dtype" in c.message for c in report.cases if not c.passed)


# --------------------------------------------------------------------------------------------
# the measured exercise: learn.train_digit_classifier, graded by its accuracy on held-out digits
# --------------------------------------------------------------------------------------------
CLASSIFIER = "learn.train_digit_classifier"
CLASSIFIER_SEEDS = (101, 202)
_accuracy = checks.DigitAccuracy.accuracy


def test_the_classifier_scale_is_the_published_one():
    from cvkit.learn import _digits

    assert tuple(checks.ACCURACY) == _digits.ACCURACY_SCALE == ((0.85, 0.0), (0.90, 0.5), (0.93, 1.0))
    assert checks.ACCURACY.credit(0.875) == pytest.approx(0.25) and checks.ACCURACY.credit(0.5) == 0.0
    measured_harness.assert_notebook_publishes("ch09_classification", CLASSIFIER,
                                               "train_digit_classifier(x_train, y_train, rng)", checks.ACCURACY,
                                               "accuracy on the held-out digits", _digits.BUDGET_SECONDS)


def test_the_classifier_check_measures_what_it_should():
    """The reference and k nearest neighbours (written with loops, no normalisation: another
    model of the chapters) clear the top; each mistake stays below it; a stub earns 0; the
    reports say what went wrong."""
    measured_harness.assert_measures_what_it_should(CLASSIFIER, CLASSIFIER_SEEDS, _accuracy, checks.ACCURACY,
                                                    "accuracy", alternatives=[alt.train_digit_classifier])
    report = evaluate(CLASSIFIER, checks._classifier_labels_off_by_one, hidden=True, seed=101)
    assert "labels run from 1 to 10" in report.cases[0].message
    report = evaluate(CLASSIFIER, checks._classifier_strong_regularisation, hidden=True, seed=101)
    assert "Most predictions are one class" in report.cases[0].message and report.score == 0.0


def test_classifier_partial_credit_follows_the_scale():
    """The reference recipe (its unregistered pieces) with 7 % of its predictions moved to the
    next label: between the corners of the scale."""
    worse = measured_harness.shifting_labels(checks._linear_classifier, 0.07)
    measured_harness.assert_partial_credit_follows_the_scale(CLASSIFIER, worse, 101, _accuracy, checks.ACCURACY)


def test_held_out_digits_differ_per_student_and_their_labels_stay_outside():
    def same(a, b):
        return all(np.array_equal(x, y) for x, y in zip(a.args[:3], b.args[:3])) and np.array_equal(a.truth, b.truth)

    measured_harness.assert_hidden_data_differ_and_truth_stays_outside(CLASSIFIER, same)
    (case,) = harness.hidden_cases(CLASSIFIER, 5)
    x_train, y_train, x_eval, _ = case.args
    assert x_train.shape[1:] == x_eval.shape[1:] == (64,) and len(x_train) + len(x_eval) == 1797
    assert x_train.max() > 50            # the camera's grey levels, not [0, 1]
