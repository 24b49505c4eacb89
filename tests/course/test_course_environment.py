"""When the grading environment, not the student, stops a notebook's cells (issue #34, item 2):
a tiny course graded through the real pipeline (``cvkit course grade``, the sandbox) whose
chapter, as released, imports a package that is not installed and loads a file of the kit that
is missing. The grade table and the summary say so for the instructor once per cause, naming
the submissions — never once per student, and never for what a student's own code did (a
cell they added, their answer, a file of their own folder)."""
import contextlib
import io
from pathlib import Path

import pytest

from cvkit.cli import main
from cvkit.course import Course
from cvkit.course.jobs import environment_problems

from course_helpers import SETUP, TEMPORAL_MEAN, exercise_cells, new_cell, new_notebook, submitted, write_project
from course_helpers import TEMPORAL_MEAN_LOOP as LOOP  # a right answer
ASSIGNMENT = "ch97_environment"
MISSING = "cvkit_course_needs_this_package"  # no such package anywhere
PLAN = f'[[assignment]]\nid = "{ASSIGNMENT}"\ndue = "2030-01-01 00:00:00 UTC"\n'
DEMO_IMPORT = f"import {MISSING}\n{MISSING}.show()"
DEMO_KIT_FILE = ("from pathlib import Path\nimport cvkit\n"
                 "frames = np.load(Path(cvkit.__file__).parent / 'data' / 'frames_of_the_demo.npz')")
DEMO_OWN_FILE = "results = open('my_results.txt').read()  # the student's folder: their doing"
MODULE_CAUSE = f"ModuleNotFoundError: No module named '{MISSING}'"
STUDENT_MODULE = "cvkit_a_students_own_typo"


def source_notebook():
    return new_notebook([
        new_cell("# A chapter that needs more than the course installed", cell_type="markdown"),
        new_cell(SETUP, "setup"), new_cell(DEMO_IMPORT), new_cell(DEMO_KIT_FILE), new_cell(DEMO_OWN_FILE),
        *exercise_cells("filters.temporal_mean", "temporal_mean", TEMPORAL_MEAN),
    ], ids=True)


def submission(answer, added=None):
    nb = submitted(source_notebook(), {"temporal_mean_answer": answer})
    if added is not None:  # a cell of the student's own, after the set-up cell
        nb["cells"].insert(2, dict(new_cell(added), id="students-own"))
    return {f"{ASSIGNMENT}.ipynb": nb}


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """ada (right answer), bob (right answer, plus a cell of his own importing a typo) and cyd
    (an answer importing a typo), graded once by ``cvkit course grade``."""
    project = write_project(tmp_path_factory.mktemp("project"), PLAN,
                            {f"{ASSIGNMENT}/{ASSIGNMENT}.ipynb": source_notebook()})
    folder = tmp_path_factory.mktemp("shared") / "course"
    course = Course(folder, project=project)
    course.build([ASSIGNMENT])
    own_import = LOOP.replace("def temporal_mean", f"import {STUDENT_MODULE}\n\n\ndef temporal_mean", 1)
    for student, answer, added in (("ada", LOOP, None), ("bob", LOOP, f"import {STUDENT_MODULE}"),
                                   ("cyd", own_import, None)):
        course.submit(student, ASSIGNMENT, submission(answer, added))
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = main(["course", "grade", "--course-dir", str(folder), "--workers", "2"])
    return course, status, out.getvalue()


def _kit_file_cause(text):
    lines = [line for line in text.splitlines() if "FileNotFoundError" in line]
    return [line for line in lines if "frames_of_the_demo.npz" in line]


def test_the_table_says_once_per_cause_what_the_environment_lacked(graded):
    course, status, out = graded
    assert status == 0, out
    table = course.table(ASSIGNMENT)
    assert table.count("!! Not the students' doing") == 1
    assert f"  {MODULE_CAUSE}: in 3 submissions (ada, bob, cyd)" in table.splitlines()
    kit_file = _kit_file_cause(table)
    assert len(kit_file) == 1 and kit_file[0].endswith(": in 3 submissions (ada, bob, cyd)")
    assert kit_file[0].lstrip().startswith("FileNotFoundError: [Errno 2] No such file or directory: '")
    # what the students' own code did is theirs: not reported as the environment's
    assert STUDENT_MODULE not in table.split("!! Not the students' doing")[1]
    assert "my_results.txt" not in table
    assert table.count(MODULE_CAUSE) == 1


def test_the_summary_says_it_once_per_cause_with_the_regrade(graded):
    _, _, out = graded
    lines = [line for line in out.splitlines() if line.startswith("environment: ")]
    assert len(lines) == 2, out[-3000:]
    module = next(line for line in lines if MODULE_CAUSE in line)
    assert (f"the cells as released of {ASSIGNMENT} failed in 3 submissions, not the students' doing" in module
            and module.endswith(f"cvkit course grade --regrade {ASSIGNMENT}"))
    assert len(_kit_file_cause("\n".join(lines))) == 1
    assert STUDENT_MODULE not in "\n".join(lines) and "my_results.txt" not in "\n".join(lines)
    assert out.count(MODULE_CAUSE) == 2  # once in the table, once in the summary


def test_grades_are_the_checks_own(graded):
    """The environment's failures cost no points the checks give: the right answers score full
    marks, the answer whose import fails does not."""
    course, _, _ = graded
    totals = {s: (sum(e.score for e in v), sum(e.max_score for e in v)) for s, v in course.scores(ASSIGNMENT).items()}
    assert totals["ada"] == (3.0, 3.0) and totals["bob"] == (3.0, 3.0)
    assert totals["cyd"][0] == 0.0


def _error_cell(source, count, ename, evalue, traceback_cell=None, **meta):
    frames = [f"Cell In[{traceback_cell or count}], line 1"]
    return {"cell_type": "code", "source": source, "execution_count": count, "metadata": meta,
            "outputs": [{"output_type": "error", "ename": ename, "evalue": evalue,
                         "traceback": ["\x1b[0;31m---\x1b[0m", *frames, f"{ename}: {evalue}"]}]}


def test_environment_problems_reads_only_the_cells_as_released():
    import cvkit

    kit_file = str(Path(cvkit.__file__).resolve().parent / "data" / "gone.npz")
    release = {"cells": [{"cell_type": "code", "source": s, "metadata": {}, "outputs": []}
                         for s in ("import a", "demo(answer)", "np.load(KIT)", "open('mine.txt')")]}
    executed = {"cells": [
        _error_cell("import a", 1, "ModuleNotFoundError", "No module named 'a'"),
        _error_cell("import a", 5, "ModuleNotFoundError", "No module named 'a'"),  # the same cause again
        _error_cell("import b", 2, "ModuleNotFoundError", "No module named 'b'"),  # not as released
        _error_cell("demo(answer)", 3, "ImportError", "cannot import name 'c'", traceback_cell=2),  # the answer's
        _error_cell("np.load(KIT)", 4, "FileNotFoundError", f"[Errno 2] No such file or directory: '{kit_file}'"),
        _error_cell("open('mine.txt')", 6, "FileNotFoundError", "[Errno 2] No such file or directory: 'mine.txt'"),
        _error_cell("import a", 7, "NameError", "name 'x' is not defined"),
        _error_cell("import a", 8, "ModuleNotFoundError", "No module named 'd'",
                    nbgrader={"solution": True, "grade": False, "grade_id": "x_answer", "locked": False}),
    ]}
    assert environment_problems(executed, release) == [
        "ModuleNotFoundError: No module named 'a'",
        f"FileNotFoundError: [Errno 2] No such file or directory: '{kit_file}'"]
    # without a release, only locked cells count
    locked = dict(_error_cell("import e", 1, "ModuleNotFoundError", "No module named 'e'"),
                  metadata={"nbgrader": {"locked": True, "grade_id": "setup", "solution": False, "grade": False}})
    assert environment_problems({"cells": [locked, executed["cells"][2]]}, None) == [
        "ModuleNotFoundError: No module named 'e'"]
