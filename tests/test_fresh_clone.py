"""The README's first command works from a fresh clone, wherever it is and whoever runs it (issue 33).

Two real runs of ``python3 scripts/demo`` from a fresh ``git clone`` of this checkout, each
creating its own virtual environment (``pip`` from the package registry, as a newcomer's
machine would): one as root under ``/tmp`` (the sandbox used to hide an environment there), one
by an ordinary local user (made by the test with ``useradd``, removed after) in their home
folder with Debian's ``/usr/bin/python3``. Each must grade its sample submissions in the
sandbox and finish without problems.
"""
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from user_helpers import make_user, remove_user, runuser

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parent.parent
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


def test_the_demo_runs_from_a_fresh_clone_under_tmp():
    with tempfile.TemporaryDirectory(prefix="cvkit fresh clone ", dir="/tmp") as folder:
        kit = Path(folder) / "kit"
        _clone(kit)
        env = {k: v for k, v in os.environ.items() if not k.startswith(("VIRTUAL_ENV", "PYTHON", "CVKIT_"))}
        env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if ".venv" not in p)
        done = subprocess.run([sys.executable, "scripts/demo", "--workers", "2"], cwd=kit, env=env,
                              capture_output=True, text=True, timeout=1500)
        _demo_succeeded(done)
        assert (kit / ".venv").is_dir() and (kit / "cvkit-demo" / "exports" / "grades.csv").is_file()


def test_the_demo_runs_for_an_ordinary_user_with_debians_python(ordinary_user):
    if not DEBIAN_PYTHON.is_file():
        pytest.skip("this machine has no /usr/bin/python3")
    kit = Path(ordinary_user.pw_dir) / "kit"
    _clone(kit)
    subprocess.run(["chown", "-R", f"{ordinary_user.pw_uid}:{ordinary_user.pw_gid}", str(kit)], check=True)
    env = {"PATH": "/usr/bin:/bin", "HOME": ordinary_user.pw_dir, "LANG": "C.UTF-8"}
    done = subprocess.run([runuser(), "-u", ordinary_user.pw_name, "--", str(DEBIAN_PYTHON), "scripts/demo",
                           "--workers", "2"], cwd=kit, env=env, capture_output=True, text=True, timeout=1500)
    _demo_succeeded(done)
    assert "sandbox: no control group per sandbox" in done.stdout  # the fallback is said, never silent
    grades = kit / "cvkit-demo" / "exports" / "grades.csv"
    assert grades.is_file() and os.stat(grades).st_uid == ordinary_user.pw_uid
