"""The Chapter 5 checks are worth their points (the tests every chapter owes:
``checks_harness.ChapterChecks``), mistakes that hide on natural images are still caught, the
comparators say clearly how outputs differ, and the k-d tree — a class — is graded through
``Check.call`` both in this process and in the isolated worker."""
from __future__ import annotations

import dataclasses
import textwrap

import numpy as np
import pytest

import cvkit.features
from cvkit import data
from cvkit.features import checks as ch
from cvkit.features.checks import IndexRows, Keypoints, NeighbourSearch, PointSets
from cvkit.grading import Case, evaluate, instance_call
from cvkit.course.trusted import grade_notebook

import alternatives_ch05 as alt
import checks_harness as harness
from checks_harness import EVERY_ID, SEEDS, check_of

CH05 = [
    "features.moravec", "features.structure_tensor", "features.harris", "features.peaks",
    "features.gaussian_pyramid", "features.dog_pyramid", "features.log_blobs", "features.dog_extrema",
    "features.refine_extremum", "features.is_edge_like", "features.orientations", "features.sift_descriptor",
    "features.sift", "features.match_ratio", "features.KDTree",
]


class _StubTree:
    def __init__(self, points):
        raise NotImplementedError


class TestChapter05(harness.WholeModuleChecks):
    IDS = CH05
    MEASURED = ("features.match_features",)  # §5.14.1: graded by its correct matches, tested below
    MISTAKES_MAY_CALL = EVERY_ID
    TRIVIAL = frozenset({"features.dog_pyramid"})
    ALTERNATIVES = alt.ALTERNATIVES
    EXTRA_ALTERNATIVES = [
        ("features.orientations", alt.orientations_vectorised),
        ("features.sift_descriptor", alt.descriptor_vectorised),
        ("features.KDTree", ch._Tree),  # one point per leaf, cycling axes, heap-based BBF
    ]

    def fingerprint(self, case):
        """The array arguments of a case, positional and keyword, and those inside list arguments."""
        return tuple(item for value in list(case.args) + list(case.kwargs.values())
                     for item in (value if isinstance(value, list) else [value]) if isinstance(item, np.ndarray))

    def stub(self, algorithm_id):
        return _StubTree if algorithm_id == "features.KDTree" else harness.raising_stub


# --------------------------------------------------------------------------------------------
# the cases
# --------------------------------------------------------------------------------------------
def test_hidden_cases_use_every_border_and_option():
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        moravec = check_of("features.moravec").hidden_cases(rng)
        assert {c.kwargs.get("border", "reflect101") for c in moravec} == set(ch.BORDERS)
        pyramid = check_of("features.gaussian_pyramid").hidden_cases(rng)
        assert {c.kwargs.get("upsample", True) for c in pyramid} == {True, False}
        tree = check_of("features.KDTree").hidden_cases(rng)
        assert {c.args[1] for c in tree} == {"query", "query_bbf"}
        assert any(c.args[2].ndim == 1 for c in tree if c.args[1] == "query")
        assert any(c.args[2].ndim == 1 for c in tree if c.args[1] == "query_bbf")
        assert any(c.kwargs.get("max_checks") == 1 for c in tree)
        assert any(c.kwargs.get("max_checks", 0) >= len(c.args[0]) for c in tree)
        sift = check_of("features.sift").hidden_cases(rng)
        assert {c.kwargs.get("upsample", True) for c in sift} == {True, False}
        assert {c.kwargs.get("scales", 3) for c in sift} == {2, 3}


def test_separating_inputs_are_in_the_hidden_cases():
    """The awkward inputs the mistakes need, whatever the seed."""
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        peaks = check_of("features.peaks").hidden_cases(rng)
        # a threshold equal to a peak value (≥ instead of >) and plateaus (strict maxima)
        assert any(np.any(np.asarray(c.args[0]) == c.args[1]) for c in peaks)
        extrema = check_of("features.dog_extrema").hidden_cases(rng)
        assert any(np.all(np.mod(s, 1) == 0) for c in extrema for s in c.args[0] if np.abs(s).max() > 0)
        matches = " | ".join(c.label for c in check_of("features.match_ratio").hidden_cases(rng))
        assert "0.85" in matches and "exactly 0.8" in matches and "d2 = 0" in matches
        edges = " | ".join(c.label for c in check_of("features.is_edge_like").hidden_cases(rng))
        assert "saddle" in edges and "between r and" in edges and "45°" in edges
        orient = " | ".join(c.label for c in check_of("features.orientations").hidden_cases(rng))
        assert "far from the keypoint" in orient and "two directions" in orient


# --------------------------------------------------------------------------------------------
# mistakes that hide, a SIFT built of the student's own pieces
# --------------------------------------------------------------------------------------------
def test_mistakes_hidden_by_natural_images_are_still_caught():
    """On real images, float responses have no plateaus and DoG stacks no ties: strict maxima
    and ≥-comparisons give exactly the right answer there. The hidden cases still catch them."""
    camera = data.resize_half(data.camera())[:96, :96]
    response = cvkit.features.harris(camera)
    strict = check_of("features.peaks").mistake("strict maximum (plateaus dropped)").function
    assert np.array_equal(strict(response, 1e-4), cvkit.features.peaks(response, 1e-4))
    dog = cvkit.features.dog_pyramid(cvkit.features.gaussian_pyramid(camera, octaves=3))
    ties = check_of("features.dog_extrema").mistake("ties accepted (≥ instead of >)").function
    assert np.array_equal(ties(dog, 0.01), cvkit.features.dog_extrema(dog, 0.01))
    for algorithm_id, wrong in (("features.peaks", strict), ("features.dog_extrema", ties)):
        allowing = dataclasses.replace(check_of(algorithm_id), allowed=EVERY_ID)
        for seed in SEEDS:
            assert not evaluate(algorithm_id, wrong, hidden=True, seed=seed, check=allowing).passed


def test_a_sift_built_from_the_students_own_pieces_passes():
    """What the notebook solution does: its own pyramid, extrema, refinement, orientations..."""
    for report in harness.grade_everywhere("features.sift", alt.sift, SEEDS):
        assert report.passed


# --------------------------------------------------------------------------------------------
# comparators
# --------------------------------------------------------------------------------------------
def test_point_sets_messages():
    compare = PointSets(columns=2, ordered=True, what="peaks (x, y)", order_hint="strongest first")
    expected = np.array([[3.0, 1.0], [1.0, 0.0], [0.0, 2.0]])
    assert compare(expected.copy(), expected) is None
    assert "another order" in compare(expected[[1, 0, 2]], expected).message
    assert "strongest first" in compare(expected[[1, 0, 2]], expected).message
    mismatch = compare(expected[:2], expected)
    assert "expected 3, yours 2" in mismatch.message and "First missing: (0, 2)" in mismatch.message
    assert "exchanged" in compare(expected[:, ::-1].copy(), expected).message
    assert "float" in compare(expected.astype(int), expected).message
    assert "(0, 2)" in compare(np.zeros(0), expected).message  # np.array([]) for "none"
    assert compare(np.zeros((0, 2)), np.zeros((0, 2))) is None
    blobs = PointSets(columns=3, atol=1e-9, what="blobs (x, y, σ)")
    got = np.array([[1.0, 2.0, 1.5], [4.0, 4.0, 2.0]])
    assert blobs(got[::-1], got) is None  # order free
    wrong_sigma = got.copy()
    wrong_sigma[1, 2] = 2.8
    assert "1 expected not found" in blobs(wrong_sigma, got).message


def test_index_rows_messages():
    compare = IndexRows(columns=4, names="(octave, scale, row, col)")
    expected = np.array([[0, 1, 2, 3], [0, 1, 4, 2], [1, 2, 3, 3]])
    assert compare(expected.copy(), expected) is None
    assert "not sorted lexicographically" in compare(expected[[1, 0, 2]], expected).message
    mismatch = compare(np.vstack([expected, [[1, 1, 1, 1]]]), expected)
    assert "1 extra" in mismatch.message and "[1, 1, 1, 1]" in mismatch.message
    assert "integer" in compare(expected.astype(float), expected).message
    assert "(N, 4)" in compare(expected[:, :3], expected).message


def test_keypoints_comparator_tolerates_little_and_explains():
    rng = np.random.default_rng(0)
    kp = np.column_stack([rng.uniform(0, 40, 30), rng.uniform(0, 40, 30), rng.uniform(1, 4, 30), rng.uniform(0, 6, 30)])
    de = rng.random((30, 128))
    compare = Keypoints()
    assert compare((kp.copy(), de.copy()), (kp, de)) is None
    shuffled = rng.permutation(30)
    assert compare((kp[shuffled], de[shuffled]), (kp, de)) is None  # any order
    wrapped = kp.copy()
    wrapped[:, 3] += 2 * np.pi
    assert compare((wrapped, de), (kp, de)) is None  # angles modulo 2π
    assert compare((kp[1:], de[1:]), (kp, de)) is None  # 1 of 30 missing: within 5%
    mismatch = compare((kp[3:], de[3:]), (kp, de))
    assert "3 expected ones missing" in mismatch.message
    moved = kp.copy()
    moved[:, :2] += 0.3
    assert "your nearest keypoint" in compare((moved, de), (kp, de)).message
    assert "descriptors" in compare((kp, de[:, :64]), (kp, de)).message
    assert "tuple" in compare(kp, (kp, de)).message
    few = Keypoints()
    assert few((kp[:10][1:], de[:10][1:]), (kp[:10], de[:10])) is not None  # small sets: every keypoint counts


def test_neighbour_search_comparator():
    rng = np.random.default_rng(1)
    points = rng.integers(0, 3, (30, 2)).astype(float)
    queries = rng.integers(0, 3, (5, 2)).astype(float)
    case = Case((points, "query", queries), {"k": 3})
    expected = cvkit.features.KDTree(points).query(queries, 3)
    compare = NeighbourSearch()
    assert compare(expected, expected, case) is None
    flipped = (expected[0], expected[1][:, ::-1].copy())
    mismatch = compare(flipped, expected, case)
    assert mismatch is not None and "smaller index first" in mismatch.message
    floats = rng.random((40, 3)) * 10
    float_case = Case((floats, "query", queries[:, :1].repeat(3, 1)), {"k": 2})
    right = cvkit.features.KDTree(floats).query(float_case.args[2], 2)
    assert "square root" in compare((right[0] ** 2, right[1]), right, float_case).message
    assert "integers" in compare((expected[0], expected[1].astype(float)), expected, case).message
    single = Case((points, "query", queries[0]), {"k": 3})
    assert "(k,)" in compare((expected[0][:1], expected[1][:1]), (expected[0][0], expected[1][0]), single).message
    # BBF: an exact answer within a budget of 1 is impossible; a budget ≥ N must be exact
    wide = rng.random((300, 6))
    q = rng.random((40, 6))
    tiny = Case((wide, "query_bbf", q), {"k": 1, "max_checks": 1})
    ref = cvkit.features.KDTree(wide).query_bbf(q, 1, 1)
    exact = cvkit.features.KDTree(wide).query(q, 1)
    assert compare(ref, ref, tiny) is None
    assert "max_checks = 1" in compare(exact, ref, tiny).message
    full = Case((wide, "query_bbf", q), {"k": 1, "max_checks": 300})
    assert compare(exact, exact, full) is None
    assert "must be exact" in compare(ref, exact, full).message


# --------------------------------------------------------------------------------------------
# grading a class: Check.call
# --------------------------------------------------------------------------------------------
def test_kdtree_check_builds_the_class_and_calls_its_methods():
    spec = check_of("features.KDTree")
    assert spec.call is instance_call
    calls = []

    class Recording(alt.KDTree):
        def __init__(self, points):
            calls.append(("init", np.shape(points)))
            super().__init__(points)

    report = evaluate("features.KDTree", Recording)
    assert report.passed, report.text()
    assert calls and all(c[0] == "init" for c in calls)
    assert "points=array(40, 2) float64, method='query'" in report.cases[0].description


def test_check_call_helpers():
    from cvkit.grading.checks import bind_call, call_target

    def f(x):
        return x + 1

    assert bind_call(None, f) is f  # checks without `call` run the candidate as before
    bound = bind_call(instance_call, alt.KDTree)
    assert bound.__module__ == alt.KDTree.__module__  # the guard's "own code" is the candidate's
    d, i = bound(np.eye(3), "query", np.zeros(3), k=2)
    assert d.shape == (2,) and i.tolist() == [0, 1]
    assert call_target(None) is None
    assert call_target(instance_call) == "cvkit.grading.runtime.adapters:instance_call"
    with pytest.raises(ValueError, match="cvkit.grading.runtime"):
        call_target(lambda cls, *a: cls(*a))
    with pytest.raises(ValueError, match="cvkit.grading.runtime"):
        call_target(f)  # it would not exist in the grading sandbox


def test_a_function_instead_of_a_class_is_told_what_is_wrong():
    def KDTree(points, method, q, k=1, max_checks=200):  # noqa: N802 - what a confused student writes
        return np.zeros(k), np.zeros(k, dtype=np.int64)

    report = evaluate("features.KDTree", KDTree)
    assert report.score == 0.0
    assert "raised TypeError" in report.cases[0].message and "missing 2 required" in report.cases[0].message


def test_kdtree_missing_method_is_reported():
    class OnlyExact(alt.KDTree):
        query_bbf = property(lambda self: (_ for _ in ()).throw(AttributeError("no query_bbf")))

    report = evaluate("features.KDTree", OnlyExact)
    assert not report.passed
    assert any("AttributeError" in c.message for c in report.cases if not c.passed)
    assert all(c.passed for c in report.cases if "query_bbf" not in c.description)


def test_kdtree_must_not_modify_its_points():
    class Sorting(alt.KDTree):
        def __init__(self, points):
            points.sort(axis=0)  # the student's code sorts the caller's array in place
            super().__init__(points)

    harness.assert_scores_zero("features.KDTree", Sorting, "modified its input 'points'")


SETUP = textwrap.dedent("""\
    import numpy as np
    from cvkit.grading import check
    from cvkit.registry import student
    """)


def _cell(source, grade_id=None, solution=False, grade=False, points=None):
    meta = {}
    if grade_id:
        meta = {"nbgrader": {"grade_id": grade_id, "solution": solution, "grade": grade, "locked": not solution,
                             "schema_version": 3, **({"points": points} if points is not None else {})}}
    return {"cell_type": "code", "source": source, "metadata": meta, "outputs": [], "execution_count": None}


def _tree_notebook(answer):
    return {"cells": [
        _cell(SETUP, "setup"),
        _cell(answer, "kdtree_answer", solution=True),
        _cell('check("features.KDTree", KDTree)', "kdtree_visible", grade=True, points=1),
        _cell('### BEGIN HIDDEN TESTS\ncheck("features.KDTree", KDTree, hidden=True, points=3)\n### END HIDDEN TESTS',
              "kdtree_hidden", grade=True, points=3),
    ], "metadata": {}, "nbformat": 4, "nbformat_minor": 5}


BRUTE_FORCE_CLASS = textwrap.dedent('''\
    @student("features.KDTree")
    class KDTree:
        """Brute force behind a k-d tree's interface: exact queries right, BBF ignoring its budget."""
        def __init__(self, points):
            self.points = np.asarray(points, dtype=float)

        def query(self, q, k=1):
            q = np.asarray(q, dtype=float)
            d = np.sqrt(((np.atleast_2d(q)[:, None, :] - self.points[None]) ** 2).sum(-1))
            i = np.argsort(d, axis=1, kind="stable")[:, :k]
            out = np.take_along_axis(d, i, 1), i
            return (out[0][0], out[1][0]) if q.ndim == 1 else out

        def query_bbf(self, q, k=2, max_checks=200):
            return self.query(q, k)
    ''')


def test_the_trusted_worker_grades_a_class():
    """The isolated worker imports Check.call before cvkit is hidden, builds the student's class
    and returns plain arrays: exact queries pass, the budget-ignoring BBF fails by name."""
    nb = _tree_notebook(BRUTE_FORCE_CLASS)
    result = grade_notebook(nb, student="tree", salt="ch05", source_notebook=nb)
    assert result.worker_problem is None and not result.cell_errors
    (call, visible), = result.reports["kdtree_visible"]
    assert not visible.passed and visible.mistake == "BBF ignores max_checks"
    assert [c.passed for c in visible.cases][:2] == [True, True]
    (call, hidden), = result.reports["kdtree_hidden"]
    assert 0.0 < hidden.score < 1.0
    points, reasons = result.credit("kdtree_hidden", 3)
    assert 0.0 < points < 3.0
    # the honest alternative gets full marks through the same path
    honest = textwrap.dedent('''\
        import heapq
        import math

        @student("features.KDTree")
        ''') + textwrap.dedent(_class_source(alt.KDTree))
    nb = _tree_notebook(honest)
    result = grade_notebook(nb, student="tree", salt="ch05", source_notebook=nb)
    assert result.credit("kdtree_visible", 1) == (1.0, [])
    assert result.credit("kdtree_hidden", 3)[0] == 3.0


def _class_source(cls) -> str:
    import inspect

    return inspect.getsource(cls)


# --------------------------------------------------------------------------------------------
# the measured exercise: features.match_features, graded by its correct matches under the warp
# --------------------------------------------------------------------------------------------
from cvkit.features import _measured as match_task  # noqa: E402
from cvkit.features.checks import MATCH_COUNT_SCALE, MATCH_PRECISION_SCALE  # noqa: E402

try:
    from . import measured_harness as measured
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    import measured_harness as measured

MATCH = "features.match_features"
MATCH_SEEDS = SEEDS[:2]


def _correct(output, case):
    return match_task.correct_matches(output, case.truth)[0]


def _precision(output, case):
    correct, returned = match_task.correct_matches(output, case.truth)
    return correct / returned if returned else 0.0


def test_match_features_notebook_publishes_both_scales_and_the_budget():
    assert MATCH_COUNT_SCALE.corners == match_task.COUNT_SCALE and MATCH_PRECISION_SCALE.corners == match_task.PRECISION_SCALE
    for scale, words in ((MATCH_COUNT_SCALE, "correct matches in a pair"),
                         (MATCH_PRECISION_SCALE, "precision (correct / returned)")):
        measured.assert_notebook_publishes("ch05_features", MATCH, "match_features(image1, image2)", scale, words,
                                           match_task.BUDGET_SECONDS)
    assert match_task.TOLERANCE == 2.0


def test_a_case_earns_the_smaller_share_of_the_two_scales():
    (case,) = check_of(MATCH).public_cases()
    points1, points2 = match_task.sift_matches(*case.args)
    good = match_task._apply(case.truth, points1)            # every match made exact
    rng = np.random.default_rng(3)
    for keep, junk in ((10, 0), (30, 12), (6, 30)):
        wrong = rng.uniform(0, 190, (junk, 2))
        answer = (np.r_[points1[:keep], wrong], np.r_[good[:keep], wrong[::-1] + 7.0])
        correct, returned = match_task.correct_matches(answer, case.truth)
        assert correct == len(np.unique(np.round(points1[:keep] * 2), axis=0))
        expected = min(MATCH_COUNT_SCALE.credit(correct), MATCH_PRECISION_SCALE.credit(correct / returned))
        assert check_of(MATCH).credit(answer, case) == pytest.approx(expected)
    # repeating one good match earns nothing more
    repeated = (np.repeat(points1[:1], 50, axis=0), np.repeat(good[:1], 50, axis=0))
    assert match_task.correct_matches(repeated, case.truth) == (1, 1)


def test_the_reference_clears_both_scales_on_thirty_pairs():
    """The claim of the reference's docstring, on 30 pairs: a margin on both scales."""
    counts, precisions = [], []
    for seed in range(30):
        image1, image2, H, _ = match_task.warped_pair(seed)
        correct, returned = match_task.correct_matches(match_task.match_features(image1, image2), H)
        counts.append(correct)
        precisions.append(correct / returned)
    assert min(counts) >= MATCH_COUNT_SCALE.top + 4, min(counts)
    assert min(precisions) >= MATCH_PRECISION_SCALE.top + 0.1, min(precisions)


def test_match_features_measures_what_it_should():
    measured.assert_clears_the_top(MATCH, MATCH_SEEDS, _correct, MATCH_COUNT_SCALE)
    measured.assert_measures_what_it_should(MATCH, MATCH_SEEDS, _precision, MATCH_PRECISION_SCALE, "precision",
                                            alternatives=(alt.match_features,))


def test_match_features_pairs_differ_per_student_and_the_warp_stays_with_the_grader():
    measured.assert_hidden_data_differ_and_truth_stays_outside(MATCH, measured.same_input_and_truth)
    for case in check_of(MATCH).hidden_cases(np.random.default_rng(SEEDS[0])):
        image1, image2 = case.args
        assert image1.shape == image2.shape == (match_task.SIZE, match_task.SIZE)
        assert case.truth.shape == (3, 3) and case.truth[2, 2] == 1.0
        # the warp is what the images show: the centre of image 1 reads the same in image 2
        x, y = match_task._apply(case.truth, np.array([[95.5, 95.5]]))[0]
        assert abs(image1[95, 95] - image2[int(round(y)), int(round(x))]) < 0.25


def _half_wrong(image1, image2):
    """The reference's matches with every third point of image 2 moved 10 px: precision 2/3."""
    points1, points2 = match_task.sift_matches(image1, image2)
    points2 = points2.copy()
    points2[::3] += 10.0
    return points1, points2


def test_match_features_partial_credit_follows_the_scales():
    measured.assert_partial_credit_follows_the_scale(MATCH, _half_wrong, MATCH_SEEDS[0], _precision,
                                                     MATCH_PRECISION_SCALE)


def test_matches_that_are_not_two_point_arrays_fail_with_a_message():
    report = evaluate(MATCH, lambda image1, image2: np.zeros((3, 4)))
    assert not report.passed and report.score == 0.0
    assert "(points1, points2)" in report.cases[0].message
