"""A course is a folder of its own (issue 34, item 1), outside the checkout, run as an
instructor would over a semester with the command line and the formgrader:

``cvkit new course`` (one of cvkit's chapters, copied) → the instructor's own chapter in its
``source/`` with a written question, due date and late policy in its ``plan.toml`` → ``cvkit
course build`` and ``cvkit course grade`` run from inside the folder (no ``--course-dir``) →
plain ``nbgrader`` there sees this course only → the formgrader (JupyterLab on the folder, in
Chromium) lists the plan's assignments with their due dates, and the instructor marks a written
answer in it by typing the score and a comment → ``cvkit course refresh`` → a regrade of
everything → the exports. The mark survives, the page shows it, and the checkout and the
installed package are byte for byte what they were. Bad input is refused with what to do.
"""
from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
import test_written_answers as written

import test_course_scaling as tiny
from cvkit.course import Course

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
KIT_CHAPTER = "ch01_introduction"
COMMENT = "Right; say what happens at the border."


def _fingerprint() -> dict[str, str]:
    """Every file of the checkout that a course could touch (its configuration, plan, chapters and
    the installed package's source), by content; and whether autograders/ holds a gradebook."""
    found = {}
    for part in ("autograders", "lectures", "cvkit"):
        for path in sorted((ROOT / part).rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts and path.suffix != ".pyc":
                found[str(path.relative_to(ROOT))] = hashlib.sha256(path.read_bytes()).hexdigest()
    return found


def cvkit(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("CVKIT_") or k == "CVKIT_ARTEFACTS"}
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    return subprocess.run([str(BIN / "cvkit"), *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=900)


def nbgrader(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("CVKIT_")}
    return subprocess.run([sys.executable, "-m", "nbgrader", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


@pytest.fixture(scope="module")
def semester(tmp_path_factory):
    before = _fingerprint()
    place = tmp_path_factory.mktemp("courses")
    folder = place / "ipcv-2027"
    seen: dict = {"new": cvkit("new", "course", str(folder), "--chapter", KIT_CHAPTER, "--course-id", "ipcv-2027",
                               cwd=place)}
    # the instructor's own chapter: a tiny one with two exercises, a written question and an open task
    own = folder / "source" / tiny.ASSIGNMENT
    own.mkdir(parents=True)
    (own / f"{tiny.ASSIGNMENT}.ipynb").write_text(json.dumps(written._source_notebook()))
    plan = folder / "plan.toml"
    plan.write_text(plan.read_text().replace('[late]\npolicy = "none"', '[late]\npolicy = "per_hour"')
                    + f'\n[[assignment]]\nid = "{tiny.ASSIGNMENT}"\ndue = "2031-01-15 23:59:00 UTC"\n')
    seen["build"] = cvkit("course", "build", cwd=folder)
    course = Course(folder)
    release = json.loads(course.release_notebooks(tiny.ASSIGNMENT)[0].read_text())
    answered = json.loads(json.dumps(release))
    solutions = {"mean_kernel_answer": tiny.KERNEL, "temporal_mean_answer": tiny.TEMPORAL,
                 "question_99_1": "It keeps the level of a flat image."}
    for cell in answered["cells"]:
        grade_id = cell["metadata"].get("nbgrader", {}).get("grade_id")
        if grade_id in solutions:
            cell["source"] = re.sub(r" *### (BEGIN|END) SOLUTION\n?", "", solutions[grade_id])
    course.submit("ada", tiny.ASSIGNMENT, {f"{tiny.ASSIGNMENT}.ipynb": answered})
    course.submit("bob", tiny.ASSIGNMENT, {f"{tiny.ASSIGNMENT}.ipynb": release})
    seen["grade"] = cvkit("course", "grade", "--workers", "2", cwd=folder)
    seen["nbgrader list"] = nbgrader("db", "assignment", "list", cwd=folder)
    seen["marked in the formgrader"] = _mark_in_the_formgrader(course, place)
    seen["refresh"] = cvkit("course", "refresh", cwd=folder)
    seen["page"] = next((folder / "feedback" / "ada" / tiny.ASSIGNMENT).glob("*.html")).read_text()
    seen["regrade"] = cvkit("course", "grade", "--regrade", "all", cwd=folder)
    seen["grades.csv"] = list(csv.DictReader((folder / "exports" / "grades.csv").open()))
    seen["exercises.csv"] = list(csv.DictReader((folder / "exports" / "exercises.csv").open()))
    seen["unchanged"] = before == _fingerprint()
    return {"folder": folder, "course": course, "seen": seen}


# the formgrader's own flags: its grade and comment models fetched and bound to the inputs
# (its ``loaded`` flag stays false here: with no MathJax offline, its init stops half-way)
FORMGRADER_READY = """() => window.formgrader
    && formgrader.grades && formgrader.grades.loaded
    && formgrader.comments && formgrader.comments.loaded"""


def _mark_in_the_formgrader(course: Course, place: Path) -> dict:
    """The formgrader of a JupyterLab started in the course folder, in Chromium: its assignment
    list, then ada's written answer marked by typing the score and the comment."""
    from nbgrader.api import Gradebook

    test_browser = pytest.importorskip("test_browser")
    chromium = test_browser._chromium() or pytest.skip("no Chromium here")
    from playwright.sync_api import sync_playwright

    with Gradebook(course.db_url) as gradebook:
        notebook_id = gradebook.find_submission_notebook(tiny.ASSIGNMENT, tiny.ASSIGNMENT, "ada").id
    env = {k: v for k, v in os.environ.items() if not k.startswith("CVKIT_")}
    done: dict = {}
    with test_browser.jupyter_lab(course.root, env=env) as (url, token), sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium, headless=True, args=test_browser.CHROMIUM_FLAGS)
        context = browser.new_context(viewport={"width": 1400, "height": 1000},
                                      extra_http_headers={"Authorization": f"token {token}"})
        page = context.new_page()
        page.set_default_timeout(60_000)
        reply = page.goto(f"{url}/formgrader/api/assignments")
        done["assignments"] = {a["name"]: a["duedate"] for a in json.loads(reply.text())}
        page.goto(f"{url}/formgrader/submissions/{notebook_id}/?index=0")
        # the inputs are in the page before its script has fetched the grade and comment models
        # and bound them; a field typed into earlier is never saved, as for a grader who types
        # before the page has finished loading
        page.wait_for_function(FORMGRADER_READY)
        score = page.locator("input.score#question_99_1")
        score.fill("1.5")
        score.press("Tab")  # the formgrader saves a field when it loses focus
        comment = page.locator("textarea#question_99_1-comment")
        comment.fill(COMMENT)
        comment.press("Tab")
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            with Gradebook(course.db_url) as gradebook:
                grade = gradebook.find_grade("question_99_1", tiny.ASSIGNMENT, tiny.ASSIGNMENT, "ada")
                text = gradebook.find_comment("question_99_1", tiny.ASSIGNMENT, tiny.ASSIGNMENT, "ada").manual_comment
                done["mark"] = (grade.manual_score, grade.needs_manual_grade, text)
            if done["mark"] == (1.5, False, COMMENT):
                break
            time.sleep(0.3)
        page.screenshot(path=str(test_browser.ARTEFACTS.parent / "course-folder-formgrader-mark.png"), full_page=True)
        browser.close()
    return done


def test_new_course_builds_from_inside_the_folder(semester):
    folder, seen = semester["folder"], semester["seen"]
    assert seen["new"].returncode == 0, seen["new"].stderr
    assert seen["build"].returncode == 0, seen["build"].stdout + seen["build"].stderr
    assert sorted(p.name for p in (folder / "source").iterdir()) == sorted([KIT_CHAPTER, tiny.ASSIGNMENT])
    assert sorted(p.name for p in (folder / "release").iterdir()) == sorted([KIT_CHAPTER, tiny.ASSIGNMENT])
    # the grading rules' page travels with cvkit's chapter as a plain file
    page = folder / "source" / KIT_CHAPTER / "how_this_course_is_graded.md"
    assert page.is_file() and not page.is_symlink()
    assert 'id = "ipcv-2027"' in (folder / "plan.toml").read_text()


def test_plain_nbgrader_in_the_folder_sees_this_course_only(semester):
    folder, seen = semester["folder"], semester["seen"]
    listed = seen["nbgrader list"]
    assert listed.returncode == 0, listed.stderr
    out = listed.stdout + listed.stderr
    assert "There are 2 assignments in the database" in out, out
    assert f"{tiny.ASSIGNMENT} (due: 2031-01-15 23:59:00" in out and f"{KIT_CHAPTER} (due: None)" in out
    assert not (ROOT / "autograders" / "gradebook.db").exists()


def test_graded_marked_in_the_formgrader_refreshed_regraded_and_exported(semester):
    seen = semester["seen"]
    assert seen["grade"].returncode == 0, seen["grade"].stdout[-3000:] + seen["grade"].stderr[-3000:]
    marked = seen["marked in the formgrader"]
    # the formgrader lists the plan's assignments, with the plan's due dates
    assert set(marked["assignments"]) == {KIT_CHAPTER, tiny.ASSIGNMENT}
    assert marked["assignments"][tiny.ASSIGNMENT].startswith("2031-01-15") and marked["assignments"][KIT_CHAPTER] is None
    assert marked["mark"] == (1.5, False, COMMENT)
    assert seen["refresh"].returncode == 0 and f"ada/{tiny.ASSIGNMENT}" in seen["refresh"].stdout, seen["refresh"].stderr
    assert COMMENT in seen["page"]
    assert seen["regrade"].returncode == 0, seen["regrade"].stderr[-3000:]
    ada = {r["exercise"]: r for r in seen["exercises.csv"] if r["student"] == "ada"}
    assert (ada["question_99_1"]["score"], ada["question_99_1"]["status"]) == ("1.5", "graded")
    row = next(r for r in seen["grades.csv"] if r["student_id"] == "ada" and r["assignment"] == tiny.ASSIGNMENT)
    assert float(row["raw_score"]) == pytest.approx(6 + 1.5)  # both exercises right, and the mark


def test_the_checkout_and_the_installed_package_are_unchanged(semester):
    assert semester["seen"]["unchanged"]


def test_bad_course_folders_are_refused_with_what_to_do(semester, tmp_path):
    folder = semester["folder"]
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    done = cvkit("new", "course", str(tmp_path / "busy"), "--chapter", KIT_CHAPTER, cwd=tmp_path)
    assert done.returncode == 2 and "is not empty and not a course folder made by cvkit new course" in done.stderr
    done = cvkit("new", "course", str(ROOT / "autograders" / "mine"), "--chapter", KIT_CHAPTER, cwd=tmp_path)
    assert done.returncode == 2 and "is inside the cvkit checkout" in done.stderr
    assert not (ROOT / "autograders" / "mine").exists()
    done = cvkit("new", "course", str(tmp_path / "c"), "--chapter", "ch42_nothing", cwd=tmp_path)
    assert done.returncode == 2 and "no chapter ch42_nothing in cvkit (chapters: ch01_introduction" in done.stderr
    assert not (tmp_path / "c").exists()
    # adding a chapter to the course: copied, appended to the plan, the rest of the plan untouched
    plan = (folder / "plan.toml").read_text()
    done = cvkit("new", "course", str(folder), "--chapter", "ch02_image_formation", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert (folder / "plan.toml").read_text() == plan + '\n[[assignment]]\nid = "ch02_image_formation"\n'
    assert (folder / "source" / "ch02_image_formation" / "ch02_image_formation.ipynb").is_file()
    # a plan naming a chapter that has no folder, a course folder without a plan
    (folder / "plan.toml").write_text(plan + '\n[[assignment]]\nid = "ch77_gone"\n')
    done = cvkit("course", "build", cwd=folder)
    assert done.returncode == 2 and re.search(r"plan\.toml names ch77_gone, but .*source has no such chapter folder",
                                              done.stderr), done.stderr
    (folder / "plan.toml").unlink()
    done = cvkit("course", "build", cwd=folder)
    assert done.returncode == 2 and "has no plan.toml: write one" in done.stderr, done.stderr
    (folder / "plan.toml").write_text(plan)


def test_two_courses_sharing_a_gradebook_are_refused(semester, tmp_path):
    """A second course given the first one's gradebook by mistake (a --db-url) is refused before
    anything is written; the first course's gradebook is untouched."""
    folder = semester["folder"]
    other = tmp_path / "ipcv-lab"
    assert cvkit("new", "course", str(other), "--chapter", KIT_CHAPTER, cwd=tmp_path).returncode == 0
    shared = f"sqlite:///{folder / 'gradebook.db'}"
    before = (folder / "gradebook.db").read_bytes()
    done = cvkit("course", "build", "--db-url", shared, cwd=other)
    assert done.returncode == 2
    assert (f"holds the course 'ipcv-2027' (course folder {folder}), not 'ipcv-lab' of {other}: two courses must not "
            "share a gradebook") in " ".join(done.stderr.split()), done.stderr
    assert (folder / "gradebook.db").read_bytes() == before and not (other / "release").exists()

