"""The Chapter 6 checks are worth their points (the tests every chapter owes:
``checks_harness.ChapterChecks``), mistakes that hide on natural inputs are still caught, and
the comparators say clearly how outputs differ."""
from __future__ import annotations

import dataclasses
import math

import numpy as np

import cvkit.detection
from cvkit.detection.checks import HoughVotes, RTableClose, ShapeModelClose, VotesAndBest, moved_votes
from cvkit.grading import evaluate

import alternatives_ch06 as alt
import checks_harness as harness
import measured_harness
from checks_harness import EVERY_ID, SEEDS, check_of

CH06 = [
    "detection.match_template", "detection.best_match", "detection.shape_model", "detection.shape_match",
    "detection.hough_lines", "detection.hough_peaks", "detection.ght_build", "detection.ght_detect",
]
#: the measured exercise (§6.0.5): graded by the F1 of the lines it finds
LINES = "detection.find_lines"


class TestChapter06(harness.WholeModuleChecks):
    IDS = CH06
    MEASURED = (LINES,)
    MISTAKES_MAY_CALL = EVERY_ID
    ALTERNATIVES = alt.ALTERNATIVES


def _option(case, name, index, default):
    return case.kwargs.get(name, case.args[index] if len(case.args) > index else default)


def test_hidden_cases_use_every_option_value():
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        tm = check_of("detection.match_template").hidden_cases(rng)
        assert {_option(c, "measure", 2, "zncc") for c in tm} == {"ssd", "sad", "ncc", "zncc"}
        bm = check_of("detection.best_match").hidden_cases(rng)
        assert {c.args[1] for c in bm} == {"ssd", "sad", "ncc", "zncc"}
        sm = check_of("detection.shape_match").hidden_cases(rng)
        assert {_option(c, "polarity", 2, "none") for c in sm} == {"none", "global", "local"}
        gd = check_of("detection.ght_detect").hidden_cases(rng)
        assert any(len(_option(c, "angles", 3, (0.0,))) > 1 for c in gd)
        assert any(len(_option(c, "scales", 2, (1.0,))) > 1 for c in gd)


def test_separating_inputs_are_in_the_hidden_cases():
    """The awkward inputs the mistakes need: flat and all-zero windows (NCC/ZNCC), ties
    (best_match), magnitudes equal to the threshold (shape_model), exact halves at θ = 0 (Hough
    rounding), votes equal to the threshold (peaks), reference points on half pixels (GHT)."""
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        labels = " | ".join(c.label for c in check_of("detection.match_template").hidden_cases(rng))
        assert "constant windows" in labels and "all-zero" in labels
        bm = check_of("detection.best_match").hidden_cases(rng)
        assert any("tied" in c.label for c in bm)
        sm = check_of("detection.shape_model").hidden_cases(rng)
        assert any(np.any(np.hypot(*cvkit.edges.sobel(c.args[0])) == c.args[1]) for c in sm)
        hl = check_of("detection.hough_lines").hidden_cases(rng)
        assert any("exact halves" in c.label for c in hl)
        hp = check_of("detection.hough_peaks").hidden_cases(rng)
        assert any("threshold" in c.kwargs and np.any(np.asarray(c.args[0]) == c.kwargs["threshold"]) for c in hp)
        gd = check_of("detection.ght_detect").hidden_cases(rng)
        assert any("half pixels" in c.label for c in gd)


def test_a_mistake_hidden_by_natural_images_is_still_caught():
    """ZNCC with the image's mean instead of each window's finds the same best match on a
    natural image, yet fails the check (the scores differ)."""
    from cvkit import data

    img = data.camera()[100:180, 150:250]
    tpl = img[30:45, 40:60]
    wrong = check_of("detection.match_template").mistake("image mean subtracted instead of each window's mean").function
    assert cvkit.detection.best_match(wrong(img, tpl), "zncc") == cvkit.detection.best_match(
        cvkit.detection.match_template(img, tpl), "zncc")
    allowing = dataclasses.replace(check_of("detection.match_template"), allowed=EVERY_ID)
    for seed in SEEDS:
        assert not evaluate("detection.match_template", wrong, hidden=True, seed=seed, check=allowing).passed


def test_ght_detect_may_call_canny_but_not_the_reference():
    def cheat(image, rtable, scales=(1.0,), angles=(0.0,), edge_params=None):
        return cvkit.detection.ght_detect(image, rtable, scales, angles, edge_params)

    assert evaluate("detection.ght_detect", cheat).score == 0.0
    assert evaluate("detection.ght_detect", alt.ght_detect).passed       # calls edges.canny


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
def test_shape_model_comparator():
    expected = {"points": np.array([[1.0, 0.0], [0.0, 1.0]]), "directions": np.array([[1.0, 0.0], [0.0, 1.0]]),
                "shape": (2, 3)}
    compare = ShapeModelClose()
    shuffled = {"points": expected["points"][::-1], "directions": expected["directions"][::-1], "shape": [2, 3]}
    assert compare(shuffled, expected) is None
    assert "lacks" in compare({"points": expected["points"]}, expected).message
    assert "shape" in compare({**expected, "shape": (3, 2)}, expected).message
    swapped = {**expected, "points": expected["points"][:, ::-1] + [[0, 1], [0, 0]]}
    assert "control points differ" in compare(swapped, expected).message
    assert "Directions differ" in compare({**expected, "directions": 2 * expected["directions"]}, expected).message
    assert "None" in compare(None, expected).message


def test_rtable_comparator():
    expected = {"bins": 2, "reference": (1.0, 2.0), "table": [np.array([[0.0, 1.0], [1.0, 0.0]]), np.zeros((0, 2))]}
    compare = RTableClose()
    got = {"bins": 2, "reference": (1.0, 2.0), "table": [np.array([[1.0, 0.0], [0.0, 1.0]]), []]}
    assert compare(got, expected) is None
    assert "(y, x)" in compare({**got, "reference": (2.0, 1.0)}, expected).message
    bad = {**got, "table": [np.array([[0.0, -1.0], [1.0, 0.0]]), np.zeros((0, 2))]}
    assert "bin 0" in compare(bad, expected).message
    assert "list of 2" in compare({**got, "table": got["table"][:1]}, expected).message


def test_moved_votes_and_hough_comparator():
    a = np.array([[1, 0], [2, 3], [0, 1]])
    b = np.array([[0, 0], [3, 3], [0, 1]])
    assert moved_votes(a, b, axis=0) == 1.0
    assert math.isinf(moved_votes(a, b[:, ::-1] * 2, axis=0))
    thetas, rhos = np.array([0.0, 0.5]), np.array([-1.0, 0.0, 1.0])
    compare = HoughVotes()
    assert compare((a, thetas, rhos), (a, thetas, rhos)) is None
    assert compare((b, thetas, rhos), (a, thetas, rhos)) is None          # one vote moved: tolerated
    far = np.array([[0, 0], [0, 3], [3, 1]])
    assert "differ" in compare((far, thetas, rhos), (a, thetas, rhos)).message
    assert "integer" in compare((a.astype(float), thetas, rhos), (a, thetas, rhos)).message
    assert "degrees" in compare((a, np.degrees(thetas) + 1, rhos), (a, thetas, rhos)).message
    assert "samples" in compare((a, thetas, rhos[1:]), (a, thetas, rhos)).message


def test_votes_and_best_comparator():
    acc = np.zeros((1, 2, 4, 5))
    acc[0, 1, 2, 3] = 5.0
    acc[0, 0, 1, 1] = 2.0
    expected = (acc, (3, 2, 1.0, 0.5))
    compare = VotesAndBest()
    assert compare((acc.copy(), (3, 2, 1.0, 0.5)), expected) is None
    assert "(y, x)" in compare((acc.copy(), (2, 3, 1.0, 0.5)), expected).message
    other = acc.copy()
    other[0, 1, 2, 3] = 0.0
    other[0, 1, 0, 0] = 5.0
    assert "differ" in compare((other, (0, 0, 1.0, 0.5)), expected).message
    assert "shape" in compare((acc[0], (3, 2, 1.0, 0.5)), expected).message


# --------------------------------------------------------------------------------------------
# the measured exercise: detection.find_lines, graded by the F1 of the lines found
# --------------------------------------------------------------------------------------------
from cvkit.detection import _lines  # noqa: E402
from cvkit.detection import checks as detection_checks  # noqa: E402

LINE_SEEDS = (101, 202)
_line_f1 = detection_checks.LineDetection.f1


def test_the_line_scale_is_the_published_one():
    assert tuple(detection_checks.LINES_F1) == _lines.F1_SCALE == ((0.50, 0.0), (0.70, 0.5), (0.85, 1.0))
    measured_harness.assert_notebook_publishes("ch06_detection", LINES, "find_lines(edges)", detection_checks.LINES_F1,
                                               "F1 of the lines found", _lines.BUDGET_SECONDS)


def test_the_line_check_measures_what_it_should():
    """The reference and another pipeline (θ over [0, π), a relative threshold) clear the top;
    a quarter-turn of θ, no suppression and x/y swapped stay below it; a stub earns 0."""
    measured_harness.assert_measures_what_it_should(LINES, LINE_SEEDS, _line_f1, detection_checks.LINES_F1, "F1",
                                                    alternatives=[alt.find_lines])
    measured_harness.assert_reports_advise(LINES, {"θ only over [0, π/2)": "[−π/2, π/2)",
                                                   "no suppression around a peak": "suppress the bins around"})


def _one_line_short_and_one_invented(edges):
    """The reference's lines, the first one dropped and a line that is not there added: F1
    between the corners of the scale for three to five true lines."""
    found = _lines.strongest_peaks(*_lines.line_votes(edges), threshold=45)   # the reference's unregistered twin
    return np.vstack([found[1:], [[3.0, 0.01]]])


def test_line_partial_credit_follows_the_scale():
    measured_harness.assert_partial_credit_follows_the_scale(LINES, _one_line_short_and_one_invented, 101, _line_f1,
                                                             detection_checks.LINES_F1)


def test_the_matching_of_lines():
    """Tolerances are inclusive; (ρ, θ) and (−ρ, θ ± π) are one line; a true line is matched once."""
    case = detection_checks.MeasuredCase((), {}, truth=np.array([[10.0, -1.5], [40.0, 0.3]]))
    tol_theta = detection_checks.THETA_TOLERANCE
    assert detection_checks.LineDetection.counts([[42.0, 0.3 + 0.99 * tol_theta]], case) == (1, 1, 2)
    assert detection_checks.LineDetection.counts([[42.5, 0.3]], case) == (0, 1, 2)
    assert detection_checks.LineDetection.counts([[-10.0, -1.5 + np.pi]], case) == (1, 1, 2)
    assert detection_checks.LineDetection.counts([[40.0, 0.3], [40.5, 0.31]], case) == (1, 2, 2)
    assert detection_checks.LineDetection.f1([[40.0, 0.3], [10.0, -1.5]], case) == 1.0
    assert detection_checks.LineDetection.f1(np.zeros((0, 2)), case) == 0.0
    report = evaluate(LINES, lambda edges: np.zeros((3, 3)))
    assert not report.passed and "(K, 2)" in report.cases[0].message


def test_line_scenes_differ_per_student_and_their_truth_stays_outside():
    measured_harness.assert_hidden_data_differ_and_truth_stays_outside(LINES, measured_harness.same_input_and_truth)
    for seed in range(6):
        for case in harness.hidden_cases(LINES, seed):
            (edges,) = case.args
            assert edges.shape == (128, 128) and edges.dtype == bool and 3 <= len(case.truth) <= 5
            assert (case.truth[:, 1] < 0).any() and (case.truth[:, 1] >= 0).any()
            for rho, theta in case.truth:             # each true line keeps at least 60 of its pixels
                ys, xs = np.nonzero(edges)
                assert np.sum(np.abs(xs * np.cos(theta) + ys * np.sin(theta) - rho) <= 0.75) >= 60
