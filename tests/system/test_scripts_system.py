"""The system prerequisite, bubblewrap, set up by one helper (``scripts/_system.py``) for
``scripts/demo``, ``scripts/lab`` and the test suite: installed with apt-get where the user is
root on Debian, otherwise one line saying what to run. Nothing is installed here: ``shutil.which``,
``os.geteuid`` and ``subprocess.run`` are stand-ins."""
from __future__ import annotations

import importlib.util
import io
import runpy
import subprocess
import sys
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / "scripts"


def _load():
    spec = importlib.util.spec_from_file_location("cvkit_scripts_system_under_test", SCRIPTS / "_system.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class Machine:
    """What the helper may see and do: programs on the PATH, the user, apt-get's answers."""

    def __init__(self, monkeypatch, system, *, programs=("apt-get",), uid=0, apt_results=(0,)):
        self.programs = set(programs)
        self.commands: list[list[str]] = []
        self.environments: list[dict] = []
        self.results = list(apt_results)
        monkeypatch.setattr(system.sys, "platform", "linux")
        monkeypatch.setattr(system.shutil, "which", lambda name: f"/usr/bin/{name}" if name in self.programs else None)
        monkeypatch.setattr(system.os, "geteuid", lambda: uid)
        monkeypatch.setattr(system.subprocess, "run", self.run)

    def run(self, command, **options):
        self.commands.append(list(command))
        self.environments.append(options.get("env") or {})
        if "install" not in command:  # apt-get update
            return subprocess.CompletedProcess(command, 0, "", "")
        status = self.results.pop(0) if self.results else 1
        if status == 0:
            self.programs.add("bwrap")
            return subprocess.CompletedProcess(command, 0, "Setting up bubblewrap (0.8.0-2) ...\n", "")
        return subprocess.CompletedProcess(command, 100, "", "E: Unable to locate package bubblewrap\n")


def test_nothing_runs_when_bubblewrap_is_there(monkeypatch):
    system = _load()
    machine = Machine(monkeypatch, system, programs=("apt-get", "bwrap"))
    said = []
    assert system.ensure_bubblewrap(said.append) == ""
    assert system.install_bubblewrap() == ""
    assert machine.commands == [] and said == []


def test_root_on_debian_installs_it_without_a_question(monkeypatch):
    system = _load()
    machine = Machine(monkeypatch, system)
    said = []
    assert system.ensure_bubblewrap(said.append) == ""
    assert machine.commands == [["apt-get", "-o", "DPkg::Lock::Timeout=900", "install", "-y", "-q",
                                 "--no-install-recommends", "bubblewrap"]]
    assert machine.environments[0]["DEBIAN_FRONTEND"] == "noninteractive"
    assert len(said) == 1 and "apt-get" in said[0]


def test_stale_package_lists_are_refreshed_once(monkeypatch):
    system = _load()
    machine = Machine(monkeypatch, system, apt_results=(100, 0))
    assert system.ensure_bubblewrap(lambda line: None) == ""
    assert [command[3] for command in machine.commands] == ["install", "update", "install"]
    assert all(command[1:3] == ["-o", "DPkg::Lock::Timeout=900"] for command in machine.commands)


def test_when_apt_get_fails_one_line_says_why_and_what_to_run(monkeypatch):
    system = _load()
    Machine(monkeypatch, system, apt_results=(100, 100))
    line = system.ensure_bubblewrap(lambda line: None)
    assert "\n" not in line and "Unable to locate package bubblewrap" in line and "apt-get install bubblewrap" in line


def test_an_apt_get_that_hangs_gives_the_line_not_a_traceback(monkeypatch):
    system = _load()
    machine = Machine(monkeypatch, system)

    def hang(command, **options):
        machine.commands.append(command)
        raise subprocess.TimeoutExpired(command, 900)

    monkeypatch.setattr(system.subprocess, "run", hang)
    line = system.ensure_bubblewrap(lambda line: None)
    assert "timed out after 900 seconds" in line and "\n" not in line and len(machine.commands) == 1


def test_not_root_gets_the_one_line_and_nothing_is_run(monkeypatch):
    system = _load()
    machine = Machine(monkeypatch, system, uid=1000)
    said = []
    line = system.ensure_bubblewrap(said.append)
    assert machine.commands == [] and said == []
    assert "\n" not in line and "`sudo apt-get install bubblewrap`" in line and "bwrap" in line
    assert system.install_bubblewrap() == "" and machine.commands == []


@pytest.mark.parametrize("programs, expected", [(("dnf",), "`sudo dnf install bubblewrap`"),
                                                ((), "package manager")])
def test_without_apt_get_the_line_names_the_systems_way(monkeypatch, programs, expected):
    system = _load()
    machine = Machine(monkeypatch, system, programs=programs)
    line = system.ensure_bubblewrap(lambda line: None)
    assert expected in line and "\n" not in line and machine.commands == []


def test_outside_linux_the_line_says_the_sandbox_needs_linux(monkeypatch):
    system = _load()
    Machine(monkeypatch, system, programs=())
    monkeypatch.setattr(system.sys, "platform", "darwin")
    assert "needs Linux" in system.ensure_bubblewrap(lambda line: None)


def _run_script(name: str, argv: list[str], monkeypatch, line: str):
    """``scripts/<name>`` run here with the helper answering ``line`` and the virtual environment
    stood in for: the exit status, what it wrote to standard error, the programs it ran."""
    ran = []
    helper = types.SimpleNamespace(ensure_bubblewrap=lambda announce=None: line)
    venv = types.SimpleNamespace(run=lambda *args, **options: ran.append(args) or 0)
    monkeypatch.setitem(sys.modules, "_system", helper)
    monkeypatch.setitem(sys.modules, "_venv", venv)
    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.setattr(sys, "argv", [str(SCRIPTS / name), *argv])
    errors = io.StringIO()
    monkeypatch.setattr(sys, "stderr", errors)
    with pytest.raises(SystemExit) as stop:
        runpy.run_path(str(SCRIPTS / name), run_name="__main__")
    return stop.value.code, errors.getvalue(), ran


MISSING = "[cvkit] bubblewrap (bwrap) is missing, and grading runs student code in its sandbox: run `sudo apt-get install bubblewrap`, then run this again."


def test_the_demo_stops_at_once_with_the_line_when_bubblewrap_is_missing(monkeypatch):
    status, errors, ran = _run_script("demo", [], monkeypatch, MISSING)
    assert status == 1 and ran == []  # before a minute of installing the environment
    assert errors.count("\n") == 1 and MISSING in errors and "--no-sandbox" in errors
    status, errors, ran = _run_script("demo", [], monkeypatch, "")
    assert status == 0 and ran == [("cvkit", "demo")] and errors == ""
    status, errors, ran = _run_script("demo", ["--no-sandbox"], monkeypatch, MISSING)
    assert status == 0 and ran == [("cvkit", "demo", "--no-sandbox")] and errors == ""


def test_the_lab_says_the_line_and_opens_anyway(monkeypatch):
    status, errors, ran = _run_script("lab", [], monkeypatch, MISSING)
    assert status == 0 and ran == [("jupyter", "lab", "lectures/")] and errors == MISSING + "\n"


def test_one_copy_of_the_apt_get_logic():
    """scripts/demo, scripts/lab and tests/conftest.py all use scripts/_system.py."""
    for path in (SCRIPTS / "demo", SCRIPTS / "lab", ROOT / "tests" / "conftest.py"):
        text = path.read_text()
        assert "_system" in text and "DPkg::Lock" not in text and '"apt-get"' not in text, path
    import conftest

    assert conftest._system_helpers().install_bubblewrap.__doc__ == _load().install_bubblewrap.__doc__
