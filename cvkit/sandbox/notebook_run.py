"""Execution of a student's notebook for autograding, in a disposable process.

The parallel phase of ``cvkit course grade`` runs every submitted notebook once, so that the
feedback shows the student's own figures and printed results. Grades are *not* decided by this
run (test cells are no-ops in the kernel, ``CVKIT_TRUSTED_GRADING=1``); they are decided
afterwards by the trusted checks (:mod:`cvkit.course.trusted`).

The steps mirror nbgrader's autograde, with nbgrader's own settings:

1. :func:`cvkit.course.notebook.prepare` (the course's worker, outside the box) — nbgrader's
   *sanitizing* steps: the source of every locked or test cell is put back from the release
   notebook (matched by grade id, as nbgrader's ``OverwriteCells`` does), outputs are cleared
   and the kernel is the release's.
2. ``python -I -m cvkit.sandbox.notebook_run IN OUT``, started by :func:`execute_in_sandbox` inside
   the grading sandbox (:mod:`cvkit.sandbox.isolation`) — the notebook is executed with :mod:`nbclient` as nbgrader's ``Execute`` preprocessor does:
   errors are recorded and execution goes on, a cell that exceeds its time limit is
   interrupted and gets a ``CellTimeoutError``.

Running this small program instead of a whole ``nbgrader autograde`` per submission saves
nbgrader's start-up and database work (about 4 s per notebook); nbgrader itself still records
every grade, in one batched run (:meth:`cvkit.course.Course.record_many`).
"""
from __future__ import annotations

import json
import os
import sys

from .startup import skip_unused_schema_grammars

skip_unused_schema_grammars()  # 1.4 s of CPU per notebook's run (see cvkit.sandbox.startup)

CELL_TIMEOUT_VARIABLE = "CVKIT_CELL_TIMEOUT"
DEFAULT_CELL_TIMEOUT = 180
TIMEOUT_ERROR = {
    "ename": "CellTimeoutError",
    "evalue": "",
    "traceback": ["\x1b[0;31mCellTimeoutError\x1b[0m: No reply from kernel before timeout"],
}


#: the environment of a notebook's run inside the sandbox (``PATH`` is added per run)
SANDBOX_ENV = {"HOME": "/tmp", "TMPDIR": "/tmp", "JUPYTER_RUNTIME_DIR": "/tmp/.jupyter", "IPYTHONDIR": "/tmp/.ipython",
               "MPLCONFIGDIR": "/tmp/.mpl", "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
               "MKL_NUM_THREADS": "1", "PYTHONDONTWRITEBYTECODE": "1", "LANG": "C.UTF-8"}
#: the grading run's IPython kernel: no history file, and inline figures written with zlib
#: level 3 instead of 6 (the same pixels, about 30 ms less per figure: 0.6 s of ch03's run)
PYTHON_KERNEL_ARGUMENTS = [
    "--HistoryManager.hist_file=:memory:",
    "--InlineBackend.print_figure_kwargs={'bbox_inches': 'tight', 'pil_kwargs': {'compress_level': 3}}",
]

EXECUTION_MEMORY_MB = 6144      # address space of each process of the executing sandbox
EXECUTION_WALL_SECONDS = 900    # a whole notebook, kept outside; a cell has CVKIT_CELL_TIMEOUT (180 s)
EXECUTED_MAX_BYTES = 64 << 20   # an executed notebook larger than this is not read back


def execute_in_sandbox(files: dict, name: str, wall_seconds: float = EXECUTION_WALL_SECONDS) -> tuple[str | None, str]:
    r"""Execute the notebook ``files[name]`` (already :func:`prepare`\ d) in the grading sandbox
    (:mod:`cvkit.sandbox.isolation`): a writable copy of ``files`` (this one submission), the
    Python environment and cvkit read-only, a private ``/tmp``, no network, limits on memory,
    CPU, processes and file size, and ``wall_seconds`` for the whole notebook, kept from here.
    Returns the executed notebook's JSON text (``None`` if it could not run to the end) and a
    short log. The run gives the student's own outputs; no grade depends on it."""
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from . import isolation

    sandboxed = not isolation.sandbox_disabled()
    package = str(Path(__file__).resolve().parent.parent)
    # cvkit as Python found it (a path through a symbolic link, say), and its real folder
    known_as = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with tempfile.TemporaryDirectory(prefix="cvkit-execute-") as scratch:
        folder = Path(scratch) / "submission"
        folder.mkdir()
        for relative, data in files.items():
            target = folder / relative
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data if isinstance(data, bytes) else str(data).encode())
        env = dict(SANDBOX_ENV, PATH=str(Path(sys.executable).parent) + ":/usr/bin:/bin")
        if os.environ.get(CELL_TIMEOUT_VARIABLE):
            env[CELL_TIMEOUT_VARIABLE] = os.environ[CELL_TIMEOUT_VARIABLE]
        inside = "/submission" if sandboxed else str(folder)
        read_only = [(package, target) for target in dict.fromkeys((package, known_as))]
        mounts = isolation.Mounts(read_only=read_only, writable=[(str(folder), inside)], chdir=inside)
        try:
            fonts = matplotlib_font_list() if sandboxed else None
        except Exception:  # noqa: BLE001 - the list only saves time: never a reason not to run a notebook
            fonts = None
        if fonts is not None:
            mounts.read_only_in_tmp.append((fonts[0], f"{SANDBOX_ENV['MPLCONFIGDIR']}/{fonts[1]}"))
        limits = isolation.Limits(memory_mb=EXECUTION_MEMORY_MB, cpu_seconds=int(wall_seconds), processes=64,
                                  file_mb=64, tmpfs_mb=512)
        output = "executed.cvkit-output.ipynb"
        with tempfile.TemporaryFile() as console:
            box = isolation.Sandbox([sys.executable, "-I", "-m", "cvkit.sandbox.notebook_run", name, output],
                                    mounts=mounts, limits=limits, env=env, sandboxed=sandboxed,
                                    stdin=subprocess.DEVNULL, stdout=console, stderr=subprocess.STDOUT)
            try:
                status = box.wait(timeout=wall_seconds)
            except subprocess.TimeoutExpired:
                status = None
            finally:
                box.close()  # every process the notebook started ends here
            console.seek(0, 2)
            console.seek(max(0, console.tell() - 2000))
            log = console.read().decode("utf-8", "replace")
        if status is None:
            return None, log + f"\nexecution exceeded {wall_seconds:g} s and was stopped"
        result = folder / output
        # everything in the sandbox is dead now: no race between this check and the read
        if status != 0 or result.is_symlink() or not result.is_file():
            return None, log + f"\nthe notebook could not run to the end (exit status {status})"
        if result.stat().st_size > EXECUTED_MAX_BYTES:
            return None, log + "\nthe executed notebook is larger than 64 MB (printed too much)"
        return result.read_text(errors="replace"), log


_font_lists: dict = {}


def matplotlib_font_list() -> tuple[str, str] | None:
    """``(host path, file name)`` of matplotlib's font list as the sandbox sees it, or None
    (matplotlib not installed, or the list could not be made).

    Without it, the first figure of every notebook makes matplotlib rebuild its font list
    inside the sandbox (about 0.25 s a notebook), and fontconfig prints "Cannot load default
    config file" into the student's outputs (the sandbox has no ``/etc/fonts``). The list is
    made once by matplotlib itself, in a sandbox that runs no student code, kept in the
    user's cache folder under a key of the matplotlib version, the Python environment and
    the system's font files, and bound read-only into each execution's ``MPLCONFIGDIR``
    (:attr:`cvkit.sandbox.isolation.Mounts.read_only_in_tmp`), so a notebook cannot change
    it for the next one."""
    import hashlib
    import importlib.metadata
    import subprocess
    import tempfile
    from pathlib import Path

    from . import isolation

    try:
        version = importlib.metadata.version("matplotlib")
    except importlib.metadata.PackageNotFoundError:
        return None
    fonts = sorted((str(path), path.stat().st_size) for path in Path("/usr/share/fonts").rglob("*") if path.is_file())
    key = hashlib.sha256(repr((version, sys.prefix, sys.base_prefix, fonts)).encode()).hexdigest()[:16]
    if key in _font_lists:
        return _font_lists[key]
    found = None
    try:
        cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "cvkit" / f"matplotlib-{key}"
        made = sorted(cache.glob("fontlist-*.json")) if cache.is_dir() else []
        if not made:
            cache.parent.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=cache.parent, prefix=".building-") as building:
                os.chmod(building, 0o777)  # the sandbox's unprivileged user writes the list here
                box = isolation.Sandbox(
                    [sys.executable, "-I", "-c", "import matplotlib.font_manager"],
                    mounts=isolation.Mounts(writable=[(building, SANDBOX_ENV["MPLCONFIGDIR"])]),
                    limits=isolation.Limits(memory_mb=2048, cpu_seconds=120, processes=16, file_mb=16),
                    env=dict(SANDBOX_ENV), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                try:
                    status = box.wait(timeout=120)
                except subprocess.TimeoutExpired:
                    status = None
                finally:
                    box.close()
                lists = sorted(Path(building).glob("fontlist-*.json"))
                if status == 0 and len(lists) == 1 and not lists[0].is_symlink():
                    json.loads(lists[0].read_text())  # a whole JSON file, or nothing is kept
                    staged = Path(building) / "staged"
                    staged.mkdir()
                    os.replace(lists[0], staged / lists[0].name)
                    os.chmod(staged / lists[0].name, 0o644)
                    os.chmod(staged, 0o755)
                    try:
                        os.replace(staged, cache)  # atomic: another worker may have made it first
                    except OSError:
                        pass
            made = sorted(cache.glob("fontlist-*.json"))
        if len(made) == 1:
            found = (str(made[0]), made[0].name)
    except (OSError, ValueError, RuntimeError, isolation.SandboxUnavailable):  # no home, no sandbox: no list
        found = None
    _font_lists[key] = found
    return found


def execute(notebook: dict, folder: str, timeout: int | None = None) -> dict:
    """Run ``notebook`` (a dict, or the ``NotebookNode`` nbformat read) in a fresh kernel with
    working directory ``folder``."""
    import nbformat
    from nbclient import NotebookClient

    from .kernel import KernelManager

    nb = notebook if isinstance(notebook, nbformat.NotebookNode) else \
        nbformat.reads(json.dumps(notebook), as_version=4)  # joins multi-line sources
    timeout = int(os.environ.get(CELL_TIMEOUT_VARIABLE, DEFAULT_CELL_TIMEOUT)) if timeout is None else timeout
    kernel = (nb.metadata.get("kernelspec") or {}).get("name") or "python3"
    client = NotebookClient(
        nb, timeout=timeout, kernel_name=kernel, allow_errors=True, interrupt_on_timeout=True,
        raise_on_iopub_timeout=True, error_on_timeout=TIMEOUT_ERROR, record_timing=False,
        shutdown_kernel="immediate",  # every output is in; a graceful shutdown only waits (~0.2 s)
        extra_arguments=PYTHON_KERNEL_ARGUMENTS if kernel.startswith("python") else [],
        resources={"metadata": {"path": folder}}, kernel_manager_class=KernelManager,
    )
    client.execute()
    return json.loads(nbformat.writes(nb))


MAX_TEXT = 100_000        # characters of one text output kept for the feedback
MAX_OUTPUTS_BYTES = 16 << 20   # all outputs of a notebook
MAX_ERROR_TEXT = 2000     # characters of an error's message, and of each of its traceback lines
MAX_TRACEBACK_LINES = 40  # lines of an error's traceback kept (the last ones: where it was raised)


def _cut(text: str, limit: int) -> str:
    return text if len(text) <= limit else text[:limit] + f" [… {len(text) - limit} characters cut by the grader]"


def _bounded_error(output: dict) -> None:
    """An error output with its message and traceback capped (a 64 KB message raised in every
    cell must not make a 36 MB notebook and a 15 MB feedback page)."""
    output["ename"] = _cut(str(output.get("ename", "")), 200)
    output["evalue"] = _cut(str(output.get("evalue", "")), MAX_ERROR_TEXT)
    lines = output.get("traceback") or []
    lines = [_cut(str(line), MAX_ERROR_TEXT) for line in (lines if isinstance(lines, list) else [lines])]
    if len(lines) > MAX_TRACEBACK_LINES:
        lines = [f"[… {len(lines) - MAX_TRACEBACK_LINES} traceback lines cut by the grader]"] + lines[-MAX_TRACEBACK_LINES:]
    output["traceback"] = lines


def bounded(notebook: dict) -> dict:
    """The executed notebook with floods cut: long text outputs keep their start and end, and
    outputs beyond the notebook's budget are replaced by a note (a 1.5 GB print must not
    reach the grader)."""
    budget = MAX_OUTPUTS_BYTES
    for cell in notebook.get("cells", []):
        kept = []
        for output in cell.get("outputs", []) or []:
            if output.get("output_type") == "error":
                _bounded_error(output)
            text = output.get("text")
            if isinstance(text, list):
                text = "".join(text)
            if isinstance(text, str) and len(text) > MAX_TEXT:
                output["text"] = (text[: MAX_TEXT // 2] + f"\n... [{len(text) - MAX_TEXT} characters cut by the grader] ...\n"
                                  + text[-MAX_TEXT // 2:])
            size = len(json.dumps(output))
            if size > budget:
                kept.append({"output_type": "stream", "name": "stdout",
                             "text": "[output removed by the grader: the notebook's outputs exceed 16 MB]\n"})
                continue
            budget -= size
            kept.append(output)
        if "outputs" in cell:
            cell["outputs"] = kept
    return notebook


def private_memory() -> bool:
    """Make this process's memory closed to the other processes of its user (Linux
    ``prctl(PR_SET_DUMPABLE, 0)``): the student's kernel, a child of this driver running as the
    same sandbox user, can then neither open ``/proc/<driver>/mem`` nor attach to it. The
    kernel's own process is not affected (an ``exec`` makes a process dumpable again). Returns
    whether it took effect."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(4, 0, 0, 0, 0) == 0  # 4 = PR_SET_DUMPABLE
    except (OSError, AttributeError):
        return False


def main(argv: list[str] | None = None) -> int:  # pragma: no cover - runs in the disposable process
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print("usage: python -m cvkit.sandbox.notebook_run IN.ipynb OUT.ipynb", file=sys.stderr)
        return 2
    source, target = argv
    processes = int(os.environ.get("CVKIT_SANDBOX_NPROC", "0") or 0)
    if processes:  # inside the sandbox's user namespace: counts this sandbox's processes only
        import resource

        resource.setrlimit(resource.RLIMIT_NPROC, (processes, processes))
    os.environ["CVKIT_TRUSTED_GRADING"] = "1"  # the kernel's check() calls are no-ops
    private_memory()
    import nbformat

    with open(source, encoding="utf-8") as handle:  # the one read of the notebook in the sandbox
        notebook = nbformat.read(handle, as_version=4)
    executed = bounded(execute(notebook, os.path.dirname(os.path.abspath(source))))
    with open(target, "w", encoding="utf-8") as handle:
        json.dump(executed, handle, indent=1)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
