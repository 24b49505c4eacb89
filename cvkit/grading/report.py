"""Grading reports: per-case results, the matched mistake, text and HTML renderings."""
from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass, field
from typing import Any

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

    def to_dict(self) -> dict:
        return {
            "index": self.index,
            "label": self.label,
            "passed": self.passed,
            "message": self.message,
            "mistake": self.mistake,
            "elapsed": round(self.elapsed, 4),
            "warnings": self.warnings,
        }


@dataclass
class Report:
    """The result of grading one candidate on one algorithm's public or hidden cases."""

    algorithm: str
    section: str
    hidden: bool
    seed: int | None
    cases: list
    mistake: str | None = None
    hint: str | None = None
    problem: str | None = None  # a failure before any case ran (e.g. not a function)

    @property
    def passed(self) -> bool:
        return self.problem is None and bool(self.cases) and all(c.passed for c in self.cases)

    @property
    def score(self) -> float:
        """Fraction of cases passed, 0..1."""
        if self.problem is not None or not self.cases:
            return 0.0
        return sum(c.passed for c in self.cases) / len(self.cases)

    @property
    def failures(self) -> list:
        return [c for c in self.cases if not c.passed]

    def summary(self) -> str:
        kind = "hidden" if self.hidden else "visible"
        if self.problem:
            return f"{self.algorithm}: {self.problem}"
        n = sum(c.passed for c in self.cases)
        verdict = "passed" if self.passed else "FAILED"
        text = f"{self.algorithm} (§{self.section}), {kind} tests: {n}/{len(self.cases)} cases passed — {verdict}"
        if self.mistake:
            text += f"\nYour output matches a known mistake: {self.mistake}. {self.hint}"
        return text

    def text(self, max_failures: int = 3) -> str:
        lines = [self.summary()]
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
            if case.traceback:
                lines.append("  traceback (your code):")
                lines += [f"    {line}" for line in case.traceback.splitlines()[-8:]]
            if case.mistake:
                lines.append(f"  → matches the mistake “{case.mistake}”: {case.hint}")
        notes = sorted({w for c in self.cases for w in c.warnings})
        if notes:
            lines.append("\nWarnings raised by your code (they cost no points, but look at them):")
            lines += [f"  {w}" for w in notes[:5]]
        printed = next((c.stdout for c in self.cases if c.stdout), "")
        if printed:
            lines.append("\nYour code printed (first case):")
            lines += [f"  {line}" for line in printed.splitlines()[:10]]
        errors = next((c.stderr for c in self.cases if c.stderr), "")
        if errors:
            lines.append("\nYour code wrote to stderr (captured):")
            lines += [f"  {line}" for line in errors.splitlines()[:10]]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.text()

    def to_dict(self) -> dict:
        return {
            "algorithm": self.algorithm,
            "section": self.section,
            "hidden": self.hidden,
            "seed": self.seed,
            "passed": self.passed,
            "score": self.score,
            "mistake": self.mistake,
            "hint": self.hint,
            "problem": self.problem,
            "cases": [c.to_dict() for c in self.cases],
        }

    # ---------------------------------------------------------------- HTML for JupyterLab
    def _repr_html_(self) -> str:
        colour = "#1a7f37" if self.passed else "#cf222e"
        parts = [
            f'<div class="cvkit-report" style="border-left:4px solid {colour};padding:4px 10px;font-family:sans-serif">',
            f"<b style='color:{colour}'>{html.escape(self.summary().splitlines()[0])}</b>",
        ]
        if self.mistake:
            parts.append(
                f"<p>Your output matches a known mistake: <b>{html.escape(self.mistake)}</b>. "
                f"{html.escape(self.hint or '')}</p>"
            )
        rows = []
        for case in self.cases:
            mark = "✓" if case.passed else "✗"
            detail = "" if case.passed else html.escape(case.message.splitlines()[0] if case.message else "")
            rows.append(
                f"<tr><td>{mark}</td><td>{html.escape(case.label)}</td>"
                f"<td><code>{html.escape(case.description[:120])}</code></td><td>{detail}</td></tr>"
            )
        parts.append("<table style='font-size:90%'><tr><th></th><th>case</th><th>input</th><th>problem</th></tr>"
                     + "".join(rows) + "</table>")
        failing = [c for c in self.cases if not c.passed]
        if failing:
            first = failing[0]
            parts.append(f"<pre style='font-size:85%'>{html.escape(first.message)}</pre>")
            if first.traceback:
                parts.append(f"<pre style='font-size:80%;color:#555'>{html.escape(first.traceback)}</pre>")
            parts.append(_image_comparison(first))
        parts.append("</div>")
        return "".join(parts)


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
    try:
        tiles = [
            ("yours", _png(got, lo, hi, "gray")),
            ("expected", _png(exp, lo, hi, "gray")),
            (f"|difference| (max {diff.max():.3g})", _png(diff, 0.0, float(diff.max()) or 1.0, "magma")),
        ]
    except Exception:
        return ""
    cells = "".join(
        f"<figure style='display:inline-block;margin:4px'><img style='{style}' src='data:image/png;base64,{data}'/>"
        f"<figcaption style='font-size:80%;text-align:center'>{html.escape(name)}</figcaption></figure>"
        for name, data in tiles
    )
    return f"<div>{cells}</div>"
