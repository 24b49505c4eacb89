"""Autograding throughput: the same submissions graded with 1 and with N workers.

    python benchmarks/bench_grading.py [--submissions 8] [--chapters ch03_filtering,ch04_edges,ch07_camera_model]

For each chapter it builds a course in a temporary folder, makes ``--submissions`` submissions
(the solutions and the typical mistakes, alternately, under different student ids), grades them
one chapter at a time, with 1 worker and then with N, checks that both runs recorded identical
grades, and prints per chapter notebooks per minute, seconds per notebook, the CPU seconds all
processes spent per notebook (where a ``cpuacct`` control group can be made: root, cgroup v1),
and the speed-up.

``--where`` instead says where a notebook's CPU goes (needs the ``cpuacct`` group): each
submission is graded in this process by the workers' own function, the student's notebook run
(sandbox, driver, kernel and the notebook's cells) and the trusted checks timed apart, an
empty notebook's sandboxed run for the fixed part of a run, then the whole ``Course.grade``
with one worker for the total.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from cvkit.course import Course, solution_sources, typical_mistakes  # noqa: E402


def submissions(course: Course, assignment: str, count: int) -> dict[str, dict]:
    source = {p.name: json.loads(p.read_text()) for p in (course.source_dir / assignment).glob("*.ipynb")}
    mistakes = typical_mistakes(course.project / "autograders" / "samples" / assignment)
    made = {}
    for index in range(count):
        student = f"student{index:02d}"
        notebooks = {}
        for release in course.release_notebooks(assignment):
            nb = json.loads(release.read_text())
            solutions = solution_sources(source[release.name])
            for cell in nb["cells"]:
                grade_id = cell.get("metadata", {}).get("nbgrader", {}).get("grade_id")
                if not cell.get("metadata", {}).get("nbgrader", {}).get("solution"):
                    continue
                if index % 2 and grade_id in mistakes:
                    cell["source"] = mistakes[grade_id]
                elif grade_id in solutions:
                    cell["source"] = solutions[grade_id]
            notebooks[release.name] = nb
        made[student] = notebooks
    return made


def grades(course: Course) -> dict:
    from nbgrader.api import Gradebook

    out = {}
    with Gradebook(course.db_url) as gb:
        for student, assignment in course.submissions():
            sub = gb.find_submission(assignment, student)
            out[(student, assignment)] = {g.name: round(g.score, 6) for nb in sub.notebooks for g in nb.grades}
    return out


class TreeCPU:
    """CPU seconds (user + system) of this process and of every process it starts — the grading
    workers, their forkserver, the sandboxes, the kernels — from a ``cpuacct`` control group of
    its own. Wall time on a shared 2-core machine moves by ±10 % from run to run; the CPU the
    grading spends much less, so a change's effect shows in it first. Needs root and cgroup v1's
    ``cpuacct`` (on cgroup v2 a group of our own would take the sandboxes' ``pids`` groups with
    it, changing what is measured): elsewhere ``seconds()`` is None."""

    def __init__(self) -> None:
        self.group: Path | None = None
        hierarchy = Path("/sys/fs/cgroup/cpuacct")
        try:
            if (hierarchy / "cpuacct.usage").exists() and os.geteuid() == 0:
                group = hierarchy / f"cvkit-bench-{os.getpid()}"
                group.mkdir(exist_ok=True)
                self.group = group
                (group / "cgroup.procs").write_text(str(os.getpid()))
        except OSError:
            self.close()

    def seconds(self) -> float | None:
        try:
            return int((self.group / "cpuacct.usage").read_text()) / 1e9 if self.group else None
        except (OSError, ValueError):
            return None

    def close(self) -> None:
        """Move this process and what is left of its children (the workers' forkserver lives
        until this process exits) back to the hierarchy's root, and remove the group."""
        if self.group is None:
            return
        try:
            pids = (self.group / "cgroup.procs").read_text().split()
        except OSError:
            pids = [str(os.getpid())]
        for pid in pids:
            try:
                (self.group.parent / "cgroup.procs").write_text(pid)
            except OSError:  # it has just ended
                pass
        try:
            self.group.rmdir()
        except OSError:
            pass
        self.group = None


def sandbox_cost(repeats: int = 10) -> float:
    """Seconds the bubblewrap sandbox adds to one sandboxed run (the trusted worker with one
    answer cell and one case, sandboxed minus the same run with resource limits only). A
    notebook is graded in two sandboxed runs (its execution and its trusted checks), so the
    cost per notebook is twice this figure."""
    import numpy as np

    from cvkit.grading.runtime import wire
    from cvkit.sandbox import isolation, session as sandbox

    isolation.require()
    cells = ["def f(x):\n    return x + 1"]
    calls = [wire.BoxCall(function="f", args=(np.ones(3),), time_limit=5.0)]
    timings = {}
    for sandboxed in (False, True, False, True):
        start = time.perf_counter()
        for _ in range(repeats):
            assert sandbox.run_calls(cells, calls, sandboxed=sandboxed).outcomes[0].error is None
        timings[sandboxed] = (time.perf_counter() - start) / repeats
    return timings[True] - timings[False]


def where_the_time_goes(chapters: list[str], count: int) -> None:
    """Print, per chapter and for all, the CPU seconds per notebook of the student's notebook
    run, of the trusted checks, and of the whole grading (1 worker), and their shares."""
    from cvkit.course import jobs, trusted
    from cvkit.sandbox import notebook_run

    cpu = TreeCPU()
    if cpu.seconds() is None:
        print("not measured: needs root and cgroup v1's cpuacct")
        return
    spent: dict[str, float] = {}

    def timed(module, name: str, key: str) -> None:
        function = getattr(module, name)

        def measured(*args, **kwargs):
            start = cpu.seconds()
            try:
                return function(*args, **kwargs)
            finally:
                spent[key] = spent.get(key, 0.0) + cpu.seconds() - start
        setattr(module, name, measured)

    empty = {"cells": [{"cell_type": "code", "execution_count": None, "metadata": {}, "outputs": [], "source": ""}],
             "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}},
             "nbformat": 4, "nbformat_minor": 5}
    start = cpu.seconds()
    for _ in range(5):
        notebook_run.execute_in_sandbox({"empty.ipynb": json.dumps(empty).encode()}, "empty.ipynb")
    fixed = (cpu.seconds() - start) / 5
    timed(jobs, "_execute", "run")
    timed(trusted, "apply_trusted_checks", "checks")
    totals = {"run": 0.0, "checks": 0.0, "whole": 0.0}
    print(f"an empty notebook's sandboxed run (sandbox, driver, kernel start): {fixed:.2f} CPU s")
    print(f"{'chapter':<20} {'notebook run':>13} {'trusted checks':>15} {'whole grading':>14} {'run share':>10} "
          f"{'checks share':>13}   (CPU s per notebook)")
    with tempfile.TemporaryDirectory(prefix="cvkit-bench-") as folder, contextlib.closing(cpu):
        for chapter in chapters:
            spent.clear()
            course = Course(Path(folder) / chapter)
            (course.root / ".grading_salt").write_text("benchmark")
            course.build([chapter])
            for student, notebooks in submissions(course, chapter, count).items():
                course.submit(student, chapter, notebooks)
            for student, assignment in course.submissions():
                jobs.grade_submission(*jobs.payload(course, student, assignment))
            start = cpu.seconds()
            course.grade([chapter], workers=1)
            whole = cpu.seconds() - start
            run, checks = spent.get("run", 0.0), spent.get("checks", 0.0)
            for key, value in (("run", run), ("checks", checks), ("whole", whole)):
                totals[key] += value
            print(f"{chapter:<20} {run / count:>13.2f} {checks / count:>15.2f} {whole / count:>14.2f} "
                  f"{run / whole:>10.0%} {checks / whole:>13.0%}")
    n = count * len(chapters)
    print(f"{'all':<20} {totals['run'] / n:>13.2f} {totals['checks'] / n:>15.2f} {totals['whole'] / n:>14.2f} "
          f"{totals['run'] / totals['whole']:>10.0%} {totals['checks'] / totals['whole']:>13.0%}")
    print(f"the fixed part of a notebook's run: {fixed * n / totals['whole']:.0%} of the whole grading")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--submissions", type=int, default=8)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--chapters", default="ch03_filtering,ch04_edges,ch07_camera_model")
    parser.add_argument("--sandbox-cost-only", action="store_true", help="only measure the sandbox's cost")
    parser.add_argument("--where", action="store_true", help="where a notebook's CPU goes (see above)")
    args = parser.parse_args()
    if args.where:
        where_the_time_goes([c for c in args.chapters.split(",") if (ROOT / "lectures" / c).is_dir()], args.submissions)
        return 0
    cost = sandbox_cost()
    print(f"sandbox cost: {cost:.3f} s per sandboxed run, {2 * cost:.3f} s per notebook (goal <= 0.3 s)")
    if args.sandbox_cost_only:
        return 0 if 2 * cost <= 0.3 else 1
    chapters = [c for c in args.chapters.split(",") if (ROOT / "lectures" / c).is_dir()]
    print(f"machine: {os.cpu_count()} CPUs; {args.submissions} submissions per chapter; chapters: {', '.join(chapters)}")
    runs = {}
    cpu = TreeCPU()  # before any worker or sandbox starts: they all belong to its group
    with tempfile.TemporaryDirectory(prefix="cvkit-bench-") as folder, contextlib.closing(cpu):
        for workers in (1, args.workers):
            course = Course(Path(folder) / f"course{workers}")
            (course.root / ".grading_salt").write_text("benchmark")
            course.build(chapters)
            for chapter in chapters:
                for student, notebooks in submissions(course, chapter, args.submissions).items():
                    course.submit(student, chapter, notebooks)
            timings, failed = {}, []
            for chapter in chapters:  # as an instructor would: one chapter's submissions at a time
                start, start_cpu = time.perf_counter(), cpu.seconds()
                results = course.grade([chapter], workers=workers)
                end_cpu = cpu.seconds()
                spent = None if start_cpu is None or end_cpu is None else end_cpu - start_cpu
                timings[chapter] = (len(results), time.perf_counter() - start, spent)
                failed += [r for r in results if not r.ok]
            runs[workers] = (timings, grades(course), failed)
    print(f"{'chapter':<20} {'workers':>8} {'notebooks':>10} {'seconds':>8} {'notebooks/min':>14} {'s/notebook':>11} "
          f"{'CPU s/notebook':>15}")
    for workers, (timings, _, _) in runs.items():
        spent = [c for _, _, c in timings.values()]
        rows = list(timings.items()) + [("all", (sum(n for n, _, _ in timings.values()),
                                                 sum(t for _, t, _ in timings.values()),
                                                 None if None in spent else sum(spent)))]
        for chapter, (count, elapsed, used) in rows:
            shown = "not measured" if used is None else f"{used / count:.2f}"
            print(f"{chapter:<20} {workers:>8} {count:>10} {elapsed:>8.1f} {60 * count / elapsed:>14.1f} "
                  f"{elapsed / count:>11.1f} {shown:>15}")
    (t1, g1, f1), (tn, gn, fn) = runs[1], runs[args.workers]
    total1, totaln = sum(t for _, t, _ in t1.values()), sum(t for _, t, _ in tn.values())
    slowest = max(t / n for n, t, _ in t1.values())
    print(f"speed-up with {args.workers} workers: {total1 / totaln:.2f}x (goal >= 1.85x on 2 cores); "
          f"slowest chapter with 1 worker: {slowest:.1f} s/notebook (goal <= 15 s); "
          f"identical grades: {g1 == gn}; failures: {len(f1) + len(fn)}")
    return 0 if g1 == gn and not (f1 or fn) else 1


if __name__ == "__main__":
    sys.exit(main())
