"""Grading on a real Dask cluster (issue 33): a scheduler and workers started by the ``dask``
command line as processes of their own, the workers running as another, ordinary Unix user
than the instructor — who is an ordinary user too (``docs/scale-out.md``).

- The workers reach cvkit's environment (this checkout, read-only), bubblewrap and a temporary
  folder of their own; they have no home. They cannot read the course folder (0700: the salt,
  the gradebook, the submissions) nor the instructor's project: a job on a worker that touches
  them fails, and grading still succeeds — a job carries all it needs.
- The grades of the cluster equal those of the local pool for the same submissions (honest,
  wrong, blank: the helpers of ``test_course_scaling``).
- A scheduler that cannot be reached stops ``cvkit course grade`` with a message naming its
  address, before anything is recorded.
- A worker killed while it runs a submission loses nothing: the scheduler gives the job to
  another worker (or the instructor's process grades it), and every grade is the local one.
  A scheduler killed during the run loses nothing either, nor do workers that all die: the rest
  is graded locally.
- A worker that would not grade as the instructor's machine (no sandbox, other checks) stops
  the run before anything is graded; one whose sandbox fails when its job comes never grades
  it (a scheduler and worker in this process, whose reports the test chooses).

The test makes two local accounts (``useradd``, removed afterwards, with every process they
ran), so it needs root, as ``tests/system/test_ordinary_user.py``.
"""
import contextlib
import json
import os
import pwd
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import pytest

from course_helpers import ROOT, cell_grades
from test_course_scaling import ASSIGNMENT, EXPECTED, STUDENTS, assert_expected, make_course, source_notebook

# where the test process's Python is out of other users' reach (a pyenv Python in /root), their
# processes run the same environment on the system's Python of that minor version: Dask warns
pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::distributed.versions.VersionMismatchWarning")]
BIN = Path(sys.executable).parent
pytest.importorskip("distributed")


def _runuser() -> str:
    return shutil.which("runuser") or shutil.which("runuser", path="/usr/sbin:/sbin") or "runuser"


def _make_user(prefix: str, home: bool) -> pwd.struct_passwd:
    name = f"{prefix}{uuid.uuid4().hex[:8]}"
    options = (["--create-home", "--shell", "/bin/sh"] if home
               else ["--no-create-home", "--home-dir", "/nonexistent", "--shell", "/usr/sbin/nologin"])
    subprocess.run(["useradd", *options, name], check=True, capture_output=True)
    return pwd.getpwnam(name)


def _remove_user(user: pwd.struct_passwd) -> None:
    subprocess.run(["pkill", "-KILL", "-u", user.pw_name], capture_output=True)  # only this test's account
    subprocess.run(["userdel", "--remove", user.pw_name], capture_output=True)


def _env(user: pwd.struct_passwd, **extra: str) -> dict:
    return {"PATH": f"{BIN}:/usr/bin:/bin", "HOME": user.pw_dir, "LANG": "C.UTF-8", "MPLBACKEND": "Agg", **extra}


def _as(user, argv):
    """``argv`` run as ``user`` (``runuser``)."""
    return [_runuser(), "-u", user.pw_name, "--", *argv]


def _chown(path: Path, user) -> None:
    for folder, dirs, files in os.walk(path):
        for name in [folder, *(os.path.join(folder, n) for n in dirs + files)]:
            os.lchown(name, user.pw_uid, user.pw_gid)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for_port(port: int, process: subprocess.Popen, log: Path, seconds: float = 90) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if process.poll() is not None:
            pytest.fail(f"the Dask scheduler ended ({process.returncode}): {log.read_text()[-2000:]}")
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    pytest.fail(f"the Dask scheduler did not listen on port {port}: {log.read_text()[-2000:]}")


def _stop(process: subprocess.Popen) -> None:
    try:
        os.killpg(process.pid, signal.SIGTERM)
        process.wait(timeout=20)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        process.wait(timeout=20)


@pytest.fixture(scope="module")
def people():
    """The instructor (an ordinary user with a home) and the workers' user (no home)."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("useradd") is None:
        pytest.skip("making local accounts needs root and useradd (the suite's CI runs as root)")
    if not os.access(sys.executable, os.X_OK) or not os.stat(ROOT).st_mode & 0o005:
        pytest.fail(f"the project {ROOT} and its environment must be readable by other users for this test")
    made = []
    try:
        made.append(_make_user("cvki", home=True))
        made.append(_make_user("cvkw", home=False))
        os.chmod(made[0].pw_dir, 0o700)
        yield tuple(made)
    finally:
        for user in made:
            _remove_user(user)


@pytest.fixture(scope="module")
def place(people):
    """The instructor's project (in their home, 0700: out of the workers' reach) and a folder
    others may cross, where the instructor's course folders are made (each 0700)."""
    instructor, _ = people
    project = Path(instructor.pw_dir) / "project"
    (project / "autograders").mkdir(parents=True)
    shutil.copy(ROOT / "autograders" / "nbgrader_config.py", project / "autograders" / "nbgrader_config.py")
    (project / "autograders" / "plan.toml").write_text(f'[[assignment]]\nid = "{ASSIGNMENT}"\n')
    (project / "lectures" / ASSIGNMENT).mkdir(parents=True)
    (project / "lectures" / ASSIGNMENT / f"{ASSIGNMENT}.ipynb").write_text(json.dumps(source_notebook()))
    _chown(project, instructor)
    courses = Path(tempfile.mkdtemp(prefix="cvkit-dask-courses-"))
    os.chmod(courses, 0o755)
    try:
        yield project, courses
    finally:
        shutil.rmtree(courses, ignore_errors=True)


def _course(people, place, name):
    """A built course with the three submissions of ``test_course_scaling``, the instructor's,
    0700."""
    instructor, _ = people
    project, courses = place
    course = make_course(project, courses / name)
    _chown(course.root, instructor)
    os.chmod(course.root, 0o700)
    return course


def _grade(people, course, *options, extra_env=None, **popen):
    instructor, _ = people
    argv = _as(instructor, [str(BIN / "cvkit"), "course", "grade", "--course-dir", str(course.root), *options])
    return subprocess.Popen(argv, env=_env(instructor, **(extra_env or {})), cwd=instructor.pw_dir,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **popen)


@pytest.fixture(scope="module")
def local_grades(place, tmp_path_factory):
    """The local pool's grades of the same submissions (this process, two workers)."""
    project, _ = place
    course = make_course(project, tmp_path_factory.mktemp("local") / "course")
    results = course.grade(workers=2)
    assert all(r.ok for r in results), [r.log[-800:] for r in results if not r.ok]
    grades = cell_grades(course)
    assert_expected(grades)
    return grades


@contextlib.contextmanager
def _cluster(worker, logs: Path, workers: int = 2):
    """``dask scheduler`` and ``dask worker --nworkers N --nthreads 1`` started as ``worker``
    on loopback, with a temporary folder of their own (``TMPDIR``): (the address, the
    scheduler's process). Every process they started is stopped at the end."""
    from distributed import Client

    scratch = Path(tempfile.mkdtemp(prefix="cvkit-dask-worker-"))
    os.chown(scratch, worker.pw_uid, worker.pw_gid)
    os.chmod(scratch, 0o700)
    env = _env(worker, TMPDIR=str(scratch))
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    processes = []
    try:
        with open(logs / "scheduler.log", "wb") as log:
            processes.append(subprocess.Popen(
                _as(worker, [str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                             "--no-dashboard"]),
                env=env, cwd="/", stdout=log, stderr=subprocess.STDOUT, start_new_session=True))
        _wait_for_port(port, processes[0], logs / "scheduler.log")
        with open(logs / "workers.log", "wb") as log:
            processes.append(subprocess.Popen(
                _as(worker, [str(BIN / "dask"), "worker", address, "--nworkers", str(workers), "--nthreads", "1",
                             "--host", "127.0.0.1", "--no-dashboard", "--local-directory", str(scratch / "dask")]),
                env=env, cwd="/", stdout=log, stderr=subprocess.STDOUT, start_new_session=True))
        with Client(address, timeout=60) as client:
            try:
                client.wait_for_workers(workers, timeout=120)
            except TimeoutError:
                pytest.fail("the Dask workers did not start: " + (logs / "workers.log").read_text()[-3000:])
        yield address, processes[0]
    finally:
        for process in reversed(processes):
            _stop(process)
        shutil.rmtree(scratch, ignore_errors=True)


@pytest.fixture(scope="module")
def cluster(people, tmp_path_factory):
    """The suite's cluster: a scheduler and two workers, as the workers' user (its address)."""
    with _cluster(people[1], tmp_path_factory.mktemp("dask-logs")) as (address, _):
        yield address


def test_an_unreachable_scheduler_is_named_and_nothing_is_recorded(people, place):
    course = _course(people, place, "unreachable")
    done = _grade(people, course, "--scheduler", "tcp://127.0.0.1:1",
                  extra_env={"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "3s"})
    out, err = done.communicate(timeout=300)
    assert done.returncode == 2, out[-2000:] + err[-3000:]
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:1" in err, err[-3000:]
    assert "Traceback" not in err, err[-3000:]
    # nothing recorded, as a zero or otherwise: no journal entry, no gradebook submission, no export
    assert course.journal.entries() == {}
    assert not (course.root / "exports" / "grades.csv").exists()
    assert not (course.root / "feedback").exists()
    assert course.audit(course.submissions()) == sorted(course.submissions())


def test_the_workers_cannot_read_the_course_folder(people, place, cluster):
    from distributed import Client

    instructor, worker = people
    project, _ = place
    course = _course(people, place, "reach")
    with Client(cluster, timeout=60) as client:
        assert set(client.run(os.getuid).values()) == {worker.pw_uid}
        # the job looked at the right folder: the instructor's, 0700 ...
        info = client.submit(os.stat, str(course.root), pure=False).result()
        assert info.st_uid == instructor.pw_uid and info.st_mode & 0o777 == 0o700
        # ... and cannot open it, nor the salt, the gradebook, a submission, or the project
        for touch, path in ((os.listdir, course.root), (os.listdir, course.root / "submitted"),
                            (Path.read_bytes, course.root / ".grading_salt"), (Path.read_bytes, course.root / "gradebook.db"),
                            (os.listdir, project)):
            with pytest.raises(PermissionError):
                client.submit(touch, path, pure=False).result()


def _jobs_done(address: str) -> dict:
    """How many grading jobs the scheduler has seen end, by how they ended (its cumulative
    counts): proof that the workers graded, not the instructor's fallback."""
    from distributed import Client

    with Client(address, timeout=60) as client:
        return client.run_on_scheduler(lambda dask_scheduler: {
            state: prefix.state_counts[state] for prefix in [dask_scheduler.task_prefixes.get("grade_on_worker")]
            if prefix is not None for state in ("memory", "erred")})


def test_the_cluster_grades_as_the_local_pool(people, place, cluster, local_grades):
    course = _course(people, place, "cluster")
    before = _jobs_done(cluster)
    done = _grade(people, course, "--scheduler", cluster)
    out, err = done.communicate(timeout=600)
    assert done.returncode == 0, out[-3000:] + err[-3000:]
    assert "autograded 3 submissions" in out and "lost" not in out, out[-3000:]
    after = _jobs_done(cluster)
    assert after["memory"] - before.get("memory", 0) == 3 and after["erred"] == before.get("erred", 0), (before, after)
    assert cell_grades(course) == local_grades
    assert (course.root / "exports" / "grades.csv").is_file()
    assert os.stat(course.root / "exports" / "grades.csv").st_uid == people[0].pw_uid


def _executing_on_a_worker(uid: int) -> int | None:
    """The pid of a Dask worker process (``uid``'s) running a submission's notebook in the
    sandbox: the parent of a ``bwrap`` that runs ``cvkit.sandbox.notebook_run``."""
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            status = dict(line.split(":\t", 1) for line in (entry / "status").read_text().splitlines() if ":\t" in line)
            command = (entry / "cmdline").read_bytes().split(b"\0")
            if status.get("Name", "").strip() != "bwrap" or int(status["Uid"].split()[0]) != uid:
                continue
            if b"cvkit.sandbox.notebook_run" not in command:
                continue
            parent = int(status["PPid"].strip())
            parent_command = (Path("/proc") / str(parent) / "cmdline").read_bytes()
        except (OSError, ValueError, KeyError):
            continue
        if b"python" in parent_command and b"bwrap" not in parent_command:
            return parent
    return None


def test_a_worker_killed_mid_job_loses_no_submission(people, place, cluster, local_grades):
    _, worker = people
    course = _course(people, place, "killed")
    done = _grade(people, course, "--scheduler", cluster)
    killed = None
    deadline = time.monotonic() + 300
    while killed is None and done.poll() is None and time.monotonic() < deadline:
        killed = _executing_on_a_worker(worker.pw_uid)
        if killed is None:
            time.sleep(0.02)
    assert killed is not None, "no worker was seen grading a submission"
    os.kill(killed, signal.SIGKILL)  # the worker process, while its sandbox runs a notebook
    out, err = done.communicate(timeout=600)
    assert done.returncode == 0, out[-3000:] + err[-3000:]
    assert "autograded 3 submissions" in out, out[-3000:]
    assert cell_grades(course) == local_grades
    assert course.audit(course.submissions()) == []


def test_a_scheduler_lost_mid_run_loses_no_submission(people, place, local_grades, tmp_path):
    """The scheduler dies while its worker runs a submission: what is left is graded on the
    instructor's machine, and said so."""
    _, worker = people
    course = _course(people, place, "lost")
    with _cluster(worker, tmp_path, workers=1) as (address, scheduler):
        done = _grade(people, course, "--scheduler", address)
        deadline = time.monotonic() + 300
        while _executing_on_a_worker(worker.pw_uid) is None and done.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert done.poll() is None, "the grading ended before any worker ran a submission"
        os.killpg(scheduler.pid, signal.SIGKILL)
        out, err = done.communicate(timeout=600)
    assert done.returncode == 0, out[-3000:] + err[-3000:]
    assert f"lost the Dask cluster at {address}" in err and "left on this machine" in err, err[-3000:]
    assert cell_grades(course) == local_grades
    assert course.audit(course.submissions()) == []


def test_every_worker_lost_mid_run_loses_no_submission(people, place, local_grades, tmp_path):
    """Every worker dies (the scheduler lives on): the jobs would wait for a worker for ever;
    after Dask's connection timeout without one, the rest is graded on the instructor's machine."""
    _, worker = people
    course = _course(people, place, "orphaned")
    with _cluster(worker, tmp_path, workers=1) as (address, scheduler):
        done = _grade(people, course, "--scheduler", address,
                      extra_env={"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "5s"})
        deadline = time.monotonic() + 300
        while _executing_on_a_worker(worker.pw_uid) is None and done.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert done.poll() is None, "the grading ended before any worker ran a submission"
        for pid in [int(p) for p in os.listdir("/proc") if p.isdigit()]:  # every process of the workers' user
            try:
                if os.stat(f"/proc/{pid}").st_uid == worker.pw_uid and os.getpgid(pid) != scheduler.pid:
                    os.kill(pid, signal.SIGKILL)
            except (OSError, ProcessLookupError):
                pass
        out, err = done.communicate(timeout=600)
        assert scheduler.poll() is None  # the scheduler lived on, without workers
    assert done.returncode == 0, out[-3000:] + err[-3000:]
    assert f"lost the Dask cluster at {address} (no worker left in the cluster for 5 s)" in err, err[-3000:]
    assert "left on this machine" in err
    assert cell_grades(course) == local_grades
    assert course.audit(course.submissions()) == []


@pytest.fixture
def in_process_cluster(tmp_path):
    """A scheduler and a worker in this process (a thread): what a worker reports can be chosen."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0",
                      worker_dashboard_address=":0", local_directory=str(tmp_path / "dask")) as local:
        yield local.scheduler_address


def test_a_worker_that_would_grade_otherwise_stops_the_run(place, in_process_cluster, tmp_path, monkeypatch):
    """A worker without a working sandbox, or with other checks (another cvkit, a course
    package missing), is named before anything is graded: never a class of zeros."""
    from cvkit.course import jobs
    from cvkit.course.parallel import ClusterUnavailable

    project, _ = place
    course = make_course(project, tmp_path / "course", students={"ada": STUDENTS["ada"]})
    monkeypatch.setattr(jobs, "worker_report", lambda sources: {
        "sandbox": "bubblewrap (bwrap) is not installed", "checks": {ASSIGNMENT: "0" * 64}, "where": "grader@node7"})
    with pytest.raises(ClusterUnavailable) as refused:
        course.grade(scheduler=in_process_cluster)
    message = str(refused.value)
    assert "grader@node7" in message and "cannot grade in the sandbox: bubblewrap (bwrap) is not installed" in message
    assert f"would grade {ASSIGNMENT} with other checks" in message and "nothing was graded" in message
    assert course.audit(course.submissions()) == course.submissions()


def test_a_job_whose_worker_sandbox_broke_is_graded_here(place, in_process_cluster, tmp_path, monkeypatch):
    """A worker that passed the check but cannot run the sandbox when its job comes (it joined
    later, its bubblewrap was removed) never grades: the job fails and this machine grades it."""
    from cvkit.course import jobs

    project, _ = place
    course = make_course(project, tmp_path / "course", students={"ada": STUDENTS["ada"]})
    monkeypatch.setattr(jobs, "worker_report", lambda sources: {
        "sandbox": None, "checks": jobs.checks_fingerprints(sources), "where": "grader@node7"})
    asked = []
    monkeypatch.setattr(jobs, "sandbox_problem", lambda: asked.append(1) or "bubblewrap (bwrap) is not installed")
    results = course.grade(scheduler=in_process_cluster)
    assert asked, "the job never asked its worker for the sandbox"
    assert [(r.student, r.ok) for r in results] == [("ada", True)], [r.log[-800:] for r in results]
    assert cell_grades(course)["ada"] == pytest.approx(EXPECTED["ada"])
