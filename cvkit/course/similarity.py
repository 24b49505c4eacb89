"""Similarity report: answers that look copied, for the instructor to look at.

For every exercise of an assignment (an nbgrader answer cell: a ``solution: true`` code cell),
each student's answer — the answer cell and the code it pulls in from the cells the student
added (:func:`student_code`) — is compared with every other student's answer, with the reference
implementation of the exercise's algorithm (its source, :func:`inspect.getsource`) and with the
instructor's solution (the source notebook's text between ``### BEGIN SOLUTION`` and
``### END SOLUTION``); all of a student's added code is also compared with the other students'
(the pseudo-exercise :data:`ADDED`). Pairs above a threshold are listed (:func:`similar_pairs`,
:func:`report`), gathered into groups of near-identical answers (:func:`groups`) and exported,
one row per student of a group and one section per group (:func:`write_csv`,
:func:`write_html`). It is a signal for the instructor, never a score change: nothing here
touches a grade.

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

Every pair of an exercise's distinct normalised texts is measured by a vectorized equivalent of
:func:`copydetect.compare_files`: one text against all the others at once, in a few array
operations over a table of which text holds which shared k-gram, the copied share being the
union of the shared k-grams' spans, as copydetect's own ``get_copied_slices`` computes it (the
same values to rounding, tested; with too many shared k-grams to hold, one pair at a time).
:func:`~copydetect.compare_files` itself measures again only the pairs within 1e-6 of the
threshold, so that rounding never decides a pair. (It used to measure again every pair at or
above the threshold: in a class whose answers come from a few common sources that is most pairs,
and 60 % of the time.) Identical normalised texts (copies) are fingerprinted and compared once.
Tokenizing (Pygments) costs a few milliseconds per answer, a pair well under one.

Added code
~~~~~~~~~~
The grader runs every code cell a student added or changed, not only the answer cells
(:func:`cvkit.course.trusted.worker_cells`), so all of that code is compared. A student's
**added code** is every code cell of their notebook that is neither an exercise's answer cell
(the first cell with that ``grade_id``) nor a test cell, and whose text (white space at its ends
aside) is none of the instructor's non-answer code cells (of the source or the release
notebook): the cells they inserted, and the release cells they changed. Unchanged set-up, demo
and test cells are never compared; test cells are never student code (the grader does not run
a student's test cells).

*Per exercise*, the compared text is the answer cell followed by the definitions it **pulls
in**. Each cell is split into its top-level statements (statements sharing a line are one). A
statement *defines* the module-level names it binds (``def``, ``class``, assignments, ``for`` and
``with`` targets, a ``global`` name assigned in a function; imports are not definitions) and
the names whose value it changes (``d[k] = …``, ``o.x = …``, a statement ``d.update(…)``); it
*uses* the module-level names it reads, as :mod:`symtable` resolves them (a function's
parameters and locals are not module-level names). Starting from the names the answer cell uses
and defines and the names of the functions its test cells check, each name pulls in every
statement of the added cells that defines it — all of them, wherever they are in the notebook,
since a later cell may redefine the graded function — then the names those statements use,
transitively. An exercise whose answer cell is gone (deleted, or its metadata changed) is
compared with what its checked function's name pulls in. Top-level statements placed beside
another exercise's answer function (a helper
in another answer cell) are pulled in the same way; that exercise's answer function itself is
not (a building block such as ``pad`` called by ``correlate`` is compared in its own exercise).
Names are matched, not traced: a name read only through a string (``globals()["f"]``) pulls in
nothing, and a module-level name that happens to be defined in an added cell pulls in that
definition even if it is dead code (more is compared, never less). A cell that does not compile
(after IPython's ``%``/``!`` lines are replaced, as the grader's worker replaces them) does not run
in the grader, so it defines nothing; its text is still compared (as an answer, or among the
added cells). The pulled statements follow the answer in notebook order, after a comment naming
them (comments are not compared), and each pair says whose text includes added code
(:attr:`SimilarPair.added`, the CSV's and the page's exercise column:
``mean_kernel_answer + added code (ann: _helper)``). The exercise's boilerplate also holds the
k-grams of the obvious wrapper (the stub's body a call of a helper with the function's
parameters, then the helper's ``def`` line — the stub's signature or the bare parameter names —
with or without a docstring): two students who each move their whole answer into a helper share
that glue, and it is nobody's own code.

*All added code* of a notebook is compared too, as one more exercise, :data:`ADDED`: each
student's added cells, in notebook order, against the other students' (not with a reference or
the solution: it is no exercise's answer). It shows copied helper code however it is called
(through a string, a dict, a wrapper the names do not reveal). Its boilerplate is every code cell
the instructor released (set-up, demos, test cells, the answer stubs), so a demo run again with
other numbers, or a copy of a test call, is nothing of the student's own.

Cost: cells are split with :mod:`ast` and resolved with :mod:`symtable` (about a second per
megabyte); an answer cell with nothing beside its answer function (every line that starts in
column 0 a comment, a decorator or that function's ``def`` line) is parsed only when the
notebook has something to pull in. A student's cells are parsed up to :data:`MAX_PARSED_CHARS` characters per
notebook, in notebook order (cells beyond define nothing; they are still compared as text). A
pulled definition is tokenized again in each exercise that pulls it in; :data:`ADDED` adds one
text per student with added code, and one exercise per notebook. Measured on 100 submissions of
Chapter 3 (13 exercises, CPU time of :func:`report`): 2.4 s before added code was compared; now
2.6 s when no one added code, 3.2 s when every student added two cells.

What is skipped: unanswered cells (the released stub as it is, or nothing of the student's own
left once the stub's k-grams are removed) and answers with fewer than ``min_size``
(:data:`MIN_SIZE`) normalised characters of their own: a three-line exercise has only one
natural solution, so matching ones say nothing.

Threshold
---------
:data:`THRESHOLD` (0.6) was chosen on the course's own material
(``tests/course/test_similarity.py``): copies with renamed variables and reordered statements of
Chapter 3's solutions score 0.75 to 1.0; independent correct solutions (the notebooks'
solutions, cvkit's references and the loop/FFT/integral-image versions of
``tests/library/alternatives_ch03.py``, among themselves; a loop and a vectorized Gaussian kernel)
score at most 0.41. Over all 140 exercises of the course, the notebooks' solutions against
cvkit's references (written by the same authors, so not quite independent) score at most 0.58.
Added code is measured the same way and with the same threshold
(``tests/course/test_similarity_added_cells.py``): a helper copied with renamed variables and two
statements swapped, called from two answer cells that share nothing, scores 0.68 with the
pulled-in code and 0.91 among the added cells; the instructor's solution pasted into a helper
scores 0.97 against the solution; two honest students' own helpers score 0. The independent
solutions above, each moved whole into a helper that the answer cell calls, score at most 0.41
among themselves (0.39 as plain answers; 0.59 without the wrapper boilerplate).

Groups
------
A real class's correct answers come from a few common sources (the textbook, a popular version,
each other), so the pairs above the threshold grow with the square of the class: a simulated
class of 60 students answering Chapter 3's 13 exercises from three sources
(``tests/course/simulated_class.py``) gives 7,163 pairs, and a page of one side-by-side view per pair
was 23.8 MB (a class of 300: 191,763 pairs, about 640 MB). The report is made of **groups**
instead (:func:`groups`): per exercise, the connected components of the graph whose edges are
the pairs at or above the threshold (single linkage, found by union-find over the pairs
:func:`similar_pairs` already measured: no comparison more). Single linkage was chosen over
average or complete linkage because it hides nothing: every reported pair is inside one group,
so two answers alike are always seen together (a copied pair among unique answers is a group of
two); its weakness, chaining (A like B, B like C, A not like C), is shown rather than hidden —
each member is listed with the text closest to it and its similarity to the group's central
answer, "below the threshold" when that pair is not alike. The instructor's solution and the
references are members like the students: a group that holds one is labelled *textbook answer*
(everyone who wrote the usual correct answer: a weak signal) and listed after the groups of
students alone; a student who pasted the reference is a group of one student and the reference.
Each group shows its answers side by side: all of them in a group of up to :data:`SHOWN_ALL`
students, else its central answer (the student whose similarities to the others add up to the
most) and its student least like the central answer (the spread); then the textbook text, in a
textbook group. The page and the CSV grow with the number of students in groups, not with the
pairs: the simulated class of 60 gives 39 groups and a page of 0.24 MB, a class of 300 a page of
0.47 MB (``tests/course/test_similarity_clusters.py``). Measuring, grouping and writing take 2 s of CPU
for the class of 60 and 10 to 14 s for the class of 300, most of it tokenizing the answers
(``benchmarks/bench_similarity.py``; figures in ``benchmarks/README.md``).
"""
from __future__ import annotations

import ast
import csv
import html
import inspect
import io
import json
import os
import re
import stat
import symtable
from dataclasses import dataclass
from functools import lru_cache
from itertools import combinations
from pathlib import Path
from typing import Any, Iterable, Mapping

from .._text import name_problem, printable
from ..grading.runtime.cells import cell_source, cells_of, is_code, is_test_cell, nbgrader_metadata
from .files import whole_file, write_whole

__all__ = [
    "NOISE", "THRESHOLD", "MIN_SIZE", "SOLUTION", "CODE_STUB", "MAX_NOTEBOOK_BYTES", "MAX_ANSWER_CHARS", "ADDED",
    "ALL_ADDED", "MAX_PARSED_CHARS", "SimilarPair", "Exercise", "Answer",
    "answer_sources", "exercise_algorithms", "exercises_from", "student_code", "added_cells_exercise", "similar_pairs",
    "report", "write_csv", "write_html", "reference_label", "exercise_label", "Member", "SimilarGroup", "groups",
    "CSV_COLUMNS", "SHOWN_ALL",
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
#: the pseudo-exercise of a notebook that holds all of a student's added code (prefixed by the
#: notebook's stem, as exercises are, when the assignment has several notebooks)
ADDED = "(added cells)"
#: :attr:`SimilarPair.added` of a pair of :data:`ADDED` texts
ALL_ADDED = "all added cells"
#: characters of a student's code cells (answers and added cells, in notebook order) parsed per
#: notebook to find the definitions answers pull in; a cell that does not fit defines nothing
MAX_PARSED_CHARS = 1_000_000

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
    added : str
        What of the two texts is added code: ``""`` (answer cells only), :data:`ALL_ADDED` (a
        pair of :data:`ADDED` texts), or whose answer pulls in which definitions from added
        cells, e.g. ``"ann: _helper; bob: _kernel _inner"``.
    a_pulled, b_pulled : tuple of str
        The names of the definitions each text pulls in from added cells (:attr:`Answer.pulled`).
    textbook : bool or None
        Whether ``b`` is the instructor's solution or a reference implementation rather than a
        student (:func:`similar_pairs` sets it; None: told by the name, see :meth:`is_textbook`).
    """

    exercise: str
    a: str
    b: str
    similarity: float
    a_source: str
    b_source: str
    assignment: str = ""
    added: str = ""
    a_pulled: tuple[str, ...] = ()
    b_pulled: tuple[str, ...] = ()
    textbook: bool | None = None

    def is_textbook(self) -> bool:
        """Whether ``b`` is the instructor's solution or a reference implementation (the
        ``textbook`` attribute; when it is None, told by ``b``'s name)."""
        if self.textbook is not None:
            return bool(self.textbook)
        return self.b == SOLUTION or (self.b.startswith("(reference ") and self.b.endswith(")"))


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
    added_cells : bool
        Whether this is a notebook's :data:`ADDED` pseudo-exercise (its ``stub``: every code
        cell the instructor released).
    """

    stub: str = ""
    reference: str | None = None
    reference_name: str = ""
    solution: str | None = None
    added_cells: bool = False


@dataclass(frozen=True)
class Answer:
    """A student's code for one exercise, as it is compared (:func:`student_code`).

    Attributes
    ----------
    text : str
        The answer cell, followed by the definitions it pulls in from added cells; for
        :data:`ADDED`, all the student's added cells.
    pulled : tuple of str
        The names of the definitions pulled in, in notebook order (empty: the cell alone).
    """

    text: str
    pulled: tuple[str, ...] = ()


def reference_label(name: str) -> str:
    """The name of a reference implementation in a pair: ``"(reference cvkit.filters.gaussian)"``."""
    return f"(reference {name})"


# ------------------------------------------------------------------------------- notebooks
def _answer_cell(cell: Mapping) -> bool:
    return is_code(cell) and nbgrader_metadata(cell).get("solution") is True


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
    for cell in cells_of(notebook):
        grade_id = nbgrader_metadata(cell).get("grade_id")
        source = cell_source(cell, None)
        if _answer_cell(cell) and isinstance(grade_id, str) and source is not None:
            answers.setdefault(grade_id, source)
    return answers


def _exercise_calls(notebook: Mapping) -> dict[str, list[Any]]:
    """``{answer grade_id: [CheckCall, ...]}``: the ``check(...)`` calls of the graded cells that
    follow each answer cell (up to the next answer cell), in order."""
    from .trusted import check_calls

    found: dict[str, list[Any]] = {}
    current = None
    for cell in cells_of(notebook):
        meta = nbgrader_metadata(cell)
        if _answer_cell(cell):
            current = meta.get("grade_id") if isinstance(meta.get("grade_id"), str) else None
        elif current is not None and is_code(cell) and meta.get("grade"):
            calls = check_calls(cell_source(cell), str(meta.get("grade_id", "")))
            if calls:
                found.setdefault(current, []).extend(calls)
    return found


def exercise_algorithms(notebook: Mapping) -> dict[str, str]:
    """``{answer grade_id: algorithm id}``: the first argument of the first ``check("<id>", ...)``
    in the graded cells that follow each answer cell (up to the next answer cell)."""
    return {grade_id: calls[0].algorithm_id for grade_id, calls in _exercise_calls(notebook).items()}


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


# ------------------------------------------------------------------------------- student code
@dataclass(frozen=True)
class _Unit:
    """Top-level statements of a cell (those sharing a line together): the module-level names
    they define, the module-level names they use, their text."""

    defines: frozenset[str]
    uses: frozenset[str]
    text: str


def _without_magics(source: str) -> str:
    """The cell as the grader's worker compiles it: IPython's ``%`` and ``!`` lines made ``pass``."""
    return "\n".join("pass  # magic" if line.lstrip().startswith(("%", "!")) else line
                     for line in source.splitlines())


def _changed(statements: list[ast.stmt]) -> set[str]:
    """Names whose value module-level statements change without binding them: the root name of
    an attribute or item they assign or delete (``d[k] = f``, ``o.x = f``), and the object of a
    method call that is a statement (``d.update(k=f)``). Function and class bodies are not
    module level."""
    found: set[str] = set()
    for statement in statements:
        call = statement.value if isinstance(statement, ast.Expr) else None
        method = call.func if isinstance(call, ast.Call) else None
        if isinstance(method, ast.Attribute) and isinstance(method.value, ast.Name):
            found.add(method.value.id)
        stack: list[ast.AST] = [statement]
        while stack:
            node = stack.pop()
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Lambda)):
                stack += [*getattr(node, "decorator_list", ()), *getattr(node, "bases", ())]
                continue
            if isinstance(node, (ast.Attribute, ast.Subscript)) and isinstance(node.ctx, (ast.Store, ast.Del)):
                root = node.value
                while isinstance(root, (ast.Attribute, ast.Subscript)):
                    root = root.value
                if isinstance(root, ast.Name):
                    found.add(root.id)
            stack.extend(ast.iter_child_nodes(node))
    return found


def _scopes(text: str) -> tuple[set[str], set[str]] | None:
    """(defined, used) module-level names of ``text``, as :mod:`symtable` resolves them; None
    if it does not compile on its own."""
    try:
        top = symtable.symtable(text, "<cell>", "exec")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return None
    defines: set[str] = set()
    uses: set[str] = set()
    tables = [top]
    while tables:
        table = tables.pop()
        for symbol in table.get_symbols():
            name = symbol.get_name()
            if symbol.is_referenced() and (table is top or symbol.is_global()):
                uses.add(name)
            if symbol.is_assigned() and not symbol.is_imported() and (table is top or symbol.is_declared_global()):
                defines.add(name)
        tables.extend(table.get_children())
    return defines, uses


def _units(source: str) -> list[_Unit]:
    """The top-level statements of a cell with what they define and use; ``[]`` for a cell
    that does not compile (it does not run in the grader, so it defines nothing)."""
    code = _without_magics(source)
    try:
        tree = ast.parse(code)
        compile(tree, "<cell>", "exec", dont_inherit=True)
    except (SyntaxError, ValueError, TypeError, RecursionError, MemoryError):
        return []
    lines = code.split("\n")
    groups: list[tuple[int, int, list[ast.stmt]]] = []  # (first line, last line, statements), 1-based
    for statement in tree.body:
        first = min([statement.lineno] + [d.lineno for d in getattr(statement, "decorator_list", ())])
        last = statement.end_lineno or statement.lineno
        if groups and first <= groups[-1][1]:
            groups[-1] = (groups[-1][0], max(last, groups[-1][1]), groups[-1][2] + [statement])
        else:
            groups.append((first, last, [statement]))
    units = []
    for first, last, statements in groups:
        text = "\n".join(lines[first - 1:last])
        names = _scopes(text)
        if names is not None:
            defines, uses = names
            units.append(_Unit(frozenset(defines | _changed(statements)), frozenset(uses), text))
    return units


def _instructor_code(*notebooks: Mapping | None) -> set[str]:
    """The text (ends stripped) of every non-answer code cell of the instructor's notebooks."""
    found = set()
    for notebook in notebooks:
        for cell in cells_of(notebook):
            source = cell_source(cell, None)
            if is_code(cell) and not _answer_cell(cell) and source is not None:
                found.add(source.strip())
    return found


@dataclass(frozen=True)
class _Release:
    """What the instructor's notebooks tell about students' cells (read once per notebook):
    the exercises' grade ids, the functions each exercise's test cells check, and the text of
    the instructor's non-answer code cells."""

    exercise_ids: frozenset[str]
    checked: Mapping[str, frozenset[str]]
    instructors: frozenset[str]

    @classmethod
    def of(cls, source_notebook: Mapping, release_notebook: Mapping | None = None) -> _Release:
        if not isinstance(source_notebook, Mapping):
            raise TypeError(f"source_notebook must be a notebook dict, got {type(source_notebook).__name__}")
        calls = _exercise_calls(source_notebook)
        return cls(frozenset(answer_sources(source_notebook)),
                   {grade_id: frozenset(call.function for call in found) for grade_id, found in calls.items()},
                   frozenset(_instructor_code(source_notebook, release_notebook)))


def student_code(notebook: Mapping, source_notebook: Mapping,
                 release_notebook: Mapping | None = None) -> dict[str, Answer]:
    """What a student wrote in one notebook, as the report compares it (module docstring,
    *Added code*).

    Parameters
    ----------
    notebook : dict
        The student's notebook (as read by :func:`json.load`).
    source_notebook : dict
        The instructor's source notebook: its answer cells are the exercises, its test cells
        name the checked functions, its other code cells are not the student's.
    release_notebook : dict, optional
        The released notebook: its code cells are not the student's either.

    Returns
    -------
    dict
        ``{grade_id: Answer}`` for each exercise the notebook has an answer cell for (the cell,
        then the definitions it pulls in from added code), or whose checked function its added
        code defines (an answer moved out of its cell); and ``{ADDED: Answer}`` (all the added
        cells, up to :data:`MAX_ANSWER_CHARS`) when the student added or changed code cells.
        Malformed cells are left out; a notebook that is not a dict gives ``{}``.
    """
    return _student_code(notebook, _Release.of(source_notebook, release_notebook))


def _student_code(notebook: Mapping, release: _Release) -> dict[str, Answer]:
    """:func:`student_code`, the instructor's notebooks read once (``release``)."""
    checked = release.checked
    answers: dict[str, tuple[int, str]] = {}  # grade_id -> (cell position, source)
    added: list[tuple[int, str]] = []
    for position, cell in enumerate(cells_of(notebook)):
        source = cell_source(cell, None)
        if not is_code(cell) or source is None or is_test_cell(cell):
            continue
        grade_id = nbgrader_metadata(cell).get("grade_id")
        if _answer_cell(cell) and isinstance(grade_id, str) and grade_id in release.exercise_ids \
                and grade_id not in answers:
            answers[grade_id] = (position, source)
        elif source.strip() not in release.instructors:  # not a release cell left as it is
            added.append((position, source))
    budget = MAX_PARSED_CHARS
    units: dict[int, list[_Unit]] = {}

    def parse(position: int, source: str) -> list[_Unit]:
        nonlocal budget
        if position not in units:
            units[position] = _units(source) if len(source) <= budget else []
            budget -= len(source) if len(source) <= budget else 0
        return units[position]

    # what can be pulled in: (position, answer cell's grade_id or None, unit), in notebook order
    pool: list[tuple[tuple[int, int], str | None, _Unit]] = []
    sources = sorted([(position, grade_id, source) for grade_id, (position, source) in answers.items()]
                     + [(position, None, source) for position, source in added], key=lambda item: item[0])
    for position, origin, source in sources:
        if origin is not None and _only_defines(source, checked.get(origin, frozenset())):
            continue  # an answer cell with nothing beside its answer function: parsed below if needed
        found = parse(position, source)
        pool += [((position, index), origin, unit) for index, unit in enumerate(found)
                 if origin is None or not unit.defines & checked.get(origin, frozenset())]
    result = {grade_id: Answer(source) for grade_id, (_, source) in answers.items()}
    if pool:
        defined_by: dict[str, list[int]] = {}
        for index, (_, _, unit) in enumerate(pool):
            for name in unit.defines:
                defined_by.setdefault(name, []).append(index)
        for grade_id in sorted(release.exercise_ids):
            # no answer cell: the checked function may be defined in added code
            position, source = answers.get(grade_id, (-1, ""))
            pending = set(checked.get(grade_id, frozenset()))
            for unit in parse(position, source) if source else []:
                pending |= unit.uses | unit.defines
            seen: set[str] = set()
            matched: set[str] = set()
            chosen: set[int] = set()
            while pending:
                name = pending.pop()
                seen.add(name)
                for index in defined_by.get(name, ()):
                    _, origin, unit = pool[index]
                    if origin != grade_id:
                        matched.add(name)
                        if index not in chosen:
                            chosen.add(index)
                            pending |= unit.uses - seen
            if chosen or grade_id in answers:
                result[grade_id] = _with_pulled(source, [pool[index][2] for index in sorted(chosen)], matched)
    if added:
        text, size = [], 0
        for _, part in added:
            text.append(part[:MAX_ANSWER_CHARS - size])
            size += len(text[-1]) + 2
            if size >= MAX_ANSWER_CHARS:
                break
        result[ADDED] = Answer("\n\n".join(text))
    return result


_DEF_LINE = re.compile(r"(?:async[ \t]+)?(?:def|class)[ \t]+(\w+)")


def _only_defines(source: str, names: frozenset[str]) -> bool:
    """Whether every line of ``source`` that may start a top-level statement (a line, as the
    grader's worker splits them, starting with neither white space, ``#`` nor ``@``) is the
    ``def`` or ``class`` line of one of ``names``: then the cell has nothing beside its answer
    (a test that spares parsing it; a top-level statement always starts in column 0)."""
    for line in source.splitlines():
        if line and line[0] not in " \t#@":
            definition = _DEF_LINE.match(line)
            if definition is None or definition.group(1) not in names:
                return False
    return True


def _with_pulled(source: str, units: list[_Unit], matched: set[str]) -> Answer:
    """The answer cell followed by the units it pulls in, after a comment naming them."""
    if not units:
        return Answer(source)
    names = tuple(dict.fromkeys(name for unit in units for name in sorted(unit.defines) if name in matched))
    comment = "# ---- pulled in from the student's other cells: " + " ".join(names) + " ----"
    pulled = "\n\n".join(unit.text for unit in units)
    return Answer((source + "\n\n" if source else "") + comment + "\n" + pulled, names)


def added_cells_exercise(source_notebook: Mapping, release_notebook: Mapping | None = None) -> Exercise:
    """A notebook's :data:`ADDED` pseudo-exercise: compared between students only, with every
    code cell the instructor released as boilerplate (the non-answer code cells of both
    notebooks and the answer stubs: the release's, or made from the source as nbgrader does)."""
    if not isinstance(source_notebook, Mapping):
        raise TypeError(f"source_notebook must be a notebook dict, got {type(source_notebook).__name__}")
    released = answer_sources(release_notebook) if isinstance(release_notebook, Mapping) else {}
    stubs = [released.get(grade_id, _released(text)) for grade_id, text in answer_sources(source_notebook).items()]
    return Exercise(stub="\n\n".join(sorted(_instructor_code(source_notebook, release_notebook)) + stubs),
                    added_cells=True)


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


def _wrappers(stub: str) -> list[str]:
    """The released answer cell as a student who moves the whole answer into a helper of their
    own writes it: the function's body a call of the helper with the function's parameters,
    then the helper's ``def`` line (the stub's signature, or the parameter names alone), with
    and without a docstring. Two such wrappers alike say nothing, as two stubs alike say nothing."""
    try:
        tree = ast.parse(stub)
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return []
    lines = stub.split("\n")
    texts = []
    for node in tree.body:
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) or not node.body:
            continue
        first = node.body[0]
        documented = isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
            and isinstance(first.value.value, str)
        head = "\n".join(lines[:(first.end_lineno or first.lineno) if documented else first.lineno - 1])
        signature = "\n".join(lines[node.lineno - 1:first.lineno - 1]).strip()
        signature = re.sub(r"^(async\s+)?def\s+\w+", "def _helper", signature)
        if "\n" in signature or not signature.endswith(":"):  # a def line written on several lines, or a one-liner
            signature = ""
        arguments = node.args
        names = [a.arg for a in arguments.posonlyargs + arguments.args]
        keywords = [a.arg for a in arguments.kwonlyargs]
        rest = [f"**{arguments.kwarg.arg}"] if arguments.kwarg else []
        star = [f"*{arguments.vararg.arg}"] if arguments.vararg else []
        passed = names + star + [f"{k}={k}" for k in keywords] + rest
        plain = names + (star or (["*"] if keywords else [])) + keywords + rest
        indent = " " * first.col_offset
        call = f"{head}\n{indent}return _helper({', '.join(passed)})\n\n\n"
        for define in ([signature] if signature else []) + [f"def _helper({', '.join(plain)}):"]:
            texts += [call + define, call + define + '\n    """The answer."""']
    return texts


def _boilerplate(stub: str, wrappers: bool = True) -> Any:
    """The hashes of the k-grams that are nobody's own code: the stub's, and its wrappers' (:func:`_wrappers`)."""
    import numpy as np

    if not stub.strip():
        return None
    texts = [stub] + (_wrappers(stub) if wrappers else [])
    return np.unique(np.concatenate([np.array(sorted(_fingerprint(_normalised(text)).hashes), dtype=np.int64)
                                     for text in texts]))


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

    def __init__(self, stub: str, wrappers: bool = True) -> None:
        self.boilerplate = _boilerplate(stub, wrappers)
        self.documents: dict[str, _Document] = {}
        self.values: dict[tuple[str, str], float] = {}
        self.checked: set[tuple[str, str]] = set()

    def size(self, normalised: str) -> float:
        """Normalised characters of the text's own code (covered by k-grams not in the stub)."""
        if normalised not in self.documents:
            self.documents[normalised] = _Document(normalised, self.boilerplate)
        return float(self.documents[normalised].fingerprint.token_coverage)

    def measure_all(self, texts: Iterable[str]) -> None:
        """Measure every pair of the distinct ``texts`` (normalised, each passed to :meth:`size`
        before) at once: for each text, the share of its own code found in every other text, one text
        against all the others in a few array operations (:meth:`_Document.share`'s values:
        tested). :meth:`similarity` then reads them."""
        import numpy as np

        names = [text for text in dict.fromkeys(texts) if text in self.documents]
        if len(names) < 3:
            return
        documents = [self.documents[name] for name in names]
        count = len(documents)
        # only the k-grams found in two texts or more can be shared
        every, seen = np.unique(np.concatenate([d.unique for d in documents]), return_counts=True)
        vocabulary = every[seen >= 2]
        if count * vocabulary.size > 32 * _BATCH:  # too many shared k-grams to hold: one pair at a time
            return
        member = np.zeros((count, vocabulary.size + 1), dtype=bool)  # the last column: a k-gram of one text
        for row, document in enumerate(documents):
            member[row, _columns(vocabulary, document.unique)] = True
        member[:, -1] = False
        shares = np.zeros((count, count))
        far = np.iinfo(np.int64).max // 4
        for row, document in enumerate(documents):
            coverage = document.fingerprint.token_coverage
            if not coverage or document.hashes.size == 0:
                continue
            order = np.argsort(document.positions, kind="stable")
            positions = document.positions[order]
            columns = _columns(vocabulary, document.hashes[order])
            k = document.fingerprint.k
            step = max(1, _BATCH // positions.size)
            for start in range(0, count, step):  # a block of the other texts at a time (bounded memory)
                found = member[start:start + step, columns]  # others x this text's positions: k-gram shared?
                at = np.where(found, positions, far)
                following = np.minimum.accumulate(at[:, ::-1], axis=1)[:, ::-1]
                following = np.concatenate([following[:, 1:], np.full((found.shape[0], 1), far)], axis=1)
                # copydetect's get_copied_slices: the union of the shared k-grams [p, p + k)
                covered = np.where(found, np.minimum(k, following - positions), 0).sum(axis=1)
                shares[row, start:start + step] = covered.astype(np.float64) / float(coverage)
        for one in range(count):
            for two in range(one + 1, count):
                first, second = names[one], names[two]
                key = (first, second) if first <= second else (second, first)
                self.values.setdefault(key, (float(shares[one, two]) + float(shares[two, one])) / 2.0)

    def similarity(self, first: str, second: str, threshold: float) -> float:
        """Mean over the two texts of the fraction of each one's own code found in the other.

        The vectorized :meth:`_Document.share` gives the value of every pair (copydetect's own,
        to rounding: tested); a pair within :data:`_MARGIN` of ``threshold`` is measured again by
        :func:`copydetect.compare_files`, whose value then decides and is the one reported."""
        from copydetect import compare_files

        key = (first, second) if first <= second else (second, first)
        if key not in self.checked:
            one, two = self.documents[key[0]], self.documents[key[1]]
            value = self.values[key] if key in self.values else (one.share(two) + two.share(one)) / 2.0
            if abs(value - threshold) <= _MARGIN and value > 0.0:
                _, (share_one, share_two), _ = compare_files(one.fingerprint, two.fingerprint)
                value = (float(share_one) + float(share_two)) / 2.0
            self.values[key] = value
            self.checked.add(key)
        return self.values[key]


def _columns(vocabulary: Any, hashes: Any) -> Any:
    """The column of each hash in the sorted ``vocabulary``; ``vocabulary.size`` (the extra
    column) for a hash that is not in it."""
    import numpy as np

    if vocabulary.size == 0:
        return np.zeros(hashes.shape, dtype=np.int64)
    place = np.minimum(np.searchsorted(vocabulary, hashes), vocabulary.size - 1)
    return np.where(vocabulary[place] == hashes, place, vocabulary.size)


#: elements of one block of :meth:`_Comparer.measure_all` (other texts x positions of a text)
_BATCH = 2_000_000
#: a pair whose vectorized similarity is this close to the threshold is measured again by
#: copydetect itself (the two agree to about 1e-15; rounding must not decide a pair)
_MARGIN = 1e-6


def _blank(answer: str, stub: str) -> bool:
    return "".join(answer.split()) == "".join(stub.split())


def _check_threshold(threshold: Any, min_size: Any) -> None:
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)) or not 0.0 <= threshold <= 1.0:
        raise ValueError(f"threshold must be a number in [0, 1] (a fraction of matching code), got {threshold!r}")
    if isinstance(min_size, bool) or not isinstance(min_size, int) or min_size < 0:
        raise ValueError(f"min_size must be an integer >= 0 (normalised characters), got {min_size!r}")


def similar_pairs(answers: Mapping[str, Mapping[str, str | Answer]], exercises: Mapping[str, Exercise], *,
                  threshold: float = THRESHOLD, min_size: int = MIN_SIZE, assignment: str = "") -> list[SimilarPair]:
    """The pairs of answers to one assignment's exercises whose similarity is at least ``threshold``.

    Parameters
    ----------
    answers : mapping
        ``{student: {grade_id: answer source or Answer}}`` (e.g. :func:`student_code` or
        :func:`answer_sources` of each student's notebook). Grade ids not in ``exercises`` are
        ignored.
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
        Unanswered cells are never compared. A pair's ``added`` says which of its texts
        include added code.
    """
    if not isinstance(answers, Mapping) or not all(isinstance(a, Mapping) for a in answers.values()):
        raise TypeError("answers must be a mapping {student: {grade_id: source}}")
    if not isinstance(exercises, Mapping) or not all(isinstance(e, Exercise) for e in exercises.values()):
        raise TypeError("exercises must be a mapping {grade_id: Exercise} (see exercises_from)")
    _check_threshold(threshold, min_size)
    pairs = []
    for grade_id in sorted(exercises):
        exercise = exercises[grade_id]
        comparer = _Comparer(exercise.stub, wrappers=not exercise.added_cells)
        texts: dict[str, tuple[str, str]] = {}  # name -> (text, normalised), large enough to compare
        pulled: dict[str, tuple[str, ...]] = {}
        for student in sorted(answers, key=str):
            given = answers[student].get(grade_id)
            answer = given if isinstance(given, Answer) else Answer(given) if isinstance(given, str) else None
            if answer is not None and isinstance(answer.text, str) and not _blank(answer.text, exercise.stub):
                cut = answer.text[:MAX_ANSWER_CHARS]
                texts[str(student)] = (cut, _normalised(cut))
                pulled[str(student)] = tuple(answer.pulled)
        students = [name for name in texts if comparer.size(texts[name][1]) >= max(min_size, 1)]
        targets = []
        for name, text in ((reference_label(exercise.reference_name or "implementation"), exercise.reference),
                           (SOLUTION, exercise.solution)):
            if text:
                texts[name] = (text, _normalised(text))
                if comparer.size(texts[name][1]) >= min_size:
                    targets.append(name)
        comparer.measure_all(texts[name][1] for name in students + targets)
        comparisons = list(combinations(students, 2)) + [(a, b) for a in students for b in targets]
        for a, b in comparisons:
            value = comparer.similarity(texts[a][1], texts[b][1], threshold)
            if value >= threshold:
                added = ALL_ADDED if exercise.added_cells else _added_note(a, pulled.get(a, ()), b, pulled.get(b, ()))
                pairs.append(SimilarPair(grade_id, a, b, round(value, 6), texts[a][0], texts[b][0], assignment, added,
                                         pulled.get(a, ()), pulled.get(b, ()), b in targets))
    return sorted(pairs, key=lambda p: (-p.similarity, p.exercise, p.a, p.b))


def _added_note(a: str, a_names: tuple[str, ...], b: str, b_names: tuple[str, ...]) -> str:
    """``"ann: _helper; bob: _kernel _inner"``: whose text pulls in which definitions (at most
    six names each, names cut at 40 characters)."""
    def names(found: tuple[str, ...]) -> str:
        shown = [name if len(name) <= 40 else name[:39] + "…" for name in found[:6]]
        return " ".join(shown) + (f" (+{len(found) - 6} more)" if len(found) > 6 else "")

    return "; ".join(f"{who}: {names(found)}" for who, found in ((a, a_names), (b, b_names)) if found)


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
        As :func:`similar_pairs`, sorted by decreasing similarity: each answer with the code it
        pulls in from the student's added cells (:func:`student_code`), and each notebook's
        added cells (:data:`ADDED`). With several notebooks in the assignment, exercises are
        named ``"<notebook stem>:<grade_id>"`` (and ``"<notebook stem>:(added cells)"``).

    Notes
    -----
    Of the submissions, only regular files in plain folders are read: symbolic links (and
    what they point at), hard links to other files, devices and pipes are skipped, as are
    notebooks that are not valid JSON, larger than :data:`MAX_NOTEBOOK_BYTES`, and student
    folders whose name starts with a dot or is refused by :func:`cvkit._text.name_problem`
    (not valid UTF-8, control or invisible characters: such submissions are not graded either).
    The files it writes show every name printable (:func:`cvkit._text.printable`). The course's own folders (``submitted``,
    ``release``, the sources) may be links. Nothing is written.
    """
    _check_threshold(threshold, min_size)
    answers, exercises = report_inputs(course_root, source_dir, assignment)
    return similar_pairs(answers, exercises, threshold=threshold, min_size=min_size, assignment=assignment)


def report_inputs(course_root: str | os.PathLike, source_dir: str | os.PathLike,
                  assignment: str) -> tuple[dict[str, dict[str, Answer]], dict[str, Exercise]]:
    """What :func:`report` compares: ``({student: {exercise: Answer}}, {exercise: Exercise})``
    read from the course folder as :func:`report` says (same arguments, same rules)."""
    for name, value in (("course_root", course_root), ("source_dir", source_dir)):
        if not isinstance(value, (str, os.PathLike)):
            raise TypeError(f"{name} must be a path, got {type(value).__name__}")
    if not isinstance(assignment, str) or not assignment or assignment in (".", "..") or re.search(r"[/\\\0]", assignment):
        raise ValueError(f"assignment must be a folder name such as 'ch03_filtering', got {assignment!r}")
    root, sources = Path(course_root), Path(source_dir) / assignment
    names = sorted(p.name for p in sources.glob("*.ipynb") if not p.name.startswith(".")) if sources.is_dir() else []
    submitted = root / "submitted"
    students = sorted(p.name for p in submitted.iterdir()
                      if not p.name.startswith(".") and name_problem(p.name) is None and _plain_folder(p)) \
        if submitted.is_dir() else []
    exercises: dict[str, Exercise] = {}
    answers: dict[str, dict[str, Answer]] = {student: {} for student in students}
    for name in names:
        source = _read_notebook(sources / name, links=True)
        if source is None:
            continue
        release = _read_notebook(root / "release" / assignment / name, links=True)
        prefix = f"{Path(name).stem}:" if len(names) > 1 else ""
        exercises.update({prefix + key: value for key, value in exercises_from(source, release).items()})
        exercises[prefix + ADDED] = added_cells_exercise(source, release)
        facts = _Release.of(source, release)
        for student in students:
            folder = submitted / student / assignment
            notebook = _read_notebook(folder / name) if _plain_folder(folder) else None
            if notebook is not None:
                answers[student].update({prefix + key: code for key, code in _student_code(notebook, facts).items()})
    return answers, exercises


# ------------------------------------------------------------------------------- clusters
@dataclass(frozen=True)
class Member:
    """One text of a :class:`SimilarGroup`.

    Attributes
    ----------
    name : str
        A student id, or the instructor's solution (:data:`SOLUTION`) or a reference
        (:func:`reference_label`) in :attr:`SimilarGroup.textbook`.
    source : str
        The text compared.
    closest : str
        The other member most similar to this one (ties: the first name in sorted order).
    similarity : float
        Their similarity: at least the report's threshold (it is what put this text in the group).
    to_centre : float or None
        The similarity to the group's central answer (:attr:`SimilarGroup.centre`), when that pair
        is at or above the threshold (1.0 for the centre itself); None when it is below.
    pulled : tuple of str
        The names of the definitions this text pulls in from the student's added cells.
    """

    name: str
    source: str
    closest: str
    similarity: float
    to_centre: float | None = None
    pulled: tuple[str, ...] = ()


@dataclass(frozen=True)
class SimilarGroup:
    """A cluster of near-identical answers to one exercise (:func:`groups`).

    Attributes
    ----------
    exercise : str
        As in :class:`SimilarPair`.
    members : tuple of Member
        The students of the group: the central answer first, then by name.
    textbook : tuple of Member
        The instructor's solution and the references that are in the group (empty: none). A group
        with a textbook member is "everyone who wrote the textbook answer" (or a variant of it):
        the usual correct answer, a weak signal of copying between its students.
    assignment : str
        The assignment, when known.
    added : bool
        Whether the texts are a notebook's :data:`ADDED` cells (:data:`ALL_ADDED` pairs).
    """

    exercise: str
    members: tuple[Member, ...]
    textbook: tuple[Member, ...] = ()
    assignment: str = ""
    added: bool = False

    @property
    def centre(self) -> Member:
        """The central answer: the student whose similarities to the others (those at or above
        the threshold) add up to the most."""
        return self.members[0]

    @property
    def high(self) -> float:
        """The highest similarity of two texts of the group."""
        return max(m.similarity for m in self.members + self.textbook)

    @property
    def low(self) -> float:
        """The lowest of the members' similarities to their closest member (each at least the
        threshold)."""
        return min(m.similarity for m in self.members + self.textbook)

    def shown(self) -> tuple[Member, ...]:
        """The texts the page shows side by side: in a group of at most :data:`SHOWN_ALL`
        students, every student's (the central answer first); in a larger one, the central
        answer and the student least alike to it (the spread of the group). In a textbook group,
        followed by the textbook text most alike to the group."""
        if len(self.members) <= SHOWN_ALL:
            students = self.members
        else:
            students = self.centre, min(self.members[1:], key=lambda m: (m.to_centre or 0.0, m.name))
        if self.textbook:
            return students + (max(self.textbook, key=lambda m: (m.to_centre or 0.0, m.similarity, m.name)),)
        return students


#: a group of at most this many students shows all their answers (a larger one, two of them)
SHOWN_ALL = 4


class _Links:
    """Union-find over the texts of one exercise, with the similarities of the pairs that linked them."""

    def __init__(self) -> None:
        self.parent: dict[str, str] = {}
        self.values: dict[str, dict[str, float]] = {}

    def root(self, name: str) -> str:
        self.parent.setdefault(name, name)
        while self.parent[name] != name:
            self.parent[name] = self.parent[self.parent[name]]
            name = self.parent[name]
        return name

    def link(self, a: str, b: str, value: float) -> None:
        self.values.setdefault(a, {})[b] = value
        self.values.setdefault(b, {})[a] = value
        first, second = self.root(a), self.root(b)
        if first != second:
            self.parent[max(first, second)] = min(first, second)

    def components(self) -> list[list[str]]:
        found: dict[str, list[str]] = {}
        for name in sorted(self.parent):
            found.setdefault(self.root(name), []).append(name)
        return list(found.values())


def groups(pairs: Iterable[SimilarPair]) -> list[SimilarGroup]:
    """The clusters of similar answers that ``pairs`` make: per assignment and exercise, the texts
    connected by pairs at or above the threshold (single linkage: the connected components of the
    graph of reported pairs, found by union-find).

    Every reported pair is inside one group, so no pair is hidden: two students whose answers are
    alike are always in the same group. A chain (A like B, B like C, A not like C) is one group;
    each member's closest member and its similarity to the group's central answer show how it
    is linked. A group that holds the instructor's solution or a reference is labelled
    (:attr:`SimilarGroup.textbook`); a student who pasted the reference alone is a group of
    one student and the reference.

    Parameters
    ----------
    pairs : iterable of SimilarPair
        E.g. :func:`similar_pairs` or :func:`report` (of one or several assignments).

    Returns
    -------
    list of SimilarGroup
        Groups of students' answers first, then the textbook groups; each by decreasing highest
        similarity, then by size (largest first), assignment, exercise and central answer.
        Nothing here changes a score.
    """
    by_exercise: dict[tuple[str, str], list[SimilarPair]] = {}
    for pair in _pairs(pairs):
        by_exercise.setdefault((pair.assignment, pair.exercise), []).append(pair)
    found = []
    for (assignment, exercise), listed in by_exercise.items():
        links = _Links()
        sources: dict[str, str] = {}
        pulled: dict[str, tuple[str, ...]] = {}
        textbook: set[str] = set()
        added = False
        for pair in listed:
            links.link(pair.a, pair.b, pair.similarity)
            sources.setdefault(pair.a, pair.a_source)
            sources.setdefault(pair.b, pair.b_source)
            pulled.setdefault(pair.a, tuple(pair.a_pulled))
            pulled.setdefault(pair.b, tuple(pair.b_pulled))
            added = added or pair.added == ALL_ADDED
            if pair.is_textbook():
                textbook.add(pair.b)
        for names in links.components():
            students = [name for name in names if name not in textbook]
            if not students:  # the solution like the reference, with no student: nothing to see
                continue
            weight = {name: sum(v for other, v in links.values[name].items() if other not in textbook)
                      for name in students}
            centre = min(students, key=lambda name: (-weight[name], name))

            def member(name: str) -> Member:
                near = links.values[name]
                closest = min(near, key=lambda other: (-near[other], other))
                to_centre = 1.0 if name == centre else near.get(centre)
                return Member(name, sources[name], closest, near[closest], to_centre, pulled.get(name, ()))

            found.append(SimilarGroup(
                exercise, tuple(member(name) for name in [centre] + sorted(n for n in students if n != centre)),
                tuple(member(name) for name in sorted(n for n in names if n in textbook)), assignment, added))
    return sorted(found, key=lambda g: (bool(g.textbook), -g.high, -len(g.members), g.assignment, g.exercise,
                                        g.centre.name))


# ------------------------------------------------------------------------------- exports
def _pairs(pairs: Iterable[SimilarPair]) -> list[SimilarPair]:
    items = list(pairs)
    if not all(isinstance(pair, SimilarPair) for pair in items):
        raise TypeError("pairs must be an iterable of SimilarPair (see similar_pairs, report), "
                        "or of SimilarGroup (see groups)")
    return sorted(items, key=lambda p: (-p.similarity, p.assignment, p.exercise, p.a, p.b))


def _groups(items: Iterable[SimilarPair | SimilarGroup]) -> list[SimilarGroup]:
    """``items`` as groups: groups as they are, pairs grouped (:func:`groups`)."""
    items = list(items)
    if items and all(isinstance(item, SimilarGroup) for item in items):
        return items  # type: ignore[return-value]
    return groups(items)  # type: ignore[arg-type]


def exercise_label(pair: SimilarPair) -> str:
    """A pair's exercise, followed, when an answer pulls in added code, by whose and what
    (``"mean_kernel_answer + added code (ann: _helper)"``); a pair of :data:`ADDED` texts is named
    by its pseudo-exercise."""
    if pair.added and pair.added != ALL_ADDED:
        return f"{pair.exercise} + added code ({pair.added})"
    return pair.exercise


def _pulled_note(group: SimilarGroup, member: Member) -> str:
    """The CSV's ``added_code`` of a member: :data:`ALL_ADDED`, the names its text pulls in from
    added cells (at most six, each cut at 40 characters), or ``""``."""
    if group.added:
        return ALL_ADDED
    names = [name if len(name) <= 40 else name[:39] + "…" for name in member.pulled[:6]]
    return " ".join(names) + (f" (+{len(member.pulled) - 6} more)" if len(member.pulled) > 6 else "")


#: the columns of ``exports/similarity.csv`` (:func:`write_csv`)
CSV_COLUMNS = ("assignment", "exercise", "cluster", "students", "student", "closest", "similarity", "textbook",
               "added_code")


def write_csv(items: Iterable[SimilarPair | SimilarGroup], path: str | os.PathLike) -> Path:
    """Write the groups of similar answers as CSV (``exports/similarity.csv``), **one row per
    student of a group**, and return the path.

    Columns (:data:`CSV_COLUMNS`):

    ``assignment``, ``exercise``
        The exercise (``"<notebook>:<grade_id>"`` with several notebooks, :data:`ADDED` for the
        added cells).
    ``cluster``
        The group's number, 1, 2, … in the page's order (its anchor ``#cluster-<n>`` in
        ``similarity.html``); the rows of a group are together, its central answer first.
    ``students``
        How many students the group has (the instructor's solution and references not counted).
    ``student``
        One student of the group.
    ``closest``, ``similarity``
        The text of the group most like this student's (a student, :data:`SOLUTION` or a
        reference) and their similarity, three decimals, at least the threshold.
    ``textbook``
        The instructor's solution and references in the group, ``"; "``-separated: the group is
        everyone who wrote the textbook answer; empty for a group of students alone.
    ``added_code``
        The definitions this student's text pulls in from their added cells, or
        :data:`ALL_ADDED` for the :data:`ADDED` pseudo-exercise, or empty.

    ``items`` are groups (:func:`groups`), or pairs, which are grouped first. Cells that a
    spreadsheet would read as a formula are escaped by :func:`cvkit.course.safety.csv_safe`.
    Missing parent folders are created.
    """
    from .safety import csv_safe

    rows = []
    for number, group in enumerate(_groups(items), 1):
        textbook = "; ".join(m.name for m in group.textbook)
        rows += [(group.assignment, group.exercise, str(number), str(len(group.members)), m.name, m.closest,
                  f"{m.similarity:.3f}", textbook, _pulled_note(group, m)) for m in group.members]
    path = Path(path)
    with whole_file(path, newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(CSV_COLUMNS)
        writer.writerows([csv_safe(printable(cell)) for cell in row] for row in rows)
    return path


_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="default-src 'none'; style-src 'unsafe-inline'">
<title>Similar answers</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; }}
table.index td, table.index th, table.members td, table.members th {{ padding: 0.2em 0.8em; text-align: left; }}
section {{ border-top: 1px solid #999; margin-top: 1.5em; }}
.sides {{ display: grid; grid-template-columns: 1fr 1fr; gap: 1em; }}
.note {{ background: #eef5ee; padding: 0.4em; }}
pre {{ background: #f4f4f4; padding: 0.6em; overflow-x: auto; white-space: pre; font-size: 0.85em; }}
</style></head><body>
<h1>Similar answers</h1>
<p>{count} group(s) of similar answers ({students} student answer(s) in all). A group is the
answers to one exercise that are linked by a similarity at or above the threshold (each is that
close to at least one other of its group); the two most alike are always in the same group.
Each group lists every student with the answer closest to theirs, and shows its answers side by
side: all of them in a group of up to {shown_all} students, else its central answer (the most
alike to the others) and its answer least like the central one; then the textbook answer the
group is close to, if any. Groups that hold the instructor's solution or a reference
implementation come last, marked <em>textbook answer</em>: everyone who wrote the usual correct
answer, a weak signal. Similarity: the mean over the two answers of the share of each one's own
code (the released stub left out) that the other contains, after names, strings and numbers are
abstracted (copydetect's winnowing). An answer is its answer cell and the definitions it pulls
in from the cells the student added or changed (the list names them); &ldquo;{added}&rdquo;
compares all of two students' added cells. A signal to look at, never a score.</p>
{index}
{sections}
</body></html>
"""


def _names(group: SimilarGroup, e: Any, most: int = 6) -> str:
    names = [e(m.name) for m in group.members[:most]]
    more = f" (+{len(group.members) - most} more)" if len(group.members) > most else ""
    return ", ".join(names) + more


def write_html(items: Iterable[SimilarPair | SimilarGroup], path: str | os.PathLike) -> Path:
    """Write one self-contained HTML page of the groups of similar answers (:func:`groups`; pairs
    are grouped first) and return the path: an index of the groups, then per group its students
    (each with its closest text and its similarity to the central answer) and two texts side by
    side (:meth:`SimilarGroup.shown`). Its size grows with the number of students in groups,
    not with the number of similar pairs. Every text is HTML-escaped; the page has no script and
    a Content-Security-Policy that allows none. Missing parent folders are created."""
    ordered = _groups(items)

    def e(text: object) -> str:
        return html.escape(printable(text, newlines=True))

    def percent(value: float | None) -> str:
        return f"{value:.0%}" if value is not None else "below the threshold"

    rows, sections = [], []
    for number, group in enumerate(ordered, 1):
        where = e(f"{group.assignment} / {group.exercise}" if group.assignment else group.exercise)
        spread = f"{group.low:.0%}" if group.low == group.high else f"{group.low:.0%}&ndash;{group.high:.0%}"
        textbook = ", ".join(e(m.name) for m in group.textbook)
        kind = f"textbook answer: {textbook}" if textbook else ""
        rows.append(f'<tr><td><a href="#cluster-{number}">{number}</a></td><td>{where}</td>'
                    f"<td>{len(group.members)}</td><td>{spread}</td><td>{_names(group, e)}</td><td>{kind}</td></tr>")
        note = (f'<p class="note">Textbook answer: this group is close to {textbook}. Its students wrote '
                f"the usual correct answer (or a variant of it); that they are alike is a weak signal.</p>"
                if textbook else "")
        members = "".join(
            f"<tr><td>{e(m.name)}{' (central)' if index == 0 else ' (textbook)' if index >= len(group.members) else ''}"
            f"</td><td>{e(m.closest)}</td><td>{m.similarity:.0%}</td><td>{percent(m.to_centre) if index else ''}</td>"
            f"<td>{e(_pulled_note(group, m)) if index < len(group.members) else ''}</td></tr>"
            for index, m in enumerate(group.members + group.textbook))
        shown = "".join(f"<div><h3>{e(m.name)}</h3><pre>{e(m.source)}</pre></div>" for m in group.shown())
        sections.append(
            f'<section id="cluster-{number}"><h2>{number}. {where} &mdash; {len(group.members)} '
            f"student{'s' * (len(group.members) != 1)}, {spread}</h2>{note}"
            f'<table class="members"><tr><th>student</th><th>closest</th><th>similarity</th>'
            f"<th>to the central answer</th><th>added code</th></tr>{members}</table>"
            f'<div class="sides">{shown}</div></section>')
    index = ('<table class="index"><tr><th>group</th><th>exercise</th><th>students</th><th>similarity</th>'
             "<th>who</th><th></th></tr>" + "".join(rows) + "</table>") if rows \
        else "<p>No answers alike above the threshold.</p>"
    path = Path(path)
    write_whole(path, _PAGE.format(count=len(ordered), students=sum(len(g.members) for g in ordered),
                                   index=index, sections="\n".join(sections), added=e(ADDED), shown_all=SHOWN_ALL))
    return path
