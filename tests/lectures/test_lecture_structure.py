"""What a lecturer checks before adopting a chapter notebook as it is (issue #19):

- every numbered section of the notes has its heading, in the notes' order and at its level, in
  its chapter's notebook (intentional merges are listed, with a reason, in
  ``lectures/section_merges.toml``), no invented section numbers, one H1;
- learning objectives at the start, a self-assessment at the end;
- at least three written questions (manually graded answer cells with a model answer and a
  rubric) and one open task (an nbgrader task cell with a mark scheme) per chapter;
- every markdown table renders with the header's number of cells in every row (GFM, as
  JupyterLab renders it: a ``|`` splits cells even inside a code span or ``$...$`` unless escaped);
- nothing in the student's release refers to files or machines the student does not have.
"""
from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

import lecture_release as L

ROOT = L.ROOT
SECTIONS_FILE = ROOT / "lectures" / "notes_sections.txt"
MERGES_FILE = ROOT / "lectures" / "section_merges.toml"
NOTES = ROOT.parent / "shared" / "seed" / "000_981e4c5a00ad51f4.txt"
SECTION_LINE = re.compile(r"^(\d+(?:\.\d+)+) (\S.*)$")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
NUMBERED = re.compile(r"^(\d+(?:\.\d+)+)(?![\d])")
IDS = [p.parent.name for p in L.NOTEBOOKS]


def _sections() -> list[tuple[str, str]]:
    rows = []
    for line in SECTIONS_FILE.read_text().splitlines():
        match = SECTION_LINE.match(line)
        if match:
            rows.append((match.group(1), match.group(2)))
    return rows


def _chapter_of(folder: str) -> int:
    return int(folder[2:4])


def _merges() -> dict:
    return tomllib.loads(MERGES_FILE.read_text())


def _headings(nb) -> list[tuple[int, str]]:
    out, fence = [], False
    for cell in nb["cells"]:
        if cell["cell_type"] != "markdown":
            continue
        for line in L.source(cell).splitlines():
            if line.lstrip().startswith(("```", "~~~")):
                fence = not fence
            if fence:
                continue
            match = HEADING.match(line)
            if match:
                out.append((len(match.group(1)), match.group(2)))
    return out


def _level(number: str, known: set[str]) -> int:
    parts = number.split(".")
    parent = ".".join(parts[:-1])
    return 2 if len(parts) == 2 or parent not in known else _level(parent, known) + 1


def test_section_list_matches_the_notes():
    sections = _sections()
    assert len(sections) > 200
    if not NOTES.is_file():
        pytest.skip("the course notes are not next to the project")
    from_notes = [SECTION_LINE.match(l).groups() for l in NOTES.read_text().splitlines() if SECTION_LINE.match(l)]
    assert sections == [tuple(r) for r in from_notes]


def test_merges_file_is_well_formed():
    merges = _merges()
    known = {number for number, _ in _sections()}
    assert set(merges) == set(IDS), "one table per chapter notebook folder"
    for folder, table in merges.items():
        for number, reason in table.items():
            assert number in known, f"{folder}: {number} is not a section of the notes"
            assert int(number.split(".")[0]) == _chapter_of(folder), f"{folder}: {number} belongs to another chapter"
            assert isinstance(reason, str) and len(reason) > 15, f"{folder}: {number} needs the covering heading and a reason"


@pytest.mark.parametrize("path", L.NOTEBOOKS, ids=IDS)
def test_every_section_of_the_notes_has_its_heading(path):
    folder = path.parent.name
    chapter = _chapter_of(folder)
    sections = [(n, t) for n, t in _sections() if int(n.split(".")[0]) == chapter]
    known = {n for n, _ in _sections()}
    merged = set(_merges().get(folder, {}))
    headings = _headings(L.load(path))
    numbered = [(level, NUMBERED.match(text).group(1), text) for level, text in headings if NUMBERED.match(text)]
    found = {number: (level, text) for level, number, text in numbered}
    missing = [f"{n} {t}" for n, t in sections if n not in found and n not in merged]
    assert not missing, f"{folder}: no heading for section(s) {missing} (or list them in section_merges.toml)"
    invented = [text for _, number, text in numbered if number not in known]
    assert not invented, f"{folder}: headings with section numbers the notes do not have: {invented}"
    wrong_level = [f"{text!r} is level {level}, expected {_level(number, known)}" for level, number, text in numbered
                   if level != _level(number, known)]
    assert not wrong_level, f"{folder}: {wrong_level}"
    order = [n for n, _ in sections]
    positions = [order.index(number) for _, number, _ in numbered if number in order]
    assert positions == sorted(positions), f"{folder}: section headings are not in the notes' order"
    both = merged & set(found)
    assert not both, f"{folder}: {sorted(both)} listed as merged but have their own heading"


@pytest.mark.parametrize("path", L.NOTEBOOKS, ids=IDS)
def test_one_title_and_learning_objectives_and_self_assessment(path):
    nb = L.load(path)
    headings = _headings(nb)
    titles = [text for level, text in headings if level == 1]
    assert len(titles) == 1 and titles[0].startswith(f"Chapter {_chapter_of(path.parent.name)} "), titles
    markdown = [L.source(c) for c in nb["cells"] if c["cell_type"] == "markdown"]
    opening = [text for text in markdown[:4] if "**Learning objectives.**" in text]
    assert opening, "learning objectives near the top"
    block = opening[0].split("**Learning objectives.**", 1)[1]
    block = re.split(r"\n\s*\n(?![ \t]*[-*] )", block.strip("\n"), maxsplit=1)[0]  # the list right after it
    bullets = [line for line in block.splitlines() if re.match(r"^\s*[-*] \S", line)]
    assert 3 <= len(bullets) <= 5, f"3-5 learning objectives, found {len(bullets)}"
    tail = [i for i, (level, text) in enumerate(headings) if level == 2 and text.startswith("Self-assessment")]
    assert tail and tail[-1] == len(headings) - 1 or (tail and all(level > 2 for level, _ in headings[tail[-1] + 1:])), (
        "the chapter ends with '## Self-assessment'")
    last = "\n".join(markdown[-3:])
    assert last.count("<details>") >= 4, "4-6 self-assessment questions with their answers in <details> blocks"


def _questions(nb) -> list[dict]:
    return [c for c in nb["cells"] if c["cell_type"] == "markdown" and L.nbgrader(c).get("solution")
            and L.nbgrader(c).get("grade")]


def _tasks(nb) -> list[dict]:
    return [c for c in nb["cells"] if L.nbgrader(c).get("task")]


@pytest.mark.parametrize("path", L.NOTEBOOKS, ids=IDS)
def test_written_questions_and_an_open_task(path):
    nb = L.load(path)
    cells = nb["cells"]
    questions = _questions(nb)
    assert len(questions) >= 3, f"{path.name}: at least three written questions, found {len(questions)}"
    for cell in questions:
        meta = L.nbgrader(cell)
        assert meta["grade_id"].startswith("question_") and meta.get("points", 0) > 0 and not meta.get("locked")
        text = L.source(cell)
        assert "**Model answer.**" in text and "**Rubric" in text, f"{meta['grade_id']}: model answer and rubric"
        assert "BEGIN SOLUTION" not in text and not re.search(r"^#", text, re.M), meta["grade_id"]
        before = L.source(cells[cells.index(cell) - 1])
        assert "**Question" in before, f"{meta['grade_id']}: the question is stated in the cell before"
    tasks = _tasks(nb)
    assert len(tasks) >= 1, f"{path.name}: one open task"
    for cell in tasks:
        meta = L.nbgrader(cell)
        text = L.source(cell)
        assert cell["cell_type"] == "markdown" and meta.get("points", 0) > 0 and meta.get("locked")
        assert meta["grade_id"].startswith("task_"), meta["grade_id"]
        assert "**Open task" in text and "BEGIN MARK SCHEME" in text and "END MARK SCHEME" in text, meta["grade_id"]
    released = L.release(path)
    for cell in released.cells:
        assert "MARK SCHEME" not in cell.source and "**Model answer.**" not in cell.source, "the release keeps no rubric"


def _split_row(line: str) -> list[str]:
    """GFM: a row's cells are separated by unescaped pipes, whatever inline spans they are in."""
    body = line.strip()
    if body.startswith("|"):
        body = body[1:]
    if body.endswith("|") and not body.endswith("\\|"):
        body = body[:-1]
    return re.split(r"(?<!\\)\|", body)


def table_problems(text: str) -> list[str]:
    """Rows of the GFM tables in ``text`` (found with markdown-it, as JupyterLab's renderer would)
    whose cell count differs from the header's, or that contain a raw ``|`` inside a code span or
    ``$...$`` (GFM splits the cell there)."""
    from markdown_it import MarkdownIt

    problems = []
    lines = text.splitlines()
    tokens = MarkdownIt("commonmark").enable("table").parse(text)
    for token in tokens:
        if token.type != "table_open" or not token.map:
            continue
        start, end = token.map
        rows = [lines[i] for i in range(start, end) if lines[i].strip()]
        width = len(_split_row(rows[0]))
        for row in rows[:1] + rows[2:]:
            cells = _split_row(row)
            if len(cells) != width:
                problems.append(f"{len(cells)} cells instead of {width}: {row.strip()[:90]}")
            for span in re.findall(r"`[^`]*`|\$[^$]*\$", row):
                if re.search(r"(?<!\\)\|", span):
                    problems.append(f"raw | inside {span[:40]!r}: escape it as \\|: {row.strip()[:90]}")
    # a table whose delimiter row does not match its header is not a table at all: look for
    # pipe-rows followed by a delimiter row that markdown-it did not turn into a table
    found = {line for token in tokens if token.type == "table_open" and token.map for line in range(*token.map)}
    for i, line in enumerate(lines[1:], 1):
        if re.match(r"^\s*\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)+\|?\s*$", line) and i not in found:
            problems.append(f"not rendered as a table (header and delimiter rows differ): {lines[i - 1].strip()[:90]}")
    return problems


def test_table_checker_catches_the_known_defects():
    good = "| a | b |\n|---|---|\n| `x \\| y` | 2 |\n"
    assert table_problems(good) == []
    assert table_problems("| a | b |\n|---|---|\n| `x | y` | 2 |\n")
    assert table_problems("| a | b |\n|---|---|\n| $|x|$ | 2 |\n")
    assert table_problems("| a | b |\n|---|---|\n| 1 | 2 | 3 |\n")
    assert table_problems("| a | b | c |\n|---|---|\n| 1 | 2 |\n")


@pytest.mark.parametrize("path", L.NOTEBOOKS, ids=IDS)
def test_markdown_tables_render(path):
    problems = []
    for index, cell in enumerate(L.load(path)["cells"]):
        if cell["cell_type"] == "markdown":
            problems += [f"cell {index}: {p}" for p in table_problems(L.source(cell))]
    assert not problems, "\n".join(problems)


FORBIDDEN = [
    (re.compile(r"\btests?/"), "the project's tests/ folder"),
    (re.compile(r"\bbenchmarks?/|\bbench_\w+\.py"), "the project's benchmarks"),
    (re.compile(r"\bscripts/"), "the project's scripts"),
    (re.compile(r"CATALOG(\.md)?|\bcatalog\b", re.I), "the algorithm catalog (not part of a student's release)"),
    (re.compile(r"\b\d+-core\b|course machine|our machine|grading machine", re.I), "a machine"),
    (re.compile(r"/work/|/root/|/home/\w+"), "a path on our machine"),
]


@pytest.mark.parametrize("path", L.NOTEBOOKS, ids=IDS)
def test_release_refers_to_nothing_a_student_does_not_have(path):
    found = []
    for index, cell in enumerate(L.release(path).cells):
        for pattern, what in FORBIDDEN:
            for match in pattern.finditer(cell.source):
                found.append(f"cell {index}: {match.group(0)!r} ({what})")
    assert not found, "\n".join(found)


# ---------------------------------------------------------------- the § a report cites (issue #35)
CHECK_CALL = re.compile(r'check\(\s*"([a-z_]+\.[A-Za-z_0-9]+)"')


def _numbers(text: str) -> tuple[int, ...]:
    return tuple(int(part) for part in text.strip().split("."))


def cites(section: str, heading: str) -> bool:
    """Whether a registered section (``"4.5"``, ``"3.6–3.7"``, ``"7.6, 7.5.1"``) covers the
    numbered heading an exercise sits under (itself, a range holding it, or a parent of it)."""
    number = _numbers(heading)
    for part in section.split(","):
        low, _, high = part.strip().partition("–")
        low_n, high_n = _numbers(low), _numbers(high or low)
        if not high and number[:len(low_n)] == low_n:  # the section or one of its subsections
            return True
        if high and low_n <= number and number[:len(high_n)] <= high_n:
            return True
    return False


def test_cites_reads_ranges_lists_and_subsections():
    assert cites("4.5", "4.5") and cites("5.12", "5.12.1") and cites("3.6–3.7", "3.7")
    assert cites("11.2–11.5", "11.5.7") and cites("7.6, 7.5.1", "7.5.1") and cites("9.6.1–9.6.5", "9.6.1")
    assert not cites("4.5", "4.4") and not cites("5.8", "5.9") and not cites("10.7.4", "10.7.3")
    assert not cites("6.0.7", "6.0.6") and not cites("3.6", "3.7") and not cites("4.5", "4.50")


def test_every_report_cites_the_section_its_exercise_sits_under():
    """The report of ``check("edges.magnitude", ...)`` says "§…": the section of the notes the
    check is registered with (the catalog's), and where its exercise sits when that differs. The student reads it under a numbered heading of the notebook;
    they must agree (issue #35: six exercises cited another section)."""
    from cvkit import registry

    wrong, seen = [], 0
    for path in L.NOTEBOOKS:
        heading = None
        for cell in L.load(path)["cells"]:
            if cell["cell_type"] == "markdown":
                for level, title in _headings({"cells": [cell]}):
                    found = NUMBERED.match(title)
                    if found:
                        heading = found.group(1)
                continue
            if not L.nbgrader(cell).get("grade_id", "").endswith("_visible"):
                continue
            for algorithm_id in CHECK_CALL.findall(L.source(cell)):
                seen += 1
                section = registry.get(algorithm_id).cited  # the catalog's section, and the exercise's own
                if heading is None or not cites(section, heading):
                    wrong.append(f"{path.parent.name}: {algorithm_id} cites §{section} under the heading {heading}")
    assert seen > 130
    assert not wrong, "\n".join(wrong)
