"""Shared scaffolding of the chapter benchmarks (``bench_chNN.py``): timing, the machine line,
command-line options, results tables and target verdicts.

Each benchmark imports it after putting the checkout on ``sys.path``::

    HERE = Path(__file__).resolve().parent
    sys.path[:0] = [str(HERE.parent), str(HERE)]  # cvkit and _timing from this checkout
    from _timing import ...

Timing convention (quoted in the README): one warm-up call, then the *median* of ``repeats``
calls, in milliseconds.
"""
from __future__ import annotations

import argparse
import importlib
import os
import platform
import statistics
import time
from dataclasses import dataclass
from types import ModuleType
from typing import Any, Callable, Iterable, Sequence

__all__ = [
    "BenchmarkParser", "Column", "Measurement", "Row", "Targets", "comparison_table", "limit_checks",
    "machine_line", "measure", "optional_import", "print_table", "timeit",
]

NOISY = "timings are noisy on a loaded machine: rerun to confirm"


# -- timing -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Measurement:
    """Median wall and CPU time (ms) of the timed calls, and the result of the last call."""

    ms: float
    cpu_ms: float
    result: Any


def measure(fn: Callable[[], Any], repeats: int) -> Measurement:
    """Call ``fn`` once to warm up, then ``repeats`` times; the medians of wall-clock time and of
    this process's CPU time (on a loaded machine wall time exceeds CPU time)."""
    result = fn()
    wall, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = fn()
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return Measurement(1e3 * statistics.median(wall), 1e3 * statistics.median(cpu), result)


def timeit(fn: Callable[[], Any], repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``fn``, in ms, after one warm-up call."""
    return measure(fn, repeats).ms


# -- environment and options ---------------------------------------------------------------------

def optional_import(name: str) -> ModuleType | None:
    """The module ``name``, or None when it is not installed (OpenCV is a test-only dependency)."""
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


_LABELS = {"skimage": "scikit-image", "sklearn": "scikit-learn"}


def machine_line(*libraries: ModuleType, opencv: ModuleType | None = None) -> str:
    """``machine: CPUs, processor, Python, numpy, <libraries>, opencv, load average`` — what a
    reader needs to judge the timings (OpenCV uses all its threads, cvkit/NumPy one)."""
    import numpy as np

    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    numpy = f"numpy {np.__version__}"
    if "OPENBLAS_NUM_THREADS" in os.environ:
        numpy += f" (OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']})"
    parts = [f"CPUs {os.cpu_count()} (usable {usable})", platform.processor() or platform.machine(),
             f"Python {platform.python_version()}", numpy]
    parts += [f"{_LABELS.get(m.__name__, m.__name__)} {m.__version__}" for m in libraries]
    parts.append(f"opencv {opencv.__version__} ({opencv.getNumThreads()} threads)" if opencv is not None
                 else "opencv not installed")
    try:
        parts.append(f"load average {os.getloadavg()[0]:.1f}")
    except (AttributeError, OSError):
        pass
    return "machine: " + ", ".join(parts)


class BenchmarkParser(argparse.ArgumentParser):
    """The options every chapter benchmark takes: ``--quick``, ``--repeats N`` and ``--check``.

    ``parse_args`` resolves ``args.repeats``: the value given, else ``quick_repeats`` with
    ``--quick``, else ``repeats``. Add a benchmark's own options with ``add_argument``.
    """

    def __init__(self, doc: str, *, repeats: int, quick_repeats: int, quick_help: str | None = None):
        super().__init__(description=doc.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
        self.default_repeats, self.quick_repeats = repeats, quick_repeats
        self.add_argument("--quick", action="store_true", help=quick_help or f"{quick_repeats} repeats")
        self.add_argument("--repeats", type=int, default=None,
                          help=f"timing repeats (default {repeats}, or {quick_repeats} with --quick)")
        self.add_argument("--check", action="store_true", help="exit with status 1 if a target is missed")

    def parse_args(self, args=None, namespace=None):  # type: ignore[override]
        parsed = super().parse_args(args, namespace)
        parsed.repeats = parsed.repeats or (self.quick_repeats if parsed.quick else self.default_repeats)
        return parsed


# -- tables ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Column:
    """A table column: its title and alignment (``"<"`` text, ``">"`` numbers)."""

    title: str
    align: str = "<"


def print_table(columns: Sequence[Column], rows: Iterable[Sequence[str]]) -> None:
    """Print a header, a rule and the rows (already formatted cells), each column as wide as
    its widest cell."""
    rows = [list(row) for row in rows]
    widths = [max([len(c.title)] + [len(row[i]) for row in rows]) for i, c in enumerate(columns)]

    def line(cells):
        return "  ".join(f"{cell:{c.align}{w}}" for cell, c, w in zip(cells, columns, widths)).rstrip()

    header = line([c.title for c in columns])
    print(header)
    print("-" * (sum(widths) + 2 * (len(widths) - 1)))
    for row in rows:
        print(line(row))


@dataclass
class Row:
    """One timing comparison: cvkit against a peer.

    ``target`` is the largest allowed ratio cvkit / peer (strictly smaller with ``strict``), or,
    when ``peer_ms`` is None, the largest allowed time of cvkit in ms; None = informative.
    """

    operation: str
    ours_ms: float
    peer: str
    peer_ms: float | None
    target: float | None
    strict: bool = False
    note: str = ""

    @property
    def ratio(self) -> float | None:
        return None if self.peer_ms is None else self.ours_ms / self.peer_ms

    @property
    def verdict(self) -> str:
        """``info`` (no target), ``ok`` or ``MISSED``."""
        if self.target is None:
            return "info"
        value = self.ours_ms if self.peer_ms is None else self.ratio
        ok = value < self.target if self.strict else value <= self.target
        return "ok" if ok else "MISSED"

    def target_text(self) -> str:
        if self.target is None:
            return "informative"
        unit = " ms" if self.peer_ms is None else "x"
        return f"{'<' if self.strict else '<='} {self.target:g}{unit}"

    def miss_text(self) -> str:
        """What was measured against the target, for the summary of missed targets."""
        value = f"{self.ours_ms:.1f} ms" if self.ratio is None else f"{self.ratio:.2f}x"
        return f"{self.operation}: {value} (target {self.target_text()})"


def comparison_table(rows: Sequence[Row], *, digits: int = 1, peer: str = "peer", peer_ms: str = "peer ms") -> None:
    """Print the timing rows: operation, cvkit ms, peer, peer ms, ratio, target, verdict (and a
    note column when a row has a note); ``digits`` decimals for the milliseconds."""
    columns = [Column("operation"), Column("cvkit ms", ">"), Column(peer), Column(peer_ms, ">"),
               Column("ratio", ">"), Column("target"), Column("")]
    notes = any(row.note for row in rows)
    if notes:
        columns.append(Column("note"))
    cells = []
    for row in rows:
        cells.append([row.operation, f"{row.ours_ms:.{digits}f}", row.peer,
                      "" if row.peer_ms is None else f"{row.peer_ms:.{digits}f}",
                      "" if row.ratio is None else f"{row.ratio:.2f}x", row.target_text(), row.verdict]
                     + ([row.note] if notes else []))
    print_table(columns, cells)


# -- targets --------------------------------------------------------------------------------------

class Targets:
    """The targets of one run: each check gives a verdict, the missed ones decide the exit status."""

    def __init__(self) -> None:
        self.missed: list[str] = []

    def check(self, name: str, ok: bool) -> str:
        """``ok``, or ``MISSED`` (and ``name`` is remembered)."""
        if not ok:
            self.missed.append(name)
        return "ok" if ok else "MISSED"

    def check_rows(self, rows: Iterable[Row]) -> None:
        """Remember every timing row whose verdict is ``MISSED``."""
        self.missed += [row.miss_text() for row in rows if row.verdict == "MISSED"]

    def finish(self, check: bool) -> int:
        """Print the missed targets, if any; the exit status: 1 if one was missed and ``check``."""
        if self.missed:
            print(f"\n{len(self.missed)} target(s) missed: {'; '.join(self.missed)} ({NOISY})")
        return 1 if (self.missed and check) else 0


def limit_checks(checks: Iterable[tuple[str, float, float | None]], targets: Targets, fmt: str = ".3g") -> None:
    """Print one line per ``(what, measured, limit)``: the measured value must be <= limit
    (None: printed for information only)."""
    checks = list(checks)
    width = max(len(what) for what, _, _ in checks)
    for what, value, limit in checks:
        line = f"  {what:<{width}} {value:>9{fmt}}"
        if limit is not None:
            line += f"  <= {limit:g}  {targets.check(what, value <= limit)}"
        print(line)

