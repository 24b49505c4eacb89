"""The attack suite of issue 17: a determined student against ``cvkit course grade``.

Every attack is a real submission in one batch with honest students, graded through
:meth:`Course.grade` (what ``cvkit course grade`` runs) with two workers on a tiny throwaway
chapter (two exercises, so that a run takes a minute). Each attack asserts its exact grade,
and the suite asserts that the honest students' grades, the files outside the sandbox and
the host's ``/tmp`` are unchanged, that no process outlives the run, and that submissions that
cannot be graded are listed as *not graded* with the reason — never as zeros.
"""
import csv
import json
import re
import os
import subprocess
import textwrap

import numpy as np
import pytest

from cvkit.course import Course
from cvkit.sandbox import isolation, session as sandbox
from cvkit.grading.runtime.wire import BoxCall

from course_helpers import ROOT, cell_grades, new_cell
from test_course_scaling import ASSIGNMENT, _answers, make_course
from test_course_scaling import project  # noqa: F401  (the tiny chapter's project, a fixture)

pytestmark = pytest.mark.slow

FULL = {"mean_kernel_visible": 1, "mean_kernel_hidden": 2, "temporal_mean_visible": 1, "temporal_mean_hidden": 2}
KERNEL_ZERO = dict(FULL, mean_kernel_visible=0, mean_kernel_hidden=0)
MARKER = "cvkit-attack-marker"
# the real import machinery, reached from NumPy's module globals (the answer cells' own
# ``import`` goes through the allow-list): the door a determined student uses
REAL_IMPORT = "__imp = np.__builtins__['__import__']\n"


def kernel(body: str) -> str:
    """A mean_kernel answer whose body is ``body`` (which must return something)."""
    return '@student("filters.mean_kernel")\ndef mean_kernel(size):\n' + textwrap.indent(body, "    ")


ATTACKS = {
    # --- reaching the reference or expected outputs
    "via_globals": (kernel('import cvkit\ng = getattr(cvkit.filters.mean_kernel, "__globals__")\n'
                           'return g["mean_kernel"](size)'), KERNEL_ZERO),
    "via_sys_modules": (kernel(REAL_IMPORT + 'sys = __imp("sys")\nsys.meta_path.clear()\n'
                               'return sys.modules["cvkit.filters"].mean_kernel(size)'), KERNEL_ZERO),
    "via_scipy": (kernel(REAL_IMPORT + 'nd = __imp("scipy.ndimage")\nreturn nd.uniform_filter(np.eye(size), size)'),
                  KERNEL_ZERO),
    "via_frames": (kernel(REAL_IMPORT + textwrap.dedent('''\
        sys = __imp("sys")
        frame = sys._getframe()
        while frame is not None:
            for value in frame.f_locals.values():
                if isinstance(value, dict) and "expected" in value:
                    return value["expected"]
            frame = frame.f_back
        return np.zeros((size, size))''')), KERNEL_ZERO),
    "via_gc": (kernel(REAL_IMPORT + textwrap.dedent('''\
        gc = __imp("gc")
        for obj in gc.get_objects():
            if type(obj).__name__ == "Check":
                return obj.reference(size)
        return np.zeros((size, size))''')), KERNEL_ZERO),
    "via_thread": (kernel(REAL_IMPORT + textwrap.dedent('''\
        threading = __imp("threading")
        box = []
        t = threading.Thread(target=lambda: box.append(__imp("cvkit").filters.mean_kernel(size)))
        t.start(); t.join()
        return box[0] if box else np.zeros((size, size))''')), KERNEL_ZERO),
    "via_lectures": (kernel(textwrap.dedent(f'''\
        for path in ({str(ROOT / "lectures" / "ch03_filtering" / "ch03_filtering.ipynb")!r},
                     "/work/main/lectures/ch03_filtering/ch03_filtering.ipynb"):
            try:
                open(path).read()
                return np.full((size, size), 1.0 / (size * size))
            except OSError:
                pass
        return np.zeros((size, size))''')), KERNEL_ZERO),
    "via_pillow": ('from PIL import ImageFilter\n' + kernel("return np.full((size, size), 1.0 / (size * size))"),
                   KERNEL_ZERO),
    # --- resources
    "huge_lazy_array": (kernel("return np.broadcast_to(np.float64(1.0 / (size * size)), (100000, 100000))"),
                        KERNEL_ZERO),
    "flood": ('print("x" * (300 << 20))\n' + kernel("return np.full((size, size), 1.0 / (size * size))"), FULL),
    "memory_bomb": (kernel("a = np.ones(100 * 2**30 // 8)\nreturn np.full((size, size), 1.0 / (size * size))"),
                    KERNEL_ZERO),
    # a cell that never ends: stopped from outside, what it defines is missing
    "sleeper": ("import time\ntime.sleep(10**6)\n" + kernel("return np.full((size, size), 1.0 / (size * size))"),
                KERNEL_ZERO),
    # SIGALRM ignored inside the function: the case's limit (20 s) is kept outside
    "alarm_ignorer": (kernel(REAL_IMPORT + 'signal = __imp("signal"); time = __imp("time")\n'
                             "signal.signal(signal.SIGALRM, signal.SIG_IGN)\ntime.sleep(21)\n"
                             "return np.full((size, size), 1.0 / (size * size))"), KERNEL_ZERO),
}

# cells added after the setup cell (they run in the notebook and, as student code, in the
# trusted worker too); the answers themselves are honest
ADDED_CELLS = {
    "daemon": REAL_IMPORT + textwrap.dedent(f'''\
        os = __imp("os"); time = __imp("time")
        if os.fork() == 0:
            os.setsid()
            if os.fork() == 0:
                try:
                    os.execv("/bin/sleep", ["/bin/sleep", "600", "{MARKER}"])
                finally:
                    os._exit(0)
            os._exit(0)
        time.sleep(0.2)'''),
    "parent_killer": REAL_IMPORT + 'os = __imp("os")\nos.kill(os.getppid(), 9)',
    "tmp_writer": REAL_IMPORT + textwrap.dedent(f'''\
        for folder in ("/tmp", "/dev/shm", "/var/tmp"):
            try:
                open(folder + "/{MARKER}", "w").write("left behind")
            except OSError:
                pass'''),
    "fork_counter": REAL_IMPORT + textwrap.dedent('''\
        os = __imp("os")
        children = 0
        for _ in range(200):
            try:
                pid = os.fork()
            except OSError:
                break
            if pid == 0:
                __imp("time").sleep(5)
                os._exit(0)
            children += 1
        print("forks allowed:", children)'''),
    "html_injection": REAL_IMPORT + textwrap.dedent('''\
        from IPython.display import HTML, display
        display(HTML('<script>alert("pwned-script")</script><img src=x onerror="alert(1)">'))'''),
}


@pytest.fixture(scope="module")
def graded(bubblewrap, project, tmp_path_factory):
    course = Course(tmp_path_factory.mktemp("attack-course") / "course", project=project)
    (course.root / ".grading_salt").write_text("attack-salt")
    course.build([ASSIGNMENT])
    name = f"{ASSIGNMENT}.ipynb"
    submissions = {"ada": _answers(), "bea": _answers(), "=HYPERLINK(1)": _answers()}
    for student, (answer, _) in ATTACKS.items():
        submissions[student] = _answers(kernel=answer)
    for student, source in ADDED_CELLS.items():
        nb = _answers()
        nb["cells"].insert(2, new_cell(source))
        submissions[student] = nb
    for student, nb in submissions.items():
        course.submit(student, ASSIGNMENT, {name: nb})
    # submissions that are not notebooks at all, or not regular files
    (course.root / "submitted" / "empty" / ASSIGNMENT).mkdir(parents=True)
    (course.root / "submitted" / "empty" / ASSIGNMENT / name).write_bytes(b"")
    (course.root / "submitted" / "garbled" / ASSIGNMENT).mkdir(parents=True)
    (course.root / "submitted" / "garbled" / ASSIGNMENT / name).write_text('{"cells": [')
    (course.root / "submitted" / "linker" / ASSIGNMENT).mkdir(parents=True)
    os.symlink(course.root / "submitted" / "ada" / ASSIGNMENT / name, course.root / "submitted" / "linker" / ASSIGNMENT / name)
    course.submit("peeker", ASSIGNMENT, {name: _answers()})
    os.symlink(course.root / ".grading_salt", course.root / "submitted" / "peeker" / ASSIGNMENT / "salt.txt")
    os.symlink("/etc/shadow", course.root / "submitted" / "peeker" / ASSIGNMENT / "shadow.txt")
    for leftover in ("/tmp", "/dev/shm", "/var/tmp"):
        if os.path.exists(f"{leftover}/{MARKER}"):
            os.remove(f"{leftover}/{MARKER}")
    victim = course.root / "submitted" / "ada" / ASSIGNMENT / name
    before = {"victim": victim.read_bytes(), "salt": (course.root / ".grading_salt").read_text()}
    with pytest.MonkeyPatch.context() as patch:  # short limits for this run only
        patch.setenv("CVKIT_CELL_TIMEOUT", "30")
        patch.setenv("CVKIT_ANSWER_CELL_TIMEOUT", "20")
        # more workers than cores: the attacks that wait out their 20-s limit (sleeper,
        # alarm_ignorer) sit idle while the other submissions are graded beside them
        results = course.grade(workers=4)
    return course, results, before


def test_every_attack_gets_exactly_what_it_deserves(graded):
    course, results, _ = graded
    grades = cell_grades_graded(course)
    for student in ("ada", "bea", "=HYPERLINK(1)", *ADDED_CELLS):
        assert grades[student] == pytest.approx(FULL), student
    for student, (_, expected) in ATTACKS.items():
        assert grades[student] == pytest.approx(expected), student


def cell_grades_graded(course):
    from nbgrader.api import Gradebook

    not_graded = course.not_graded()
    out = {}
    with Gradebook(course.db_url) as gb:
        for student, assignment in course.submissions():
            if f"{student}/{assignment}" in not_graded:
                continue
            submission = gb.find_submission(assignment, student)
            out[student] = {g.name: g.score for nb in submission.notebooks for g in nb.grades}
    return out


FLAGGED = {  # what the instructor is told about each attack
    "via_globals": "__globals__", "via_sys_modules": "sys.modules", "via_scipy": "__builtins__",
    "via_frames": "__builtins__", "via_gc": "__builtins__", "via_thread": "__builtins__", "via_lectures": "opens files",
    "via_pillow": "import PIL", "sleeper": "was stopped", "alarm_ignorer": "__builtins__", "daemon": "__builtins__",
    "parent_killer": "__builtins__", "tmp_writer": "opens files", "fork_counter": "__builtins__",
}


def test_attacks_are_flagged_and_honest_work_is_not(graded):
    course, _, _ = graded
    scores = course.scores(ASSIGNMENT)
    flags = {student: [f for e in exercises for f in e.flags] for student, exercises in scores.items()}
    for student, expected in FLAGGED.items():
        assert any(expected in f for f in flags[student]), (student, flags[student])
    assert not flags["ada"] and not flags["bea"]


def test_not_a_notebook_is_listed_as_not_graded_never_as_zero(graded):
    course, results, _ = graded
    not_graded = course.not_graded()
    assert "not a valid notebook" in not_graded[f"empty/{ASSIGNMENT}"]
    assert "not a valid notebook" in not_graded[f"garbled/{ASSIGNMENT}"]
    assert "symbolic link" in not_graded[f"linker/{ASSIGNMENT}"]
    table = course.table(ASSIGNMENT)
    assert "empty: not graded:" in table and "linker: not graded:" in table
    rows = list(csv.DictReader((course.root / "exports" / "grades.csv").open()))
    status = {r["student_id"]: r for r in rows}
    assert status["garbled"]["status"].startswith("not graded") and status["garbled"]["score"] == ""
    assert status["ada"]["status"] == "graded"
    exercises = (course.root / "exports" / "exercises.csv").read_text()
    assert "garbled" in exercises and "not graded" in exercises
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gb:  # the formgrader's flag column
        assert all(nb.flagged for nb in gb.find_submission(ASSIGNMENT, "garbled").notebooks)
    assert all(r.ok for r in results), [(r.student, r.log[-500:]) for r in results if not r.ok]


def test_links_are_refused_and_nothing_outside_leaks(graded):
    course, _, before = graded
    flags = [f for e in course.scores(ASSIGNMENT)["peeker"] for f in e.flags]
    assert any("salt.txt" in f and "symbolic link" in f for f in flags)
    assert any("shadow.txt" in f for f in flags)
    feedback = "".join(p.read_text() for p in (course.root / "feedback" / "peeker").rglob("*.html"))
    assert before["salt"] not in feedback and "root:" not in feedback
    assert (course.root / "submitted" / "ada" / ASSIGNMENT / f"{ASSIGNMENT}.ipynb").read_bytes() == before["victim"]


def test_no_process_or_file_outlives_the_run(graded):
    survivors = subprocess.run(["pgrep", "-f", MARKER], capture_output=True, text=True).stdout.split()
    assert not survivors
    for folder in ("/tmp", "/dev/shm", "/var/tmp"):
        assert not os.path.exists(f"{folder}/{MARKER}")


def test_processes_are_limited(graded):
    course, _, _ = graded
    nb = json.loads((course.root / "autograded" / "fork_counter" / ASSIGNMENT / f"{ASSIGNMENT}.ipynb").read_text())
    printed = "".join("".join(o.get("text", "")) for c in nb["cells"] for o in c.get("outputs", []))
    count = int(printed.split("forks allowed:")[1].split()[0])
    assert count < 64


def test_refused_imports_are_named(graded):
    course, _, _ = graded
    flags = [f for e in course.scores(ASSIGNMENT)["via_pillow"] for f in e.flags]
    assert any("PIL" in f and "not allowed" in f for f in flags)


def test_student_html_is_sanitised_in_feedback(graded):
    course, _, _ = graded
    pages = "".join(p.read_text() for p in (course.root / "feedback" / "html_injection").rglob("*.html"))
    assert pages and '<script>alert("pwned-script")' not in pages  # shown escaped in the code listing only
    assert not re.search(r"<img[^>]*onerror", pages)


def test_csv_cells_cannot_be_formulas(graded):
    course, _, _ = graded
    for name in ("grades.csv", "exercises.csv"):
        for row in csv.reader((course.root / "exports" / name).open()):
            assert not any(cell.startswith(("=", "+", "@")) for cell in row), (name, row)
    assert "'=HYPERLINK(1)" in (course.root / "exports" / "grades.csv").read_text()


def test_ignoring_sigalrm_does_not_beat_the_limit(bubblewrap):
    cells = [textwrap.dedent('''\
        import numpy as np
        __imp = np.__builtins__["__import__"]
        def slow(x):
            signal = __imp("signal"); time = __imp("time")
            signal.signal(signal.SIGALRM, signal.SIG_IGN)
            time.sleep(2.5)
            return x''')]
    result = sandbox.run_calls(cells, [BoxCall("slow", args=(np.ones(2),), time_limit=1.0)])
    assert result.outcomes[0].timed_out and result.outcomes[0].value is None


def test_timeouts_are_named(graded):
    course, _, _ = graded
    problems = [p for e in course.scores(ASSIGNMENT)["alarm_ignorer"] for p in e.problems]
    assert any(p.startswith("did not return within") for p in problems), problems


def test_plain_nbgrader_autograde_runs_the_notebook_in_the_sandbox(graded):
    """An instructor who runs `nbgrader autograde` by hand gets cvkit's SandboxedExecute, never
    nbgrader's Execute with the grader's rights."""
    course, _, _ = graded
    spy = _answers()
    spy["cells"].insert(2, new_cell(f"import os\nprint('uid', os.getuid(), 'sees-course', os.path.exists({str(course.root)!r}))"))
    course.submit("spy", ASSIGNMENT, {f"{ASSIGNMENT}.ipynb": spy})
    done = course.nbgrader("autograde", ASSIGNMENT, "--student", "spy", "--force")
    assert done.returncode == 0, done.stderr[-2000:]
    nb = json.loads((course.root / "autograded" / "spy" / ASSIGNMENT / f"{ASSIGNMENT}.ipynb").read_text())
    printed = "".join("".join(o.get("text", "")) for c in nb["cells"] for o in c.get("outputs", []))
    assert "uid 65534 sees-course False" in printed


def test_no_sandbox_stops_grading_with_a_clear_message(monkeypatch, tmp_path):
    monkeypatch.setattr(isolation, "bwrap_path", lambda: None)
    monkeypatch.setattr(isolation, "_probe", {})
    course = Course(tmp_path / "course", project=ROOT)
    with pytest.raises(isolation.SandboxUnavailable, match="apt-get install bubblewrap"):
        course.grade(workers=1)


def test_no_sandbox_mode_is_marked_everywhere(bubblewrap, project, tmp_path):
    course = make_course(project, tmp_path / "course", students={"ada": _answers()})
    try:
        results = course.grade(workers=1, sandbox=False)
    finally:
        os.environ.pop("CVKIT_NO_SANDBOX", None)
    assert all(r.ok for r in results)
    assert cell_grades(course)["ada"] == pytest.approx(FULL)  # same grades, but marked
    assert "GRADED WITHOUT THE SANDBOX" in course.table(ASSIGNMENT)
    assert "WITHOUT SANDBOX" in (course.root / "exports" / "grades.csv").read_text()
    assert "WITHOUT THE SANDBOX" in (course.root / "exports" / "exercises.csv").read_text()
    pages = "".join(p.read_text() for p in (course.root / "feedback" / "ada").rglob("*.html"))
    assert "Graded without the sandbox" in pages
