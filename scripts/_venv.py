"""Create (once) and reuse the project's local virtual environment ``.venv``.

Only the Python standard library is used, so a machine with nothing but ``python3`` can run
``python3 scripts/test`` or ``python3 scripts/demo`` straight after cloning.
"""
from __future__ import annotations

import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv"
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")
STAMP = VENV / ".cvkit-installed"
EXTRAS = "test,learn"


def _needs_install() -> bool:
    if not STAMP.exists():
        return True
    installed = STAMP.read_text().strip()
    return installed != _fingerprint()


def _fingerprint() -> str:
    return f"{EXTRAS}:{(ROOT / 'pyproject.toml').stat().st_mtime_ns}"


def ensure() -> Path:
    """Make sure ``.venv`` exists with cvkit installed (editable) and its extras; return bin/."""
    python = BIN / "python"
    if not python.exists():
        print(f"[cvkit] creating virtual environment in {VENV}", flush=True)
        venv.EnvBuilder(with_pip=True, clear=False).create(VENV)
    if _needs_install():
        print("[cvkit] installing cvkit and its dependencies (first run only)", flush=True)
        pip = [str(python), "-m", "pip", "--disable-pip-version-check"]
        subprocess.run(pip + ["install", "-q", "--upgrade", "pip"], check=True)
        subprocess.run(pip + ["install", "-q", "-e", f".[{EXTRAS}]"], cwd=ROOT, check=True)
        STAMP.write_text(_fingerprint())
    return BIN


def run(program: str, *args: str) -> int:
    """Run ``program`` from the virtual environment's bin/ in the project root."""
    bin_dir = ensure()
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}", VIRTUAL_ENV=str(VENV))
    env.setdefault("MPLBACKEND", "Agg")
    return subprocess.call([str(bin_dir / program), *args], cwd=ROOT, env=env)


if __name__ == "__main__":
    ensure()
