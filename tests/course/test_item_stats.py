"""Item analysis on simulated cohorts (no grading): answers drawn with known per-exercise
facility, a planted mistake rate per exercise and planted failure rates per case parameter; the
analysis must recover them, and each figure must agree with an independent computation (SciPy,
the closed forms of Cronbach's α)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

from cvkit.course.item_stats import (MIN_CORRELATION, MIN_DISCRIMINATION, ExerciseStats, Response, analyse,
                                     cronbach_alpha, parameters_of, upper_lower)

#: exercise → planted facility (pass rate), loading on ability, mistakes planted among failures
PLANTED = {
    "easy": (0.90, 0.8, {"off by one": 0.5}),
    "pad": (0.75, 0.8, {"wrong border": 0.6, "transposed": 0.2}),
    "gauss": (0.60, 0.8, {"sigma as variance": 0.5}),
    "noise": (0.45, 0.0, {}),          # answers unrelated to ability: does not discriminate
    "hard": (0.30, 0.8, {"forgot to normalise": 0.7, "float32": 0.1}),
}
POINTS = 3.0
N = 600  # students: a planted share's binomial standard deviation is at most 2 points
#: the partial-credit exercise's cases: label → planted failure probability
CASES = {"radius 1, zero": 0.10, "radius (2, 4), reflect101": 0.80, "radius 1, reflect101": 0.80,
         "radius 2, replicate": 0.10, "uint8 image, zero": 0.10}


def cohort(n: int, seed: int = 7):
    """Simulated students: pass/fail exercises through a Gaussian copula (pass when
    ρθ + √(1−ρ²)ε exceeds the planted quantile, so the pass rate is exactly the planted facility in
    expectation), and one partial-credit exercise whose cases fail with the planted rates."""
    rng = np.random.default_rng(seed)
    ability = rng.standard_normal(n)
    responses = {}
    for i in range(n):
        student = f"s{i:03d}"
        row = {}
        for name, (facility, loading, mistakes) in PLANTED.items():
            z = loading * ability[i] + np.sqrt(1 - loading ** 2) * rng.standard_normal()
            passed = z > sps.norm.ppf(1 - facility)
            named = []
            if not passed:
                u, edge = rng.random(), 0.0
                for mistake, rate in mistakes.items():
                    if edge <= u < edge + rate:
                        named = [mistake]
                    edge += rate
            attempted = passed or bool(named) or rng.random() < 0.5
            row[name] = Response(POINTS if passed else 0.0, POINTS, mistakes=named,
                                 problems=[] if attempted else ["not implemented yet"], attempted=attempted,
                                 flagged=bool(rng.random() < 0.05))
        cases = [(label, bool(rng.random() >= rate)) for label, rate in CASES.items()]
        row["borders"] = Response(2.0 * sum(p for _, p in cases) / len(cases), 2.0, cases=cases)
        responses[student] = row
    return responses


@pytest.fixture(scope="module")
def big():
    responses = cohort(N)
    return responses, analyse("ch99", responses)


def _column(responses, name):
    return np.array([responses[s][name].score for s in responses], dtype=float)


def test_facility_ranking_and_values_are_recovered(big):
    responses, result = big
    by_name = {e.name: e for e in result.exercises}
    planted_order = sorted(PLANTED, key=lambda name: -PLANTED[name][0])
    found_order = sorted(PLANTED, key=lambda name: -by_name[name].facility)
    assert found_order == planted_order
    for name, (facility, _, _) in PLANTED.items():
        assert by_name[name].facility == pytest.approx(_column(responses, name).mean() / POINTS)
        assert abs(by_name[name].facility - facility) < 4 * np.sqrt(facility * (1 - facility) / N)
        assert by_name[name].graded == by_name[name].students == N


def test_planted_mistake_shares_are_recovered_within_five_points(big):
    responses, result = big
    by_name = {e.name: e for e in result.exercises}
    for name, (facility, _, mistakes) in PLANTED.items():
        found = {m.name: m for m in by_name[name].mistakes}
        assert set(found) == set(mistakes)
        for mistake, rate in mistakes.items():
            exact = sum(mistake in responses[s][name].mistakes for s in responses)
            assert found[mistake].count == exact and found[mistake].of == N
            assert abs(found[mistake].share - (1 - facility) * rate) <= 0.05, (name, mistake)
        # failures matching no mistake: attempted, lost points, nothing named
        unexplained = sum(1 for s in responses if responses[s][name].score < POINTS and not responses[s][name].mistakes
                          and responses[s][name].attempted)
        assert by_name[name].unexplained.count == unexplained
        planted_unexplained = (1 - facility) * (1 - sum(mistakes.values())) * 0.5
        assert abs(by_name[name].unexplained.share - planted_unexplained) <= 0.05
        assert abs(by_name[name].not_attempted.share - planted_unexplained) <= 0.05
        assert abs(by_name[name].flagged.share - 0.05) <= 0.05
    pad = by_name["pad"].mistakes
    assert [m.name for m in pad] == ["wrong border", "transposed"]  # most frequent first


def test_item_rest_correlation_is_scipys_point_biserial_and_pearson(big):
    responses, result = big
    names = [e.name for e in result.exercises]
    matrix = np.array([[responses[s][e].score for e in names] for s in responses])
    for j, exercise in enumerate(result.exercises):
        rest = np.delete(matrix, j, axis=1).sum(axis=1)
        if exercise.name in PLANTED:
            assert exercise.correlation_kind == "point-biserial"
            expected = sps.pointbiserialr(matrix[:, j] > 0, rest)[0]
        else:
            assert exercise.correlation_kind == "Pearson"
            expected = sps.pearsonr(matrix[:, j], rest)[0]
        assert exercise.rest_correlation == pytest.approx(expected, abs=1e-10)
    by_name = {e.name: e for e in result.exercises}
    # the exercise unrelated to ability discriminates least, and about not at all
    assert min(by_name, key=lambda n: by_name[n].rest_correlation) == "noise"
    assert abs(by_name["noise"].rest_correlation) < 0.15 and abs(by_name["noise"].discrimination) < 0.15
    for name in ("easy", "pad", "gauss", "hard"):
        assert by_name[name].rest_correlation > 0.2 and by_name[name].discrimination > 0.15


def test_upper_lower_discrimination_against_a_direct_count(big):
    responses, result = big
    names = [e.name for e in result.exercises]
    students = list(responses)
    group = round(0.27 * len(students))
    for exercise in result.exercises:
        rest = {s: sum(responses[s][e].score for e in names if e != exercise.name) for s in students}
        ranked = sorted(students, key=lambda s: (-round(rest[s], 9), students.index(s)))
        upper = np.mean([responses[s][exercise.name].score for s in ranked[:group]])
        lower = np.mean([responses[s][exercise.name].score for s in ranked[-group:]])
        assert exercise.discrimination == pytest.approx((upper - lower) / exercise.max_score)


def test_cronbach_alpha_matches_the_closed_forms(big):
    responses, result = big
    names = [e.name for e in result.exercises]
    matrix = np.array([[responses[s][e].score for e in names] for s in responses])
    covariance = np.cov(matrix, rowvar=False)
    k = len(names)
    assert result.alpha == pytest.approx(k / (k - 1) * (1 - np.trace(covariance) / covariance.sum()), abs=1e-12)
    # worked by hand: identical items → α = 1; items [2,1,0] and [1,1,1]: Σσ²ᵢ = 1 = σ²ₜ → α = 0
    assert cronbach_alpha(np.array([[1, 1], [0, 0], [2, 2], [1, 1]])) == pytest.approx(1.0)
    assert cronbach_alpha(np.array([[2, 1], [1, 1], [0, 1]])) == pytest.approx(0.0)
    # standardised check: k parallel items with correlation ρ → α = kρ/(1+(k−1)ρ) (Spearman–Brown)
    rng = np.random.default_rng(3)
    common = rng.standard_normal(200_000)
    items = np.stack([0.6 * common + 0.8 * rng.standard_normal(common.size) for _ in range(4)], axis=1)
    rho = 0.36
    assert cronbach_alpha(items) == pytest.approx(4 * rho / (1 + 3 * rho), abs=0.01)


def test_failure_rate_per_case_parameter_recovers_the_planted_rates(big):
    responses, result = big
    borders = next(e for e in result.exercises if e.name == "borders")
    found = {p.name: p for p in borders.parameters}
    # every part of a label of several: radius 1, zero, radius (2, 4), reflect101, radius 2, replicate, uint8 image
    assert set(found) == {"reflect101", "zero", "radius 1", "radius (2, 4)", "radius 2", "replicate", "uint8 image"}
    assert {p.name for p in borders.parameters[:2]} == {"reflect101", "radius (2, 4)"}  # worst first (80 %)
    assert abs(found["reflect101"].share - 0.80) <= 0.05 and found["reflect101"].of == 2 * N
    assert abs(found["zero"].share - 0.10) <= 0.05
    assert abs(found["radius 1"].share - 0.45) <= 0.05
    exact = sum(not passed for s in responses for label, passed in responses[s]["borders"].cases if "reflect101" in label)
    assert found["reflect101"].count == exact
    per_case = {c.name: c for c in borders.cases}
    for label, rate in CASES.items():
        assert per_case[label].of == N and abs(per_case[label].share - rate) <= 0.05


def test_score_distribution_counts_every_complete_student(big):
    responses, result = big
    bands = result.distribution
    assert sum(b.count for b in bands) == N == result.complete
    totals = np.array(result.totals) / result.max_total
    assert bands[9].count == int(np.sum(totals >= 0.9))
    assert bands[0].count == int(np.sum(totals < 0.1))


def test_a_label_of_one_part_is_not_repeated_as_a_parameter():
    responses = {f"s{i}": {"a": Response(0.0, 1.0, cases=[("size 1", i % 2 == 0), ("size 2, float", False),
                                                          ("size 3, float", True)])} for i in range(4)}
    a = analyse("ch01", responses).exercises[0]
    assert {p.name: (p.count, p.of) for p in a.parameters} == {"float": (4, 8), "size 2": (4, 4), "size 3": (0, 4)}
    assert {c.name: (c.count, c.of) for c in a.cases} == {"size 1": (2, 4), "size 2, float": (4, 4),
                                                           "size 3, float": (0, 4)}


def test_labels_split_at_commas_outside_brackets():
    assert parameters_of("radius (2, 4), reflect101") == ["radius (2, 4)", "reflect101"]
    assert parameters_of("colour image, int radius (the channel axis is not padded)") == [
        "colour image", "int radius (the channel axis is not padded)"]
    assert parameters_of("") == []
    assert parameters_of("a, [1, 2], a") == ["a", "[1, 2]"]


# ------------------------------------------------------------------ bad input: words, never numbers
def test_empty_class_gives_a_line_not_a_number():
    result = analyse("ch01", {})
    assert result.students == 0 and result.exercises == [] and result.alpha is None
    assert result.warnings == ["ch01: no graded submission — nothing to analyse"]


def test_one_student_gives_counts_and_a_warning():
    result = analyse("ch01", {"ada": {"a": Response(1.0, 2.0, mistakes=["m"]), "b": Response(2.0, 2.0)}})
    assert result.alpha is None and any("one student" in w for w in result.warnings)
    a = result.exercises[0]
    assert a.facility == 0.5 and a.rest_correlation is None and a.discrimination is None
    assert a.mistakes[0].count == 1 and a.mistakes[0].share == 1.0


def test_small_class_has_no_correlation_and_says_so():
    responses = {s: v for s, v in list(cohort(MIN_CORRELATION - 1).items())}
    result = analyse("ch01", responses)
    assert result.alpha is None
    assert all(e.rest_correlation is None and e.discrimination is None for e in result.exercises)
    assert any(f"at least {MIN_CORRELATION}" in w for w in result.warnings)
    middle = analyse("ch01", cohort(MIN_DISCRIMINATION - 1))
    assert middle.alpha is not None and all(e.discrimination is None for e in middle.exercises)
    assert any(f"at least {MIN_DISCRIMINATION}" in w for w in middle.warnings)


def test_constant_scores_give_no_correlation_nor_alpha():
    responses = {f"s{i}": {"a": Response(1.0, 1.0), "b": Response(1.0, 1.0)} for i in range(30)}
    result = analyse("ch01", responses)
    assert result.alpha is None and any("same total" in w for w in result.warnings)
    assert all(e.rest_correlation is None and e.warnings for e in result.exercises)
    assert all(e.discrimination == 0.0 and e.facility == 1.0 for e in result.exercises)


def test_exercise_still_to_mark_is_left_out_of_the_correlations():
    responses = cohort(40)
    responses["s000"]["easy"] = Response(None, POINTS)
    result = analyse("ch01", responses)
    assert result.complete == 39 and result.students == 40
    easy = next(e for e in result.exercises if e.name == "easy")
    assert easy.students == 40 and easy.graded == 39
    assert any("still to mark" in w for w in result.warnings)


def test_pure_helpers_refuse_to_make_up_numbers():
    assert upper_lower([1.0], [1.0], 1.0) is None
    assert upper_lower([1.0, 0.0], [2.0, 1.0], 0.0) is None
    assert cronbach_alpha(np.ones((5, 1))) is None


def test_a_plot_that_cannot_be_drawn_leaves_a_line_and_the_tables(tmp_path, monkeypatch):
    from cvkit.course import item_analysis

    def broken(*args, **kwargs):
        raise RuntimeError("no backend")

    monkeypatch.setattr(item_analysis, "_png", broken)
    page = item_analysis.write_html([analyse("ch01", cohort(30))], tmp_path / "page.html").read_text()
    assert page.count("not drawn (RuntimeError: no backend)") == 4 and "<img" not in page
    assert "<table class=\"exercises\">" in page


def test_reading_points_at_the_planted_weak_and_easy_exercises(big):
    from cvkit.course.item_stats import reading

    _, result = big
    notes = {e.name: reading(e) for e in result.exercises}
    assert any(n.startswith("weak discrimination") for n in notes["noise"])
    for e in result.exercises:  # the thresholds as documented
        assert any(n.startswith("very easy") for n in notes[e.name]) == (e.facility > 0.9)
        assert any(n.startswith("hard") for n in notes[e.name]) == (e.facility < 0.3)
    assert any(n.startswith("hard") for n in notes["hard"])
    assert not any("discrimination" in n for n in notes["pad"] + notes["gauss"])
    # the partial-credit exercise has no named mistake at all: most failures are unexplained
    assert any("without a named mistake" in n for n in notes["borders"])
    flipped = ExerciseStats("x", 1.0, facility=0.5, discrimination=-0.3)
    assert reading(flipped) == ["negative discrimination: stronger students did worse; check the statement and the "
                                "check"]


def test_an_exercise_nobody_has_a_mark_for_yet_does_not_void_the_class_statistics():
    responses = cohort(40)
    for row in responses.values():
        row["written"] = Response(None, 2.0)  # a written answer, still to mark by hand for everyone
    result = analyse("ch01", responses)
    assert result.complete == 40 and result.alpha is not None
    assert result.max_total == len(PLANTED) * POINTS + 2.0  # the other exercises only
    written = next(e for e in result.exercises if e.name == "written")
    assert written.graded == 0 and written.facility is None and written.rest_correlation is None
    assert any("no score yet for written" in w for w in result.warnings)
    # nothing scored at all: no totals, no distribution, no α
    nothing = analyse("ch01", {f"s{i}": {"written": Response(None, 2.0)} for i in range(12)})
    assert nothing.totals == [] and nothing.complete == 0 and nothing.alpha is None
    assert all(band.count == 0 for band in nothing.distribution)


def test_the_plots_of_unchanged_figures_are_kept_not_drawn_again(tmp_path, monkeypatch):
    """Every grading run exports every chapter: an assignment whose figures did not change is
    not drawn again, and the page is the same byte for byte as one drawn afresh."""
    from cvkit.course import item_analysis

    drawn = []
    plain = item_analysis._plots
    monkeypatch.setattr(item_analysis, "_plots", lambda result: drawn.append(result.assignment) or plain(result))
    kept = tmp_path / "kept"
    results = [analyse("ch01", cohort(30)), analyse("ch02", cohort(25, seed=3))]
    fresh = item_analysis.write_html(results, tmp_path / "fresh.html").read_bytes()
    assert drawn == ["ch01", "ch02"]
    drawn.clear()
    first = item_analysis.write_html(results, tmp_path / "first.html", plots=kept, prune=True).read_bytes()
    again = item_analysis.write_html(results, tmp_path / "again.html", plots=kept, prune=True).read_bytes()
    assert drawn == ["ch01", "ch02"]  # drawn once, then read
    assert first == again == fresh
    assert len(list(kept.glob("*.html"))) == 2
    # one student more in ch02: its plots are drawn again; ch01's are read
    drawn.clear()
    changed = [results[0], analyse("ch02", cohort(26, seed=3))]
    page = item_analysis.write_html(changed, tmp_path / "changed.html", plots=kept, prune=True).read_bytes()
    assert drawn == ["ch02"]
    assert page == item_analysis.write_html(changed, tmp_path / "changed_fresh.html").read_bytes()
    assert len(list(kept.glob("*.html"))) == 2  # the old ch02 plots are gone (pruned)
    # an export of some assignments keeps the others' plots
    item_analysis.write_html(changed[:1], tmp_path / "one.html", plots=kept, prune=False)
    assert len(list(kept.glob("*.html"))) == 2


def test_a_plot_that_could_not_be_drawn_is_not_kept(tmp_path, monkeypatch):
    from cvkit.course import item_analysis

    def broken(*args, **kwargs):
        raise RuntimeError("no backend")

    monkeypatch.setattr(item_analysis, "_png", broken)
    kept = tmp_path / "kept"
    page = item_analysis.write_html([analyse("ch01", cohort(30))], tmp_path / "page.html", plots=kept).read_text()
    assert "not drawn (RuntimeError: no backend)" in page
    assert not kept.exists() or not list(kept.glob("*.html"))  # nothing kept of a failed plot
    monkeypatch.undo()
    page = item_analysis.write_html([analyse("ch01", cohort(30))], tmp_path / "page.html", plots=kept).read_text()
    assert "not drawn" not in page and "<img" in page
