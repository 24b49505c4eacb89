"""The ``cvkit`` command line.

    cvkit list                      algorithms, sections, providers, check status
    cvkit course build              nbgrader generate_assignment for the chapters
    cvkit course grade              autograde all submissions in parallel, feedback, CSV, table
    cvkit course table              the grade table of what has been graded
    cvkit demo                      the whole pipeline on three sample submissions
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def _cmd_list(args) -> int:
    from . import registry

    rows = []
    for algo in registry.algorithms():
        providers = ["reference"] + [
            name for name in registry.providers()[1:] if algo.id in registry.provider(name)
        ]
        try:
            check = algo.check
            status = (
                f"{len(check.public_cases())} public, {len(check.hidden_cases(__import__('numpy').random.default_rng(0)))} hidden, "
                f"{len(check.mistakes)} mistakes" if check is not None else "no check"
            )
        except Exception as exc:  # a broken check is reported, not fatal
            status = f"check broken: {type(exc).__name__}: {exc}"
        rows.append((algo.id, algo.section, ", ".join(providers), status))
    if args.json:
        import json

        print(json.dumps([dict(zip(("id", "section", "providers", "check"), r)) for r in rows], indent=1))
        return 0
    w = max(len(r[0]) for r in rows) + 2 if rows else 10
    print(f"{'id'.ljust(w)}{'§'.ljust(8)}{'providers'.ljust(22)}check")
    for r in rows:
        print(f"{r[0].ljust(w)}{r[1].ljust(8)}{r[2].ljust(22)}{r[3]}")
    errors = registry.plugin_errors()
    for name, why in errors.items():
        print(f"plugin {name!r} failed to load: {why}")
    print(f"{len(rows)} algorithms")
    return 0


def _course(args):
    from .course import Course

    return Course(Path(args.course_dir) if args.course_dir else None, db_url=args.db_url)


def _cmd_build(args) -> int:
    course = _course(args)
    built = course.build(args.assignment or None, progress=True)
    for a in built:
        print(f"released {a}: {', '.join(p.name for p in course.release_notebooks(a))} in {course.root / 'release' / a}")
    return 0


def _print_results(course, results, assignments) -> int:
    failed = [r for r in results if not r.ok]
    for r in failed:
        print(f"!! autograding {r.student}/{r.assignment} failed after {r.attempts} attempts:\n{r.log[-1500:]}")
    for a in assignments:
        print(f"\n== {a} ==")
        print(course.table(a))
    print(f"\nfeedback: {course.root / 'feedback'}   grades: {course.root / 'exports' / 'grades.csv'}")
    return 1 if failed else 0


def _cmd_grade(args) -> int:
    course = _course(args)
    jobs = course.submissions(args.assignment or None)
    if not jobs:
        print(f"no submissions in {course.root / 'submitted'}")
        return 1
    from .grading.isolation import SandboxUnavailable

    start = time.perf_counter()
    try:
        results = course.grade(args.assignment or None, workers=args.workers, scheduler=args.scheduler,
                               progress=True, sandbox=not args.no_sandbox)
    except SandboxUnavailable as error:
        print(f"cvkit course grade: cannot grade safely: {error}", file=sys.stderr)
        return 2
    print(f"autograded {len(results)} submissions in {time.perf_counter() - start:.0f} s")
    return _print_results(course, results, sorted({a for _, a in jobs}))


def _cmd_table(args) -> int:
    course = _course(args)
    for a in args.assignment or sorted({a for _, a in course.submissions()}):
        print(f"== {a} ==")
        print(course.table(a))
    return 0


def _cmd_demo(args) -> int:
    import shutil

    from .course import SAMPLE_STUDENTS, Course, format_table

    root = Path(args.dir).resolve()
    if root.exists() and not args.keep:
        shutil.rmtree(root)
    course = Course(root, db_url=args.db_url)
    assignments = args.assignment or course.assignments()
    start = time.perf_counter()
    print(f"[1/4] building the course in {root}")
    course.build(assignments, progress=True)
    print("[2/4] creating sample submissions: " + ", ".join(SAMPLE_STUDENTS))
    for a in assignments:
        course.make_samples(a)
    print(f"[3/4] autograding with nbgrader ({args.workers} workers)")
    from .grading.isolation import SandboxUnavailable

    try:
        results = course.grade(assignments, workers=args.workers, progress=True, sandbox=not args.no_sandbox)
    except SandboxUnavailable as error:
        print(f"cvkit demo: cannot grade safely: {error}", file=sys.stderr)
        return 2
    print("[4/4] feedback and grades exported")
    status = _print_results(course, results, assignments)
    # the three samples must land where they should: complete full marks (of the autograded
    # points: written answers wait for the instructor), blank zero
    for a in assignments:
        scores = course.scores(a)
        total = {s: (sum(e.score for e in v if not e.to_mark), sum(e.max_score for e in v if not e.to_mark))
                 for s, v in scores.items()}
        got, top = total.get("sample_complete", (0, 1))
        if abs(got - top) > 1e-6:
            print(f"!! sample_complete scored {got}/{top} on {a}, expected full marks")
            status = 1
        got, _ = total.get("sample_blank", (1, 1))
        if got != 0:
            print(f"!! sample_blank scored {got} on {a}, expected 0")
            status = 1
    print(f"\ndemo finished in {time.perf_counter() - start:.0f} s" + ("" if status == 0 else " WITH PROBLEMS"))
    return status


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="cvkit", description="cvkit course kit: algorithms, grading, nbgrader course")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="list algorithms with their providers and checks")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=_cmd_list)

    def course_options(p):
        p.add_argument("--course-dir", help="course folder (default: the project's autograders/)")
        p.add_argument("--db-url", help="gradebook SQLAlchemy URL (default: SQLite in the course folder)")
        p.add_argument("--assignment", action="append", help="only this assignment (repeatable)")

    course = sub.add_parser("course", help="the nbgrader course")
    csub = course.add_subparsers(dest="course_command", required=True)
    p = csub.add_parser("build", help="generate the student versions of the chapters")
    course_options(p)
    p.set_defaults(func=_cmd_build)
    p = csub.add_parser("grade", help="autograde every submission, write feedback and grades.csv")
    course_options(p)
    p.add_argument("--workers", type=int, default=2, help="parallel autograde processes (default 2)")
    p.add_argument("--scheduler", help="Dask distributed scheduler address (workers must share the course folder)")
    p.add_argument("--no-sandbox", action="store_true",
                   help="DANGEROUS: grade without the bubblewrap sandbox (one trusted machine only); "
                        "every grade is marked in the table, the exports and the feedback")
    p.set_defaults(func=_cmd_grade)
    p = csub.add_parser("table", help="print the grade table")
    course_options(p)
    p.set_defaults(func=_cmd_table)

    p = sub.add_parser("demo", help="build, make three sample submissions, autograde, print the grade table")
    p.add_argument("--dir", default="cvkit-demo", help="where the demo course is made (default ./cvkit-demo)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--db-url", help="gradebook SQLAlchemy URL (default SQLite in --dir)")
    p.add_argument("--assignment", action="append", help="only this assignment (repeatable)")
    p.add_argument("--keep", action="store_true", help="do not wipe --dir first")
    p.add_argument("--no-sandbox", action="store_true",
                   help="grade the sample submissions without the bubblewrap sandbox (marked in the table)")
    p.set_defaults(func=_cmd_demo)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (FileNotFoundError, RuntimeError, KeyError, ValueError) as exc:
        print(f"cvkit: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
