"""Class-wide notes in the hand-back (optional, off by default): next to a named mistake, the
feedback page may say "41 % of the class made this mistake too".

Aggregate only: a share of the students graded on the assignment, rounded to a whole percent,
never a name nor anything of another student's answer; shown only when the class has at least
``min_class`` students (never fewer than :data:`MIN_CLASS_FLOOR`) and at least one other student
made the same mistake. A course turns it on in its ``plan.toml``::

    [class_notes]
    enabled = true
    min_class = 20      # optional; at least 10

Where it hooks in: :func:`annotate_feedback` runs after the feedback pages and the exports are
written (:func:`cvkit.course.parallel.grade` and :func:`~cvkit.course.parallel.refresh`, one
line each). It edits the pages already made safe by :mod:`cvkit.course.safety` in place: after
each trusted report's paragraph ``<p class="cvkit-mistake">`` it inserts one escaped paragraph
``<p class="cvkit-class-note">`` (no markup of its own beyond that, no script, no link). It is
idempotent: notes written before are removed first, so turning the option off removes them.
"""
from __future__ import annotations

import html
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

from ..grading.report import MIME_TYPE
from .files import write_whole
from .notebook import cell_outputs
from .plan import plan_data, switch_table

if TYPE_CHECKING:
    from .state import CourseState

#: the smallest class a course may ask notes for (below, a share says too much about a few people)
MIN_CLASS_FLOOR = 10
DEFAULT_MIN_CLASS = 20
TABLE = "class_notes"

_SECTION = re.compile(r"<section class=\"cvkit-report[^\"]*\"[^>]*>.*?</section>", re.S)
_ALGORITHM = re.compile(r"aria-label=\"([A-Za-z0-9_.]+) \(")
_MISTAKE = re.compile(r"(<p class=\"cvkit-mistake\">.*?<b>(.*?)</b>.*?</p>)", re.S)
_NOTE = re.compile(r"<p class=\"cvkit-class-note\">[^<]*</p>")


@dataclass(frozen=True)
class Settings:
    enabled: bool = False
    min_class: int = DEFAULT_MIN_CLASS


def settings(data: Mapping[str, Any], where: str = "plan.toml") -> Settings:
    """The ``[class_notes]`` table of a plan's TOML data (absent: off).

    Raises
    ------
    ValueError
        Naming the key, when ``enabled`` is not true/false or ``min_class`` not a whole number of
        at least :data:`MIN_CLASS_FLOOR`, or the table has another key.
    """
    return Settings(*switch_table(data, TABLE, "min_class", DEFAULT_MIN_CLASS, MIN_CLASS_FLOOR,
                                  "fewer students and a share says too much about each", where))


def read_settings(path: Path) -> Settings:
    """:func:`settings` of a ``plan.toml`` (off when there is none)."""
    return settings(plan_data(path), str(path))


def mistake_shares(named: Mapping[str, Iterable[tuple[str, str]]], min_class: int = DEFAULT_MIN_CLASS
                   ) -> dict[tuple[str, str], tuple[int, int]]:
    """(algorithm, mistake) → (students who made it, class size), from student → the (algorithm,
    mistake) pairs their reports named; empty when the class is smaller than ``min_class``, and
    without a mistake only one student made (the note says "too")."""
    size = len(named)
    if size < max(2, min_class):
        return {}
    counts: dict[tuple[str, str], int] = {}
    for pairs in named.values():
        for pair in set(pairs):
            counts[pair] = counts.get(pair, 0) + 1
    return {pair: (count, size) for pair, count in counts.items() if count >= 2}


def note(count: int, size: int) -> str:
    """The words of a note: "41 % of the class made this mistake too." (rounded down below 100 %,
    so that a share never reads as everyone when it is not)."""
    percent = 100 * count // size if count < size else 100
    if percent < 1:
        return "A few others in the class made this mistake too."
    return f"{percent} % of the class made this mistake too."


def annotate(page: str, shares: Mapping[tuple[str, str], tuple[int, int]]) -> str:
    """``page`` (a feedback page's HTML) with the notes of ``shares`` after each named mistake of a
    trusted report, and without the notes it had."""
    page = _NOTE.sub("", page)
    if not shares:
        return page

    def section(match: re.Match) -> str:
        text = match.group(0)
        found = _ALGORITHM.search(text[:text.find(">") + 1])
        if not found:
            return text

        def mistake(m: re.Match) -> str:
            share = shares.get((found.group(1), html.unescape(m.group(2))))
            if share is None:
                return m.group(1)
            return m.group(1) + f"<p class=\"cvkit-class-note\">{html.escape(note(*share))}</p>"

        return _MISTAKE.sub(mistake, text)

    return _SECTION.sub(section, page)


def named_mistakes(folder: Path) -> set[tuple[str, str]]:
    """The (algorithm, mistake) pairs the trusted reports of one submission's autograded notebooks
    named (their test cells' outputs)."""
    found: set[tuple[str, str]] = set()
    for _, output in cell_outputs(folder):
        report = (output.get("data") or {}).get(MIME_TYPE)
        if isinstance(report, dict) and report.get("mistake") and report.get("algorithm"):
            found.add((str(report["algorithm"]), str(report["mistake"])))
    return found


def annotate_feedback(course: CourseState, assignments: Iterable[str] | None = None,
                      chosen: Settings | None = None) -> list[str]:
    """Write (or remove) the class-wide notes on the feedback pages of ``assignments`` (default:
    every assignment with feedback) as the course's ``[class_notes]`` says (or ``chosen``).

    Returns
    -------
    list of str
        Lines for the instructor: what was done, or why nothing was (a plan that cannot be read
        is named, never a crash at the end of grading).
    """
    try:
        chosen = chosen or read_settings(Path(course.plan_path))
    except ValueError as error:
        return [f"class-wide notes: not written: {error}"]
    feedback = course.root / "feedback"
    graded = course.root / "autograded"
    lines = []
    found = sorted({p.name for p in feedback.glob("*/*") if p.is_dir()})
    not_graded = course.not_graded() if chosen.enabled else {}
    for assignment in sorted(set(assignments) if assignments is not None else found):
        named = {folder.parent.name: named_mistakes(folder) for folder in sorted(graded.glob(f"*/{assignment}"))
                 if f"{folder.parent.name}/{assignment}" not in not_graded} if chosen.enabled else {}
        shares = mistake_shares(named, chosen.min_class)
        pages = 0
        for page in sorted(feedback.glob(f"*/{assignment}/*.html")):
            text = page.read_text(encoding="utf-8")
            changed = annotate(text, shares)
            if changed != text:
                write_whole(page, changed, mode=page.stat().st_mode & 0o777)
                pages += 1
        if chosen.enabled:
            lines.append(f"class-wide notes {assignment}: " + (
                f"{len(shares)} mistake{'s' * (len(shares) != 1)} noted on {pages} page{'s' * (pages != 1)}" if shares
                else f"none (class of {len(named)}; notes need at least {chosen.min_class} students and a mistake "
                     "made by two or more)"))
    return lines
