"""The operating-system sandbox itself (cvkit.sandbox.isolation), one property at a time."""
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from cvkit.sandbox import isolation

ROOT = Path(__file__).resolve().parents[2]
PYTHON = os.path.realpath(getattr(sys, "_base_executable", sys.executable))


def run(code: str, limits=None, mounts=None, timeout=60) -> tuple[int, str]:
    with isolation.Sandbox([PYTHON, "-I", "-S", "-c", textwrap.dedent(code)], limits=limits or isolation.Limits(),
                           mounts=mounts, stdout=subprocess.PIPE, stderr=subprocess.STDOUT) as box:
        out, _ = box.process.communicate(timeout=timeout)
        return box.process.returncode, out.decode(errors="replace")


@pytest.fixture(autouse=True)
def sandbox_available(grading_sandbox):
    assert grading_sandbox is None, grading_sandbox  # the reason, with how to install bubblewrap


def test_unprivileged_and_alone():
    status, out = run("""\
        import os
        print(os.getuid(), os.getgid(), os.getpid())
        print(sorted(p for p in os.listdir('/proc') if p.isdigit()))""")
    uid, gid, pid = out.split("\n")[0].split()
    assert status == 0 and uid == gid == str(isolation.SANDBOX_UID)
    assert int(pid) < 10  # a PID namespace of its own: the grader's processes are invisible
    assert len(eval(out.split("\n")[1])) <= 3


def test_sees_no_course_no_lectures_no_host_tmp(tmp_path):
    secret = tmp_path / "salt"
    secret.write_text("s3cret")
    # what the sandbox binds (the runtime's own folders, e.g. /root/.pyenv, and this environment,
    # which may lie under /tmp: then /tmp holds the folders leading to it, and nothing else)
    bound = [target for _, target in isolation.system_mounts()]
    candidates = [str(secret), str(ROOT / "lectures"), str(ROOT / "autograders"), "/var/tmp", "/etc/shadow",
                  "/etc/passwd", "/root/.bashrc", "/home", "/srv", "/opt"]
    present = [p for p in candidates if os.path.exists(p) and not any(isolation.within(t, p) for t in bound)]
    assert len(present) >= 4
    private = sorted(t for t in bound if any(isolation.within(t, f) for f in isolation.PRIVATE_FOLDERS))
    status, out = run(f"""\
        import os
        for path in {present!r}:
            print(path, os.path.exists(path))
        seen = []
        for top in ('/tmp', '/dev/shm'):
            for folder, folders, files in os.walk(top):
                if folder in {private!r}:
                    folders[:] = []
                    continue
                seen += [os.path.join(folder, name) for name in folders + files]
        print(sorted(seen))""")
    assert status == 0, out
    for line in out.splitlines()[:-1]:
        assert line.endswith("False"), line
    for path in eval(out.splitlines()[-1]):  # only the bound folders and the empty folders leading to them
        assert any(isolation.within(target, path) for target in private), (path, private)


def test_no_network():
    status, out = run("""\
        import socket
        try:
            socket.create_connection(('1.1.1.1', 53), timeout=3)
            print('connected')
        except OSError as error:
            print('refused', error)""")
    assert "refused" in out


def test_read_only_runtime_and_private_writable_tmp():
    status, out = run(f"""\
        import os
        try:
            open({os.path.join(os.path.realpath(sys.base_prefix), 'cvkit-was-here')!r}, 'w')
            print('wrote the runtime')
        except OSError:
            print('read-only')
        open('/tmp/x', 'w').write('ok')
        print(open('/tmp/x').read())""")
    assert out.split() == ["read-only", "ok"]
    assert not os.path.exists("/tmp/x") or open("/tmp/x").read() != "ok"


def test_memory_and_file_size_limits():
    status, out = run("""\
        try:
            b = bytearray(2 * 1024 ** 3)
            print('allocated')
        except MemoryError:
            print('memory refused')""", limits=isolation.Limits(memory_mb=512))
    assert "memory refused" in out
    status, out = run("open('/tmp/big', 'wb').write(b'x' * (3 << 20))", limits=isolation.Limits(file_mb=1, tmpfs_mb=64))
    assert status != 0  # SIGXFSZ (or an error) at the file-size limit


def test_process_limit():
    status, out = run("""\
        import os, resource, time
        n = int(os.environ['CVKIT_SANDBOX_NPROC'])
        resource.setrlimit(resource.RLIMIT_NPROC, (n, n))
        count = 0
        for _ in range(100):
            try:
                pid = os.fork()
            except OSError:
                break
            if pid == 0:
                time.sleep(3)
                os._exit(0)
            count += 1
        print('children', count)""", limits=isolation.Limits(processes=16))
    count = int(out.split("children")[1].split()[0])
    assert count < 16


def test_killing_the_sandbox_ends_every_process_in_it():
    marker = f"cvkit-isolation-{os.getpid()}"
    box = isolation.Sandbox([PYTHON, "-I", "-S", "-c", textwrap.dedent(f"""\
        import os, time
        if os.fork() == 0:
            os.setsid()
            if os.fork() == 0:
                os.execv('/bin/sleep', ['/bin/sleep', '300', '{marker}'])
            os._exit(0)
        time.sleep(300)""")], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 20
        while not subprocess.run(["pgrep", "-f", marker], capture_output=True).stdout and time.monotonic() < deadline:
            time.sleep(0.1)
        assert subprocess.run(["pgrep", "-f", marker], capture_output=True).stdout  # the daemon runs...
    finally:
        box.close()
    deadline = time.monotonic() + 10
    while subprocess.run(["pgrep", "-f", marker], capture_output=True).stdout and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not subprocess.run(["pgrep", "-f", marker], capture_output=True).stdout  # ...and is gone with it


def test_probe_explains_how_to_install(monkeypatch):
    monkeypatch.setattr(isolation, "bwrap_path", lambda: None)
    monkeypatch.setattr(isolation, "_probe", {})
    reason = isolation.probe()
    assert reason and "apt-get install bubblewrap" in reason and "--no-sandbox" in reason
    with pytest.raises(isolation.SandboxUnavailable):
        isolation.require()


def test_collect_files_refuses_links_and_devices(tmp_path):
    folder = tmp_path / "sub"
    folder.mkdir()
    (folder / "nb.ipynb").write_text("{}")
    (folder / "data").mkdir()
    (folder / "data" / "a.txt").write_text("a")
    os.symlink("/etc/passwd", folder / "passwd")
    os.symlink(tmp_path, folder / "up")
    outside = tmp_path / "outside.txt"
    outside.write_text("theirs")
    os.link(outside, folder / "hard.txt")
    os.mkfifo(folder / "pipe")
    files, refused = isolation.collect_files(folder)
    assert sorted(files) == ["data/a.txt", "nb.ipynb"]
    text = " ".join(refused)
    for name in ("passwd", "up", "hard.txt", "pipe"):
        assert name in text


def test_read_only_binds_into_the_private_tmp(tmp_path):
    shared = tmp_path / "fontlist.json"
    shared.write_text('{"made": "by the grader"}')
    mounts = isolation.Mounts(read_only_in_tmp=[(str(shared), "/tmp/.cache/list.json")])
    status, out = run("""\
        import os
        print(open('/tmp/.cache/list.json').read())
        for attempt in (lambda: open('/tmp/.cache/list.json', 'w'), lambda: os.remove('/tmp/.cache/list.json'),
                        lambda: os.rename('/tmp/.cache/list.json', '/tmp/.cache/moved')):
            try:
                attempt()
                print('changed')
            except OSError:
                print('refused')
        open('/tmp/.cache/own', 'w').write('ok')   # the folder around it stays the sandbox's own
        print(sorted(os.listdir('/tmp/.cache')))""", mounts=mounts)
    assert status == 0, out
    assert out.split("\n")[:5] == ['{"made": "by the grader"}', "refused", "refused", "refused",
                                   "['list.json', 'own']"]
    assert shared.read_text() == '{"made": "by the grader"}'
    with pytest.raises(ValueError, match="read_only_in_tmp"):
        isolation.command(["true"], isolation.Mounts(read_only_in_tmp=[(str(shared), "/etc/list.json")]),
                          isolation.Limits(), {})


def test_binds_under_a_private_folder_come_after_its_tmpfs():
    """bubblewrap applies mounts in order: an environment under /tmp bound before the private
    tmpfs would be hidden by it (issue 33), a masked folder must come after the bind around it."""
    mounts = isolation.Mounts(read_only=[("/srv/env", "/tmp/a kit/.venv")], masked=["/tmp/a kit/.venv/lib/site-packages"],
                              writable=[("/srv/shared", "/dev/shm/work")])
    args = isolation.command(["true"], mounts, isolation.Limits(), {"HOME": "/tmp"})

    def at(*operation):
        found = [i for i in range(len(args)) if args[i:i + len(operation)] == list(operation)]
        assert len(found) == 1, operation
        return found[0]

    assert at("--size", str(256 << 20), "--tmpfs", "/tmp") < at("--ro-bind", "/srv/env", "/tmp/a kit/.venv") \
        < at("--tmpfs", "/tmp/a kit/.venv/lib/site-packages")
    assert at("--tmpfs", "/dev/shm") < at("--bind", "/srv/shared", "/dev/shm/work")
    assert at("--ro-bind", "/usr", "/usr") < at("--tmpfs", "/tmp")
    # the host's /tmp itself is never bound: only folders inside the private one
    assert not any(args[i] in ("--bind", "--ro-bind") and args[i + 2] in ("/tmp", "/dev/shm") for i in range(len(args) - 2))


@pytest.mark.parametrize("target", ["/tmp", "/tmp/", "/dev/shm", "/dev", "/"])
def test_a_bind_that_would_cover_a_private_folder_is_refused(target):
    with pytest.raises(isolation.SandboxUnavailable, match="folder of its own"):
        isolation.command(["true"], isolation.Mounts(read_only=[("/srv/env", target)]), isolation.Limits(), {})


def test_a_python_that_lives_in_tmp_itself_is_explained_by_the_probe(monkeypatch):
    monkeypatch.setattr(isolation, "system_mounts", lambda with_environment=True: [("/usr", "/usr"), ("/tmp", "/tmp")])
    monkeypatch.setattr(isolation, "_probe", {})
    reason = isolation.probe()
    assert reason and "cannot bind /tmp at /tmp" in reason


def test_a_folder_under_tmp_is_bound_into_the_private_tmp(tmp_path):
    """A folder of the host's /tmp bound read-only is seen at its own path; what lies beside it
    is not, and the private /tmp stays writable."""
    shared = tmp_path / "a kit" / ".venv"
    shared.mkdir(parents=True)
    (shared / "pyvenv.cfg").write_text("home = /usr/bin\n")
    (tmp_path / "a kit" / "secret.txt").write_text("s3cret")
    mounts = isolation.Mounts(read_only=[(str(shared), str(shared))])
    status, out = run(f"""\
        import os
        print(open({str(shared / 'pyvenv.cfg')!r}).read().strip())
        print(sorted(os.listdir({str(tmp_path / 'a kit')!r})))
        try:
            open({str(shared / 'x')!r}, 'w')
            print('wrote the bind')
        except OSError:
            print('read-only')
        open('/tmp/own', 'w').write('ok')
        print(open('/tmp/own').read())""", mounts=mounts)
    assert status == 0, out
    assert out.splitlines() == ["home = /usr/bin", "['.venv']", "read-only", "ok"]
    assert not (shared / "x").exists()
