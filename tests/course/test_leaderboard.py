"""The opt-in leaderboards of the measured exercises (cvkit/course/leaderboard.py, plan.toml
[leaderboard]): the measured value travels in the report's data (CaseResult.measure); a course
folder laid out as grading leaves it (hand-ins in submitted/, trusted reports in the autograded
notebooks' hidden test cells, feedback pages) is ranked without running the pipeline: students who
opt in and who do not, refused pseudonyms (empty, too long, bidi, look-alike of an id, a name of the
gradebook, chosen twice), ties, the minimum number of entries, the switch in the plan."""
from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import pytest

from cvkit.course import leaderboard as lb
from cvkit.grading import Case, Check, CaseResult, Measure, Report, close, evaluate
from cvkit.grading.report import MIME_TYPE
from cvkit.course.safety import sanitize_html
from cvkit.registry import get
from cvkit.train.checks import MeasuredCase

ROOT = Path(__file__).resolve().parents[2]
ASSIGNMENT = "ch12_training"
DIGITS = "train.train_digits"
NOTEBOOK = ROOT / "lectures" / ASSIGNMENT / f"{ASSIGNMENT}.ipynb"


# ------------------------------------------------------------------------------ the report's data
def test_a_measured_check_puts_its_value_in_the_report_data():
    """Check.measure fills CaseResult.measure on every case that returned (passed or not), the
    report's JSON carries it; a check without one leaves it out."""
    def share(got, case):
        return float(np.mean(np.isclose(got, 1.0 / case.args[0] ** 2)))

    measure = Measure("right values", lambda got, case: 100 * share(got, case), "%")
    spec = Check(public=[Case((3,), {}, "3"), Case((4,), {}, "4")], hidden=lambda rng: [Case((5,), {}, "5")],
                 compare=close(), credit=share, measure=measure)
    half = evaluate("filters.mean_kernel", lambda size: np.where(np.arange(size * size).reshape(size, size) % 2, 0.0,
                                                                 1.0 / size ** 2), check=spec)
    assert [c.measure["value"] for c in half.cases] == [pytest.approx(500 / 9, abs=1e-5), 50.0]
    data = half.to_dict()["cases"][0]["measure"]
    assert data == {"name": "right values", "value": pytest.approx(55.555556), "unit": "%", "better": "higher"}
    right = evaluate("filters.mean_kernel", lambda size: np.full((size, size), 1.0 / size ** 2), check=spec)
    assert right.passed and [c.measure["value"] for c in right.cases] == [100.0, 100.0]
    crash = evaluate("filters.mean_kernel", lambda size: 1 / 0, check=spec)
    assert [c.measure for c in crash.cases] == [None, None]
    plain = evaluate("filters.mean_kernel", lambda size: np.full((size, size), 1.0 / size ** 2))
    assert all(c.measure is None and "measure" not in c.to_dict() for c in plain.cases)


def test_measure_is_checked_and_says_nothing_for_what_it_cannot_measure():
    with pytest.raises(TypeError, match="name"):
        Measure("", lambda got, case: 1.0)
    with pytest.raises(TypeError, match="of must be a function"):
        Measure("accuracy", 3.0)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="Check.measure"):
        Check(public=[], hidden=lambda rng: [], compare=close(), measure="accuracy")  # type: ignore[arg-type]
    assert Measure("x", lambda got, case: float("nan")).on(None, None) is None
    assert Measure("x", lambda got, case: 1 / 0).on(None, None) is None
    assert Measure("loss", lambda got, case: 0.25, higher_is_better=False).on(None, None)["better"] == "lower"
    # a value that rounds to zero is 0, not -0 (a gap of -1e-15 dB to the reference must not print as "-0.00")
    zero = Measure("gap", lambda got, case: -1e-15).on(None, None)["value"]
    assert zero == 0 and str(zero) == "0.0"


def test_the_digits_check_measures_the_accuracy_in_percent():
    spec = get(DIGITS).check
    assert spec.credit is not None and spec.measure is not None and lb.is_measured(DIGITS)
    truth = np.arange(200) % 10
    labels = truth.copy()
    labels[:5] = (labels[:5] + 1) % 10
    assert spec.measure.on(labels, MeasuredCase((), {}, "", truth=truth)) == {
        "name": "accuracy", "value": 97.5, "unit": "%", "better": "higher"}
    assert not lb.is_measured("filters.mean_kernel")


# ------------------------------------------------------------------------------ a graded course, laid out
def _cell(source, grade_id=None, outputs=None, cell_type="code", trusted=True):
    meta = {"nbgrader": {"grade_id": grade_id, "grade": not grade_id.endswith("_answer"),
                         "solution": grade_id.endswith("_answer"), "points": 4}} if grade_id else {}
    if grade_id and trusted and not grade_id.endswith("_answer"):  # what the trusted grader writes on a test cell
        meta["cvkit"] = {"report": {"points": 4, "credit": 0.0, "checks": [], "flags": []}}
    cell = {"cell_type": cell_type, "source": source, "metadata": meta}
    if cell_type == "code":
        cell.update(outputs=outputs or [], execution_count=None)
    return cell


def _notebook(cells, flags=()):
    return {"cells": cells, "metadata": {"cvkit": {"trusted": True, "flags": list(flags)}}, "nbformat": 4,
            "nbformat_minor": 5}


def _hidden_output(accuracy):
    """The trusted hidden report of train_digits as the autograded notebook holds it: one case on
    200 digits, ``accuracy`` % of them right (None: the candidate crashed)."""
    spec = get(DIGITS).check
    truth = np.arange(200) % 10
    case = MeasuredCase((), {}, "digits", truth=truth)
    if accuracy is None:
        result = CaseResult(0, "your own split", "", False, message="raised ZeroDivisionError")
    else:
        labels = truth.copy()
        wrong = round((100 - accuracy) * 2)
        labels[:wrong] = (labels[:wrong] + 1) % 10
        result = CaseResult(0, "your own split", "", accuracy >= 97, credit=spec.credit(labels, case),
                            measure=spec.measure.on(labels, case))
    report = Report(DIGITS, "12.5.4", True, None, [result])
    return {"output_type": "display_data", "metadata": {},
            "data": {"text/plain": report.text(), MIME_TYPE: json.loads(json.dumps(report.to_dict(), default=str))}}


# student id → (the LEADERBOARD cell's source or None, accuracy, flags)
CLASS = {
    "stud_ada": ('LEADERBOARD = {"join": True, "pseudonym": "Owl"}', 99.0, ()),
    "stud_bob": ('LEADERBOARD = {"join": True, "pseudonym": "Falcon"}', 98.0, ()),
    "stud_cyd": ('# my choice\nLEADERBOARD = {"join": True, "pseudonym": " Heron "}', 98.0, ()),  # ties with Falcon
    "stud_dan": (lb.CELL, 99.5, ()),                                                 # the released cell: not joined
    "stud_eve": (None, 99.5, ()),                                                    # deleted the cell
    "stud_fay": ('LEADERBOARD = {"join": True, "pseudonym": "Rav\\u202eneN"}', 97.0, ()),  # bidi override
    "stud_gus": ('LEADERBOARD = {"join": True, "pseudonym": "ｓｔｕｄ＿ａｄａ"}', 97.0, ()),  # full-width id
    "stud_hal": ('LEADERBOARD = {"join": True, "pseudonym": "Kestrel"}', 96.0, ()),
    "stud_ivy": ('LEADERBOARD = {"join": True, "pseudonym": "kestrel."}', 95.0, ()),  # same as hal's: both out
    "stud_jon": ('LEADERBOARD = {"join": True, "pseudonym": "  "}', 97.0, ()),
    "stud_kim": ('LEADERBOARD = {"join": True, "pseudonym": "Osprey"}', None, ()),  # crashed: nothing measured
    "stud_lea": ('LEADERBOARD = {"join": True, "pseudonym": "Wren"}', 99.9,
                 ("train_digits_visible: passes only the public cases (train.train_digits)",)),
    "stud_mo": ('LEADERBOARD = {"join": True, "pseudonym": "' + "x" * 30 + '"}', 97.0, ()),
    "stud_nia": ('LEADERBOARD = {"join": "yes", "pseudonym": "Swift"}', 97.0, ()),
    "stud_pat": ('LEADERBOARD = {"join": True, "pseudonym": "Lovelace fan"}', 97.0, ()),  # a name in the gradebook
    "stud_quinn": ('LEADERBOARD = {"join": True, "pseudonym": "ud_bo"}', 97.0, ()),  # a piece of an id... (5 chars)
    "stud_rex": ('LEADERBOARD = {"join": True, "pseudonym": "Raven"}', None, ()),  # crashed, displayed a forged report
}
FORGED = "stud_rex"
PUBLISHED = [(1, "Owl", 99.0), (2, "Falcon", 98.0), (2, "Heron", 98.0)]
LEFT_OUT = {"stud_fay": "invisible or format", "stud_gus": "looks like a student id", "stud_hal": "also the choice",
            "stud_ivy": "also the choice", "stud_jon": "empty", "stud_kim": "no measured value",
            "stud_lea": "flagged for review", "stud_mo": "longer than 24", "stud_nia": '"join" must be True',
            "stud_pat": "student's name", "stud_quinn": "looks like a student id", "stud_rex": "no measured value"}
PAGE = "<!DOCTYPE html><html><head><title>feedback</title></head><body><p>your feedback</p></body></html>"


def make_course(folder: Path, plan: str = "[leaderboard]\nenabled = true\n"):
    from nbgrader.api import Gradebook

    from cvkit.course import Course
    from cvkit.course.plan import stamp_new_gradebook

    folder.mkdir(parents=True)
    (folder / "plan.toml").write_text(f'[[assignment]]\nid = "{ASSIGNMENT}"\n\n{plan}')
    course = Course(folder, project=ROOT)
    stamp_new_gradebook(course.db_url)  # spares nbgrader's `alembic` process
    with Gradebook(course.db_url) as gradebook:
        for student in CLASS:
            first, last = ("Ada", "Lovelace") if student == "stud_ada" else (student[5:].title(), "Student")
            gradebook.add_student(student, first_name=first, last_name=last)
    for student, (cell, accuracy, flags) in CLASS.items():
        cells = [_cell("x = 1")] + ([_cell(cell)] if cell is not None else [])
        test = _cell("### BEGIN HIDDEN TESTS\n...\n### END HIDDEN TESTS", "train_digits_hidden")
        course.submit(student, ASSIGNMENT, {f"{ASSIGNMENT}.ipynb": _notebook(cells + [test])})
        graded = folder / "autograded" / student / ASSIGNMENT
        graded.mkdir(parents=True)
        test = _cell("# (hidden tests: their results are shown below)", "train_digits_hidden",
                     [_hidden_output(accuracy), {"output_type": "execute_result", "data": {"text/plain": "2.0"},
                                                 "metadata": {}, "execution_count": None}])
        answer = _cell("def train_digits(x_train, y_train, rng=None): ...", "train_digits_answer",
                       [_hidden_output(100.0)] if student == FORGED else [])
        (graded / f"{ASSIGNMENT}.ipynb").write_text(json.dumps(_notebook([answer] + cells + [test], flags)))
        feedback = folder / "feedback" / student / ASSIGNMENT
        feedback.mkdir(parents=True)
        (feedback / f"{ASSIGNMENT}.html").write_text(PAGE)
    return course


@pytest.fixture(scope="module")
def course(tmp_path_factory):
    course = make_course(tmp_path_factory.mktemp("board") / "course")
    lines = lb.publish(course)
    return course, lines


def _page(course):
    return (course.root / "leaderboard" / f"{ASSIGNMENT}.html").read_text(encoding="utf-8")


def test_ranks_the_students_who_opted_in_with_shared_ranks_for_ties(course):
    course, _ = course
    board = lb.build(course, ASSIGNMENT)
    assert [(t.algorithm, t.measure, t.unit) for t in board.tables] == [(DIGITS, "accuracy", "%")]
    assert board.tables[0].rows == PUBLISHED
    with (course.root / "leaderboard" / f"{ASSIGNMENT}.csv").open(encoding="utf-8", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [(int(r["rank"]), r["pseudonym"], float(r["value"])) for r in rows] == PUBLISHED
    assert {r["exercise"] for r in rows} == {DIGITS} and {r["unit"] for r in rows} == {"%"}


def test_the_page_holds_no_student_id_no_name_and_no_script(course):
    course, _ = course
    page = _page(course)
    assert "stud_" not in page and "Lovelace" not in page
    assert "<script" not in page.lower() and "default-src 'none'" in page
    for refused in ("Kestrel", "kestrel", "Osprey", "Wren", "Swift", "\u202e", "ｓｔｕｄ"):
        assert refused not in page
    cells = re.findall(r"<tr><td>(\d+)</td><td>([^<]*)</td><td>([\d.]+)</td></tr>", page)
    assert [(int(r), p, float(v)) for r, p, v in cells] == PUBLISHED


def test_students_who_did_not_opt_in_never_appear(course):
    course, lines = course
    board = lb.build(course, ASSIGNMENT)
    assert set(board.pseudonyms) == {"stud_ada", "stud_bob", "stud_cyd", "stud_kim", "stud_lea", "stud_rex"}
    assert "stud_dan" not in board.left_out and "stud_eve" not in board.left_out  # not asked: nothing to say
    assert "99.50" not in _page(course)


def test_refused_pseudonyms_are_left_out_and_the_summary_says_why(course):
    course, lines = course
    board = lb.build(course, ASSIGNMENT)
    assert set(board.left_out) == set(LEFT_OUT)
    for student, words in LEFT_OUT.items():
        line = next(line for line in lines if f"left out: {student}:" in line)
        assert words in line, line
    saved = (course.root / "exports" / lb.SUMMARY_NAME).read_text(encoding="utf-8")
    assert saved.splitlines() == lines
    assert all(line.isprintable() for line in lines)  # the bidi pseudonym is never echoed raw


def test_each_feedback_page_gets_the_board_and_marks_the_students_own_row(course):
    course, _ = course
    pages = {s: (course.root / "feedback" / s / ASSIGNMENT / f"{ASSIGNMENT}.html").read_text() for s in CLASS}
    for student, text in pages.items():
        assert text.count('<section class="cvkit-leaderboard"') == 1
        assert text.index("cvkit-leaderboard") > text.index("your feedback") and text.endswith("</body></html>")
        assert "stud_" not in text.replace(f"{ASSIGNMENT}", "")
    assert "<td>Owl <b>(you)</b></td>" in pages["stud_ada"]
    assert "(you)" not in pages["stud_dan"] and "(you)" not in pages["stud_kim"]
    assert "<td>Heron <b>(you)</b></td>" in pages["stud_cyd"]
    # who asked and is not on it reads why on their own page, in words that name no one else
    notes = {s: re.findall(r'<p class="cvkit-leaderboard-note">([^<]*)</p>', text) for s, text in pages.items()}
    assert {s for s, found in notes.items() if found} == set(LEFT_OUT)
    assert all(len(found) <= 1 for found in notes.values())
    assert "looks like a student id" in notes["stud_gus"][0] and "empty" in notes["stud_jon"][0]
    assert "someone else chose the same pseudonym" in notes["stud_hal"][0] == notes["stud_ivy"][0]
    assert "no measured value" in notes["stud_kim"][0]
    assert "ask your instructor" in notes["stud_lea"][0] and "public" not in notes["stud_lea"][0]
    assert "\u202e" not in pages["stud_fay"] and "U+202E" in notes["stud_fay"][0]
    # idempotent: published again, the pages do not change
    lb.publish(course)
    assert {s: (course.root / "feedback" / s / ASSIGNMENT / f"{ASSIGNMENT}.html").read_text() for s in CLASS} == pages


def test_the_section_is_what_the_feedback_sanitizer_keeps():
    board = lb.Board(ASSIGNMENT, 3, [lb.Table(DIGITS, "accuracy", "%", True, [(1, "O'Neil <b>", 99.0)])])
    section = lb.fragment(board, own="O'Neil <b>", note="the pseudonym holds <script> & co")
    assert sanitize_html(section, trusted_report=True) == section
    assert "&lt;script&gt; &amp; co" in section
    assert "<b>(you)</b>" in section and "&lt;b&gt;" in section


def test_below_the_minimum_no_page_and_what_was_written_goes(tmp_path):
    course = make_course(tmp_path / "course", "[leaderboard]\nenabled = true\nmin_entries = 4\n")
    page = course.root / "feedback" / "stud_ada" / ASSIGNMENT / f"{ASSIGNMENT}.html"
    lb.publish(course, chosen=lb.Settings(True, 3))
    assert (course.root / "leaderboard" / f"{ASSIGNMENT}.html").is_file() and "cvkit-leaderboard" in page.read_text()
    lines = lb.publish(course)  # the plan's minimum, 4: three entries are too few
    assert not (course.root / "leaderboard" / f"{ASSIGNMENT}.html").exists()
    assert not (course.root / "leaderboard" / f"{ASSIGNMENT}.csv").exists()
    assert page.read_text() == PAGE
    assert any("not shown, 3 entries (at least 4 needed)" in line for line in lines)
    assert any("not published" in line for line in lines)


def test_switched_off_in_the_plan_nothing_is_written(tmp_path):
    course = make_course(tmp_path / "course", "")
    assert lb.publish(course) == ["leaderboard: off (plan.toml [leaderboard] enabled = true turns it on)"]
    assert not (course.root / "leaderboard").exists() and not (course.root / "exports" / lb.SUMMARY_NAME).exists()
    assert all(p.read_text() == PAGE for p in (course.root / "feedback").glob(f"*/{ASSIGNMENT}/*.html"))
    # on, then off again: everything it wrote is taken back
    lb.publish(course, chosen=lb.Settings(True))
    assert (course.root / "leaderboard" / f"{ASSIGNMENT}.html").is_file()
    lb.publish(course)
    assert not list((course.root / "leaderboard").iterdir())
    assert not (course.root / "exports" / lb.SUMMARY_NAME).exists()
    assert all(p.read_text() == PAGE for p in (course.root / "feedback").glob(f"*/{ASSIGNMENT}/*.html"))


def test_the_command_writes_and_prints_the_summary(tmp_path, capsys):
    from cvkit.cli import main

    course = make_course(tmp_path / "course")
    assert main(["course", "leaderboard", "--course-dir", str(course.root), ASSIGNMENT]) == 0
    out = capsys.readouterr().out
    assert f"leaderboard {ASSIGNMENT}: leaderboard/{ASSIGNMENT}.html, {DIGITS} (3) entries" in out
    assert "left out: stud_gus: the pseudonym looks like a student id" in out
    assert (course.root / "leaderboard" / f"{ASSIGNMENT}.html").is_file()


# ------------------------------------------------------------------------------ the rules, one by one
def test_settings_are_off_by_default_and_checked():
    assert lb.settings({}) == lb.Settings(False, lb.DEFAULT_MIN_ENTRIES)
    assert lb.settings({"leaderboard": {"enabled": True, "min_entries": 5}}) == lb.Settings(True, 5)
    for bad, words in (({"enabled": "yes"}, "true or false"), ({"min_entries": 2}, "at least 3"),
                       ({"min_entries": 3.5}, "whole number"), ({"min_entries": True}, "whole number"),
                       ({"top": 10}, "unknown key")):
        with pytest.raises(ValueError, match=words):
            lb.settings({"leaderboard": bad})
    with pytest.raises(ValueError, match="must be a table"):
        lb.settings({"leaderboard": True})


def test_the_plan_reader_accepts_the_table_and_a_broken_plan_is_named(tmp_path):
    from cvkit.course.plan import read_plan

    plan = tmp_path / "plan.toml"
    plan.write_text(f'[[assignment]]\nid = "{ASSIGNMENT}"\n\n[leaderboard]\nenabled = true\nmin_entries = 4\n')
    assert read_plan(plan).ids() == [ASSIGNMENT]
    assert lb.read_settings(plan) == lb.Settings(True, 4)
    assert lb.read_settings(tmp_path / "none.toml") == lb.Settings()
    plan.write_text("[leaderboard\n")
    with pytest.raises(ValueError, match="not valid TOML"):
        lb.read_settings(plan)


def test_ranking_shares_ranks_on_ties_both_ways():
    values = {"b": 90.0, "a": 95.004, "c": 95.0, "d": 80.0, "e": 90.0}
    assert lb.rank(values) == [(1, "a", 95.0), (1, "c", 95.0), (3, "b", 90.0), (3, "e", 90.0), (5, "d", 80.0)]
    assert lb.rank({"x": 0.5, "y": 0.25, "z": 0.25}, higher_is_better=False) == [(1, "y", 0.25), (1, "z", 0.25),
                                                                                 (3, "x", 0.5)]
    assert lb.rank({}) == []


@pytest.mark.parametrize("pseudonym, words", [
    ("", "empty"), ("   ", "empty"), ("a" * 25, "longer than 24"), ("Owl\u200b", "invisible"),
    ("Owl\u2066", "invisible"), ("Owl\x1b[2J", "control"), ("<b>Owl</b>", "other than letters"),
    ("=HYPERLINK(1)", "other than letters"), ("...", "no letter or digit"),
    ("s1234567", "student id"), ("S1234567", "student id"), ("ｓ１２３４５６７", "student id"),
    ("s-1234-567", "student id"), ("fan of s1234567", "student id"), ("234567", "student id"),
    ("Lovelace", "student's name"), ("ada lovelace fan", "student's name"),
])
def test_pseudonym_rules(pseudonym, words):
    assert words in lb.pseudonym_problem(pseudonym, ["s1234567", "bo"], ["Ada", "Lovelace"])


@pytest.mark.parametrize("pseudonym", ["Owl", "Grey Heron", "Zoë", "O'Neil", "night_owl-2", "бобр", "bob"])
def test_ordinary_pseudonyms_pass(pseudonym):
    # "bob" contains the id "bo", which is too short to reveal anyone; an id shorter than 3 is never matched
    assert lb.pseudonym_problem(pseudonym, ["s1234567", "bo"], ["Ada", "Lovelace"]) is None


@pytest.mark.parametrize("source, expected", [
    (lb.CELL, lb.OptIn(False, "")),
    ('LEADERBOARD = {"join": True, "pseudonym": "Owl"}', lb.OptIn(True, "Owl")),
    ('%matplotlib inline\nLEADERBOARD: dict = {"join": True, "pseudonym": "Owl"}', lb.OptIn(True, "Owl")),
    ('LEADERBOARD = {"join": True}', lb.OptIn(True, "")),
    ("x = 1  # LEADERBOARD is elsewhere", None),
])
def test_the_cell_is_read_never_run(source, expected):
    found = lb.opt_ins_in(source)
    assert (found[0] if found else None) == expected


@pytest.mark.parametrize("source, words", [
    ('LEADERBOARD = dict(join=True, pseudonym="Owl")', "plain dictionary"),
    ('LEADERBOARD = {"join": __import__("os").system("true"), "pseudonym": "Owl"}', "plain dictionary"),
    ('LEADERBOARD = {"join": 1, "pseudonym": "Owl"}', '"join" must be True'),
    ('LEADERBOARD = {"join": True, "pseudonym": "Owl", "id": "s1"}', "keys"),
    ('LEADERBOARD = {"join": True, "pseudonym": "Owl"', "not valid Python"),
    ("LEADERBOARD = " + "[" * 5000 + "]" * 5000, "plain dictionary|not valid Python|too long"),
])
def test_what_cannot_be_read_is_no(source, words):
    found = lb.opt_ins_in(source)
    assert len(found) == 1 and not found[0].join and re.search(words, found[0].problem)


def test_only_the_reports_the_trusted_grader_wrote_count(tmp_path):
    """A report displayed by the student's own code (an answer cell, or a test cell the trusted
    grader did not write) is never read; the test cell's is."""
    forged = [_hidden_output(100.0)]
    cells = [_cell("...", "train_digits_answer", forged), _cell("...", "train_digits_hidden", forged, trusted=False)]
    (tmp_path / "a.ipynb").write_text(json.dumps(_notebook(cells)))
    assert lb.measured_values(tmp_path) == ({}, {})
    cells.append(_cell("...", "train_digits_hidden", [_hidden_output(96.5)]))
    (tmp_path / "a.ipynb").write_text(json.dumps(_notebook(cells)))
    values, missing = lb.measured_values(tmp_path)
    assert values == {DIGITS: lb.Value("accuracy", "%", True, 96.5)} and not missing


def test_two_different_settings_in_one_hand_in_are_no(tmp_path):
    cells = [_cell('LEADERBOARD = {"join": True, "pseudonym": "Owl"}'), _cell(lb.CELL)]
    (tmp_path / "a.ipynb").write_text(json.dumps(_notebook(cells)))
    assert "more than once" in lb.read_opt_in(tmp_path).problem
    (tmp_path / "a.ipynb").write_text(json.dumps(_notebook(cells[:1] * 2)))
    assert lb.read_opt_in(tmp_path) == lb.OptIn(True, "Owl")
    (tmp_path / "a.ipynb").write_text("{not json")
    assert lb.read_opt_in(tmp_path) is None


@pytest.mark.parametrize("notebook", [
    [1, 2], {"cells": "LEADERBOARD"}, {"cells": ["LEADERBOARD = {'join': True}", 3]},
    {"cells": [{"cell_type": "code", "source": ["LEADERBOARD = ", 5], "metadata": {}}]},
    {"cells": [{"cell_type": "markdown", "source": 'LEADERBOARD = {"join": True, "pseudonym": "Owl"}'}]},
], ids=["a list", "cells a string", "cells not dicts", "source not all text", "markdown"])
def test_a_hand_edited_notebook_is_no_opt_in_and_no_error(tmp_path, notebook):
    """JSON a student edited by hand is read as far as it is a notebook: what is not a code
    cell with text for its source sets nothing, and nothing raises."""
    (tmp_path / "a.ipynb").write_text(json.dumps(notebook))
    assert lb.read_opt_in(tmp_path) is None
    cells = [_cell('LEADERBOARD = {"join": True, "pseudonym": "Owl"}')]
    (tmp_path / "b.ipynb").write_text(json.dumps(_notebook(cells)))
    assert lb.read_opt_in(tmp_path) == lb.OptIn(True, "Owl")


# ------------------------------------------------------------------------------ the chapters
def _measured_ids(notebook: dict) -> set[str]:
    found = set()
    for cell in notebook["cells"]:
        if cell["cell_type"] == "code":
            found |= set(re.findall(r"check\(\"([a-z0-9_]+\.[a-z0-9_]+)\"", "".join(cell["source"])))
    return {i for i in found if lb.is_measured(i)}


def test_every_chapter_with_a_measured_exercise_releases_the_opt_in_cell():
    """Each chapter notebook that checks a measured exercise has the released cell, not graded,
    saying no by default, and a statement of it before."""
    seen = 0
    for path in sorted((ROOT / "lectures").glob("ch*/ch*.ipynb")):
        notebook = json.loads(path.read_text(encoding="utf-8"))
        if not _measured_ids(notebook):
            continue
        seen += 1
        cells = notebook["cells"]
        index = next((i for i, c in enumerate(cells) if c["cell_type"] == "code" and "".join(c["source"]).strip()
                      .endswith(lb.CELL)), None)
        assert index is not None, f"{path.name}: no cell {lb.CELL}"
        assert "nbgrader" not in cells[index]["metadata"], "the opt-in cell is not graded"
        assert [o for c in cells for o in lb.opt_ins_in("".join(c["source"])) if c["cell_type"] == "code"] == [
            lb.OptIn(False, "")]
        before = "".join(cells[index - 1]["source"])
        assert cells[index - 1]["cell_type"] == "markdown" and "pseudonym" in before and "no points" in before
    assert seen >= 1  # Chapter 12's train_digits at least


# ------------------------------------------------------------------------------ through the real pipeline
TINY = "ch98_measured"
_NEAREST = '''@student("train.train_digits")
def train_digits(x_train, y_train, rng=None):
    ### BEGIN SOLUTION
    def unit(x):
        x = np.asarray(x, dtype=float).reshape(len(x), -1)
        x = x - x.mean(axis=1, keepdims=True)
        return x / (np.linalg.norm(x, axis=1, keepdims=True) + 1e-12)

    known, labels = unit(x_train), np.asarray(y_train)

    def predict(x):
        return labels[np.argmax(unit(x) @ known.T, axis=1)]
    return predict
    ### END SOLUTION'''


def _variant(vote: str) -> str:
    """The answer with another rule to pick the label (every variant clears 97 % here, so that no
    mistake of the bank is trained: the test stays short)."""
    plain = "\n".join(line for line in _NEAREST.splitlines() if "### " not in line)
    return plain.replace("        return labels[np.argmax(unit(x) @ known.T, axis=1)]", vote)


_THREE_NEIGHBOURS = _variant("        nearest = np.argsort(-(unit(x) @ known.T), axis=1)[:, :3]\n"
                             "        return np.array([np.bincount(v, minlength=10).argmax() for v in labels[nearest]])")
_ONE_NEIGHBOUR = _variant("        return labels[np.argmax(unit(x) @ known.T, axis=1)]")


def _tiny_notebook(answer=_NEAREST, opt_in=lb.CELL):
    def cell(source, grade_id=None, points=None, solution=False):
        meta = {}
        if grade_id:
            meta["nbgrader"] = {"grade_id": grade_id, "solution": solution, "grade": points is not None,
                                "locked": not solution, "schema_version": 3}
            if points is not None:
                meta["nbgrader"]["points"] = points
        return {"cell_type": "code", "source": source, "metadata": meta, "outputs": [], "execution_count": None}

    cells = [cell("import numpy as np\nfrom cvkit.grading import check\nfrom cvkit.registry import student", "setup"),
             cell(answer, "train_digits_answer", solution=True),
             cell('check("train.train_digits", train_digits)', "train_digits_visible", 1),
             cell('### BEGIN HIDDEN TESTS\ncheck("train.train_digits", train_digits, hidden=True, points=4)\n'
                  "### END HIDDEN TESTS", "train_digits_hidden", 4),
             cell(opt_in)]
    return {"cells": cells, "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3",
                                                        "language": "python"}}, "nbformat": 4, "nbformat_minor": 5}


@pytest.mark.slow
def test_grading_a_course_publishes_the_board_from_the_sandboxed_reports(tmp_path):
    """A tiny chapter with the digits exercise, graded for real (sandbox, nbgrader, feedback):
    the hidden reports carry the accuracy on each student's own digits, and `cvkit course grade`
    writes the board from them, ranked by it (who is left out and why: the tests above)."""
    import shutil

    from cvkit.course import Course

    project = tmp_path / "project"
    (project / "autograders").mkdir(parents=True)
    shutil.copy(ROOT / "autograders" / "nbgrader_config.py", project / "autograders" / "nbgrader_config.py")
    (project / "autograders" / "plan.toml").write_text(f'[[assignment]]\nid = "{TINY}"\n\n[leaderboard]\n'
                                                       "enabled = true\n")
    (project / "lectures" / TINY).mkdir(parents=True)
    (project / "lectures" / TINY / f"{TINY}.ipynb").write_text(json.dumps(_tiny_notebook()))
    project.chmod(0o755)
    course = Course(tmp_path / "course", project=project)
    (course.root / ".grading_salt").write_text("leaderboard-salt")
    course.build([TINY])
    hand_ins = {"ada": (_ONE_NEIGHBOUR, 'LEADERBOARD = {"join": True, "pseudonym": "Owl"}'),
                "bob": (_THREE_NEIGHBOURS, 'LEADERBOARD = {"join": True, "pseudonym": "Falcon"}'),
                "cyd": (_ONE_NEIGHBOUR, 'LEADERBOARD = {"join": True, "pseudonym": "Heron"}')}
    for student, (answer, opt_in) in hand_ins.items():
        course.submit(student, TINY, {f"{TINY}.ipynb": _tiny_notebook(answer, opt_in)})
    results = course.grade(workers=2)
    assert all(r.ok for r in results), [r.log for r in results if not r.ok]
    accuracy = {}
    for student in hand_ins:
        values, missing = lb.measured_values(course.root / "autograded" / student / TINY)
        assert not missing and values[DIGITS].name == "accuracy" and values[DIGITS].unit == "%"
        accuracy[student] = values[DIGITS].value
    pseudonym = {"ada": "Owl", "bob": "Falcon", "cyd": "Heron"}
    expected = lb.rank({pseudonym[s]: accuracy[s] for s in pseudonym})
    with (course.root / "leaderboard" / f"{TINY}.csv").open(encoding="utf-8", newline="") as handle:
        rows = [(int(r["rank"]), r["pseudonym"], float(r["value"])) for r in csv.DictReader(handle)]
    assert rows == expected
    page = (course.root / "leaderboard" / f"{TINY}.html").read_text(encoding="utf-8")
    assert all(student not in page for student in hand_ins)
    for student in hand_ins:
        feedback = (course.root / "feedback" / student / TINY / f"{TINY}.html").read_text(encoding="utf-8")
        assert feedback.count('<section class="cvkit-leaderboard"') == 1
        assert f"<td>{pseudonym[student]} <b>(you)</b></td>" in feedback
    assert any(line.startswith(f"leaderboard {TINY}: leaderboard/{TINY}.html") for line in lb.saved_summary(course))
