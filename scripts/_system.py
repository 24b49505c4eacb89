"""The system prerequisite of grading, bubblewrap (``bwrap``), set up in one way for
``scripts/demo``, ``scripts/lab`` and the test suite (``tests/conftest.py``).

Where the user is root on a Debian-like system (apt-get), bubblewrap is installed without a
question; anywhere else a missing ``bwrap`` gets one line saying what to run. Only the Python
standard library is used: this runs before the virtual environment exists.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys

PACKAGE = "bubblewrap"
#: wait for another apt-get or dpkg (unattended upgrades, a second test run) instead of failing at once
APT_GET = ["apt-get", "-o", "DPkg::Lock::Timeout=900"]
APT_TIMEOUT = 900  # seconds for one apt-get run


def installed() -> bool:
    return shutil.which("bwrap") is not None


def can_install() -> bool:
    """apt-get is here and this process may use it (root): bubblewrap can be installed unasked."""
    return shutil.which("apt-get") is not None and hasattr(os, "geteuid") and os.geteuid() == 0


def install_bubblewrap() -> str:
    """Install bubblewrap with apt-get (non-interactive) when it is missing and :func:`can_install`;
    apt-get's output (its tail), or ``""`` when apt-get did not run. Stale package lists are
    refreshed once (``apt-get update``) when the first attempt fails."""
    if installed() or not can_install():
        return ""
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    command = APT_GET + ["install", "-y", "-q", "--no-install-recommends", PACKAGE]
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=APT_TIMEOUT)
    if done.returncode != 0:  # stale package lists: refresh them once
        subprocess.run(APT_GET + ["update", "-q"], capture_output=True, env=env, timeout=APT_TIMEOUT)
        done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=APT_TIMEOUT)
    return done.stdout[-1000:] + done.stderr[-1000:]


def advice(log: str = "") -> str:
    """One line saying what to run so that ``bwrap`` is here (``log``: apt-get's output when it
    ran and failed)."""
    if not sys.platform.startswith("linux"):
        return (f"[cvkit] the grading sandbox (bubblewrap) needs Linux, and this is {sys.platform}: "
                "grade on Linux, or with --no-sandbox on a single trusted machine.")
    if log:
        last = next((line.strip() for line in reversed(log.splitlines()) if line.strip()), "")
        return (f"[cvkit] apt-get could not install bubblewrap ({last[:200]}): "
                "run `apt-get install bubblewrap` to see why, then run this again.")
    if shutil.which("apt-get"):
        how = "run `sudo apt-get install bubblewrap`"
    elif shutil.which("dnf"):
        how = "run `sudo dnf install bubblewrap`"
    else:
        how = "install the package bubblewrap with your system's package manager"
    return f"[cvkit] bubblewrap (bwrap) is missing, and grading runs student code in its sandbox: {how}, then run this again."


def ensure_bubblewrap(announce=None) -> str:
    """Make sure ``bwrap`` is installed: install it where :func:`can_install` (saying so through
    ``announce``). Returns ``""`` when it is installed, else the one line of :func:`advice`."""
    if installed():
        return ""
    log = ""
    if can_install():
        (announce or (lambda line: print(line, flush=True)))(
            "[cvkit] installing bubblewrap, the grading sandbox, with apt-get (first run only)")
        try:
            log = install_bubblewrap()
        except (OSError, subprocess.SubprocessError) as error:  # apt-get timed out or could not start
            log = str(error)
        if installed():
            return ""
    return advice(log)
