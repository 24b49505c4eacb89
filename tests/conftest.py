"""Test-session set-up shared by every test module.

Grading runs student code inside bubblewrap (``cvkit.sandbox.isolation``). On a fresh Debian
machine the suite installs it with apt-get, as the browser test installs Chromium, and in the
same way as ``scripts/demo`` and ``scripts/lab`` (``scripts/_system.py``); where that is
impossible the grading tests fail with the installation hint (they are never skipped: a grader
without its sandbox is not a working grader).
"""
import importlib.util
import shutil
from pathlib import Path

import pytest

from cvkit.sandbox.startup import skip_unused_schema_grammars

# the test processes import nbformat while collecting (course helpers, nbgrader's plugins): skip
# jsonschema's IRI grammars there too, as every grading process does (1.4 s per pytest worker)
skip_unused_schema_grammars()


def _system_helpers():
    """``scripts/_system.py``, which ``scripts/demo`` and ``scripts/lab`` use too (one way to
    install bubblewrap), loaded by its path: ``scripts/`` is not a package."""
    path = Path(__file__).resolve().parent.parent / "scripts" / "_system.py"
    spec = importlib.util.spec_from_file_location("cvkit_scripts_system", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session", autouse=True)
def grading_sandbox():
    """bubblewrap on this machine (installed once per session when missing)."""
    log = _system_helpers().install_bubblewrap()
    from cvkit.sandbox import isolation

    isolation._probe.clear()
    yield isolation.probe() or None
    if log and not shutil.which("bwrap"):  # pragma: no cover - reported by the grading tests themselves
        print(f"apt-get could not install bubblewrap:\n{log}")


# The files that keep one worker busy longest, in seconds (one idle 2-core run, 2026-11-27).
# ``scripts/test`` hands files to the workers in collection order (``--no-loadscope-reorder``),
# and this order puts the long ones first: a long file started last (the browser test, which has
# few tests and so came last in pytest-xdist's own order by test count) would keep one worker
# running while the other sits idle. Files not listed follow in their collection order.
LONGEST_FILES = {
    "tests/library/test_hidden_cases_reference.py": 490,
    # two demos (150 s each) + Run All of every released chapter (70 s), 2026-12-06
    "tests/system/test_fresh_clone.py": 375,
    "tests/system/test_browser.py": 160,
    "tests/lectures/test_notebooks.py": 150,
    "tests/lectures/test_release.py": 145,
    "tests/sandbox/test_sandbox_attacks_round2.py": 120,
    "tests/sandbox/test_sandbox_attacks.py": 115,
    "tests/course/test_course_scaling.py": 100,
    # grades a tiny measured chapter: 6 reference CNNs trained, 90 s loaded (2026-12-06)
    "tests/course/test_leaderboard.py": 100,
    "tests/system/test_hub_round_trip.py": 100,
    "tests/library/test_checks_ch08.py": 95,
    "tests/course/test_course.py": 75,
    "tests/course/test_lms_course.py": 50,  # grades a tiny course once (40-50 s on 2 shared cores, 2026-12-06)
    "tests/library/test_checks_ch05.py": 70,
    "tests/grading/test_visible_probes.py": 60,  # 4 variants of every reference, hidden and visible, 2026-12-06
    "tests/course/test_dask_cluster.py": 60,  # measured 55-75 s on 2 shared cores (2026-12-06)
    "tests/sandbox/test_allowed_helpers.py": 55,
    "tests/sandbox/test_trusted.py": 50,
    "tests/library/test_checks_ch09.py": 45,
    "tests/course/test_course_plan.py": 45,
    # grades a tiny course, then Chromium: 15-41 s on 2 shared cores (2026-12-06)
    "tests/course/test_item_analysis.py": 40,
    # 60 and 300 simulated students: 25 s CPU, 54-65 s loaded (2026-12-06)
    "tests/course/test_similarity_clusters.py": 30,
    "tests/course/test_course_package.py": 35,
    "tests/course/test_hand_marks.py": 35,
    "tests/library/test_checks_ch03.py": 30,
    "tests/course/test_parse_count.py": 35,  # builds and grades one chapter in-process (25-36 s loaded, 2026-12-06)
}


#: Files that mostly wait (time limits running out, servers and subprocesses starting) rather than
#: compute. They are handed out right after the longest file, the sweep, whose own worker
#: processes keep both cores busy meanwhile; at the end of the run their waits left a core idle.
MOSTLY_WAITING = ("tests/sandbox/test_guard.py", "tests/sandbox/test_execute.py",
                  "tests/course/test_written_answers.py")


def _rank(path: str) -> tuple[int, float]:
    seconds = LONGEST_FILES.get(path, 0)
    if seconds == max(LONGEST_FILES.values()):
        return 0, 0.0
    return (1, 0.0) if path in MOSTLY_WAITING else (2, -seconds)


def pytest_collection_modifyitems(config, items):
    """The longest file first, then the mostly waiting ones, then the others longest first
    (stable: the tests of a file keep their order)."""
    ranked = sorted(range(len(items)), key=lambda i: (_rank(items[i].nodeid.split("::")[0]), i))
    items[:] = [items[i] for i in ranked]
