"""The similarity report at class scale (issue #37, item 5): time and page size.

A simulated class (``tests/course/simulated_class.py``) answers Chapter 3's 13 exercises from three
common sources (the instructor's solution, cvkit's reference, an independent version), each
student changing names, swapping independent statements and adding comments; three students
answer on their own. The answers go to :func:`cvkit.course.similarity.similar_pairs` directly
(no grading), then :func:`~cvkit.course.similarity.groups`, ``write_html`` and ``write_csv``.

``--distinct`` adds one to three useless statements to every copy, so that no two students'
texts are the same once normalised: every pair is then measured (the costliest case; without
it, copies that differ only in names and comments are measured once).

    .venv/bin/python benchmarks/bench_similarity.py                  # 60 and 300 students
    .venv/bin/python benchmarks/bench_similarity.py --students 300 --distinct

Printed per class: students, pairs at or above the threshold, groups, distinct normalised texts
per exercise (mean), CPU seconds (comparison: tokenizing and measuring; grouping; writing the
two files) and the sizes of ``similarity.html`` and ``similarity.csv``.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "course"))


def run(students: int, distinct: bool, seed: int) -> dict:
    import simulated_class

    from cvkit.course import similarity

    exercises = simulated_class.exercises()
    sources = simulated_class.sources(exercises)
    chosen = {grade_id: exercises[grade_id] for grade_id in sources}
    answers = simulated_class.answers(students, seed=seed, chosen=sources, distinct=distinct)
    similarity._normalised.cache_clear()
    start = time.process_time()
    pairs = similarity.similar_pairs(answers, chosen, assignment="ch03_filtering")
    compared = time.process_time()
    groups = similarity.groups(pairs)
    grouped = time.process_time()
    with tempfile.TemporaryDirectory() as folder:
        page = similarity.write_html(groups, Path(folder) / "similarity.html").stat().st_size
        table = similarity.write_csv(groups, Path(folder) / "similarity.csv").stat().st_size
    written = time.process_time()
    texts = statistics.mean(len({similarity._normalised(a[g]) for a in answers.values()}) for g in chosen)
    return {"students": students, "distinct": distinct, "pairs": len(pairs), "groups": len(groups), "texts": texts,
            "compare": compared - start, "group": grouped - compared, "write": written - grouped,
            "html": page, "csv": table}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--students", type=int, nargs="+", default=[60, 300])
    parser.add_argument("--distinct", action="store_true", help="no two texts alike once normalised")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    import os
    import platform

    print(f"# {platform.python_version()}, {os.cpu_count()} CPUs, CPU seconds of one process")
    print("students  texts/exercise  pairs    groups  compare  group  write  total   similarity.html  similarity.csv")
    for students in args.students:
        r = run(students, args.distinct, args.seed)
        total = r["compare"] + r["group"] + r["write"]
        print(f"{r['students']:>8}  {r['texts']:>14.0f}  {r['pairs']:>7}  {r['groups']:>6}  {r['compare']:>6.1f}s"
              f"  {r['group']:>4.1f}s  {r['write']:>4.1f}s  {total:>5.1f}s  {r['html'] / 2**20:>12.2f} MB"
              f"  {r['csv'] / 2**20:>11.2f} MB", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
