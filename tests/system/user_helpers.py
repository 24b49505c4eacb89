"""Local Unix accounts for tests that run the kit as an ordinary user (made with ``useradd``,
removed after, with every process they left)."""
import os
import pwd
import shutil
import subprocess
import uuid

import pytest


def make_user():
    """A new local account (its ``pwd`` entry), for a ``yield`` fixture; skips where the suite
    cannot make one (not root, no ``useradd``): CI runs as root."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("useradd") is None:
        pytest.skip("making a local account needs root and useradd (the suite's CI runs as root)")
    name = f"cvk{uuid.uuid4().hex[:8]}"
    subprocess.run(["useradd", "--create-home", "--shell", "/bin/sh", name], check=True, capture_output=True)
    return pwd.getpwnam(name)


def remove_user(user) -> None:
    subprocess.run(["pkill", "-KILL", "-u", user.pw_name], capture_output=True)
    subprocess.run(["userdel", "--remove", user.pw_name], capture_output=True)


def runuser() -> str:
    """The ``runuser`` command (in ``/usr/sbin``, often not on a test's ``PATH``)."""
    return shutil.which("runuser") or shutil.which("runuser", path="/usr/sbin:/sbin") or "runuser"
