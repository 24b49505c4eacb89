"""Grading works wherever the kit and its Python environment live (issue 33).

The sandbox mounts a private tmpfs on ``/tmp`` and ``/dev/shm``; an environment bound there
before that tmpfs was hidden by it (``bwrap: execvp /tmp/…/.venv/bin/python: No such file or
directory``). Each case below makes a kit and an environment the way a user would, at one
place and of one kind, in a folder whose name has spaces, and grades through that
environment's own Python in a subprocess: a sandboxed call (:func:`cvkit.sandbox.session.run_calls`,
the worker that decides hidden cases: the base installation's Python, NumPy and the runtime)
and a sandboxed notebook run (:func:`cvkit.sandbox.notebook_run.execute_in_sandbox`: the
environment's Python, its packages and the kit). The notebook also reports what it sees of the
kit's folder: only the bound folders, never the files beside them.

How an environment is made, cheaply but as a user would have it (no network here, so no
``pip install``): the interpreter makes the virtual environment itself (``python -m venv``, with
symbolic links or ``--copies``, ``--without-pip`` since pip plays no part in grading); the
packages that grading imports (NumPy, nbclient, nbformat, ipykernel and what they require, as
``pip`` would have installed them: every file of each distribution's ``RECORD``) are put into
that environment's own ``site-packages`` as hard links to the test environment's files (copies
where the place is another file system, ``/dev/shm``); the kit is a copy of ``cvkit/`` beside
it, found through a ``.pth`` file as an editable install finds it. So every file the graded
run needs lies at the place under test, as it would after ``pip install -e .`` there; a ``.pth``
pointing back at the test environment would not be faithful (the sandbox binds the
environment's own prefix, not folders a ``.pth`` names elsewhere). A Python installed outside
``/usr`` (pyenv, conda, a copy under ``/tmp``) is the test environment's own base (pyenv here)
for the virtual environments, and for the cases without one, Debian's ``/usr/bin/python3.X``
(one static binary) copied to the place with its standard library hard-linked beside it: a
complete CPython installation whose prefix is that folder, used directly (packages in its own
site folder, as conda's base environment is used) or as the base of a virtual environment.
"""
from __future__ import annotations

import importlib.metadata
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from cvkit.sandbox import session as sandbox

ROOT = Path(__file__).resolve().parents[2]
#: the distributions a graded run imports (and what they require): the worker needs NumPy, the
#: notebook's run nbclient, nbformat and an IPython kernel; cvkit's own SciPy is imported by
#: neither
ROOTS = ("numpy", "nbclient", "nbformat", "ipykernel")
VERSION = f"python{sys.version_info.major}.{sys.version_info.minor}"

#: run by the environment's own Python: one sandboxed call, one sandboxed notebook
PROBE = r'''
import json, os, sys
import cvkit
from cvkit.sandbox import notebook_run as execute, isolation, session as sandbox
from cvkit.grading.runtime.wire import BoxCall

kit, clone = sys.argv[1], sys.argv[2]
result = sandbox.run_calls(["def f(x):\n    return x + 1"], [BoxCall("f", args=(1,))])
cell = ("import json, os, sys, cvkit\n"
        f"kit, clone = {kit!r}, {clone!r}\n"
        "print(json.dumps({'prefix': sys.prefix, 'cvkit': cvkit.__file__, 'answer': 6 * 7,\n"
        "                  'kit': sorted(os.listdir(kit)), 'secret': os.path.exists(os.path.join(kit, 'secret.txt')),\n"
        "                  'clone': os.path.exists(clone)}))")
notebook = {"nbformat": 4, "nbformat_minor": 5, "cells": [
    {"cell_type": "code", "id": "only", "source": cell, "metadata": {}, "execution_count": None, "outputs": []}],
    "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}}}
text, log = execute.execute_in_sandbox({"one cell.ipynb": json.dumps(notebook).encode()}, "one cell.ipynb",
                                       wall_seconds=300)
outputs = json.loads(text)["cells"][0]["outputs"] if text else []
print(json.dumps({
    "value": result.outcomes[0].value if result.outcomes[0] else None, "crashed": result.crashed,
    "output": result.output[-2000:], "cvkit": cvkit.__file__, "prefix": sys.prefix,
    "masked": isolation.site_packages_of_the_system(), "purelib": __import__("sysconfig").get_paths()["purelib"],
    "cell": "".join("".join(o.get("text", "")) for o in outputs if o.get("output_type") == "stream"),
    "errors": [o for o in outputs if o.get("output_type") == "error"], "log": log[-2000:]}))
'''


def _requirement_names(distribution) -> list[str]:
    names = []
    for requirement in distribution.requires or []:
        if re.search(r"""extra\s*==""", requirement):
            continue
        match = re.match(r"[A-Za-z0-9][A-Za-z0-9._-]*", requirement)
        if match:
            names.append(match.group(0))
    return names


def _distributions() -> list:
    """``ROOTS`` and everything they require that is installed here (markers aside: a package
    too many is harmless)."""
    found: dict[str, object] = {}
    todo = list(ROOTS)
    while todo:
        name = re.sub(r"[-_.]+", "-", todo.pop()).lower()
        if name in found:
            continue
        try:
            distribution = importlib.metadata.distribution(name)
        except importlib.metadata.PackageNotFoundError:
            continue
        found[name] = distribution
        todo += _requirement_names(distribution)
    return list(found.values())


def _link_or_copy(source: str, target: str) -> None:
    try:
        os.link(source, target)
    except OSError:  # another file system (/dev/shm)
        shutil.copy2(source, target)


def _install_packages(site_packages: Path) -> None:
    """Every file of the needed distributions, at ``site_packages`` (as pip lays them out)."""
    for distribution in _distributions():
        base = Path(distribution.locate_file("")).resolve()
        for entry in distribution.files or []:
            source = Path(distribution.locate_file(entry)).resolve()
            if not source.is_file() or not source.is_relative_to(base):  # scripts in bin/ and the like
                continue
            target = site_packages / source.relative_to(base)
            target.parent.mkdir(parents=True, exist_ok=True)
            if not target.exists():
                _link_or_copy(str(source), str(target))


def _python_installation(folder: Path) -> Path | None:
    """A CPython installation whose prefix is ``folder``: Debian's static ``/usr/bin/python3.X``
    and its standard library (hard links, or copies on another file system); its Python, or
    None where this machine has no such Python of the test environment's version."""
    system = Path("/usr/bin") / VERSION
    if not system.is_file() or not Path("/usr/lib", VERSION, "os.py").is_file():
        return None
    (folder / "bin").mkdir(parents=True)
    shutil.copy2(system, folder / "bin" / VERSION)
    os.symlink(VERSION, folder / "bin" / "python3")
    shutil.copytree(Path("/usr/lib", VERSION), folder / "lib" / VERSION, symlinks=True, copy_function=_link_or_copy,
                    ignore=shutil.ignore_patterns("dist-packages", "site-packages"))
    python = folder / "bin" / VERSION
    done = subprocess.run([str(python), "-c", "import sys; print(sys.prefix)"], capture_output=True, text=True)
    if done.returncode != 0 or done.stdout.strip() != str(folder):  # not relocatable (needs its libpython)
        return None
    return python


def _make(kind: str, case: Path, folder) -> tuple[Path, Path]:
    """The kit and its environment in ``case`` (``folder(place)`` makes other folders, removed
    with it); the environment's Python and the kit's folder as the user reaches them."""
    kit = case / "the kit"
    shutil.copytree(ROOT / "cvkit", kit / "cvkit", copy_function=_link_or_copy)
    (kit / "secret.txt").write_text("lectures, gradebook, salt: never seen by a sandbox")
    known_kit = kit
    if kind == "debian-system-site-packages":
        base = Path("/usr/bin/python3")
        if not base.exists():
            pytest.skip("no Debian /usr/bin/python3 on this machine")
        version = subprocess.run([str(base), "-c", "import sys; print(sys.version_info[:2])"],
                                 capture_output=True, text=True).stdout.strip()
        if version != str(sys.version_info[:2]):
            pytest.skip(f"Debian's python3 is {version}, not the test environment's version (binary packages)")
        venv_args = [str(base), "-m", "venv", "--without-pip", "--system-site-packages"]
    elif kind.startswith("installation"):
        base = _python_installation(case / "python 3")
        if base is None:
            pytest.skip(f"no relocatable /usr/bin/{VERSION} (Debian's static build) to install elsewhere")
        venv_args = [str(base), "-m", "venv", "--without-pip"] if kind == "installation-and-venv" else None
    else:
        base = Path(os.path.realpath(getattr(sys, "_base_executable", sys.executable)))  # pyenv, conda, /usr
        venv_args = [str(base), "-m", "venv", "--without-pip"] + (["--copies"] if kind == "copies" else [])
    if venv_args is None:  # the installation itself, packages in its own site folder
        python = base
    else:
        environment = (folder("/var/tmp") if kind == "installation-and-venv" else kit) / ".venv"
        subprocess.run(venv_args + [str(environment)], check=True, capture_output=True)
        python = environment / "bin" / "python"
    if kind == "symlinked-folder":  # the user works in the kit through a link (/home → /var/home)
        link = folder("/var/tmp") / "my kit"
        os.symlink(kit, link)
        known_kit, python = link, link / python.relative_to(kit)
    purelib = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    _install_packages(Path(purelib))
    (Path(purelib) / "the-kit.pth").write_text(f"{known_kit}\n")  # as an editable install
    return python, known_kit


CASES = [  # (place, kind)
    ("/tmp", "copies"),                          # scripts/_venv.py's own kind (venv.EnvBuilder copies)
    ("/tmp", "symlinks"),                        # python3 -m venv
    ("/dev/shm", "copies"),
    ("/var/tmp", "symlinks"),
    ("/tmp", "debian-system-site-packages"),     # Debian's /usr/bin/python3, packages of the system visible
    ("/tmp", "installation"),                    # a Python installed under /tmp, no venv (conda's base)
    ("/dev/shm", "installation-and-venv"),       # a Python installed under /dev/shm, its venv in /var/tmp
    ("/var/tmp", "symlinked-folder"),            # the kit reached through a symbolic link (/home → /var/home)
]


@pytest.fixture
def case_folders():
    made: list[Path] = []

    def make(place: str) -> Path:
        made.append(Path(tempfile.mkdtemp(prefix="cvkit location 33 ", dir=place)))
        return made[-1]

    yield make
    for folder in made:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.slow
@pytest.mark.parametrize("place, kind", CASES, ids=[f"{place}-{kind}" for place, kind in CASES])
def test_grading_runs_where_the_kit_and_its_environment_live(place, kind, case_folders, grading_sandbox):
    """(``grading_sandbox``: bubblewrap installed; whether a sandbox can be made is the case's own
    question, answered by the environment's Python: the test process may live anywhere.)"""
    if not os.path.isdir(place):
        pytest.skip(f"{place} does not exist here")
    python, kit = _make(kind, case_folders(place), case_folders)
    env = {key: value for key, value in os.environ.items()
           if key not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "CVKIT_NO_SANDBOX")}
    done = subprocess.run([str(python), "-c", PROBE, str(kit), str(ROOT)], capture_output=True, text=True, env=env,
                          cwd="/", timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.splitlines()[-1])
    assert report["cvkit"].startswith(str(kit) + "/"), report["cvkit"]  # the kit at this place, not the clone
    assert report["value"] == 2 and report["crashed"] is None, report["output"]
    assert not report["errors"], report["errors"]
    assert report["cell"], report["log"]
    seen = json.loads(report["cell"])
    assert seen["answer"] == 42 and seen["prefix"] == report["prefix"] and seen["cvkit"] == report["cvkit"]
    assert seen["secret"] is False and seen["clone"] is False  # the bound folders only, not what is beside them
    assert set(seen["kit"]) <= {"cvkit", ".venv"} and "cvkit" in seen["kit"], seen["kit"]
    if kind == "installation":  # its own package folder is hidden from the worker like any base's
        assert report["purelib"] in report["masked"], report


def test_the_worker_runs_the_base_installations_python_not_the_environments_copy(tmp_path, monkeypatch):
    """Python 3.10 names the environment's own ``python`` as ``sys._base_executable``: in a
    ``--copies`` environment (as scripts/_venv.py makes) that file is not in the worker's
    sandbox, which binds the base installation only."""
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    base, environment = tmp_path / "base python", tmp_path / "kit" / ".venv"
    for folder in (base / "bin", environment / "bin"):
        folder.mkdir(parents=True)
    (base / "bin" / version).write_bytes(b"")
    (environment / "bin" / "python").write_bytes(b"")
    monkeypatch.setattr(sys, "base_prefix", str(base))
    monkeypatch.setattr(sys, "_base_executable", str(environment / "bin" / "python"), raising=False)
    expected = os.path.realpath(base / "bin" / version)
    assert sandbox.base_python() == expected
    monkeypatch.setattr(sys, "_base_executable", str(base / "bin" / version))  # 3.11 and later
    assert sandbox.base_python() == expected
