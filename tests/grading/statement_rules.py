"""The rules an exercise's statement states about its inputs and side effects, read from the
chapter notebooks (``tests/grading/test_statement_rules.py``).

A statement is the markdown from an exercise's heading (``### Exercise N.M — ...``) to the
cell that calls ``check("<id>", ...)``. Each rule of :data:`cvkit.grading.checks.RULES` has the
phrases a statement uses for it (:data:`PHRASES`).
"""
from __future__ import annotations

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted(ROOT.glob("lectures/ch*/ch*.ipynb"))
HEADING = re.compile(r"^#+\s*Exercise\b", re.M)
CHECK_CALL = re.compile(r"""\bcheck\(\s*["']([\w.]+)["']""")

#: rule -> phrases of a statement that state it (case-insensitive regular expressions)
PHRASES = {
    "integer": (r"possibly integer\b", r"any real dtype", r"integer input", r"integer arrays too",
                r"integers? or floats?"),
    "uint8": (r"\buint8\b",),
    "single point": (r"single point", r"\(a single row\)"),
    "no warnings": (r"no (?:\w+\s+)?warning", r"without a warning", r"not (?:print|raise) a warning"),
}


def statements() -> dict[str, str]:
    """``{algorithm id: its statement}`` for every exercise of the chapter notebooks."""
    found: dict[str, str] = {}
    for path in NOTEBOOKS:
        cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
        text: list[str] = []
        for cell in cells:
            source = "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]
            if cell["cell_type"] == "markdown":
                heading = HEADING.search(source)
                if heading:
                    text = [source[heading.start():]]
                elif text:
                    text.append(source)
                continue
            ids = CHECK_CALL.findall(source)
            for algorithm_id in ids:
                if text:
                    found.setdefault(algorithm_id, "\n".join(text))
    return found


def stated_rules(statement: str) -> set[str]:
    """The rules of :data:`PHRASES` that ``statement`` states."""
    return {rule for rule, phrases in PHRASES.items()
            if any(re.search(p, statement, re.I) for p in phrases)}
