"""Measured exercises: an answer graded by what it achieves, on data drawn per student.

A measured check (``Check(credit=...)``) does not compare an answer with the reference value
by value: it measures the answer against the **truth** the case was drawn from (the labels of
held-out digits, the outlines of drawn shapes, the lines of a scene) and puts the measurement
through a published :class:`Scale`. Two pieces serve every such check:

- :class:`MeasuredCase` — a :class:`~cvkit.grading.checks.Case` that also carries its
  ``truth``. Only ``args`` and ``kwargs`` are sent to the candidate (in the grading sandbox);
  the truth stays with the grader, where the comparator and the credit read it.
- :class:`Scale` — a piecewise-linear map from a measurement to a share of the points, flat
  outside its corners, with the words and the table a notebook publishes, so that the
  statement and the grader cannot disagree.

>>> scale = Scale(((0.90, 0.0), (0.95, 0.5), (0.97, 1.0)))
>>> scale.credit(0.96), scale.credit(0.5), scale.credit(0.99)
(0.75, 0.0, 1.0)
>>> scale.text()
'90 % → 0, 95 % → 0.5, 97 % → 1'
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np

from .checks import Case

__all__ = ["MeasuredCase", "Scale"]


@dataclass
class MeasuredCase(Case):
    """A case whose answer is measured against ``truth`` (labels, true edge pixels, true lines).

    Only ``args`` and ``kwargs`` enter the sandbox; ``truth`` stays with the grader."""

    truth: Any = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


@dataclass(frozen=True)
class Scale:
    """A published scale: ``(measurement, share of the points)`` corners, linear in between,
    flat outside them (the first share is 0, the last 1).

    Parameters
    ----------
    corners : sequence of (float, float)
        Measurements strictly increasing, shares non-decreasing from 0 to 1.
    percent : bool
        Measurements are fractions shown as percentages (accuracy 0.97 → "97 %"); otherwise
        they are shown as they are (an F-score 0.85 → "0.85").
    """

    corners: tuple[tuple[float, float], ...]
    percent: bool = True

    def __post_init__(self) -> None:
        corners = tuple((float(a), float(s)) for a, s in self.corners)
        xs, shares = [a for a, _ in corners], [s for _, s in corners]
        if (len(corners) < 2 or not all(map(math.isfinite, xs + shares)) or any(b <= a for a, b in zip(xs, xs[1:]))
                or any(b < a for a, b in zip(shares, shares[1:])) or shares[0] != 0.0 or shares[-1] != 1.0):
            raise ValueError(f"Scale corners must be (measurement, share) pairs, measurements increasing, shares "
                             f"non-decreasing from 0 to 1; got {self.corners!r}")
        object.__setattr__(self, "corners", corners)

    def __iter__(self) -> Iterator[tuple[float, float]]:
        return iter(self.corners)

    def __len__(self) -> int:
        return len(self.corners)

    def __getitem__(self, index: int) -> tuple[float, float]:
        return self.corners[index]

    @property
    def bottom(self) -> float:
        """The measurement at and below which an answer earns nothing."""
        return self.corners[0][0]

    @property
    def top(self) -> float:
        """The measurement from which an answer earns all the points."""
        return self.corners[-1][0]

    def credit(self, value: float) -> float:
        """The share of the points (0..1) a measurement earns; NaN earns 0."""
        value = float(value)
        if not math.isfinite(value):
            return 0.0 if math.isnan(value) or value < 0 else 1.0
        xs, shares = zip(*self.corners)
        return float(np.interp(value, xs, shares))

    def show(self, value: float) -> str:
        """A measurement in the scale's words: ``"97 %"`` or ``"0.85"``."""
        return f"{100 * value:g} %" if self.percent else f"{value:g}"

    def text(self) -> str:
        """The scale on one line, for reports: ``"90 % → 0, 95 % → 0.5, 97 % → 1"``."""
        return ", ".join(f"{self.show(a)} → {s:g}" for a, s in self.corners)

    def table(self, measured: str, points: float) -> str:
        """The scale as the two-row Markdown table a notebook's statement publishes.

        ``measured`` names the measurement ("accuracy on the held-out digits"), ``points`` the
        hidden test's points."""
        heads = [self.show(a) for a, _ in self.corners]
        heads[0] += " or less"
        heads[-1] += " or more"
        return "\n".join([f"| {measured} | " + " | ".join(heads) + " |",
                          "|---" * (len(heads) + 1) + "|",
                          f"| share of the hidden test's {points:g} points | "
                          + " | ".join(f"{s:g}" for _, s in self.corners) + " |"])

    def shortfall(self, value: float, measured: str, detail: str = "") -> str:
        """The sentence a report gives a measurement below the top: what it is (``detail``
        follows the value: " on 539 digits"), where the top is, what it earns."""
        shown = f"{100 * value:.2f} %" if self.percent else f"{value:.3f}"
        return (f"{measured} {shown}{detail}, below {self.show(self.top)}, the top of the scale; it earns "
                f"{self.credit(value):.2f} of the points (scale: {self.text()}).")
