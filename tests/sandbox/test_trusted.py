"""Trusted grading: the attack suite at the notebook level.

Every attack is a real student notebook graded by :func:`cvkit.course.trusted.grade_notebook`
(the function nbgrader's TrustedChecks preprocessor calls): the student's code runs in an
isolated worker, outputs come back as data, the verdict is made here. Each attack must be
graded exactly as it deserves — zero for the cheated exercise, full marks for the honest one
next to it — and flagged where the static scan can see it.
"""
import dataclasses
import json
import os
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cvkit import registry
from cvkit.grading import wire
from cvkit.sandbox import session as sandbox
from cvkit.course.trusted import grade_notebook, hide_hidden_tests, scan

SETUP = textwrap.dedent("""\
    %matplotlib inline
    import numpy as np
    import cvkit
    from cvkit import filters, noise
    from cvkit.grading import check
    from cvkit.registry import student
    """)

HONEST_KERNEL = textwrap.dedent("""\
    @student("filters.mean_kernel")
    def mean_kernel(size):
        return np.full((size, size), 1.0 / (size * size))
    """)

HONEST_MEDIAN = textwrap.dedent("""\
    @student("filters.median")
    def median(image, size, border="reflect101"):
        image = np.asarray(image, dtype=float)
        modes = {"zero": "constant", "replicate": "edge", "reflect": "symmetric", "reflect101": "reflect"}
        r = size // 2
        width = ((r, r), (r, r)) + ((0, 0),) * (image.ndim - 2)
        if border == "zero":
            padded = np.pad(image, width, mode="constant")
        else:
            padded = np.pad(image, width, mode=modes[border])
        windows = np.lib.stride_tricks.sliding_window_view(padded, (size, size), axis=(0, 1))
        return np.median(windows, axis=(-2, -1))
    """)


def _code(source, grade_id=None, solution=False, grade=False, points=None):
    meta = {}
    if grade_id:
        meta = {"nbgrader": {"grade_id": grade_id, "solution": solution, "grade": grade, "locked": not solution,
                             "schema_version": 3}}
        if points is not None:
            meta["nbgrader"]["points"] = points
    return {"cell_type": "code", "source": source, "metadata": meta, "outputs": [], "execution_count": None}


def notebook(kernel_answer=HONEST_KERNEL, median_answer=HONEST_MEDIAN, extra_cells=()):
    cells = [_code(SETUP, "setup")]
    cells.append(_code(kernel_answer, "mean_kernel_answer", solution=True))
    cells.append(_code('check("filters.mean_kernel", mean_kernel)', "mean_kernel_visible", grade=True, points=1))
    cells.append(_code('### BEGIN HIDDEN TESTS\ncheck("filters.mean_kernel", mean_kernel, hidden=True, points=2)\n'
                       '### END HIDDEN TESTS', "mean_kernel_hidden", grade=True, points=2))
    cells += [_code(c) for c in extra_cells]
    cells.append(_code(median_answer, "median_answer", solution=True))
    cells.append(_code('check("filters.median", median)', "median_visible", grade=True, points=1))
    cells.append(_code('### BEGIN HIDDEN TESTS\ncheck("filters.median", median, hidden=True, points=2)\n'
                       '### END HIDDEN TESTS', "median_hidden", grade=True, points=2))
    return {"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5}


SOURCE = notebook()


def grade(nb, student="mallory"):
    result = grade_notebook(nb, student=student, salt="attack-suite", source_notebook=SOURCE)
    scores = {gid: result.credit(gid, points)[0] for gid, points in
              (("mean_kernel_visible", 1), ("mean_kernel_hidden", 2), ("median_visible", 1), ("median_hidden", 2))}
    return scores, result


def exercise(scores, name):
    return scores[f"{name}_visible"] + scores[f"{name}_hidden"]


@pytest.fixture
def quick_median():
    """The median check with a 1-second time limit (the loops below must not take minutes)."""
    record = registry.get("filters.median")
    original = record.check
    record._check = dataclasses.replace(original, time_limit=1.0)
    yield
    record._check = original


def test_honest_notebook_gets_full_marks():
    scores, result = grade(notebook())
    assert exercise(scores, "mean_kernel") == 3 and exercise(scores, "median") == 3
    assert result.flags == [] and result.worker_problem is None


def test_calling_the_reference_scores_zero():
    cheat = HONEST_MEDIAN.replace("image = np.asarray(image, dtype=float)", "return filters.median(image, size, border)")
    scores, result = grade(notebook(median_answer=cheat))
    assert exercise(scores, "median") == 0 and exercise(scores, "mean_kernel") == 3
    messages = [c.message for _, r in result.reports["median_visible"] for c in r.cases]
    assert any("not available while your code is graded" in m for m in messages)


@pytest.mark.parametrize("library", ["scipy.ndimage", "skimage.filters", "cv2", "sklearn.neighbors"])
def test_forbidden_libraries_cannot_be_imported(library):
    cheat = f"import {library}\n" + HONEST_MEDIAN
    scores, result = grade(notebook(median_answer=cheat))
    assert exercise(scores, "median") in (0, 3)  # the import fails at cell level ...
    assert any(library.split(".")[0] in e for e in result.cell_errors)  # ... and is reported
    assert any("not allowed in exercises" in f for f in result.flags)
    inside = HONEST_MEDIAN.replace("image = np.asarray(image, dtype=float)",
                                   f"import {library}\n    image = np.asarray(image, dtype=float)")
    scores, _ = grade(notebook(median_answer=inside))
    assert exercise(scores, "median") == 0 and exercise(scores, "mean_kernel") == 3


def test_monkeypatching_the_grader_changes_nothing():
    cheat = textwrap.dedent("""\
        import cvkit.grading
        cvkit.grading.check = lambda *args, **kwargs: 2.0
        np.allclose = lambda *args, **kwargs: True
        np.testing.assert_allclose = lambda *args, **kwargs: None
        def check(*args, **kwargs):
            return 2.0

        @student("filters.median")
        def median(image, size, border="reflect101"):
            return np.asarray(image, dtype=float)
        """)
    scores, result = grade(notebook(median_answer=cheat))
    plain = cheat[cheat.index('@student("filters.median")'):]  # the same wrong answer, no cheating
    honest_scores, _ = grade(notebook(median_answer=plain))
    assert scores == honest_scores and exercise(scores, "median") < 1 and exercise(scores, "mean_kernel") == 3
    flags = " | ".join(result.flags)
    assert "monkeypatches np.allclose" in flags and "redefines the grader's check()" in flags
    assert "imports cvkit.grading" in flags


@pytest.mark.parametrize("fallback", ["np.zeros(np.shape(image)).tolist()", "np.asarray(image, dtype=float).tolist()"],
                         ids=["zeros", "identity"])
def test_hard_coded_public_outputs_score_zero_and_are_flagged(fallback):
    """Memorising the shown answers gains nothing, even when the fallback answers the hidden
    cases whose output is trivial (all zeros, or the input itself)."""
    check = registry.get("filters.median").check
    table = {}
    for case in check.public_cases():
        with registry.use("reference"):
            out = registry.get("filters.median").reference(*case.args, **case.kwargs)
        key = f"{np.asarray(case.args[0], dtype=float).tobytes().hex()}|{case.args[1]}|{case.kwargs.get('border', 'reflect101')}"
        table[key] = out.tolist()
    cheat = textwrap.dedent(f"""\
        ANSWERS = {json.dumps(table)}

        @student("filters.median")
        def median(image, size, border="reflect101"):
            key = f"{{np.asarray(image, dtype=float).tobytes().hex()}}|{{size}}|{{border}}"
            return np.array(ANSWERS.get(key, FALLBACK))
        """).replace("FALLBACK", fallback)
    scores, result = grade(notebook(median_answer=cheat))
    assert exercise(scores, "median") == 0 and exercise(scores, "mean_kernel") == 3
    assert any("passes only the public cases" in f for f in result.flags)


def test_infinite_loop_costs_only_that_exercise(quick_median):
    cheat = HONEST_MEDIAN.replace("image = np.asarray(image, dtype=float)", "while True:\n        pass")
    scores, result = grade(notebook(median_answer=cheat))
    assert exercise(scores, "median") == 0 and exercise(scores, "mean_kernel") == 3
    for grade_id in ("median_visible", "median_hidden"):
        (_, report), = result.reports[grade_id]
        first, rest = report.cases[0], report.cases[1:]
        # stopped in its `while True:` (line 3 of the answer cell): the advice is the loop's exit
        # condition, and the rest of the check is not run to its limit (issue #35)
        assert first.timed_out and "look at your loop's exit condition" in first.message, first.message
        assert "`while` loop of line 3" in first.message and "vectorize" not in first.message
        assert rest and all(c.message.startswith("not run:") for c in rest), [c.message for c in rest]


def test_huge_allocation_is_refused():
    cheat = HONEST_MEDIAN.replace("image = np.asarray(image, dtype=float)",
                                  "np.ones(100 * 2**30 // 8)\n    image = np.asarray(image, dtype=float)")
    scores, result = grade(notebook(median_answer=cheat))
    assert exercise(scores, "median") == 0 and exercise(scores, "mean_kernel") == 3
    messages = [c.message for _, r in result.reports["median_visible"] for c in r.cases]
    assert any("MemoryError" in m for m in messages)


@pytest.mark.parametrize("exit_call", ["os._exit(0)", "sys.exit(0)", "exit()"])
def test_exiting_costs_only_that_exercise(exit_call):
    cheat = "import os, sys\n" + HONEST_MEDIAN.replace("image = np.asarray(image, dtype=float)", exit_call)
    # the exiting exercise comes first, the honest one after it
    nb = notebook(median_answer=cheat)
    nb["cells"] = nb["cells"][:1] + nb["cells"][4:] + nb["cells"][1:4]
    scores, result = grade(nb)
    assert exercise(scores, "median") == 0
    assert exercise(scores, "mean_kernel") == 3
    assert any("exit" in f for f in result.flags)


def test_exit_at_cell_level_costs_only_that_cell():
    # no import needed: NumPy's ctypes door reaches libc's _exit
    scores, result = grade(notebook(extra_cells=["np.ctypeslib.ctypes.CDLL(None)._exit(3)"]))
    assert scores == {"mean_kernel_visible": 1, "mean_kernel_hidden": 2, "median_visible": 1, "median_hidden": 2}
    assert any("cell 2" in e and "ended early" in e for e in result.cell_errors)


def test_fake_output_and_warnings_change_nothing():
    noisy = HONEST_MEDIAN.replace(
        "image = np.asarray(image, dtype=float)",
        "import warnings\n    print('All tests passed! 3/3')\n    warnings.warn('just a warning')\n"
        "    image = np.asarray(image, dtype=float)")
    scores, _ = grade(notebook(median_answer=noisy))
    assert exercise(scores, "median") == 3
    wrong = HONEST_MEDIAN.replace("np.median(", "np.mean(")
    scores, _ = grade(notebook(median_answer="print('All tests passed!')\n" + wrong))
    silent, _ = grade(notebook(median_answer=wrong))
    assert scores == silent and exercise(scores, "median") < 1


def test_worker_cannot_touch_course_files(tmp_path):
    course = tmp_path / "course"
    course.mkdir(mode=0o700)
    victim = course / "gradebook.db"
    victim.write_text("precious")
    other = course / "other_student.ipynb"
    other.write_text("their work")
    cheat = HONEST_MEDIAN.replace(
        "image = np.asarray(image, dtype=float)",
        "libc = np.ctypeslib.ctypes.CDLL(None)\n"
        f"    for path in ({str(victim)!r}, {str(other)!r}):\n"
        "        libc.unlink(path.encode())\n"
        f"    try:\n        open({str(victim)!r}, 'w').write('pwned')\n    except OSError:\n        pass\n"
        "    image = np.asarray(image, dtype=float)")
    scores, result = grade(notebook(median_answer=cheat))
    assert victim.read_text() == "precious" and other.read_text() == "their work"
    assert exercise(scores, "median") == 3  # the honest computation still counts ...
    assert any("opens files" in f for f in result.flags)  # ... and the attempt is flagged


def test_student_added_helper_cells_are_used():
    helper = "def window_median(windows):\n    return np.median(windows, axis=(-2, -1))"
    answer = HONEST_MEDIAN.replace("return np.median(windows, axis=(-2, -1))", "return window_median(windows)")
    scores, _ = grade(notebook(median_answer=answer, extra_cells=[helper]))
    assert exercise(scores, "median") == 3


def test_hidden_cases_differ_between_students():
    _, a = grade(notebook(), student="ada")
    _, b = grade(notebook(), student="bob")
    seeds = lambda r: [rep.seed for _, rep in r.reports["median_hidden"]]  # noqa: E731
    assert seeds(a) != seeds(b)


def test_wire_format_refuses_objects_and_roundtrips_arrays():
    value = (np.arange(6.0).reshape(2, 3), {"k": [1, 2.5, None, True]}, np.uint8(7), "text")
    back = wire.loads(wire.dumps(value))
    assert np.array_equal(back[0], value[0]) and back[1] == {"k": [1, 2.5, None, True]}
    assert int(back[2]) == 7 and back[3] == "text"
    zero_d = wire.loads(wire.dumps(np.array(2.5)))
    assert isinstance(zero_d, np.ndarray) and zero_d.shape == () and zero_d == 2.5
    assert wire.loads(wire.dumps(np.float32(1.5))) == 1.5  # NumPy scalars travel as plain numbers
    fortran = np.asfortranarray(np.arange(6.0).reshape(2, 3))
    assert np.array_equal(wire.loads(wire.dumps(fortran)), fortran)
    rng = np.random.default_rng(5)
    assert wire.decode(wire.encode(rng)).random() == np.random.default_rng(5).random()
    with pytest.raises(wire.WireError):
        wire.encode(np.array([object()]))
    with pytest.raises(wire.WireError):
        wire.encode(lambda: 0)
    with pytest.raises(wire.WireError):
        wire.decode({"t": "nd", "dtype": "|O", "shape": [1], "data": ""})


def test_a_box_call_crosses_the_wire_as_the_worker_reads_it():
    """The one request for a case: the trusted side's BoxCall comes back the same from its wire form
    (JSON), with the keys the worker has always read, and an input that cannot cross is refused
    before any sandbox starts."""
    import json

    call = wire.BoxCall("correlate", group="correlate:filters.correlate:hidden", args=(np.arange(6.0).reshape(2, 3),),
                        kwargs={"border": "wrap"}, time_limit=7.5, allowed=("filters.pad", "data.camera"),
                        arg_names=("image", "kernel"), forbidden_libraries=("scipy",),
                        forbidden_functions=("numpy.pad",), adapter="instance_call", substitute={"pad": "filters.pad"})
    data = json.loads(json.dumps(call.to_wire()))
    assert list(data) == ["function", "group", "args", "kwargs", "time_limit", "allowed", "arg_names",
                          "forbidden_libraries", "forbidden_functions", "call", "substitute"]
    back = wire.BoxCall.from_wire(data)
    assert np.array_equal(back.args[0], call.args[0]) and back.kwargs == call.kwargs
    assert (back.function, back.group, back.time_limit, back.allowed, back.arg_names, back.forbidden_libraries,
            back.forbidden_functions, back.adapter, back.substitute) == \
        (call.function, call.group, call.time_limit, call.allowed, call.arg_names, call.forbidden_libraries,
         call.forbidden_functions, call.adapter, call.substitute)
    plain = wire.BoxCall.from_wire(json.loads(json.dumps(wire.BoxCall("f", args=(1,)).to_wire())))
    assert plain.check_group == "f" and plain.allowed is None and plain.time_limit == wire.DEFAULT_TIME_LIMIT
    with pytest.raises(wire.WireError):
        wire.BoxCall("f", args=(object(),)).to_wire()
    with pytest.raises(wire.WireError):
        sandbox.run_calls(["def f(x):\n    return x"], [wire.BoxCall("f", args=(object(),))], sandboxed=False)


def test_scan_flags_and_hidden_test_source_is_hidden():
    flags = scan("import ctypes\nimport subprocess\nx.__globals__\nos.remove('a')\nsys.setprofile(None)")
    text = " | ".join(flags)
    for expected in ("imports ctypes", "imports subprocess", ".__globals__", "deletes files", "sys.setprofile"):
        assert expected in text
    assert scan(HONEST_MEDIAN) == []
    shown = hide_hidden_tests('x = 1\n### BEGIN HIDDEN TESTS\ncheck("a.b", f, hidden=True)\n### END HIDDEN TESTS\n')
    assert "check(" not in shown and "hidden tests" in shown


CORRELATE_WITH_PAD = textwrap.dedent("""\
    @student("filters.correlate")
    def correlate(image, kernel, border="reflect101", output="same"):
        image = np.asarray(image, dtype=float)
        kernel = np.asarray(kernel, dtype=float)
        ry, rx = kernel.shape[0] // 2, kernel.shape[1] // 2
        padded = filters.pad(image, (ry, rx), border) if output == "same" else image
        windows = np.lib.stride_tricks.sliding_window_view(padded, kernel.shape, axis=(0, 1))
        if image.ndim == 3:
            return np.einsum("hwcij,ij->hwc", windows, kernel)
        return np.einsum("hwij,ij->hw", windows, kernel)
    """)


def _correlate_notebook(answer):
    setup = SETUP
    cells = [_code(setup, "setup"), _code(answer, "correlate_answer", solution=True),
             _code('check("filters.correlate", correlate)', "correlate_visible", grade=True, points=1)]
    return {"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5}


def test_an_allowed_building_block_is_served_and_others_are_refused():
    """filters.pad is allowed in the correlation exercise: the sandbox has no reference code,
    its stand-in gets the value from the trusted side. filters.correlate itself is refused."""
    nb = _correlate_notebook(CORRELATE_WITH_PAD)
    graded = grade_notebook(nb, student="sam", salt="s", source_notebook=_correlate_notebook("pass"))
    (call, report), = graded.reports["correlate_visible"]
    # (this quick correlate mishandles even kernels; the odd-kernel cases need pad served)
    assert report.cases[0].passed and report.cases[3].passed, report.summary()
    cheat = '@student("filters.correlate")\ndef correlate(image, kernel, border="reflect101", output="same"):\n' \
            '    return filters.correlate(image, kernel, border, output)'
    graded = grade_notebook(_correlate_notebook(cheat), student="sam", salt="s",
                            source_notebook=_correlate_notebook("pass"))
    (call, report), = graded.reports["correlate_visible"]
    assert not report.passed and report.score == 0
    assert any("not available" in (c.message or "") or "not allowed" in (c.message or "") for c in report.cases)


def test_building_blocks_are_graded_before_the_exercises_that_use_them():
    from cvkit.course.trusted import CheckCall, _building_blocks_first

    calls = [CheckCall("c", "filters.correlate", "correlate", False, None),
             CheckCall("p", "filters.pad", "pad", False, None),
             CheckCall("m", "filters.median", "median", True, 2)]
    order = [c.algorithm_id for c in _building_blocks_first(calls)]
    assert order.index("filters.pad") < order.index("filters.correlate")
    assert order.index("filters.pad") < order.index("filters.median")


def test_scan_sees_reflection_and_the_import_machinery():
    flags = scan('g = getattr(f, "__globals__")\nh = getattr(f, name)\nimport sys\nsys.meta_path.remove(b)\n'
                 'm = sys.modules["cvkit"]\nimp = np.__builtins__["__import__"]')
    for expected in ("getattr(…, '__globals__')", "computed attribute name", "changes sys.meta_path",
                     "indexes sys.modules", "indexes np.__builtins__"):
        assert any(expected in f for f in flags), (expected, flags)
    assert scan("def f(x):\n    return getattr(x, 'shape')") == []


TOPIC_IMPORTS = textwrap.dedent("""\
    import cvkit.camera
    from cvkit import calibration

    def project(points):
        return cvkit.camera.project(points)

    def calibrate(points):
        return calibration.calibrate(points)
    """)
NEW_TOPIC_IMPORT = textwrap.dedent("""\
    import cvkit.segmentation

    def segment(points):
        return cvkit.segmentation.segment(points)
    """)


@pytest.mark.parametrize("extra", [[], ["segmentation"]], ids=["cvkit", "with a new topic"])
def test_cvkit_modules_are_flagged_and_refused_through_one_list(monkeypatch, extra):
    """registry.topic_modules() is the one list of cvkit's algorithm modules: an answer cell
    importing one of them is flagged by the static scan and meets a refusing stand-in in the
    sandbox worker. A topic added to that list (here a made-up ``segmentation``) is both."""
    topics = registry.topic_modules()
    assert {"camera", "calibration"} <= set(topics) and "segmentation" not in topics
    monkeypatch.setattr(registry, "topic_modules", lambda: topics + extra)
    flags = scan(TOPIC_IMPORTS + NEW_TOPIC_IMPORT)
    for module in ["camera", "calibration"] + extra:
        assert f"imports cvkit.{module} (not allowed in exercises)" in flags, flags
    assert any("segmentation" in flag for flag in flags) == bool(extra)

    points = np.zeros((4, 3))
    calls = [wire.BoxCall(name, args=(points,), time_limit=5.0)
             for name in ("project", "calibrate", "segment")]
    result = sandbox.run_calls([TOPIC_IMPORTS, NEW_TOPIC_IMPORT], calls)
    refused = [o for o in result.outcomes if o.error and "not available while your code is graded" in o.error]
    assert all(o.value is None for o in result.outcomes)
    if extra:  # a stand-in for the new topic too: every call is refused by its stand-in
        assert result.cell_errors == [] and len(refused) == 3, (result.cell_errors, result.outcomes)
    else:  # not a topic: no stand-in, the import itself fails and `segment` is never defined
        assert len(refused) == 2 and "no function called 'segment'" in result.outcomes[2].error
        assert any("cvkit.segmentation" in error for error in result.cell_errors), result.cell_errors


def _chapter3_solution(grade_id):
    from pathlib import Path

    from cvkit.course import solution_sources

    path = Path(__file__).resolve().parents[2] / "lectures" / "ch03_filtering" / "ch03_filtering.ipynb"
    return solution_sources(json.loads(path.read_text()))[grade_id]


HONEST_PAD = _chapter3_solution("pad_answer")
WRONG_PAD = HONEST_PAD.replace("return np.minimum(idx, period - idx)", "return np.minimum(idx, period - 1 - idx)")
assert WRONG_PAD != HONEST_PAD


def _cascade_notebook(pad_answer, correlate_answer):
    cells = [_code(SETUP, "setup"), _code(pad_answer, "pad_answer", solution=True),
             _code('check("filters.pad", pad)', "pad_visible", grade=True, points=1),
             _code(correlate_answer, "correlate_answer", solution=True),
             _code('check("filters.correlate", correlate)', "correlate_visible", grade=True, points=1),
             _code('### BEGIN HIDDEN TESTS\ncheck("filters.correlate", correlate, hidden=True, points=2)\n'
                   '### END HIDDEN TESTS', "correlate_hidden", grade=True, points=2)]
    return {"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5}


CORRELATE_WITH_OWN_PAD = _chapter3_solution("correlate_answer")  # it calls the student's own pad


def test_a_wrong_building_block_costs_points_once():
    """The student's correlate calls their own (wrong) pad: correlate is graded with the
    reference pad, passes, and the report says which function is to blame."""
    nb = _cascade_notebook(WRONG_PAD, CORRELATE_WITH_OWN_PAD)
    graded = grade_notebook(nb, student="cas", salt="s", source_notebook=_cascade_notebook("pass", "pass"))
    assert graded.credit("pad_visible", 1)[0] == 0
    assert graded.credit("correlate_visible", 1)[0] == 1 and graded.credit("correlate_hidden", 2)[0] == 2
    (_, report), = graded.reports["correlate_visible"]
    assert "`pad`" in report.cascade and "costs points once" in report.cascade
    # with a correct pad there is no cascade to report
    graded = grade_notebook(_cascade_notebook(HONEST_PAD, CORRELATE_WITH_OWN_PAD), student="cas", salt="s",
                            source_notebook=_cascade_notebook("pass", "pass"))
    assert graded.credit("pad_visible", 1)[0] == 1 and graded.credit("correlate_visible", 1)[0] == 1
    assert not getattr(graded.reports["correlate_visible"][0][1], "cascade", None)


def test_a_wrong_exercise_is_not_excused_by_its_building_block():
    wrong_correlate = CORRELATE_WITH_OWN_PAD.replace("kernel[m, n] *", "kernel[kh - 1 - m, kw - 1 - n] *")
    graded = grade_notebook(_cascade_notebook(WRONG_PAD, wrong_correlate), student="cas", salt="s",
                            source_notebook=_cascade_notebook("pass", "pass"))
    assert graded.credit("correlate_visible", 1)[0] == 0
    (_, report), = graded.reports["correlate_visible"]
    assert "problem is in `correlate` itself" in report.cascade


def test_in_the_notebook_a_wrong_building_block_costs_points_once(capsys):
    """check() in the student's kernel applies the same rule as the grader."""
    import cvkit
    from cvkit.grading import check

    student = registry.provider("student")
    saved = dict(student.functions)
    namespace = {"np": np, "student": cvkit.student}
    try:
        exec(compile(WRONG_PAD + "\n" + CORRELATE_WITH_OWN_PAD, "<answers>", "exec"), namespace)
        with pytest.raises(AssertionError):
            check("filters.pad", namespace["pad"])
        check("filters.correlate", namespace["correlate"])  # passes with the reference pad
        shown = capsys.readouterr().out
        assert "costs points once" in shown and "`pad`" in shown
        assert namespace["pad"] is student.functions["filters.pad"]  # the student's pad is put back
    finally:
        student.functions.clear()
        student.functions.update(saved)


def test_the_kernel_and_the_grader_word_a_cascade_alike(capsys):
    """One wording of "which function to fix" (cvkit.grading.report.cascade_report): the
    sentence the trusted grader writes is the one check() prints in the student's kernel."""
    import cvkit
    from cvkit.grading import check

    graded = grade_notebook(_cascade_notebook(WRONG_PAD, CORRELATE_WITH_OWN_PAD), student="cas", salt="s",
                            source_notebook=_cascade_notebook("pass", "pass"))
    (_, report), = graded.reports["correlate_visible"]
    student = registry.provider("student")
    saved = dict(student.functions)
    namespace = {"np": np, "student": cvkit.student}
    try:
        exec(compile(WRONG_PAD + "\n" + CORRELATE_WITH_OWN_PAD, "<answers>", "exec"), namespace)
        check("filters.correlate", namespace["correlate"])
    finally:
        student.functions.clear()
        student.functions.update(saved)
    assert report.cascade and report.cascade in capsys.readouterr().out


LECTURES = sorted((Path(__file__).resolve().parents[2] / "lectures").glob("ch*/*.ipynb"))


@pytest.mark.parametrize("path", LECTURES, ids=lambda p: p.parent.name)
def test_every_lecture_setup_cell_runs_in_the_grading_worker(path):
    """The locked set-up cells of each chapter run in the sandbox worker before the answers:
    every name they import from cvkit (check, needs_answer, load_answers, ...) has a stand-in
    there, or the whole notebook would score zero."""
    nb = json.loads(path.read_text())
    setup = ["".join(c["source"]) if isinstance(c["source"], list) else c["source"] for c in nb["cells"]
             if c["cell_type"] == "code" and c.get("metadata", {}).get("nbgrader", {}).get("locked")
             and not c["metadata"]["nbgrader"].get("grade") and not c["metadata"]["nbgrader"].get("solution")]
    assert setup, "a locked set-up cell"
    result = sandbox.run_calls(setup, [])
    assert result.cell_errors == [], result.cell_errors


@pytest.mark.slow
@pytest.mark.parametrize("path", LECTURES, ids=lambda p: p.parent.name)
def test_every_chapters_solutions_get_full_marks_in_the_sandbox(path):
    """The instructor's solutions, graded as a submission is (every check decided in the
    sandbox worker, hidden cases of a student's seed): every test cell full marks, no flag,
    no worker problem. A check whose ``call`` adapter or stand-in the sandbox lacks fails here
    rather than on the first real submission."""
    nb = json.loads(path.read_text())
    graded = grade_notebook(nb, student="honest-student", salt="ci-salt", source_notebook=nb)
    assert graded.worker_problem is None and graded.cell_errors == [], (graded.worker_problem, graded.cell_errors)
    assert graded.flags == [], graded.flags
    tests = [c["metadata"]["nbgrader"]["grade_id"] for c in nb["cells"] if c["cell_type"] == "code"
             and c.get("metadata", {}).get("nbgrader", {}).get("grade") and not c["metadata"]["nbgrader"].get("solution")]
    assert sorted(graded.reports) == sorted(tests)
    lost = {grade_id: [(call.algorithm_id, report.summary()) for call, report in reports if report.score < 1.0]
            for grade_id, reports in graded.reports.items()}
    assert not any(lost.values()), {k: v for k, v in lost.items() if v}
