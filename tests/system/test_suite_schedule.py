"""The suite's own schedule (tests/conftest.py): long files go to the workers first."""
from pathlib import Path
from types import SimpleNamespace

import conftest

ROOT = Path(__file__).resolve().parents[2]
LONGEST = max(conftest.LONGEST_FILES, key=conftest.LONGEST_FILES.get)


def test_every_listed_long_file_exists():
    missing = [name for name in conftest.LONGEST_FILES if not (ROOT / name).is_file()]
    assert not missing, f"tests/conftest.py LONGEST_FILES names files that are gone: {missing}"


def test_long_files_come_first_and_each_file_keeps_its_order():
    names = ["tests/test_a.py::one", "tests/system/test_browser.py::first", "tests/test_a.py::two",
             f"{LONGEST}::x", "tests/system/test_browser.py::second", "tests/test_b.py::one"]
    items = [SimpleNamespace(nodeid=name) for name in names]
    conftest.pytest_collection_modifyitems(None, items)
    assert [item.nodeid for item in items] == [
        f"{LONGEST}::x", "tests/system/test_browser.py::first",
        "tests/system/test_browser.py::second", "tests/test_a.py::one", "tests/test_a.py::two", "tests/test_b.py::one"]


def test_files_that_mostly_wait_run_beside_the_longest():
    names = ["tests/test_a.py::one", "tests/system/test_browser.py::first", "tests/sandbox/test_guard.py::g",
             f"{LONGEST}::x", "tests/sandbox/test_execute.py::e"]
    items = [SimpleNamespace(nodeid=name) for name in names]
    conftest.pytest_collection_modifyitems(None, items)
    assert [item.nodeid for item in items] == [
        f"{LONGEST}::x", "tests/sandbox/test_guard.py::g",
        "tests/sandbox/test_execute.py::e", "tests/system/test_browser.py::first", "tests/test_a.py::one"]
    assert all((ROOT / name).is_file() for name in conftest.MOSTLY_WAITING)


def test_the_test_command_keeps_that_order():
    """pytest-xdist would otherwise hand out the files with the most tests first."""
    assert "--no-loadscope-reorder" in (ROOT / "scripts" / "test").read_text()
