"""Similarity report: answers that look copied, for the instructor to look at.

For every exercise of an assignment (an nbgrader answer cell: a ``solution: true`` code cell),
each student's answer is compared with every other student's answer, with the reference
implementation of the exercise's algorithm (its source, :func:`inspect.getsource`) and with the
instructor's solution (the source notebook's text between ``### BEGIN SOLUTION`` and
``### END SOLUTION``). Pairs above a threshold are listed (:func:`similar_pairs`,
:func:`report`) and exported (:func:`write_csv`, :func:`write_html`). It is a signal for the
instructor, never a score change: nothing here touches a grade.

Method
------
The detector is `copydetect <https://github.com/blingenf/copydetect>`_ (winnowing, as in
Schleimer, Wilkerson & Aiken, *Winnowing: local algorithms for document fingerprinting*, 2003,
the method of MOSS): its tokenizer (``copydetect.utils.filter_code``, Pygments) replaces every
name by ``V``, function names by ``F``, strings by ``S`` and drops comments and white space;
number literals, which it keeps, become ``N`` here, so that ``2.0`` and ``2`` read the same.
Each answer becomes a :class:`copydetect.CodeFingerprint` of its k-grams (:data:`NOISE`
normalised characters, every k-gram kept: copydetect's window 1, since answers are short),
without the k-grams of the released answer cell (the stub every student starts from: the
``def`` line, the docstring, ``raise NotImplementedError()``), passed as copydetect's
boilerplate (copydetect 0.5 then also keeps only the last occurrence of a repeated k-gram,
so an answer padded with many copies of a line is measured as if the line were there once).
:func:`copydetect.compare_files` gives, for each of the two answers, the fraction
of its own code that is covered by matches; the **similarity of a pair is the mean of the two
fractions** (symmetric; the mean, rather than the minimum, still reports a short answer pasted
whole into a longer one, e.g. a reference with its input checks; rather than the maximum, it
does not report every answer that contains a short one).

Renamed variables, other strings and numbers, changed comments and white space do not change
the normalised text; reordering independent statements only breaks the k-grams that span the
moved boundaries, which is why :data:`NOISE` is 20 rather than copydetect's 25.

Every pair of distinct normalised texts is first measured by a vectorized equivalent of
:func:`copydetect.compare_files` (copydetect's own ``get_copied_slices`` on the shared k-grams'
positions; same values, tested), and :func:`~copydetect.compare_files` measures again the pairs
that reach the threshold: its value is the one reported. Identical normalised texts (copies)
are fingerprinted and compared once. Tokenizing (Pygments) costs a few milliseconds per answer,
a pair well under one.

What is skipped: unanswered cells (the released stub as it is, or nothing of the student's own
left once the stub's k-grams are removed) and answers with fewer than ``min_size``
(:data:`MIN_SIZE`) normalised characters of their own: a three-line exercise has only one
natural solution, so matching ones say nothing.

Threshold
---------
:data:`THRESHOLD` (0.6) was chosen on the course's own material
(``tests/test_similarity.py``): copies with renamed variables and reordered statements of
Chapter 3's solutions score 0.75 to 1.0; independent correct solutions (the notebooks'
solutions, cvkit's references and the loop/FFT/integral-image versions of
``tests/alternatives_ch03.py``, among themselves; a loop and a vectorized Gaussian kernel)
score at most 0.41. Over all 140 exercises of the course, the notebooks' solutions against
cvkit's references (written by the same authors, so not quite independent) score at most 0.58.
"""
from __future__ import annotations

import csv
import html
import inspect
import io
import json
import os
import re
import stat
from dataclasses import dataclass
from functools import lru_cache
from itertools import combinations
from pathlib import Path
from typing import Any, Iterable, Mapping

__all__ = [
    "NOISE", "THRESHOLD", "MIN_SIZE", "SOLUTION", "CODE_STUB", "MAX_NOTEBOOK_BYTES", "MAX_ANSWER_CHARS", "SimilarPair", "Exercise",
    "answer_sources", "exercise_algorithms", "exercises_from", "similar_pairs", "report",
    "write_csv", "write_html", "reference_label",
]

#: length of the k-grams (normalised characters) fingerprinted: the shortest match that counts
NOISE = 20
#: pairs whose similarity (mean of the two directions) is at least this are reported
THRESHOLD = 0.6
#: answers with fewer normalised characters of their own (stub removed) are not compared
MIN_SIZE = 40
#: the name the instructor's solution has in a pair
SOLUTION = "(instructor's solution)"
#: what nbgrader's ClearSolutions writes in place of a solution (cvkit's nbgrader_config.py too)
CODE_STUB = "# YOUR CODE HERE\nraise NotImplementedError()"
#: notebooks larger than this are not read (a notebook's answers are a few kB)
MAX_NOTEBOOK_BYTES = 64 * 2**20
#: answers are compared (and shown) up to this many characters
MAX_ANSWER_CHARS = 100_000

_SOLUTION_REGION = re.compile(r"^([ \t]*)### BEGIN SOLUTION[^\n]*\n(.*?)^[ \t]*### END SOLUTION[^\n]*$",
                              re.MULTILINE | re.DOTALL)
_NUMBER = re.compile(r"(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?[jJ]?")


@dataclass(frozen=True)
class SimilarPair:
    """Two answers to one exercise that look alike.

    Attributes
    ----------
    exercise : str
        The answer cell's ``grade_id`` (``"<notebook>:<grade_id>"`` when the assignment has
        several notebooks).
    a, b : str
        Student ids; ``b`` may also be ``"(reference cvkit.<id>)"`` or :data:`SOLUTION`.
        Two students come in sorted order.
    similarity : float
        Mean over the two answers of the fraction of each one's own code that matches the
        other, in [0, 1].
    a_source, b_source : str
        The two texts compared.
    assignment : str
        The assignment, when known.
    """

    exercise: str
    a: str
    b: str
    similarity: float
    a_source: str
    b_source: str
    assignment: str = ""


@dataclass(frozen=True)
class Exercise:
    """What one exercise's answers are compared with, besides each other.

    Attributes
    ----------
    stub : str
        The released answer cell (every student's starting point: boilerplate).
    reference : str or None
        Source of the reference implementation.
    reference_name : str
        How the reference is named, e.g. ``"cvkit.filters.gaussian"``.
    solution : str or None
        The instructor's solution.
    """

    stub: str = ""
    reference: str | None = None
    reference_name: str = ""
    solution: str | None = None


def reference_label(name: str) -> str:
    """The name of a reference implementation in a pair: ``"(reference cvkit.filters.gaussian)"``."""
    return f"(reference {name})"


# ------------------------------------------------------------------------------- notebooks
def _source(cell: Mapping) -> str | None:
    source = cell.get("source", "")
    if isinstance(source, list) and all(isinstance(part, str) for part in source):
        return "".join(source)
    return source if isinstance(source, str) else None


def _nbgrader(cell: Mapping) -> Mapping:
    metadata = cell.get("metadata")
    meta = metadata.get("nbgrader") if isinstance(metadata, Mapping) else None
    return meta if isinstance(meta, Mapping) else {}


def _cells(notebook: Any) -> list[Mapping]:
    cells = notebook.get("cells") if isinstance(notebook, Mapping) else None
    return [cell for cell in cells if isinstance(cell, Mapping)] if isinstance(cells, list) else []


def _answer_cell(cell: Mapping) -> bool:
    return cell.get("cell_type") == "code" and _nbgrader(cell).get("solution") is True


def answer_sources(notebook: Mapping) -> dict[str, str]:
    """The answer cells of a notebook: ``{grade_id: source}``.

    Parameters
    ----------
    notebook : dict
        A notebook as read by :func:`json.load` (or an nbformat node).

    Returns
    -------
    dict
        The source of every code cell whose nbgrader metadata has ``solution: true``, by its
        ``grade_id``. Malformed cells (a student can edit the JSON) are left out; a notebook
        that is not a dict gives ``{}``.
    """
    answers: dict[str, str] = {}
    for cell in _cells(notebook):
        grade_id = _nbgrader(cell).get("grade_id")
        source = _source(cell)
        if _answer_cell(cell) and isinstance(grade_id, str) and source is not None:
            answers.setdefault(grade_id, source)
    return answers


def exercise_algorithms(notebook: Mapping) -> dict[str, str]:
    """``{answer grade_id: algorithm id}``: the first argument of the first ``check("<id>", ...)``
    in the graded cells that follow each answer cell (up to the next answer cell)."""
    from .trusted import check_calls

    found: dict[str, str] = {}
    current = None
    for cell in _cells(notebook):
        meta = _nbgrader(cell)
        if _answer_cell(cell):
            current = meta.get("grade_id") if isinstance(meta.get("grade_id"), str) else None
        elif current is not None and current not in found and cell.get("cell_type") == "code" and meta.get("grade"):
            calls = check_calls(_source(cell) or "", str(meta.get("grade_id", "")))
            if calls:
                found[current] = calls[0].algorithm_id
    return found


def _released(text: str) -> str:
    """The answer cell as nbgrader releases it: each solution region replaced by the code stub,
    indented like its ``### BEGIN SOLUTION`` line."""
    return _SOLUTION_REGION.sub(lambda m: "\n".join(m.group(1) + line for line in CODE_STUB.splitlines()), text)


def _solution(text: str) -> str | None:
    """The instructor's solution: the text between the markers (all regions), or None."""
    regions = [m.group(2) for m in _SOLUTION_REGION.finditer(text)]
    return "".join(regions) if regions else None


def _reference(algorithm_id: str) -> tuple[str | None, str]:
    """Source and name of the reference implementation of ``algorithm_id`` (None if unknown)."""
    from .. import registry

    try:
        function = registry.get(algorithm_id).reference
        source = inspect.getsource(function)
    except (KeyError, ValueError, TypeError, OSError):
        return None, ""
    module = getattr(function, "__module__", "") or ""
    name = f"cvkit.{algorithm_id}" if module.split(".")[0] == "cvkit" else f"{module}.{function.__qualname__}"
    return source, name


def exercises_from(source_notebook: Mapping, release_notebook: Mapping | None = None) -> dict[str, Exercise]:
    """Every exercise of an instructor's source notebook: ``{grade_id: Exercise}``.

    Parameters
    ----------
    source_notebook : dict
        The nbgrader source notebook (solutions between ``### BEGIN SOLUTION`` /
        ``### END SOLUTION``, visible test cells ``check("<id>", ...)``).
    release_notebook : dict, optional
        The released notebook. Its answer cells are the stubs; without it (or for a cell it
        lacks) the stub is made from the source as nbgrader's ClearSolutions makes it.

    Returns
    -------
    dict
        For each answer cell: its stub, the instructor's solution and, when a test cell names
        a registered algorithm, the reference's source and name.
    """
    if not isinstance(source_notebook, Mapping):
        raise TypeError(f"source_notebook must be a notebook dict, got {type(source_notebook).__name__}")
    released = answer_sources(release_notebook) if isinstance(release_notebook, Mapping) else {}
    algorithms = exercise_algorithms(source_notebook)
    result = {}
    for grade_id, text in answer_sources(source_notebook).items():
        reference, name = _reference(algorithms[grade_id]) if grade_id in algorithms else (None, "")
        result[grade_id] = Exercise(released.get(grade_id, _released(text)), reference, name, _solution(text))
    return result


# ------------------------------------------------------------------------------- comparison
@lru_cache(maxsize=4096)
def _normalised(text: str) -> str:
    """copydetect's token text of ``text`` (names V, functions F, strings S), numbers as N."""
    from copydetect.utils import filter_code

    code, _ = filter_code(text, "answer.py", "python")
    return _NUMBER.sub("N", code)


def _fingerprint(normalised: str, boilerplate: Any = None) -> Any:
    from copydetect import CodeFingerprint

    return CodeFingerprint("answer.py", NOISE, 1, boilerplate, filter=False, fp=io.StringIO(normalised))


def _boilerplate(stub: str) -> Any:
    import numpy as np

    return np.array(sorted(_fingerprint(_normalised(stub)).hashes)) if stub.strip() else None


class _Document:
    """One normalised text's copydetect fingerprint, and its (hash, position) pairs as arrays."""

    def __init__(self, normalised: str, boilerplate: Any) -> None:
        import numpy as np

        self.fingerprint = _fingerprint(normalised, boilerplate)
        index = self.fingerprint.hash_idx
        self.hashes = np.array([h for h, places in index.items() for _ in places], dtype=np.int64)
        self.positions = np.array([p for places in index.values() for p in places], dtype=np.int64)
        self.unique = np.unique(self.hashes)

    def share(self, other: _Document) -> float:
        """The fraction of this text's own code that ``other`` contains, as
        :func:`copydetect.compare_files` computes it (copydetect's ``get_copied_slices`` over
        the positions of the shared k-grams, found by one vectorized binary search)."""
        import numpy as np
        from copydetect.utils import get_copied_slices

        if other.unique.size == 0 or not self.fingerprint.token_coverage:
            return 0.0
        found = other.unique[np.minimum(np.searchsorted(other.unique, self.hashes), other.unique.size - 1)]
        shared = self.positions[found == self.hashes]
        if shared.size == 0:
            return 0.0
        starts, ends = get_copied_slices(shared, self.fingerprint.k)
        return float(np.sum(ends - starts)) / float(self.fingerprint.token_coverage)


class _Comparer:
    """The fingerprints of one exercise's texts (one per distinct normalised text: copies are
    fingerprinted and compared once) and their pairwise similarities."""

    def __init__(self, stub: str) -> None:
        self.boilerplate = _boilerplate(stub)
        self.documents: dict[str, _Document] = {}
        self.values: dict[tuple[str, str], float] = {}

    def size(self, normalised: str) -> float:
        """Normalised characters of the text's own code (covered by k-grams not in the stub)."""
        if normalised not in self.documents:
            self.documents[normalised] = _Document(normalised, self.boilerplate)
        return float(self.documents[normalised].fingerprint.token_coverage)

    def similarity(self, first: str, second: str, threshold: float) -> float:
        """Mean over the two texts of the fraction of each one's own code found in the other.

        The vectorized :meth:`_Document.share` gives the value of every pair; the pairs it
        finds at or above ``threshold`` are measured again by :func:`copydetect.compare_files`,
        whose value is the one reported."""
        from copydetect import compare_files

        key = (first, second) if first <= second else (second, first)
        if key not in self.values:
            one, two = self.documents[key[0]], self.documents[key[1]]
            value = (one.share(two) + two.share(one)) / 2.0
            if value >= threshold - 1e-9 and value > 0.0:
                _, (share_one, share_two), _ = compare_files(one.fingerprint, two.fingerprint)
                value = (float(share_one) + float(share_two)) / 2.0
            self.values[key] = value
        return self.values[key]


def _blank(answer: str, stub: str) -> bool:
    return "".join(answer.split()) == "".join(stub.split())


def _check_threshold(threshold: Any, min_size: Any) -> None:
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)) or not 0.0 <= threshold <= 1.0:
        raise ValueError(f"threshold must be a number in [0, 1] (a fraction of matching code), got {threshold!r}")
    if isinstance(min_size, bool) or not isinstance(min_size, int) or min_size < 0:
        raise ValueError(f"min_size must be an integer >= 0 (normalised characters), got {min_size!r}")


def similar_pairs(answers: Mapping[str, Mapping[str, str]], exercises: Mapping[str, Exercise], *,
                  threshold: float = THRESHOLD, min_size: int = MIN_SIZE, assignment: str = "") -> list[SimilarPair]:
    """The pairs of answers to one assignment's exercises whose similarity is at least ``threshold``.

    Parameters
    ----------
    answers : mapping
        ``{student: {grade_id: answer source}}`` (e.g. :func:`answer_sources` of each
        student's notebook). Grade ids not in ``exercises`` are ignored.
    exercises : mapping
        ``{grade_id: Exercise}`` (e.g. :func:`exercises_from`): the stub, the reference's
        source and the instructor's solution of each exercise.
    threshold : float, default THRESHOLD
        Smallest similarity reported, in [0, 1].
    min_size : int, default MIN_SIZE
        Answers (and references, solutions) with fewer normalised characters of their own are
        not compared. Answers longer than :data:`MAX_ANSWER_CHARS` are cut there.
    assignment : str, optional
        Copied into every pair.

    Returns
    -------
    list of SimilarPair
        Student–student pairs (ids in sorted order), then student–reference and
        student–solution pairs, all sorted by decreasing similarity (ties by exercise, ids).
        Unanswered cells are never compared.
    """
    if not isinstance(answers, Mapping) or not all(isinstance(a, Mapping) for a in answers.values()):
        raise TypeError("answers must be a mapping {student: {grade_id: source}}")
    if not isinstance(exercises, Mapping) or not all(isinstance(e, Exercise) for e in exercises.values()):
        raise TypeError("exercises must be a mapping {grade_id: Exercise} (see exercises_from)")
    _check_threshold(threshold, min_size)
    pairs = []
    for grade_id in sorted(exercises):
        exercise = exercises[grade_id]
        comparer = _Comparer(exercise.stub)
        texts: dict[str, tuple[str, str]] = {}  # name -> (text, normalised), large enough to compare
        for student in sorted(answers, key=str):
            text = answers[student].get(grade_id)
            if isinstance(text, str) and not _blank(text, exercise.stub):
                text = text[:MAX_ANSWER_CHARS]
                texts[str(student)] = (text, _normalised(text))
        students = [name for name in texts if comparer.size(texts[name][1]) >= max(min_size, 1)]
        targets = []
        for name, text in ((reference_label(exercise.reference_name or "implementation"), exercise.reference),
                           (SOLUTION, exercise.solution)):
            if text:
                texts[name] = (text, _normalised(text))
                if comparer.size(texts[name][1]) >= min_size:
                    targets.append(name)
        comparisons = list(combinations(students, 2)) + [(a, b) for a in students for b in targets]
        for a, b in comparisons:
            value = comparer.similarity(texts[a][1], texts[b][1], threshold)
            if value >= threshold:
                pairs.append(SimilarPair(grade_id, a, b, round(value, 6), texts[a][0], texts[b][0], assignment))
    return sorted(pairs, key=lambda p: (-p.similarity, p.exercise, p.a, p.b))


# ------------------------------------------------------------------------------- course folders
def _read_notebook(path: Path, *, links: bool = False) -> dict | None:
    """The notebook at ``path``, or None: not a regular file (a device, a pipe; a symbolic link
    unless ``links``, a hard link to a file elsewhere), larger than MAX_NOTEBOOK_BYTES, not
    JSON, not a JSON object. Links are followed only for the instructor's own files."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | (0 if links else getattr(os, "O_NOFOLLOW", 0))
    try:
        descriptor = os.open(path, flags)
    except OSError:
        return None
    try:
        info = os.fstat(descriptor)
        if not stat.S_ISREG(info.st_mode) or info.st_size > MAX_NOTEBOOK_BYTES or (info.st_nlink > 1 and not links):
            return None
        with os.fdopen(descriptor, "rb", closefd=False) as handle:
            data = handle.read(MAX_NOTEBOOK_BYTES + 1)
        if len(data) > MAX_NOTEBOOK_BYTES:  # grew after fstat
            return None
        notebook = json.loads(data)
    except (OSError, ValueError, RecursionError):
        return None
    finally:
        os.close(descriptor)
    return notebook if isinstance(notebook, dict) else None


def _plain_folder(path: Path) -> bool:
    """A folder that is not a symbolic link."""
    try:
        return stat.S_ISDIR(path.lstat().st_mode)
    except OSError:
        return False


def report(course_root: str | os.PathLike, source_dir: str | os.PathLike, assignment: str,
           threshold: float = THRESHOLD, *, min_size: int = MIN_SIZE) -> list[SimilarPair]:
    """The similar pairs of one assignment of an nbgrader course.

    Parameters
    ----------
    course_root : path
        The course folder: answers are read from
        ``course_root/submitted/<student>/<assignment>/*.ipynb``, stubs from
        ``course_root/release/<assignment>/`` when it is there.
    source_dir : path
        The instructor's source notebooks: ``source_dir/<assignment>/*.ipynb``.
    assignment : str
        The assignment (a folder name).
    threshold : float, default THRESHOLD
        Smallest similarity reported, in [0, 1].
    min_size : int, default MIN_SIZE
        See :func:`similar_pairs`.

    Returns
    -------
    list of SimilarPair
        As :func:`similar_pairs`, sorted by decreasing similarity. With several notebooks in
        the assignment, exercises are named ``"<notebook stem>:<grade_id>"``.

    Notes
    -----
    Of the submissions, only regular files in plain folders are read: symbolic links (and
    what they point at), hard links to other files, devices and pipes are skipped, as are
    notebooks that are not valid JSON, larger than :data:`MAX_NOTEBOOK_BYTES`, and student
    folders whose name starts with a dot. The course's own folders (``submitted``,
    ``release``, the sources) may be links. Nothing is written.
    """
    for name, value in (("course_root", course_root), ("source_dir", source_dir)):
        if not isinstance(value, (str, os.PathLike)):
            raise TypeError(f"{name} must be a path, got {type(value).__name__}")
    if not isinstance(assignment, str) or not assignment or assignment in (".", "..") or re.search(r"[/\\\0]", assignment):
        raise ValueError(f"assignment must be a folder name such as 'ch03_filtering', got {assignment!r}")
    _check_threshold(threshold, min_size)
    root, sources = Path(course_root), Path(source_dir) / assignment
    names = sorted(p.name for p in sources.glob("*.ipynb") if not p.name.startswith(".")) if sources.is_dir() else []
    submitted = root / "submitted"
    students = sorted(p.name for p in submitted.iterdir() if not p.name.startswith(".") and _plain_folder(p)) \
        if submitted.is_dir() else []
    exercises: dict[str, Exercise] = {}
    answers: dict[str, dict[str, str]] = {student: {} for student in students}
    for name in names:
        source = _read_notebook(sources / name, links=True)
        if source is None:
            continue
        release = _read_notebook(root / "release" / assignment / name, links=True)
        prefix = f"{Path(name).stem}:" if len(names) > 1 else ""
        exercises.update({prefix + key: value for key, value in exercises_from(source, release).items()})
        for student in students:
            folder = submitted / student / assignment
            notebook = _read_notebook(folder / name) if _plain_folder(folder) else None
            if notebook is not None:
                answers[student].update({prefix + key: text for key, text in answer_sources(notebook).items()})
    return similar_pairs(answers, exercises, threshold=threshold, min_size=min_size, assignment=assignment)


# ------------------------------------------------------------------------------- exports
def _pairs(pairs: Iterable[SimilarPair]) -> list[SimilarPair]:
    items = list(pairs)
    if not all(isinstance(pair, SimilarPair) for pair in items):
        raise TypeError("pairs must be an iterable of SimilarPair (see similar_pairs, report)")
    return sorted(items, key=lambda p: (-p.similarity, p.assignment, p.exercise, p.a, p.b))


def write_csv(pairs: Iterable[SimilarPair], path: str | os.PathLike) -> Path:
    """Write ``pairs`` as CSV (``exports/similarity.csv``) and return the path.

    Columns ``assignment, exercise, student_a, student_b, similarity`` (three decimals), by
    decreasing similarity. Cells that a spreadsheet would read as a formula are escaped by
    :func:`cvkit.grading.safety.csv_safe`. Missing parent folders are created.
    """
    from .safety import csv_safe

    rows = [(p.assignment, p.exercise, p.a, p.b, f"{p.similarity:.3f}") for p in _pairs(pairs)]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8", errors="surrogateescape") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(["assignment", "exercise", "student_a", "student_b", "similarity"])
        writer.writerows([csv_safe(cell) for cell in row] for row in rows)
    return path


_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="default-src 'none'; style-src 'unsafe-inline'">
<title>Similar answers</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; }}
table.index td, table.index th {{ padding: 0.2em 0.8em; text-align: left; }}
section {{ border-top: 1px solid #999; margin-top: 1.5em; }}
.sides {{ display: grid; grid-template-columns: 1fr 1fr; gap: 1em; }}
pre {{ background: #f4f4f4; padding: 0.6em; overflow-x: auto; white-space: pre; font-size: 0.85em; }}
</style></head><body>
<h1>Similar answers</h1>
<p>{count} pair(s). Similarity: the mean over the two answers of the share of each one's own code
(the released stub left out) that the other contains, after names, strings and numbers are
abstracted (copydetect's winnowing). A signal to look at, never a score.</p>
{index}
{sections}
</body></html>
"""


def write_html(pairs: Iterable[SimilarPair], path: str | os.PathLike) -> Path:
    """Write one self-contained HTML page of ``pairs`` (the two answers side by side, by
    decreasing similarity) and return the path. Every text is HTML-escaped; the page has no
    script and a Content-Security-Policy that allows none. Missing parent folders are created."""
    ordered = _pairs(pairs)
    e = html.escape
    rows, sections = [], []
    for number, p in enumerate(ordered, 1):
        where = f"{p.assignment} / {p.exercise}" if p.assignment else p.exercise
        rows.append(f'<tr><td><a href="#pair-{number}">{p.similarity:.0%}</a></td><td>{e(where)}</td>'
                    f"<td>{e(p.a)}</td><td>{e(p.b)}</td></tr>")
        sections.append(
            f'<section id="pair-{number}"><h2>{p.similarity:.0%} &mdash; {e(where)}</h2><div class="sides">'
            f"<div><h3>{e(p.a)}</h3><pre>{e(p.a_source)}</pre></div>"
            f"<div><h3>{e(p.b)}</h3><pre>{e(p.b_source)}</pre></div></div></section>")
    index = ("<table class=\"index\"><tr><th>similarity</th><th>exercise</th><th>a</th><th>b</th></tr>"
             + "".join(rows) + "</table>") if rows else "<p>No pair above the threshold.</p>"
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(_PAGE.format(count=len(ordered), index=index, sections="\n".join(sections)), encoding="utf-8",
                    errors="surrogateescape")
    return path
