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
# What each extra brings along (pyproject.toml): ``test`` includes ``course``, which includes
# ``learn`` and ``data`` (every chapter's data: Chapters 9-12 load scikit-learn's digits).
_INCLUDES = {"test": {"test", "course", "learn", "data", "distributed", "hub", "lms"}, "course": {"course", "data", "learn"},
             "hub": {"hub", "course", "data", "learn"}}


def _covered(extras: str) -> set[str]:
    names: set[str] = set()
    for extra in filter(None, extras.split(",")):
        names |= _INCLUDES.get(extra, {extra})
    return names


def _needs_install(extras: str) -> bool:
    """True unless the stamp shows this pyproject.toml installed with at least ``extras``."""
    if not STAMP.exists():
        return True
    installed, _, mtime = STAMP.read_text().strip().rpartition(":")
    if mtime != str((ROOT / "pyproject.toml").stat().st_mtime_ns):
        return True
    return not _covered(extras) <= _covered(installed)


def ensure(extras: str = "test") -> Path:
    """Make sure ``.venv`` exists with cvkit installed (editable) with ``extras``; return bin/.

    ``scripts/demo`` asks for ``course`` (what a course needs), ``scripts/test`` for ``test``
    (which adds the test tools and oracles on top of it).
    """
    python = BIN / "python"
    if not python.exists():
        print(f"[cvkit] creating virtual environment in {VENV}", flush=True)
        venv.EnvBuilder(with_pip=True, clear=False).create(VENV)
    if _needs_install(extras):
        print(f"[cvkit] installing cvkit[{extras}] and its dependencies (first run only)", flush=True)
        pip = [str(python), "-m", "pip", "--disable-pip-version-check"]
        subprocess.run(pip + ["install", "-q", "--upgrade", "pip"], check=True)
        subprocess.run(pip + ["install", "-q", "-e", f".[{extras}]"], cwd=ROOT, check=True)
        STAMP.write_text(f"{extras}:{(ROOT / 'pyproject.toml').stat().st_mtime_ns}")
    return BIN


def run(program: str, *args: str, extras: str = "test") -> int:
    """Run ``program`` from the virtual environment's bin/ in the project root."""
    bin_dir = ensure(extras)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}", VIRTUAL_ENV=str(VENV))
    env.setdefault("MPLBACKEND", "Agg")
    # Python's bytecode caches (git-ignored) are kept even where PYTHONDONTWRITEBYTECODE is set:
    # the test suite and the demo start hundreds of Python processes (kernels, sandboxed runs,
    # workers), and without the caches each one compiles cvkit again (about 0.5 s of CPU), and
    # every pytest worker rewrites the asserts of every test module again (about 6 s)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return subprocess.call([str(bin_dir / program), *args], cwd=ROOT, env=env)


if __name__ == "__main__":
    ensure()
