"""The grading engine on a small synthetic algorithm: reports, mistakes, guard, check()."""
import time
import warnings

import numpy as np
import pytest

from cvkit import registry
from cvkit.grading import Case, Check, Mistake, Statistics, check, close, evaluate, hidden_seed, mistake
from cvkit.grading.report import MIME_TYPE


def shift_right(image, steps=1):
    """Reference of the synthetic algorithm: roll columns to the right."""
    return np.roll(np.asarray(image, dtype=float), steps, axis=1)


def _shift(image, steps=1):
    """The same computation, not registered: what a student's correct answer looks like."""
    return np.roll(np.asarray(image, dtype=float), steps, axis=1)


def _cases_public():
    return [Case((np.arange(12.0).reshape(3, 4),), {"steps": 1}, "3×4 ramp"),
            Case((np.arange(20.0).reshape(4, 5),), {"steps": 2}, "4×5, two steps")]


def _cases_hidden(rng):
    return [Case((rng.random((int(rng.integers(2, 6)), int(rng.integers(3, 7)))),), {"steps": int(rng.integers(1, 3))},
                 f"random {i}") for i in range(4)]


SHIFT_CHECK = Check(
    public=_cases_public,
    hidden=_cases_hidden,
    compare=close(rtol=1e-12, atol=1e-12),
    mistakes=[
        Mistake("rolled the rows", lambda image, steps=1: np.roll(np.asarray(image, float), steps, axis=0),
                "columns are axis 1: images are indexed [row, col]"),
        Mistake("rolled left", lambda image, steps=1: np.roll(np.asarray(image, float), -steps, axis=1),
                "a shift to the right moves x to x + steps"),
    ],
    time_limit=1.0,
)


@pytest.fixture(autouse=True)
def synthetic_algorithm():
    registry.algorithm("testing.shift_right", section="0.1", check=SHIFT_CHECK)(shift_right)
    yield
    registry._algorithms.pop("testing.shift_right", None)


def test_reference_passes_public_and_hidden():
    assert evaluate("testing.shift_right", shift_right).score == 1.0
    report = evaluate("testing.shift_right", shift_right, hidden=True, seed=5)
    assert report.passed and report.score == 1.0 and len(report.cases) == 4


def test_stub_scores_zero_and_says_not_implemented():
    def stub(image, steps=1):
        raise NotImplementedError()

    report = evaluate("testing.shift_right", stub)
    assert not report.passed and report.score == 0.0
    assert "not implemented" in report.cases[0].message


def test_mistake_is_named_with_hint():
    def wrong(image, steps=1):
        return np.roll(image, -steps, axis=1)

    report = evaluate("testing.shift_right", wrong)
    assert not report.passed
    assert report.mistake == "rolled left"
    assert "x + steps" in report.hint
    assert "rolled left" in report.text()


def test_a_mistake_marked_on_its_function_joins_the_bank_in_the_listed_order():
    @mistake("rolled left", "a shift to the right moves x to x + steps")
    def rolled_left(image, steps=1):
        return np.roll(np.asarray(image, float), -steps, axis=1)

    assert rolled_left(np.eye(2)).tolist() == [[0.0, 1.0], [1.0, 0.0]]  # the function itself is unchanged
    rows = Mistake("rolled the rows", lambda image, steps=1: np.roll(np.asarray(image, float), steps, axis=0),
                   "columns are axis 1")
    spec = Check(public=_cases_public, hidden=_cases_hidden, compare=close(), mistakes=[rolled_left, rows])
    assert [type(m) for m in spec.mistakes] == [Mistake, Mistake]
    assert [m.name for m in spec.mistakes] == ["rolled left", "rolled the rows"]
    assert spec.mistakes[0].function is rolled_left and spec.mistakes[0].hint.endswith("x + steps")
    with pytest.raises(TypeError, match="marked with @mistake"):
        Check(public=_cases_public, hidden=_cases_hidden, compare=close(), mistakes=[_shift])
    with pytest.raises(TypeError, match="mistake hint"):
        mistake("a name", "")


def test_partial_score_is_fraction_of_cases():
    def half_right(image, steps=1):
        return _shift(image, 1)  # right only when steps == 1

    report = evaluate("testing.shift_right", half_right)
    assert report.score == 0.5
    assert [c.passed for c in report.cases] == [True, False]


def test_error_message_has_numpy_testing_details():
    def off_by_one_pixel(image, steps=1):
        out = _shift(image, steps)
        out[1, 2] += 0.5
        return out

    report = evaluate("testing.shift_right", off_by_one_pixel)
    message = report.cases[0].message   # plain words first, the numpy.testing lines in the details
    assert message.startswith("1 of 12 values differ") and "[row 1, col 2]: yours 5.5, expected 5" in message
    assert "tolerance" not in message and "rtol" not in message
    details = report.cases[0].details
    assert "Mismatched elements: 1 / 12" in details
    assert "Max absolute difference: 0.5 at [1, 2]" in details
    assert report.cases[0].worst == (1, 2)


def test_shape_mismatch_messages():
    report = evaluate("testing.shift_right", lambda image, steps=1: _shift(image, steps).T)
    assert "shape mismatch: expected (3, 4), got (4, 3)" in report.cases[0].message
    assert "rows and columns swapped" in report.cases[0].message
    report = evaluate("testing.shift_right", lambda image, steps=1: np.pad(_shift(image, steps), 1))
    assert "larger by 2 rows and 2 columns" in report.cases[0].message
    report = evaluate("testing.shift_right", lambda image, steps=1: None)
    assert "forget to `return`" in report.cases[0].message


def test_candidate_exception_never_escapes_and_traceback_is_the_candidates():
    def broken(image, steps=1):
        return image[10, 10]

    report = evaluate("testing.shift_right", broken)
    assert report.score == 0
    assert "IndexError" in report.cases[0].message
    assert "broken" in report.cases[0].traceback
    assert "guard.py" not in report.cases[0].traceback


def test_not_callable_candidate():
    report = evaluate("testing.shift_right", 42)
    assert not report.passed and "expected a function" in report.summary()


def test_input_modification_is_caught():
    def in_place(image, steps=1):
        image[:] = np.roll(image, steps, axis=1)
        return image

    report = evaluate("testing.shift_right", in_place)
    assert not report.passed
    assert "modified its input 'image'" in report.cases[0].message


def test_time_limit_with_vectorize_hint():
    def slow(image, steps=1):
        time.sleep(5)
        return shift_right(image, steps)

    report = evaluate("testing.shift_right", slow)
    # without the limit the answer (right after its sleep) would pass: failing proves it was stopped
    assert not report.passed and "vectorize" in report.cases[0].message


def test_the_candidate_runs_with_blas_on_one_thread_as_on_the_grader():
    """The grader's sandbox runs NumPy's BLAS on one thread; a check run in a student's kernel does
    too while the candidate runs (a time limit means the same on both), and gives the threads back."""
    threadpoolctl = pytest.importorskip("threadpoolctl")

    def blas_threads():
        return {info["internal_api"]: info["num_threads"] for info in threadpoolctl.threadpool_info()
                if info["user_api"] == "blas"}

    seen = []

    def counting(image, steps=1):
        seen.append(blas_threads())
        return _shift(image, steps)

    libraries = set(blas_threads())
    with threadpoolctl.threadpool_limits(2):  # as in a kernel on a machine with several cores
        inside = blas_threads()
        assert evaluate("testing.shift_right", counting).passed
        after = blas_threads()
    assert libraries and seen and all(counts == dict.fromkeys(libraries, 1) for counts in seen), seen
    assert after == inside


def test_forbidden_library_calls_are_caught():
    import scipy.ndimage

    def via_scipy(image, steps=1):
        return scipy.ndimage.shift(np.asarray(image, float), (0, steps), order=0, mode="grid-wrap")

    report = evaluate("testing.shift_right", via_scipy)
    assert not report.passed
    assert "scipy.ndimage" in report.cases[0].message


def test_opencv_builtin_calls_are_caught():
    cv2 = pytest.importorskip("cv2")

    def via_cv2(image, steps=1):
        cv2.flip(np.zeros((2, 2)), 0)
        return _shift(image, steps)

    report = evaluate("testing.shift_right", via_cv2)
    assert not report.passed and "cv2" in report.cases[0].message


def test_calling_the_reference_is_caught_unless_allowed():
    def via_reference(image, steps=1):
        return shift_right(image, steps)

    report = evaluate("testing.shift_right", via_reference)
    assert not report.passed
    assert "reference implementation of 'testing.shift_right'" in report.cases[0].message
    allowed = Check(public=_cases_public, hidden=_cases_hidden, compare=close(), allowed=("testing.shift_right",))
    assert evaluate("testing.shift_right", via_reference, check=allowed).passed


def test_numpy_is_allowed_and_library_exception_list_works():
    import scipy.ndimage

    def via_scipy(image, steps=1):
        return scipy.ndimage.shift(np.asarray(image, float), (0, steps), order=0, mode="grid-wrap")

    lenient = Check(public=_cases_public, hidden=_cases_hidden, compare=close(), allowed_libraries=("scipy.ndimage",))
    assert evaluate("testing.shift_right", via_scipy, check=lenient).passed


def test_warnings_and_prints_are_captured_and_cost_nothing(capsys):
    def chatty(image, steps=1):
        print("debugging output")
        warnings.warn("a student warning")
        np.log(np.zeros(1))  # RuntimeWarning
        return _shift(image, steps)

    report = evaluate("testing.shift_right", chatty)
    captured = capsys.readouterr()
    assert report.passed
    assert captured.err == "" and captured.out == ""
    assert any("a student warning" in w for w in report.cases[0].warnings)
    assert "debugging output" in report.cases[0].stdout


def test_hidden_seed_mixes_salt_student_and_algorithm(monkeypatch):
    base = hidden_seed("filters.gaussian", student="ada", salt="s1")
    assert base == hidden_seed("filters.gaussian", student="ada", salt="s1")
    assert base != hidden_seed("filters.gaussian", student="bob", salt="s1")
    assert base != hidden_seed("filters.gaussian", student="ada", salt="s2")
    assert base != hidden_seed("filters.mean", student="ada", salt="s1")
    monkeypatch.setenv("CVKIT_GRADING_SALT", "s1")
    monkeypatch.setenv("CVKIT_STUDENT_ID", "ada")
    assert hidden_seed("filters.gaussian") == base
    first = evaluate("testing.shift_right", shift_right, hidden=True)
    assert first.seed == hidden_seed("testing.shift_right")


def test_hidden_cases_are_reproducible_and_vary_with_seed():
    a = SHIFT_CHECK.hidden_cases(np.random.default_rng(1))
    b = SHIFT_CHECK.hidden_cases(np.random.default_rng(1))
    c = SHIFT_CHECK.hidden_cases(np.random.default_rng(2))
    assert all(np.array_equal(x.args[0], y.args[0]) for x, y in zip(a, b))
    assert not all(x.args[0].shape == y.args[0].shape and np.array_equal(x.args[0], y.args[0]) for x, y in zip(a, c))


def test_check_visible_raises_and_hidden_returns_partial_credit(capsys):
    assert check("testing.shift_right", shift_right) is None
    assert "2/2 cases passed" in capsys.readouterr().out
    with pytest.raises(AssertionError, match="FAILED"):
        check("testing.shift_right", lambda image, steps=1: image)
    assert check("testing.shift_right", shift_right, hidden=True, points=3) == 3.0

    def half_right(image, steps=1):
        return _shift(image, 1)

    value = check("testing.shift_right", half_right, hidden=True, points=2, seed=0)
    report = evaluate("testing.shift_right", half_right, hidden=True, seed=0)
    assert value == pytest.approx(2 * report.score)
    assert capsys.readouterr().err == ""


def test_report_html_shows_images_and_json_roundtrip():
    import json

    report = evaluate("testing.shift_right", lambda image, steps=1: np.roll(image, steps, axis=0))
    page = report._repr_html_()
    assert page.count("<img") == 3 and "rolled the rows" in page
    data = json.loads(json.dumps(report.to_dict()))
    assert data["mistake"] == "rolled the rows" and data["score"] == 0.0
    assert MIME_TYPE.startswith("application/vnd.cvkit")


def test_a_report_shows_the_same_bundle_in_the_kernel_and_on_the_feedback_page(monkeypatch):
    """Report.mime_bundle is what check() displays and what the trusted grader writes: the text,
    the report's data under MIME_TYPE, and the HTML unless it cannot be drawn."""
    import json

    report = evaluate("testing.shift_right", lambda image, steps=1: np.roll(image, steps, axis=0))
    bundle = report.mime_bundle()
    assert bundle["text/plain"] == report.text() and bundle["text/html"] == report._repr_html_()
    assert bundle[MIME_TYPE] == json.loads(json.dumps(report.to_dict(), default=str))

    def broken(self):
        raise ValueError("no images today")

    monkeypatch.setattr(type(report), "_repr_html_", broken)
    assert sorted(report.mime_bundle()) == sorted(["text/plain", MIME_TYPE])


def _html_elements(page: str) -> list[tuple[str, dict]]:
    from html.parser import HTMLParser

    found = []

    class Collect(HTMLParser):
        def handle_starttag(self, tag, attrs):
            found.append((tag, dict(attrs)))

    Collect().feed(page)
    return found


def test_report_html_is_accessible():
    """Alt text on every image, the verdict in words (not only colour), colours from the
    JupyterLab theme variables so the dark theme stays readable."""
    import re

    failing = evaluate("testing.shift_right", lambda image, steps=1: np.roll(image, steps, axis=0))
    passing = evaluate("testing.shift_right", lambda image, steps=1: _shift(image, steps))
    for report, word in ((failing, "FAILED"), (passing, "passed")):
        page = report._repr_html_()
        elements = _html_elements(page)
        images = [attrs for tag, attrs in elements if tag == "img"]
        assert all(len(attrs.get("alt", "").strip()) > 20 for attrs in images), images
        assert word in page  # the verdict is a word, not only a colour
        cases = page.split("<tbody>")[1]
        assert cases.count(" pass") + cases.count("<b>fail</b>") == len(report.cases)
        assert all(attrs.get("scope") == "col" for tag, attrs in elements if tag == "th")
        for colour in re.findall(r"color:\s*([^;'\"]+)", page):
            assert colour.startswith("var(--jp-"), f"hard-coded colour {colour!r} ignores the theme"
    alts = [attrs["alt"] for tag, attrs in _html_elements(failing._repr_html_()) if tag == "img"]
    assert len(alts) == 3 and alts[0].startswith("Your output") and alts[1].startswith("Expected output")
    assert "difference" in alts[2]


def test_close_comparator_nan_inf_and_tuples():
    cmp = close(rtol=0, atol=1e-9)
    assert cmp(np.array([1.0, np.nan, np.inf]), np.array([1.0, np.nan, np.inf])) is None
    assert "NaN/inf" in cmp(np.array([1.0, 2.0, np.inf]), np.array([1.0, np.nan, np.inf])).message
    assert cmp((np.ones(2), np.zeros(2)), (np.ones(2), np.zeros(2))) is None
    assert "result [1]" in cmp((np.ones(2), np.ones(2)), (np.ones(2), np.zeros(2))).message
    assert "tuple of 2" in cmp(np.ones(2), (np.ones(2), np.zeros(2))).message
    assert "numeric array" in cmp(np.array(["a"]), np.array([1.0])).message
    assert "dtype mismatch" in close(kind="b")(np.array([1.0]), np.array([True])).message


def test_statistics_comparator():
    def stats(output, case):
        return {"mean": float(np.mean(output)), "std": float(np.std(output))}

    cmp = Statistics(stats, lambda case: {"mean": 0.05, "std": 0.05}, dtype_kind="f")
    rng = np.random.default_rng(0)
    a, b = rng.normal(0, 1, 4000), rng.normal(0, 1, 4000)
    assert cmp(a, b) is None
    wrong = cmp(2 * a, b)
    assert wrong is not None and "std" in wrong.message and "mean" not in wrong.message
    assert "dtype mismatch" in cmp(np.round(a).astype(int), b).message


def test_drawn_judges_each_draw_and_how_often_a_result_comes_back():
    """A ``draws`` case: every draw by the single comparator (its message names the call and
    its seed), then the share of the most frequent result, whatever the output's form."""
    from cvkit.grading import Drawn
    from cvkit.grading.compare import REPEATS, repeat_share

    single = close(rtol=0.0, atol=10.0)
    cmp = Drawn(single=single)
    case = Case((), {"draws": (7, 40)})
    fresh = [np.random.default_rng(seed).normal(size=3) for seed in range(7, 47)]
    fixed = [np.random.default_rng(0).normal(size=3) for _ in range(40)]
    assert cmp(fresh, fresh, case) is None and cmp(fresh[0], fresh[1], Case((), {"rng": 1})) is None
    message = cmp(fixed, fresh, case).message
    assert REPEATS in message and "yours 1, expected 0.025" in message
    assert message.endswith("All 40 calls returned the same result, whatever the seed: draw every random number "
                            "from np.random.default_rng(rng), not from a generator with a fixed seed (nor from "
                            "np.random.seed)")
    half = cmp(fixed[:20] + fresh[:20], fresh, case).message  # repeats, but not one result every time
    assert REPEATS in half and "All 40 calls" not in half
    far = fresh[:5] + [fresh[5] + 100] + fresh[6:]
    assert cmp(far, fresh, case).message.startswith("call 6 of 40 (rng = 12): ")
    assert "outputs of 40 calls" in cmp(fresh[:39], fresh, case).message
    assert repeat_share([]) == 0.0
    nested = [(np.zeros(2), {"mask": np.ones(2, bool), "p": 0.5}), (np.zeros(2), {"mask": np.ones(2, bool), "p": 0.5}),
              (np.zeros(2), {"mask": np.zeros(2, bool), "p": 0.5}), [np.zeros(2), {"mask": np.ones(2, bool), "p": 0.5}]]
    assert repeat_share(nested) == 0.5  # a list is not the tuple it looks like; equal dicts are equal
    assert repeat_share([np.zeros(2), np.zeros(2, np.float32), np.zeros(3), 0.0]) == 0.25


def test_switching_off_the_watch_is_caught():
    import sys as _sys

    def sneaky(image, steps=1):
        _sys.setprofile(None)
        return shift_right(image, steps)  # the reference, unseen

    report = evaluate("testing.shift_right", sneaky)
    assert not report.passed and "sys.setprofile" in report.cases[0].message


def test_expected_output_is_not_reachable_from_the_candidate():
    import sys as _sys

    def peeking(image, steps=1):
        frame = _sys._getframe(1)
        while frame is not None:
            if "expected" in frame.f_locals:
                return frame.f_locals["expected"]
            frame = frame.f_back
        return np.zeros_like(image)

    assert not evaluate("testing.shift_right", peeking).passed


def test_numpy_functions_reexported_by_forbidden_modules_are_fine():
    import scipy.signal  # noqa: F401  (re-exports numpy builtins such as arange)

    def uses_numpy_builtins(image, steps=1):
        np.arange(3)
        np.concatenate([np.zeros(1), np.ones(1)])
        return _shift(image, steps)

    assert evaluate("testing.shift_right", uses_numpy_builtins).passed


def test_nan_arguments_are_not_reported_as_modified():
    from cvkit.grading.runtime.guard import run_guarded

    outcome = run_guarded(lambda image, fill=0.0: image, (np.ones(2),), {"fill": float("nan")})
    assert outcome.modified == [] and outcome.error is None


@pytest.mark.parametrize("nbgrader_metadata", [
    None, {}, {"grade": True, "solution": False}, {"grade": True, "solution": True},
    {"grade": False, "solution": True}, {"grade": False, "solution": False, "locked": True}, {"grade": True},
    {"solution": True}, {"grade_id": "setup", "locked": True},
], ids=str)
def test_cell_roles_are_nbgrader_s_own(nbgrader_metadata):
    """cvkit.grading.runtime.cells answers as nbgrader.utils does (without importing nbgrader
    where it runs), for nbformat's NotebookNode and for the plain JSON dict of the same cell."""
    import nbformat
    from nbgrader import utils

    from cvkit.grading.runtime import cells

    metadata = {} if nbgrader_metadata is None else {"nbgrader": nbgrader_metadata}
    plain = {"cell_type": "code", "source": "x = 1", "metadata": metadata}
    node = nbformat.from_dict(plain)
    for cell in (node, plain):
        assert cells.is_grade(cell) == bool(utils.is_grade(node))
        assert cells.is_solution(cell) == bool(utils.is_solution(node))
        assert cells.is_test_cell(cell) == bool(utils.is_grade(node) and not utils.is_solution(node))
        assert cells.nbgrader_metadata(cell) == (nbgrader_metadata or {})
    assert plain["metadata"] == metadata  # the cell is only read


def test_cells_of_a_notebook_read_alike_from_json_and_nbformat_and_survive_edited_json():
    """One reader of a notebook's cells for every course module: a dict and nbformat's node
    give the same cells, kinds and sources; JSON a student edited by hand (metadata that is a
    list, a cell that is a string, cells that are not a list) reads as "no such cell" rather
    than raising."""
    import nbformat

    from cvkit.grading.runtime import cells

    plain = {"cells": [{"cell_type": "markdown", "source": ["# a", "\n"], "metadata": {}},
                       {"cell_type": "code", "source": ["x = 1\n", "y = 2"], "metadata": {"nbgrader": {"solution": True}},
                        "outputs": [], "execution_count": None}],
             "metadata": {}, "nbformat": 4, "nbformat_minor": 5}
    node = nbformat.from_dict(plain)
    for notebook in (plain, node):
        found = cells.cells_of(notebook)
        assert [cells.is_code(c) for c in found] == [False, True]
        assert [cells.cell_source(c) for c in found] == ["# a\n", "x = 1\ny = 2"]
        assert cells.is_solution(found[1]) and not cells.is_solution(found[0])
    edited = {"cells": ["not a cell", {"cell_type": "code", "source": "z", "metadata": ["junk"]}, 7]}
    found = cells.cells_of(edited)
    assert len(found) == 1 and cells.nbgrader_metadata(found[0]) == {} and not cells.is_test_cell(found[0])
    assert cells.cell_source({"source": [1, 2]}) == "" and cells.cell_source({"source": 3}, None) is None
    assert cells.cells_of({"cells": "abc"}) == [] and cells.cells_of(None) == [] and cells.cells_of([]) == []
    assert not cells.is_code({"cell_type": "raw"}) and not cells.is_code("code")
