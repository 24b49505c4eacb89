"""Item analysis of one assignment, on plain data: how the class did on each exercise, which
exercises tell strong students from weak ones, what went wrong most.

Pure statistics, nothing read from disk: the input is one :class:`Response` per student and
exercise (built from a graded course by :mod:`cvkit.course.item_analysis`, or simulated in the
tests), the output an :class:`AssignmentStats`. The formulas (named as on the report page):

- **facility** of an exercise: its mean score divided by its maximum (the share of its points the
  class earned; 1 = everyone got it right);
- **corrected item–rest correlation**: Pearson's r between the exercise's score and the rest
  score (the total of the *other* exercises), so that the exercise does not correlate with
  itself. Where the exercise is pass/fail (every score 0 or the maximum) this is the
  point-biserial correlation (same formula, `scipy.stats.pointbiserialr`);
- **upper–lower discrimination** (Kelley 1939), corrected as the correlation is: the students
  ranked by their rest score (the exercise left out; with the few exercises of an assignment, a
  total that includes the exercise would make even a coin toss look discriminating), the top
  and bottom 27 % (at least one student each; ties at the cut broken by the order of the
  student ids): D = facility in the upper group − facility in the lower group, from −1 to 1;
- **Cronbach's α** (Cronbach 1951): α = k/(k−1) · (1 − Σ σ²ᵢ / σ²ₜ) over the k exercises,
  with σ²ᵢ the variance of exercise i and σ²ₜ that of the total (sample variances, n−1);
- the shares of the class: not attempted (the function still raises NotImplementedError),
  flagged (the grader flagged code trying to get around it), each named mistake, and failures
  matching no known mistake ("unexplained");
- the **failure rate per case parameter**: the check's cases are described by labels such as
  "radius (2, 4), reflect101"; each comma-separated part (outside brackets) is a parameter
  value, and its failure rate is failed cases / graded cases among the cases carrying it (a
  label of one part, carried by one case only, is that case's own rate and not repeated).

Correlations, discrimination and α are computed on the students with a score for every
exercise of the assignment (an exercise still to mark by hand has none yet). Where too few
students remain for a figure to mean anything, it is None and a warning says why: a warning,
never a number.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

#: fewest students with complete scores for a correlation or Cronbach's α
MIN_CORRELATION = 10
#: fewest students for the upper–lower discrimination (each 27 % group then has ≥ 5)
MIN_DISCRIMINATION = 19
#: share of the class in each of the upper and lower groups
GROUP_SHARE = 0.27
#: a case-label part is shown as a parameter when this many different cases carry it (or it is one
#: part of a label of several)
MIN_CASES_PER_PARAMETER = 2

FORMULAS = [
    ("Facility", "mean score ÷ maximum score of the exercise (1 = everyone earned every point).", ""),
    ("Corrected item–rest correlation",
     "Pearson's r between the exercise's score and the total of the other exercises (the exercise left out, so it "
     "does not correlate with itself); for a pass/fail exercise this is the point-biserial correlation.",
     "Nunnally & Bernstein, Psychometric Theory (3rd ed., 1994), ch. 8; scipy.stats.pointbiserialr."),
    ("Upper–lower discrimination D",
     "students ranked by their rest score (the exercise left out, as for the correlation); D = facility in the top "
     "27 % − facility in the bottom 27 % (ties at the cut broken by student id).",
     "Kelley, J. Educ. Psychol. 30 (1939) 17–24."),
    ("Cronbach's α",
     "α = k/(k−1) · (1 − Σ σ²ᵢ / σ²ₜ), k exercises, σ²ᵢ the variance of exercise i, σ²ₜ that of the total "
     "(sample variances).", "Cronbach, Psychometrika 16 (1951) 297–334."),
    ("Failure rate per case parameter",
     "failed cases ÷ graded cases among the cases whose label carries the parameter (labels split at commas "
     "outside brackets).", ""),
]


@dataclass
class Response:
    """One student's answer to one exercise, as the grader saw it.

    ``score`` is None when it has no score yet (a written answer still to mark by hand).
    ``cases`` holds ``(case label, passed)`` for every counted case of the exercise's checks.
    """

    score: float | None
    max_score: float
    mistakes: Sequence[str] = ()
    problems: Sequence[str] = ()
    flagged: bool = False
    attempted: bool = True
    cases: Sequence[tuple[str, bool]] = ()
    visible_runs: int | None = None  # runs of the visible test in the student's kernel (student-controlled)


@dataclass
class Rate:
    """How many of how many: ``count`` of ``of`` (``share`` is None when ``of`` is 0)."""

    name: str
    count: int
    of: int

    @property
    def share(self) -> float | None:
        return self.count / self.of if self.of else None


@dataclass
class ExerciseStats:
    name: str
    max_score: float
    students: int = 0             # students whose submission holds this exercise
    graded: int = 0               # … with a score (not still to mark)
    mean: float | None = None
    facility: float | None = None
    rest_correlation: float | None = None
    correlation_kind: str = ""    # "point-biserial" or "Pearson"
    discrimination: float | None = None
    not_attempted: Rate | None = None
    flagged: Rate | None = None
    mistakes: list[Rate] = field(default_factory=list)      # most frequent first
    unexplained: Rate | None = None                           # lost points, attempted, no mistake named
    unexplained_problems: list[Rate] = field(default_factory=list)
    parameters: list[Rate] = field(default_factory=list)     # count = failed cases, of = graded cases
    cases: list[Rate] = field(default_factory=list)          # per case label
    warnings: list[str] = field(default_factory=list)
    #: runs of the visible test before the hand-in, of the students whose notebook says (sorted):
    #: counted in the student's kernel and saved in their notebook, so the student controls it
    visible_runs: list[int] = field(default_factory=list)


@dataclass
class AssignmentStats:
    assignment: str
    students: int = 0
    complete: int = 0             # students with a score for every exercise
    max_total: float = 0.0
    totals: list[float] = field(default_factory=list)   # per complete student, in points
    alpha: float | None = None
    exercises: list[ExerciseStats] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def distribution(self) -> list[Rate]:
        """The totals in ten bands of 10 % of the maximum (the last one includes 100 %)."""
        bands = [0] * 10
        for total in self.totals:
            share = total / self.max_total if self.max_total else 0.0
            bands[min(9, max(0, int(math.floor(share * 10 + 1e-9))))] += 1
        return [Rate(f"{10 * i}–{10 * i + 10} %", n, len(self.totals)) for i, n in enumerate(bands)]


def reading(e: ExerciseStats) -> list[str]:
    """What to look at in an exercise's figures, in plain words (empty: nothing stands out).
    Thresholds of the usual rules of thumb (Ebel & Frisbie, Essentials of Educational
    Measurement, 1991): facility above 0.9 or below 0.3, discrimination below 0.2 (clearly below
    0, under −0.1: stronger students do worse), and a fifth of the class or more failing without a
    named mistake."""
    notes = []
    if e.facility is not None and e.facility > 0.9:
        notes.append("very easy: tells students apart little")
    elif e.facility is not None and e.facility < 0.3:
        notes.append("hard: most of the class lost its points")
    measure = e.discrimination if e.discrimination is not None else e.rest_correlation
    if measure is not None and measure < -0.1:
        notes.append("negative discrimination: stronger students did worse; check the statement and the check")
    elif measure is not None and measure < 0.2:
        notes.append("weak discrimination: does not follow the rest of the assignment")
    if e.unexplained and e.unexplained.share is not None and e.unexplained.share >= 0.2:
        notes.append("a fifth of the class or more failed without a named mistake: add one to the check's bank")
    return notes


def pearson(x: ArrayLike, y: ArrayLike) -> float | None:
    """Pearson's r, or None when either variable is constant (r is undefined) or n < 2."""
    a, b = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if a.size < 2 or a.size != b.size:
        return None
    a, b = a - a.mean(), b - b.mean()
    denominator = math.sqrt(float(a @ a) * float(b @ b))
    if denominator <= 1e-12 * max(1.0, float(np.abs(a).max()) * float(np.abs(b).max()) * a.size):
        return None
    return float(a @ b) / denominator


def cronbach_alpha(matrix: np.ndarray) -> float | None:
    """Cronbach's α of a students × items score matrix; None when undefined (fewer than two
    items or two students, or every student has the same total)."""
    scores = np.asarray(matrix, dtype=float)
    if scores.ndim != 2 or scores.shape[0] < 2 or scores.shape[1] < 2:
        return None
    k = scores.shape[1]
    total_variance = float(scores.sum(axis=1).var(ddof=1))
    if total_variance <= 1e-12:
        return None
    return k / (k - 1) * (1.0 - float(scores.var(axis=0, ddof=1).sum()) / total_variance)


def upper_lower(item: ArrayLike, total: ArrayLike, max_score: float,
                order: Sequence[int] | None = None) -> float | None:
    """Kelley's upper–lower discrimination D of one item, the students ranked by ``total`` (the
    analysis passes the rest score, see the module docstring): ``order`` breaks ties at the cut
    (default: the given order); None without a maximum or with < 2 students."""
    item_a, total_a = np.asarray(item, dtype=float), np.asarray(total, dtype=float)
    n = item_a.size
    if n < 2 or max_score <= 0:
        return None
    tie = np.arange(n) if order is None else np.asarray(order)
    # highest total first; ties (equal to 1e-9 points: sums in another order are ties) by ``order``
    ranked = np.lexsort((tie, -np.round(total_a, 9)))
    group = max(1, int(round(GROUP_SHARE * n)))
    upper, lower = ranked[:group], ranked[n - group:]
    return float(item_a[upper].mean() - item_a[lower].mean()) / max_score


def parameters_of(label: str) -> list[str]:
    """The parts of a case label, split at commas outside brackets: "radius (2, 4), reflect101"
    → ["radius (2, 4)", "reflect101"]."""
    parts: list[str] = []
    current: list[str] = []
    depth = 0
    for char in str(label):
        if char in "([{":
            depth += 1
        elif char in ")]}":
            depth = max(0, depth - 1)
        if char == "," and depth == 0:
            parts.append("".join(current).strip())
            current = []
        else:
            current.append(char)
    parts.append("".join(current).strip())
    return [p for p in dict.fromkeys(parts) if p]


def analyse(assignment: str, responses: Mapping[str, Mapping[str, Response]],
            exercises: Iterable[str] | None = None, top: int = 5) -> AssignmentStats:
    """The item analysis of one assignment.

    Parameters
    ----------
    assignment : str
        Its name (only shown).
    responses : mapping
        student → exercise → :class:`Response`; students in the order ties are broken by.
    exercises : iterable of str, optional
        The exercises in the order shown (default: in order of first appearance).
    top : int
        How many named mistakes and unexplained problems to keep per exercise.

    Returns
    -------
    AssignmentStats
        With a warning, never a number, where there are too few students for a figure.
    """
    students = list(responses)
    names = list(dict.fromkeys(list(exercises or []) + [e for s in students for e in responses[s]]))
    result = AssignmentStats(assignment, students=len(students))
    if not students:
        result.warnings.append(f"{assignment}: no graded submission — nothing to analyse")
        return result
    if not names:
        result.warnings.append(f"{assignment}: the graded submissions hold no graded exercise — nothing to analyse")
        return result
    maxima = {e: max((responses[s][e].max_score for s in students if e in responses[s]), default=0.0) for e in names}
    # the items of the totals, correlations and α: the exercises with a score for someone (a written
    # answer nobody's mark is in yet would leave no student with complete scores)
    items = [e for e in names if any(e in responses[s] and responses[s][e].score is not None for s in students)]
    complete = [s for s in students if items and all(e in responses[s] and responses[s][e].score is not None
                                                     for e in items)]
    matrix = np.zeros((len(complete), len(items)))
    for i, s in enumerate(complete):
        for j, e in enumerate(items):
            matrix[i, j] = float(responses[s][e].score or 0.0)  # never None: ``complete``
    totals = matrix.sum(axis=1)
    result.complete = len(complete)
    result.max_total = float(sum(maxima[e] for e in items))
    result.totals = [float(t) for t in totals]
    n = len(complete)
    too_few = n < MIN_CORRELATION
    if len(students) == 1:
        result.warnings.append(f"{assignment}: one student — no class statistics (correlations, discrimination, α) "
                               "can be computed from one answer")
    elif too_few:
        result.warnings.append(f"{assignment}: {n} student{'s' * (n != 1)} with complete scores — too few for "
                               f"correlations and α to mean anything (at least {MIN_CORRELATION} needed); "
                               "only counts and shares are shown")
    elif n < MIN_DISCRIMINATION:
        result.warnings.append(f"{assignment}: {n} students with complete scores — too few for the upper–lower "
                               f"discrimination (at least {MIN_DISCRIMINATION} needed)")
    if len(complete) < len(students):
        missing = len(students) - len(complete)
        result.warnings.append(f"{assignment}: {missing} student{'s' * (missing != 1)} without a score for every "
                               "scored exercise (still to mark by hand) left out of the totals, correlations, "
                               "discrimination and α")
    unscored = [e for e in names if e not in items]
    if unscored:
        result.warnings.append(f"{assignment}: no score yet for {', '.join(unscored)} (still to mark by hand): left out "
                               "of the totals, correlations, discrimination and α")
    if len(items) == 1:
        result.warnings.append(f"{assignment}: one exercise — no item–rest correlation or α (they need two or more)")
    elif len(items) >= 2 and not too_few:
        result.alpha = cronbach_alpha(matrix)
        if result.alpha is None:
            result.warnings.append(f"{assignment}: every student has the same total — Cronbach's α is undefined")
    for name in names:
        column = items.index(name) if name in items else None
        result.exercises.append(_exercise(name, maxima[name], column, students, responses, matrix, complete, top))
    return result


def _exercise(name: str, max_score: float, j: int | None, students: list[str], responses: Mapping[str, Mapping[str, Response]],
              matrix: np.ndarray, complete: list[str], top: int) -> ExerciseStats:
    present = [responses[s][name] for s in students if name in responses[s]]
    stats = ExerciseStats(name, max_score, students=len(present))
    stats.visible_runs = sorted(int(r.visible_runs) for r in present if r.visible_runs is not None)
    scored = [float(r.score) for r in present if r.score is not None]
    stats.graded = len(scored)
    if scored:
        stats.mean = float(np.mean(scored))
        stats.facility = stats.mean / max_score if max_score > 0 else None
    if scored and max_score <= 0:
        stats.warnings.append("worth no points — no facility")
    n = len(complete)
    if j is not None and matrix.shape[1] >= 2 and n >= MIN_CORRELATION:
        item = matrix[:, j]
        rest = matrix.sum(axis=1) - item
        binary = bool(np.all(np.isclose(item, 0.0) | np.isclose(item, max_score)))
        stats.correlation_kind = "point-biserial" if binary else "Pearson"
        stats.rest_correlation = pearson(item, rest)
        if stats.rest_correlation is None:
            stats.warnings.append("every student scored the same on it, or on the rest — no correlation")
    if j is not None and n >= MIN_DISCRIMINATION:
        stats.discrimination = upper_lower(matrix[:, j], matrix.sum(axis=1) - matrix[:, j], max_score)
    class_size = len(present)
    stats.not_attempted = Rate("not attempted", sum(not r.attempted for r in present), class_size)
    stats.flagged = Rate("flagged", sum(bool(r.flagged) for r in present), class_size)
    counted = Counter(m for r in present for m in dict.fromkeys(r.mistakes))
    stats.mistakes = [Rate(m, c, class_size) for m, c in sorted(counted.items(), key=lambda mc: (-mc[1], mc[0]))[:top]]
    unexplained = [r for r in present if r.attempted and r.score is not None and r.score < r.max_score - 1e-9
                   and not r.mistakes]
    stats.unexplained = Rate("unexplained failures", len(unexplained), class_size)
    problems = Counter(r.problems[0] if r.problems else "(no problem recorded)" for r in unexplained)
    stats.unexplained_problems = [Rate(p, c, len(unexplained))
                                  for p, c in sorted(problems.items(), key=lambda pc: (-pc[1], pc[0]))[:top]]
    cases: dict[str, list[int]] = {}
    parts: dict[str, list[int]] = {}
    labels_of: dict[str, set] = {}
    for r in present:
        for label, passed in r.cases:
            entry = cases.setdefault(str(label), [0, 0])
            entry[0] += not passed
            entry[1] += 1
            for part in parameters_of(str(label)):
                labels_of.setdefault(part, set()).add(str(label))
                entry = parts.setdefault(part, [0, 0])
                entry[0] += not passed
                entry[1] += 1
    stats.cases = sorted((Rate(k, f, s) for k, (f, s) in cases.items()), key=lambda r: (-(r.share or 0), r.name))
    # a parameter: a part several cases share, or one part of a label of several ("reflect101" of
    # "radius (2, 4), reflect101"); a label of one part alone is only its case
    stats.parameters = sorted((Rate(k, f, s) for k, (f, s) in parts.items()
                               if len(labels_of[k]) >= MIN_CASES_PER_PARAMETER
                               or any(label != k for label in labels_of[k])),
                              key=lambda r: (-(r.share or 0), r.name))
    return stats
