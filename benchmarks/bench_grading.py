"""Autograding throughput: the same submissions graded with 1 and with N workers.

    python benchmarks/bench_grading.py [--submissions 8] [--chapters ch03_filtering,ch04_edges,ch07_camera_model]

For each chapter it builds a course in a temporary folder, makes ``--submissions`` submissions
(the solutions and the typical mistakes, alternately, under different student ids), grades them
sequentially and then in parallel, checks that both runs recorded identical grades, and prints
notebooks per minute, the speed-up, and the time per notebook.
"""
from __future__ import annotations

import argparse
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--submissions", type=int, default=8)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--chapters", default="ch03_filtering,ch04_edges,ch07_camera_model")
    args = parser.parse_args()
    chapters = [c for c in args.chapters.split(",") if (ROOT / "lectures" / c).is_dir()]
    print(f"machine: {os.cpu_count()} CPUs; {args.submissions} submissions per chapter; chapters: {', '.join(chapters)}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="cvkit-bench-") as folder:
        for workers in (1, args.workers):
            course = Course(Path(folder) / f"course{workers}")
            (course.root / ".grading_salt").write_text("benchmark")
            course.build(chapters)
            for chapter in chapters:
                for student, notebooks in submissions(course, chapter, args.submissions).items():
                    course.submit(student, chapter, notebooks)
            start = time.perf_counter()
            results = course.grade(chapters, workers=workers)
            elapsed = time.perf_counter() - start
            failed = [r for r in results if not r.ok]
            rows.append((workers, len(results), elapsed, grades(course), failed))
    (w1, n1, t1, g1, f1), (wn, nn, tn, gn, fn) = rows
    print(f"{'workers':>8} {'notebooks':>10} {'seconds':>8} {'notebooks/min':>14} {'s/notebook':>11}")
    for workers, count, elapsed, _, _ in rows:
        print(f"{workers:>8} {count:>10} {elapsed:>8.1f} {60 * count / elapsed:>14.1f} {elapsed / count:>11.1f}")
    print(f"speed-up with {wn} workers: {t1 / tn:.2f}x (goal >= 1.8x on 2 cores); "
          f"identical grades: {g1 == gn}; failures: {len(f1) + len(fn)}")
    return 0 if g1 == gn and not (f1 or fn) else 1


if __name__ == "__main__":
    sys.exit(main())
