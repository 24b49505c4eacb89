"""Feedback a student can act on (issue 18): plain words first, the shape of the error, crashes
explained, structural mistakes named before normalisation advice, one plain line per student ×
exercise in the instructor's summary.

Every wrong attempt here is written the way a student would write it (no call to the reference
of the graded algorithm); each test says which words its report must contain.
"""
from __future__ import annotations

import json
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cvkit.edges  # noqa: F401  (registers the checks used below)
import cvkit.filters  # noqa: F401
import cvkit.warp  # noqa: F401
from cvkit import registry
from cvkit.grading import evaluate
from cvkit.grading.diagnose import describe_difference, diagnose, explain_exception, image_variants, locate
from cvkit.grading.engine import CheckFailed
from cvkit.grading.report import MIME_TYPE
from cvkit.grading.runtime.guard import run_guarded

TECHNICAL = re.compile(r"\b(rtol|atol)\b|tolerance|Mismatched elements")


def _failing(report):
    return [c for c in report.cases if not c.passed]


def _assert_plain(report):
    """What a student reads first carries no numpy.testing vocabulary."""
    assert not TECHNICAL.search(report.summary()), report.summary()
    for case in _failing(report):
        assert not TECHNICAL.search(case.message.splitlines()[0]), case.message


# --------------------------------------------------------------------------------------------
# student-like attempts
# --------------------------------------------------------------------------------------------
_NP_MODES = {"zero": "constant", "replicate": "edge", "reflect": "symmetric", "reflect101": "reflect"}


def _indices(n, r, border):
    i = np.arange(-r, n + r)
    if border == "zero":
        return np.clip(i, 0, n - 1), (i < 0) | (i >= n)
    if border == "replicate":
        return np.clip(i, 0, n - 1), None
    if border == "reflect":
        i = np.where(i < 0, -i - 1, i)
        return np.where(i >= n, 2 * n - 1 - i, i), None
    # reflect101 mirrored off by one: −i + 1 instead of −i (edcb|abcd… instead of dc|abcd|cb)
    i = np.where(i < 0, -i + 1, i)
    return np.clip(np.where(i >= n, 2 * n - 3 - i, i), 0, n - 1), None


def pad_reflect101_off_by_one(image, radius, border="reflect101"):
    img = np.asarray(image, dtype=float)
    ry, rx = (radius, radius) if np.isscalar(radius) else radius
    rows, zero_rows = _indices(img.shape[0], ry, border)
    cols, zero_cols = _indices(img.shape[1], rx, border)
    out = img[rows][:, cols]
    if border == "zero":
        out[zero_rows] = 0
        out[:, zero_cols] = 0
    return out


def _windows(image, size, border, extra=0):
    img = np.asarray(image, dtype=float)
    r = size // 2 + extra
    width = ((r, r), (r, r)) + ((0, 0),) * (img.ndim - 2)
    padded = np.pad(img, width, mode=_NP_MODES[border])
    H, W = img.shape[:2]
    return np.stack([padded[dy:dy + H, dx:dx + W] for dy in range(size) for dx in range(size)])


def median(image, size, border="reflect101"):
    """A correct median filter (NumPy's own padding)."""
    return np.median(_windows(image, size, border), axis=0)


def median_shifted(image, size, border="reflect101"):
    """Padded by one pixel too many, windows not re-centred: the output moves down-right."""
    return np.median(_windows(image, size, border, extra=1), axis=0)


def bilinear_xy_swapped(image, x, y, fill=0.0):
    """Bilinear sampling written with image[x, y]."""
    img = np.asarray(image, dtype=float)
    H, W = img.shape[:2]
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    with np.errstate(invalid="ignore"):
        inside = (x >= 0) & (x <= W - 1) & (y >= 0) & (y <= H - 1)
    xi, yi = np.where(inside, x, 0.0), np.where(inside, y, 0.0)
    x0 = np.minimum(np.floor(xi).astype(int), max(W - 2, 0))
    y0 = np.minimum(np.floor(yi).astype(int), max(H - 2, 0))
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    a, b = xi - x0, yi - y0
    if img.ndim == 3:
        a, b, inside = a[..., None], b[..., None], inside[..., None]
    out = (img[x0, y0] * (1 - a) * (1 - b) + img[x1, y0] * a * (1 - b) + img[x0, y1] * (1 - a) * b
           + img[x1, y1] * a * b)
    return np.where(inside, out, float(fill))


def rotation_wrong_way(A, R):
    """A⁻¹·R·A, not divided by H[2, 2]."""
    A = np.asarray(A, dtype=float)
    return np.linalg.inv(A) @ np.asarray(R, dtype=float) @ A


def rotation_wrong_way_scaled(A, R):
    """A⁻¹·R·A divided by H[2, 2]."""
    H = rotation_wrong_way(A, R)
    return H / H[2, 2]


def rotation_right_unscaled(A, R):
    A = np.asarray(A, dtype=float)
    return A @ np.asarray(R, dtype=float) @ np.linalg.inv(A)


SEEDS = (1, 2)


# --------------------------------------------------------------------------------------------
# 1. plain words first  /  2. the shape of the error
# --------------------------------------------------------------------------------------------
def test_pad_reflect101_off_by_one_says_the_wrong_values_are_in_the_border_frame():
    report = evaluate("filters.pad", pad_reflect101_off_by_one)
    assert not report.passed and report.mistake is None
    case = _failing(report)[0]
    assert case.label.endswith("(reflect101)")
    first = case.message.splitlines()[0]
    assert first.startswith("60 of 90 values differ, all in the border frame 2 pixels wide (the interior is right)")
    assert "first at [row 0, col 0]: yours" in first and "largest error" in first
    assert "Not equal to tolerance" in case.details          # the numpy.testing lines: details only
    assert "only the border frame 2 pixels wide is wrong" in case.diagnosis.lower()
    assert "border" in report.summary() and "reflect101" in report.summary()
    _assert_plain(report)
    for seed in SEEDS:
        hidden = evaluate("filters.pad", pad_reflect101_off_by_one, hidden=True, seed=seed)
        wrong = [c for c in _failing(hidden) if "reflect101" in c.label]
        assert wrong and all("border frame" in c.message or "first" in c.message or "column" in c.message
                             for c in wrong)
        _assert_plain(hidden)


def test_median_shifted_by_one_pixel_is_named_a_shift():
    report = evaluate("filters.median", median_shifted)
    assert not report.passed and report.mistake is None
    assert "shifted by 1 row down and 1 column right" in report.summary()
    assert "[r − 1, c − 1]" in report.summary() and "centred" in report.summary()
    assert all("shifted by" in c.diagnosis for c in _failing(report))
    _assert_plain(report)
    text = report.text()
    assert "What we see (case 1): Your output is shifted by" in text
    html = report._repr_html_()
    assert "shifted by 1 row down" in html and "<details" in html and "tolerance" in html.split("<details")[1]
    for seed in SEEDS:
        hidden = evaluate("filters.median", median_shifted, hidden=True, seed=seed)
        assert "shifted by" in hidden.summary(), hidden.text()


def test_correct_median_passes_without_diagnosis():
    report = evaluate("filters.median", median)
    assert report.passed and report.diagnosis is None and all(c.diagnosis is None for c in report.cases)


@pytest.mark.parametrize("wrong, words", [
    (lambda out: np.swapaxes(out, 0, 1), "transposed (rows and columns swapped)"),
    (lambda out: out[::-1], "flipped upside down"),
    (lambda out: out[:, ::-1], "mirrored left-right"),
    (lambda out: 2 * out, "2 times the expected one"),
    (lambda out: out / 9, "divided by 9"),
    (lambda out: out + 0.5, "plus 0.5 everywhere"),
    (lambda out: -out, "opposite sign"),
], ids=["transposed", "flipped", "mirrored", "scaled", "divided", "offset", "sign"])
def test_wrong_outputs_are_diagnosed(wrong, words):
    def attempt(image, size, border="reflect101"):
        return wrong(median(image, size, border))

    report = evaluate("filters.median", attempt)
    assert not report.passed and report.mistake is None
    assert all(words in (c.diagnosis or "") for c in _failing(report)), [c.diagnosis for c in _failing(report)]
    assert words in report.summary()
    _assert_plain(report)


def test_colour_channels_swapped():
    def attempt(image, size, border="reflect101"):
        out = median(image, size, border)
        return out[..., ::-1] if out.ndim == 3 else out

    report = evaluate("filters.median", attempt)
    failing = _failing(report)
    assert [c.label for c in failing] == ["colour uint8 image, replicate"]
    assert "BGR instead of RGB" in failing[0].diagnosis and "[..., 0] red" in failing[0].diagnosis


def test_nan_where_numbers_are_expected():
    def attempt(image, size, border="reflect101"):
        out = median(image, size, border)
        out[1, 2] = np.nan
        return out

    report = evaluate("filters.median", attempt)
    case = _failing(report)[0]
    assert case.message.startswith("1 of 30 values differ (NaN/inf in one output but not in the other)")
    assert "at [row 1, col 2]: yours NaN" in case.message
    assert "NaN/inf value where the expected values are numbers" in case.diagnosis and "0/0" in case.diagnosis


def test_named_mistake_beats_the_diagnosis():
    """A bank mistake that fits is the better diagnosis: no "what we see" line then."""
    def reflect_for_reflect101(image, size, border="reflect101"):
        return median(image, size, {"reflect": "reflect101", "reflect101": "reflect"}.get(border, border))

    report = evaluate("filters.median", reflect_for_reflect101)
    assert report.mistake == "reflect and reflect101 swapped"
    assert report.diagnosis is None and "What we see" not in report.text()


def test_other_comparators_lose_the_tolerance_vocabulary_too():
    """Angles (edges.direction) writes numpy.testing-like lines; the engine moves them to the details."""
    def direction(ix, iy):
        out = np.arctan2(np.asarray(iy, float), np.asarray(ix, float))
        out.flat[0] += 1.0
        return out

    report = evaluate("edges.direction", direction)
    case = _failing(report)[0]
    assert re.match(r"1 of \d+ values differ\.", case.message), case.message
    assert "tolerance" in case.details
    _assert_plain(report)


# --------------------------------------------------------------------------------------------
# 3. exceptions explained
# --------------------------------------------------------------------------------------------
def test_bilinear_sample_with_image_x_y_names_the_swap_and_the_convention():
    report = evaluate("warp.bilinear_sample", bilinear_xy_swapped)
    assert report.mistake == "x and y swapped (image[x, y])"
    case = _failing(report)[0]
    assert case.message.startswith("raised IndexError")
    assert "square 4×4 crop" in case.diagnosis and "x and y swapped" in case.diagnosis
    assert "image[row, col] = image[y, x]" in case.diagnosis
    text = report.text()
    assert "[row, col] = [y, x]" in text and "x and y swapped" in report.summary()
    for seed in SEEDS:
        hidden = evaluate("warp.bilinear_sample", bilinear_xy_swapped, hidden=True, seed=seed)
        assert hidden.mistake == "x and y swapped (image[x, y])", hidden.text()


def test_crash_in_the_sandbox_is_read_against_the_inputs():
    """Trusted grading cannot re-run the candidate: the error is read against the case's image."""
    spec = registry.get("warp.bilinear_sample").check

    def runner(index, case, attempt):  # outcomes as the sandbox worker computes them
        return run_guarded(bilinear_xy_swapped, case.args, case.kwargs, time_limit=spec.time_limit)

    report = evaluate("warp.bilinear_sample", lambda *a, **k: None, runner=runner)
    case = _failing(report)[0]
    assert "past the last row of the 4×5 image" in case.diagnosis
    assert "if you index with [x, y], rows and columns are swapped" in case.diagnosis
    assert "image[row, col] = image[y, x]" in case.diagnosis


def test_an_index_error_on_square_images_too_is_not_called_a_swap():
    def pad_loop_too_far(image, radius, border="reflect101"):
        img = np.asarray(image, dtype=float)
        H, W = img.shape[:2]
        return np.array([[img[r, c] for c in range(W + 1)] for r in range(H)])  # one column too many

    report = evaluate("filters.pad", pad_loop_too_far)
    case = _failing(report)[0]
    assert "IndexError" in case.message
    assert "one past the last one" in case.diagnosis and "swapped" not in case.diagnosis


def test_explain_exception_reads_shapes():
    img = np.zeros((4, 5))
    assert "rows and columns are swapped" in explain_exception("index 4 is out of bounds for axis 0 with size 4", (img,))
    text = explain_exception("index 4 is out of bounds for axis 0 with size 4", (img,), swap_plausible=False)
    assert "one past the last one (3)" in text and "swapped" not in text
    assert explain_exception("index 7 is out of bounds for axis 0 with size 4", (img,)) is None
    text = explain_exception("operands could not be broadcast together with shapes (4,5) (5,4) ", (img,))
    assert "rows and columns swapped" in text
    text = explain_exception("operands could not be broadcast together with shapes (9,10) (5,6) ", (img,))
    assert "padded and an unpadded image" in text
    assert explain_exception("something else entirely", (img,)) is None
    assert [kind for kind, _ in image_variants((img, 1))] == ["square", "transposed"]
    assert image_variants((np.zeros((4, 4)),)) == [] and image_variants((np.zeros(5),)) == []


def test_failed_check_shows_one_line_without_the_graders_frames():
    from cvkit.grading import check

    with pytest.raises(AssertionError) as info:
        check("filters.median", median_shifted)
    error = info.value
    assert isinstance(error, CheckFailed) and error.__suppress_context__
    rendered = error._render_traceback_()
    assert rendered[0].startswith("\x1b[0;31mAssertionError\x1b[0m: filters.median")
    assert not any("engine.py" in line or "File " in line for line in rendered)


def test_ipython_shows_the_failed_check_without_a_traceback(capsys):
    from IPython.core.interactiveshell import InteractiveShell

    shell = InteractiveShell.instance()
    shell.user_ns["median_shifted"] = median_shifted
    shell.run_cell("from cvkit.grading import check\ncheck('filters.median', median_shifted)")
    out = capsys.readouterr().out
    assert "AssertionError" in out and "shifted by 1 row down" in out
    assert "engine.py" not in out and "Traceback" not in out


# --------------------------------------------------------------------------------------------
# 4. structural mistakes before normalisation advice
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("attempt", [rotation_wrong_way, rotation_wrong_way_scaled], ids=["raw", "divided"])
def test_rotation_homography_wrong_way_is_named_with_or_without_normalising(attempt):
    for report in [evaluate("warp.rotation_homography", attempt)] + [
            evaluate("warp.rotation_homography", attempt, hidden=True, seed=s) for s in SEEDS]:
        assert report.mistake == "A⁻¹·R·A (inverted the wrong way)", report.text()
        text = report.text()
        assert "divid" not in text.lower() and "scale the homography" not in text
        assert all(c.message.startswith("Your H maps points elsewhere") for c in _failing(report))


def test_scaling_advice_only_when_the_scale_is_the_problem():
    report = evaluate("warp.rotation_homography", rotation_right_unscaled)
    assert report.mistake == "not scaled to H[2, 2] = 1"
    assert all("only its scale is off; normalise it by dividing it by H[2, 2]" in c.message for c in _failing(report))


def test_homography_comparator_normalises():
    compare = registry.get("warp.rotation_homography").check.compare
    assert compare.normalises
    H = np.array([[2.0, 0.0, 4.0], [0.0, 2.0, 6.0], [0.0, 0.0, 2.0]])
    assert np.allclose(compare.normalise(H), H / 2)
    assert compare(H / 2, H / 2) is None
    assert "only its scale is off" in compare(H, H / 2).message


# --------------------------------------------------------------------------------------------
# the diagnosis itself: no false diagnoses
# --------------------------------------------------------------------------------------------
_shapes = st.one_of(
    st.tuples(st.integers(1, 9)),
    st.tuples(st.integers(1, 9), st.integers(1, 9)),
    st.tuples(st.integers(1, 6), st.integers(1, 6), st.sampled_from([1, 3, 4])),
)


@st.composite
def _arrays(draw):
    shape = draw(_shapes)
    kind = draw(st.sampled_from(["random", "constant", "integers", "periodic", "sparse", "bool"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if kind == "random":
        return rng.normal(0, draw(st.sampled_from([1e-3, 1.0, 1e6])), shape)
    if kind == "constant":
        return np.full(shape, draw(st.floats(-1e6, 1e6, allow_nan=False)))
    if kind == "integers":
        return rng.integers(0, 4, shape).astype(draw(st.sampled_from([np.int64, np.uint8, np.float64])))
    if kind == "periodic":
        base = rng.random(2)
        return np.resize(base, int(np.prod(shape))).reshape(shape)
    if kind == "sparse":
        out = np.zeros(shape)
        out.flat[rng.integers(0, out.size)] = 1.0
        return out
    return rng.random(shape) < 0.5


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_arrays(), st.sampled_from([0.0, 1e-12, 1e-9]))
def test_no_diagnosis_for_a_correct_output(expected, noise):
    got = expected.astype(np.float64) + noise * np.maximum(1.0, np.abs(expected.astype(np.float64))) \
        if expected.dtype.kind == "f" else expected.copy()
    assert diagnose(got, expected, rtol=1e-7, atol=1e-8 * max(1.0, float(np.abs(expected).max()))) is None
    assert diagnose((got, got), (expected, expected)) is None
    assert describe_difference(expected.copy(), expected) == ""


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_arrays())
def test_a_diagnosis_always_describes_a_real_difference(expected):
    """Whatever a transformation of the expected output is diagnosed as, it differs from it; and
    a shift is never claimed where a shift changes nothing."""
    e = expected.astype(np.float64)
    for got in (e[::-1], np.roll(e, 1, axis=0), 2 * e, e + 1, np.swapaxes(e, 0, 1) if e.ndim >= 2 else e):
        found = diagnose(got, e)
        if found is not None:
            assert got.shape != e.shape or not np.allclose(got, e, rtol=1e-7, atol=1e-10, equal_nan=True)
            if found.kind == "shift":
                assert not np.allclose(np.roll(e, 1, axis=0), e)


def test_constant_and_periodic_outputs_are_not_called_shifted():
    e = np.full((6, 7), 3.0)
    got = e.copy()
    got[0] = 0.0
    found = diagnose(got, e)
    assert found is None or found.kind != "shift"
    stripes = np.tile([1.0, 5.0], (6, 4))                 # columns alternate: a shift by one column is
    moved = np.roll(stripes, 1, axis=1)                    # also a shift by minus one column
    assert diagnose(moved, stripes) is None or diagnose(moved, stripes).kind != "shift"


def test_diagnose_recognises_more_shapes_of_error():
    rng = np.random.default_rng(3)
    e = rng.random((6, 7)) * 200
    assert diagnose(np.round(e), e).kind == "rounding"
    assert diagnose(np.clip(e, 0, 100), e).kind == "clipping"
    assert diagnose(np.degrees(e / 200), e / 200).what.endswith("degrees instead of radians")
    big = e + 100
    assert diagnose(np.mod(np.trunc(big), 256), big).kind == "wraparound"
    assert diagnose((e - e.min()) / (e.max() - e.min()), e).what.endswith("stretched to the range [0, 1]")
    assert diagnose(np.zeros_like(e), e).kind == "zeros"
    assert diagnose(e.astype(np.float32), e, rtol=1e-12, atol=1e-12).kind == "precision"
    assert diagnose(e.astype(np.float32), e) is None          # within the tolerance: nothing to say
    assert diagnose((e.T.copy(), e.copy()), (e.copy(), e.T.copy())).kind == "order"
    mask = np.zeros((6, 7), dtype=bool)
    mask[5, 2:5] = True
    assert locate(mask) == "all in row 5 (the last row)"
    mask[:] = False
    mask[1:3, 3] = True
    assert locate(mask) == "all in column 3"
    mask[:] = False
    mask[2:4, 2:5] = True
    assert locate(mask) == "all in the interior (the outermost rows and columns are right)"


def test_image_only_diagnoses_for_outputs_compared_value_by_value():
    """Random outputs (seeded checks) are judged by statistics: never diagnosed as shifted."""
    from cvkit.grading.engine import _diagnosable

    assert not _diagnosable(registry.get("noise.add_gaussian").check)
    assert _diagnosable(registry.get("filters.median").check)


# --------------------------------------------------------------------------------------------
# 6. the instructor's summary
# --------------------------------------------------------------------------------------------
def _graded_notebook(path, reports):
    cells = []
    for grade_id, report in reports:
        cells.append({"cell_type": "code", "metadata": {"nbgrader": {"grade_id": grade_id}}, "source": "",
                      "outputs": [{"output_type": "display_data", "data": {MIME_TYPE: report}, "metadata": {}}]})
    path.write_text(json.dumps({"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5}))


def test_instructor_summary_lists_each_student_and_exercise_once_in_plain_words(tmp_path):
    from cvkit.course import ExerciseScore, format_table
    from cvkit.course.results import reported_findings

    old = ("Not equal to tolerance rtol=1e-07, atol=1.78e-08\nMismatched elements: 60 / 90 (66.7%)\n"
           "Max absolute difference: 24 at [2, 0]")
    shifted = evaluate("filters.median", median_shifted).to_dict()
    hidden = evaluate("filters.median", median_shifted, hidden=True, seed=1).to_dict()
    _graded_notebook(tmp_path / "ch03.ipynb", [
        ("pad_visible", {"mistake": None, "cases": [{"passed": False, "message": old}]}),
        ("pad_hidden", {"mistake": None, "cases": [{"passed": False, "message": old.replace("60 / 90", "61 / 99")}]}),
        ("median_visible", shifted),
        ("median_hidden", hidden),
        ("bilinear_visible", evaluate("warp.bilinear_sample", bilinear_xy_swapped).to_dict()),
    ])
    found = reported_findings(tmp_path)
    assert found["pad_visible"] == [("problem", "60 of 90 values differ")]
    assert found["median_visible"] == [("problem", "your output is shifted by 1 row down and 1 column right")]
    assert found["bilinear_visible"] == [("mistake", "x and y swapped (image[x, y])")]
    scores = {"ann": []}
    for name in ("pad", "median", "bilinear"):
        entry = ExerciseScore(name, 0.5, 2.0)
        for grade, items in found.items():
            if grade.rsplit("_", 1)[0] == name:
                for kind, text in items:
                    bucket = entry.mistakes if kind == "mistake" else entry.problems
                    if text not in bucket:
                        bucket.append(text)
        scores["ann"].append(entry)
    table = format_table(scores)
    notes = table.split("What the checks found:")[1].strip().splitlines()
    assert len(notes) == 3, notes                      # one line per student × exercise
    assert notes[0].strip() == "ann · pad: 60 of 90 values differ"
    assert notes[1].strip() == "ann · median: your output is shifted by 1 row down and 1 column right"
    assert notes[2].strip() == "ann · bilinear: mistake “x and y swapped (image[x, y])”"
    assert not TECHNICAL.search(table)


def test_the_border_advice_is_given_only_for_an_image_of_the_input():
    """A wrong last column of a 4×4 matrix is told where it is, without the advice about an
    image's border; an output computed from an image (filtered, padded, cropped) gets it."""
    e = np.arange(16.0).reshape(4, 4)
    got = e.copy()
    got[:3, 3] += 1.0
    for image in (False, (3, 3), (5, 2)):  # no input image; a 3×3 matrix; points
        found = diagnose(got, e, image=image)
        assert found.kind == "edge_entries" and found.what == "only the last column of the result is wrong, " \
            "the rest is right", image
        assert "outside the image" not in str(found) and "border" not in str(found)
    ring = e.copy()
    ring[0] += 1.0
    ring[-1] += 1.0
    ring[:, 0] += 1.0
    ring[:, -1] += 1.0
    assert "first and last rows and columns" in diagnose(ring, e, image=False).what
    picture = np.random.default_rng(1).random((9, 8))
    wrong = picture.copy()
    wrong[:, -1] = 0.0
    # the image itself; its colour source; a crop of it; a padded 5×4 image; not known
    for image in ((9, 8), (9, 8, 3), (12, 10), (5, 4), True):
        assert diagnose(wrong, picture, image=image).kind == "border", image


def test_a_wrong_translation_column_is_not_called_a_border_error():
    def extrinsic_matrix(R, t):
        G = np.eye(4)
        G[:3, :3] = R
        G[:3, 3] = -np.asarray(t, dtype=float)  # the camera's centre, not t
        return G

    report = evaluate("camera.extrinsic_matrix", extrinsic_matrix)
    failed = [c for c in report.cases if not c.passed]
    assert failed
    for case in failed:
        text = f"{case.message} {case.diagnosis or ''} {case.hint or ''}"
        assert "outside the image" not in text and "border" not in text, text
