"""Issue 32, round 2: nothing a student names can stop or corrupt the class's grading run.

A student controls the names of their files (any bytes: not UTF-8, control characters), their
student folder's name when they can choose it, and the text of their exceptions and imports.
None of it may stop ``cvkit course grade``, reach the instructor's terminal or the CSV exports as
escape sequences, or pass for another student: file names that are not valid UTF-8 or hold
control or invisible characters are refused (the rest of the submission is graded); such student
folders, and look-alikes of another student's id, are listed as *not graded* with a printable
reason, never graded under that id, never shown as a zero; every student-derived text that
leaves cvkit is shown with visible escapes (:func:`cvkit._text.printable`).

The unit tests run in milliseconds; the graded batch (``slow``) grades real submissions through
:meth:`Course.grade` on the tiny chapter of ``tests/course/test_course_scaling.py``.
"""
import csv
import io
import os
import unicodedata
from contextlib import redirect_stdout

import pytest

from cvkit._text import name_problem, printable, skeleton
from cvkit.course import Course
from cvkit.course.exports import format_table, similarity_summary
from cvkit.course.journal import Journal
from cvkit.course.results import ExerciseScore
from cvkit.sandbox import isolation

from test_course_scaling import ASSIGNMENT, _answers, make_course
from test_course_scaling import project  # noqa: F401  (the tiny chapter's project, a fixture)
from test_sandbox_attacks import FULL, KERNEL_ZERO, cell_grades_graded, kernel

NOT_UTF8 = os.fsdecode(b"st\xffudent")            # what pathlib gives for the bytes b"st\xffudent"
ZERO_WIDTH = "ada\u200b"                          # a zero-width-space copy of ada's id
FULL_WIDTH = "\uff42ea"                            # "ｂea": bea with a full-width b (NFKC: "bea")
ESCAPED_ID = "mal\x1b]0;pwned\x07"                 # sets the terminal's title
CLEAR = "\x1b[2J\x1b[3Jcleared"                    # clears the screen and the scrollback


def unsafe(text: str) -> list[str]:
    """The characters of ``text`` a terminal acts on or nobody sees (newline, tab and carriage
    return allowed: CSV needs them), and lone surrogates (bytes that were not UTF-8)."""
    return [c for c in text if unicodedata.category(c) in ("Cc", "Cf", "Cs", "Zl", "Zp") and c not in "\n\r\t"]


# ------------------------------------------------------------------------------- the helper
def test_printable_shows_controls_bidi_and_invisible_characters_as_escapes():
    assert printable(CLEAR) == "\\x1b[2J\\x1b[3Jcleared"
    assert printable("\x1b]0;title\x07") == "\\x1b]0;title\\x07"
    assert printable("\x9b31m \x7f \x00") == "\\x9b31m \\x7f \\x00"           # C1 CSI, DEL, NUL
    assert printable("abc\u202edef \u2066x\u2069") == "abc\\u202edef \\u2066x\\u2069"  # bidi override, isolate
    assert printable("ada\u200b \ufeff \u00ad \u200d") == "ada\\u200b \\ufeff \\xad \\u200d"
    assert printable("a\u2028b") == "a\\u2028b"
    assert printable(NOT_UTF8) == "st\\xffudent"                               # the byte, as it was
    assert printable("one\ntwo\tthree\r") == "one\\ntwo\\tthree\\r"
    assert printable("one\ntwo\r", newlines=True) == "one\ntwo\\r"
    assert printable(3.5) == "3.5"


def test_printable_leaves_ordinary_text_alone():
    for text in ("ada", "Zoë Åsa", "=HYPERLINK(1)", "0.50/1 ✓", "“all ones”", "日本語", "a\\x1b", "ｂea", ""):
        assert printable(text) == text


def test_names_refused_and_look_alikes():
    assert name_problem("ada") is None and name_problem("ｂea") is None and name_problem("Zoë") is None
    assert name_problem(NOT_UTF8) == "is not valid UTF-8"
    assert name_problem(ESCAPED_ID) == "holds control characters (U+001B, U+0007)"
    assert name_problem("x\ty") == "holds control characters (U+0009)"
    assert name_problem(ZERO_WIDTH) == "holds invisible or format characters (U+200B ZERO WIDTH SPACE)"
    assert name_problem("a\u202eb") == "holds invisible or format characters (U+202E RIGHT-TO-LEFT OVERRIDE)"
    assert skeleton(ZERO_WIDTH) == skeleton("ada\ufeff") == skeleton("a\u00add\u200da") == "ada"
    assert skeleton(FULL_WIDTH) == "bea"
    assert skeleton(unicodedata.normalize("NFD", "Åsa")) == "Åsa"
    assert skeleton("Ada") == "Ada"  # case is kept


# ------------------------------------------------------------------------------- files
def _odd_folder(folder):
    """A submission folder with one good notebook and every kind of hostile name."""
    folder.mkdir(parents=True)
    (folder / "a.ipynb").write_bytes(b"{}")
    os.symlink("/etc/passwd", os.fsencode(folder) + b"/\xff\xfe.ipynb")
    os.mkfifo(os.fsencode(folder) + b"/bad\xff")
    (folder / os.fsdecode(b"notes\xff.txt")).write_bytes(b"hello")
    (folder / "x\x1b[2J.txt").write_bytes(b"hello")
    (folder / "rtl\u202etxt.exe").write_bytes(b"hello")
    os.mkdir(os.fsencode(folder) + b"/d\xff")
    (folder / os.fsdecode(b"d\xff") / "inner.txt").write_bytes(b"hello")


def test_collect_files_refuses_hostile_names_and_keeps_the_rest(tmp_path):
    folder = tmp_path / "submission"
    _odd_folder(folder)
    files, refused = isolation.collect_files(folder)
    assert files == {"a.ipynb": b"{}"}
    assert sorted(refused) == sorted([
        "\\xff\\xfe.ipynb: a symbolic link (refused, not followed)",
        "bad\\xff: not a regular file (refused)",
        "notes\\xff.txt: a file whose name is not valid UTF-8 (refused)",
        "x\\x1b[2J.txt: a file whose name holds control characters (U+001B) (refused)",
        "rtl\\u202etxt.exe: a file whose name holds invisible or format characters "
        "(U+202E RIGHT-TO-LEFT OVERRIDE) (refused)",
        "d\\xff/inner.txt: a file whose name is not valid UTF-8 (refused)",
    ])
    assert all(not unsafe(note) for note in refused)


def test_the_journal_hashes_a_folder_of_hostile_names(tmp_path):
    _odd_folder(tmp_path / "submitted" / "ada" / ASSIGNMENT)
    journal = Journal(tmp_path)
    first = journal.submission_hash("ada", ASSIGNMENT)
    assert first == journal.submission_hash("ada", ASSIGNMENT)
    os.rename(os.fsencode(tmp_path) + b"/submitted/ada/" + ASSIGNMENT.encode() + b"/notes\xff.txt",
              os.fsencode(tmp_path) + b"/submitted/ada/" + ASSIGNMENT.encode() + b"/notes\xfe.txt")
    assert journal.submission_hash("ada", ASSIGNMENT) != first  # a renamed refused file is a change
    journal.mark_graded([("ada", ASSIGNMENT)])
    assert journal.is_current("ada", ASSIGNMENT)


# ------------------------------------------------------------------------------- student ids
def test_hostile_and_look_alike_ids_are_listed_as_not_graded(project, tmp_path):
    course = Course(tmp_path / "course", project=project)
    nfd = unicodedata.normalize("NFD", "Åsa")
    for student in ("ada", "bea", "Zoë", nfd, ZERO_WIDTH, FULL_WIDTH, NOT_UTF8, ESCAPED_ID, "\uff43yd"):
        course.submit(student, ASSIGNMENT, {f"{ASSIGNMENT}.ipynb": _answers()})
    # a chapter folder of a name that is not UTF-8 beside ada's real one
    course.submit("ada", os.fsdecode(b"ch\xff"), {f"{ASSIGNMENT}.ipynb": _answers()})
    # ordinary ids, and look-alikes of nobody (NFD Åsa, full-width ｃyd), are graded as before
    assert course.submissions() == sorted((s, ASSIGNMENT) for s in ("ada", "bea", "Zoë", nfd, "\uff43yd"))
    refused = course.refused_submissions()
    assert refused == {
        f"{ZERO_WIDTH}/{ASSIGNMENT}": "the student id 'ada\\u200b' looks like student 'ada' (it differs only by "
                                      "invisible characters (U+200B ZERO WIDTH SPACE)): no grade is recorded under "
                                      "an id that cannot be told apart; rename the folder if it is another student",
        f"{FULL_WIDTH}/{ASSIGNMENT}": "the student id 'ｂea' looks like student 'bea' (it differs only by "
                                      "compatibility forms of characters (U+FF42 FULLWIDTH LATIN SMALL LETTER B)): "
                                      "no grade is recorded under an id that cannot be told apart; rename the "
                                      "folder if it is another student",
        f"{NOT_UTF8}/{ASSIGNMENT}": "the student folder 'st\\xffudent' is not valid UTF-8: rename the folder to "
                                    "the student's id",
        f"{ESCAPED_ID}/{ASSIGNMENT}": "the student folder 'mal\\x1b]0;pwned\\x07' holds control characters "
                                      "(U+001B, U+0007): rename the folder to the student's id",
        f"ada/{os.fsdecode(b'ch' + bytes([255]))}": "the chapter folder 'ch\\xff' is not valid UTF-8: rename the "
                                                     "folder to the chapter's id",
    }
    assert all(not unsafe(reason) for reason in refused.values())
    assert refused.items() <= course.not_graded().items()


def test_the_table_shows_student_text_with_escapes():
    scores = {"ada": [ExerciseScore("mean_kernel", 0.0, 3.0, problems=[f"raised ValueError: {CLEAR}"],
                                    flags=["import os\x1b[2J is not allowed", "a\u202eb"])],
              "bea": [ExerciseScore("mean_kernel", 3.0, 3.0, mistakes=["all\x9bones"])]}
    table = format_table(scores, not_graded={NOT_UTF8: "the student folder 'st\\xffudent' is not valid UTF-8",
                                             "eve": f"nbgrader said {CLEAR}"},
                         unsandboxed=[ESCAPED_ID])
    assert not unsafe(table.replace("\n", ""))
    assert "ada · mean_kernel: raised ValueError: \\x1b[2J\\x1b[3Jcleared" in table
    assert "ada · mean_kernel: import os\\x1b[2J is not allowed" in table and "a\\u202eb" in table
    assert "“all\\x9bones”" in table
    assert "  st\\xffudent: not graded: the student folder 'st\\xffudent' is not valid UTF-8" in table
    assert "  eve: not graded: nbgrader said \\x1b[2J\\x1b[3Jcleared" in table
    assert "mal\\x1b]0;pwned\\x07" in table


def test_the_similarity_summary_is_printable(project, tmp_path):
    """The report may name any folder of submitted/ (its bytes as they are on disk)."""
    course = Course(tmp_path / "course", project=project)
    (course.root / "exports").mkdir()
    (course.root / "exports" / "similarity.csv").write_bytes(
        b"assignment,exercise,cluster,students,student,closest,similarity,textbook,added_code\n"
        b"ch99_tiny,mean_kernel_answer,1,2,ada,st\xffudent,1.000,,\n"
        b"ch99_tiny,mean_kernel_answer,1,2,st\xffudent,ada,1.000,,\n"
        b"ch99_tiny,mean_kernel_answer,2,1,mal\x1b]0;pwned\x07,(reference x\x1b[2J),0.950,(reference x\x1b[2J),\n")
    lines = similarity_summary(course)
    assert lines[1:] == ["  100%  ch99_tiny · mean_kernel_answer: ada ↔ st\\xffudent",
                         "   95%  ch99_tiny · mean_kernel_answer: mal\\x1b]0;pwned\\x07 ≈ (reference x\\x1b[2J)"]
    assert not unsafe("".join(lines))


# ------------------------------------------------------------------------------- a graded batch
@pytest.fixture(scope="module")
def hostile(project, tmp_path_factory):
    """One batch: honest ada and bea beside every hostile name, graded by Course.grade."""
    if isolation.probe(force=True):
        pytest.fail(f"the sandbox is needed for this test: {isolation.probe()}")
    name = f"{ASSIGNMENT}.ipynb"
    students = {
        "ada": _answers(), "bea": _answers(), "oddfiles": _answers(),
        ZERO_WIDTH: _answers(), FULL_WIDTH: _answers(), NOT_UTF8: _answers(), ESCAPED_ID: _answers(),
        "escaper": _answers(kernel=kernel('raise ValueError("\\x1b[2J\\x1b[3Jcleared")')),
        "importer": _answers(kernel=kernel('__import__("os\\x1b[2J")\nreturn np.full((size, size), 1.0 / size**2)')),
    }
    course = make_course(project, tmp_path_factory.mktemp("hostile") / "course", salt="hostile-salt",
                         students=students)
    odd = os.fsencode(course.root / "submitted" / "oddfiles" / ASSIGNMENT)
    os.symlink(os.fsencode(course.root / "submitted" / "ada" / ASSIGNMENT / name), odd + b"/\xff\xfe.ipynb")
    os.mkfifo(odd + b"/bad\xff")
    with open(odd + b"/notes\xff.txt", "wb") as handle:
        handle.write(b"my notes")
    results = course.grade(workers=2)
    return course, results


def _graded_ids(course):
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gb:
        return sorted(student.id for student in gb.students)


@pytest.mark.slow
def test_the_run_finishes_and_honest_students_get_full_marks(hostile):
    course, results = hostile
    assert all(r.ok for r in results), [(r.student, r.log[-500:]) for r in results if not r.ok]
    assert sorted(r.student for r in results) == ["ada", "bea", "escaper", "importer", "oddfiles"]
    grades = cell_grades_graded(course)
    assert grades == {"ada": pytest.approx(FULL), "bea": pytest.approx(FULL), "oddfiles": pytest.approx(FULL),
                      "escaper": pytest.approx(KERNEL_ZERO), "importer": pytest.approx(KERNEL_ZERO)}
    # nbgrader never saw the refused ids
    assert _graded_ids(course) == ["ada", "bea", "escaper", "importer", "oddfiles"]
    assert sorted(course.scores(ASSIGNMENT)) == ["ada", "bea", "escaper", "importer", "oddfiles"]


@pytest.mark.slow
def test_refused_files_are_flagged_with_printable_names(hostile):
    course, _ = hostile
    flags = [f for e in course.scores(ASSIGNMENT)["oddfiles"] for f in e.flags]
    assert sorted(flags) == ["\\xff\\xfe.ipynb: a symbolic link (refused, not followed)",
                             "bad\\xff: not a regular file (refused)",
                             "notes\\xff.txt: a file whose name is not valid UTF-8 (refused)"]


@pytest.mark.slow
def test_the_table_is_printable_and_lists_refused_ids_as_not_graded(hostile):
    course, _ = hostile
    table = course.table(ASSIGNMENT)
    assert not unsafe(table.replace("\n", ""))
    assert table.splitlines()[0].split() == ["exercise", "ada", "bea", "escaper", "importer", "oddfiles"]
    assert "  st\\xffudent: not graded: the student folder 'st\\xffudent' is not valid UTF-8" in table
    assert "  ada\\u200b: not graded: the student id 'ada\\u200b' looks like student 'ada'" in table
    assert "  ｂea: not graded: the student id 'ｂea' looks like student 'bea'" in table
    assert "  mal\\x1b]0;pwned\\x07: not graded: the student folder 'mal\\x1b]0;pwned\\x07' holds control" in table
    assert "\n  escaper · mean_kernel: raised ValueError: \\x1b[2J\\x1b[3Jcleared\n" in table
    assert "\n  importer · mean_kernel: raised ImportError: os\\x1b[2J is not allowed in graded code" in table


@pytest.mark.slow
def test_the_exports_are_printable_and_say_not_graded(hostile):
    course, _ = hostile
    for name in ("grades.csv", "exercises.csv"):
        data = (course.root / "exports" / name).read_bytes()
        text = data.decode("utf-8")  # valid UTF-8: no byte of a student's name passes through raw
        assert b"\x1b" not in data and not unsafe(text), name
    rows = list(csv.DictReader((course.root / "exports" / "exercises.csv").open(encoding="utf-8")))
    by_student = {}
    for row in rows:
        by_student.setdefault(row["student"], []).append(row)
    for shown, why in (("st\\xffudent", "is not valid UTF-8"), ("ada\\u200b", "looks like student 'ada'"),
                       ("ｂea", "looks like student 'bea'"), ("mal\\x1b]0;pwned\\x07", "holds control characters")):
        [row] = by_student[shown]  # one row, never a score
        assert row["exercise"] == "(submission)" and row["score"] == "" and row["status"] == "not graded"
        assert why in row["problems"], row
    assert "\\x1b[2J\\x1b[3Jcleared" in " ".join(r["problems"] for r in by_student["escaper"])
    assert {r["score"] for r in by_student["ada"]} == {"3"}
    grades = {r["student_id"]: r for r in csv.DictReader((course.root / "exports" / "grades.csv").open(encoding="utf-8"))}
    assert grades["ada"]["status"] == "graded" and grades["oddfiles"]["status"] == "graded"
    assert grades["st\\xffudent"]["status"].startswith("not graded: the student folder 'st\\xffudent'")
    assert grades["st\\xffudent"]["score"] == "" and grades["ada\\u200b"]["score"] == ""
    assert "looks like student 'ada'" in grades["ada\\u200b"]["status"]


@pytest.mark.slow
def test_every_later_run_of_cvkit_course_grade_prints_safely(hostile):
    from cvkit.cli import main

    course, _ = hostile
    printed = io.StringIO()
    with redirect_stdout(printed):
        status = main(["course", "grade", "--course-dir", str(course.root), "--workers", "2"])
    out = printed.getvalue()
    assert status == 0, out[-3000:]
    assert not unsafe(out.replace("\n", "")) and "\x1b" not in out
    assert "autograded 0 submissions" in out
    assert "  ada\\u200b: not graded: the student id 'ada\\u200b' looks like student 'ada'" in out
    assert "\nsimilar answers: " in out
    assert cell_grades_graded(course)["ada"] == pytest.approx(FULL)
