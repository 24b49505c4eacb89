"""Opt-in leaderboards of the measured exercises (``plan.toml`` ``[leaderboard]``, off by default).

A *measured* exercise is one whose check has :attr:`~cvkit.grading.Check.credit` (Chapter 12's
``train.train_digits``: the points follow the accuracy a student's network reaches on digits they
never saw). For each assignment with one, the course can rank the students **who asked for it**
by the value measured on their **hidden** cases, under a **pseudonym** they chose:

- **Opting in** is the student's act, in their own hand-in: the chapter has a released cell
  ``LEADERBOARD = {"join": False, "pseudonym": ""}`` (no points). The course reads that
  dictionary from the submitted notebook's text (:func:`read_opt_in`: parsed, never run); a
  student who left ``"join"`` false, deleted the cell or wrote something unreadable is not on
  the board. Only a literal ``True`` joins.
- **Pseudonyms only.** A pseudonym is left out (:func:`pseudonym_problem`), and the
  instructor's summary says why, when it is empty, longer than :data:`MAX_PSEUDONYM`
  characters, holds control, bidi or invisible characters or anything but letters, digits,
  spaces and ``_ - . '``, equals or looks like a student id (compared after removing invisible
  characters, Unicode compatibility forms, case, spaces and punctuation; containing an id, or
  being a piece of four characters or more of one, counts) or a student's first or last name
  in the gradebook. When two students choose the same pseudonym (compared the same way),
  **both** are left out: "first come" would rank one student under a name another chose, and
  hand-in order is not something either controls.
- **What is ranked**: per measured exercise, the mean over the hidden cases of the value the
  check measures (:attr:`~cvkit.grading.Check.measure`, e.g. the accuracy in %, kept in the
  report's data as ``CaseResult.measure``); a measured check without a ``measure`` is ranked by
  the share of the points its hidden cases earned. Values are rounded to two decimals of their
  unit before ranking, so that equal-looking values share their rank ("1, 2, 2, 4"). A student
  whose hidden report has no value for every case (a crash, the time limit), was graded on the
  visible cases instead, or whose exercise was flagged for review is left out of that table.
- **Never a handful.** An exercise's table is shown only when at least ``min_entries``
  students are on it (default :data:`DEFAULT_MIN_ENTRIES`, never fewer than
  :data:`MIN_ENTRIES_FLOOR`): with two, each would know the other's result. An assignment with
  no table big enough gets no page at all (and pages written before are removed).

Outputs (when enabled): ``leaderboard/<assignment>.html`` (static, no script, a
Content-Security-Policy that allows none, every text escaped) and ``leaderboard/<assignment>.csv``
in the course folder (no student id in either); the same tables at the end of each student's
feedback pages of the assignment (a ``<section class="cvkit-leaderboard">``, their own row marked;
a student who asked to be on it and is not reads why, in words that name no one else),
since nbgrader's exchange hands a student back only the pages of the notebooks they submitted; and
the instructor's summary (who was left out and why, by student id) in
``exports/leaderboard_summary.txt``. A course turns it on in its ``plan.toml``::

    [leaderboard]
    enabled = true
    min_entries = 5     # optional; at least 3

It is written by ``cvkit course grade`` and ``cvkit course refresh`` (one line in each, in
:mod:`cvkit.course.parallel`) and by ``cvkit course leaderboard``. It is idempotent: turned off,
or below the minimum, it removes what it wrote before. Off by default because publishing a
ranking, even pseudonymous and opt-in, is a decision of the course's (its institution's rules
on students' results), not of the kit.
"""
from __future__ import annotations

import ast
import csv
import html
import json
import re
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping, NamedTuple

from .._text import name_problem, printable, skeleton
from ..grading.report import MIME_TYPE
from ..grading.runtime.cells import cell_source, cells_of, is_code
from .files import whole_file, write_whole
from .notebook import cell_outputs, exercise_name
from .plan import plan_data, switch_table

if TYPE_CHECKING:
    from .state import CourseState

TABLE = "leaderboard"
VARIABLE = "LEADERBOARD"
#: the released cell, as the chapters hold it (and :func:`read_opt_in` reads it back)
CELL = f'{VARIABLE} = {{"join": False, "pseudonym": ""}}'
FOLDER = "leaderboard"
SUMMARY_NAME = "leaderboard_summary.txt"
DEFAULT_MIN_ENTRIES = 3
MIN_ENTRIES_FLOOR = 3
MAX_PSEUDONYM = 24
DIGITS = 2  # of the measure's unit: what the page shows, and what ties are decided on
_PUNCTUATION = frozenset(" _-.'")
_LARGEST_CELL = 20_000
_SECTION = re.compile(r"<section class=\"cvkit-leaderboard\".*?</section>", re.S)


# ------------------------------------------------------------------------------ settings
class Settings(NamedTuple):
    """The ``[leaderboard]`` table: on or off, and how many students a table needs to be shown."""

    enabled: bool = False
    min_entries: int = DEFAULT_MIN_ENTRIES


def settings(data: Mapping[str, Any], where: str = "plan.toml") -> Settings:
    """The ``[leaderboard]`` table of a plan's TOML ``data`` (absent: off); a ValueError names the
    key whose value is not what it should be (:func:`cvkit.course.plan.switch_table`)."""
    return Settings(*switch_table(data, TABLE, "min_entries", DEFAULT_MIN_ENTRIES, MIN_ENTRIES_FLOOR,
                                  "with fewer, each student on the board knows the others' results", where))


def read_settings(path: Path) -> Settings:
    """:func:`settings` of a ``plan.toml`` (off when there is none, or Python cannot read TOML)."""
    return settings(plan_data(path), str(path))


# ------------------------------------------------------------------------------ the student's choice
@dataclass(frozen=True)
class OptIn:
    """What a hand-in's ``LEADERBOARD`` cell says: ``join`` and ``pseudonym``, or ``problem``
    (why it could not be read: then the student is not on the board)."""

    join: bool = False
    pseudonym: str = ""
    problem: str | None = None


def _literal(node: ast.expr) -> OptIn:
    try:
        value = ast.literal_eval(node)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        return OptIn(problem=f"{VARIABLE} is not a plain dictionary (the course reads it, it does not run it)")
    if not isinstance(value, dict) or not set(value) <= {"join", "pseudonym"}:
        return OptIn(problem=f'{VARIABLE} must be a dictionary with the keys "join" and "pseudonym" only')
    join, pseudonym = value.get("join", False), value.get("pseudonym", "")
    if not isinstance(join, bool) or not isinstance(pseudonym, str):
        return OptIn(problem=f'{VARIABLE}: "join" must be True or False and "pseudonym" a string')
    return OptIn(join, pseudonym)


def opt_ins_in(source: str) -> list[OptIn]:
    """Every top-level ``LEADERBOARD = {...}`` of one code cell's ``source``, read as a literal
    (IPython's ``%`` and ``!`` lines are skipped; nothing is run)."""
    if VARIABLE not in source:
        return []
    if len(source) > _LARGEST_CELL:
        return [OptIn(problem=f"the cell that sets {VARIABLE} is too long to read")]
    plain = "\n".join("" if line.lstrip().startswith(("%", "!")) else line for line in source.splitlines())
    try:
        tree = ast.parse(plain)
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        return [OptIn(problem=f"the cell that sets {VARIABLE} is not valid Python")]
    found = []
    for node in tree.body:
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            targets, value = [node.target], node.value
        else:
            continue
        if any(isinstance(t, ast.Name) and t.id == VARIABLE for t in targets):
            found.append(_literal(value))
    return found


def read_opt_in(folder: Path) -> OptIn | None:
    """The ``LEADERBOARD`` setting of the hand-in in ``folder`` (its notebooks' code cells, in
    order), None when it has none. Set more than once to different values: not on the board
    (a doubt about consent counts as no)."""
    found: list[OptIn] = []
    for path in sorted(folder.glob("*.ipynb")):
        try:
            notebook = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        for cell in cells_of(notebook):  # hand-edited JSON: what is not a cell is left out
            if is_code(cell):
                found += opt_ins_in(cell_source(cell))  # a source that is not text reads as empty
    if not found:
        return None
    if len(set(found)) > 1:
        return OptIn(problem=f"the hand-in sets {VARIABLE} more than once, differently")
    return found[0]


def _key(text: str) -> str:
    """How two names are compared: invisible characters, compatibility forms, case, spaces and
    punctuation removed."""
    return "".join(c for c in skeleton(text).casefold() if c.isalnum())


def pseudonym_problem(pseudonym: str, student_ids: Iterable[str], names: Iterable[str] = ()) -> str | None:
    """Why ``pseudonym`` cannot be shown (None when it can): see the module docstring. The answer
    names no student."""
    text = pseudonym.strip()
    if not text:
        return "the pseudonym is empty"
    problem = name_problem(text)
    if problem:
        return f"the pseudonym {problem}"
    if len(text) > MAX_PSEUDONYM:
        return f"the pseudonym is longer than {MAX_PSEUDONYM} characters"
    key = _key(text)
    if not key:
        return "the pseudonym has no letter or digit"
    for student in student_ids:
        other = _key(student)
        if other and (other == key or (len(other) >= 3 and other in key) or (len(key) >= 4 and key in other)):
            return "the pseudonym looks like a student id"
    for name in names:
        other = _key(name)
        if len(other) >= 3 and other in key:
            return "the pseudonym holds a student's name"
    odd = sorted({c for c in text if not (c.isalnum() or c in _PUNCTUATION)})
    if odd:
        return ("the pseudonym holds characters other than letters, digits, spaces and _ - . ' "
                f"({printable(' '.join(odd[:5]))})")
    return None


def roster_names(course: CourseState) -> list[str]:
    """The students' first and last names the gradebook holds (none when it has none or cannot
    be read; an SQLite gradebook that does not exist yet is not created)."""
    url = course.db_url
    if url.startswith("sqlite:///") and not Path(url[len("sqlite:///"):]).is_file():
        return []
    try:
        from nbgrader.api import Gradebook

        with Gradebook(url) as gradebook:
            return [n for s in gradebook.students for n in (s.first_name, s.last_name) if isinstance(n, str) and n]
    except Exception:  # noqa: BLE001 - no names to compare with: the ids still are
        return []


# ------------------------------------------------------------------------------ measured values
@dataclass(frozen=True)
class Value:
    """A student's measured value on one exercise's hidden cases."""

    name: str
    unit: str
    higher_is_better: bool
    value: float


@lru_cache(maxsize=None)
def is_measured(algorithm_id: str) -> bool:
    """True when ``algorithm_id``'s registered check is measured (:attr:`Check.credit` set)."""
    from ..registry import get

    try:
        return getattr(get(algorithm_id).check, "credit", None) is not None
    except Exception:  # noqa: BLE001 - an id the registry does not know (any more) is not ranked
        return False


def _case_value(case: Mapping[str, Any]) -> tuple[str, str, bool, float] | None:
    measure = case.get("measure")
    if isinstance(measure, Mapping) and isinstance(measure.get("value"), (int, float)) \
            and not isinstance(measure.get("value"), bool) and isinstance(measure.get("name"), str):
        return (str(measure["name"]), str(measure.get("unit", "")), measure.get("better", "higher") != "lower",
                float(measure["value"]))
    credit = case.get("credit")
    if isinstance(credit, (int, float)) and not isinstance(credit, bool):
        return ("share of the points", "%", True, 100.0 * float(credit))
    return None


def _flags(folder: Path) -> dict[str, list[str]]:
    """exercise → what the trusted grader flagged on its cells (``metadata.cvkit.flags``)."""
    found: dict[str, list[str]] = {}
    for path in sorted(folder.glob("*.ipynb")):
        try:
            flags = json.loads(path.read_text(encoding="utf-8")).get("metadata", {}).get("cvkit", {}).get("flags", [])
        except (OSError, ValueError, AttributeError):
            continue
        for flag in flags if isinstance(flags, list) else []:
            cell, _, what = str(flag).partition(": ")
            found.setdefault(exercise_name(cell, answers=False), []).append(what)
    return found


def measured_values(folder: Path) -> tuple[dict[str, Value], dict[str, str]]:
    """From one autograded submission's notebooks: algorithm id → the measured :class:`Value` of
    each measured exercise's hidden report, and algorithm id → why there is none to rank. Only
    the reports the trusted grader wrote into the test cells count: an answer cell's outputs are
    the student's code's, and could display a report of its own making."""
    values: dict[str, Value] = {}
    missing: dict[str, str] = {}
    flags = _flags(folder)
    for cell_id, output in cell_outputs(folder, trusted=True):
        report = (output.get("data") or {}).get(MIME_TYPE)
        if not cell_id or not isinstance(report, dict) or report.get("hidden") is not True:
            continue
        algorithm = str(report.get("algorithm") or "")
        cases = [c for c in report.get("cases") or [] if isinstance(c, dict)]
        if not algorithm or not (is_measured(algorithm) or any("measure" in c for c in cases)):
            continue
        found = [_case_value(c) for c in cases]
        flagged = flags.get(exercise_name(cell_id, answers=False))
        if report.get("problem"):
            missing[algorithm] = f"not graded ({printable(report['problem'])})"
        elif report.get("fallback"):
            missing[algorithm] = "graded on the visible cases, not the hidden ones"
        elif flagged:
            missing[algorithm] = f"flagged for review ({printable(flagged[0])})"
        elif not found or any(f is None for f in found) or len({f[:3] for f in found if f}) > 1:
            missing[algorithm] = "no measured value on every hidden case (a crash or the time limit)"
        else:
            first = found[0]
            assert first is not None
            values[algorithm] = Value(first[0], first[1], first[2], sum(f[3] for f in found if f) / len(found))
    return values, missing


# ------------------------------------------------------------------------------ ranking
def rank(values: Mapping[str, float], higher_is_better: bool = True, digits: int = DIGITS
         ) -> list[tuple[int, str, float]]:
    """(rank, pseudonym, value rounded to ``digits``) by rank, ties sharing their rank
    ("competition" ranking: 1, 2, 2, 4); equal values are listed by pseudonym."""
    rounded = {name: round(float(v), digits) for name, v in values.items()}
    order = sorted(rounded.items(), key=lambda nv: (-nv[1] if higher_is_better else nv[1], nv[0].casefold(), nv[0]))
    ranked: list[tuple[int, str, float]] = []
    for position, (name, value) in enumerate(order):
        shared = ranked[-1][0] if ranked and ranked[-1][2] == value else position + 1
        ranked.append((shared, name, value))
    return ranked


@dataclass
class Table:
    """One measured exercise's ranking."""

    algorithm: str
    measure: str
    unit: str
    higher_is_better: bool
    rows: list[tuple[int, str, float]]

    @property
    def heading(self) -> str:
        unit = f" ({self.unit})" if self.unit else ""
        return f"{self.algorithm}: {self.measure}{unit}, {'higher' if self.higher_is_better else 'lower'} is better"


@dataclass
class Board:
    """The leaderboard of one assignment: the tables shown, and for the instructor only who was
    left out and why (``left_out``: student id → reason) and whose pseudonym is whose
    (``pseudonyms``: student id → pseudonym, to mark a student's own row on their page); and for
    each student who asked to be on it and is not, the sentence their own page shows (``notes``:
    student id → why, in words that name no one else and tell nothing the grader keeps for the
    instructor)."""

    assignment: str
    min_entries: int
    tables: list[Table] = field(default_factory=list)
    hidden_tables: dict[str, int] = field(default_factory=dict)  # algorithm → entries, below the minimum
    left_out: dict[str, str] = field(default_factory=dict)
    pseudonyms: dict[str, str] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    measured: bool = False  # the assignment has a measured exercise

    @property
    def published(self) -> bool:
        return bool(self.tables)


def build(course: CourseState, assignment: str, min_entries: int = DEFAULT_MIN_ENTRIES) -> Board:
    """The :class:`Board` of ``assignment`` from the course's hand-ins and autograded notebooks."""
    board = Board(assignment, min_entries)
    not_graded = course.not_graded()
    students = sorted(s for s, a in course.submissions([assignment]) if f"{s}/{a}" not in not_graded)
    ids = {s for s, _ in course.submissions()} | {key.partition("/")[0] for key in not_graded}
    names = roster_names(course)
    chosen: dict[str, str] = {}
    values: dict[str, dict[str, Value]] = {}
    for student in students:
        found, missing = measured_values(course.root / "autograded" / student / assignment)
        board.measured = board.measured or bool(found) or bool(missing)
        opt_in = read_opt_in(course.root / "submitted" / student / assignment)
        if opt_in is None or (opt_in.problem is None and not opt_in.join):
            continue
        problem = opt_in.problem or pseudonym_problem(opt_in.pseudonym, ids, names)
        if problem:
            board.left_out[student] = board.notes[student] = problem
            continue
        chosen[student] = opt_in.pseudonym.strip()
        values[student] = found
        for algorithm, why in missing.items():
            board.left_out.setdefault(student, f"{algorithm}: {why}")
            board.notes.setdefault(student, f"{algorithm} is not ranked for you this time: "
                                   + ("ask your instructor why" if why.startswith("flagged") else why))
    keys: dict[str, list[str]] = {}
    for student, pseudonym in chosen.items():
        keys.setdefault(_key(pseudonym), []).append(student)
    for group in keys.values():
        if len(group) > 1:
            for student in group:
                board.left_out[student] = f"the pseudonym is also the choice of {len(group) - 1} other student" \
                                          f"{'s' * (len(group) > 2)} (all of them are left out)"
                board.notes[student] = ("someone else chose the same pseudonym, so neither is shown: choose one "
                                        "nobody else would think of")
                chosen.pop(student)
    board.pseudonyms = dict(chosen)
    algorithms = sorted({a for student in chosen for a in values[student]})
    for algorithm in algorithms:
        entries = {chosen[s]: values[s][algorithm] for s in chosen if algorithm in values[s]}
        first = next(iter(entries.values()))
        kinds = {(v.name, v.unit, v.higher_is_better) for v in entries.values()}
        if len(kinds) > 1:  # graded under two versions of the check: the most common kind is ranked
            common = max(kinds, key=lambda k: sum((v.name, v.unit, v.higher_is_better) == k for v in entries.values()))
            for student in chosen:
                v = values[student].get(algorithm)
                if v is not None and (v.name, v.unit, v.higher_is_better) != common:
                    board.left_out.setdefault(student, f"{algorithm}: graded under another version of the check "
                                                       "(regrade the chapter)")
            entries = {p: v for p, v in entries.items() if (v.name, v.unit, v.higher_is_better) == common}
            first = next(iter(entries.values()))
        if len(entries) < min_entries:
            board.hidden_tables[algorithm] = len(entries)
            continue
        board.tables.append(Table(algorithm, first.name, first.unit, first.higher_is_better,
                                  rank({p: v.value for p, v in entries.items()}, first.higher_is_better)))
    return board


# ------------------------------------------------------------------------------ pages
def _number(value: float) -> str:
    return f"{value:.{DIGITS}f}"


def fragment(board: Board, own: str | None = None, note: str | None = None) -> str:
    """The tables as an HTML section (escaped text only; what :func:`cvkit.course.safety.
    sanitize_html` keeps as it is for a trusted report); ``own``: the pseudonym whose row is
    marked "(you)"; ``note``: why the reader, who asked to be on the board, is not."""
    parts = [f"<section class=\"cvkit-leaderboard\" aria-label=\"Leaderboard of {html.escape(board.assignment)}\">",
             f"<p class=\"cvkit-leaderboard-title\"><b>Leaderboard of {html.escape(board.assignment, quote=False)}"
             "</b></p>",
             "<p>Students who chose to take part, under the pseudonym they picked, ranked by what their work "
             "achieved on their own hidden cases. Equal values share a rank. It changes nothing in anyone's "
             "grade.</p>"]
    if note:
        parts.append(f"<p class=\"cvkit-leaderboard-note\">You asked to be on this board, but you are not on it: "
                     f"{html.escape(printable(note), quote=False)}.</p>")
    for table in board.tables:
        parts.append(f"<table><caption>{html.escape(table.heading, quote=False)}</caption><thead><tr>"
                     f"<th scope=\"col\">rank</th><th scope=\"col\">pseudonym</th>"
                     f"<th scope=\"col\">{html.escape(table.measure, quote=False)}</th></tr></thead><tbody>")
        for position, pseudonym, value in table.rows:
            mine = own is not None and pseudonym == own
            name = html.escape(printable(pseudonym), quote=False) + (" <b>(you)</b>" if mine else "")
            parts.append(f"<tr><td>{position}</td><td>{name}</td><td>{_number(value)}</td></tr>")
        parts.append("</tbody></table>")
    parts.append("</section>")
    return "".join(parts)


_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="default-src 'none'; style-src 'unsafe-inline'">
<title>Leaderboard of {assignment}</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; color: #1f2328; background: #ffffff; max-width: 48em; }}
table {{ border-collapse: collapse; margin: 0.5em 0 1.5em; }}
caption {{ text-align: left; font-weight: bold; padding: 0.3em 0; }}
td, th {{ padding: 0.2em 0.8em; text-align: left; border-bottom: 1px solid #d0d7de; }}
td:first-child, td:last-child {{ text-align: right; }}
</style></head><body>
{body}
</body></html>
"""


def page(board: Board) -> str:
    """The standalone page ``leaderboard/<assignment>.html`` (no script, no student id)."""
    from .safety import sanitize_html

    return _PAGE.format(assignment=html.escape(board.assignment),
                        body=sanitize_html(fragment(board), trusted_report=True))


CSV_COLUMNS = ["assignment", "exercise", "measure", "unit", "rank", "pseudonym", "value"]


def write_csv(board: Board, path: Path) -> Path:
    """The tables, one row per entry (texts printable, never a spreadsheet formula)."""
    from .safety import csv_safe

    with whole_file(path, newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(CSV_COLUMNS)
        for table in board.tables:
            for position, pseudonym, value in table.rows:
                writer.writerow([csv_safe(printable(c)) if isinstance(c, str) else csv_safe(c) for c in
                                 (board.assignment, table.algorithm, table.measure, table.unit, position, pseudonym,
                                  _number(value))])
    return path


def with_board(text: str, section: str | None) -> str:
    """A feedback page's HTML with ``section`` at the end of its body (None: without one), and
    without the one written before."""
    text = _SECTION.sub("", text)
    if not section:
        return text
    end = text.rfind("</body>")
    return text + section if end < 0 else text[:end] + section + text[end:]


def _annotate_pages(course: CourseState, board: Board | None, assignment: str) -> int:
    from .safety import sanitize_html

    pages = 0
    for path in sorted((course.root / "feedback").glob(f"*/{assignment}/*.html")):
        student = path.parent.parent.name
        section = None
        if board is not None and board.published:
            section = sanitize_html(fragment(board, board.pseudonyms.get(student), board.notes.get(student)),
                                    trusted_report=True)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            continue
        changed = with_board(text, section)
        if changed != text:
            write_whole(path, changed, mode=path.stat().st_mode & 0o777)
            pages += 1
    return pages


def _remove(course: CourseState, assignment: str) -> None:
    for suffix in (".html", ".csv"):
        (course.root / FOLDER / f"{assignment}{suffix}").unlink(missing_ok=True)
    _annotate_pages(course, None, assignment)


def _assignments(course: CourseState) -> list[str]:
    try:
        planned = list(course.plan().ids())
    except (OSError, ValueError):
        planned = []
    graded = sorted(p.name for p in (course.root / "autograded").glob("*/*") if p.is_dir())
    written = sorted(p.stem for p in (course.root / FOLDER).glob("*.html"))
    return list(dict.fromkeys(planned + graded + written))


def summary(board: Board) -> list[str]:
    """The instructor's lines about one board (student ids printable: for the instructor only)."""
    name = printable(board.assignment)
    lines = []
    if board.published:
        shown = ", ".join(f"{printable(t.algorithm)} ({len(t.rows)})" for t in board.tables)
        lines.append(f"leaderboard {name}: {FOLDER}/{name}.html, {shown} entries; on the students' feedback pages")
    else:
        lines.append(f"leaderboard {name}: not published ({len(board.pseudonyms)} student"
                     f"{'s' * (len(board.pseudonyms) != 1)} opted in with a usable pseudonym; a table needs at "
                     f"least {board.min_entries})")
    for algorithm, count in sorted(board.hidden_tables.items()):
        lines.append(f"  {printable(algorithm)}: not shown, {count} entr{'ies' if count != 1 else 'y'} (at least "
                     f"{board.min_entries} needed)")
    for student, why in sorted(board.left_out.items()):
        lines.append(f"  left out: {printable(student)}: {printable(why)}")
    return lines


def publish(course: CourseState, assignments: Iterable[str] | None = None, chosen: Settings | None = None) -> list[str]:
    """Write (or remove) the leaderboards of ``assignments`` (default: every assignment of the plan
    or with autograded hand-ins) as the course's ``[leaderboard]`` says (or ``chosen``).

    Returns
    -------
    list of str
        Lines for the instructor (also in ``exports/leaderboard_summary.txt`` when enabled): what
        was published, and who was left out and why. A plan that cannot be read is named, never a
        crash at the end of grading.
    """
    try:
        chosen = chosen or read_settings(Path(course.plan_path))
    except ValueError as error:
        return [f"leaderboard: not written: {error}"]
    report = course.root / "exports" / SUMMARY_NAME
    names = list(dict.fromkeys(assignments)) if assignments is not None else _assignments(course)
    if not chosen.enabled:
        if not (course.root / FOLDER).is_dir() and not report.is_file():
            return [f"leaderboard: off (plan.toml [{TABLE}] enabled = true turns it on)"]  # nothing to take back
        for assignment in names:
            _remove(course, assignment)
        report.unlink(missing_ok=True)
        return [f"leaderboard: off (plan.toml [{TABLE}] enabled = true turns it on)"]
    lines = []
    for assignment in names:
        board = build(course, assignment, chosen.min_entries)
        if not board.measured:
            _remove(course, assignment)
            continue
        if board.published:
            folder = course.root / FOLDER
            write_whole(folder / f"{assignment}.html", page(board))
            write_csv(board, folder / f"{assignment}.csv")
            _annotate_pages(course, board, assignment)
        else:
            _remove(course, assignment)
        lines += summary(board)
    if not lines:
        lines = ["leaderboard: no graded assignment has a measured exercise"]
    write_whole(report, "\n".join(lines) + "\n")
    return lines


def saved_summary(course: CourseState) -> list[str]:
    """The lines of the last :func:`publish` (for the summary after ``cvkit course grade``)."""
    try:
        return (course.root / "exports" / SUMMARY_NAME).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return []
