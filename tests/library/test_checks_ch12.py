"""The Chapter 12 checks are worth their points (the tests every chapter owes:
``checks_harness.ChapterChecks``; a mistake is graded with the check as registered), and the
random functions are graded by properties, not draws. The measured exercise
(``train.train_digits``) is graded by the accuracy a trained network reaches on held-out digits:
the reference recipe clears the top of the published scale, the broken recipes of its bank fall
below it (a diverged run looks the same whatever made it diverge, so they are not told apart by
name), and partial credit follows the scale."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import cvkit.train
from cvkit import registry
from cvkit.grading import evaluate
from cvkit.train import checks as train_checks

import alternatives_ch12 as alt
import checks_harness as harness
from checks_harness import SEEDS, check_of, reference_of

CH12 = [
    "train.step_decay", "train.cosine_decay", "train.warmup", "train.one_cycle", "train.sgd_weight_decay_step",
    "train.early_stopping", "train.smooth_labels", "train.stochastic_depth", "train.random_resized_crop",
    "train.cutout", "train.mixup", "train.cutmix", "train.random_search", "train.ensemble_predict", "train.ema_update",
]
RANDOM = ["train.stochastic_depth", "train.random_resized_crop", "train.cutout", "train.mixup", "train.cutmix",
          "train.random_search"]
ARRAY_RANDOM = ["train.stochastic_depth", "train.random_resized_crop", "train.cutout"]
#: the measured exercise (§12.5.4): graded by the accuracy it reaches, not value by value
MEASURED = ["train.train_digits"]


class TestChapter12(harness.ChapterChecks):
    IDS = CH12
    MISTAKES_MAY_CALL = None  # the check as registered: no building blocks added to its allowed ones
    ALTERNATIVES = alt.ALTERNATIVES
    EXTRA_ALTERNATIVES = list(alt.EXTRA_ALTERNATIVES.items())

    def test_check_is_complete(self, algorithm_id):
        super().test_check_is_complete(algorithm_id)
        assert check_of(algorithm_id).seeded == (algorithm_id in ARRAY_RANDOM or algorithm_id in RANDOM)


# --------------------------------------------------------------------------------------------
# the shape of every check
# --------------------------------------------------------------------------------------------
def test_every_catalog_id_of_the_chapter_is_registered_with_a_check():
    ids = {a.id for a in registry.algorithms() if a.module == "train"}
    assert ids == set(CH12) | set(MEASURED)
    for algorithm_id in CH12 + MEASURED:
        record = registry.get(algorithm_id)
        assert record.section.startswith("12.")
        assert record.check is getattr(train_checks, algorithm_id.split(".")[1])


def test_schedule_cases_include_the_boundaries():
    """The off-by-one boundaries of the issue are among the hidden cases of every seed."""
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        labels = [c.label for c in check_of("train.one_cycle").hidden_cases(rng)]
        for needed in ("the peak", "step T − 1", "step 0", "step T:"):
            assert any(needed in label for label in labels), (needed, labels)
        cases = check_of("train.one_cycle").hidden_cases(np.random.default_rng(seed))
        peak = next(c for c in cases if "the peak" in c.label)
        T, p = peak.args[1], peak.kwargs["pct_start"]
        assert peak.args[0] == p * T - 1
        cases = check_of("train.cosine_decay").hidden_cases(np.random.default_rng(seed))
        assert any(c.args[0] == 0 for c in cases) and any(c.args[0] == c.args[1] for c in cases)
        cases = check_of("train.warmup").hidden_cases(np.random.default_rng(seed))
        assert any(c.args[0] == c.args[1] for c in cases)           # step W
        assert any(c.args[0] == c.args[1] - 1 for c in cases)       # step W − 1
        cases = check_of("train.step_decay").hidden_cases(np.random.default_rng(seed))
        every = [c.kwargs.get("every", c.args[3] if len(c.args) > 3 else 30) for c in cases]
        assert any(c.args[0] == e for c, e in zip(cases, every))     # the first drop
        assert any(c.args[0] % e == e - 1 for c, e in zip(cases, every) if e > 1)  # the epoch before a drop


# --------------------------------------------------------------------------------------------
# the notebook's own answers, random functions graded by properties
# --------------------------------------------------------------------------------------------
NOTEBOOK = Path(__file__).resolve().parents[2] / "lectures" / "ch12_training" / "ch12_training.ipynb"


def _notebook_solutions():
    """The answer cells of the chapter's notebook, executed: {algorithm id: function}."""
    import math

    namespace = {"np": np, "math": math}
    found = {}

    def student(algorithm_id):
        def record(function):
            found[algorithm_id] = function
            return function
        return record

    namespace["student"] = student
    for cell in json.loads(NOTEBOOK.read_text())["cells"]:
        if cell["cell_type"] == "code" and cell.get("metadata", {}).get("nbgrader", {}).get("solution"):
            exec("".join(cell["source"]), namespace)  # written answers (markdown) are graded by hand
    return found


@pytest.mark.skipif(not NOTEBOOK.exists(), reason="the notebook is not there")
def test_notebook_solutions_pass_public_and_hidden_cases():
    solutions = _notebook_solutions()
    # the chapter's own ids, plus the dropout layer of §12.3.6 (its check lives with the nn layers)
    assert set(solutions) == set(CH12) | set(MEASURED) | {"nn.dropout_forward", "nn.dropout_backward"}
    for algorithm_id, function in solutions.items():
        harness.assert_passes_everywhere(algorithm_id, function, SEEDS)


@pytest.mark.parametrize("algorithm_id", RANDOM)
def test_random_checks_accept_other_seeds_of_the_reference(algorithm_id):
    """A correct function that draws other numbers (here: the reference with the seed
    shifted) passes: random functions are graded by properties and statistics."""
    reference = reference_of(algorithm_id)

    def shifted(*args, rng=None, **kwargs):
        generator = np.random.default_rng(rng)
        generator.random(3)  # other draws from the same seed
        return reference(*args, rng=generator, **kwargs)

    allowing = dataclasses.replace(check_of(algorithm_id), allowed=(algorithm_id,))
    for seed in SEEDS:
        report = evaluate(algorithm_id, shifted, hidden=True, seed=seed, check=allowing)
        assert report.passed, report.text()


# --------------------------------------------------------------------------------------------
# random functions: reproducibility through rng
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("algorithm_id", ARRAY_RANDOM)
def test_drawing_from_np_random_fails_the_seeded_check(algorithm_id):
    reference = reference_of(algorithm_id)

    def careless(*args, rng=None, **kwargs):
        return reference(*args, rng=np.random.default_rng(), **kwargs)  # ignores the seed

    allowing = dataclasses.replace(check_of(algorithm_id), allowed=(algorithm_id,))
    report = evaluate(algorithm_id, careless, hidden=True, seed=SEEDS[0], check=allowing)
    assert not report.passed
    assert any("same rng seed" in c.message for c in report.cases)


@pytest.mark.parametrize("algorithm_id", ["train.mixup", "train.cutmix", "train.random_search"])
def test_drawing_from_np_random_fails_the_structured_seeded_checks(algorithm_id):
    reference = reference_of(algorithm_id)

    def careless(*args, rng=None, **kwargs):
        return reference(*args, rng=np.random.default_rng(), **kwargs)

    allowing = dataclasses.replace(check_of(algorithm_id), allowed=(algorithm_id,))
    report = evaluate(algorithm_id, careless, hidden=True, seed=SEEDS[0], check=allowing)
    assert not report.passed
    assert any("same rng seed" in c.message for c in report.cases)


# --------------------------------------------------------------------------------------------
# comparators and messages
# --------------------------------------------------------------------------------------------
def test_exact_value_comparator():
    compare = train_checks.ExactValue("epoch")
    assert compare(5, 5) is None and compare(np.int64(5), 5) is None and compare(None, None) is None
    assert "None" in compare(None, 5).message
    assert "expected None" in compare(3, None).message
    assert "return an int" in compare(5.0, 5).message
    assert compare(True, 1) is not None
    assert "expected epoch 4, got 5" in compare(5, 4).message


def test_structured_statistics_reports_the_form_first():
    spec = check_of("train.mixup")
    case = spec.public_cases()[0]
    expected = reference_of("train.mixup")(*case.args, **case.kwargs)
    assert spec.compare(expected, expected, case) is None
    assert "tuple" in spec.compare(expected[0], expected, case).message
    assert "one number" in spec.compare((expected[0], expected[1], np.array([0.3, 0.4])), expected, case).message
    assert "[0, 1]" in spec.compare((expected[0], expected[1], 1.5), expected, case).message


def test_label_smoothing_torch_convention_is_recognised():
    def torch_style(y, classes, eps):
        onehot = np.eye(classes)[np.asarray(y)]
        return onehot * (1 - eps) + eps / classes

    report = evaluate("train.smooth_labels", torch_style)
    assert not report.passed and report.mistake == "PyTorch's convention (ε/C on every class)"
    assert "C − 1" in report.hint


def test_mistakes_that_are_right_on_natural_inputs_still_fail():
    """E.g. weight decay after the step equals the right update when λ = 0, the one-cycle
    peak truncated to an int is right whenever p·T is an integer: the hidden cases separate
    them anyway (checked for every mistake above); here the natural cases are shown to agree."""
    after = check_of("train.sgd_weight_decay_step").mistake("weight decay applied after the gradient step").function
    theta, g = np.array([1.0, -2.0]), np.array([0.3, 0.1])
    assert np.allclose(after(theta, g, 0.1, 0.0), cvkit.train.sgd_weight_decay_step(theta, g, 0.1, 0.0))
    truncated = check_of("train.one_cycle").mistake("peak step truncated to an integer").function
    assert all(truncated(t, 100, 1.0) == cvkit.train.one_cycle(t, 100, 1.0) for t in range(101))


def test_guard_forbids_calling_the_reference():
    def cutout(image, size, rng=None):
        return cvkit.train.cutout(image, size, rng)

    harness.assert_scores_zero("train.cutout", cutout, "'train.cutout'", hidden=True, seed=SEEDS[0])


def test_modifying_the_input_fails():
    def ema_update(ema_params, params, decay=0.999):
        if isinstance(ema_params, np.ndarray):
            ema_params *= decay
            ema_params += (1 - decay) * np.asarray(params)
            return ema_params.copy()
        return alt.ema_update(ema_params, params, decay)

    report = evaluate("train.ema_update", ema_update)
    assert not report.passed
    assert any("modified its input" in c.message for c in report.cases)


def test_float32_results_are_refused_where_float64_is_the_convention():
    def ensemble_predict(logits_list):
        return np.mean(np.stack([np.asarray(v) for v in logits_list]), axis=0)  # float32 stays float32

    report = evaluate("train.ensemble_predict", ensemble_predict, hidden=True, seed=SEEDS[0])
    failed = [c for c in report.cases if not c.passed]
    assert [c.label for c in failed] == ["float32 logits"], report.text()


# --------------------------------------------------------------------------------------------
# the measured exercise: train.train_digits, graded by its accuracy on held-out digits
# --------------------------------------------------------------------------------------------
from cvkit.grading import hidden_seed  # noqa: E402
from cvkit.train import _digits as digits_task  # noqa: E402

DIGITS = "train.train_digits"
DIGIT_SEEDS = (101, 202)


def _credits(report):
    return [case.credit for case in report.cases]


def test_the_scale_is_piecewise_linear_between_its_published_corners():
    credit = train_checks.ACCURACY.credit
    assert tuple(train_checks.ACCURACY) == digits_task.ACCURACY_SCALE
    for accuracy, share in digits_task.ACCURACY_SCALE:
        assert credit(accuracy) == pytest.approx(share)
    (a0, s0), (a1, s1) = digits_task.ACCURACY_SCALE[:2]
    assert credit((a0 + a1) / 2) == pytest.approx((s0 + s1) / 2)
    assert credit(0.0) == 0.0 and credit(0.5) == 0.0          # flat below the bottom
    assert credit(1.0) == 1.0                                  # and above the top
    shares = [s for _, s in digits_task.ACCURACY_SCALE]
    assert shares[0] == 0.0 and shares[-1] == 1.0 and shares == sorted(shares)


def test_the_notebook_publishes_the_scale_and_the_budget_the_check_applies():
    spec = check_of(DIGITS)
    assert spec.time_limit == digits_task.BUDGET_SECONDS == 30.0
    cells = json.loads(NOTEBOOK.read_text())["cells"]
    statement = next("".join(c["source"]) for c in cells
                     if c["cell_type"] == "markdown" and "`train_digits(x_train, y_train, rng)`" in "".join(c["source"]))
    assert f"**{digits_task.BUDGET_SECONDS:g} seconds**" in statement
    row = next(line for line in statement.splitlines() if line.strip().startswith("| share of"))
    for accuracy, share in digits_task.ACCURACY_SCALE:
        assert f"{100 * accuracy:g} %" in statement
        assert f" {share:g} |" in row
    hidden = next(c for c in cells if c.get("metadata", {}).get("nbgrader", {}).get("grade_id") == "train_digits_hidden")
    points = hidden["metadata"]["nbgrader"]["points"]
    assert f"hidden test's {points} points" in statement
    assert f"points={points})" in "".join(hidden["source"])


def test_the_reference_recipe_clears_the_top_of_the_scale():
    """Public case and the hidden cases of two students: every case passes with full credit,
    and the accuracy reached is at the top of the scale or above."""
    top = digits_task.ACCURACY_SCALE[-1][0]
    reports = harness.grade_everywhere(DIGITS, reference_of(DIGITS), DIGIT_SEEDS)
    for report in reports:
        assert report.passed and report.score == 1.0, report.text()
        assert _credits(report) == [1.0] * len(report.cases)
        for case in report.cases:
            accuracy = train_checks.HeldOutAccuracy.accuracy(case.got, _case_of(report, case))
            assert accuracy >= top
            # the measured value the course's leaderboards rank (Check.measure), in the report's data
            assert case.to_dict()["measure"] == {"name": "accuracy", "value": pytest.approx(100 * accuracy),
                                                 "unit": "%", "better": "higher"}


def _case_of(report, result):
    spec = check_of(DIGITS)
    cases = spec.hidden_cases(np.random.default_rng(report.seed)) if report.hidden else spec.public_cases()
    return cases[result.index]


@pytest.mark.parametrize("name", [m.name for m in check_of(DIGITS).bank])
def test_a_broken_recipe_falls_below_the_scale(name):
    """No normalisation, or a learning rate 100 times too large: every case fails and earns
    nothing (the accuracy is far below the bottom of the scale)."""
    mistake = check_of(DIGITS).mistake(name)
    bottom = digits_task.ACCURACY_SCALE[0][0]
    for report in harness.grade_everywhere(DIGITS, mistake.function, DIGIT_SEEDS):
        assert not report.passed and report.score == 0.0, report.text()
        for case in report.cases:
            assert train_checks.HeldOutAccuracy.accuracy(case.got, _case_of(report, case)) < bottom
            assert "below 97 %, the top of the scale" in case.message
            if train_checks.HeldOutAccuracy.accuracy(case.got, _case_of(report, case)) < 0.3:
                assert "diverged" in case.message


def test_train_digits_stub_scores_zero():
    harness.assert_stub_scores_zero(DIGITS, DIGIT_SEEDS)


def _four_percent_worse(x_train, y_train, rng=None):
    """The reference recipe (its unregistered twin: a candidate may not call the registered
    one) with 4 % of its predictions shifted to the next label."""
    predict = digits_task.train_cnn(x_train, y_train, rng)

    def spoiled(x):
        labels = np.array(predict(x))
        k = int(0.04 * len(labels))
        labels[:k] = (labels[:k] + 1) % 10
        return labels
    return spoiled


def test_partial_credit_follows_the_scale():
    """A recipe between the corners of the scale earns the scale's share, not 0 or 1."""
    worse = _four_percent_worse
    for report in harness.grade_everywhere(DIGITS, worse, DIGIT_SEEDS[:1]):
        (result,) = report.cases
        accuracy = train_checks.HeldOutAccuracy.accuracy(result.got, _case_of(report, result))
        assert not report.passed
        assert result.credit is not None and 0.0 < result.credit < 1.0, result.message
        assert report.score == pytest.approx(train_checks.ACCURACY.credit(accuracy))
        assert report.to_dict()["cases"][0]["credit"] == pytest.approx(result.credit, abs=1e-6)


def test_held_out_digits_differ_per_student_and_never_enter_the_sandbox():
    from cvkit.data import digits

    spec = check_of(DIGITS)
    (a, _), (b, _) = digits(flatten=False)
    known = np.concatenate([a, b]).reshape(len(a) + len(b), -1)
    drawn = []
    for student in ("student-a", "student-b"):
        seed = hidden_seed(DIGITS, student=student, salt="course-salt")
        (case,) = spec.hidden_cases(np.random.default_rng(seed))
        (again,) = spec.hidden_cases(np.random.default_rng(seed))
        x_train, y_train, x_eval, _ = case.args
        assert np.array_equal(x_eval, again.args[2]) and np.array_equal(case.truth, again.truth)
        assert case.truth.shape == (len(x_eval),) and not case.kwargs
        # the labels to predict are nowhere in what the sandbox receives
        assert not any(isinstance(arg, np.ndarray) and arg.shape == case.truth.shape and np.array_equal(arg, case.truth)
                       for arg in case.args)
        assert len(y_train) == len(x_train) and len(y_train) + len(case.truth) == len(known)
        # every image to predict differs from every digit of cvkit.data.digits (whatever the camera)
        flat = x_eval.reshape(len(x_eval), -1)
        standard = (flat - flat.mean(axis=1, keepdims=True)) / flat.std(axis=1, keepdims=True)
        ref = (known - known.mean(axis=1, keepdims=True)) / (known.std(axis=1, keepdims=True))
        nearest = np.min(((standard[:, None, :] - ref[None, :50, :]) ** 2).sum(-1), axis=1)
        assert np.all(nearest > 0)
        drawn.append((x_train, x_eval, case.truth))
    (t1, e1, y1), (t2, e2, y2) = drawn
    assert not np.array_equal(e1, e2) and not np.array_equal(y1, y2)
    assert not np.array_equal(t1, t2)


def test_a_predict_of_the_wrong_shape_fails_with_a_message():
    def wrong(x_train, y_train, rng=None):
        return lambda x: np.zeros((len(x), 10))

    report = evaluate(DIGITS, wrong)
    assert not report.passed and report.score == 0.0
    assert "one label per image" in report.cases[0].message


def test_in_the_sandbox_a_recipe_below_the_top_keeps_its_visible_point_and_earns_its_share():
    """Trusted grading of the notebook in bubblewrap with a shortened recipe (3 epochs): the
    hidden test earns the share of its points the scale gives, the visible test is not taken
    for memorised answers (a measured case that earned credit counts as telling), and the
    model solution earns everything."""
    import copy

    import nbformat

    from cvkit.course.trusted import grade_notebook

    source = nbformat.read(NOTEBOOK, as_version=4)
    short = copy.deepcopy(source)
    (answer,) = [c for c in short.cells if c.get("metadata", {}).get("nbgrader", {}).get("grade_id") == "train_digits_answer"]
    assert "epochs, batch, lr = 20, 32, 0.3" in answer.source
    answer.source = answer.source.replace("epochs, batch, lr = 20, 32, 0.3", "epochs, batch, lr = 3, 32, 0.3")
    for book, full in ((source, True), (short, False)):
        grade = grade_notebook(book, student="student-a", salt="e2e-salt", source_notebook=source)
        hidden, _ = grade.credit("train_digits_hidden", 4)
        visible_reports = [report for _, report in grade.reports["train_digits_visible"]]
        assert not any("memorised" in case.message for report in visible_reports for case in report.cases)
        assert not any("passes only the public cases (train.train_digits)" in flag for flag in grade.flags)
        if full:
            assert hidden == 4.0 and grade.credit("train_digits_visible", 1)[0] == 1.0
        else:
            assert 0.0 < hidden
