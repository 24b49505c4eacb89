"""The grading engine behind the course notebooks.

- :class:`Check` (in :mod:`.checks`): public cases, a hidden-case generator, a comparator and a
  bank of named :class:`Mistake`\\ s, declared next to each reference implementation; a wrong
  version carries its name and advice on its own function (:func:`mistake`).
- :func:`evaluate`: grade any callable, never raising for a faulty one; returns a
  :class:`Report`.
- :func:`check`: what notebook test cells call (shows the report, asserts or returns partial
  credit for nbgrader).
- :mod:`.runtime`: what runs inside the grading sandbox next to student code (NumPy only):
  the guard (copies of the inputs, time limit, captured output, forbidden calls), the JSON
  wire format, the sandbox worker and the adapters of :attr:`Check.call`.
- :mod:`.isolation` and :mod:`.sandbox`: the operating-system sandbox (bubblewrap) and the
  trusted side of a sandboxed run.
"""
from .checks import FORBIDDEN_LIBRARIES, Case, Check, Measure, Mistake, instance_call, mistake
from .compare import Close, Comparator, Drawn, Mismatch, Statistics, close
from .diagnose import Diagnosis, diagnose
from .engine import CheckFailed, check, evaluate, hidden_seed, needs_answer
from .answers import AnswersUnavailable, load_answers
from .report import MIME_TYPE, CaseResult, Report
from .runtime import guard, wire  # noqa: F401  (cvkit.grading.wire, cvkit.grading.guard)

__all__ = [
    "Case", "Check", "Measure", "Mistake", "mistake", "FORBIDDEN_LIBRARIES", "instance_call",
    "Comparator", "Close", "Drawn", "Statistics", "Mismatch", "close",
    "check", "evaluate", "hidden_seed", "needs_answer", "CheckFailed", "diagnose", "Diagnosis",
    "Report", "CaseResult", "MIME_TYPE", "load_answers", "AnswersUnavailable",
]
