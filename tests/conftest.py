"""Test-session set-up shared by every test module.

Grading runs student code inside bubblewrap (``cvkit.sandbox.isolation``). On a fresh Debian
machine the suite installs it with apt-get, as the browser test installs Chromium, and in the
same way as ``scripts/demo`` and ``scripts/lab`` (``scripts/_system.py``); where that is
impossible the grading tests fail with the installation hint (they are never skipped: a grader
without its sandbox is not a working grader).
"""
import importlib.util
import os
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


#: what makes a process the trusted grader (nbgrader_settings.configure sets them): left behind by
#: a test, they would make every later test of its worker a grading run (checks become no-ops)
GRADER_VARIABLES = ("CVKIT_TRUSTED_GRADING", "CVKIT_GRADING_SALT")


@pytest.fixture(autouse=True)
def no_grader_environment_left_behind():
    """Put the grader's variables back after every test, and fail the test that changed them
    (setting them for a test goes through ``monkeypatch``, which undoes it first)."""
    before = {name: os.environ.get(name) for name in GRADER_VARIABLES}
    yield
    changed = sorted(name for name in GRADER_VARIABLES if os.environ.get(name) != before[name])
    for name, value in before.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value
    if changed:
        pytest.fail(f"the test left {', '.join(changed)} changed in the environment (put back now): "
                    "set them with monkeypatch, or take them back as CourseState does")


@pytest.fixture(scope="module")
def bubblewrap(grading_sandbox):
    """The sandbox, for the attack suites: they fail (never skip) when it cannot run."""
    from cvkit.sandbox import isolation

    if isolation.probe(force=True):
        pytest.fail(f"the sandbox is needed for this suite: {isolation.probe()}")


# The files that keep one worker busy longest, in seconds (one 2-core run of the whole suite,
# 2026-12-07, 20 min). ``scripts/test`` hands files to the workers in collection order
# (``--no-loadscope-reorder``), and this order puts the long ones first: a long file started last
# (the browser test, which has few tests and so came last in pytest-xdist's own order by test count)
# would keep one worker running while the other sits idle. Files not listed follow in their
# collection order.
LONGEST_FILES = {
    # two demos from fresh clones (their own venvs) + Run All of every released chapter
    "tests/system/test_fresh_clone.py": 315,
    "tests/library/test_hidden_cases_reference.py": 145,  # the sweep, on a pool of its own
    "tests/system/test_hub_round_trip.py": 130,
    "tests/system/test_browser.py": 120,
    "tests/lectures/test_notebooks.py": 115,
    "tests/sandbox/test_sandbox_attacks_round2.py": 115,
    "tests/library/test_checks_ch12.py": 100,  # the digits' network trained some 20 times
    "tests/course/test_dask_cluster.py": 90,
    "tests/sandbox/test_sandbox_attacks.py": 85,
    "tests/course/test_course.py": 80,
    "tests/library/test_checks_ch05.py": 75,
    "tests/grading/test_visible_probes.py": 70,  # 4 variants of every reference, hidden and visible
    "tests/library/test_checks_ch08.py": 70,
    "tests/sandbox/test_allowed_helpers.py": 60,
    "tests/course/test_course_scaling.py": 55,
    "tests/course/test_hand_marks.py": 45,
    "tests/sandbox/test_trusted.py": 45,
    "tests/course/test_course_folder.py": 40,
    "tests/course/test_parse_count.py": 35,  # builds and grades one chapter in-process
    "tests/course/test_course_plan.py": 35,
    "tests/sandbox/test_sandbox_locations.py": 35,
    "tests/system/test_ordinary_user.py": 30,
    "tests/course/test_similarity_clusters.py": 30,  # 60 and 300 simulated students
    "tests/course/test_leaderboard.py": 30,  # grades a tiny measured chapter: reference CNNs trained
}


#: Files that mostly wait (time limits running out, servers and subprocesses starting) rather than
#: compute. They are handed out right after the longest file (the fresh clones: pip, and the
#: demos' own grading workers, keep the cores busy meanwhile); at the end of the run their waits
#: left a core idle.
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
