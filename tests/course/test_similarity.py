"""cvkit.course.similarity: the similarity report (copydetect's winnowing on normalised tokens).

Test data: Chapter 3's source notebook (its solutions and stubs), cvkit's references, the
independent correct versions of ``tests/library/alternatives_ch03.py``, and a few answers written here
(copies with renamed variables and reordered statements; a loop and a vectorized Gaussian
kernel)."""
from __future__ import annotations

import copy
import csv
import inspect
import json
import os
import re
from pathlib import Path

import pytest

from cvkit import filters
from cvkit.course import similarity
from cvkit.course.similarity import SOLUTION, THRESHOLD, Exercise, SimilarPair, reference_label

pytest.importorskip("copydetect")
import alternatives_ch03  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
CH03 = ROOT / "lectures" / "ch03_filtering" / "ch03_filtering.ipynb"

# Chapter 3's add_salt_and_pepper solution, every name changed, independent statements reordered
# (input check first, generator before the conversion, copy before the indices)
SALT_COPY = '''@student("noise.add_salt_and_pepper")
def add_salt_and_pepper(image, amount, rng=None, low=0.0, high=1.0):
    """Replace a fraction `amount` of the pixels by low or high (probability 1/2 each)."""
    if not 0.0 <= amount <= 1.0:
        raise ValueError(f"amount out of range: {amount}")
    g = np.random.default_rng(rng)
    im = np.asarray(image, dtype=np.float64)
    nr, nc = im.shape[:2]
    n = int(round(amount * nr * nc))
    picked = g.choice(nr * nc, size=n, replace=False)
    vals = np.where(g.random(n) < 0.5, high, low)
    result = im.copy()
    rr, cc = np.unravel_index(picked, (nr, nc))
    result[rr, cc] = vals.reshape((n,) + (1,) * (im.ndim - 2))
    return result
'''

# Chapter 3's bilateral solution renamed, with swapped set-up lines and accumulations, comments gone
BILATERAL_COPY = '''@student("filters.bilateral")
def bilateral(image, sigma_space, sigma_range, radius=None, border="reflect101"):
    """Bilateral filter: weights Gaussian in the distance and in the intensity difference."""
    img = np.asarray(image, dtype=np.float64)
    if not (sigma_space > 0 and sigma_range > 0):
        raise ValueError(f"bad sigmas {sigma_space}, {sigma_range}")
    if radius is None:
        radius = int(np.ceil(3 * sigma_space - 1e-9))
    rad = int(radius)
    big = pad(img, rad, border)
    nrows, ncols = img.shape[:2]
    norm = np.zeros((nrows, ncols))
    acc = np.zeros(img.shape)
    for oy in range(-rad, rad + 1):
        for ox in range(-rad, rad + 1):
            nb = big[rad + oy:rad + oy + nrows, rad + ox:rad + ox + ncols]
            diff = (nb - img) ** 2
            if img.ndim == 3:
                diff = diff.sum(axis=2)
            wt = np.exp(-(oy * oy + ox * ox) / (2 * sigma_space**2) - diff / (2 * sigma_range**2))
            acc += (wt if img.ndim == 2 else wt[..., None]) * nb
            norm += wt
    return acc / (norm if img.ndim == 2 else norm[..., None])
'''

# two independent correct Gaussian kernels: a loop over the offsets, and a vectorized one
KERNEL_LOOP = '''@student("filters.gaussian_kernel")
def gaussian_kernel(sigma, radius=None):
    """Normalised 1-D Gaussian kernel of length 2r+1, r = ceil(3 sigma) by default."""
    if sigma <= 0 or sigma != sigma:
        raise ValueError("sigma must be positive")
    if radius is None:
        radius = math.ceil(3 * sigma - 1e-9)
    values = []
    total = 0.0
    for k in range(-radius, radius + 1):
        v = math.exp(-(k * k) / (2 * sigma * sigma))
        values.append(v)
        total = total + v
    result = np.zeros(len(values))
    for i in range(len(values)):
        result[i] = values[i] / total
    return result
'''

KERNEL_VECTORIZED = '''@student("filters.gaussian_kernel")
def gaussian_kernel(sigma, radius=None):
    """Normalised 1-D Gaussian kernel of length 2r+1, r = ceil(3 sigma) by default."""
    sigma = float(sigma)
    assert sigma > 0, "sigma must be positive"
    r = int(np.ceil(3 * sigma - 1e-9)) if radius is None else int(radius)
    k = np.exp(-0.5 * (np.linspace(-r, r, 2 * r + 1) / sigma) ** 2)
    k /= np.sum(k)
    return k
'''


@pytest.fixture(scope="module")
def ch03():
    """(source notebook, its exercises, the solutions' answer cells)."""
    notebook = json.loads(CH03.read_text())
    return notebook, similarity.exercises_from(notebook), similarity.answer_sources(notebook)


def _stubs(exercises) -> dict[str, str]:
    return {grade_id: exercise.stub for grade_id, exercise in exercises.items()}


def _pair(pairs, exercise, a, b):
    found = [p for p in pairs if p.exercise == exercise and {p.a, p.b} == {a, b}]
    return found[0] if found else None


# ------------------------------------------------------------------------------- notebooks
def test_answer_cells_stubs_algorithms_and_solutions_come_from_the_source_notebook(ch03):
    notebook, exercises, answers = ch03
    assert {"gaussian_kernel_answer", "gaussian_answer", "bilateral_answer"} <= set(answers)
    assert set(exercises) == set(answers)
    gaussian = exercises["gaussian_answer"]
    assert gaussian.reference_name == "cvkit.filters.gaussian"
    assert gaussian.reference == inspect.getsource(filters.gaussian)
    assert "### BEGIN SOLUTION" not in gaussian.solution and "gaussian_kernel(sigma)" in gaussian.solution
    assert "raise NotImplementedError()" in gaussian.stub and "gaussian_kernel(sigma)" not in gaussian.stub
    assert gaussian.stub.startswith('@student("filters.gaussian")\ndef gaussian(image, sigma, border="reflect101"):')
    assert similarity.exercise_algorithms(notebook)["add_salt_and_pepper_answer"] == "noise.add_salt_and_pepper"


def test_answer_sources_skips_malformed_cells_and_never_raises():
    cells = [
        {"cell_type": "code", "source": ["a = 1\n", "b = 2"], "metadata": {"nbgrader": {"solution": True, "grade_id": "x"}}},
        {"cell_type": "code", "source": 42, "metadata": {"nbgrader": {"solution": True, "grade_id": "y"}}},
        {"cell_type": "code", "source": "c = 3", "metadata": {"nbgrader": "nonsense"}},
        {"cell_type": "markdown", "source": "text", "metadata": {"nbgrader": {"solution": True, "grade_id": "w"}}},
        {"cell_type": "code", "source": "d = 4", "metadata": {"nbgrader": {"solution": True, "grade_id": 7}}},
        "not a cell",
    ]
    assert similarity.answer_sources({"cells": cells}) == {"x": "a = 1\nb = 2"}
    assert similarity.answer_sources({"cells": "nope"}) == {} and similarity.answer_sources([]) == {}  # type: ignore[arg-type]


# ------------------------------------------------------------------------------- detection
def test_renamed_variables_and_reordered_statements_still_match(ch03):
    _, exercises, solutions = ch03
    answers = {
        "ann": {"add_salt_and_pepper_answer": solutions["add_salt_and_pepper_answer"],
                "bilateral_answer": solutions["bilateral_answer"]},
        "bob": {"add_salt_and_pepper_answer": SALT_COPY, "bilateral_answer": BILATERAL_COPY},
    }
    pairs = similarity.similar_pairs(answers, exercises, assignment="ch03_filtering")
    for exercise in ("add_salt_and_pepper_answer", "bilateral_answer"):
        pair = _pair(pairs, exercise, "ann", "bob")
        assert pair is not None and pair.similarity >= THRESHOLD + 0.1, (exercise, pair)
        assert (pair.a, pair.b) == ("ann", "bob") and pair.assignment == "ch03_filtering"
        assert pair.b_source in (SALT_COPY, BILATERAL_COPY)
        # the copy of the notebook's solution is also reported against the instructor's solution
        assert _pair(pairs, exercise, "bob", SOLUTION).similarity >= THRESHOLD
    assert [p.similarity for p in pairs] == sorted((p.similarity for p in pairs), reverse=True)


def test_independent_correct_solutions_stay_below_the_threshold(ch03):
    _, exercises, solutions = ch03
    alternatives = {grade_id: inspect.getsource(getattr(alternatives_ch03, grade_id[: -len("_answer")]))
                    for grade_id in exercises if hasattr(alternatives_ch03, grade_id[: -len("_answer")])}
    assert len(alternatives) >= 10
    answers = {"loop": {"gaussian_kernel_answer": KERNEL_LOOP}, "vectorized": {"gaussian_kernel_answer": KERNEL_VECTORIZED},
               "alternatives": alternatives, "notebook": solutions}
    pairs = similarity.similar_pairs(answers, exercises)
    # the notebook's own solutions match the instructor's solution, and nothing else does: not
    # the alternatives, the loop and the vectorized kernel, cvkit's references, among themselves
    assert pairs and all((p.a, p.b) == ("notebook", SOLUTION) for p in pairs), pairs
    everything = similarity.similar_pairs(answers, exercises, threshold=0.0)
    independent = [p.similarity for p in everything if (p.a, p.b) != ("notebook", SOLUTION)]
    assert len(independent) > 30 and max(independent) < THRESHOLD - 0.1
    loop_vectorized = _pair(everything, "gaussian_kernel_answer", "loop", "vectorized")
    assert loop_vectorized is not None and loop_vectorized.similarity < 0.2


def test_a_pasted_reference_is_reported_against_the_reference(ch03):
    _, exercises, _ = ch03
    reference = exercises["gaussian_answer"].reference
    body = reference[reference.index('"""', reference.index('"""') + 3) + 3:]
    stub = exercises["gaussian_answer"].stub
    pasted = stub[: stub.index("# YOUR CODE HERE")] + body.replace("weights", "w8").replace("padded", "big")
    answers = {"cat": {"gaussian_answer": pasted}, "dan": {"gaussian_answer": KERNEL_LOOP}}
    pairs = similarity.similar_pairs(answers, exercises)
    assert [(p.exercise, p.a, p.b) for p in pairs] == [
        ("gaussian_answer", "cat", reference_label("cvkit.filters.gaussian"))]
    assert pairs[0].b == "(reference cvkit.filters.gaussian)" and pairs[0].b_source == reference
    assert pairs[0].similarity >= 0.8


def test_blank_and_tiny_answers_are_not_reported(ch03):
    _, exercises, _ = ch03
    stubs = _stubs(exercises)
    spaced = {grade_id: stub.replace("\n", "\n\n") + "\n   " for grade_id, stub in stubs.items()}
    tiny = {"temporal_mean_answer": stubs["temporal_mean_answer"].replace(
        "# YOUR CODE HERE\n    raise NotImplementedError()", "return frames.mean(0)")}
    answers = {"eve": dict(stubs), "fay": dict(stubs), "gus": spaced, "hal": tiny, "ivy": dict(tiny), "joe": {}}
    before = copy.deepcopy(answers)
    assert similarity.similar_pairs(answers, exercises, threshold=0.0) == []
    assert answers == before  # inputs are not modified
    # without the size floor, the two identical one-liners match
    assert {(p.a, p.b) for p in similarity.similar_pairs(answers, exercises, min_size=0)} == {("hal", "ivy")}


def test_exercise_made_by_hand_without_reference_or_solution():
    first = "def f(x):\n    total = 0\n    for value in x:\n        total = total + value * value - 3\n    return total\n"
    second = first.replace("total", "acc").replace("value", "v").replace("3", "4")
    pairs = similarity.similar_pairs({"a": {"q": first}, "b": {"q": second}}, {"q": Exercise()}, min_size=0)
    assert [(p.a, p.b, p.similarity) for p in pairs] == [("a", "b", 1.0)]


@pytest.mark.parametrize("kwargs, message", [
    ({"threshold": 1.5}, "threshold must be a number in [0, 1]"),
    ({"threshold": "0.5"}, "threshold must be a number in [0, 1]"),
    ({"min_size": -1}, "min_size must be an integer >= 0"),
])
def test_bad_parameters_name_the_argument(kwargs, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        similarity.similar_pairs({}, {}, **kwargs)


def test_bad_inputs_name_the_argument(tmp_path):
    with pytest.raises(TypeError, match="answers must be a mapping"):
        similarity.similar_pairs([("a", {})], {})  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="exercises must be a mapping"):
        similarity.similar_pairs({}, {"q": "def f(): pass"})  # type: ignore[dict-item]
    with pytest.raises(ValueError, match="assignment must be a folder name"):
        similarity.report(tmp_path, tmp_path, "../elsewhere")
    with pytest.raises(TypeError, match="course_root must be a path"):
        similarity.report(3, tmp_path, "ch03")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="pairs must be an iterable of SimilarPair"):
        similarity.write_csv(["a"], tmp_path / "x.csv")  # type: ignore[list-item]


# ------------------------------------------------------------------------------- exports
HOSTILE = SimilarPair("gaussian_answer", "<script>alert('a')</script>", "=HYPERLINK(\"http://x\")", 0.8,
                      "x = '</pre><script>alert(1)</script>'\n<img src=x onerror=alert(2)>",
                      "@SUM(A1) <b>bold</b> & more", "ch03_filtering")
OTHER = SimilarPair("pad_answer", "-1+2", "+cmd", 0.95, "a", "b", "ch03_filtering")


def test_html_page_escapes_every_student_text_and_puts_the_answers_side_by_side(tmp_path):
    page = similarity.write_html([HOSTILE, OTHER], tmp_path / "exports" / "similarity.html").read_text()
    assert "<script" not in page.lower() and "<img" not in page.lower()
    assert "&lt;script&gt;alert(&#x27;a&#x27;)&lt;/script&gt;" in page
    assert "&lt;/pre&gt;&lt;script&gt;alert(1)&lt;/script&gt;" in page and "&lt;img src=x onerror=alert(2)&gt;" in page
    assert "&lt;b&gt;bold&lt;/b&gt; &amp; more" in page and "<b>" not in page
    assert "default-src 'none'" in page and 'href="http' not in page
    assert page.index("pad_answer") < page.index("gaussian_answer")  # by decreasing similarity
    assert page.count('class="sides"') == 2 and page.count("<pre>") == 4


def test_csv_export_escapes_formulas(tmp_path):
    path = similarity.write_csv([HOSTILE, OTHER], tmp_path / "exports" / "similarity.csv")
    rows = list(csv.reader(path.open(newline="", encoding="utf-8")))
    header = ["assignment", "exercise", "cluster", "students", "student", "closest", "similarity", "textbook",
              "added_code"]
    assert rows[0] == header
    # one row per student of each group (a pair is a group of two), the groups by decreasing similarity
    assert rows[1:3] == [["ch03_filtering", "pad_answer", "1", "2", "'+cmd", "'-1+2", "0.950", "", ""],
                         ["ch03_filtering", "pad_answer", "1", "2", "'-1+2", "'+cmd", "0.950", "", ""]]
    hyperlink = "'=HYPERLINK(\"http://x\")"
    assert rows[3:] == [["ch03_filtering", "gaussian_answer", "2", "2", "<script>alert('a')</script>", hyperlink,
                         "0.800", "", ""],
                        ["ch03_filtering", "gaussian_answer", "2", "2", hyperlink, "<script>alert('a')</script>",
                         "0.800", "", ""]]
    empty = similarity.write_csv([], tmp_path / "empty.csv")
    assert empty.read_text() == ",".join(header) + "\n"


# ------------------------------------------------------------------------------- course folders
def _course(tmp_path: Path, ch03) -> tuple[Path, Path]:
    """A course with one assignment (Chapter 3's notebook) and its submissions."""
    notebook, _, solutions = ch03
    source = tmp_path / "source"
    (source / "ch03").mkdir(parents=True)
    (source / "ch03" / "ch03.ipynb").write_text(json.dumps(notebook))

    def submit(student: str, answers: dict) -> Path:
        student_notebook = copy.deepcopy(notebook)
        for cell in student_notebook["cells"]:
            grade_id = cell.get("metadata", {}).get("nbgrader", {}).get("grade_id")
            if cell["cell_type"] == "code" and grade_id in answers:
                cell["source"] = answers[grade_id]
        folder = tmp_path / "course" / "submitted" / student / "ch03"
        folder.mkdir(parents=True)
        path = folder / "ch03.ipynb"
        path.write_text(json.dumps(student_notebook))
        return path

    stubs = _stubs(similarity.exercises_from(notebook))
    submit("ann", {**stubs, "add_salt_and_pepper_answer": solutions["add_salt_and_pepper_answer"]})
    submit("bob", {**stubs, "add_salt_and_pepper_answer": SALT_COPY})
    submit("cat", {**stubs, "gaussian_kernel_answer": KERNEL_LOOP})
    linked = tmp_path / "course" / "submitted" / "eve" / "ch03"
    linked.mkdir(parents=True)
    (linked / "ch03.ipynb").symlink_to(tmp_path / "course" / "submitted" / "bob" / "ch03" / "ch03.ipynb")
    broken = tmp_path / "course" / "submitted" / "fay" / "ch03"
    broken.mkdir(parents=True)
    (broken / "ch03.ipynb").write_text('{"cells": [ {"cell_type": "code", ')  # invalid JSON
    (tmp_path / "course" / "submitted" / "gus").symlink_to(tmp_path / "course" / "submitted" / "bob")
    outside = submit("ida", {**stubs, "add_salt_and_pepper_answer": SALT_COPY})  # then made a hard link to
    moved = tmp_path / "elsewhere.ipynb"  # a file outside the submission
    outside.rename(moved)
    os.link(moved, outside)
    return tmp_path / "course", source


def test_report_reads_regular_files_only_and_skips_invalid_notebooks(tmp_path, ch03):
    course, source = _course(tmp_path, ch03)
    pairs = similarity.report(course, source, "ch03")
    assert {(p.exercise, p.a, p.b) for p in pairs} == {
        ("add_salt_and_pepper_answer", "ann", "bob"),
        ("add_salt_and_pepper_answer", "ann", SOLUTION),
        ("add_salt_and_pepper_answer", "bob", SOLUTION),
    }
    assert all(p.assignment == "ch03" and p.similarity >= THRESHOLD for p in pairs)
    assert not any({"eve", "fay", "gus", "ida"} & {p.a, p.b} for p in pairs)  # links and broken JSON skipped
    assert similarity.report(course, source, "ch03", threshold=1.0) == []
    assert similarity.report(course, source, "no_such_assignment") == []


def test_report_takes_the_stubs_from_the_release_when_it_is_there(tmp_path, ch03):
    course, source = _course(tmp_path, ch03)
    release = course / "release" / "ch03"
    release.mkdir(parents=True)
    notebook = json.loads((source / "ch03" / "ch03.ipynb").read_text())
    stubs = {**_stubs(similarity.exercises_from(notebook)), "add_salt_and_pepper_answer": SALT_COPY}
    for cell in notebook["cells"]:  # a release whose salt-and-pepper stub is bob's answer: bob left it as released
        grade_id = cell.get("metadata", {}).get("nbgrader", {}).get("grade_id")
        if cell["cell_type"] == "code" and grade_id in stubs:
            cell["source"] = stubs[grade_id]
    (release / "ch03.ipynb").write_text(json.dumps(notebook))
    pairs = similarity.report(course, source, "ch03")
    assert {(p.a, p.b) for p in pairs} == {("ann", SOLUTION)}


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs named pipes")
def test_a_named_pipe_in_place_of_a_notebook_is_skipped_without_blocking(tmp_path, ch03):
    course, source = _course(tmp_path, ch03)
    folder = course / "submitted" / "hal" / "ch03"
    folder.mkdir(parents=True)
    os.mkfifo(folder / "ch03.ipynb")
    assert {p.a for p in similarity.report(course, source, "ch03")} == {"ann", "bob"}


def test_the_vectorized_pre_check_gives_copydetects_own_values(ch03):
    from copydetect import compare_files

    _, exercises, solutions = ch03
    texts = [solutions["add_salt_and_pepper_answer"], SALT_COPY, inspect.getsource(alternatives_ch03.add_salt_and_pepper),
             exercises["add_salt_and_pepper_answer"].reference, KERNEL_LOOP]
    comparer = similarity._Comparer(exercises["add_salt_and_pepper_answer"].stub)
    for text in texts:
        comparer.size(similarity._normalised(text))
    documents = list(comparer.documents.values())
    assert len(documents) == len(texts)
    values = set()
    for one in documents:
        for two in documents:
            _, shares, _ = compare_files(one.fingerprint, two.fingerprint)
            assert (one.share(two), two.share(one)) == pytest.approx(shares, abs=1e-12)
            values.add(round(float(shares[0]), 3))
    assert len(values) > 5  # pairs from unrelated to identical


def test_huge_answers_are_cut_and_padding_with_repeated_lines_hides_no_copy(ch03):
    _, exercises, _ = ch03
    huge = SALT_COPY + "\n".join(f"    waste_{i} = [{i}] * {i}" for i in range(20000))
    assert len(huge) > 2 * similarity.MAX_ANSWER_CHARS
    pairs = similarity.similar_pairs({"kim": {"add_salt_and_pepper_answer": huge},
                                      "lee": {"add_salt_and_pepper_answer": huge}}, exercises)
    assert (pairs[0].a, pairs[0].b) == ("kim", "lee") and pairs[0].similarity == pytest.approx(1.0)
    assert pairs[0].a_source == huge[: similarity.MAX_ANSWER_CHARS]
    # the 20000 lines read the same once normalised, and a repeated k-gram counts once
    assert {(p.a, p.b) for p in pairs[1:]} == {("kim", SOLUTION), ("lee", SOLUTION)}


def test_a_grading_run_measures_an_assignment_again_only_when_what_it_compares_changed(tmp_path, ch03, monkeypatch):
    from types import SimpleNamespace

    from cvkit.course import exports

    course, source = _course(tmp_path, ch03)
    state = SimpleNamespace(root=course, source_dir=source)
    first = exports._similar_pairs(state, "ch03")
    assert first == similarity.report(course, source, "ch03") and first  # measured, and what report says
    assert (course / ".cvkit" / "similarity" / "ch03.json").is_file()

    measured = []
    real = similarity.similar_pairs
    monkeypatch.setattr(similarity, "similar_pairs", lambda *a, **k: measured.append(1) or real(*a, **k))
    assert exports._similar_pairs(state, "ch03") == first and not measured  # nothing changed: the kept pairs

    bob = course / "submitted" / "bob" / "ch03" / "ch03.ipynb"
    notebook = json.loads(bob.read_text())
    for cell in notebook["cells"]:  # bob hands in an answer of his own
        if cell.get("metadata", {}).get("nbgrader", {}).get("grade_id") == "add_salt_and_pepper_answer":
            cell["source"] = KERNEL_VECTORIZED.replace("gaussian_kernel", "add_salt_and_pepper")
    bob.write_text(json.dumps(notebook))
    again = exports._similar_pairs(state, "ch03")
    assert measured == [1] and again != first
    assert again == similarity.report(course, source, "ch03")

    measured.clear()
    (course / ".cvkit" / "similarity" / "ch03.json").write_text("{not json")  # a damaged file: measured again
    assert exports._similar_pairs(state, "ch03") == again and measured == [1]
