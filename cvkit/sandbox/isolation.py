"""The operating-system sandbox in which every line of student code runs at grading time.

Built on bubblewrap (``bwrap``, Debian package ``bubblewrap``): each sandbox gets new user,
PID, network, IPC, UTS and mount namespaces, an unprivileged uid (65534), ``--die-with-parent``
and ``--new-session``. Its file system holds only what the caller binds read-only (the Python
runtime and the packages it needs), an optional writable copy of one submission, and a private
tmpfs for ``/tmp`` (``/dev/shm`` is private too); no course folder, no ``lectures/``, no
gradebook, no grading salt, no other submission, no network. The binds keep their host paths,
wherever those are: a kit or an environment under ``/tmp`` or ``/dev/shm`` is bound *into* the
private tmpfs after it is made (bubblewrap applies its mounts in order), so the sandbox sees
those folders and the empty folders leading to them, and nothing else of the host's ``/tmp``.

Limits: address space, CPU time, file size and open files are resource limits set before
bubblewrap starts (inherited by everything inside); the number of processes is limited inside
the sandbox's own user namespace (``CVKIT_SANDBOX_NPROC``, applied by the sandboxed program)
and, when the grader may create control groups (root), by a ``pids`` control group that also
caps the sandbox's total memory. Wall-clock limits are the caller's: it kills the sandbox from
outside (:meth:`Sandbox.kill`), and because the sandbox is a PID namespace, every process it
started ends with it — a daemon cannot outlive its submission.

Grading refuses to start when the sandbox cannot be made (:func:`require`); the explicit
``--no-sandbox`` mode of ``cvkit course grade`` (one trusted machine, e.g. a laptop without
user namespaces) runs the same programs with the resource limits only, and says so loudly.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from .._text import name_problem, printable

SANDBOX_UID = 65534
INSTALL_HINT = (
    "cvkit grades student code inside a bubblewrap sandbox. Install it with "
    "`sudo apt-get install bubblewrap` (Debian/Ubuntu; `dnf install bubblewrap` on Fedora) and make sure "
    "unprivileged user namespaces are enabled (`sysctl kernel.unprivileged_userns_clone=1`, and on Ubuntu ≥ 23.10 "
    "an AppArmor profile for bwrap). On a single trusted machine you may grade without it: "
    "`cvkit course grade --no-sandbox` (every grade is then marked as graded without a sandbox)."
)


class SandboxUnavailable(RuntimeError):
    """The sandbox cannot be made on this machine (the message says how to fix it)."""


@dataclass
class Limits:
    """Resource limits of one sandbox."""

    memory_mb: int = 3072        # address space of each process
    cpu_seconds: int = 600       # CPU time of each process
    processes: int = 64          # processes and threads inside the sandbox
    file_mb: int = 64            # largest file a process may write
    tmpfs_mb: int = 256          # the private /tmp
    open_files: int = 256
    total_memory_mb: int = 6144  # whole sandbox, where a memory control group is available


@dataclass
class Mounts:
    """What the sandbox sees: read-only binds (host path → path inside), writable binds."""

    read_only: list = field(default_factory=list)
    writable: list = field(default_factory=list)
    chdir: str = "/tmp"
    with_environment: bool = True   # the grader's Python environment (a venv: its packages)
    masked: list = field(default_factory=list)  # folders hidden behind an empty tmpfs
    read_only_in_tmp: list = field(default_factory=list)  # read-only binds into the private /tmp


def collect_files(folder: Path) -> tuple[dict[str, bytes], list[str]]:
    """The regular files of a submission folder, and what was refused, as printable notes
    (``"<name>: <why> (refused)"``).

    Symbolic links, hard links to files elsewhere, devices, sockets and pipes are never followed
    nor read. Nor is a file whose name (or the name of a folder on its way) is not valid UTF-8
    or holds control or invisible characters (:func:`cvkit._text.name_problem`): such a name
    cannot be written safely to the journal, nbgrader's folders or a report, and no notebook of
    the assignment bears it. Names in the notes are shown with visible escapes
    (:func:`cvkit._text.printable`, ``b"bad\\xff"`` → ``bad\\xff``), so that the notes are
    safe to hash, store and print; every file kept has a name that is.
    """
    import stat

    files: dict[str, bytes] = {}
    refused: list[str] = []
    if folder.is_symlink() or not folder.is_dir():
        return files, [f"{printable(folder.name)}: the submission folder is not a plain folder (refused)"]
    for path in sorted(folder.rglob("*")):
        name = str(path.relative_to(folder))
        shown = printable(name)
        try:
            info = path.lstat()
        except OSError as error:  # gone while we looked
            refused.append(f"{shown}: could not be read ({printable(error.strerror)}) (refused)")
            continue
        if stat.S_ISDIR(info.st_mode) and not path.is_symlink():
            continue
        problem = name_problem(name)
        if stat.S_ISLNK(info.st_mode):
            refused.append(f"{shown}: a symbolic link (refused, not followed)")
        elif not stat.S_ISREG(info.st_mode):
            refused.append(f"{shown}: not a regular file (refused)")
        elif problem:
            refused.append(f"{shown}: a file whose name {problem} (refused)")
        elif info.st_nlink > 1:
            refused.append(f"{shown}: a hard link to another file (refused)")
        elif any(parent.is_symlink() for parent in path.relative_to(folder).parents if str(parent) != "."):
            refused.append(f"{shown}: inside a linked folder (refused)")
        else:
            try:
                files[name] = path.read_bytes()
            except OSError as error:
                refused.append(f"{shown}: could not be read ({printable(error.strerror)}) (refused)")
    return files, refused


def bwrap_path() -> str | None:
    return shutil.which("bwrap")


_probe: dict = {}


def system_mounts(with_environment: bool = True) -> list[tuple[str, str]]:
    """The read-only base every sandbox needs: /usr (and /lib… where they are not links into
    /usr), and the Python installation when it lives elsewhere (pyenv, conda, a copy under
    /opt or /tmp); with ``with_environment``, also the grader's virtual environment (its
    packages). Each installation is bound at its real path and, when it is reached through a
    symbolic link (``/home`` → ``/var/home``), at the path Python knows it by as well, so that
    ``sys.executable`` and the environment's own paths resolve inside."""
    mounts: list[tuple[str, str]] = [("/usr", "/usr")]
    for name in ("/lib", "/lib64", "/lib32", "/bin", "/sbin"):
        if os.path.isdir(name) and not os.path.islink(name):
            mounts.append((name, name))
    for name in ("/etc/ld.so.cache", "/etc/localtime"):
        if os.path.exists(name):
            mounts.append((os.path.realpath(name), name))
    prefixes = [sys.base_prefix] + ([sys.prefix] if with_environment else [])
    for prefix in prefixes:
        real = os.path.realpath(prefix)
        for target in dict.fromkeys((real, os.path.abspath(prefix))):
            if not within(target, "/usr") and (real, target) not in mounts:
                mounts.append((real, target))
    return mounts


def site_packages_of_the_system() -> list[str]:
    """Package folders of the base Python and the distribution (hidden where only NumPy may be)."""
    import site

    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    base = os.path.realpath(sys.base_prefix)
    candidates = [os.path.join(base, "lib", version, "site-packages"),
                  "/usr/lib/python3/dist-packages", f"/usr/lib/{version}/site-packages",
                  f"/usr/local/lib/{version}/dist-packages", f"/usr/local/lib/{version}/site-packages"]
    try:  # where this Python's own site module looks in the base installation (Debian: dist-packages)
        candidates += site.getsitepackages([base])
    except (AttributeError, TypeError):  # pragma: no cover - a site module without it
        pass
    return [path for path in dict.fromkeys(candidates) if os.path.isdir(path)]


#: folders every sandbox gets fresh and empty (a size-limited tmpfs of its own), whatever the host
#: keeps there; a bind whose target lies inside one is applied after it (:func:`command`)
PRIVATE_FOLDERS = ("/tmp", "/dev/shm")


def within(path: str, folder: str) -> bool:
    """``path`` is ``folder`` or lies inside it (both absolute and normalised)."""
    return path == folder or path.startswith(folder.rstrip("/") + "/")


def _depth(path: str) -> int:
    return len([part for part in os.path.normpath(path).split("/") if part])


def _symlinks() -> list[tuple[str, list[str]]]:
    links = []
    for name in ("/lib", "/lib64", "/lib32", "/bin", "/sbin"):
        if os.path.islink(name):
            links.append((name, ["--symlink", os.readlink(name), name]))
    return links


def _bind(kind: str, source, target) -> tuple[str, list[str]]:
    """A bind as a mount operation; refused when it would cover a folder the sandbox makes itself
    (a Python environment that *is* ``/tmp``, say): the host's content would replace it."""
    target = os.path.normpath(str(target))
    covered = [own for own in ("/proc", "/dev", *PRIVATE_FOLDERS) if within(own, target)]
    if covered:
        raise SandboxUnavailable(
            f"cannot bind {source} at {target} in the grading sandbox: it would cover the sandbox's own "
            f"{covered[-1]} (move the kit or its Python environment into a folder of its own)")
    return target, [kind, str(source), target]


def command(argv: list[str], mounts: Mounts, limits: Limits, env: dict[str, str]) -> list[str]:
    """The ``bwrap`` command line that runs ``argv`` in a fresh sandbox.

    bubblewrap applies its mounts in the order given, and a mount hides whatever an earlier one
    put beneath its target; so the mounts are given parents first (by the depth of their
    target, in the order below among equals): a kit, an environment or a Python under ``/tmp``
    or ``/dev/shm`` is bound into the sandbox's private tmpfs once it is made (and only those
    folders are seen there), a masked package folder is hidden after the installation around
    it is bound. A bind that would cover a private folder (an environment *in* ``/tmp``)
    is refused."""
    bwrap = bwrap_path()
    if bwrap is None:
        raise SandboxUnavailable("bubblewrap (bwrap) is not installed. " + INSTALL_HINT)
    args = [bwrap, "--unshare-user", "--unshare-pid", "--unshare-net", "--unshare-ipc", "--unshare-uts",
            "--unshare-cgroup-try", "--disable-userns", "--uid", str(SANDBOX_UID), "--gid", str(SANDBOX_UID),
            "--hostname", "sandbox", "--die-with-parent", "--new-session", "--cap-drop", "ALL"]
    operations: list[tuple[str, list[str]]] = []  # (target, arguments)
    seen = set()
    for source, target in system_mounts(mounts.with_environment) + list(mounts.read_only):
        operation = _bind("--ro-bind", source, target)
        if operation[0] in seen:
            continue
        seen.add(operation[0])
        operations.append(operation)
    operations += _symlinks()
    for path in mounts.masked:
        operations.append((os.path.normpath(str(path)), ["--tmpfs", str(path)]))
    operations += [("/proc", ["--proc", "/proc"]), ("/dev", ["--dev", "/dev"]),
                   ("/tmp", ["--size", str(limits.tmpfs_mb * 1024 * 1024), "--tmpfs", "/tmp"]),
                   ("/dev/shm", ["--size", str(64 * 1024 * 1024), "--tmpfs", "/dev/shm"])]
    for source, target in mounts.read_only_in_tmp:
        if not str(target).startswith("/tmp/"):
            raise ValueError(f"read_only_in_tmp targets must lie in /tmp, got {target!r}")
        operations.append(_bind("--ro-bind", source, target))
    for source, target in mounts.writable:
        operations.append(_bind("--bind", source, target))
    for _, arguments in sorted(operations, key=lambda operation: _depth(operation[0])):  # stable: parents first
        args += arguments
    args += ["--chdir", mounts.chdir, "--clearenv"]
    for key, value in sorted(env.items()):
        args += ["--setenv", key, value]
    return args + ["--", *argv]


class _ControlGroup:
    """A ``pids`` (and ``memory``) control group for one sandbox, where the grader may make one
    (root on cgroup v1, or a v2 hierarchy whose own group delegates ``pids``)."""

    def __init__(self, limits: Limits, enabled: bool = True):
        self.paths: list[Path] = []
        if not enabled or not hasattr(os, "geteuid") or os.geteuid() != 0:
            return
        name = f"cvkit-{uuid.uuid4().hex[:12]}"
        try:
            own: dict[str, str] = {}  # controller -> this process's cgroup
            for line in Path("/proc/self/cgroup").read_text().splitlines():
                _, controllers, group = line.split(":", 2)
                for controller in controllers.split(",") if controllers else ["unified"]:
                    own[controller] = group
            root = Path("/sys/fs/cgroup")
            if (root / "pids" / "cgroup.procs").exists() or (root / "pids").is_dir():  # v1
                for controller, files in (("pids", {"pids.max": str(limits.processes)}),
                                          ("memory", {"memory.limit_in_bytes": str(limits.total_memory_mb << 20)})):
                    base = root / controller / own.get(controller, "/").lstrip("/")
                    if not base.is_dir():
                        continue
                    path = base / name
                    path.mkdir()
                    self.paths.append(path)
                    for key, value in files.items():
                        (path / key).write_text(value)
            elif "pids" in (root / own.get("unified", "/").lstrip("/") / "cgroup.subtree_control").read_text():
                path = root / own.get("unified", "/").lstrip("/") / name
                path.mkdir()
                self.paths.append(path)
                (path / "pids.max").write_text(str(limits.processes))
                if (path / "memory.max").exists():
                    (path / "memory.max").write_text(str(limits.total_memory_mb << 20))
        except (OSError, ValueError):
            self.remove()
            self.paths = []

    @property
    def active(self) -> bool:
        return bool(self.paths)

    def join(self) -> None:  # in the child, between fork and exec
        for path in self.paths:
            (path / "cgroup.procs").write_text("0")

    def remove(self) -> None:
        for path in self.paths:
            for _ in range(50):
                try:
                    pids = (path / "cgroup.procs").read_text().split()
                except OSError:
                    break
                for pid in pids:
                    try:
                        os.kill(int(pid), signal.SIGKILL)
                    except (ProcessLookupError, ValueError, PermissionError):
                        pass
                try:
                    path.rmdir()
                    break
                except OSError:
                    import time

                    time.sleep(0.02)


_fallback: dict = {}


def limits_fallback() -> str | None:
    """None where each sandbox gets its control group (``pids``, and ``memory`` where
    available); else, in words, the documented fallback in force — for the run's summary, so
    that a weaker limit is never silent."""
    if "note" not in _fallback:
        group = _ControlGroup(Limits())
        active = group.active
        group.remove()
        _fallback["note"] = None if active else (
            "no control group per sandbox (they need root and a delegated cgroup hierarchy): processes are "
            "limited by RLIMIT_NPROC inside each sandbox's user namespace, memory by each process's address-space "
            "limit")
    return _fallback["note"]


def _preexec(limits: Limits, group: _ControlGroup):
    def limit() -> None:
        import resource

        os.setpgrp()
        group.join()
        for which, value in ((resource.RLIMIT_AS, limits.memory_mb << 20), (resource.RLIMIT_CPU, limits.cpu_seconds),
                             (resource.RLIMIT_FSIZE, limits.file_mb << 20), (resource.RLIMIT_CORE, 0),
                             (resource.RLIMIT_NOFILE, limits.open_files)):
            resource.setrlimit(which, (value, value))
    return limit


class Sandbox:
    """One running sandbox (a :class:`subprocess.Popen` with its control group)."""

    def __init__(self, argv: list[str], *, mounts: Mounts | None = None, limits: Limits | None = None,
                 env: dict[str, str] | None = None, sandboxed: bool = True, **popen):
        self.limits = limits or Limits()
        self.mounts = mounts or Mounts()
        env = dict(env or {})
        env.setdefault("PATH", "/usr/bin:/bin")
        env.setdefault("HOME", "/tmp")
        env.setdefault("TMPDIR", "/tmp")
        env["CVKIT_SANDBOX_NPROC"] = str(self.limits.processes)
        self.sandboxed = sandboxed
        self._scratch = None
        if sandboxed:
            cwd, full, outer_env = "/", command(argv, self.mounts, self.limits, env), {"PATH": "/usr/bin:/bin"}
        else:  # --no-sandbox: the same program with the resource limits only, in a scratch folder
            self._scratch = tempfile.mkdtemp(prefix="cvkit-nosandbox-")
            cwd = next((source for source, target in self.mounts.writable if target == self.mounts.chdir), self._scratch)
            env.update(HOME=self._scratch, TMPDIR=self._scratch)
            full, outer_env = argv, env
        self.group = _ControlGroup(self.limits, enabled=sandboxed)  # once the command line is made
        try:
            self.process = subprocess.Popen(full, cwd=cwd, env=outer_env, preexec_fn=_preexec(self.limits, self.group),
                                            **popen)
        except BaseException:
            self.group.remove()
            raise

    @property
    def pid(self) -> int:
        return self.process.pid

    def kill(self) -> None:
        """Stop the sandbox and everything in it (the PID namespace ends with its init)."""
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        try:
            self.process.kill()
        except ProcessLookupError:
            pass

    def wait(self, timeout: float | None = None) -> int:
        return self.process.wait(timeout)

    def close(self) -> None:
        """Kill what is left, reap, remove the control group and the scratch folder."""
        if self.process.poll() is None:
            self.kill()
        try:
            self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:  # pragma: no cover
            pass
        self.group.remove()
        if self._scratch:
            shutil.rmtree(self._scratch, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def probe(force: bool = False) -> str | None:
    """None when a sandbox can be made here, else the reason (cached per process)."""
    if "result" in _probe and not force:
        return _probe["result"]
    reason = None
    if sys.platform != "linux":
        reason = f"the grading sandbox needs Linux (this is {sys.platform}). " + INSTALL_HINT
    elif bwrap_path() is None:
        reason = "bubblewrap (bwrap) is not installed. " + INSTALL_HINT
    else:
        python = os.path.realpath(sys.executable)
        try:
            with Sandbox([python, "-I", "-S", "-c", "import os; print(os.getuid())"], limits=Limits(),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE) as box:
                out, err = box.process.communicate(timeout=60)
            if box.process.returncode != 0 or out.decode().strip() != str(SANDBOX_UID):
                reason = ("bubblewrap cannot create a sandbox here: "
                          + (err.decode(errors="replace").strip()[-300:] or f"exit status {box.process.returncode}")
                          + ". " + INSTALL_HINT)
        except SandboxUnavailable as exc:  # where this Python lives cannot be bound (it says why)
            reason = str(exc)
        except (OSError, subprocess.SubprocessError) as exc:
            reason = f"bubblewrap cannot create a sandbox here ({exc}). " + INSTALL_HINT
    _probe["result"] = reason
    return reason


def require() -> None:
    """Raise :class:`SandboxUnavailable` (with how to fix it) unless a sandbox can be made."""
    reason = probe()
    if reason:
        raise SandboxUnavailable(reason)


def sandbox_disabled() -> bool:
    """The instructor chose ``--no-sandbox`` (inherited by grading workers as an environment variable)."""
    return os.environ.get("CVKIT_NO_SANDBOX") == "1"
