"""The library is typed: mypy over cvkit/ (configuration in mypy.ini) finds no error, and the
package ships ``py.typed`` so that users' type checkers read the hints."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_cvkit_ships_py_typed():
    assert (ROOT / "cvkit" / "py.typed").is_file()
    assert "py.typed" in (ROOT / "pyproject.toml").read_text()


@pytest.mark.slow
def test_mypy_finds_no_error_in_cvkit():
    pytest.importorskip("mypy")
    done = subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(ROOT / "mypy.ini"), "cvkit"],
                          cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-6000:] + done.stderr[-2000:]
    assert "Success: no issues found" in done.stdout
