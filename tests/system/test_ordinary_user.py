"""The instructor is an ordinary user (issue 33): grading works without root.

The test makes a local Unix account (``useradd``, removed afterwards) and runs ``cvkit demo``
as that user with the suite's environment: build, sandboxed grading, feedback and exports in
the user's home. What only root can do (a control group per sandbox) falls back to the
documented limits, and the run's summary says so. The environment's base Python may be out of
the user's reach (here: a pyenv Python in ``/root``, the environment made with ``--copies``):
the grading worker then runs the environment's own interpreter with its packages hidden.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from user_helpers import make_user, remove_user, runuser

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def instructor():
    user = make_user()
    try:
        yield user
    finally:
        remove_user(user)


def _as(user, *argv, timeout=900):
    env = {"PATH": f"{Path(sys.executable).parent}:/usr/bin:/bin", "HOME": user.pw_dir, "LANG": "C.UTF-8",
           "MPLBACKEND": "Agg"}
    return subprocess.run([runuser(), "-u", user.pw_name, "--", *argv], cwd=user.pw_dir, env=env,
                          capture_output=True, text=True, timeout=timeout)


def test_the_demo_grades_as_an_ordinary_user(instructor):
    if not os.access(sys.executable, os.X_OK) or not os.stat(ROOT).st_mode & 0o005:
        pytest.fail(f"the project {ROOT} must be readable by other users for this test")
    folder = Path(instructor.pw_dir) / "demo"
    done = _as(instructor, str(Path(sys.executable).parent / "cvkit"), "demo", "--dir", str(folder),
               "--assignment", "ch03_filtering", "--workers", "2")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "WITH PROBLEMS" not in done.stdout and "ended early" not in done.stdout, done.stdout[-3000:]
    # a weaker limit is never silent: the summary names the fallback in force
    assert "sandbox: no control group per sandbox" in done.stdout
    grades = folder / "exports" / "grades.csv"
    assert grades.is_file() and list((folder / "feedback" / "sample_complete").rglob("*.html"))
    assert os.stat(grades).st_uid == instructor.pw_uid
    assert (os.stat(folder / ".grading_salt").st_mode & 0o077) == 0  # the salt stays the instructor's


def test_the_grading_worker_refuses_to_start_rather_than_grade_zeros(instructor, tmp_path):
    """If the worker cannot run in the sandbox at all, grading stops with what the sandbox said."""
    script = ("from cvkit.sandbox import session as sandbox, isolation\n"
              "sandbox.worker_interpreter = lambda: ('/nonexistent/python', [], [])\n"
              "try:\n    sandbox.require_worker()\nexcept isolation.SandboxUnavailable as error:\n"
              "    print('REFUSED', error)\n")
    done = _as(instructor, sys.executable, "-c", script)
    assert "REFUSED the grading worker cannot run in the sandbox" in done.stdout, done.stdout + done.stderr
    assert "/nonexistent/python" in done.stdout
