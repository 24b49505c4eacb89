"""What the attack suites share: bubblewrap, installed if missing (as root on Debian)."""
import shutil
import subprocess

import pytest

from cvkit.sandbox import isolation


@pytest.fixture(scope="module")
def bubblewrap():
    if shutil.which("bwrap") is None:
        subprocess.run(["apt-get", "-o", "DPkg::Lock::Timeout=900", "install", "-y", "-q", "bubblewrap"],
                       check=False, capture_output=True)
    if isolation.probe(force=True):
        pytest.fail(f"the sandbox is needed for this suite: {isolation.probe()}")
