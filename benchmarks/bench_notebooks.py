"""How long each chapter notebook takes to execute with its solutions (what autograding costs per
student and chapter, before the trusted checks), and its released version under *Run All*.

    python benchmarks/bench_notebooks.py [--chapters ch03_filtering,ch12_training] [--check]

Each notebook runs in a fresh kernel (nbclient) from the lecture folder, as
``tests/lectures/test_notebooks.py`` runs it; the release is made with nbgrader's own preprocessors as in
``tests/lectures/test_release.py``. Goal: every chapter well under a minute (``--check`` exits 1 when one
takes 60 s or more). Timings are noisy on a loaded machine: rerun to confirm.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "lectures")]

GOAL_SECONDS = 60.0


def run(nb, folder: Path) -> float:
    from nbclient import NotebookClient

    client = NotebookClient(nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(folder)}})
    start = time.perf_counter()
    client.execute()
    return time.perf_counter() - start


def main() -> int:
    import nbformat

    import lecture_release

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--chapters", default="", help="comma-separated chapter folders (default: all)")
    parser.add_argument("--check", action="store_true", help=f"exit 1 if a chapter takes {GOAL_SECONDS:.0f} s or more")
    args = parser.parse_args()
    os.environ.setdefault("MPLBACKEND", "Agg")
    os.environ.setdefault("CVKIT_GRADING_SALT", "benchmark")
    os.environ.setdefault("CVKIT_STUDENT_ID", "instructor")
    wanted = [c for c in args.chapters.split(",") if c]
    paths = [p for p in lecture_release.NOTEBOOKS if not wanted or p.parent.name in wanted]
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    print(f"{'chapter':<24} {'solutions (s)':>14} {'release, Run All (s)':>21}")
    slow = []
    for path in paths:
        solved = run(nbformat.read(path, as_version=4), path.parent)
        released = run(lecture_release.release(path), path.parent)
        print(f"{path.parent.name:<24} {solved:>14.1f} {released:>21.1f}", flush=True)
        if solved >= GOAL_SECONDS:
            slow.append(path.parent.name)
    print(f"goal: every chapter under {GOAL_SECONDS:.0f} s with its solutions; "
          + ("all met" if not slow else f"missed by {', '.join(slow)}"))
    return 1 if args.check and slow else 0


if __name__ == "__main__":
    sys.exit(main())
