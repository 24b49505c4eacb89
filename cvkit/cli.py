"""The ``cvkit`` command line.

    cvkit list [NAMESPACE]          algorithms, sections, packages, providers, check sizes
    cvkit list --validate           ... and whether each check is sound (reference, hidden cases, mistakes)
    cvkit list --markdown           the catalog of cvkit's algorithms (docs/catalog.md)
    cvkit new course DIR            a course folder of its own (cvkit's chapters you choose, yours)
    cvkit new exercise ID           scaffold an exercise of an instructor's course package
    cvkit course build              nbgrader generate_assignment for the chapters
    cvkit course grade              autograde all submissions in parallel, feedback, CSV, table
    cvkit course grade --regrade CHAPTER    ... and regrade a chapter (after a due date or check changed)
    cvkit course table              the grade table of what has been graded
    cvkit course refresh            after marking in the formgrader: pages and exports, without grading
    cvkit course leaderboard [CH]   the opt-in leaderboards of the measured exercises (plan.toml [leaderboard])
    cvkit course collect            hand-ins from nbgrader's exchange, an LMS download or one notebook
    cvkit course export --canvas    a CSV Canvas's gradebook imports (--moodle FIELD: Moodle's; docs/lms.md)
    cvkit course push --lti CONFIG  the grades to the LMS's line items (LTI 1.3 Assignment and Grade Services)
    cvkit demo                      the whole pipeline on three sample submissions of a few chapters
    cvkit demo --all                ... of every chapter
    cvkit hub init                  a JupyterHub for one or more courses (run as root; docs/deploy-jupyterhub.md)
    cvkit hub check                 what is wrong with a hub made by cvkit hub init
    cvkit hub start                 start that hub (as root), after checking it can
"""
from __future__ import annotations

import argparse
import datetime as _dt
import os
import sys
import time
from pathlib import Path
from typing import Sequence


def _table(headers: Sequence[object], rows: Sequence[Sequence[object]], gap: int = 2) -> list[str]:
    """Rows of text whose columns are as wide as their widest cell plus ``gap``: a column never
    runs into the next, and each starts at the same offset on every line."""
    widths = [max(len(str(row[i])) for row in [headers, *rows]) + gap for i in range(len(headers) - 1)]
    return ["".join(str(cell).ljust(width) for cell, width in zip(row, widths)) + str(row[-1])
            for row in [headers, *rows]]


def _show(text: object = "") -> None:
    """Print ``text``, which may hold what a student wrote (ids, exception messages, logs), line
    by line with every control, bidi or invisible character as a visible escape
    (:func:`cvkit._text.printable`): nothing printed can drive the instructor's terminal."""
    from ._text import printable

    print("\n".join(printable(line) for line in str(text).split("\n")))


def _check_status(row: dict) -> str:
    if row.get("check_error"):
        return "check broken (see below)"
    if row.get("public") is None:
        return "no check"
    return f"{row['public']} public, {row['mistakes']} mistakes"


def _listing(namespace: str | None) -> list[dict]:
    """cvkit's algorithms (from the catalog's index) and the course packages' (live)."""
    from . import catalog, registry

    if namespace in registry.topic_modules():
        rows = [r for r in catalog.listing() if r["id"].startswith(namespace + ".")]
    elif namespace is None:
        rows = catalog.listing()
    else:
        rows = []
    for package in registry.course_packages():
        if package.error or namespace not in (None, package.name):
            continue
        for row in catalog.entries([registry.get(i) for i in sorted(package.ids)]):
            rows.append(dict(row, package=package.distribution))
    return rows


def _validate_rows(rows: list[dict], notes: list[str], seeds: int, quiet: bool) -> int:
    """Validate the checks of ``rows`` (their ``check`` cell gets ``valid`` or ``REFUSED``),
    adding the reasons to ``notes``; returns how many were refused.

    A check is refused when its reference fails its own public cases
    (:func:`cvkit.registry.validate`), or when it is not sound over ``seeds`` draws of hidden
    cases (:func:`cvkit.grading.soundness.soundness`: a hidden case the reference cannot
    compute, a mistake no case tells from the reference, two mistakes no case tells apart).
    The reference's warnings are listed, naming the case, without refusing the check."""
    from . import registry
    from .course.progress import Phase
    from .grading.soundness import soundness

    def refusal(row: dict) -> str | None:
        """Why the check of ``row`` is refused (None: valid), its warnings added to ``notes``."""
        try:
            registry.validate(row["id"])  # also refuses an algorithm without a check
            found = soundness(row["id"], seeds=seeds)
        except (ValueError, KeyError) as error:
            return str(error.args[0])
        notes.extend(f"{row['id']}: warning (not refused; grading silences it): {note}" for note in found.notes)
        if found.problems:
            return f"{registry.get(row['id']).package}: the check of {row['id']!r} is refused: " + "; ".join(found.problems)
        row["check"] += ", valid" + (" (warnings below)" if found.notes else "")
        return None

    refused = 0
    with Phase("validate", len(rows), enabled=not quiet and len(rows) > 1, unit="check") as bar:
        for row in rows:
            why = None if row.get("check_error") else refusal(row)
            if row.get("check_error") or why is not None:
                refused += 1
            if why is not None:
                row["check"] += ", REFUSED (see below)"
                notes.append(why)
            bar.update()
    return refused


def _cmd_list(args) -> int:
    from . import catalog, registry

    if args.markdown:
        sys.stdout.write(catalog.markdown())
        return 0
    rows = _listing(args.namespace)
    offered = {name: set(registry.provider(name).functions) for name in registry.providers()[1:]}
    notes = [f"{row['id']}: check broken: {row['check_error']}" for row in rows if row.get("check_error")]
    refused = 0
    for row in rows:
        row["providers"] = ["reference"] + [name for name, ids in offered.items() if row["id"] in ids]
        row["check"] = _check_status(row)
    if args.validate:
        refused = _validate_rows(rows, notes, args.seeds, quiet=args.json)
    if args.json:
        import json

        keys = ("id", "section", "package", "providers", "public", "mistakes", "allowed", "check")
        print(json.dumps([{key: row.get(key) for key in keys} for row in rows], indent=1, ensure_ascii=False))
        return 1 if refused else 0
    table = [(row["id"], row["section"], row["package"], ", ".join(row["providers"]), row["check"]) for row in rows]
    print("\n".join(_table(("id", "§", "package", "providers", "check"), table)))
    for note in notes:
        print(f"!! {note}")
    for name, why in registry.plugin_errors().items():
        print(f"plugin {name!r} failed to load: {why}")
    for name, why in registry.package_errors().items():
        print(f"course package {name!r} failed to load: {why}")
    packages = len({row["package"] for row in rows} - {registry.CVKIT})
    print(f"{len(rows)} algorithm{'s' * (len(rows) != 1)}" + (f" ({packages} course package{'s' * (packages != 1)})" if packages else "")
          + (f", {refused} check{'s' * (refused != 1)} refused" if refused else ""))
    return 1 if refused else 0


def _cmd_new_exercise(args) -> int:
    from .scaffold import new_exercise

    written = new_exercise(args.id, args.package, args.section)
    for path in written:
        print(f"wrote {path}")
    namespace, name = args.id.split(".")
    module = next(p for p in written if p.name == f"{name}.py")
    cells = next(p for p in written if p.suffix == ".ipynb")
    print(f"next: 1. write the reference, its cases and its mistakes in {module}\n"
          f"      2. pip install -e {args.package}, then: cvkit list {namespace} --validate\n"
          f"      3. paste the cells of {cells} into a chapter notebook\n"
          "      (docs/own-exercise.md walks through it)")
    if not any(p.name == "__init__.py" for p in written):
        print(f"note: {module.parent / '__init__.py'} was there already: make sure it imports {module.stem}")
    return 0


def _course(args):
    from .course import Course
    from .course.course import made_by_cvkit

    # a course folder cvkit made (cvkit new course, cvkit hub init, --course-dir): the one we are in
    folder = args.course_dir or next((str(p) for p in (Path.cwd(), *Path.cwd().parents) if made_by_cvkit(p)), None)
    return Course(Path(folder) if folder else None, db_url=args.db_url)


def _cmd_new_course(args) -> int:
    from .course.new_course import CourseFolderError, new_course

    try:
        written = new_course(args.dir, args.chapter or [], args.course_id)
    except CourseFolderError as error:
        print(f"cvkit new course: {error}", file=sys.stderr)
        return 2
    for path in written:
        print(f"wrote {path}")
    folder = Path(args.dir).resolve()
    print(f"next: cd {folder}; edit plan.toml (due dates, late policy); cvkit course build; after the hand-ins: "
          "cvkit course grade (docs/own-course.md)")
    return 0


def _cmd_build(args) -> int:
    course = _course(args)
    built = course.build(args.assignment or None, progress=True)
    for a in built:
        print(f"released {a}: {', '.join(p.name for p in course.release_notebooks(a))} in {course.root / 'release' / a}")
    return 0


def _summary(course, jobs) -> list[str]:
    """What the instructor must know besides the tables, for the submissions ``jobs``: chapters
    left out of the plan, submissions graded under an older due date, late policy or checks,
    similar answers."""
    from .course.exports import similarity_summary

    lines = []
    outside: dict[str, int] = {}
    for reason in course.outside_plan(jobs).values():
        outside[reason] = outside.get(reason, 0) + 1
    for reason, count in sorted(outside.items()):
        lines.append(f"not graded: {reason}: {count} submission{'s' * (count != 1)} "
                     f"(add the chapter to {course.plan_path} to grade them)")
    outdated: dict[str, dict[str, list[str]]] = {}
    for (student, assignment), what in sorted(course.outdated(jobs).items()):
        for item in what:
            outdated.setdefault(assignment, {}).setdefault(item, []).append(student)
    if outdated:
        lines.append("graded under an older due date, late policy or checks (grades may change when regraded):")
        for assignment, changed in sorted(outdated.items()):
            for what, students in sorted(changed.items()):
                shown = ", ".join(students[:6]) + (f" and {len(students) - 6} more" if len(students) > 6 else "")
                lines.append(f"  {assignment}: {len(students)} under an older {what} ({shown})")
            lines.append(f"    → cvkit course grade --regrade {assignment}")
    from .course.results import late_penalties

    not_graded = course.not_graded()
    plan = course.plan()
    for (student, assignment), (points, seconds) in late_penalties(
            course, [(s, a) for s, a in jobs if f"{s}/{a}" not in not_graded]).items():
        late = f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"
        extension = plan.extension(student, assignment)
        due = (f"their extended due date ({extension.until:%Y-%m-%d %H:%M} UTC)" if extension is not None
               else "the due date")
        lines.append(f"late: {student} {assignment}: −{points:g} point{'s' * (points != 1)} (handed in {late} after "
                     f"{due}; the table shows the points before it)")
    from .course.results import environment

    for cause, per in sorted(environment(course, {a for _, a in jobs}).items()):
        count = sum(len(students) for students in per.values())
        chapters = sorted(per)
        fix = ("reinstall the package that lacks this file where grading runs" if cause.startswith("FileNotFoundError")
               else "install what the chapters need where grading runs (pip install \"cvkit[course]\" brings every "
                    "chapter of cvkit's)")
        lines.append(f"environment: {cause}: the cells as released of {', '.join(chapters)} failed in {count} "
                     f"submission{'s' * (count != 1)}, not the students' doing: {fix}, then "
                     "cvkit course grade " + " ".join(f"--regrade {c}" for c in chapters))
    from .sandbox import isolation

    note = None if isolation.sandbox_disabled() else isolation.limits_fallback()
    if note:
        lines.append(f"sandbox: {note}")
    from .course.leaderboard import saved_summary

    assignments = {a for _, a in jobs}
    return lines + _without_notebooks(course, None) + _exchange_notes(course, assignments) \
        + similarity_summary(course) + [f"item analysis: {course.root / 'exports' / 'item_analysis.html'} "
                                        "(a summary: cvkit course stats)"] + saved_summary(course)


def _without_notebooks(course, assignments) -> list[str]:
    """A line for each submission folder of ``assignments`` that holds no notebook."""
    lines = []
    for key, files in sorted(course.without_notebooks(assignments).items()):
        student, _, assignment = key.partition("/")
        expected = ", ".join(p.name for p in course.release_notebooks(assignment)) or "the assignment's notebooks"
        shown = ", ".join(files[:5]) + (f" and {len(files) - 5} more" if len(files) > 5 else "") if files else "nothing"
        lines.append(f"not graded: {key} holds no notebook ({shown}): nothing to grade; ask {student} to hand in "
                     f"{expected} (nbgrader submit hands in the assignment's folder as fetched)")
    return lines


def _exchange_notes(course, assignments) -> list[str]:
    """The notes about nbgrader's exchange of a course on a hub (none for other courses)."""
    from .course.hub import exchange_notes

    try:
        return exchange_notes(course, assignments)
    except OSError as error:  # an exchange this account cannot read: say so, never stop the report
        return [f"exchange: cannot read it ({error}); run cvkit hub check as root"]


def _print_results(course, results, jobs) -> int:
    failed = [r for r in results if not r.ok]
    for r in failed:
        _show(f"!! autograding {r.student}/{r.assignment} failed after {r.attempts} attempts:\n{r.log[-1500:]}")
    for a in sorted({a for _, a in jobs}):
        _show(f"\n== {a} ==")
        _show(course.table(a))
    print()
    for line in _summary(course, jobs):
        _show(line)
    print(f"\nfeedback: {course.root / 'feedback'}   grades: {course.root / 'exports' / 'grades.csv'}")
    return 1 if failed else 0


def _regrade_option(values) -> bool | list[str]:
    """``--regrade`` as :meth:`Course.grade` takes it: True for ``all``, else the chapters."""
    if not values:
        return False
    return True if "all" in values else list(values)


def _cmd_grade(args) -> int:
    course = _course(args)
    jobs = course.submissions(args.assignment or None)
    if not jobs:
        print(f"no submissions in {course.root / 'submitted'}")
        for key, reason in sorted(course.refused_submissions(args.assignment or None).items()):
            _show(f"  {key}: not graded: {reason}")
        for line in _without_notebooks(course, args.assignment) + _exchange_notes(course, args.assignment
                                                                                   or course.assignments()):
            _show(line)
        return 1
    from .course.parallel import ClusterUnavailable
    from .sandbox.isolation import SandboxUnavailable

    regrade = _regrade_option(args.regrade)
    if isinstance(regrade, list):
        unknown = sorted(set(regrade) - {a for _, a in jobs})
        if unknown:
            raise ValueError(f"--regrade {', '.join(unknown)}: no submissions of this chapter "
                             f"(chapters with submissions: {', '.join(sorted({a for _, a in jobs}))}; or --regrade all)")
    start = time.perf_counter()
    try:
        results = course.grade(args.assignment or None, workers=args.workers, scheduler=args.scheduler,
                               progress=True, regrade=regrade, sandbox=not args.no_sandbox)
    except SandboxUnavailable as error:
        print(f"cvkit course grade: cannot grade safely: {error}", file=sys.stderr)
        return 2
    except ClusterUnavailable as error:
        print(f"cvkit course grade: cannot grade on the cluster: {error}", file=sys.stderr)
        return 2
    graded = [r for r in results if not r.not_graded]
    print(f"autograded {len(graded)} submission{'s' * (len(graded) != 1)} in {time.perf_counter() - start:.0f} s")
    return _print_results(course, results, jobs)


def _cmd_refresh(args) -> int:
    course = _course(args)
    pages = course.refresh(progress=True)
    print(f"wrote {len(pages)} feedback page{'s' * (len(pages) != 1)} with new marks"
          + (f" ({', '.join(f'{s}/{a}' for s, a in pages)})" if pages else "")
          + f"; exports: {course.root / 'exports'}; marks: {course.root / '.cvkit' / 'marks.log'}")
    from .course.leaderboard import saved_summary

    for line in saved_summary(course):
        _show(line)
    return 0


def _cmd_leaderboard(args) -> int:
    from .course import leaderboard

    course = _course(args)
    chosen = ([args.chapter] if args.chapter else []) + (args.assignment or [])
    for line in leaderboard.publish(course, chosen or None):
        _show(line)
    return 0


def _cmd_collect(args) -> int:
    from .course.collect import collect_exchange, collect_files
    from .course.plan import parse_due

    course = _course(args)
    if not args.assignment or len(args.assignment) != 1:
        raise ValueError("say which chapter the hand-ins are for: --assignment CHAPTER (one)")
    assignment = args.assignment[0]
    if args.source is None:
        if args.student or args.pattern or args.roster or args.received_at:
            raise ValueError("--student, --pattern, --roster and --received-at describe a download: give it with "
                             "--from ZIP_OR_FOLDER_OR_NOTEBOOK")
        result = collect_exchange(course, assignment, update=args.update)
    else:
        when = None
        if args.received_at:
            due = parse_due(args.received_at, "--received-at")
            when = due.replace(tzinfo=_dt.timezone.utc) if due is not None else None
        result = collect_files(course, assignment, args.source, student=args.student, pattern=args.pattern,
                               roster=args.roster, received_at=when, update=args.update)
    for line in result.lines():
        _show(line)
    print(f"{len(result.imported)} hand-in{'s' * (len(result.imported) != 1)} collected into "
          f"{course.root / 'submitted'}" + (f"; {len(result.refused)} refused (above)" if result.refused else "")
          + ("; next: cvkit course grade" if result.imported else ""))
    return 1 if result.refused else 0


def _cmd_stats(args) -> int:
    from .course import item_analysis

    course = _course(args)
    results = item_analysis.analyse_course(course, args.assignment or None)
    folder = course.root / "exports"
    item_analysis.write_csv(results, folder / item_analysis.CSV_NAME)
    page = item_analysis.write_html(results, folder / item_analysis.HTML_NAME)
    for line in item_analysis.summary(results, page) if results else [f"no assignment to analyse in {course.root}"]:
        _show(line)
    return 0


def _cmd_export(args) -> int:
    """``cvkit course export``: the LMS files (--canvas, --moodle), else grades.csv and exercises.csv."""
    from .course.lms import canvas_export, grade_sheet, moodle_export

    if not args.canvas and not args.moodle and (args.roster or args.roster_column):
        raise ValueError("--roster and --roster-column go with --canvas or --moodle")
    if args.canvas and args.moodle:
        raise ValueError("--canvas and --moodle: one LMS at a time (the --roster of each is its own)")
    if args.roster_column and not args.canvas:
        raise ValueError("--roster-column goes with --canvas (Moodle's roster is matched by student_id)")
    roster = Path(args.roster) if args.roster else None
    if roster is not None and not roster.is_file():
        raise FileNotFoundError(f"--roster {roster}: no such file")
    course = _course(args)
    if not args.canvas and not args.moodle:
        print(f"wrote {course.export()}")
        return 0
    sheet = grade_sheet(course, args.assignment or None)
    folder = course.root / "exports"
    if args.canvas:
        done = canvas_export(sheet, folder / "canvas_grades.csv", roster, args.roster_column or "SIS Login ID")
    else:
        done = moodle_export(sheet, folder / "moodle_grades.csv", args.moodle, roster)
    for line in done.lines:
        _show(line)
    graded = sum(1 for g in sheet.grades.values() if g.points is not None)
    print(f"wrote {done.path}: {len(sheet.students)} student{'s' * (len(sheet.students) != 1)}, "
          f"{len(sheet.assignments)} assignment{'s' * (len(sheet.assignments) != 1)}, {graded} grade"
          f"{'s' * (graded != 1)} (after late penalties); {len(done.blank)} blank or left out, with the reason, "
          f"in {done.reasons}")
    return 0


def _cmd_push(args) -> int:
    """``cvkit course push --lti CONFIG``: the grades to the platform's line items."""
    from .course.lms import grade_sheet
    from .course.lti import load_config, push

    config = load_config(args.lti)
    course = _course(args)
    report = push(grade_sheet(course, args.assignment or None), config)
    for line in report.lines:
        _show(line)
    if report.created:
        print(f"line items made: {', '.join(report.created)}")
    if report.reused:
        print(f"line items updated: {', '.join(report.reused)}")
    counts: dict[str, int] = {}
    grouped: dict[tuple[str, str, str], list[str]] = {}  # (assignment, status, why) → students
    for outcome in report.outcomes:
        counts[outcome.status] = counts.get(outcome.status, 0) + 1
        if outcome.status == "failed":  # each refusal on its line, with what the platform said
            _show(f"  {outcome.student} {outcome.assignment}: failed: {outcome.detail}")
        elif outcome.status != "posted":
            grouped.setdefault((outcome.assignment, outcome.status, outcome.detail), []).append(outcome.student)
    for (assignment, status, why), students in sorted(grouped.items()):
        named = ", ".join(students[:6]) + (f" and {len(students) - 6} more" if len(students) > 6 else "")
        _show(f"  {assignment}: {status}: {why}: {named}")
    summary = ", ".join(f"{n} {status}" for status, n in sorted(counts.items())) or "no students: nothing posted"
    if report.retried:
        summary += f" ({report.retried} request{'s' * (report.retried != 1)} repeated after a passing failure)"
    print(summary)
    if report.failed:
        print(f"!! {len(report.failed)} score{'s' * (len(report.failed) != 1)} refused by the platform (listed above); "
              "the others are posted: fix the cause, then push again (posting again is harmless)")
    return 1 if report.failed else 0


def _cmd_table(args) -> int:
    course = _course(args)
    for a in args.assignment or sorted({a for _, a in course.submissions()}):
        _show(f"== {a} ==")
        _show(course.table(a))
    return 0


#: the chapters of the quick demo (`cvkit demo`; `--all` grades every chapter): short notebooks
#: that show autograded exercises with a typical mistake named (the kernel-flip family of
#: Chapter 3 among them) and written questions waiting for the instructor
DEMO_CHAPTERS = ("ch03_filtering", "ch04_edges", "ch07_camera_model")


def _demo_chapters(args, course) -> list[str]:
    planned = course.assignments()
    if args.assignment:
        return list(args.assignment)
    if args.all:
        return planned
    return [c for c in DEMO_CHAPTERS if c in planned] or planned[:2]


def _cmd_demo(args) -> int:
    import shutil

    from .course import SAMPLE_STUDENTS, Course
    from .course.progress import progress

    root = Path(args.dir).resolve()
    if root.exists() and not args.keep:
        shutil.rmtree(root)
    course = Course(root, db_url=args.db_url)
    assignments = _demo_chapters(args, course)
    start = time.perf_counter()
    planned = len(course.assignments())
    which = (f"{len(assignments)} of the {planned} chapters (--all for every one)" if len(assignments) < planned
             else f"{len(assignments)} chapter{'s' * (len(assignments) != 1)}")
    print(f"[1/4] building {which} in {root}", flush=True)
    course.build(assignments, progress=True)
    print("[2/4] creating sample submissions: " + ", ".join(SAMPLE_STUDENTS), flush=True)
    for a in progress(assignments, "samples", True, unit="chapter"):
        course.make_samples(a)
    print(f"[3/4] autograding with nbgrader ({args.workers} workers), feedback pages, exports, similarity report",
          flush=True)
    from .sandbox.isolation import SandboxUnavailable

    try:
        results = course.grade(assignments, workers=args.workers, progress=True, sandbox=not args.no_sandbox)
    except SandboxUnavailable as error:
        print(f"cvkit demo: cannot grade safely: {error}", file=sys.stderr)
        return 2
    print("[4/4] the grade tables", flush=True)
    status = _print_results(course, results, course.submissions(assignments))
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
    from .course.results import environment

    for cause, per in sorted(environment(course, assignments).items()):
        # the demo's own environment must run every cell of its chapters as released
        print(f"!! the grading environment lacks what {', '.join(sorted(per))} need: {cause}")
        status = 1
    print(f"\ndemo finished in {time.perf_counter() - start:.0f} s" + ("" if status == 0 else " WITH PROBLEMS"))
    return status


def _hub_settings(args):
    from .course import project_root
    from .course.hub import HubSettings, courses_from_options

    students = list(args.student or [])
    if args.students_file:
        lines = Path(args.students_file).read_text().splitlines()
        students += [line.strip() for line in lines if line.strip() and not line.lstrip().startswith("#")]
    courses = courses_from_options(args.course or [], args.instructor or [], students, args.course_dir or [],
                                   args.grader or [])
    hub = Path(args.hub_dir)
    return HubSettings(folder=str(hub), courses=courses, exchange=args.exchange or str(hub / "exchange"),
                       ip=args.ip, port=args.port, hub_port=args.hub_port, proxy_api_port=args.proxy_api_port,
                       subdomain_host=(args.subdomain_host or "").rstrip("/"),
                       project=str(Path(args.project).resolve() if args.project else project_root()))


def _cmd_hub_init(args) -> int:
    from .course.hub import course_folder, init_hub, load_settings

    written, warnings = init_hub(_hub_settings(args))
    settings = load_settings(args.hub_dir)
    for path in written:
        print(f"wrote {path}")
    for warning in warnings:
        _show(f"!! {warning}")
    print(f"\nthe hub: {settings.url}  (students and instructors log in with their Unix passwords)")
    print(f"next: 1. start it (as root): cvkit hub start --hub-dir {settings.folder}\n"
          f"         or with systemd: systemctl link {Path(settings.folder) / 'jupyterhub.service'} && "
          "systemctl start jupyterhub")
    for course in settings.courses:
        folder = course_folder(course)
        print(f"      2. {course.id}: as {course.instructor}, in {folder}: cvkit course build --course-dir . "
              "--assignment CHAPTER, then nbgrader release_assignment CHAPTER")
        formgrader = (f"{settings.subdomain_host.replace('://', f'://{course.instructor}.', 1)}/user/"
                      if settings.subdomain_host else f"{settings.url}/user/")
        print(f"         formgrader: {formgrader}{course.instructor}/formgrader"
              + ("" if settings.subdomain_host else " (in a browser tab of its own: see docs/deploy-jupyterhub.md)"))
        if course.shared_formgrader:
            print(f"         shared formgrader ({course.instructor} and {', '.join(course.graders)}): "
                  f"{settings.url}/services/{course.id}/formgrader")
    print("      3. students: the Assignments panel of JupyterLab (Nbgrader menu → Assignment List)")
    return 0


def _cmd_hub_check(args) -> int:
    from .course.hub import check_hub, load_settings

    problems = check_hub(load_settings(args.hub_dir), ports=not args.running)
    for problem in problems:
        _show(f"!! {problem}")
    if not problems:
        print(f"the hub in {args.hub_dir} is set up as cvkit hub init made it")
    return 1 if problems else 0


def _cmd_hub_start(args) -> int:
    from ._text import printable
    from .course.hub import check_hub, load_settings

    settings = load_settings(args.hub_dir)
    problems = check_hub(settings)
    if problems:
        print("cvkit hub start: the hub cannot start (safely):", file=sys.stderr)
        for problem in problems:
            print(f"  {printable(problem)}", file=sys.stderr)
        return 2
    config = Path(settings.folder) / "jupyterhub_config.py"
    program = Path(settings.python_bin) / "jupyterhub"
    os.chdir(settings.folder)
    sys.stdout.flush()
    os.execv(str(program), [str(program), "-f", str(config), *args.jupyterhub_args])
    return 0  # pragma: no cover - execv does not return


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="cvkit", description="cvkit course kit: algorithms, grading, nbgrader course")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="list algorithms with their providers and checks")
    p.add_argument("namespace", nargs="?", help="only this cvkit topic or course package (e.g. filters, mycourse)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--markdown", action="store_true", help="the catalog of cvkit's algorithms (docs/catalog.md)")
    p.add_argument("--validate", action="store_true",
                   help="check every check: its reference passes its public cases and computes its hidden cases "
                        "(over --seeds draws), every mistake differs from the reference and from every other "
                        "mistake on some case; exit status 1 when a check is refused")
    p.add_argument("--seeds", type=_positive_int, default=200,
                   help="with --validate: how many draws of hidden cases to examine per check (default 200)")
    p.set_defaults(func=_cmd_list)

    p = sub.add_parser("new", help="a course folder of your own, or an exercise of your course package")
    nsub = p.add_subparsers(dest="new_command", required=True)
    p = nsub.add_parser("course", help="a course folder of its own, with cvkit's chapters you choose (or add them)")
    p.add_argument("dir", help="the course folder (new or empty; or one made by this command, to add chapters)")
    p.add_argument("--chapter", action="append", metavar="CHAPTER",
                   help="one of cvkit's chapters, e.g. ch03_filtering (repeatable; 'all' for every one)")
    p.add_argument("--course-id", help="nbgrader's course id (default: the folder's name)")
    p.set_defaults(func=_cmd_new_course)
    p = nsub.add_parser("exercise", help="reference stub, check, mistake and notebook cells of a new exercise")
    p.add_argument("id", help="<course>.<name>, e.g. mycourse.gamma_correction")
    p.add_argument("--package", default=".", help="the course package folder (default: here); made if missing")
    p.add_argument("--section", default="1", help="section of your notes the exercise belongs to (default 1)")
    p.set_defaults(func=_cmd_new_exercise)

    def course_options(p):
        p.add_argument("--course-dir", help="course folder (default: the course folder cvkit made that you are in; "
                                            "else the project's autograders/)")
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
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="grade on the workers of this Dask scheduler, e.g. tcp://host:8786 (they need cvkit's "
                        "environment and bubblewrap, never the course folder: docs/scale-out.md)")
    p.add_argument("--regrade", action="append", metavar="CHAPTER",
                   help="grade this chapter's submissions again, e.g. after its due date or a check changed "
                        "(repeatable; 'all' for every chapter); new and changed submissions are always graded")
    p.add_argument("--no-sandbox", action="store_true",
                   help="DANGEROUS: grade without the bubblewrap sandbox (one trusted machine only); "
                        "every grade is marked in the table, the exports and the feedback")
    p.set_defaults(func=_cmd_grade)
    p = csub.add_parser("stats", help="item analysis: facility, discrimination, α, the most frequent mistakes and "
                                      "failure rates per case parameter (exports/item_analysis.csv and .html)")
    course_options(p)
    p.set_defaults(func=_cmd_stats)
    p = csub.add_parser("table", help="print the grade table")
    course_options(p)
    p.set_defaults(func=_cmd_table)
    p = csub.add_parser("collect", help="hand-ins into the course: from nbgrader's exchange, an LMS download "
                                        "(zip or folder) or one student's notebook")
    course_options(p)
    p.add_argument("--from", dest="source", metavar="PATH",
                   help="a zip or folder downloaded from the LMS (Canvas, Moodle, or one folder per student), or one "
                        "notebook (with --student); without it: nbgrader's exchange")
    p.add_argument("--student", help="every file of --from is this student's")
    p.add_argument("--pattern", help="how the download names files: a regular expression with the groups "
                                     "(?P<student_id>...) and (?P<file_id>...)")
    p.add_argument("--roster", help="a CSV with the columns lms and student_id: the LMS's names to your students' ids")
    p.add_argument("--received-at", metavar="TIME",
                   help="when the hand-ins arrived, e.g. '2027-03-01 23:10:00 UTC' (default: now)")
    p.add_argument("--update", action="store_true", help="replace hand-ins collected before with newer files")
    p.set_defaults(func=_cmd_collect)
    p = csub.add_parser("export", help="the grades as files: for Canvas (--canvas) or Moodle (--moodle FIELD) "
                                       "to import; without either, grades.csv and exercises.csv again")
    course_options(p)
    p.add_argument("--canvas", action="store_true", help="exports/canvas_grades.csv for Canvas's gradebook import")
    p.add_argument("--moodle", choices=("email", "username", "idnumber"), metavar="FIELD",
                   help="exports/moodle_grades.csv for Moodle's grade import, users identified by FIELD: email, "
                        "username or idnumber")
    p.add_argument("--roster", metavar="CSV",
                   help="with --canvas: Canvas's gradebook export, to copy the students' identities and assignment "
                        "ids from; with --moodle: a CSV with the columns student_id and FIELD")
    p.add_argument("--roster-column", metavar="COLUMN",
                   help="with --canvas --roster: the roster's column that holds cvkit's student ids (default "
                        "'SIS Login ID')")
    p.set_defaults(func=_cmd_export)
    p = csub.add_parser("push", help="the grades to the LMS through LTI 1.3 Assignment and Grade Services")
    course_options(p)
    p.add_argument("--lti", required=True, metavar="CONFIG", help="the LTI configuration (TOML; docs/lms.md)")
    p.set_defaults(func=_cmd_push)
    p = csub.add_parser("refresh", help="after marking in the formgrader: write the pages whose marks changed "
                                        "and the exports again, without grading")
    course_options(p)
    p.set_defaults(func=_cmd_refresh)
    p = csub.add_parser("leaderboard", help="the opt-in leaderboards of the measured exercises: "
                                            "leaderboard/<chapter>.html and .csv, and on the feedback pages "
                                            "(plan.toml [leaderboard] enabled = true)")
    course_options(p)
    p.add_argument("chapter", nargs="?", help="only this chapter (default: every one with a measured exercise)")
    p.set_defaults(func=_cmd_leaderboard)

    p = sub.add_parser("demo", help="build, make three sample submissions, autograde, print the grade table")
    p.add_argument("--dir", default="cvkit-demo", help="where the demo course is made (default ./cvkit-demo)")
    p.add_argument("--workers", type=int, default=2, help="parallel autograde processes (default 2)")
    p.add_argument("--db-url", help="gradebook SQLAlchemy URL (default SQLite in --dir)")
    p.add_argument("--all", action="store_true",
                   help="every chapter of the plan (default: " + ", ".join(DEMO_CHAPTERS) + ")")
    p.add_argument("--assignment", action="append", help="only this assignment (repeatable)")
    p.add_argument("--keep", action="store_true", help="do not wipe --dir first")
    p.add_argument("--no-sandbox", action="store_true",
                   help="grade the sample submissions without the bubblewrap sandbox (marked in the table)")
    p.set_defaults(func=_cmd_demo)

    hub = sub.add_parser("hub", help="a course on JupyterHub (docs/deploy-jupyterhub.md)")
    hsub = hub.add_subparsers(dest="hub_command", required=True)
    p = hsub.add_parser("init", help="write a JupyterHub, nbgrader's exchange and the course folders (as root)")
    p.add_argument("--hub-dir", default="/srv/cvkit-hub", help="the hub's folder (default /srv/cvkit-hub)")
    p.add_argument("--course", action="append", metavar="ID", help="a course id (repeatable)")
    p.add_argument("--instructor", action="append", metavar="[COURSE=]USER",
                   help="the instructor account of a course (one per course; COURSE= with several courses)")
    p.add_argument("--student", action="append", metavar="[COURSE=]USER[,USER...]",
                   help="student accounts (repeatable; COURSE= with several courses)")
    p.add_argument("--students-file", help="a file of students, one [COURSE=]USER a line")
    p.add_argument("--grader", action="append", metavar="[COURSE=]USER[,USER...]",
                   help="teaching assistants: they grade in the course's shared formgrader (/services/COURSE/formgrader)")
    p.add_argument("--course-dir", action="append", metavar="[COURSE=]FOLDER",
                   help="the course folder (default ~INSTRUCTOR/COURSE)")
    p.add_argument("--exchange", help="nbgrader's exchange (default HUB_DIR/exchange)")
    p.add_argument("--ip", default="127.0.0.1",
                   help="the address the hub listens on (default 127.0.0.1, behind a TLS reverse proxy)")
    p.add_argument("--port", type=int, default=8000, help="its port (default 8000)")
    p.add_argument("--hub-port", type=int, default=8081, help="the hub's API port on 127.0.0.1 (default 8081)")
    p.add_argument("--proxy-api-port", type=int, default=8001, help="the proxy's API port on 127.0.0.1 (default 8001)")
    p.add_argument("--subdomain-host", help="e.g. https://hub.example.org: a subdomain per user (needs wildcard "
                                            "DNS and TLS); the formgrader then shows inside JupyterLab")
    p.add_argument("--project", help="the cvkit project (default: this checkout)")
    p.set_defaults(func=_cmd_hub_init)
    p = hsub.add_parser("check", help="what is wrong with a hub made by cvkit hub init")
    p.add_argument("--hub-dir", default="/srv/cvkit-hub", help="the hub's folder (default /srv/cvkit-hub)")
    p.add_argument("--running", action="store_true", help="the hub is running: do not check that its ports are free")
    p.set_defaults(func=_cmd_hub_check)
    p = hsub.add_parser("start", help="check the hub, then run JupyterHub (as root, in the foreground)")
    p.add_argument("--hub-dir", default="/srv/cvkit-hub", help="the hub's folder (default /srv/cvkit-hub)")
    p.add_argument("jupyterhub_args", nargs="*", help="passed on to jupyterhub (after --)")
    p.set_defaults(func=_cmd_hub_start)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        status = args.func(args)
        sys.stdout.flush()  # here, so that a closed pipe is handled below and not at exit
        return status
    except (FileNotFoundError, FileExistsError, RuntimeError, KeyError, ValueError) as exc:
        from ._text import printable

        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"cvkit: error: {printable(message, newlines=True)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `cvkit list | head`: the reader has gone
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
