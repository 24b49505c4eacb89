"""Grading at scale and under attack, through the real pipeline, on a tiny throwaway course
(one short chapter) so that every run takes seconds:

- several workers give exactly the grades of one worker; an interrupted run resumes without
  regrading finished work; a changed submission is regraded;
- a real Dask LocalCluster on loopback runs the same work;
- a real PostgreSQL server, started by the test on loopback, holds the gradebook;
- attacks from inside the student's kernel: deleting the gradebook and another student's
  submission, tampering with graded cells, calling the reference.
"""
import json
import shutil
import socket
import subprocess
import time
from pathlib import Path

import pytest

from cvkit.course import Course

from course_helpers import TEMPORAL_MEAN, cell_grades, exercise_cells, new_cell, new_notebook, submitted, write_project

pytestmark = pytest.mark.slow
ASSIGNMENT = "ch99_tiny"


KERNEL = ('@student("filters.mean_kernel")\ndef mean_kernel(size):\n'
          '    ### BEGIN SOLUTION\n    return np.full((size, size), 1.0 / (size * size))\n    ### END SOLUTION')
TEMPORAL = TEMPORAL_MEAN  # (the released solution)


def source_notebook():
    return new_notebook([
        new_cell("# A tiny chapter", cell_type="markdown"),
        new_cell("import numpy as np\nimport cvkit\nfrom cvkit import filters\nfrom cvkit.grading import check\n"
                 "from cvkit.registry import student", "setup"),
        *exercise_cells("filters.mean_kernel", "mean_kernel", KERNEL),
        *exercise_cells("filters.temporal_mean", "temporal_mean", TEMPORAL),
    ])


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """A project with the real course configuration and one tiny chapter."""
    return write_project(tmp_path_factory.mktemp("project"), f'[[assignment]]\nid = "{ASSIGNMENT}"\n',
                         {f"{ASSIGNMENT}/{ASSIGNMENT}.ipynb": source_notebook()})


def _answers(kernel=None, temporal=None):
    """A submission: the release notebook with the answer cells replaced (where ``None``: by the
    solution without its markers)."""
    def solved(solution):
        return "\n".join(line for line in solution.splitlines() if "### " not in line)

    return submitted(source_notebook(), {"mean_kernel_answer": solved(KERNEL) if kernel is None else kernel,
                                         "temporal_mean_answer": solved(TEMPORAL) if temporal is None else temporal})


WRONG_KERNEL = '@student("filters.mean_kernel")\ndef mean_kernel(size):\n    return np.ones((size, size))'
BLANK_TEMPORAL = '@student("filters.temporal_mean")\ndef temporal_mean(frames):\n    raise NotImplementedError()'
STUDENTS = {
    "ada": _answers(),
    "bob": _answers(kernel=WRONG_KERNEL),
    "cyd": _answers(kernel=WRONG_KERNEL, temporal=BLANK_TEMPORAL),
}


def make_course(project, folder, db_url=None, salt="scaling-salt", students=STUDENTS):
    course = Course(folder, db_url=db_url, project=project)
    (course.root / ".grading_salt").write_text(salt)
    course.build([ASSIGNMENT])
    for student, nb in students.items():
        course.submit(student, ASSIGNMENT, {f"{ASSIGNMENT}.ipynb": nb})
    return course


EXPECTED = {
    "ada": {"mean_kernel_visible": 1, "mean_kernel_hidden": 2, "temporal_mean_visible": 1, "temporal_mean_hidden": 2},
    "bob": {"mean_kernel_visible": 0, "temporal_mean_visible": 1, "temporal_mean_hidden": 2},
    "cyd": {"mean_kernel_visible": 0, "temporal_mean_visible": 0, "temporal_mean_hidden": 0},
}


def assert_expected(grades):
    for student, expected in EXPECTED.items():
        for name, value in expected.items():
            assert grades[student][name] == pytest.approx(value), (student, name)
    assert grades["bob"]["mean_kernel_hidden"] < 2  # an all-ones kernel is right only for size 1


@pytest.fixture(scope="module")
def sequential(project, tmp_path_factory):
    course = make_course(project, tmp_path_factory.mktemp("seq") / "course")
    results = course.grade(workers=1)
    assert all(r.ok for r in results), [r.log for r in results if not r.ok]
    return course


def test_grades_are_right(sequential):
    assert_expected(cell_grades(sequential))
    assert sequential.audit(sequential.submissions()) == []


def test_parallel_equals_sequential_and_resumes(project, sequential, tmp_path):
    course = make_course(project, tmp_path / "course")
    results = course.grade(workers=2)
    assert all(r.ok for r in results) and len(results) == len(STUDENTS)
    assert cell_grades(course) == cell_grades(sequential)
    assert "database is locked" not in " ".join(r.log for r in results)
    before = cell_grades(course)
    # a second run finds everything graded from the same files: nothing is redone
    assert course.grade(workers=2) == []
    assert cell_grades(course) == before
    # an interrupted run (one submission's result never recorded) resumes with just that one
    journal = json.loads((course.root / ".cvkit" / "journal.json").read_text())
    del journal[f"bob/{ASSIGNMENT}"]
    (course.root / ".cvkit" / "journal.json").write_text(json.dumps(journal))
    assert [(r.student, r.ok) for r in course.grade(workers=2)] == [("bob", True)]
    assert cell_grades(course) == before
    # a changed submission is graded again
    course.submit("cyd", ASSIGNMENT, {f"{ASSIGNMENT}.ipynb": _answers()})
    assert [r.student for r in course.grade(workers=2)] == ["cyd"]
    assert cell_grades(course)["cyd"] == cell_grades(course)["ada"]


def test_dask_local_cluster(project, sequential, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        course = make_course(project, tmp_path / "course")
        results = course.grade(scheduler=cluster.scheduler_address)
    assert all(r.ok for r in results) and len(results) == len(STUDENTS)
    assert cell_grades(course) == cell_grades(sequential)


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _postgres_binaries():
    import glob
    import os

    for folder in sorted(glob.glob("/usr/lib/postgresql/*/bin"), reverse=True) + ["/usr/local/bin", "/usr/bin"]:
        if os.path.exists(f"{folder}/initdb") and os.path.exists(f"{folder}/postgres"):
            return folder
    if shutil.which("apt-get") and os.geteuid() == 0:  # install the server on a fresh machine
        subprocess.run(["apt-get", "-o", "DPkg::Lock::Timeout=900", "install", "-y", "-q", "postgresql"], capture_output=True,
                       env={**os.environ, "DEBIAN_FRONTEND": "noninteractive"}, timeout=600)
        return _postgres_binaries_found()
    return None


def _postgres_binaries_found():
    import glob
    import os

    for folder in sorted(glob.glob("/usr/lib/postgresql/*/bin"), reverse=True):
        if os.path.exists(f"{folder}/initdb"):
            return folder
    return None


@pytest.fixture(scope="module")
def postgres(tmp_path_factory):
    """A PostgreSQL server of our own on loopback (installed with apt-get if needed)."""
    import os

    pytest.importorskip("psycopg")
    binaries = _postgres_binaries()
    if binaries is None:
        pytest.skip("no PostgreSQL server binaries and no way to install them here")
    import tempfile

    data = Path(tempfile.mkdtemp(prefix="cvkit-pg-"))  # outside pytest's 0700 tree: nobody must reach it
    demote = None
    if os.geteuid() == 0:  # initdb refuses to run as root
        def demote():
            os.setgid(65534)
            os.setuid(65534)
        os.chown(data, 65534, 65534)
    subprocess.run([f"{binaries}/initdb", "-D", str(data / "db"), "-U", "cvkit", "--auth=trust", "-E", "UTF8"],
                   check=True, capture_output=True, preexec_fn=demote, cwd="/")
    port = _free_port()
    server = subprocess.Popen([f"{binaries}/postgres", "-D", str(data / "db"), "-p", str(port), "-h", "127.0.0.1",
                               "-k", str(data)], preexec_fn=demote, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, cwd="/")
    import psycopg

    url = f"postgresql://cvkit@127.0.0.1:{port}/postgres"
    for _ in range(100):
        try:
            with psycopg.connect(url, autocommit=True) as conn:
                conn.execute("CREATE DATABASE gradebook")
            break
        except psycopg.OperationalError:
            time.sleep(0.2)
    else:
        server.kill()
        pytest.fail("PostgreSQL did not start")
    yield f"postgresql+psycopg://cvkit@127.0.0.1:{port}/gradebook"
    server.terminate()
    server.wait(timeout=30)
    shutil.rmtree(data, ignore_errors=True)


def test_postgresql_gradebook(project, sequential, postgres, tmp_path):
    course = make_course(project, tmp_path / "course", db_url=postgres)
    results = course.grade(workers=2)
    assert all(r.ok for r in results), [r.log[-800:] for r in results if not r.ok]
    assert cell_grades(course) == cell_grades(sequential)
    assert not (course.root / "gradebook.db").exists()


def test_attacks_from_the_kernel_change_nothing(project, tmp_path):
    course_dir = tmp_path / "course"
    honest = _answers()
    vandal = _answers()
    course = Course(course_dir, project=project)
    gradebook = course.root / "gradebook.db"
    victim = course.root / "submitted" / "ada" / ASSIGNMENT / f"{ASSIGNMENT}.ipynb"
    # a demo-looking cell that tries to delete the gradebook and another student's work
    vandal["cells"].insert(2, new_cell(
        "import os\n"
        f"for path in ({str(gradebook)!r}, {str(victim)!r}):\n"
        "    try:\n        os.remove(path)\n    except OSError as exc:\n        print('blocked:', exc)\n"))
    # tampering with graded cells: the visible test deleted, the hidden one duplicated, an
    # answer retyped as markdown
    tampered = _answers()
    cells = tampered["cells"]
    cells.pop(3)                                   # mean_kernel_visible deleted
    cells.insert(4, json.loads(json.dumps(cells[3])))  # mean_kernel_hidden duplicated
    for cell in cells:
        if cell["metadata"].get("nbgrader", {}).get("grade_id") == "temporal_mean_answer":
            cell["cell_type"] = "markdown"
            cell.pop("outputs", None)
            cell.pop("execution_count", None)
    cheater = _answers(kernel='from cvkit import filters\n@student("filters.mean_kernel")\n'
                              'def mean_kernel(size):\n    return filters.mean_kernel(size)')
    course = make_course(project, course_dir, students={"ada": honest, "vic": vandal, "tom": tampered,
                                                         "eve": cheater})
    before = victim.read_bytes()
    results = course.grade(workers=2)
    assert all(r.ok for r in results), [r.log[-800:] for r in results if not r.ok]
    assert victim.read_bytes() == before and gradebook.exists()
    grades = cell_grades(course)
    full = {"mean_kernel_visible": 1, "mean_kernel_hidden": 2, "temporal_mean_visible": 1, "temporal_mean_hidden": 2}
    assert grades["ada"] == pytest.approx(full) and grades["vic"] == pytest.approx(full)
    assert grades["eve"]["mean_kernel_visible"] == 0 and grades["eve"]["mean_kernel_hidden"] == 0
    # tampering with graded cells gains nothing and loses no honest work: nbgrader refuses the
    # notebook, cvkit grades the student's answers in a repaired copy of the release, and flags it
    assert grades["tom"] == pytest.approx(full)
    flags = {s: [f for e in v for f in e.flags] for s, v in course.scores(ASSIGNMENT).items()}
    assert any("deletes files" in f for f in flags["vic"])
    assert any("repaired copy" in f for f in flags["tom"])
    assert not flags["ada"]
