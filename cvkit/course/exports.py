"""What a graded course shows: the grade table (terminal), the CSV exports and the similarity
report (``exports/similarity.csv`` and ``.html``, :func:`export_similarity`).

Students name much of it: their ids (folder names), their files, the text of their exceptions
and imports. Every such text is shown with :func:`cvkit._text.printable`: control characters
(terminal escape sequences), bidi and invisible characters, and bytes that were not UTF-8 appear
as visible escapes (``\\x1b[2J``, ``\\u202e``, ``\\xff``). The terminal table keeps each text on
its line (a newline too is escaped, so a student cannot forge a line of the table); a CSV cell
keeps its newlines (quoted by the CSV writer), and is neutralised for spreadsheets
(:func:`cvkit.course.safety.csv_safe`). The CSV files are UTF-8.
"""
from __future__ import annotations

import csv
from pathlib import Path
from typing import TYPE_CHECKING, Iterable

from .._text import printable
from .files import whole_file, write_whole
from .progress import Phase
from .results import ExerciseScore, environment, scores, unsandboxed

if TYPE_CHECKING:
    from .state import CourseState


def format_table(scores: dict[str, list[ExerciseScore]], students: Iterable[str] | None = None,
                 not_graded: dict[str, str] | None = None, unsandboxed: Iterable[str] = (),
                 environment: dict[str, list[str]] | None = None, extended: dict[str, str] | None = None) -> str:
    """A plain-text table: one row per exercise, one column per student, totals, mistakes;
    then the submissions that could not be graded (``not_graded``: student → reason, never
    shown as zeros), a loud warning for those graded without the sandbox, and one line per
    thing the grading environment lacked (``environment``: cause → the students whose cells as
    released it stopped), and the students whose due date the plan extends (``extended``: student →
    until when). Every text is shown printable, on its line (see the module docstring)."""
    refused = sorted((printable(s), printable(reason)) for s, reason in (not_graded or {}).items())
    unsandboxed = sorted(printable(s) for s in unsandboxed)
    tail = []
    if extended:
        tail.append("\nExtensions (plan.toml; late penalties count from them):")
        tail += [f"  {printable(s)}: extended to {until}" for s, until in sorted(extended.items())]
    if environment:
        tail.append("\n!! Not the students' doing: the chapter's own cells (as released) failed in the grading "
                    "environment; install what it needs where grading runs, then grade again with --regrade:")
        for cause, who in sorted(environment.items()):
            named = ", ".join(printable(s) for s in who[:6]) + (f" and {len(who) - 6} more" if len(who) > 6 else "")
            tail.append(f"  {printable(cause)}: in {len(who)} submission{'s' * (len(who) != 1)} ({named})")
    if unsandboxed:
        tail.append("\n!! GRADED WITHOUT THE SANDBOX (--no-sandbox): student code ran with the grader's rights for "
                    + ", ".join(unsandboxed))
    if refused:
        tail.append("\nNot graded (no score recorded; fix the cause and grade again):")
        tail += [f"  {s}: not graded: {reason}" for s, reason in refused]
    shown = _shown(scores)
    students = [printable(s) for s in (students or scores) if s in scores]
    if not students:
        return "(no graded submissions)" + "\n".join(tail)
    lines = _grades(shown, students)
    lines += _findings(shown, students)
    return "\n".join(lines + tail)


def _shown(scores: dict[str, list[ExerciseScore]]) -> dict[str, list[ExerciseScore]]:
    """``scores`` with every text in it printable (:func:`cvkit._text.printable`, newlines
    escaped too): the student ids, exercise names, mistakes, problems and flags."""
    def text(items: list) -> list[str]:
        return [printable(item) for item in items]

    return {printable(student): [ExerciseScore(printable(e.name), e.score, e.max_score, text(e.mistakes),
                                               text(e.problems), text(e.flags), e.to_mark) for e in exercises]
            for student, exercises in scores.items()}


def _grades(scores: dict[str, list[ExerciseScore]], students: list[str]) -> list[str]:
    """The table's rows: one per exercise, then the totals."""
    exercises: list[str] = []
    for s in students:
        for e in scores[s]:
            if e.name not in exercises:
                exercises.append(e.name)
    cell = {}
    for s in students:
        for e in scores[s]:
            if e.to_mark:
                cell[(e.name, s)] = f"to mark/{e.max_score:g} ✎"
                continue
            if e.max_score <= 0 and not e.score:
                # a row of flags only (the whole notebook's): no points to show, nothing passed
                cell[(e.name, s)] = "flagged ⚑" if e.flags else "-"
                continue
            mark = "✓" if e.score >= e.max_score - 1e-9 else ("·" if e.score > 0 else "✗")
            cell[(e.name, s)] = f"{e.score:.2f}/{e.max_score:g} {mark}"
    width = max(len(x) for x in exercises + ["exercise"]) + 2
    colw = max(14, *(len(s) + 2 for s in students))
    lines = ["exercise".ljust(width) + "".join(s.rjust(colw) for s in students)]
    lines.append("-" * len(lines[0]))
    for name in exercises:
        lines.append(name.ljust(width) + "".join(cell.get((name, s), "-").rjust(colw) for s in students))
    lines.append("-" * len(lines[0]))
    totals = []
    for s in students:
        got = sum(e.score for e in scores[s] if not e.to_mark)
        top = sum(e.max_score for e in scores[s])
        pending = sum(e.max_score for e in scores[s] if e.to_mark)
        totals.append((f"{got:.2f}/{top:g}" + (f" +{pending:g}✎" if pending else "")).rjust(colw))
    lines.append("total".ljust(width) + "".join(totals))
    if any(e.to_mark for s in students for e in scores[s]):
        lines.append("✎ written answers and open tasks to mark by hand in nbgrader's formgrader "
                     "(`+N✎`: points still to mark); the totals add them once marked")
    return lines


def _findings(scores: dict[str, list[ExerciseScore]], students: list[str]) -> list[str]:
    """Below the table: what the checks found, and the flags for the instructor."""
    lines = []
    notes = []
    for s in students:
        missing = [e.name for e in scores[s] if any(p.startswith("not implemented") for p in e.problems)]
        for e in scores[s]:
            # one line per student × exercise (its visible and hidden tests together): the named
            # mistake(s), else the first problem, in the reports' plain words
            mistakes = list(dict.fromkeys(e.mistakes))
            problems = [p for p in dict.fromkeys(e.problems) if not p.startswith("not implemented")]
            if mistakes:
                notes.append(f"  {s} · {e.name}: mistake{'s' if len(mistakes) > 1 else ''} "
                             + ", ".join(f"“{m}”" for m in mistakes))
            elif problems:
                notes.append(f"  {s} · {e.name}: {problems[0]}")
        if missing:
            shown = ", ".join(missing) if len(missing) <= 4 else f"{len(missing)} exercises"
            notes.append(f"  {s} · not attempted: {shown}")
    if notes:
        lines.append("\nWhat the checks found:")
        lines += notes
    flagged = [f"  {s} · {e.name}: {flag}" for s in students for e in scores[s] for flag in e.flags]
    if flagged:
        lines.append("\nFlags for the instructor (code that tries to get around the grader):")
        lines += flagged
    return lines


def table(course: CourseState, assignment: str) -> str:
    """See :meth:`Course.table`."""
    not_graded = {k.partition("/")[0]: v for k, v in course.not_graded().items() if k.endswith(f"/{assignment}")}
    graded_unsandboxed = sorted(k.partition("/")[0] for k in unsandboxed(course) if k.endswith(f"/{assignment}"))
    lacking = {cause: per[assignment] for cause, per in environment(course, [assignment]).items() if assignment in per}
    plan = course.plan()
    extended = {e.student: f"{e.until:%Y-%m-%d %H:%M} UTC" + (f" ({e.reason})" if e.reason else "")
                for e in plan.extensions if e.assignment == assignment}
    return format_table(scores(course, assignment), not_graded=not_graded, unsandboxed=graded_unsandboxed,
                        environment=lacking, extended=extended)


def export(course: CourseState, progress: bool = False) -> Path:
    """See :meth:`Course.export`."""
    target = course.root / "exports" / "grades.csv"
    target.parent.mkdir(exist_ok=True)
    assignments = sorted({a for _, a in course.submissions()} | {k.partition("/")[2] for k in course.not_graded()})
    with Phase("exports", 1 + len(assignments), progress, unit="file") as bar:
        _export_grades(course, target)
        bar.update()
        _export_exercises(course, course.root / "exports" / "exercises.csv", assignments, bar)
    return target


def _cell(value: object) -> str:
    """A CSV cell of text a student may have written: printable (newlines kept) and never a
    spreadsheet formula."""
    from .safety import csv_safe

    return csv_safe(printable(value, newlines=True)) if isinstance(value, str) else csv_safe(value)


def _export_grades(course: CourseState, target: Path) -> None:
    """nbgrader's grades.csv, with a status column (not graded, graded without the sandbox), and
    a row for each folder refused for its names (:meth:`Course.refused_submissions`: nbgrader
    never sees them), its scores empty."""
    from nbgrader.api import Gradebook
    from nbgrader.plugins import CsvExportPlugin

    with Gradebook(course.db_url) as gradebook:
        CsvExportPlugin(to=str(target)).export(gradebook)
    not_graded = course.not_graded()
    graded_unsandboxed = unsandboxed(course)
    with target.open(newline="", encoding="utf-8", errors="surrogateescape") as handle:
        rows = list(csv.reader(handle))
    if not rows:
        return
    header = rows[0]
    column = {name: i for i, name in enumerate(header)}
    out = [header + ["status"]]
    listed = set()
    for row in rows[1:]:
        key = f"{row[column['student_id']]}/{row[column['assignment']]}" if "student_id" in column else ""
        listed.add(key)
        status = "graded"
        if key in not_graded:
            status = f"not graded: {not_graded[key]}"
            for name in ("raw_score", "score", "late_submission_penalty"):
                if name in column:
                    row[column[name]] = ""
        elif key in graded_unsandboxed:
            status = "graded WITHOUT SANDBOX (--no-sandbox)"
        out.append([_cell(cell) for cell in row] + [_cell(status)])
    if "student_id" in column and "assignment" in column:
        for key, reason in sorted(course.refused_submissions().items()):
            if key not in listed:
                row = [""] * len(header)
                row[column["student_id"]], _, row[column["assignment"]] = key.partition("/")
                out.append([_cell(cell) for cell in row] + [_cell(f"not graded: {reason}")])
    with whole_file(target, newline="") as handle:
        csv.writer(handle).writerows(out)


def _export_exercises(course: CourseState, target: Path, assignments: list[str], bar: Phase) -> None:
    """cvkit's exercises.csv: one row per student × exercise, and one per submission not graded
    (``bar`` counts the assignments written)."""
    not_graded = course.not_graded()
    with whole_file(target, newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["assignment", "student", "exercise", "score", "max_score", "mistakes", "problems", "flags",
                         "status"])
        for assignment in assignments:
            bar.update()
            for student, exercises in scores(course, assignment).items():
                for e in exercises:
                    flags_only = e.max_score <= 0 and not e.score and not e.to_mark  # the "(notebook)" row
                    writer.writerow([_cell(x) for x in (
                        assignment, student, e.name, "" if e.to_mark or flags_only else f"{e.score:g}",
                        "" if flags_only else f"{e.max_score:g}",
                        "; ".join(e.mistakes), "; ".join(e.problems), "; ".join(e.flags),
                        "to mark by hand (formgrader)" if e.to_mark else
                        "flags for the instructor (no points)" if flags_only else "graded")])
            for key, reason in sorted(not_graded.items()):
                student, _, a = key.partition("/")
                if a == assignment:
                    writer.writerow([_cell(x) for x in (assignment, student, "(submission)", "", "", "",
                                                         f"not graded: {reason}", "not graded", "not graded")])


def export_similarity(course: CourseState, assignments: Iterable[str] | None = None, progress: bool = False,
                      position: int | None = None) -> Path:
    """See :meth:`Course.similarity` (``position``: the line of its progress bar, below the bars
    of a grading run it goes along with)."""
    from . import similarity

    planned = set(course.plan().ids())
    chosen = sorted(set(assignments) if assignments is not None
                    else {a for _, a in course.submissions() if a in planned})
    pairs = []
    with Phase("similarity", len(chosen), progress, unit="assignment", position=position) as bar:
        for assignment in chosen:
            bar.describe(f"similarity {assignment}")
            pairs += _similar_pairs(course, assignment)
            bar.update()
    groups = similarity.groups(pairs)
    folder = course.root / "exports"
    similarity.write_html(groups, folder / "similarity.html")
    return similarity.write_csv(groups, folder / "similarity.csv")


SIMILARITY_CACHE = "similarity"  # .cvkit/similarity/<assignment>.json: the last pairs of each assignment


def _similar_pairs(course: CourseState, assignment: str) -> list:
    """:func:`cvkit.course.similarity.report` of one assignment, measured again only when what it
    compares changed. Reading the answers is cheap; measuring them (tokenizing every answer, the
    stubs and the references) is not, and a grading run exports every assignment's report while
    it has graded one. The pairs are kept in ``.cvkit/similarity/<assignment>.json`` with the
    digest of everything they depend on — the answers and exercises as read, the threshold, and
    the code that measures them (this module's and copydetect's and Pygments' versions) — and
    reused while the digest is the same."""
    import dataclasses
    import hashlib
    import json
    from importlib.metadata import version

    from . import similarity

    answers, exercises = similarity.report_inputs(course.root, course.source_dir, assignment)
    digest = hashlib.sha256(json.dumps({
        "answers": {s: {e: [a.text, list(a.pulled)] for e, a in sorted(found.items())} for s, found in sorted(answers.items())},
        "exercises": {e: dataclasses.asdict(x) for e, x in sorted(exercises.items())},
        "assignment": assignment, "threshold": similarity.THRESHOLD, "min_size": similarity.MIN_SIZE,
        "code": hashlib.sha256(Path(similarity.__file__).read_bytes()).hexdigest(),
        "copydetect": version("copydetect"), "pygments": version("pygments"),
    }, sort_keys=True).encode()).hexdigest()
    path = course.root / ".cvkit" / SIMILARITY_CACHE / f"{assignment}.json"
    try:
        kept = json.loads(path.read_text(encoding="utf-8"))
        if kept.get("digest") == digest:
            return [similarity.SimilarPair(**dict(p, a_pulled=tuple(p["a_pulled"]), b_pulled=tuple(p["b_pulled"])))
                    for p in kept["pairs"]]
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        pass  # none kept, or unreadable: measured again
    pairs = similarity.similar_pairs(answers, exercises, assignment=assignment)
    write_whole(path, json.dumps({"digest": digest, "pairs": [dataclasses.asdict(p) for p in pairs]}))  # ASCII
    return pairs


def similar_pairs(course: CourseState) -> list[dict[str, str]]:
    """The rows of the last similarity report (``exports/similarity.csv``): one per student of
    each group of similar answers, the groups in the page's order, as dicts with the columns of
    :data:`cvkit.course.similarity.CSV_COLUMNS` (``assignment``, ``exercise``, ``cluster``,
    ``students``, ``student``, ``closest``, ``similarity``, ``textbook``, ``added_code``)."""
    path = course.root / "exports" / "similarity.csv"
    if not path.is_file():
        return []
    with path.open(newline="", encoding="utf-8", errors="surrogateescape") as handle:  # raw bytes of a name
        return list(csv.DictReader(handle))


def similarity_summary(course: CourseState, top: int = 5) -> list[str]:
    """A few lines for ``cvkit course grade``'s summary: how many groups of similar answers,
    the ``top`` ones (groups of students first, textbook groups after)."""
    rows = similar_pairs(course)
    path = course.root / "exports" / "similarity.html"
    clusters: dict[str, list[dict[str, str]]] = {}
    for row in rows:
        clusters.setdefault(row.get("cluster") or "", []).append(row)
    if not clusters:
        return [f"similar answers: none above the threshold ({path})"]
    textbook = sum(bool(members[0].get("textbook")) for members in clusters.values())
    students = len(rows)
    kinds = [f"{students} student answer{'s' * (students != 1)} in all"]
    kinds += [f"{textbook} close to the instructor's solution or the reference"] if textbook else []
    lines = [f"similar answers: {len(clusters)} group{'s' * (len(clusters) != 1)} ({', '.join(kinds)}; a signal "
             f"for the instructor, never a score change): {path}"]
    for members in list(clusters.values())[:top]:
        first = members[0]
        names = [printable(m.get("student", "")) for m in members]
        shown = " ↔ ".join(names[:3]) + (f" (+{len(names) - 3} more)" if len(names) > 3 else "")
        if first.get("textbook"):
            shown += f" ≈ {printable(first['textbook'])}"
        best = max(float(m.get("similarity") or 0.0) for m in members)
        assignment, exercise = printable(first.get("assignment", "")), printable(first.get("exercise", ""))
        lines.append(f"  {best:>4.0%}  {assignment} · {exercise}: {shown}")
    if len(clusters) > top:
        lines.append(f"  ... and {len(clusters) - top} more in {path.name}")
    return lines
