"""The attack suite, round 2 (issue 32): a determined student against ``cvkit course grade``.

A class of 40: every attack of the round is a real submission, graded with honest students in
one batch through :meth:`Course.grade` (what ``cvkit course grade`` runs) with two workers, on a
tiny chapter of three exercises: ``filters.median``, ``noise.add_gaussian`` and
``filters.mean_kernel``. Each attack asserts its exact grades (or that it is listed as not
graded, with the reason), and every honest student keeps full marks. The attacks that
need no course (a channel flood, the notebook's total time, a lookup table of hidden cases
learned from an earlier attempt) are graded through :func:`~cvkit.course.trusted.grade_notebook`
and :func:`~cvkit.sandbox.session.run_calls`, the trusted path every submission takes.
"""
import csv
import json
import os
import re
import textwrap
import time

import numpy as np
import pytest

from cvkit import registry
from cvkit.course import Course
from cvkit.grading import evaluate, hidden_seed
from cvkit.sandbox import session as sandbox
from cvkit.sandbox.notebook_run import bounded, execute_in_sandbox
from cvkit.grading.runtime.guard import Outcome
from cvkit.grading.runtime.wire import BoxCall
from cvkit.course import trusted
from cvkit.course.trusted import grade_notebook, submission_version

from course_helpers import cell_grades, exercise_cells, new_cell, new_notebook, submitted, write_project

pytestmark = pytest.mark.slow

ASSIGNMENT = "ch98_round2"
SALT = "round-2-salt"
FULL = {"median_visible": 1, "median_hidden": 2, "add_gaussian_visible": 1, "add_gaussian_hidden": 2,
        "mean_kernel_visible": 1, "mean_kernel_hidden": 2}
REAL_IMPORT = "__imp = np.__builtins__['__import__']\n"


MEDIAN_CODE = '''\
def _median(image, size, border="reflect101"):
    image = np.asarray(image, dtype=float)
    mode = {"reflect101": "reflect", "reflect": "symmetric", "replicate": "edge", "wrap": "wrap",
            "constant": "constant", "zero": "constant"}[border]
    r = size // 2
    padded = np.pad(image, [(r, r), (r, r)] + [(0, 0)] * (image.ndim - 2), mode=mode)
    windows = np.lib.stride_tricks.sliding_window_view(padded, (size, size), axis=(0, 1))
    return np.median(windows, axis=(-2, -1))
'''
ANSWERS = {
    "median": MEDIAN_CODE + '\n@student("filters.median")\ndef median(image, size, border="reflect101"):\n'
                            '    return _median(image, size, border)',
    "add_gaussian": '@student("noise.add_gaussian")\ndef add_gaussian(image, sigma, rng=None):\n'
                    '    rng = np.random.default_rng(rng)\n    image = np.asarray(image, dtype=float)\n'
                    '    return image + rng.normal(0.0, sigma, image.shape)',
    "mean_kernel": '@student("filters.mean_kernel")\ndef mean_kernel(size):\n'
                   '    return np.full((size, size), 1.0 / (size * size))',
}
IDS = {"median": "filters.median", "add_gaussian": "noise.add_gaussian", "mean_kernel": "filters.mean_kernel"}


def source_notebook():
    cells = [new_cell("# Round 2", cell_type="markdown"),
             new_cell("import numpy as np\nimport cvkit\nfrom cvkit import data, filters, noise\n"
                      "from cvkit.grading import check\nfrom cvkit.registry import student", "setup")]
    for name, answer in ANSWERS.items():
        cells += exercise_cells(IDS[name], name, "\n".join(["### BEGIN SOLUTION", answer, "### END SOLUTION"]))
    return new_notebook(cells)


def submission(added=None, **answers):
    """The release notebook with answers (the honest ones unless given) and ``added`` cells
    inserted after the setup cell."""
    nb = submitted(source_notebook(), {f"{name}_answer": answers.get(name, answer) for name, answer in ANSWERS.items()})
    for offset, source in enumerate(added or []):
        nb["cells"].insert(2 + offset, new_cell(source))
    return nb


# ------------------------------------------------------------------------------- the attacks
HELPER_IS_THE_ANSWER = ('@student("noise.add_gaussian")\ndef add_gaussian(image, sigma, rng=None):\n'
                        '    return data.with_gaussian_noise(image, sigma, rng)')
# serving time hidden behind requests: 25 s of wall clock per case, nearly all of it spent by
# the grader answering data requests (which used to be subtracted from the case's clock)
SERVED_TIME = MEDIAN_CODE + textwrap.dedent('''
    @student("filters.median")
    def median(image, size, border="reflect101"):
        import time
        start = time.time()
        while time.time() - start < 25:
            try:
                data.camera()
            except RuntimeError:  # past the requests a case may make: keep the grader busy anyway
                pass
        return _median(image, size, border)''')
# one exercise records its inputs, a later one raises (and prints) with them
LEAKER_MEDIAN = MEDIAN_CODE + textwrap.dedent('''
    SEEN = []

    @student("filters.median")
    def median(image, size, border="reflect101"):
        SEEN.append([float(v) for v in np.asarray(image, dtype=float).ravel()[:8]])
        print("PRINTLEAK", SEEN[-1])
        return _median(image, size, border)''')
LEAKER_KERNEL = ('@student("filters.mean_kernel")\ndef mean_kernel(size):\n'
                 '    raise ValueError("LEAK" + repr(SEEN[-1] if SEEN else []))')
BIG_MESSAGE = ('@student("noise.add_gaussian")\ndef add_gaussian(image, sigma, rng=None):\n'
               '    raise ValueError("M" * 65536)')
FLOOD = (REAL_IMPORT + '@student("filters.mean_kernel")\ndef mean_kernel(size):\n'
         '    os = __imp("os")\n'
         '    os.write(int(os.environ["CVKIT_PROTOCOL_FD"]), b"[" + b"1," * 60_000_000 + b"1]\\n")\n'
         '    return np.full((size, size), 1.0 / (size * size))')
DRIVER_MEMORY = ("import os\ntry:\n    open(f'/proc/{os.getppid()}/mem', 'r+b').close()\n    print('DRIVER-MEM OPEN')\n"
                 "except OSError as error:\n    print('DRIVER-MEM', type(error).__name__)")


def _duplicated_grade_id():
    nb = submission()
    index = next(i for i, c in enumerate(nb["cells"])
                 if c["metadata"].get("nbgrader", {}).get("grade_id") == "mean_kernel_visible")
    nb["cells"].insert(index + 1, json.loads(json.dumps(nb["cells"][index])))
    return nb


# the same copied helper in an added cell, called by answer cells that differ
STACK_MEDIAN = '''\
def _stack_median(img, k, border):
    img = np.asarray(img, dtype=float)
    how = {"reflect101": "reflect", "reflect": "symmetric", "replicate": "edge", "wrap": "wrap",
           "constant": "constant", "zero": "constant"}[border]
    h = k // 2
    big = np.pad(img, [(h, h), (h, h)] + [(0, 0)] * (img.ndim - 2), mode=how)
    rows, cols = img.shape[:2]
    layers = [big[dy:dy + rows, dx:dx + cols] for dy in range(k) for dx in range(k)]
    return np.median(np.stack(layers), axis=0)
'''
STACK_MEDIAN_COPY = (STACK_MEDIAN.replace("_stack_median", "_my_filter").replace("img", "picture")
                     .replace("layers", "planes").replace("big", "framed").replace("how", "mode_name"))
COPIER_A = '@student("filters.median")\ndef median(image, size, border="reflect101"):\n    return _stack_median(image, size, border)'
COPIER_B = ('@student("filters.median")\ndef median(image, size, border="reflect101"):\n'
            '    """My median filter."""\n    result = _my_filter(np.asarray(image), int(size), border)\n    return result')
ESCAPER = ('@student("filters.mean_kernel")\ndef mean_kernel(size):\n'
           '    raise ValueError("\\x1b[2J\\x1b[3Jcleared")')

SUBMISSIONS = {
    "ada": lambda: submission(),
    "bea": lambda: submission(),
    "helper_answer": lambda: submission(add_gaussian=HELPER_IS_THE_ANSWER),
    "served_time": lambda: submission(median=SERVED_TIME),
    "leaker": lambda: submission(median=LEAKER_MEDIAN, mean_kernel=LEAKER_KERNEL),
    "big_message": lambda: submission(add_gaussian=BIG_MESSAGE, added=['raise ValueError("N" * 65536)']),
    "flooder": lambda: submission(mean_kernel=FLOOD),
    "duplicated_id": _duplicated_grade_id,
    "driver_memory": lambda: submission(added=[DRIVER_MEMORY]),
    "copier_a": lambda: submission(median=COPIER_A, added=[STACK_MEDIAN]),
    "copier_b": lambda: submission(median=COPIER_B, added=[STACK_MEDIAN_COPY]),
    "escaper": lambda: submission(mean_kernel=ESCAPER),
    "odd_files": lambda: submission(),
    "forged_time": lambda: submission(),
    "garbage_time": lambda: submission(),
}
HONEST_CLASSMATES = [f"honest_{i:02d}" for i in range(40 - len(SUBMISSIONS) - 3)]
EXPECTED = {
    "helper_answer": dict(FULL, add_gaussian_visible=0, add_gaussian_hidden=0),
    "served_time": dict(FULL, median_visible=0, median_hidden=0),
    "leaker": dict(FULL, mean_kernel_visible=0, mean_kernel_hidden=0),
    "big_message": dict(FULL, add_gaussian_visible=0, add_gaussian_hidden=0),
    "flooder": dict(FULL, mean_kernel_visible=0, mean_kernel_hidden=0),
    "duplicated_id": FULL,
    "driver_memory": FULL,
    "copier_a": FULL,
    "copier_b": FULL,
    "escaper": dict(FULL, mean_kernel_visible=0, mean_kernel_hidden=0),
    "odd_files": FULL,
    "forged_time": FULL,
    "garbage_time": FULL,
}
#: folders refused for their names: listed as not graded, never given to nbgrader
REFUSED = {"st\udcffudent": "is not valid UTF-8", "ada\u200b": "looks like student 'ada'"}


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    return write_project(tmp_path_factory.mktemp("project-round2"), f'[[assignment]]\nid = "{ASSIGNMENT}"\n',
                         {f"{ASSIGNMENT}/{ASSIGNMENT}.ipynb": source_notebook()})


@pytest.fixture(scope="module")
def graded(bubblewrap, project, tmp_path_factory):
    course = Course(tmp_path_factory.mktemp("round2-course") / "course", project=project)
    (course.root / ".grading_salt").write_text(SALT)
    course.build([ASSIGNMENT])
    name = f"{ASSIGNMENT}.ipynb"
    for student, make in SUBMISSIONS.items():
        course.submit(student, ASSIGNMENT, {name: make()})
    for student in HONEST_CLASSMATES + ["ada\u200b"]:
        course.submit(student, ASSIGNMENT, {name: submission()})
    # names of any bytes: a link and a pipe whose names are not UTF-8, a folder that is not UTF-8
    odd = bytes(course.root / "submitted" / "odd_files" / ASSIGNMENT)
    os.symlink(b"/etc/passwd", odd + b"/\xff\xfe.ipynb")
    os.mkfifo(odd + b"/bad\xff")
    bad_folder = bytes(course.root / "submitted") + b"/st\xffudent/" + ASSIGNMENT.encode()
    os.makedirs(bad_folder)
    with open(bad_folder + b"/" + name.encode(), "w") as handle:
        json.dump(submission(), handle)
    # a student's own timestamp.txt: forged, and garbage
    (course.root / "submitted" / "forged_time" / ASSIGNMENT / "timestamp.txt").write_text("1970-01-01 00:00:00.000000 UTC")
    (course.root / "submitted" / "garbage_time" / ASSIGNMENT / "timestamp.txt").write_text("not a date \x1b[2J")
    # a second notebook beside the assignment's: neither run nor checked, and flagged
    scratch = submission(mean_kernel='@student("filters.mean_kernel")\ndef mean_kernel(size):\n    return 0')
    course.submit("extra_notebook", ASSIGNMENT, {name: submission(), "scratch.ipynb": scratch})
    (course.root / "submitted" / "extra_notebook" / ASSIGNMENT / "garbage.ipynb").write_text('{"cells": [')
    calls_here = []
    sandbox.require_worker()  # the grader's own check that the worker starts (no student code), done once
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CVKIT_CELL_TIMEOUT", "60")
        patch.setenv("CVKIT_ANSWER_CELL_TIMEOUT", "20")
        # the writer (this process) must never run student code: the sandbox is only ever
        # driven from the grading workers
        def no_student_code_here(*args, **kwargs):
            calls_here.append(args)
            raise AssertionError("student code run by the process that writes the gradebook")

        patch.setattr(sandbox, "run_calls", no_student_code_here)
        patch.setattr(trusted, "run_calls", no_student_code_here)
        results = course.grade(workers=2)
    return course, results, calls_here


def _flags(course, student):
    return [f for e in course.scores(ASSIGNMENT)[student] for f in e.flags]


def _pages(course, student):
    return "".join(p.read_text() for p in (course.root / "feedback" / student).rglob("*.html"))


def _autograded(course, student):
    return (course.root / "autograded" / student / ASSIGNMENT / f"{ASSIGNMENT}.ipynb").read_text()


def test_every_attack_gets_exactly_what_it_deserves(graded):
    course, results, calls_here = graded
    assert all(r.ok for r in results), [(r.student, r.log[-500:]) for r in results if not r.ok]
    not_graded = course.not_graded()
    assert sorted(not_graded) == sorted(f"{student}/{ASSIGNMENT}" for student in REFUSED)
    for student, why in REFUSED.items():
        assert why in not_graded[f"{student}/{ASSIGNMENT}"]
    grades = cell_grades(course)
    assert len(grades) + len(REFUSED) == 40
    for student in ("ada", "bea", "extra_notebook", *HONEST_CLASSMATES):
        assert grades[student] == pytest.approx(FULL), student
    for student, expected in EXPECTED.items():
        assert grades[student] == pytest.approx(expected), student
    assert not calls_here  # the writer ran no student code (the duplicated grade id included)
    assert not _flags(course, "ada") and not _flags(course, "bea")


def test_names_and_texts_of_any_bytes_stop_nothing_and_print_safely(graded):
    course, _, _ = graded
    flags = _flags(course, "odd_files")
    assert any("\\xff\\xfe.ipynb: a symbolic link" in f for f in flags), flags
    assert any("bad\\xff: not a regular file" in f for f in flags), flags
    table = course.table(ASSIGNMENT)
    for text in [table] + [(course.root / "exports" / n).read_text(encoding="utf-8")
                           for n in ("grades.csv", "exercises.csv", "similarity.csv")]:
        assert "\x1b" not in text and not any(0xD800 <= ord(c) <= 0xDFFF for c in text)
    assert "\\x1b[2J\\x1b[3Jcleared" in table


def test_submission_time_is_the_graders_and_a_students_claim_is_only_checked(graded):
    course, _, _ = graded
    assert any("submission time" in f for f in _flags(course, "forged_time"))
    assert any("submission time" in f for f in _flags(course, "garbage_time"))
    assert not any("submission time" in f for f in _flags(course, "ada"))


def test_copied_code_in_added_cells_is_in_the_similarity_report(graded):
    course, _, _ = graded
    rows = list(csv.DictReader((course.root / "exports" / "similarity.csv").open(encoding="utf-8")))
    groups: dict[str, set[str]] = {}
    for row in rows:  # one row per student of a group of similar answers
        groups.setdefault(row["cluster"], set()).add(row["student"])
    together = {row["exercise"] for row in rows if {"copier_a", "copier_b"} <= groups[row["cluster"]]}
    assert any("added" in exercise for exercise in together), rows


def test_a_helper_that_is_the_answer_is_refused_by_name(graded):
    course, _, _ = graded
    problems = [p for e in course.scores(ASSIGNMENT)["helper_answer"] for p in e.problems]
    assert any("data.with_gaussian_noise" in p for p in problems), problems


def test_serving_time_counts_on_the_case_clock(graded):
    course, _, _ = graded
    problems = [p for e in course.scores(ASSIGNMENT)["served_time"] if e.name.startswith("median")
                for p in e.problems]
    assert any("did not return within" in p or "not run" in p for p in problems), problems


def _hidden_inputs(student):
    """The first values of every hidden median case of ``student``'s graded version."""
    nb = SUBMISSIONS[student]()
    version = submission_version(nb, source_notebook())
    spec = registry.get("filters.median").check
    cases = spec.hidden_cases(np.random.default_rng(hidden_seed("filters.median", student=student, salt=SALT,
                                                                  version=version)))
    return [repr(float(v)) for case in cases for v in np.asarray(case.args[0], dtype=float).ravel()[:8]
            if abs(float(v)) > 1e-3 and float(v) != round(float(v))]


def test_hidden_inputs_never_reach_the_student(graded):
    course, _, _ = graded
    pages, notebook = _pages(course, "leaker"), _autograded(course, "leaker")
    assert pages
    hidden = _hidden_inputs("leaker")
    assert len(hidden) > 20
    for value in hidden:
        assert value not in pages and value not in notebook, value
    # the visible cases ran first, with nothing hidden recorded yet: their message is shown whole
    assert "LEAK[" in notebook
    # a hidden case shows its error's type and the student's own line, never the message
    assert "raised ValueError (the message is not shown for hidden cases" in notebook
    assert 'raise ValueError(\\"LEAK\\" + repr(SEEN[-1] if SEEN else []))' in notebook


def test_messages_and_tracebacks_are_capped(graded):
    course, _, _ = graded
    notebook = _autograded(course, "big_message")
    honest = _autograded(course, "ada")
    assert "M" * 1000 in notebook and "N" * 1000 in notebook  # shown, but cut
    assert "M" * 5000 not in notebook and "N" * 5000 not in notebook
    assert len(notebook) < len(honest) + 300_000
    assert len(_pages(course, "big_message")) < len(_pages(course, "ada")) + 300_000


def test_a_flood_on_the_channel_is_refused_before_parsing(graded):
    course, _, _ = graded
    problems = [p for e in course.scores(ASSIGNMENT)["flooder"] if e.name.startswith("mean_kernel")
                for p in e.problems]
    assert "no result" in problems, problems
    assert "sent a message of 60000001 parts" in _autograded(course, "flooder")


def test_only_the_release_notebooks_are_graded(graded):
    course, _, _ = graded
    flags = _flags(course, "extra_notebook")
    assert any("scratch.ipynb is not a notebook of this assignment" in f for f in flags), flags
    assert any("garbage.ipynb is not a notebook of this assignment" in f for f in flags), flags
    assert not (course.root / "autograded" / "extra_notebook" / ASSIGNMENT / "scratch.ipynb").exists()


def test_a_duplicated_grade_id_is_repaired_in_a_worker(graded):
    course, _, _ = graded
    assert any("repaired copy" in f for f in _flags(course, "duplicated_id"))


def test_the_kernel_cannot_open_its_drivers_memory(graded):
    course, _, _ = graded
    assert "DRIVER-MEM PermissionError" in _autograded(course, "driver_memory")


# ------------------------------------------------------------------ the trusted path, directly
def _graded_notebook(nb, student="sam", **options):
    return grade_notebook(nb, student=student, salt=SALT, source_notebook=source_notebook(), **options)


def test_hidden_cases_are_fresh_for_every_version_and_the_same_on_a_regrade(bubblewrap):
    def seeds(result):
        return {grade_id: [r.seed for _, r in entries] for grade_id, entries in result.reports.items()
                if grade_id.endswith("_hidden")}

    first = seeds(_graded_notebook(submission()))
    again = seeds(_graded_notebook(submission()))
    changed = seeds(_graded_notebook(submission(added=["# a comment: a new version"])))
    assert first == again
    assert all(first[k] != changed[k] for k in first)


def test_a_table_learned_from_an_earlier_attempt_is_worth_nothing(bubblewrap):
    """The answers of every hidden median case of attempt 1, memorised in attempt 2: attempt 2
    meets new cases, and the table answers none of them."""
    spec = registry.get("filters.median").check
    first = submission()
    cases = spec.hidden_cases(np.random.default_rng(
        hidden_seed("filters.median", student="sam", salt=SALT, version=submission_version(first, source_notebook()))))
    table = {}
    for case in cases:
        image = np.asarray(case.args[0], dtype=float)
        table[image.tobytes().hex()[:64]] = registry.get("filters.median").reference(*case.args, **case.kwargs).tolist()
    lookup = textwrap.dedent(f'''\
        TABLE = {table!r}

        @student("filters.median")
        def median(image, size, border="reflect101"):
            key = np.asarray(image, dtype=float).tobytes().hex()[:64]
            if key in TABLE:
                return np.array(TABLE[key])
            return np.full(np.shape(image), np.nan)  # no answer but the table's''')
    # the table answers every case it was learned from ...
    namespace = {"np": np, "student": lambda algorithm_id: (lambda function: function)}
    exec(lookup, namespace)
    learned = evaluate("filters.median", namespace["median"], hidden=True, seed=hidden_seed(
        "filters.median", student="sam", salt=SALT, version=submission_version(first, source_notebook())))
    assert learned.score == 1
    # ... and none of the next attempt's
    result = _graded_notebook(submission(median=lookup))
    report = next(r for call, r in result.reports["median_hidden"])
    assert report.score == 0


def test_the_notebook_has_a_total_time_limit(bubblewrap):
    """Many added cells, each under the per-cell limit, run one after another: the notebook's
    total limit (here 12 s, for the test) ends the deciding run and the instructor is told."""
    cells = [f"import time\ntime.sleep(5)  # cell {i}" for i in range(4)]
    result = _graded_notebook(submission(added=cells), total_seconds=12)
    assert any("grading stopped after 12 s in all" in f for f in result.flags), result.flags
    hidden = next(r for _, r in result.reports["median_hidden"])
    assert hidden.score == 0 and "grading time ran out" in hidden.cases[0].message


def test_a_deadline_ends_every_call_that_has_not_run(bubblewrap):
    cells = ["import time\ndef slow(x):\n    time.sleep(3)\n    return x"]
    calls = [BoxCall("slow", args=(np.ones(2),), time_limit=10.0) for _ in range(5)]
    result = sandbox.run_calls(cells, calls, deadline=time.monotonic() + 8)
    assert result.exhausted
    assert result.outcomes[0].ok
    assert all("grading time ran out" in (o.error or "") for o in result.outcomes[-2:])


def test_requests_per_case_are_counted(bubblewrap):
    cells = ["from cvkit import data\ndef greedy(x):\n    for _ in range(1200):\n"
             "        try:\n            data.step_signal(3)\n        except RuntimeError:\n            pass\n    return x"]
    result = sandbox.run_calls(cells, [BoxCall("greedy", args=(np.ones(2),), time_limit=60.0)])
    outcome = result.outcomes[0]
    assert not outcome.ok and any("more than 1000 requests" in c for c in outcome.forbidden_calls), outcome


def test_a_message_is_refused_by_size_and_parts_before_it_is_parsed(monkeypatch):
    def no_parsing(*args, **kwargs):
        raise AssertionError("parsed")

    monkeypatch.setattr(sandbox.json, "loads", no_parsing)
    kind, why = sandbox.parse_message(b"[" + b"1," * 300_000 + b"1]\n")
    assert kind == "bad" and "parts" in why
    kind, why = sandbox.parse_message(b"x" * (sandbox.MAX_LINE + 1) + b"\n")
    assert kind == "bad" and "larger" in why
    monkeypatch.undo()
    assert sandbox.parse_message(b'{"outcome": {"error": null}}\n') == ("message", {"outcome": {"error": None}})


def test_outcomes_from_the_sandbox_are_capped():
    outcome = Outcome.from_json({"error": "E" * 65536, "traceback": "T" * 65536, "exception": "X" * 5000})
    assert len(outcome.error) < 600 and len(outcome.traceback) < 4100 and len(outcome.exception) < 200
    assert outcome.traceback.endswith("T" * 100)  # the end of a traceback is where it was raised


def test_error_outputs_of_the_executed_notebook_are_capped():
    nb = {"cells": [{"cell_type": "code", "source": "", "metadata": {}, "execution_count": 1, "outputs": [
        {"output_type": "error", "ename": "ValueError", "evalue": "v" * 65536,
         "traceback": ["line " + "t" * 65536] * 500}]}]}
    error = bounded(nb)["cells"][0]["outputs"][0]
    assert len(error["evalue"]) < 2100 and len(error["traceback"]) <= 41
    assert all(len(line) < 2100 for line in error["traceback"])


def test_the_execution_driver_is_closed_to_the_kernel(bubblewrap):
    nb = {"cells": [new_cell(DRIVER_MEMORY)], "metadata": source_notebook()["metadata"], "nbformat": 4,
          "nbformat_minor": 5}
    text, log = execute_in_sandbox({"n.ipynb": json.dumps(nb).encode()}, "n.ipynb")
    assert text is not None, log
    printed = "".join("".join(o.get("text", "")) for o in json.loads(text)["cells"][0]["outputs"])
    assert "DRIVER-MEM PermissionError" in printed, printed


def test_hidden_view_keeps_only_the_students_own_frames():
    from cvkit.grading.report import CaseResult
    from cvkit.course.trusted import hidden_view

    cells = ["x = 1", "def f(a):\n    secret = a\n    raise ValueError(str(secret))"]
    traceback_text = ('  File "<cell 1>", line 3, in f\nValueError: [0.123456, 0.654321]')
    outcome = Outcome(error="raised ValueError: [0.123456, 0.654321]", traceback=traceback_text,
                      exception="ValueError", stdout="[0.123456]", warnings=["UserWarning: 0.654321"])
    case = CaseResult(0, "case", "input", False, message=outcome.error, traceback=outcome.traceback,
                      stdout=outcome.stdout, warnings=list(outcome.warnings))
    hidden_view(case, outcome, cells, 20.0, {"a"})
    shown = json.dumps([case.message, case.traceback, case.stdout, case.stderr, case.warnings])
    assert "0.123456" not in shown and "0.654321" not in shown
    assert "cell 1, line 3, in f" in case.traceback and "raise ValueError(str(secret))" in case.traceback
    assert case.message.startswith("raised ValueError") and case.warnings == ["UserWarning"]
    # a made-up exception name carries nothing either
    odd = Outcome(error="raised 0.5: x", exception="0.5", traceback='  File "<cell 1>", line 3, in f\n0.5')
    case = CaseResult(0, "case", "input", False, message=odd.error, traceback=odd.traceback)
    hidden_view(case, odd, cells, 20.0, {"a"})
    assert "0.5" not in case.message and "0.5" not in case.traceback.replace("line 3", "")
    assert re.search(r"raised an exception", case.message)


def test_a_cell_may_load_data_but_not_compute_a_building_block(bubblewrap):
    """A demo cell the student added (``img = data.step_signal(5)``) is served the data
    sources, like a case; a building block at the top level of a cell is refused by name."""
    from cvkit import data

    cells = ["from cvkit import data, filters\nSIGNAL = data.step_signal(5)\ndef f(x):\n    return SIGNAL",
             "from cvkit import filters\nPADDED = filters.pad(np.ones((2, 2)), 1)"]
    result = sandbox.run_calls(["import numpy as np"] + cells,
                               [BoxCall("f", args=(np.ones(2),), time_limit=20.0)],
                               blocks=("filters.pad",))
    assert result.outcomes[0].ok and np.array_equal(result.outcomes[0].value, data.step_signal(5))
    assert any("cell 2: RuntimeError" in e and "filters.pad is not allowed" in e for e in result.cell_errors), \
        result.cell_errors
    assert not result.crashed
