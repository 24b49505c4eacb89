"""Grading reports: per-case results, the matched mistake, text and HTML renderings."""
from __future__ import annotations

import base64
import html
import io
import json
import re
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

MIME_TYPE = "application/vnd.cvkit.report+json"


@dataclass
class CaseResult:
    """The verdict on one case."""

    index: int
    label: str
    description: str
    passed: bool
    message: str = ""
    traceback: str | None = None
    mistake: str | None = None
    hint: str | None = None
    elapsed: float = 0.0
    warnings: list = field(default_factory=list)
    stdout: str = ""
    stderr: str = ""
    got: Any = None
    expected: Any = None
    worst: tuple | None = None
    details: str = ""                 # the technical part of the message (tolerances), shown on demand
    diagnosis: str | None = None      # what the wrong output looks like, or why the code crashed
    timed_out: bool = False           # the candidate did not return within the case's time limit
    unexplained: bool = False         # failed, and no mistake of the bank reproduces it (course tools count these)
    credit: float | None = None       # a measured check's share of the case's points (0..1), else None
    measure: dict | None = None       # a measured check's value: name, value, unit, better (Check.measure)

    #: what :meth:`to_dict` keeps (the report's JSON in notebooks and the course's results);
    #: the input, the outputs and the traceback stay out of it
    WIRE_FIELDS = ("index", "label", "passed", "message", "details", "diagnosis", "mistake", "unexplained", "elapsed",
                   "warnings")

    @property
    def worth(self) -> float:
        """What the case counts for in the score: its credit when measured, else passed (1) or not (0)."""
        if self.credit is not None:
            return 1.0 if self.passed else min(1.0, max(0.0, float(self.credit)))
        return 1.0 if self.passed else 0.0

    def to_dict(self) -> dict:
        data = {name: getattr(self, name) for name in self.WIRE_FIELDS}
        if self.credit is not None:
            data["credit"] = round(float(self.credit), 6)
        if self.measure is not None:
            data["measure"] = dict(self.measure)
        data["elapsed"] = round(self.elapsed, 4)
        return data


@dataclass
class Report:
    """The result of grading one candidate on one algorithm's public or hidden cases.

    ``cases`` holds the *counted* cases only. A case on which the reference implementation
    itself raised is not in it: it is listed in ``dropped`` (``"case N (label): reference
    raised ValueError: ..."``, for the instructor) and counts neither as passed nor as failed.
    ``fallback`` is set when no hidden case could be computed and the candidate was graded on
    the visible cases instead (see :func:`cvkit.grading.engine.evaluate`).
    """

    algorithm: str
    section: str
    hidden: bool
    seed: int | None
    cases: list
    mistake: str | None = None
    hint: str | None = None
    problem: str | None = None  # a failure before any case ran (e.g. not a function), or "not graded"
    dropped: list = field(default_factory=list)  # cases the reference could not compute (instructor's bug)
    fallback: str | None = None  # why the cases graded are the visible ones although hidden=True
    cascade: str | None = None  # graded with a reference building block: which of the student's functions to fix
    notes: list = field(default_factory=list)  # a passing visible test: what the hidden cases will check besides

    @property
    def passed(self) -> bool:
        return self.problem is None and bool(self.cases) and all(c.passed for c in self.cases)

    @property
    def score(self) -> float:
        """Fraction of the counted cases passed, 0..1 (dropped cases are not counted); a case of
        a measured check (:attr:`~cvkit.grading.Check.credit`) counts for its credit."""
        if self.problem is not None or not self.cases:
            return 0.0
        return sum(c.worth for c in self.cases) / len(self.cases)

    @property
    def gradable(self) -> bool:
        """False when the reference could not compute a single case, so there was nothing to
        grade the candidate on (the report then has ``problem`` set and scores 0)."""
        return bool(self.cases) or not self.dropped

    def dropped_note(self) -> str:
        """The line students see about dropped cases ("" when none was dropped)."""
        if not self.dropped:
            return ""
        kind = "hidden" if self.hidden else "visible"
        n = len(self.dropped)
        return (f"{n} {kind} case{'s' if n != 1 else ''} dropped: the reference could not compute "
                f"{'them' if n != 1 else 'it'} (reported to the instructor)")

    @property
    def failures(self) -> list:
        return [c for c in self.cases if not c.passed]

    @property
    def diagnosis(self) -> str | None:
        """What the first diagnosed failing case's output looks like (shifted, transposed...),
        when no known mistake was named; None otherwise."""
        if self.mistake:
            return None
        return next((c.diagnosis for c in self.cases if not c.passed and c.diagnosis), None)

    def _diagnosed_case(self):
        return next((c for c in self.cases if not c.passed and c.diagnosis), None)

    def _diagnosis_line(self) -> str:
        case = self._diagnosed_case()
        return f"What we see (case {case.index + 1}): {case.diagnosis}" if case and not self.mistake else ""

    def summary(self) -> str:
        kind = "hidden" if self.hidden else "visible"
        if self.problem:
            return f"{self.algorithm}: {self.problem}"
        n = sum(c.passed for c in self.cases)
        verdict = "passed" if self.passed else "FAILED"
        if self.fallback:
            kind = "visible tests (instead of the hidden ones)"
        else:
            kind += " tests"
        text = f"{self.algorithm} (§{self.section}), {kind}: {n}/{len(self.cases)} cases passed — {verdict}"
        if self.cascade:
            text += f"\n{self.cascade}"
        if self.fallback:
            text += f"\n{self.fallback}"
        elif self.dropped:
            text += f"\n{self.dropped_note()}"
        for note in self.notes:
            text += f"\nNote: {note}"
        if self.mistake:
            text += f"\nYour output matches a known mistake: {self.mistake}. {self.hint}"
        elif self._diagnosis_line():
            text += "\n" + self._diagnosis_line()
        return text

    def text(self, max_failures: int = 3, details: bool = False) -> str:
        """The report as plain text (terminals, ``python``, the notebook's text view): the same
        as the HTML, which folds the comparison's technical details (tolerances, exact counts)
        away; ``details=True`` shows them too, for the curious."""
        lines = [self.summary()]
        folded = False
        summarised = self._diagnosed_case() if not self.mistake else None
        shown = 0
        for case in self.cases:
            if case.passed:
                continue
            shown += 1
            if shown > max_failures:
                lines.append(f"... and {len(self.failures) - max_failures} more failing cases")
                break
            lines.append(f"\n✗ case {case.index + 1}: {case.label}")
            lines.append(f"  input: {case.description}")
            for line in case.message.splitlines():
                lines.append(f"  {line}")
            if case.diagnosis and (case.traceback or not case.mistake) and case is not summarised:
                lines.append(f"  → {case.diagnosis}")
            if case.details and details:
                lines += [f"  details: {line}" for line in case.details.splitlines()]
            folded = folded or bool(case.details and not details)
            if case.traceback:
                # bounded where it is made (the student's own frames, the last of them their line)
                lines.append("  traceback (your code):")
                lines += [f"    {line}" for line in case.traceback.splitlines()]
            if case.mistake:
                lines.append(f"  → matches the mistake “{case.mistake}”: {case.hint}")
        notes = sorted({w for c in self.cases for w in c.warnings})
        if notes:
            costly = any("raised a warning (" in c.message for c in self.cases if not c.passed)
            lines.append("\nWarnings raised by your code" + (":" if costly else " (they cost no points, but look at them):"))
            lines += [f"  {w}" for w in notes[:5]]
        printed = next((c.stdout for c in self.cases if c.stdout), "")
        if printed:
            lines.append("\nYour code printed (first case):")
            lines += [f"  {line}" for line in printed.splitlines()[:10]]
        errors = next((c.stderr for c in self.cases if c.stderr), "")
        if errors:
            lines.append("\nYour code wrote to stderr (captured):")
            lines += [f"  {line}" for line in errors.splitlines()[:10]]
        if folded:
            lines.append(f"\n(More numbers, for the curious: print(evaluate({self.algorithm!r}, your_function)"
                         ".text(details=True)), with evaluate from cvkit.grading)")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.text()

    def verdict(self) -> dict[str, Any]:
        """The report as the course's results read it (JSON-ready): what was graded, how many
        counted cases passed, and what went wrong in plain words.

        Returns
        -------
        dict
            ``algorithm``, ``hidden``, ``passed`` and ``total`` (counted cases), ``score``
            (0..1), ``mistake`` (the named mistake the output matches, or None) and ``problem``
            (when no mistake is named and a case failed: the first diagnosis, else the first
            clause of the first failure's message, see :func:`headline`; otherwise None).
        """
        found = finding(self.to_dict())
        return {
            "algorithm": self.algorithm,
            "hidden": self.hidden,
            "passed": sum(bool(c.passed) for c in self.cases),
            "total": len(self.cases),
            "score": self.score,
            "mistake": found[1] if found and found[0] == "mistake" else None,
            "problem": found[1] if found and found[0] == "problem" else None,
        }

    #: what :meth:`to_dict` keeps, in this order (the cases as :meth:`CaseResult.to_dict`)
    WIRE_FIELDS = ("algorithm", "section", "hidden", "seed", "passed", "score", "mistake", "hint", "diagnosis",
                   "problem", "cases", "dropped", "fallback", "cascade", "notes")

    def to_dict(self) -> dict:
        """The report as JSON-ready data. A hidden report leaves its seed out: with the public
        check code, the seed would give the hidden cases away."""
        data = {name: getattr(self, name) for name in self.WIRE_FIELDS}
        if self.hidden:
            data["seed"] = None
        data["cases"] = [c.to_dict() for c in self.cases]
        data["dropped"] = [str(d) for d in self.dropped]
        return data

    def mime_bundle(self) -> dict[str, Any]:
        """The report as a notebook's output shows it: its text, its data (:meth:`to_dict`,
        under :data:`MIME_TYPE`) and its HTML (left out when it cannot be drawn)."""
        bundle = {"text/plain": self.text(), MIME_TYPE: json.loads(json.dumps(self.to_dict(), default=str))}
        try:
            bundle["text/html"] = self._repr_html_()
        except Exception:  # a report that cannot draw its images still says what is wrong
            pass
        return bundle

    # ---------------------------------------------------------------- HTML for JupyterLab
    def _repr_html_(self) -> str:
        """The report for JupyterLab and the feedback pages.

        Accessible by construction: the verdict is a word (PASSED / FAILED) and a symbol as
        well as a colour; every image has an alt text saying what it shows; colours come from
        JupyterLab's theme variables (with light-theme fallbacks for plain HTML), so the
        report stays readable in the dark theme. Text is always in the theme's main text
        colour; green and red only mark the border and the ✓ / ✗ symbol, because no pair of
        theme greens/reds keeps a 4.5:1 text contrast in both the light and the dark theme."""
        verdict = "passed" if self.passed else "failed"
        accent = _SUCCESS if self.passed else _ERROR
        title = html.escape(self.summary().splitlines()[0])
        parts = [
            f'<section class="cvkit-report cvkit-{verdict}" role="region" aria-label="{title}" '
            f'style="border-left:4px solid {accent};padding:4px 10px;font-family:var(--jp-content-font-family, sans-serif);'
            f'color:{_TEXT}">',
            f"<p class='cvkit-summary' style='margin:2px 0;font-weight:bold;color:{_TEXT}'>"
            f"<span aria-hidden='true' style='color:{accent}'>{'✓' if self.passed else '✗'} </span>{title}</p>",
        ]
        for note in self.notes:
            parts.append(f"<p class='cvkit-note' style='color:{_TEXT}'><b>Note:</b> {html.escape(note)}</p>")
        if self.cascade:
            parts.append(f"<p class='cvkit-cascade' style='color:{_TEXT}'><b>Note:</b> {html.escape(self.cascade)}</p>")
        for note in filter(None, (self.fallback, self.dropped_note() if not self.fallback else "")):
            parts.append(f"<p class='cvkit-dropped' style='color:{_MUTED}'>{html.escape(note)}</p>")
        if self.mistake:
            parts.append(
                f"<p class='cvkit-mistake'>Your output matches a known mistake: <b>{html.escape(self.mistake)}</b>. "
                f"{html.escape(self.hint or '')}</p>"
            )
        elif self._diagnosis_line():
            parts.append(f"<p class='cvkit-diagnosis'>{html.escape(self._diagnosis_line())}</p>")
        rows = []
        for case in self.cases:
            mark = (f"<span aria-hidden='true'>{'✓' if case.passed else '✗'}</span> "
                    f"{'pass' if case.passed else '<b>fail</b>'}")
            detail = "" if case.passed else html.escape(case.message.splitlines()[0] if case.message else "")
            # cells on lines of their own: the page's text (copied, read by a screen reader or a
            # text browser) keeps them apart ("result case", never "resultcase")
            rows.append(
                f"<tr>\n<td style='white-space:nowrap;{_LEFT}'>{mark}</td>\n<td style='{_LEFT}'>{html.escape(case.label)}</td>\n"
                f"<td style='{_LEFT}'><code>{html.escape(case.description[:120])}</code></td>\n"
                f"<td style='{_LEFT}'>{detail}</td>\n</tr>\n"
            )
        kind = "hidden" if self.hidden else "visible"
        parts.append(f"<table class='cvkit-cases' style='font-size:90%;color:{_TEXT}'>\n"
                     f"<caption style='text-align:left;color:{_MUTED}'>{len(self.cases)} {kind} cases</caption>\n"
                     "<thead><tr>\n" + "".join(f"<th scope='col' style='{_LEFT}'>{name}</th>\n"
                                               for name in ("result", "case", "input", "problem"))
                     + "</tr></thead>\n<tbody>\n" + "".join(rows) + "</tbody></table>\n")
        failing = [c for c in self.cases if not c.passed]
        if failing:
            first = failing[0]
            parts.append(f"<pre class='cvkit-message' style='font-size:85%;color:{_TEXT};white-space:pre-wrap'>"
                         f"{html.escape(first.message)}</pre>")
            summarised = self._diagnosed_case() if not self.mistake else None
            if first.diagnosis and (first.traceback or not first.mistake) and first is not summarised:
                parts.append(f"<p class='cvkit-case-diagnosis'>→ {html.escape(first.diagnosis)}</p>")
            if first.details:
                parts.append(f"<details class='cvkit-details' style='color:{_MUTED}'><summary>details</summary>"
                             f"<pre style='font-size:80%;color:{_MUTED}'>{html.escape(first.details)}</pre></details>")
            if first.traceback:
                parts.append(f"<pre class='cvkit-traceback' style='font-size:80%;color:{_MUTED}'>"
                             f"{html.escape(first.traceback)}</pre>")
            parts.append(_image_comparison(first))
        parts.append("</section>")
        return "\n".join(parts)


def cascade_report(own: Report, again: Report, *, functions: Sequence[str], blocks: Sequence[str],
                   caller: str) -> Report:
    """One mistake costs points once: the report that counts for ``caller``, which failed
    (``own``) while it calls the student's ``functions`` that fail their own checks
    (``blocks``, their algorithm ids), and was graded again with cvkit's reference building
    blocks in their place (``again``).

    Returns
    -------
    Report
        ``again`` when it scores better, else ``own``; its :attr:`Report.cascade` says which
        function the student is to fix.
    """
    yours = ", ".join(f"`{name}`" for name in functions)
    ids = ", ".join(blocks)
    if again.score > own.score:
        passed = sum(c.passed for c in again.cases)
        verdict = "passes" if again.passed else f"passes {passed} of {len(again.cases)} cases"
        again.cascade = (f"Your {yours} fails its own check ({ids}), and your `{caller}` calls it. Graded with "
                         f"cvkit's reference {yours} instead, your `{caller}` {verdict} — so the mistake costs "
                         f"points once: fix {yours} first.")
        return again
    own.cascade = (f"Your {yours} fails its own check ({ids}), but even with cvkit's reference {yours} your "
                   f"`{caller}` fails: the problem is in `{caller}` itself.")
    return own


#: the numpy.testing vocabulary of reports written before plain words came first
_TECHNICAL_LINE = re.compile(r"\b(rtol|atol)\b|to tolerance|^Mismatched elements")


def headline(message: str, width: int = 90) -> str:
    """The first clause of a failure message, in plain words.

    "calls X, which would..." → "calls X"; "60 of 90 values differ, all in the border frame 2
    pixels wide (the interior is right); first at ..." → up to the semicolon; "Your output is
    shifted by 1 row down: ..." → "your output is shifted by 1 row down". Messages in the old
    numpy.testing wording ("Not equal to tolerance rtol=…") become "N of M values differ".

    Parameters
    ----------
    message : str
        A case's failure message (or a diagnosis).
    width : int, optional
        Longest result; a longer clause is cut at a word and ends with "…".

    Returns
    -------
    str
        The clause, never the tolerances; ``"failed"`` for an empty message.
    """
    lines = [line.strip() for line in str(message or "").splitlines() if line.strip()]
    if not lines:
        return "failed"
    first = lines[0]
    if _TECHNICAL_LINE.search(first):
        counted = re.search(r"Mismatched elements: (\d+) / (\d+)", str(message))
        first = (f"{counted.group(1)} of {counted.group(2)} values differ" if counted
                 else "the values differ from the expected ones")
    first = re.sub(r"\s*\([^()]*\b(?:rtol|atol)\b[^()]*\)", "", first)
    prefix = re.match(r"(result \[\d+\]: |`[A-Za-z_]\w*`: |[Oo]utput \d+: |[Ii]tem \d+ of the list: )?", first)
    lead = prefix.group(0) if prefix else ""
    first = first[len(lead):]
    if not first.startswith(("shape mismatch", "dtype mismatch", "raised ")):
        first = re.split(r"; |\. (?=[A-Z])", first, maxsplit=1)[0]
        for stop in (", which", ": "):
            if stop in first:
                first = first.split(stop, 1)[0]
                break
    first = (lead + first).rstrip(" .")
    if first[:1].isupper() and first[1:2].islower():
        first = first[0].lower() + first[1:]
    return first if len(first) <= width else first[: width - 1].rsplit(" ", 1)[0] + "…"


#: the longest finding (:func:`finding`) kept whole
_FINDING_WIDTH = 400


def finding(report: Mapping[str, Any]) -> tuple[str, str] | None:
    """What a report found, from its dict (:meth:`Report.to_dict`, as stored in a notebook).

    Parameters
    ----------
    report : mapping
        A report's dict: ``mistake``, ``diagnosis`` and ``cases`` (each with ``passed``,
        ``diagnosis``, ``message``) are read.

    Returns
    -------
    tuple of (str, str) or None
        ``("mistake", name)`` when the output matches a named mistake; else, when a case
        failed, ``("problem", words)`` with what the first diagnosed failing case looks like
        or the first clause of the first failure's message (:func:`headline`); else None.
    """
    if report.get("mistake"):
        return "mistake", str(report["mistake"])
    failures = [c for c in report.get("cases", []) if isinstance(c, Mapping) and not c.get("passed")]
    if not failures:
        return None
    diagnosis = report.get("diagnosis") or next((c.get("diagnosis") for c in failures if c.get("diagnosis")), None)
    # the whole clause (the exports and the table show it as it is: never cut mid-sentence);
    # the width only guards against a runaway message
    return "problem", headline(diagnosis or failures[0].get("message") or "failed", width=_FINDING_WIDTH)


# JupyterLab theme variables, with fallbacks (GitHub's light palette) for plain HTML pages
_TEXT = "var(--jp-content-font-color1, #1f2328)"
_MUTED = "var(--jp-content-font-color2, #59636e)"
_SUCCESS = "var(--jp-success-color1, #1a7f37)"
_ERROR = "var(--jp-error-color1, #cf222e)"
_LEFT = "text-align:left;vertical-align:top"  # JupyterLab right-aligns table cells by default


def _png(array: np.ndarray, vmin: float, vmax: float, cmap: str) -> str:
    from matplotlib import image as mpl_image

    buffer = io.BytesIO()
    if array.ndim == 3:
        span = (vmax - vmin) or 1.0
        array = np.clip((array - vmin) / span, 0, 1)
        mpl_image.imsave(buffer, array, format="png")
    else:
        mpl_image.imsave(buffer, array, vmin=vmin, vmax=vmax, cmap=cmap, format="png")
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _image_comparison(case: CaseResult) -> str:
    """Student / reference / |difference| side by side, when both are images of one shape."""
    try:
        got = np.asarray(case.got, dtype=np.float64)
        exp = np.asarray(case.expected, dtype=np.float64)
    except Exception:
        return ""
    if got.shape != exp.shape or exp.ndim not in (2, 3) or (exp.ndim == 3 and exp.shape[2] != 3):
        return ""
    if min(exp.shape[:2]) < 2 or not np.all(np.isfinite(got)) or not np.all(np.isfinite(exp)):
        return ""
    diff = np.abs(got - exp)
    if diff.ndim == 3:
        diff = diff.max(axis=2)
    lo, hi = float(exp.min()), float(exp.max())
    if hi <= lo:
        hi = lo + 1.0
    scale = max(1, 160 // max(exp.shape[:2]))
    style = f"image-rendering:pixelated;width:{exp.shape[1] * scale}px"
    shape = "×".join(str(n) for n in exp.shape)
    where = f"case {case.index + 1} ({case.label})"
    try:
        tiles = [
            ("yours", f"Your output for {where}: a {shape} image, grey levels {lo:.3g} (black) to {hi:.3g} (white)",
             _png(got, lo, hi, "gray")),
            ("expected", f"Expected output for {where}: a {shape} image on the same grey scale",
             _png(exp, lo, hi, "gray")),
            (f"|difference| (max {diff.max():.3g})",
             f"Absolute difference between your output and the expected one for {where}: dark where they agree, "
             f"bright where they differ; the largest difference is {diff.max():.3g}",
             _png(diff, 0.0, float(diff.max()) or 1.0, "magma")),
        ]
    except Exception:
        return ""
    cells = "\n".join(
        f"<figure style='display:inline-block;margin:4px'><img style='{style}' alt='{html.escape(alt, quote=True)}' "
        f"src='data:image/png;base64,{data}'/>"
        f"<figcaption style='font-size:80%;text-align:center'>{html.escape(name)}</figcaption></figure>"
        for name, alt, data in tiles
    )
    return f"<div class='cvkit-images'>{cells}</div>"
