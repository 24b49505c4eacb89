"""The quick main job (`cvkit demo`) and the progress of long commands, without grading:
which chapters the demo takes, and what each phase prints where nobody watches a terminal.
The whole demo runs in tests/course/test_course.py."""
import io
import json
from pathlib import Path

from cvkit.cli import DEMO_CHAPTERS, _demo_chapters, build_parser
from cvkit.course import Course
from cvkit.course.progress import Phase, progress

ROOT = Path(__file__).resolve().parents[2]


def _args(*argv):
    return build_parser().parse_args(["demo", *argv])


def test_the_quick_demo_takes_a_few_planned_chapters_and_all_takes_every_one():
    course = Course(ROOT / "autograders", project=ROOT)
    planned = course.assignments()
    assert 2 <= len(DEMO_CHAPTERS) <= 3 and set(DEMO_CHAPTERS) <= set(planned)
    assert _demo_chapters(_args(), course) == list(DEMO_CHAPTERS)
    assert _demo_chapters(_args("--all"), course) == planned
    assert _demo_chapters(_args("--assignment", "ch01_introduction"), course) == ["ch01_introduction"]


def test_the_quick_demo_shows_autograded_exercises_written_questions_and_named_mistakes():
    from cvkit.course import typical_mistakes

    for chapter in DEMO_CHAPTERS:
        cells = [c for p in (ROOT / "lectures" / chapter).glob("*.ipynb") for c in json.loads(p.read_text())["cells"]]
        kinds = {c["cell_type"] for c in cells if c.get("metadata", {}).get("nbgrader", {}).get("solution")}
        assert kinds == {"code", "markdown"}, chapter  # exercises and written answers
        assert typical_mistakes(ROOT / "autograders" / "samples" / chapter), chapter


def test_a_phase_prints_one_line_when_nobody_watches_a_terminal():
    out = io.StringIO()
    with Phase("feedback", 4, unit="page", stream=out) as phase:
        phase.update(3)
        phase.set_total(3)  # an estimate made exact
        phase.describe("feedback ch03")  # terminal only
    lines = out.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith("feedback: 3/3 pages in ") and lines[0].endswith(" s")
    quiet = io.StringIO()
    with Phase("feedback", 4, enabled=False, stream=quiet) as phase:
        phase.update(4)
    assert quiet.getvalue() == ""


def test_progress_iterates_as_one_phase(capsys):
    assert list(progress(iter("abc"), "samples", True, unit="chapter")) == ["a", "b", "c"]
    out, err = capsys.readouterr()
    assert out.startswith("samples: 3/3 chapters in ") and err == ""
