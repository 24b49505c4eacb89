"""The README's first command works from a fresh clone, wherever it is and whoever runs it (issue 33).

Two real runs of ``python3 scripts/demo`` from a fresh ``git clone`` of this checkout, each
creating its own virtual environment (``pip`` from the package registry, as a newcomer's
machine would): one as root under ``/tmp`` (the sandbox used to hide an environment there), the
README's command as it stands, and one by an ordinary local user (made by the test with
``useradd``, removed after) in their home folder with Debian's ``/usr/bin/python3``, on the
demo's first chapter only. Each must grade its sample submissions in the sandbox and finish
without problems.

Every chapter runs in the environment a course gets (issue #34, item 2): in the virtual
environment the first run's ``scripts/demo`` created (``cvkit[course]``, nothing of the test
suite's), *Run All* on every released chapter reaches its end
(``tests/lectures/run_all_released.py``).
"""
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from user_helpers import make_user, remove_user, runuser

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]
DEBIAN_PYTHON = Path("/usr/bin/python3")


def _clone(target: Path) -> None:
    done = subprocess.run(["git", "-c", f"safe.directory={ROOT}", "clone", "-q", "--no-hardlinks", str(ROOT), str(target)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def _demo_succeeded(done: subprocess.CompletedProcess) -> None:
    out = done.stdout + done.stderr
    assert done.returncode == 0, out[-4000:]
    assert "demo finished in" in out and "WITH PROBLEMS" not in out, out[-4000:]
    assert "ended early" not in out, out[-4000:]


@pytest.fixture
def ordinary_user():
    user = make_user()
    try:
        yield user
    finally:
        remove_user(user)


def _fresh_env() -> dict[str, str]:
    """This process's environment without its virtual environment and cvkit's settings."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("VIRTUAL_ENV", "PYTHON", "CVKIT_"))}
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if ".venv" not in p)
    return env


@pytest.fixture(scope="module")
def demo_under_tmp():
    """A fresh clone under /tmp and its ``scripts/demo`` run (which creates the clone's .venv)."""
    with tempfile.TemporaryDirectory(prefix="cvkit fresh clone ", dir="/tmp") as folder:
        kit = Path(folder) / "kit"
        _clone(kit)
        done = subprocess.run([sys.executable, "scripts/demo", "--workers", "2"], cwd=kit, env=_fresh_env(),
                              capture_output=True, text=True, timeout=1500)
        yield kit, done


def test_the_demo_runs_from_a_fresh_clone_under_tmp(demo_under_tmp):
    kit, done = demo_under_tmp
    _demo_succeeded(done)
    assert (kit / ".venv").is_dir() and (kit / "cvkit-demo" / "exports" / "grades.csv").is_file()


def test_every_released_chapter_runs_all_in_the_demos_environment(demo_under_tmp, tmp_path):
    """*Run All* on each released chapter, with the kernel of the .venv ``scripts/demo`` made:
    a chapter that needs a package the course's environment lacks stops with its ImportError."""
    kit, done = demo_under_tmp
    python = kit / ".venv" / "bin" / "python"
    assert python.is_file(), done.stdout[-2000:] + done.stderr[-2000:]
    home = tmp_path / "home"  # no kernel of this user's own shadows the environment's
    home.mkdir()
    env = dict(_fresh_env(), HOME=str(home), MPLBACKEND="Agg", CVKIT_STUDENT_ID="student")
    result = tmp_path / "run_all.json"
    script = kit / "tests" / "lectures" / "run_all_released.py"
    ran = subprocess.run([str(python), str(script), str(result), "2"], cwd=tmp_path,
                         env=env, capture_output=True, text=True, timeout=1500)
    assert ran.returncode == 0, ran.stdout[-2000:] + ran.stderr[-4000:]
    found = json.loads(result.read_text())
    assert Path(found["prefix"]).resolve() == (kit / ".venv").resolve() == Path(found["python_prefix"]).resolve()
    chapters = found["chapters"]
    assert sorted(chapters) == sorted(p.parent.name for p in (kit / "lectures").glob("ch*/*.ipynb"))
    assert len(chapters) == 12
    stopped = {chapter: problems for chapter, problems in chapters.items() if problems}
    assert not stopped, "\n".join(f"{chapter}: {'; '.join(problems)}" for chapter, problems in sorted(stopped.items()))


def test_the_demo_runs_for_an_ordinary_user_with_debians_python(ordinary_user):
    if not DEBIAN_PYTHON.is_file():
        pytest.skip("this machine has no /usr/bin/python3")
    kit = Path(ordinary_user.pw_dir) / "kit"
    _clone(kit)
    subprocess.run(["chown", "-R", f"{ordinary_user.pw_uid}:{ordinary_user.pw_gid}", str(kit)], check=True)
    env = {"PATH": "/usr/bin:/bin", "HOME": ordinary_user.pw_dir, "LANG": "C.UTF-8"}
    # one chapter: the run as root above grades the demo's three; what this run adds is the user,
    # the home folder and Debian's Python, which the first chapter meets as the others would
    done = subprocess.run([runuser(), "-u", ordinary_user.pw_name, "--", str(DEBIAN_PYTHON), "scripts/demo",
                           "--workers", "2", "--assignment", "ch03_filtering"], cwd=kit, env=env,
                          capture_output=True, text=True, timeout=1500)
    _demo_succeeded(done)
    assert "sandbox: no control group per sandbox" in done.stdout  # the fallback is said, never silent
    grades = kit / "cvkit-demo" / "exports" / "grades.csv"
    assert grades.is_file() and os.stat(grades).st_uid == ordinary_user.pw_uid
