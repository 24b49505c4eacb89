"""How the local grading workers start (:func:`cvkit.course.parallel.worker_context`).

They are forked from a ``forkserver`` that imported nbgrader, nbconvert and cvkit once, so a
course graded in one process pays those imports once, not once per worker and ``grade`` call.
What must not change with it: a worker takes the environment of the process that grades *now*
(``--no-sandbox`` or not, the time limits), not the one the server was started with.
"""
from __future__ import annotations

import concurrent.futures
import os
import sys

import pytest

from cvkit.course import parallel
from cvkit.sandbox import session

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forkserver: Linux")


def _worker_view(names: tuple[str, ...]) -> dict:
    """What a worker has before its first job: the environment variables ``names`` and whether
    the preloaded modules are already imported."""
    return {"env": {name: os.environ.get(name) for name in names},
            "loaded": [module for module in parallel.WORKER_PRELOAD if module in sys.modules],
            "pid": os.getpid()}


def _pool(workers: int = 1) -> concurrent.futures.ProcessPoolExecutor:
    return concurrent.futures.ProcessPoolExecutor(
        workers, mp_context=parallel.worker_context(), initializer=parallel._take_environment,
        initargs=(dict(os.environ),))


def test_workers_start_with_nbgrader_and_cvkit_already_imported():
    with _pool() as pool:
        seen = pool.submit(_worker_view, ()).result(timeout=120)
    assert seen["pid"] != os.getpid()
    assert seen["loaded"] == list(parallel.WORKER_PRELOAD)


def test_a_worker_takes_the_environment_of_the_pools_start_not_the_servers(monkeypatch):
    parallel.worker_context()  # the server runs from here on, with this environment
    monkeypatch.setenv("CVKIT_NO_SANDBOX", "1")
    monkeypatch.setenv("CVKIT_NOTEBOOK_GRADING_SECONDS", "123")
    monkeypatch.delenv("CVKIT_CELL_TIMEOUT", raising=False)
    with _pool(2) as pool:
        seen = [pool.submit(_worker_view, ("CVKIT_NO_SANDBOX", "CVKIT_NOTEBOOK_GRADING_SECONDS", "CVKIT_CELL_TIMEOUT"))
                for _ in range(4)]
        views = [future.result(timeout=120) for future in seen]
    assert all(v["env"] == {"CVKIT_NO_SANDBOX": "1", "CVKIT_NOTEBOOK_GRADING_SECONDS": "123",
                            "CVKIT_CELL_TIMEOUT": None} for v in views)
    monkeypatch.delenv("CVKIT_NO_SANDBOX")  # and the next pool, from the same server, sandboxes again
    with _pool() as pool:
        assert pool.submit(_worker_view, ("CVKIT_NO_SANDBOX",)).result(timeout=120)["env"] == {"CVKIT_NO_SANDBOX": None}


def test_the_sandbox_limits_are_read_when_a_run_starts(monkeypatch):
    """A forked worker imported :mod:`cvkit.sandbox.session` in the server: limits set by the
    caller's environment afterwards must still count, so they are read at each run."""
    monkeypatch.setenv("CVKIT_NOTEBOOK_GRADING_SECONDS", "42")
    monkeypatch.setenv("CVKIT_ANSWER_CELL_TIMEOUT", "7")
    assert (session.notebook_seconds(), session.answer_cell_seconds()) == (42.0, 7.0)
    monkeypatch.delenv("CVKIT_NOTEBOOK_GRADING_SECONDS")
    monkeypatch.delenv("CVKIT_ANSWER_CELL_TIMEOUT")
    assert (session.notebook_seconds(), session.answer_cell_seconds()) == (900.0, 60.0)


def test_the_preloaded_modules_start_no_thread():
    """Workers are forks of the server: a thread running there while it forks could leave a lock
    held forever in the worker. Importing what the server preloads must start none."""
    import subprocess

    code = ("import importlib, threading\n"
            f"for name in {list(parallel.WORKER_PRELOAD)!r}:\n"
            "    importlib.import_module(name)\n"
            "print(threading.active_count())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.split() == ["1"]


def test_without_forkserver_the_workers_are_spawned(monkeypatch):
    import multiprocessing

    monkeypatch.setattr(multiprocessing, "get_all_start_methods", lambda: ["spawn"])
    assert parallel.worker_context().get_start_method() == "spawn"
