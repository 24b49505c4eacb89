"""A fingerprint of a graded course, to prove that a change of the grading code changes nothing.

    python benchmarks/demo_fingerprint.py COURSE_DIR > before.json
    ... change the code, grade the same course again (e.g. ``cvkit demo --all --dir COURSE_DIR``) ...
    python benchmarks/demo_fingerprint.py COURSE_DIR > after.json && diff before.json after.json

What it records, with what differs from one run to the next taken out (times, the salt-free
random names nbgrader gives its ids, the absolute course folder):

- the gradebook: every submission's grades (automatic and manual score, extra credit, whether
  a hand mark is due), comments, the notebooks' ``flagged`` and the late penalty;
- every file of ``exports/`` (CSV, HTML), and every feedback page and autograded notebook, as
  a SHA-256 of its text once times and the folder are replaced by placeholders. What differs
  between two runs of the same code is left out too: cell ids made at build time, the measured
  ``elapsed`` of a case, timings a notebook prints, and how a kernel happened to split its
  printed output into messages (consecutive stream outputs are joined; a page is compared by
  its text, tags removed, and its images).
"""
from __future__ import annotations

import hashlib
import json
import re
import sys
from pathlib import Path

_TIMES = [
    re.compile(r"\d{4}-\d{2}-\d{2}[ T]\d{2}:\d{2}:\d{2}(?:\.\d+)?(?:[+-]\d{2}:?\d{2}|Z| ?UTC)?"),
    re.compile(r"\b\d+(?:\.\d+)? ?(?:s|seconds|ms)\b"),  # durations of a run
    re.compile(r'"elapsed": [0-9.e-]+'),  # a case's measured time, in the report's data
    re.compile(r"cvkit-due-[0-9a-f]+"),  # the due-date notice's cell id, made at build time
]
_TAG = re.compile(r"<[^>]*>")
_IMAGE = re.compile(r'src="data:image/[^"]+"')


def _normal(text: str, root: str) -> str:
    text = text.replace(root, "<course>")
    for pattern in _TIMES:
        text = pattern.sub("<time>", text)
    text = re.sub(r"\b[0-9a-f]{32}\b", "<id>", text)  # nbgrader's uuid4().hex ids
    return text


def _digest(path: Path, root: str) -> str:
    text = path.read_text(errors="replace")
    if path.suffix == ".ipynb":  # execution times and the kernel's session live in metadata
        nb = json.loads(text)
        for cell in nb.get("cells", []):
            cell.get("metadata", {}).pop("execution", None)
            cell.pop("id", None)
            cell["outputs"] = _joined_streams(cell.get("outputs", []))
        text = json.dumps(nb, sort_keys=True)
    elif path.suffix == ".html":  # the text a reader sees, and the pictures
        images = sorted(hashlib.sha256(m.encode()).hexdigest() for m in _IMAGE.findall(text))
        text = " ".join(_TAG.sub(" ", _IMAGE.sub("", text)).split()) + "\n" + "\n".join(images)
    return hashlib.sha256(_normal(text, root).encode()).hexdigest()[:16]


def _joined_streams(outputs: list) -> list:
    """Consecutive stream outputs of one stream as one (a kernel splits printed text into
    messages as its timing goes)."""
    joined: list = []
    for output in outputs:
        if (output.get("output_type") == "stream" and joined and joined[-1].get("output_type") == "stream"
                and joined[-1].get("name") == output.get("name")):
            text = output.get("text", "")
            joined[-1] = dict(joined[-1], text="".join(joined[-1]["text"]) + ("".join(text) if isinstance(text, list) else text))
            continue
        if output.get("output_type") == "stream":
            text = output.get("text", "")
            output = dict(output, text="".join(text) if isinstance(text, list) else text)
        joined.append(output)
    return joined


def gradebook(db_url: str) -> dict:
    from nbgrader.api import Gradebook

    found: dict = {}
    with Gradebook(db_url) as gb:
        for assignment in gb.assignments:
            for sub in assignment.submissions:
                key = f"{sub.student.id}/{assignment.name}"
                found[key] = {
                    "late_penalty": sub.late_submission_penalty,
                    "notebooks": {nb.name: {
                        "flagged": nb.flagged,
                        "grades": {g.name: [g.auto_score, g.manual_score, g.extra_credit, g.needs_manual_grade]
                                   for g in nb.grades},
                        "comments": {c.name: c.auto_comment for c in nb.comments if c.auto_comment},
                    } for nb in sub.notebooks},
                }
    return found


def fingerprint(root: Path) -> dict:
    root = root.resolve()
    where = str(root)
    files = {}
    for folder in ("exports", "feedback", "autograded"):
        for path in sorted((root / folder).rglob("*")):
            if path.is_file() and path.suffix in (".csv", ".html", ".ipynb", ".txt") and path.name != "timestamp.txt":
                files[str(path.relative_to(root))] = _digest(path, where)
    return {"gradebook": gradebook(f"sqlite:///{root / 'gradebook.db'}"), "files": files}


if __name__ == "__main__":
    json.dump(fingerprint(Path(sys.argv[1])), sys.stdout, indent=1, sort_keys=True)
    print()
