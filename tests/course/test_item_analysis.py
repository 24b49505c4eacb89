"""The item analysis of a graded course, end to end: a tiny course (tests/course/test_course_scaling.py's
chapter, three students) is graded; ``exports/item_analysis.csv`` and ``.html`` must appear with
the figures the gradebook implies, the named mistakes, the case failure rates and the warnings
for a class this small; ``cvkit course stats`` prints the summary; Chromium opens the page
offline (plots load, every image has an alt text, no script, readable contrast)."""
from __future__ import annotations

import csv
import re

import pytest
from browser_helpers import contrast, offline_page
from course_helpers import cell_grades
from test_course_scaling import ASSIGNMENT, STUDENTS, make_course
from test_course_scaling import project  # noqa: F401  (the tiny chapter's project, a fixture)

from cvkit.course import item_analysis

pytestmark = pytest.mark.slow
MISTAKE = "not normalised (all ones)"  # bob's and cyd's mean kernel (tests/course/test_course_scaling.py)


@pytest.fixture(scope="module")
def graded(project, tmp_path_factory):  # noqa: F811
    course = make_course(project, tmp_path_factory.mktemp("items") / "course")
    results = course.grade(workers=2)
    assert all(r.ok for r in results), [r.log for r in results if not r.ok]
    return course


def _rows(course):
    with (course.root / "exports" / item_analysis.CSV_NAME).open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _find(rows, exercise, measure, name=None):
    found = [r for r in rows if r["assignment"] == ASSIGNMENT and r["exercise"] == exercise and r["measure"] == measure
             and (name is None or r["name"] == name)]
    assert len(found) == 1, (exercise, measure, name, found)
    return found[0]


def test_grading_writes_the_item_analysis_with_the_gradebooks_figures(graded):
    rows = _rows(graded)
    assert (graded.root / "exports" / item_analysis.HTML_NAME).is_file()
    assert _find(rows, "", "students")["value"] == str(len(STUDENTS))
    grades = cell_grades(graded)  # nbgrader's gradebook, read directly
    for exercise in ("mean_kernel", "temporal_mean"):
        points = [grades[s].get(f"{exercise}_visible", 0) + grades[s].get(f"{exercise}_hidden", 0) for s in STUDENTS]
        facility = sum(points) / (3.0 * len(points))
        assert float(_find(rows, exercise, "facility")["value"]) == pytest.approx(facility, abs=1e-4)
        assert float(_find(rows, exercise, "max_score")["value"]) == 3.0
        # three students: no correlation, discrimination nor α — a note, never a number
        assert _find(rows, exercise, "item_rest_correlation")["value"] == ""
        assert _find(rows, exercise, "upper_lower_discrimination")["value"] == ""
    assert _find(rows, "", "cronbach_alpha")["value"] == ""
    assert any(r["measure"] == "warning" and "too few" in r["note"] for r in rows)
    mistake = _find(rows, "mean_kernel", "mistake", MISTAKE)
    assert (mistake["count"], mistake["of"]) == ("2", "3")
    blank = _find(rows, "temporal_mean", "not_attempted")
    assert (blank["count"], blank["of"]) == ("1", "3")  # cyd's raises NotImplementedError
    # every temporal_mean case: ada and bob pass it, cyd fails it
    cases = [r for r in rows if r["exercise"] == "temporal_mean" and r["measure"] == "case_failure_rate"]
    assert cases and all(r["count"] == "1" and r["of"] == "3" for r in cases)
    # mean_kernel's "size 1" case is the one an all-ones kernel passes
    size_one = _find(rows, "mean_kernel", "case_failure_rate", "size 1")
    assert size_one["count"] == "0"


def test_page_has_plots_with_alt_texts_and_no_script(graded):
    page = (graded.root / "exports" / item_analysis.HTML_NAME).read_text(encoding="utf-8")
    images = re.findall(r"<img src=\"data:image/png;base64,[A-Za-z0-9+/=]+\" alt=\"([^\"]+)\">", page)
    assert len(images) >= 2 and all(len(alt) > 20 for alt in images)
    assert any(MISTAKE in alt for alt in images)  # the mistakes' bars say what they show
    assert "<script" not in page.lower() and "Content-Security-Policy" in page
    assert "Cronbach" in page and "pointbiserialr" in page and "Kelley" in page


def test_stats_command_prints_a_summary_and_writes_the_files(graded, capsys):
    from cvkit.cli import main

    (graded.root / "exports" / item_analysis.CSV_NAME).unlink()
    assert main(["course", "stats", "--course-dir", str(graded.root)]) == 0
    out = capsys.readouterr().out
    assert f"item analysis {ASSIGNMENT}: 3 students" in out
    assert f"most frequent mistake: “{MISTAKE}” in mean_kernel (67% of the class)" in out
    assert "too few" in out
    assert (graded.root / "exports" / item_analysis.CSV_NAME).is_file()


def test_an_assignment_nobody_submitted_gets_a_line(graded):
    results = item_analysis.analyse_course(graded, ["ch98_nobody"])
    assert results[0].exercises == [] and results[0].warnings == ["ch98_nobody: no graded submission — nothing to analyse"]
    assert item_analysis.summary(results) == ["item analysis ch98_nobody: ch98_nobody: no graded submission — nothing "
                                              "to analyse"]


def test_an_empty_course_writes_a_page_saying_so(tmp_path):
    page = item_analysis.write_html([], tmp_path / "exports" / item_analysis.HTML_NAME)
    assert "No assignment to analyse" in page.read_text(encoding="utf-8")
    assert item_analysis.write_csv([], tmp_path / "exports" / item_analysis.CSV_NAME).read_text().strip() == \
        ",".join(item_analysis.CSV_COLUMNS)




def test_page_in_a_browser_offline(graded):
    """Chromium opens the page from disk with every non-file request refused: the plots load,
    nothing tries to reach the network, and every text keeps a WCAG AA contrast (4.5:1)."""
    page_path = graded.root / "exports" / item_analysis.HTML_NAME
    with offline_page(page_path) as (page, remote, dialogs):
        assert page.locator("h1").inner_text() == "Item analysis"
        images = page.locator("figure img")
        assert images.count() >= 2
        assert page.evaluate("() => [...document.querySelectorAll('img')]"
                             ".every(img => img.complete && img.naturalWidth > 100 && img.alt.length > 20)")
        assert page.locator("script").count() == 0
        assert page.locator(".warning").count() >= 1
        assert MISTAKE in page.locator("table").nth(1).inner_text()
        for selector in ("h1", "h2", "p", "td", "th", "figcaption", ".warning", "summary", "dd"):
            for i in range(min(page.locator(selector).count(), 8)):
                ratio = contrast(page, page.locator(selector).nth(i))
                assert ratio >= 4.5, (selector, i, ratio)
        assert not remote and not dialogs, (remote, dialogs)


def test_class_notes_are_off_by_default_and_written_when_asked(graded):
    from cvkit.course.class_notes import Settings, annotate_feedback

    pages = {s: graded.root / "feedback" / s / ASSIGNMENT / f"{ASSIGNMENT}.html" for s in STUDENTS}
    assert all(p.is_file() and "cvkit-class-note" not in p.read_text(encoding="utf-8") for p in pages.values())
    assert annotate_feedback(graded) == []  # the plan has no [class_notes]: nothing said, nothing written
    # three students are fewer than the default minimum: no note, and the line says why
    lines = annotate_feedback(graded, chosen=Settings(True))
    assert lines and "none (class of 3" in lines[0]
    assert all("cvkit-class-note" not in p.read_text(encoding="utf-8") for p in pages.values())
    try:
        # a minimum of 3 (below the floor a plan may set; here only to see the notes on a tiny class)
        annotate_feedback(graded, chosen=Settings(True, 3))
        for student in ("bob", "cyd"):  # both named "not normalised": 2 of 3
            text = pages[student].read_text(encoding="utf-8")
            assert re.findall(r"<p class=\"cvkit-class-note\">([^<]*)</p>", text) == [
                "66 % of the class made this mistake too."] * 2  # visible and hidden report
        assert "cvkit-class-note" not in pages["ada"].read_text(encoding="utf-8")
    finally:
        annotate_feedback(graded, chosen=Settings(False))
    assert all("cvkit-class-note" not in p.read_text(encoding="utf-8") for p in pages.values())


def test_stats_on_a_course_nobody_handed_in_to(project, tmp_path, capsys):  # noqa: F811
    from cvkit.cli import main
    from cvkit.course import Course

    course = Course(tmp_path / "course", project=project)
    course.build([ASSIGNMENT])
    assert main(["course", "stats", "--course-dir", str(course.root)]) == 0
    out = capsys.readouterr().out
    assert f"item analysis {ASSIGNMENT}: {ASSIGNMENT}: no graded submission — nothing to analyse" in out
    page = (course.root / "exports" / item_analysis.HTML_NAME).read_text(encoding="utf-8")
    assert "no graded submission" in page and "<img" not in page
