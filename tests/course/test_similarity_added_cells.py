"""cvkit.course.similarity: code in cells the student added is compared too.

Added cells run in the grader, so copied code placed in an added cell and called from the answer
cell used to escape the report (the answer cells alone differ). Now each answer is compared
together with the definitions it pulls in from added cells (transitively), and each notebook's
added cells are compared between students as the pseudo-exercise ``(added cells)``; unchanged
release cells and test cells never are. Test data: Chapter 3's source notebook, with answers
and added cells written here."""
from __future__ import annotations

import copy
import csv
import json
from pathlib import Path

import pytest

from cvkit.course import similarity
from cvkit.course.similarity import ADDED, ALL_ADDED, SOLUTION, THRESHOLD, Answer

pytest.importorskip("copydetect")

ROOT = Path(__file__).resolve().parents[2]
CH03 = ROOT / "lectures" / "ch03_filtering" / "ch03_filtering.ipynb"
HEAD = ('@student("filters.bilateral")\n'
        'def bilateral(image, sigma_space, sigma_range, radius=None, border="reflect101"):\n'
        '    """Bilateral filter: weights Gaussian in the distance and in the intensity difference."""\n')

# a bilateral filter one pixel at a time (not the notebook's loop over offsets): ann's helper
CORE = '''def _bilateral_core(img, s_space, s_range, rad, border):
    """The weighted average over a (2 rad + 1)^2 window, one pixel at a time."""
    big = pad(img, rad, border)
    ys, xs = np.mgrid[-rad:rad + 1, -rad:rad + 1]
    spatial = np.exp(-(ys ** 2 + xs ** 2) / (2.0 * s_space ** 2))
    out = np.empty_like(img)
    for i in range(img.shape[0]):
        for j in range(img.shape[1]):
            window = big[i:i + 2 * rad + 1, j:j + 2 * rad + 1]
            diff = window - img[i, j]
            if img.ndim == 3:
                diff = np.sqrt((diff ** 2).sum(axis=-1))
            w = spatial * np.exp(-diff ** 2 / (2.0 * s_range ** 2))
            norm = w.sum()
            if img.ndim == 3:
                out[i, j] = (w[..., None] * window).sum(axis=(0, 1)) / norm
            else:
                out[i, j] = (w * window).sum() / norm
    return out
'''
# bob's copy of it: every name changed, the first two statements swapped, the docstring reworded
CORE_COPY = '''def _smooth(picture, spread, tolerance, half, mode):
    """Edge-preserving smoothing."""
    oy, ox = np.mgrid[-half:half + 1, -half:half + 1]
    framed = pad(picture, half, mode)
    near = np.exp(-(oy ** 2 + ox ** 2) / (2.0 * spread ** 2))
    result = np.empty_like(picture)
    for row in range(picture.shape[0]):
        for col in range(picture.shape[1]):
            patch = framed[row:row + 2 * half + 1, col:col + 2 * half + 1]
            delta = patch - picture[row, col]
            if picture.ndim == 3:
                delta = np.sqrt((delta ** 2).sum(axis=-1))
            k = near * np.exp(-delta ** 2 / (2.0 * tolerance ** 2))
            total = k.sum()
            if picture.ndim == 3:
                result[row, col] = (k[..., None] * patch).sum(axis=(0, 1)) / total
            else:
                result[row, col] = (k * patch).sum() / total
    return result
'''
# two answer cells that share nothing but the released stub and the call of a helper
ANN_ANSWER = HEAD + '''    image = np.asarray(image, dtype=np.float64)
    if sigma_space <= 0 or sigma_range <= 0:
        raise ValueError("both sigmas must be positive")
    r = int(np.ceil(3 * sigma_space - 1e-9)) if radius is None else int(radius)
    return _bilateral_core(image, sigma_space, sigma_range, r, border)
'''
BOB_ANSWER = HEAD + '''    for name, value in (("sigma_space", sigma_space), ("sigma_range", sigma_range)):
        if not value > 0:
            raise ValueError(f"{name} must be > 0, got {value}")
    if radius is None:
        radius = math.ceil(3 * sigma_space - 1e-9)
    data = np.array(image, dtype=float)
    return _smooth(data, sigma_space, sigma_range, int(radius), border)
'''

# two honest students' Gaussian kernels, each through a helper of their own
KERNEL_HEAD = ('@student("filters.gaussian_kernel")\ndef gaussian_kernel(sigma, radius=None):\n'
               '    """Normalised 1-D Gaussian kernel of length 2r+1, r = ceil(3 sigma) by default."""\n')
CAT_HELPER = '''def _weights(sigma, radius):
    values = []
    for k in range(-radius, radius + 1):
        values.append(math.exp(-(k * k) / (2 * sigma * sigma)))
    total = sum(values)
    return np.array([v / total for v in values])
'''
CAT_ANSWER = KERNEL_HEAD + '''    if not sigma > 0:
        raise ValueError("sigma must be positive")
    if radius is None:
        radius = math.ceil(3 * sigma - 1e-9)
    return _weights(sigma, radius)
'''
DAN_HELPER = '''def bell(r, s):
    x = np.arange(-r, r + 1, dtype=float)
    g = np.exp(-0.5 * (x / s) ** 2)
    return g / g.sum()
'''
DAN_ANSWER = KERNEL_HEAD + '''    s = float(sigma)
    assert s > 0, "sigma must be positive"
    return bell(int(np.ceil(3 * s - 1e-9)) if radius is None else int(radius), s)
'''
# a cell of dan's that is his alone: a look at the kernels
DAN_PLOT = '''for s in (0.5, 1.0, 2.0, 4.0):
    kernel = gaussian_kernel(s)
    plt.plot(np.arange(kernel.size) - kernel.size // 2, kernel, label=f"sigma = {s}")
plt.legend()
plt.title("my kernels")
plt.show()
'''


@pytest.fixture(scope="module")
def source():
    return json.loads(CH03.read_text())


def _code_cell(text: str) -> dict:
    return {"cell_type": "code", "source": text, "metadata": {}, "outputs": [], "execution_count": None}


def _notebook(source: dict, answers: dict[str, str] | None = None, added: dict[str, list[str]] | None = None) -> dict:
    """A student's notebook: the release (stubs, demos and visible tests as given), the answers
    ``{grade_id: source}``, and ``added[grade_id]`` inserted as new cells after that answer cell."""
    stubs = {grade_id: exercise.stub for grade_id, exercise in similarity.exercises_from(source).items()}
    cells = []
    for cell in copy.deepcopy(source["cells"]):
        cell["source"] = "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]
        grade_id = cell.get("metadata", {}).get("nbgrader", {}).get("grade_id")
        if cell["cell_type"] == "code" and grade_id in stubs:
            cell["source"] = (answers or {}).get(grade_id, stubs[grade_id])
        cells.append(cell)
        cells += [_code_cell(text) for text in (added or {}).get(grade_id, [])]
    return {**source, "cells": cells}


def _course(tmp_path: Path, source: dict, notebooks: dict[str, dict]) -> tuple[Path, Path]:
    """A course whose one assignment is Chapter 3, and the students' ``notebooks``."""
    (tmp_path / "source" / "ch03").mkdir(parents=True)
    (tmp_path / "source" / "ch03" / "ch03.ipynb").write_text(json.dumps(source))
    for student, notebook in notebooks.items():
        folder = tmp_path / "course" / "submitted" / student / "ch03"
        folder.mkdir(parents=True)
        (folder / "ch03.ipynb").write_text(json.dumps(notebook))
    return tmp_path / "course", tmp_path / "source"


def _found(pairs) -> dict[tuple[str, str, str], similarity.SimilarPair]:
    return {(p.exercise, p.a, p.b): p for p in pairs}


# ------------------------------------------------------------------------------- the attack
def test_a_copied_helper_in_added_cells_is_reported_for_the_exercise_and_among_the_added_cells(tmp_path, source):
    """The attack: answer cells that share nothing, each calling a helper in an added cell, the
    helpers one copy (names changed, two lines swapped). Reported for the exercise (answer plus
    pulled-in helper) and among the added cells, and the CSV and the page say so."""
    notebooks = {"ann": _notebook(source, {"bilateral_answer": ANN_ANSWER}, {"bilateral_answer": [CORE]}),
                 "bob": _notebook(source, {"bilateral_answer": BOB_ANSWER}, {"bilateral_answer": [CORE_COPY]})}
    # the answer cells alone do not look alike: this is how the copy escaped
    alone = _found(similarity.similar_pairs({s: similarity.answer_sources(nb) for s, nb in notebooks.items()},
                                            similarity.exercises_from(source), threshold=0.0))
    assert alone[("bilateral_answer", "ann", "bob")].similarity < THRESHOLD - 0.2

    course, sources = _course(tmp_path, source, notebooks)
    pairs = _found(similarity.report(course, sources, "ch03"))
    assert set(pairs) == {("bilateral_answer", "ann", "bob"), (ADDED, "ann", "bob")}
    exercise = pairs[("bilateral_answer", "ann", "bob")]
    assert exercise.similarity >= THRESHOLD
    assert exercise.added == "ann: _bilateral_core; bob: _smooth"
    assert exercise.a_source.startswith(ANN_ANSWER) and exercise.a_source.endswith(CORE.rstrip("\n"))
    assert exercise.b_source.startswith(BOB_ANSWER) and exercise.b_source.endswith(CORE_COPY.rstrip("\n"))
    cells = pairs[(ADDED, "ann", "bob")]
    assert cells.similarity >= THRESHOLD + 0.3 and cells.added == ALL_ADDED  # only the swapped lines differ
    assert (cells.a_source, cells.b_source) == (CORE, CORE_COPY)

    # the CSV and the page say which pairs come from added code
    similarity.write_csv(pairs.values(), tmp_path / "similarity.csv")
    rows = list(csv.reader((tmp_path / "similarity.csv").open(newline="", encoding="utf-8")))
    assert rows[0] == list(similarity.CSV_COLUMNS)
    # one row per student of each group: the exercise, the student, the closest, what each pulls in
    assert [row[1:2] + row[4:6] + row[8:] for row in rows[1:]] == [
        [ADDED, "ann", "bob", ALL_ADDED], [ADDED, "bob", "ann", ALL_ADDED],
        ["bilateral_answer", "ann", "bob", "_bilateral_core"], ["bilateral_answer", "bob", "ann", "_smooth"]]
    page = similarity.write_html(pairs.values(), tmp_path / "similarity.html").read_text()
    assert "ch03 / bilateral_answer" in page and "ch03 / (added cells)" in page
    section = page[page.index('id="cluster-2"'):]
    assert "<td>_bilateral_core</td>" in section and "<td>_smooth</td>" in section


def test_an_honest_pair_with_their_own_helpers_is_compared_but_not_reported(source):
    """Two students with helpers and answers of their own: compared (for the exercise, with the
    reference and the solution, and among the added cells), nothing reported."""
    notebooks = {"cat": _notebook(source, {"gaussian_kernel_answer": CAT_ANSWER},
                                  {"gaussian_kernel_answer": [CAT_HELPER]}),
                 "dan": _notebook(source, {"gaussian_kernel_answer": DAN_ANSWER},
                                  {"gaussian_kernel_answer": [DAN_HELPER, DAN_PLOT]})}
    answers = {student: similarity.student_code(notebook, source) for student, notebook in notebooks.items()}
    assert answers["cat"]["gaussian_kernel_answer"] == Answer(
        CAT_ANSWER + "\n\n# ---- pulled in from the student's other cells: _weights ----\n" + CAT_HELPER.rstrip("\n"),
        ("_weights",))
    assert answers["dan"]["gaussian_kernel_answer"].pulled == ("bell",)  # not the plot: it defines no name used
    assert answers["dan"][ADDED] == Answer(DAN_HELPER + "\n\n" + DAN_PLOT)
    exercises = {**similarity.exercises_from(source), ADDED: similarity.added_cells_exercise(source)}
    assert similarity.similar_pairs(answers, exercises) == []
    everything = _found(similarity.similar_pairs(answers, exercises, threshold=0.0))
    assert set(everything) == {
        ("gaussian_kernel_answer", "cat", "dan"), (ADDED, "cat", "dan"),
        ("gaussian_kernel_answer", "cat", "(reference cvkit.filters.gaussian_kernel)"),
        ("gaussian_kernel_answer", "dan", "(reference cvkit.filters.gaussian_kernel)"),
        ("gaussian_kernel_answer", "cat", SOLUTION), ("gaussian_kernel_answer", "dan", SOLUTION)}
    assert max(p.similarity for p in everything.values()) < THRESHOLD - 0.2
    assert everything[("gaussian_kernel_answer", "cat", "dan")].added == "cat: _weights; dan: bell"


def test_the_instructors_solution_in_an_added_cell_is_reported_against_the_solution(tmp_path, source):
    """The solution pasted into a helper that a one-line answer calls: reported against the
    solution (the one-line answer alone is too small to compare)."""
    solution = similarity.exercises_from(source)["bilateral_answer"].solution
    helper = "def _impl(image, sigma_space, sigma_range, radius, border):\n" + solution
    answer = HEAD + "    return _impl(image, sigma_space, sigma_range, radius, border)\n"
    course, sources = _course(tmp_path, source, {
        "eve": _notebook(source, {"bilateral_answer": answer}, {"bilateral_answer": [helper]}),
        "fay": _notebook(source, {"gaussian_kernel_answer": CAT_ANSWER}, {"gaussian_kernel_answer": [CAT_HELPER]})})
    pairs = _found(similarity.report(course, sources, "ch03"))
    assert set(pairs) == {("bilateral_answer", "eve", SOLUTION)}
    pair = pairs[("bilateral_answer", "eve", SOLUTION)]
    assert pair.similarity >= THRESHOLD + 0.2 and pair.added == "eve: _impl" and pair.b_source == solution
    # the answer cell alone is a one-line call: nothing to compare
    alone = similarity.similar_pairs({"eve": {"bilateral_answer": answer}}, similarity.exercises_from(source),
                                     threshold=0.0)
    assert alone == []


def test_unchanged_release_cells_and_test_cells_are_never_compared(tmp_path, source):
    """Every student has the release's set-up, demo and test cells: never added code. A demo run
    again with other numbers is added code with nothing of the student's own; a changed test
    cell is not code the grader runs."""
    untouched = _notebook(source)
    code = similarity.student_code(untouched, source)
    stubs = {grade_id: exercise.stub for grade_id, exercise in similarity.exercises_from(source).items()}
    assert code == {grade_id: Answer(stub) for grade_id, stub in stubs.items()}  # no added code, nothing pulled
    # gus changed a demo cell's numbers, and a visible test cell (which the grader never runs)
    changed = _notebook(source)
    demo = next(cell for cell in changed["cells"] if cell["source"].startswith("sigmas = [0.02, 20 / 255, 0.2]"))
    demo["source"] = demo["source"].replace("[0.02, 20 / 255, 0.2]", "[0.05, 30 / 255, 0.3]")
    test = next(cell for cell in changed["cells"]
                if cell["metadata"].get("nbgrader", {}).get("grade_id") == "pad_visible")
    test["source"] = CORE
    assert similarity.student_code(changed, source)[ADDED] == Answer(demo["source"])
    course, sources = _course(tmp_path, source, {"ann": untouched, "bob": copy.deepcopy(untouched), "gus": changed,
                                                 "hal": copy.deepcopy(changed)})
    assert similarity.report(course, sources, "ch03", threshold=0.0, min_size=0) == []


def test_definitions_are_pulled_in_transitively_and_nothing_else(source):
    """answer -> _outer -> _middle -> _bilateral_core (the copy is two calls away); an unused
    definition and a top-level name equal to a local variable of the answer stay out."""
    outer = "def _outer(image, a, b, r, mode):\n    return _middle(np.asarray(image, dtype=float), a, b, r, mode)\n"
    middle = "def _middle(x, a, b, r, mode):\n    return _bilateral_core(x, a, b, r, mode)\n"
    unrelated = "def unused(x):\n    return [v * v for v in x if v > 0] + [0.0] * len(x)\n\nr = 99\n"
    answer = HEAD + ("    r = int(np.ceil(3 * sigma_space)) if radius is None else radius\n"
                     "    return _outer(image, sigma_space, sigma_range, r, border)\n")
    notebook = _notebook(source, {"bilateral_answer": answer}, {"bilateral_answer": [unrelated, CORE, middle, outer]})
    pulled = similarity.student_code(notebook, source)["bilateral_answer"]
    assert pulled.pulled == ("_bilateral_core", "_middle", "_outer")  # in notebook order
    assert pulled.text == (answer + "\n\n# ---- pulled in from the student's other cells: _bilateral_core _middle "
                           "_outer ----\n" + "\n\n".join(part.rstrip("\n") for part in (CORE, middle, outer)))
    other = {"bob": {"bilateral_answer": Answer(BOB_ANSWER + "\n" + CORE_COPY, ("_smooth",))}}
    pairs = similarity.similar_pairs({"ivy": {"bilateral_answer": pulled}, **other}, similarity.exercises_from(source))
    assert [(p.exercise, p.a, p.b, p.added) for p in pairs] == [
        ("bilateral_answer", "bob", "ivy", "bob: _smooth; ivy: _bilateral_core _middle _outer")]
    assert pairs[0].similarity >= THRESHOLD


def test_a_later_cell_redefining_the_graded_function_is_its_answer(source):
    """The answer cell left as released, ``bilateral`` defined again in an added cell (the
    grader calls the last definition): the added definition is the answer."""
    redefined = HEAD + ("    return _bilateral_core(np.asarray(image, dtype=float), sigma_space, sigma_range, "
                        "radius or 3, border)\n")
    notebook = _notebook(source, None, {"bilateral_answer": [CORE, redefined]})
    answer = similarity.student_code(notebook, source)["bilateral_answer"]
    assert answer.pulled == ("_bilateral_core", "bilateral")
    # the answer cell deleted: the exercise is what the checked function's name pulls in
    notebook["cells"] = [cell for cell in notebook["cells"]
                         if cell["metadata"].get("nbgrader", {}).get("grade_id") != "bilateral_answer"]
    moved = similarity.student_code(notebook, source)["bilateral_answer"]
    assert moved == Answer("# ---- pulled in from the student's other cells: _bilateral_core bilateral ----\n"
                           + CORE.rstrip("\n") + "\n\n" + redefined.rstrip("\n"), ("_bilateral_core", "bilateral"))


def test_malformed_cells_are_left_out_without_an_error(source):
    """A student can edit the notebook's JSON: odd metadata and sources never stop the report."""
    notebook = _notebook(source, {"bilateral_answer": ANN_ANSWER}, {"bilateral_answer": [CORE]})
    notebook["cells"] += [{"cell_type": "code", "source": 42, "metadata": {}},
                          {"cell_type": "code", "source": "x = 1\n", "metadata": ["not", "a", "dict"]},
                          {"cell_type": "code", "source": "y = 2\n", "metadata": {"nbgrader": "nonsense"}},
                          {"cell_type": "code", "source": "\0 = 3\n", "metadata": {}}, "not a cell"]
    code = similarity.student_code(notebook, source)
    assert code["bilateral_answer"].pulled == ("_bilateral_core",)
    assert code[ADDED].text == "\n\n".join([CORE, "x = 1\n", "y = 2\n", "\0 = 3\n"])
    assert similarity.student_code({"cells": "nope"}, source) == {}
    with pytest.raises(TypeError, match="source_notebook must be a notebook dict"):
        similarity.student_code(notebook, [])  # type: ignore[arg-type]


def test_helpers_beside_another_answer_are_pulled_in_but_building_blocks_are_not(source):
    """A helper put in the padding exercise's answer cell counts for the exercise that calls
    it; the padding answer itself (a building block ``bilateral`` may call) does not."""
    stubs = {grade_id: exercise.stub for grade_id, exercise in similarity.exercises_from(source).items()}
    answers = {"pad_answer": stubs["pad_answer"] + "\n\n\n" + CORE,
               "bilateral_answer": HEAD + "    return _bilateral_core(image, sigma_space, sigma_range, 3, border)\n"}
    code = similarity.student_code(_notebook(source, answers), source)
    assert code["bilateral_answer"].pulled == ("_bilateral_core",)
    assert "def pad(" not in code["bilateral_answer"].text
    assert code["pad_answer"] == Answer(answers["pad_answer"]) and ADDED not in code


def test_a_cell_that_does_not_compile_defines_nothing_but_is_compared_as_added_code(source):
    """It does not run in the grader; IPython's magic lines do not stop a cell from compiling."""
    broken = CORE + "\nreturn 3\n"  # 'return' outside a function: the cell does not compile
    magic = "%timeit -n 1 bilateral(np.zeros((4, 4)), 1, 1)\n" + CORE_COPY
    answer = HEAD + ("    return _bilateral_core(image, sigma_space, sigma_range, 3, border)"
                     " + _smooth(image, 1, 1, 1, border)\n")
    code = similarity.student_code(_notebook(source, {"bilateral_answer": answer},
                                             {"bilateral_answer": [broken, magic]}), source)
    assert code["bilateral_answer"].pulled == ("_smooth",)
    assert code[ADDED].text == broken + "\n\n" + magic


def test_a_helper_called_through_a_string_is_reported_among_the_added_cells(tmp_path, source):
    """Names are matched, not traced: ``globals()["..."]`` pulls in nothing, so the answers
    alone are compared for the exercise; the copied helper shows in ``(added cells)``."""
    roundabout = HEAD + '    return globals()["_" + "smooth"](image, sigma_space, sigma_range, radius or 3, border)\n'
    code = similarity.student_code(_notebook(source, {"bilateral_answer": roundabout},
                                             {"bilateral_answer": [CORE_COPY]}), source)
    assert code["bilateral_answer"] == Answer(roundabout)
    course, sources = _course(tmp_path, source, {
        "ann": _notebook(source, {"bilateral_answer": ANN_ANSWER}, {"bilateral_answer": [CORE]}),
        "jon": _notebook(source, {"bilateral_answer": roundabout}, {"bilateral_answer": [CORE_COPY]})})
    assert {(p.exercise, p.a, p.b, p.added) for p in similarity.report(course, sources, "ch03")} == {
        (ADDED, "ann", "jon", ALL_ADDED)}


def test_a_helper_beside_an_answer_with_other_line_endings_is_still_found(source):
    """The cheap test that spares parsing plain answer cells splits lines as the grader's
    worker does: a helper after a carriage return is a top-level statement there too."""
    stubs = {grade_id: exercise.stub for grade_id, exercise in similarity.exercises_from(source).items()}
    answers = {"pad_answer": (stubs["pad_answer"] + "\n\n\n" + CORE).replace("\n", "\r"),
               "bilateral_answer": HEAD + "    return _bilateral_core(image, sigma_space, sigma_range, 3, border)\n"}
    code = similarity.student_code(_notebook(source, answers), source)
    assert code["bilateral_answer"].pulled == ("_bilateral_core",)


def test_independent_solutions_moved_into_helpers_stay_below_the_threshold(source):
    """Chapter 3's independent alternatives and the notebook's solutions, each moved whole into
    a helper that the answer cell calls with the stub's parameters: the shared call and ``def``
    line are boilerplate (without that, gaussian's pair scores 0.59)."""
    import ast
    import inspect
    import re

    import alternatives_ch03

    exercises = similarity.exercises_from(source)
    solutions = similarity.answer_sources(source)

    def wrapped(grade_id: str, function: str, helper: str) -> tuple[str, str]:
        stub = exercises[grade_id].stub
        definition = next(node for node in ast.parse(stub).body if isinstance(node, ast.FunctionDef))
        arguments = ", ".join(a.arg for a in definition.args.args)
        body = re.sub(r"^(@student\([^)]*\)\n)?def \w+\(", f"def {helper}(", function, count=1, flags=re.M)
        return stub.replace("# YOUR CODE HERE\n    raise NotImplementedError()", f"return {helper}({arguments})"), body

    answers: dict[str, dict[str, str]] = {"alt": {}, "nb": {}}
    added: dict[str, dict[str, list[str]]] = {"alt": {}, "nb": {}}
    for grade_id in exercises:
        name = grade_id[: -len("_answer")]
        if hasattr(alternatives_ch03, name):
            for student, function in (("alt", inspect.getsource(getattr(alternatives_ch03, name))),
                                      ("nb", re.sub(r"^[ \t]*### (BEGIN|END) SOLUTION[^\n]*\n?", "",
                                                    solutions[grade_id], flags=re.M))):
                answers[student][grade_id], helper = wrapped(grade_id, function, f"_{student}_{name}")
                added[student][grade_id] = [helper]
    assert len(answers["alt"]) >= 10
    code = {student: similarity.student_code(_notebook(source, answers[student], added[student]), source)
            for student in answers}
    assert all(code["alt"][grade_id].pulled == (f"_alt_{grade_id[:-7]}",) for grade_id in answers["alt"])
    exercises_and_added = {**exercises, ADDED: similarity.added_cells_exercise(source)}
    pairs = similarity.similar_pairs(code, exercises_and_added, threshold=0.0)
    between = [p.similarity for p in pairs if (p.a, p.b) == ("alt", "nb")]
    assert len(between) == len(answers["alt"]) + 1 and max(between) < THRESHOLD - 0.15
    # the notebook's solutions, moved into helpers, are still found against the solution — those
    # with a few lines of their own: a one-line answer (Chapter 3's measured denoise calls the
    # student's nl_means with chosen parameters) is mostly the shared call and def line once moved
    def own_lines(solution: str) -> list[str]:
        body = solution.split("### BEGIN SOLUTION", 1)[-1].split("### END SOLUTION", 1)[0]
        return [line for line in body.splitlines() if line.strip() and not line.strip().startswith("#")]

    found = {p.exercise for p in pairs if (p.a, p.b) == ("nb", SOLUTION) and p.similarity >= THRESHOLD}
    substantive = {grade_id for grade_id in answers["nb"] if len(own_lines(solutions[grade_id])) >= 3}
    assert len(substantive) >= 10 and substantive <= found <= set(answers["nb"]), (substantive, found)


def test_an_assignment_with_several_notebooks_names_each_notebooks_added_cells(tmp_path, source):
    """Each notebook runs in its own kernel: its added cells are its own pseudo-exercise."""
    (tmp_path / "source" / "two").mkdir(parents=True)
    for name in ("a", "b"):
        (tmp_path / "source" / "two" / f"{name}.ipynb").write_text(json.dumps(source))
    for student, answer, helper in (("ann", ANN_ANSWER, CORE), ("bob", BOB_ANSWER, CORE_COPY)):
        folder = tmp_path / "course" / "submitted" / student / "two"
        folder.mkdir(parents=True)
        (folder / "b.ipynb").write_text(json.dumps(_notebook(source, {"bilateral_answer": answer},
                                                             {"bilateral_answer": [helper]})))
    pairs = similarity.report(tmp_path / "course", tmp_path / "source", "two")
    assert {(p.exercise, p.a, p.b) for p in pairs} == {("b:bilateral_answer", "ann", "bob"),
                                                        ("b:(added cells)", "ann", "bob")}
