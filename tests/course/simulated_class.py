"""A simulated class's answers to Chapter 3, as :mod:`cvkit.course.similarity` takes them.

Real classes' correct answers come from a few common sources: the textbook (the instructor's
solution, cvkit's reference), a popular version found elsewhere, and each other. Here every
student of a class starts from one of three sources per exercise — the notebook's solution,
cvkit's reference, the independent version of ``tests/library/alternatives_ch03.py`` — and changes it a
little, as a student hiding a copy would: local variables renamed, independent neighbouring
statements swapped, comments added. A few students write their own answer (unique texts, each an
independent correct version of another exercise's algorithm or a hand-written one).

No grading is needed: :func:`answers` gives ``{student: {grade_id: text}}`` and
:func:`exercises` the exercises, the inputs of :func:`cvkit.course.similarity.similar_pairs`.
Used by ``tests/course/test_similarity_clusters.py`` and ``benchmarks/bench_similarity.py``.
"""
from __future__ import annotations

import ast
import inspect
import io
import json
import random
import sys
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "library"))  # also when imported from benchmarks/
import alternatives_ch03  # noqa: E402

CH03 = ROOT / "lectures" / "ch03_filtering" / "ch03_filtering.ipynb"
#: the kinds of source a student's answer is made from, in the order students are given them
SOURCES = ("solution", "reference", "alternative")
_WORDS = ("tmp", "val", "arr", "res", "buf", "acc", "out", "img", "data", "cur", "nxt", "part")
_COMMENTS = ("# compute it", "# the main step", "# see the lecture", "# TODO check the borders",
             "# this works", "# careful with dtype", "# from the notes", "# loop over everything")


def source_notebook() -> dict:
    return json.loads(CH03.read_text(encoding="utf-8"))


def exercises() -> dict:
    """Chapter 3's exercises (:func:`cvkit.course.similarity.exercises_from`)."""
    from cvkit.course import similarity

    return similarity.exercises_from(source_notebook())


#: exercises left out of the simulated class: the measured denoiser's answer is one call of the
#: student's own nl_means with chosen parameters, nothing to compare (the class stays the 13
#: exercises that benchmarks/bench_similarity.py's table was measured on)
LEFT_OUT = frozenset({"denoise_answer"})


def sources(chosen: dict | None = None) -> dict[str, dict[str, str]]:
    """``{grade_id: {source kind: text}}`` for every exercise that has all three sources."""
    from cvkit.course import similarity

    chosen = exercises() if chosen is None else chosen
    solutions = similarity.answer_sources(source_notebook())
    found = {}
    for grade_id, exercise in sorted(chosen.items()):
        alternative = getattr(alternatives_ch03, grade_id[: -len("_answer")], None)
        if exercise.reference and alternative is not None and grade_id in solutions and grade_id not in LEFT_OUT:
            found[grade_id] = {"solution": solutions[grade_id], "reference": exercise.reference,
                               "alternative": inspect.getsource(alternative)}
    return found


# ------------------------------------------------------------------------------- variations
def _replace_tokens(text: str, replace) -> str:
    """``text`` with each NAME token for which ``replace(token, previous)`` gives a string replaced."""
    lines = text.splitlines(keepends=True)
    edits = []
    previous = None
    for token in tokenize.generate_tokens(io.StringIO(text).readline):
        if token.type == tokenize.NAME:
            new = replace(token.string, previous)
            if new is not None:
                edits.append((token.start, token.end, new))
        if token.type not in (tokenize.NL, tokenize.COMMENT):
            previous = token
    for (row, start), (_, end), new in reversed(edits):
        line = lines[row - 1]
        lines[row - 1] = line[:start] + new + line[end:]
    return "".join(lines)


def rename(text: str, rng: random.Random) -> str:
    """Every local variable a function assigns (not its parameters) renamed."""
    tree = ast.parse(text)
    assigned = set()
    for function in (n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))):
        for node in ast.walk(function):
            if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                assigned.add(node.id)
    names = sorted(assigned)
    new = {name: f"{rng.choice(_WORDS)}_{index}{rng.randrange(100)}" for index, name in enumerate(names)}

    def replace(name, previous):
        attribute = previous is not None and previous.type == tokenize.OP and previous.string == "."
        return new.get(name) if not attribute else None

    return _replace_tokens(text, replace)


def _names(node: ast.AST, kind: type) -> set[str]:
    return {n.id for n in ast.walk(node) if isinstance(n, ast.Name) and isinstance(n.ctx, kind)}


def reorder(text: str, rng: random.Random, swaps: int = 2) -> str:
    """Up to ``swaps`` pairs of neighbouring one-line statements of a function's body swapped,
    when neither uses what the other assigns (the program means the same)."""
    for _ in range(swaps):
        tree = ast.parse(text)
        candidates = []
        for function in (n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))):
            for first, second in zip(function.body, function.body[1:]):
                simple = all(isinstance(s, (ast.Assign, ast.AugAssign, ast.AnnAssign)) and s.lineno == s.end_lineno
                             for s in (first, second))
                if simple and not (_names(first, ast.Store) & (_names(second, ast.Load) | _names(second, ast.Store))) \
                        and not (_names(second, ast.Store) & _names(first, ast.Load)):
                    candidates.append((first.lineno, second.lineno))
        if not candidates:
            break
        one, two = rng.choice(candidates)
        lines = text.split("\n")
        lines[one - 1], lines[two - 1] = lines[two - 1], lines[one - 1]
        text = "\n".join(lines)
    return text


def comment(text: str, rng: random.Random, count: int = 2) -> str:
    """``count`` comment lines added before statements, indented like them."""
    starts = set()
    at_start = True
    for token in tokenize.generate_tokens(io.StringIO(text).readline):
        if token.type in (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT):
            at_start = True
        elif token.type not in (tokenize.NL, tokenize.COMMENT) and at_start:
            starts.add(token.start)
            at_start = False
    lines = text.split("\n")
    for row, column in sorted(rng.sample(sorted(starts), min(count, len(starts))), reverse=True):
        lines.insert(row - 1, " " * column + rng.choice(_COMMENTS))
    return "\n".join(lines)


_FILLERS = ("_unused = None", "_unused = []", "_unused = {}", "_unused = ()", "pass", "_unused = 0 + 0")


def pad(text: str, rng: random.Random, count: int = 2) -> str:
    """``count`` statements of no use added before statements of the function (``_unused = None``
    and the like): nearly every student's text then differs after normalisation too (the
    costliest case to compare)."""
    tree = ast.parse(text)
    functions = [f for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))]
    starts = sorted({(s.lineno, s.col_offset) for f in functions for s in f.body[1:]})
    lines = text.split("\n")
    for row, column in sorted(rng.sample(starts, min(count, len(starts))), reverse=True):
        lines.insert(row - 1, " " * column + rng.choice(_FILLERS))
    return "\n".join(lines)


def vary(text: str, rng: random.Random, *, distinct: bool = False) -> str:
    """A student's copy of ``text``: names changed, statements swapped, comments added (and, if
    ``distinct``, useless statements added: :func:`pad`)."""
    text = comment(reorder(rename(text, rng), rng), rng, count=rng.randrange(1, 4))
    return pad(text, rng, count=rng.randrange(1, 4)) if distinct else text


# ------------------------------------------------------------------------------- the class
def unique_answers(grade_id: str) -> list[str]:
    """Answers to ``grade_id`` that share no source with anyone's: the independent versions of the
    *other* exercises' algorithms (a student who answered with something of their own)."""
    return [inspect.getsource(function) for name, function in inspect.getmembers(alternatives_ch03, inspect.isfunction)
            if function.__module__ == alternatives_ch03.__name__ and name != grade_id[: -len("_answer")]]


def answers(students: int, *, unique: int = 3, seed: int = 0, chosen: dict[str, dict[str, str]] | None = None,
            distinct: bool = False) -> dict[str, dict[str, str]]:
    """``{student: {grade_id: text}}``: ``students - unique`` students each answer every exercise
    with a variation of one of the three sources (``s000`` … in turn: solution, reference,
    alternative; :func:`vary`), and ``unique`` students (``u00`` …) answer each exercise on their own."""
    rng = random.Random(seed)
    chosen = sources() if chosen is None else chosen
    result: dict[str, dict[str, str]] = {}
    for number in range(students - unique):
        kind = SOURCES[number % len(SOURCES)]
        result[f"s{number:03d}"] = {grade_id: vary(texts[kind], rng, distinct=distinct)
                                    for grade_id, texts in chosen.items()}
    for number in range(unique):
        result[f"u{number:02d}"] = {grade_id: unique_answers(grade_id)[number]
                                    for grade_id in chosen}
    return result


def source_of(student: str) -> str | None:
    """The source kind a simulated student copied (None: a unique answer)."""
    return SOURCES[int(student[1:]) % len(SOURCES)] if student.startswith("s") else None
