"""The item analysis of a graded course, for the instructor: ``exports/item_analysis.csv`` and
``exports/item_analysis.html`` (a dashboard: plots drawn when the page is written, embedded as
PNG with alt texts; no script).

The figures come from :mod:`cvkit.course.item_stats` (pure statistics; the formulas are there
and on the page). This module reads their inputs from the course: the scores, the named mistakes,
the problems and the flags per student and exercise (:func:`cvkit.course.results.scores`, the
same reading as the grade table), and each counted case's label and verdict from the trusted
reports the autograded notebooks keep in their test cells' outputs (``application/vnd.cvkit.
report+json``). Every text a student could have written is shown printable and escaped.
"""
from __future__ import annotations

import base64
import contextlib
import csv
import functools
import hashlib
import html
import io
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable

from .._text import printable
from ..grading.report import MIME_TYPE
from .files import whole_file, write_whole
from .notebook import cell_outputs, exercise_name
from .results import scores
from .item_stats import (FORMULAS, MIN_CORRELATION, MIN_DISCRIMINATION, AssignmentStats, Rate, Response, analyse,
                         reading)

if TYPE_CHECKING:
    from .state import CourseState

CSV_NAME = "item_analysis.csv"
HTML_NAME = "item_analysis.html"
NOTEBOOK = "(notebook)"  # flags of no exercise in particular (results.scores): not an item


# ------------------------------------------------------------------------------ reading the course
def responses(course: CourseState, assignment: str) -> tuple[list[str], dict[str, dict[str, Response]]]:
    """The exercises of ``assignment`` (in the notebooks' order) and, per graded student, a
    :class:`~cvkit.course.item_stats.Response` per exercise."""
    table = scores(course, assignment)
    order: list[str] = []
    found: dict[str, dict[str, Response]] = {}
    for student, exercises in table.items():
        cases = case_verdicts(course.root / "autograded" / student / assignment)
        runs = visible_runs(course.root / "submitted" / student / assignment)
        row = {}
        for e in exercises:
            if e.name == NOTEBOOK:
                continue
            if e.name not in order:
                order.append(e.name)
            row[e.name] = Response(None if e.to_mark else float(e.score), float(e.max_score),
                                   mistakes=list(e.mistakes), problems=list(e.problems), flagged=bool(e.flags),
                                   attempted=not any(str(p).startswith("not implemented") for p in e.problems),
                                   cases=cases.get(e.name, []), visible_runs=runs.get(e.name))
        found[student] = row
    return order, found


def case_verdicts(folder: Path) -> dict[str, list[tuple[str, bool]]]:
    """exercise → ``(case label, passed)`` of every counted case of the trusted reports in the
    autograded notebooks of ``folder`` (empty for an unreadable notebook)."""
    found: dict[str, list[tuple[str, bool]]] = {}
    for cell_id, output in cell_outputs(folder):
        report = (output.get("data") or {}).get(MIME_TYPE)
        if not cell_id or not isinstance(report, dict):
            continue
        for case in report.get("cases", []) or []:
            if isinstance(case, dict) and "passed" in case:
                label = str(case.get("label") or f"case {int(case.get('index', 0)) + 1}")
                found.setdefault(exercise_name(cell_id, answers=False), []).append((label, bool(case["passed"])))
    return found


def visible_runs(folder: Path) -> dict[str, int]:
    """exercise → how many times the student ran its visible test before handing in, as the
    hand-in's notebooks say (``visible_runs`` in the metadata of the report ``check()`` displays:
    counted in the student's kernel since it started, saved with the notebook — data the student
    controls, for analytics only, never for a grade)."""
    found: dict[str, int] = {}
    for cell_id, output in cell_outputs(folder):
        meta = (output.get("metadata") or {}).get(MIME_TYPE)
        runs = meta.get("visible_runs") if isinstance(meta, dict) else None
        if cell_id and cell_id.endswith("_visible") and isinstance(runs, int) and not isinstance(runs, bool) \
                and 0 < runs <= 100_000:
            name = exercise_name(cell_id, answers=False)
            found[name] = max(found.get(name, 0), runs)
    return found


def analyse_course(course: CourseState, assignments: Iterable[str] | None = None) -> list[AssignmentStats]:
    """The item analysis of every assignment of the plan and of every one with submissions (or of
    ``assignments``): an assignment nobody submitted gets its line, never a made-up figure."""
    if assignments is None:
        try:
            planned = list(course.plan().ids())
        except (OSError, ValueError):  # no plan, or one that cannot be read: the submissions say which
            planned = []
        chosen = list(dict.fromkeys(planned + sorted({a for _, a in course.submissions()})))
    else:
        chosen = list(dict.fromkeys(assignments))
    results = []
    for assignment in chosen:
        exercises, answers = responses(course, assignment)
        results.append(analyse(assignment, answers, exercises))
    return results


def export(course: CourseState, assignments: Iterable[str] | None = None) -> Path:
    """Write ``exports/item_analysis.csv`` and ``exports/item_analysis.html``; return the page."""
    results = analyse_course(course, assignments)
    folder = course.root / "exports"
    write_csv(results, folder / CSV_NAME)
    return write_html(results, folder / HTML_NAME, plots=course.root / PLOTS_FOLDER, prune=assignments is None)


# ------------------------------------------------------------------------------ text summary
def _pct(share: float | None) -> str:
    return "—" if share is None else f"{share:.0%}"


def _num(value: float | None, digits: int = 2) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def summary(results: list[AssignmentStats], path: Path | None = None) -> list[str]:
    """A few lines per assignment for the terminal: class size, α, hardest exercise, weakest
    discrimination, the most frequent mistake, unexplained failures, the worst case parameter."""
    lines = []
    for result in results:
        name = printable(result.assignment)
        if not result.exercises:
            lines += [f"item analysis {name}: {printable(w)}" for w in result.warnings] or [
                f"item analysis {name}: nothing to analyse"]
            continue
        alpha = f"Cronbach's α {result.alpha:.2f}" if result.alpha is not None else "no α (see the warnings)"
        lines.append(f"item analysis {name}: {result.students} student{'s' * (result.students != 1)}, {alpha}")
        scored = [e for e in result.exercises if e.facility is not None]
        if scored:
            hardest = min(scored, key=lambda e: e.facility)  # type: ignore[arg-type, return-value]
            lines.append(f"  hardest: {printable(hardest.name)} (facility {hardest.facility:.2f})")
        correlated = [e for e in result.exercises if e.rest_correlation is not None]
        if correlated:
            weakest = min(correlated, key=lambda e: e.rest_correlation)  # type: ignore[arg-type, return-value]
            lines.append(f"  weakest discrimination: {printable(weakest.name)} "
                         f"(item–rest r {weakest.rest_correlation:.2f})")
        mistakes = [(m, e.name) for e in result.exercises for m in e.mistakes]
        if mistakes:
            top, where = max(mistakes, key=lambda mw: (mw[0].count, -len(mw[0].name)))
            lines.append(f"  most frequent mistake: “{printable(top.name)}” in {printable(where)} "
                         f"({_pct(top.share)} of the class)")
        unexplained = [(e.unexplained.count, e.name) for e in result.exercises if e.unexplained and e.unexplained.count]
        if unexplained:
            lines.append("  failures matching no known mistake: " + ", ".join(
                f"{printable(n)} {c}" for c, n in sorted(unexplained, key=lambda cn: -cn[0])[:4]))
        parameters = [(p, e.name) for e in result.exercises for p in e.parameters if p.of]
        if parameters:
            worst, where = max(parameters, key=lambda pw: (pw[0].share, pw[0].of))
            lines.append(f"  worst case parameter: {printable(where)} · {printable(worst.name)} "
                         f"({_pct(worst.share)} of {worst.of} cases failed)")
        lines += [f"  ! {printable(w)}" for w in result.warnings]
    if path is not None:
        lines.append(f"item analysis: {path}")
    return lines


# ------------------------------------------------------------------------------ CSV
CSV_COLUMNS = ["assignment", "exercise", "measure", "name", "value", "count", "of", "note"]


def _rows(results: list[AssignmentStats]) -> list[list[Any]]:
    def value(x: float | None) -> Any:
        return "" if x is None else round(float(x), 4)

    rows: list[list[Any]] = []
    for r in results:
        a = r.assignment
        rows.append([a, "", "students", "", r.students, "", "", ""])
        rows.append([a, "", "students_with_complete_scores", "", r.complete, "", "", ""])
        rows.append([a, "", "cronbach_alpha", "", value(r.alpha), "", r.complete,
                     "" if r.alpha is not None else "not computed: see the warnings"])
        rows += [[a, "", "warning", "", "", "", "", w] for w in r.warnings]
        if r.totals:
            rows += [[a, "", "score_band", band.name, value(band.share), band.count, band.of, ""]
                     for band in r.distribution]
        for e in r.exercises:
            x = e.name
            rows.append([a, x, "graded", "", e.graded, "", e.students, ""])
            rows.append([a, x, "max_score", "", value(e.max_score), "", "", ""])
            rows.append([a, x, "mean_score", "", value(e.mean), "", e.graded, ""])
            rows.append([a, x, "facility", "", value(e.facility), "", e.graded, ""])
            rows.append([a, x, "item_rest_correlation", e.correlation_kind, value(e.rest_correlation), "", r.complete,
                         "" if e.rest_correlation is not None else f"not computed (needs {MIN_CORRELATION} students "
                                                                   "with complete scores and some spread)"])
            rows.append([a, x, "upper_lower_discrimination", "27 %", value(e.discrimination), "", r.complete,
                         "" if e.discrimination is not None else f"not computed (needs {MIN_DISCRIMINATION} "
                                                                 "students with complete scores)"])
            for rate, measure in ((e.not_attempted, "not_attempted"), (e.flagged, "flagged"),
                                  (e.unexplained, "unexplained_failures")):
                if rate is not None:
                    rows.append([a, x, measure, "", value(rate.share), rate.count, rate.of, ""])
            rows += [[a, x, "mistake", m.name, value(m.share), m.count, m.of, ""] for m in e.mistakes]
            rows += [[a, x, "unexplained_problem", p.name, value(p.share), p.count, p.of, ""]
                     for p in e.unexplained_problems]
            rows += [[a, x, "parameter_failure_rate", p.name, value(p.share), p.count, p.of, "failed cases of graded cases"]
                     for p in e.parameters]
            rows += [[a, x, "case_failure_rate", c.name, value(c.share), c.count, c.of, "failed cases of graded cases"]
                     for c in e.cases]
            if e.visible_runs:
                rows.append([a, x, "visible_test_runs_median", "", value(_median(e.visible_runs)), "",
                             len(e.visible_runs), STUDENT_CONTROLLED])
                rows.append([a, x, "visible_test_runs_max", "", e.visible_runs[-1], "", len(e.visible_runs),
                             STUDENT_CONTROLLED])
            rows += [[a, x, "warning", "", "", "", "", w] for w in e.warnings]
            rows += [[a, x, "reading", "", "", "", "", text] for text in reading(e)]
    return rows


#: how the page and the CSV mark the visible-test runs
STUDENT_CONTROLLED = ("student-controlled data: counted in the student's kernel and saved in their notebook "
                      "(a restart starts again; a student can change it); analytics only")


def _median(values: list[int]) -> float:
    middle = len(values) // 2
    return float(values[middle]) if len(values) % 2 else (values[middle - 1] + values[middle]) / 2


def write_csv(results: list[AssignmentStats], path: Path) -> Path:
    """One row per figure (long format, for a spreadsheet's pivot table): ``measure`` names it,
    ``value`` is the figure or share, ``count`` of ``of`` what it counts; an empty value is a
    figure not computed (``note`` says why). Texts printable, never a spreadsheet formula."""
    from .safety import csv_safe

    with whole_file(path, newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(CSV_COLUMNS)
        for row in _rows(results):
            writer.writerow([csv_safe(printable(c, newlines=True)) if isinstance(c, str) else csv_safe(c) for c in row])
    return path


# ------------------------------------------------------------------------------ plots
_INK, _BAR, _ACCENT = "#1f2328", "#0550ae", "#953800"


def _png(draw: Callable[[Any], None], width: float = 5.4, height: float = 3.2) -> str:
    """A matplotlib figure drawn by ``draw(axes)`` as base64 PNG (no global pyplot state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot(1, 1, 1)
    draw(axes)
    for spine in ("top", "right"):
        axes.spines[spine].set_visible(False)
    figure.tight_layout()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _short(text: str, width: int = 38) -> str:
    text = printable(text)
    return text if len(text) <= width else text[: width - 1] + "…"


def _figure(png: str, alt: str, caption: str) -> str:
    return (f"<figure><img src=\"data:image/png;base64,{png}\" alt=\"{html.escape(alt, quote=True)}\">"
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _histogram(result: AssignmentStats) -> str:
    bands = result.distribution
    names = [b.name.replace(" %", "") for b in bands]

    def draw(ax: Any) -> None:
        ax.bar(range(10), [b.count for b in bands], color=_BAR)
        ax.set_xticks(range(10), names, fontsize=7)
        ax.set_xlabel("total score, % of the maximum", color=_INK)
        ax.set_ylabel("students", color=_INK)
        from matplotlib.ticker import MaxNLocator

        ax.yaxis.set_major_locator(MaxNLocator(integer=True))

    alt = (f"Histogram of the total scores of {result.complete} students in {printable(result.assignment)}: "
           + "; ".join(f"{b.name}: {b.count}" for b in bands if b.count))
    return _figure(_png(draw), alt, "Score distribution (students with a score for every exercise)")


def _scatter(result: AssignmentStats) -> str:
    points: list[tuple[str, float, float]] = []
    for e in result.exercises:
        d = e.discrimination if e.discrimination is not None else e.rest_correlation
        if e.facility is not None and d is not None:
            points.append((e.name, e.facility, d))
    if not points:
        return ""
    measure = "upper–lower D" if all(e.discrimination is not None for e in result.exercises) else "item–rest r"

    def draw(ax: Any) -> None:
        ax.axhspan(-1, 0.2, color="#f6e7d8", zorder=0)
        ax.scatter([f for _, f, _ in points], [d for _, _, d in points], color=_BAR, zorder=2)
        for name, f, d in points:
            ax.annotate(_short(name, 22), (f, d), textcoords="offset points", xytext=(4, 4), fontsize=7, color=_INK)
        ax.set_xlim(-0.02, 1.08)
        ax.set_ylim(min(-0.1, min(d for _, _, d in points) - 0.05), 1.0)
        ax.set_xlabel("facility (share of the points earned)", color=_INK)
        ax.set_ylabel(f"discrimination ({measure})", color=_INK)

    alt = (f"Scatter plot of facility against discrimination ({measure}) per exercise of "
           f"{printable(result.assignment)}; the shaded band below 0.2 marks weak discrimination: "
           + "; ".join(f"{printable(n)}: facility {f:.2f}, discrimination {d:.2f}" for n, f, d in points))
    return _figure(_png(draw), alt, f"Facility against discrimination ({measure}); shaded: below 0.2, look at "
                                    "these exercises")


def _bars(rates: list[tuple[str, Rate]], what: str, xlabel: str, alt_lead: str) -> str:
    if not rates:
        return ""
    labels = [_short(f"{exercise} · {rate.name}", 48) for exercise, rate in rates]

    def draw(ax: Any) -> None:
        y = list(range(len(rates)))[::-1]
        ax.barh(y, [100 * (rate.share or 0) for _, rate in rates], color=_ACCENT)
        ax.set_yticks(y, labels, fontsize=7)
        ax.set_xlim(0, 100)
        ax.set_xlabel(xlabel, color=_INK)

    alt = alt_lead + "; ".join(f"{printable(e)}, {printable(r.name)}: {_pct(r.share)} ({r.count} of {r.of})"
                               for e, r in rates)
    return _figure(_png(draw, height=0.9 + 0.28 * len(rates)), alt, what)


def _plots(result: AssignmentStats) -> str:
    mistakes = sorted(((e.name, m) for e in result.exercises for m in e.mistakes),
                      key=lambda em: (-(em[1].share or 0), em[0], em[1].name))[:10]
    parameters = sorted(((e.name, p) for e in result.exercises for p in e.parameters if p.of),
                        key=lambda ep: (-(ep[1].share or 0), ep[0], ep[1].name))[:12]
    plots: list[tuple[str, Callable[[], str]]] = [
        ("score distribution", lambda: _histogram(result) if result.totals else ""),
        ("facility against discrimination", lambda: _scatter(result)),
        ("named mistakes", lambda: _bars(
            mistakes, "The most frequent named mistakes (share of the class)", "% of the class",
            f"Bar chart of the most frequent named mistakes in {printable(result.assignment)}: ")),
        ("failure rate by case parameter", lambda: _bars(
            parameters, "Failure rate by case parameter (failed cases ÷ graded cases carrying it)",
            "% of the cases failed", f"Bar chart of the failure rate by case parameter in {printable(result.assignment)}: ")),
    ]
    parts = []
    for name, draw in plots:
        try:
            parts.append(draw())
        except Exception as error:  # noqa: BLE001 - a plot that cannot be drawn: the tables still say it all
            parts.append(f"<p class=\"warning\" role=\"note\">Plot of the {html.escape(name)} not drawn "
                         f"({html.escape(type(error).__name__)}: {_e(str(error)[:200])}); the tables below hold the "
                         "same figures.</p>")
    return "<div class=\"plots\">" + "".join(p for p in parts if p) + "</div>"


# ------------------------------------------------------------------------------ HTML
_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="default-src 'none'; style-src 'unsafe-inline'; img-src data:">
<title>Item analysis</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; color: #1f2328; background: #ffffff; max-width: 72em; }}
table {{ border-collapse: collapse; margin: 0.5em 0 1em; }}
td, th {{ padding: 0.2em 0.7em; text-align: left; border-bottom: 1px solid #d0d7de; vertical-align: top; }}
td.n, th.n {{ text-align: right; }}
td.n {{ white-space: nowrap; }}
td.look {{ min-width: 18em; }}
section.assignment {{ border-top: 2px solid #59636e; margin-top: 2em; }}
.warning {{ background: #fff8c5; color: #3b2300; border-left: 4px solid #9a6700; padding: 0.3em 0.6em; margin: 0.3em 0; }}
.muted {{ color: #59636e; }}
.plots {{ display: flex; flex-wrap: wrap; gap: 1em; }}
figure {{ margin: 0; }}
figure img {{ max-width: 100%; }}
figcaption {{ font-size: 0.85em; color: #59636e; }}
details {{ margin: 0.4em 0; }}
</style></head><body>
<h1>Item analysis</h1>
<p>How the class did on each exercise, which exercises tell strong students from weak ones, and what went wrong
most: the mistakes the checks named, the failures matching no known mistake (a cue to add one to the check's
mistake bank), and the failure rate per case parameter. Shares are of the students whose submission was graded.
Figures that need more students than there are are not computed: a warning says so.</p>
{assignments}
<section><h2>How to read it</h2><dl>{formulas}</dl>
<p class="muted">Rules of thumb: facility between 0.3 and 0.9 and a discrimination above 0.2 make a useful exercise;
a discrimination near zero or negative means the exercise does not follow the rest of the assignment (ambiguous
statement, a check too strict or too lenient); α above 0.7 means the exercises measure one ability consistently.</p>
</section>
</body></html>
"""


def _e(text: object) -> str:
    return html.escape(printable(text, newlines=True))


def _assignment_html(result: AssignmentStats, plots: Callable[[AssignmentStats], str] | None = None) -> str:
    parts = [f"<section class=\"assignment\"><h2>{_e(result.assignment)}</h2>"]
    parts += [f"<p class=\"warning\" role=\"note\">{_e(w)}</p>" for w in result.warnings]
    if not result.exercises:
        return "".join(parts) + "</section>"
    alpha = (f"Cronbach's α = <b>{result.alpha:.2f}</b>" if result.alpha is not None
             else "Cronbach's α: not computed (see above)")
    parts.append(f"<p>{result.students} student{'s' * (result.students != 1)} graded; {result.complete} with a score "
                 f"for every exercise; maximum {result.max_total:g} points. {alpha}.</p>")
    parts.append((plots or _plots)(result))
    header = ["exercise", "graded", "mean / max", "facility", "item–rest r", "D (27 %)", "not attempted", "flagged",
              "unexplained failures", "what to look at"]
    rows = []
    for e in result.exercises:
        kind = {"point-biserial": "pb", "Pearson": "r"}.get(e.correlation_kind, "")
        r = _num(e.rest_correlation) + (f" <span class=\"muted\">({kind})</span>" if e.rest_correlation is not None
                                        else "")
        cells = [_e(e.name), str(e.graded), f"{_num(e.mean)} / {e.max_score:g}", _num(e.facility), r,
                 _num(e.discrimination), _rate(e.not_attempted), _rate(e.flagged), _rate(e.unexplained),
                 "<br>".join(html.escape(text) for text in reading(e))]
        last = len(cells) - 1
        rows.append("<tr>" + "".join(f"<td{'' if i == 0 else ' class=look' if i == last else ' class=n'}>{c}</td>"
                                     for i, c in enumerate(cells))
                    + "</tr>")
    parts.append("<table class=\"exercises\"><caption class=\"muted\">Per exercise (— : not computed; pb: point-biserial, the exercise is pass/fail; r: Pearson's r)</caption><thead><tr>"
                 + "".join(f"<th scope=\"col\"{'' if i in (0, len(header) - 1) else ' class=n'}>{h}</th>"
                           for i, h in enumerate(header))
                 + "</tr></thead><tbody>" + "".join(rows) + "</tbody></table>")
    for e in result.exercises:
        parts.append(_exercise_html(e))
    return "".join(parts) + "</section>"


def _rate(rate: Rate | None) -> str:
    return "—" if rate is None or not rate.of else f"{_pct(rate.share)} ({rate.count})"


def _table(rows: list[Rate], headers: tuple[str, str]) -> str:
    body = "".join(f"<tr><td>{_e(r.name)}</td><td class=n>{r.count} of {r.of}</td><td class=n>{_pct(r.share)}</td></tr>"
                   for r in rows)
    return (f"<table><thead><tr><th scope=\"col\">{headers[0]}</th><th scope=\"col\" class=n>{headers[1]}</th>"
            f"<th scope=\"col\" class=n>share</th></tr></thead><tbody>{body}</tbody></table>")


def _exercise_html(e: Any) -> str:
    parts = [f"<details class=\"exercise\" open><summary><b>{_e(e.name)}</b></summary>"]
    parts += [f"<p class=\"warning\" role=\"note\">{_e(w)}</p>" for w in e.warnings]
    if e.mistakes:
        parts.append("<h4>Named mistakes</h4>" + _table(e.mistakes, ("mistake", "students")))
    else:
        parts.append("<p class=\"muted\">No named mistake.</p>")
    if e.unexplained and e.unexplained.count:
        parts.append(f"<h4>Failures matching no known mistake: {e.unexplained.count} "
                     f"({_pct(e.unexplained.share)} of the class)</h4><p class=\"muted\">What the checks saw first "
                     "(consider adding a mistake to the check's bank for the most frequent):</p>"
                     + _table(e.unexplained_problems, ("what the checks saw", "of these students")))
    if e.parameters:
        parts.append("<h4>Failure rate by case parameter</h4>" + _table(e.parameters, ("parameter", "cases failed")))
    if e.cases:
        parts.append("<details><summary>Failure rate per case</summary>"
                     + _table(e.cases, ("case", "cases failed")) + "</details>")
    if e.visible_runs:
        runs = e.visible_runs
        quartiles = f"{runs[len(runs) // 4]}–{runs[(3 * len(runs)) // 4 if len(runs) > 1 else 0]}"
        parts.append(f"<h4>Runs of the visible test before handing in</h4><p>median {_median(runs):g}, middle half "
                     f"{quartiles}, at most {runs[-1]} ({len(runs)} student{'s' * (len(runs) != 1)} whose notebook "
                     f"says)</p><p class=\"muted\">{_e(STUDENT_CONTROLLED)}.</p>")
    return "".join(parts) + "</details>"


def write_html(results: list[AssignmentStats], path: Path, plots: Path | None = None, prune: bool = False) -> Path:
    """The dashboard: per assignment, the warnings, the plots, the table of exercises and per
    exercise its mistakes, unexplained failures and failure rates by case parameter; the formulas
    with their sources at the end. Self-contained, no script (a Content-Security-Policy allows
    none); every text escaped. ``plots``: a folder where each assignment's plots are kept
    (:func:`_kept_plots`), ``prune``: remove the kept plots of results not among these."""
    formulas = "".join(f"<dt><b>{html.escape(name)}</b></dt><dd>{html.escape(text)}"
                       + (f" <span class=\"muted\">({html.escape(source)})</span>" if source else "") + "</dd>"
                       for name, text, source in FORMULAS)
    used: set[str] = set()
    body = "".join(_assignment_html(r, lambda result: _kept_plots(result, plots, used)) for r in results) or \
        "<p class=\"warning\" role=\"note\">No assignment to analyse: the course has no plan and no submission.</p>"
    if plots is not None and prune and plots.is_dir():
        for kept in plots.glob("*.html"):
            if kept.name not in used:
                kept.unlink(missing_ok=True)
    write_whole(path, _PAGE.format(assignments=body, formulas=formulas))
    return path


#: where the item analysis keeps each assignment's plots, in the course folder (:func:`_kept_plots`)
PLOTS_FOLDER = Path(".cvkit") / "item_analysis_plots"


@functools.lru_cache(maxsize=1)
def _drawing_code() -> str:
    """What the plots are drawn with: this module's code, the statistics' (whose properties it
    plots), the text rules', matplotlib's version."""
    import matplotlib

    from .. import _text
    from . import item_stats

    digest = hashlib.sha256(matplotlib.__version__.encode())
    for module in (__file__, item_stats.__file__, _text.__file__):
        digest.update(Path(module).read_bytes())
    return digest.hexdigest()


def _kept_plots(result: AssignmentStats, folder: Path | None, used: set[str]) -> str:
    """:func:`_plots` of ``result``, kept in ``folder`` under a digest of all they are drawn from
    (the result's figures, exactly, and :func:`_drawing_code`): an assignment whose figures did
    not change since the last export is not drawn again — every grading run exports every
    chapter, and drawing is most of an export's time in a course of many chapters. A plot that
    could not be drawn is drawn again next time; a folder that cannot be written only costs the
    time."""
    if folder is None:
        return _plots(result)
    key = hashlib.sha256(f"{_drawing_code()}\0{result!r}".encode("utf-8", "surrogatepass")).hexdigest()[:40]
    name = f"{key}.html"
    used.add(name)
    try:
        return (folder / name).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        pass
    made = _plots(result)
    if "class=\"warning\"" not in made:
        with contextlib.suppress(OSError):
            write_whole(folder / name, made)
    return made
