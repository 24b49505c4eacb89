"""Computes the building blocks a sandboxed exercise may use, outside the sandbox.

When a student's ``correlate`` calls ``cvkit.filters.pad`` (allowed in that exercise), the
sandbox holds no reference code: its stand-in sends the arguments out, and the trusted side
asks this small server — a separate process with its own memory and CPU limits, so that
arguments chosen by a student (a 10⁹-pixel pad) cannot exhaust the grader — for the value.
The trusted side alone decides which ids may be served; this program only computes.

Protocol: JSON lines on stdin ``{"id": "filters.pad", "args": ..., "kwargs": ...}`` (values in
:mod:`cvkit.grading.runtime.wire` encoding) → JSON lines on stdout ``{"value": ...}`` or
``{"error": "..."}``.
"""
from __future__ import annotations

import json
import subprocess
import sys
import threading

from ..grading.runtime import wire
from ..grading.served import DATA_LOADERS

MEMORY_MB = 4096
CPU_SECONDS = 3600


def _function(identifier: str):
    module, _, name = identifier.partition(".")
    if module == "data":
        if name not in DATA_LOADERS:
            raise KeyError(identifier)
        from .. import data

        return getattr(data, name)
    from .. import registry

    return registry.get(identifier).reference


def serve() -> None:  # pragma: no cover - runs in the server process
    out = sys.stdout
    for line in sys.stdin:
        try:
            request = json.loads(line)
            function = _function(str(request["id"]))
            value = function(*wire.decode(request["args"]), **wire.decode(request["kwargs"]))
            reply = {"value": wire.encode(value)}
        except MemoryError:
            reply = {"error": "ran out of memory on these arguments"}
        except Exception as exc:  # noqa: BLE001 - reported to the student's code as an error
            reply = {"error": f"{type(exc).__name__}: {str(exc)[:300]}"}
        out.write(json.dumps(reply) + "\n")
        out.flush()


class ReferenceServer:
    """One server process per grading process, started at first use and restarted when a call
    kills it or runs out of time."""

    _instance: "ReferenceServer | None" = None
    _lock = threading.Lock()

    def __init__(self) -> None:
        self.process: subprocess.Popen | None = None

    @classmethod
    def shared(cls) -> "ReferenceServer":
        with cls._lock:
            if cls._instance is None:
                cls._instance = cls()
            return cls._instance

    def _start(self) -> subprocess.Popen:
        def limits() -> None:  # pragma: no cover - runs in the child
            import resource

            resource.setrlimit(resource.RLIMIT_AS, (MEMORY_MB << 20, MEMORY_MB << 20))
            resource.setrlimit(resource.RLIMIT_CPU, (CPU_SECONDS, CPU_SECONDS))
            resource.setrlimit(resource.RLIMIT_CORE, (0, 0))

        import os

        env = {k: v for k, v in os.environ.items() if not k.startswith("CVKIT_")}
        env.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1", MPLBACKEND="Agg")
        return subprocess.Popen([sys.executable, "-I", "-m", "cvkit.sandbox.reference_server"],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                preexec_fn=limits, env=env, cwd="/")

    def stop(self) -> None:
        if self.process is not None:
            try:
                self.process.kill()
                self.process.wait(timeout=10)
            except Exception:  # pragma: no cover
                pass
            self.process = None

    def call(self, identifier: str, args, kwargs, timeout: float) -> dict:
        """``{"value": encoded}`` or ``{"error": text}``; never raises for the student's arguments."""
        if self.process is None or self.process.poll() is not None:
            self.process = self._start()
        process = self.process
        request = json.dumps({"id": identifier, "args": args, "kwargs": kwargs}) + "\n"
        box: list = []

        def exchange():
            try:
                process.stdin.write(request.encode())
                process.stdin.flush()
                box.append(process.stdout.readline(4 * wire.MAX_BYTES))
            except (OSError, ValueError):
                box.append(b"")

        thread = threading.Thread(target=exchange, daemon=True)
        thread.start()
        thread.join(max(0.1, timeout))
        if thread.is_alive() or not box or not box[0].endswith(b"\n"):
            self.stop()
            return {"error": "the grader stopped computing it (too slow, too large, or it crashed on these arguments)"}
        try:
            reply = json.loads(box[0])
        except ValueError:
            self.stop()
            return {"error": "the grader could not compute it"}
        return reply if isinstance(reply, dict) else {"error": "the grader could not compute it"}


if __name__ == "__main__":  # pragma: no cover
    serve()
