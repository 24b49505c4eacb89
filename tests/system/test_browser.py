"""The student and the instructor experience, in a real browser.

Playwright drives headless Chromium — Debian's ``chromium`` package, installed here with
apt-get when it is missing (no browser download) — against a JupyterLab server started by the
test on loopback:

- **Student:** the released Chapter 3 notebook is opened in JupyterLab and run twice, once
  with correct answers and once with a typical mistake in the median filter. The rendered
  report must say PASSED / FAILED in words, name the mistake, and show the student /
  expected / difference images with alt text; in JupyterLab's dark theme its text must keep
  a WCAG AA contrast with the background.
- **Instructor:** nbgrader's formgrader, served by the same kind of server in the course
  folder, lists the three autograded sample submissions with the scores in the gradebook.

Screenshots are saved in ``artefacts/browser/`` (or ``$CVKIT_ARTEFACTS``) for a human to look at.
"""
from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest
from browser_helpers import contrast

from cvkit.course import Course, solution_sources, typical_mistakes

pytestmark = pytest.mark.slow
sync_api = pytest.importorskip("playwright.sync_api", reason="the test extra installs playwright")

ROOT = Path(__file__).resolve().parents[2]
ARTEFACTS = Path(os.environ.get("CVKIT_ARTEFACTS", ROOT / "artefacts")) / "browser"
CHAPTER = "ch03_filtering"
EXERCISE = "median_answer"            # replaced by a typical mistake in the wrong notebook
ALGORITHM = "filters.median"
CHROMIUM_FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage"]


# ---------------------------------------------------------------------------- the browser
def _chromium() -> str | None:
    for candidate in (shutil.which("chromium"), "/usr/bin/chromium"):
        if candidate and Path(candidate).exists():
            return candidate
    return None


@pytest.fixture(scope="module")
def chromium_path():
    """Debian's Chromium; installed with apt-get on a fresh machine (as root)."""
    path = _chromium()
    if path is None and shutil.which("apt-get") and os.geteuid() == 0:
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        command = ["apt-get", "-o", "DPkg::Lock::Timeout=900", "install", "-y", "-q", "--no-install-recommends", "chromium"]
        done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=900)
        if done.returncode != 0:  # stale package lists: refresh them once
            subprocess.run(["apt-get", "-o", "DPkg::Lock::Timeout=900", "update", "-q"], capture_output=True, env=env, timeout=600)
            done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=900)
        path = _chromium()
        assert path, f"apt-get could not install chromium:\n{done.stdout[-1500:]}\n{done.stderr[-1500:]}"
    if path is None:
        pytest.skip("Debian's chromium is not installed and apt-get needs root to install it")
    return path


@pytest.fixture(scope="module")
def browser(chromium_path):
    with sync_api.sync_playwright() as playwright:
        instance = playwright.chromium.launch(executable_path=chromium_path, headless=True, args=CHROMIUM_FLAGS)
        yield instance
        instance.close()


# ---------------------------------------------------------------------------- JupyterLab
def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@contextlib.contextmanager
def jupyter_lab(folder: Path, env: dict | None = None, theme: str = "JupyterLab Light"):
    """A JupyterLab server on loopback serving ``folder``; yields (base URL, token)."""
    port, token = _free_port(), secrets.token_hex(16)
    settings = folder.parent / f".lab-settings-{port}"
    theme_file = settings / "@jupyterlab" / "apputils-extension" / "themes.jupyterlab-settings"
    theme_file.parent.mkdir(parents=True)
    theme_file.write_text(json.dumps({"theme": theme}))
    notices = settings / "@jupyterlab" / "apputils-extension" / "notification.jupyterlab-settings"
    notices.write_text(json.dumps({"fetchNews": "false", "checkForUpdates": False}))
    environment = dict(env or os.environ)
    environment.update(JUPYTERLAB_SETTINGS_DIR=str(settings), JUPYTER_RUNTIME_DIR=str(settings / "runtime"),
                       MPLBACKEND="module://matplotlib_inline.backend_inline")
    environment.pop("CVKIT_TRUSTED_GRADING", None)
    environment["PATH"] = str(Path(sys.executable).parent) + os.pathsep + environment.get("PATH", "")
    log = open(folder.parent / f"jupyterlab-{port}.log", "w")
    server = subprocess.Popen(
        [sys.executable, "-m", "jupyter", "lab", "--no-browser", f"--ServerApp.port={port}",
         "--ServerApp.ip=127.0.0.1", f"--IdentityProvider.token={token}", f"--ServerApp.root_dir={folder}",
         "--allow-root", "--LabApp.expose_app_in_browser=True", "--ServerApp.disable_check_xsrf=False"],
        cwd=folder, env=environment, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                with urllib.request.urlopen(f"{url}/api/status?token={token}", timeout=2) as reply:
                    if reply.status == 200:
                        break
            except OSError:
                pass
            assert server.poll() is None, (folder.parent / f"jupyterlab-{port}.log").read_text()[-3000:]
            assert time.monotonic() < deadline, "JupyterLab did not start within 120 s"
            time.sleep(0.5)
        yield url, token
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
        log.close()


def _run_notebook(browser, url: str, token: str, name: str, shot: str, timeout_s: float = 240):
    """Open ``name`` in JupyterLab, run every cell from the Run menu and wait until the run is
    over (every code cell executed, or JupyterLab stopped at a cell that raised, as it does
    for a failing visible test); returns the page, left open for assertions."""
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    page.set_default_timeout(60_000)
    page.goto(f"{url}/lab/workspaces/{shot}/tree/{name}?reset&token={token}")  # a fresh workspace each
    page.locator(".jp-Notebook").first.wait_for()
    _wait_for_kernel(page, "idle", 90)
    deadline = time.monotonic() + timeout_s
    for attempt in range(3):  # the menu acts on the focused notebook: focus it, run, see it start
        page.locator(".jp-Notebook .jp-Cell").first.click()
        page.locator(".lm-MenuBar-itemLabel", has_text=re.compile(r"^Run$")).click()
        page.locator(".lm-Menu-itemLabel", has_text=re.compile(r"^Run All Cells$")).click()
        started = time.monotonic()
        while time.monotonic() - started < 20:
            state = page.evaluate(_RUN_STATE)
            if state["started"] or state["kernel"] == "busy":
                break
            time.sleep(0.5)
        else:
            page.screenshot(path=str(ARTEFACTS / f"{shot}-not-started-{attempt}.png"))
            continue
        break
    while True:
        state = page.evaluate(_RUN_STATE)
        if state["started"] and state["pending"] == 0 and state["kernel"] == "idle":
            break
        assert time.monotonic() < deadline, f"{name}: the run is not over after {timeout_s} s ({state})"
        time.sleep(1.0)
    page.screenshot(path=str(ARTEFACTS / f"{shot}-page.png"), full_page=False)
    return page


def _retry(what: str, page, shot: str, action, ready, attempts: int = 3):
    """Do ``action`` until ``ready`` succeeds (a slow first page load on a loaded machine must
    not fail the test); on the last failure save a screenshot and say which step it was."""
    for attempt in range(attempts):
        try:
            action()
            ready()
            return
        except sync_api.TimeoutError:
            page.screenshot(path=str(ARTEFACTS / f"{shot}-timeout-{attempt}.png"), full_page=True)
    pytest.fail(f"{what} did not appear after {attempts} attempts (screenshots: {shot}-timeout-*.png)")


# code cells still waiting to run: not executed yet, and not after a cell that raised
_RUN_STATE = """() => {
    const panel = window.jupyterapp.shell.currentWidget;
    const cells = panel.content.widgets.filter(c => c.model.type === 'code' && c.model.sharedModel.getSource().trim());
    let failed = false, pending = 0, started = 0;
    for (const cell of cells) {
        const count = cell.model.executionCount;
        const running = cell.promptNode && cell.promptNode.textContent.includes('*');
        if (count !== null && !running) {
            started += 1;
            if (cell.model.outputs.toJSON().some(o => o.output_type === 'error')) failed = true;
        } else if (!failed) {
            pending += 1;
        }
    }
    const kernel = panel.sessionContext.session && panel.sessionContext.session.kernel;
    return {cells: cells.length, started, pending, kernel: kernel ? kernel.status : null};
}"""


def _wait_for_kernel(page, status: str, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        current = page.evaluate("""() => {
            const app = window.jupyterapp;
            const widget = app && app.shell.currentWidget;
            const kernel = widget && widget.sessionContext && widget.sessionContext.session
                && widget.sessionContext.session.kernel;
            return kernel ? kernel.status : null;
        }""")
        if current == status:
            return
        time.sleep(0.5)
    raise AssertionError(f"kernel not {status} after {seconds} s")


def _report(page, algorithm: str):
    """The rendered report of the visible test of ``algorithm``."""
    report = page.locator(f"section.cvkit-report[aria-label^='{algorithm} ']").first
    report.scroll_into_view_if_needed()
    return report


# ---------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def course(tmp_path_factory):
    """Chapter 3 released, the three samples submitted and autograded (2 workers)."""
    ARTEFACTS.mkdir(parents=True, exist_ok=True)
    course = Course(tmp_path_factory.mktemp("browser") / "course")
    course.build([CHAPTER])
    course.make_samples(CHAPTER)
    results = course.grade([CHAPTER], workers=2)
    assert all(r.ok for r in results), [r.log[-800:] for r in results if not r.ok]
    return course


@pytest.fixture(scope="module")
def student_folder(course, tmp_path_factory):
    """A student's folder: the release notebook answered correctly, and with one mistake."""
    folder = tmp_path_factory.mktemp("student") / "work"
    folder.mkdir()
    release = json.loads((course.root / "release" / CHAPTER / f"{CHAPTER}.ipynb").read_text())
    solutions = solution_sources(json.loads((ROOT / "lectures" / CHAPTER / f"{CHAPTER}.ipynb").read_text()))
    mistake = typical_mistakes(ROOT / "autograders" / "samples" / CHAPTER)[EXERCISE]
    for name, replaced in (("correct.ipynb", {}), ("wrong.ipynb", {EXERCISE: mistake})):
        nb = json.loads(json.dumps(release))
        for cell in nb["cells"]:
            meta = cell.get("metadata", {}).get("nbgrader", {})
            if meta.get("solution") and meta.get("grade_id") in solutions:
                cell["source"] = replaced.get(meta["grade_id"], solutions[meta["grade_id"]])
        (folder / name).write_text(json.dumps(nb))
    (folder / "blank.ipynb").write_text(json.dumps(release))  # the release as a student fetches it
    return folder


@pytest.fixture(scope="module")
def lab(student_folder):
    """One JupyterLab server on the student's folder, in the light theme, for every student test."""
    with jupyter_lab(student_folder) as server:
        yield server


@pytest.fixture(scope="module")
def wrong_run(browser, lab):
    """``wrong.ipynb`` run once in JupyterLab; its page stays open for the light-theme checks and
    then the dark-theme ones (the theme is switched on the rendered page, as a student does)."""
    url, token = lab
    page = _run_notebook(browser, url, token, "wrong.ipynb", "wrong")
    yield page
    page.close()


def _expected_mistake() -> str:
    """The mistake the engine names for the wrong median (computed in this process)."""
    import numpy as np

    from cvkit import filters
    from cvkit.grading import evaluate

    namespace = {"np": np, "pad": filters.pad, "student": lambda algorithm_id: (lambda f: f)}
    exec(typical_mistakes(ROOT / "autograders" / "samples" / CHAPTER)[EXERCISE], namespace)
    report = evaluate(ALGORITHM, namespace["median"])
    assert report.mistake, "the sample's median mistake should be recognised by the check"
    return report.mistake


def _contrast(page, locator) -> float:
    """WCAG contrast ratio of an element's text colour with the background it sits on."""
    return contrast(page, locator)


# ---------------------------------------------------------------------------- tests
def test_student_sees_passing_and_failing_reports(browser, lab, wrong_run):
    mistake = _expected_mistake()
    url, token = lab
    page = _run_notebook(browser, url, token, "correct.ipynb", "correct")
    passed = _report(page, ALGORITHM)
    assert "cvkit-passed" in passed.get_attribute("class")
    assert "passed" in passed.locator(".cvkit-summary").text_content()
    assert page.locator("section.cvkit-report.cvkit-failed").count() == 0, "a correct notebook shows no failure"
    assert page.locator("section.cvkit-report").count() >= 10
    passed.screenshot(path=str(ARTEFACTS / "correct-report.png"))
    page.close()

    page = wrong_run
    failed = _report(page, ALGORITHM)
    assert "cvkit-failed" in failed.get_attribute("class")
    summary = failed.locator(".cvkit-summary").text_content()
    assert "FAILED" in summary and ALGORITHM in summary
    assert mistake in failed.locator(".cvkit-mistake").text_content()
    failed.scroll_into_view_if_needed()
    page.wait_for_timeout(500)
    images = failed.locator(".cvkit-images img")
    assert images.count() == 3
    for index, start in enumerate(("Your output", "Expected output", "Absolute difference")):
        assert images.nth(index).get_attribute("alt").startswith(start)
        box = images.nth(index).bounding_box()
        assert box and box["width"] >= 32 and box["height"] >= 32, "the image is not drawn"
    captions = failed.locator("figcaption").all_text_contents()
    assert captions[:2] == ["yours", "expected"] and captions[2].startswith("|difference|")
    # the failing visible test stops the run there (an AssertionError, as in any notebook);
    # every exercise before it passed: the mistake is reported where it is
    failing = [page.locator("section.cvkit-report.cvkit-failed").nth(i).get_attribute("aria-label")
               for i in range(page.locator("section.cvkit-report.cvkit-failed").count())]
    assert failing and all(label.startswith(ALGORITHM) for label in failing), failing
    assert page.locator("section.cvkit-report.cvkit-passed").count() >= 5
    assert "AssertionError" in page.locator(".jp-RenderedText[data-mime-type='application/vnd.jupyter.stderr']").last.text_content()
    failed.screenshot(path=str(ARTEFACTS / "wrong-report.png"))


_EXECUTED = """() => {
    const panel = window.jupyterapp.shell.currentWidget;
    const cells = panel.content.widgets.filter(c => c.model.type === 'code' && c.model.sharedModel.getSource().trim());
    const unexecuted = [], errors = [];
    cells.forEach((cell, i) => {
        if (cell.model.executionCount === null) unexecuted.push(i);
        for (const o of cell.model.outputs.toJSON()) {
            if (o.output_type === 'error') errors.push({index: i, ename: o.ename, evalue: o.evalue,
                tags: cell.model.getMetadata('tags') || []});
        }
    });
    return {cells: cells.length, unexecuted, errors};
}"""


def test_run_all_on_the_release_reaches_the_end_in_jupyterlab(browser, lab):
    """JupyterLab's own *Run All* on the released notebook, nothing answered yet: every code cell
    runs (the raises-exception tag lets the run go past an unanswered exercise's test), and the
    only errors are those tests' one-line "not answered yet"."""
    url, token = lab
    page = _run_notebook(browser, url, token, "blank.ipynb", "release-run-all")
    state = page.evaluate(_EXECUTED)
    deadline = time.monotonic() + 240  # the run helper stops watching at the first error: wait for the rest
    while state["unexecuted"] and time.monotonic() < deadline:
        time.sleep(1.0)
        state = page.evaluate(_EXECUTED)
    page.screenshot(path=str(ARTEFACTS / "release-run-all-end.png"))
    page.close()
    assert state["cells"] > 20 and state["unexecuted"] == [], state["unexecuted"]
    assert state["errors"], "the unanswered exercises' visible tests fail"
    for error in state["errors"]:
        assert "raises-exception" in error["tags"], error
        assert error["ename"] == "CheckFailed" and "not answered yet" in error["evalue"], error


_BACKGROUND = "() => getComputedStyle(document.querySelector('.jp-Notebook')).backgroundColor"


def _mean_channel(css_colour: str) -> float:
    channels = [float(v) for v in css_colour[css_colour.index("(") + 1:-1].split(",")[:3]]
    return sum(channels) / 3


def test_report_is_readable_in_the_dark_theme(wrong_run):
    """The rendered report of the wrong run, after switching JupyterLab to its dark theme (its
    colours follow the theme's variables: nothing is run again)."""
    page = wrong_run
    page.evaluate("() => window.jupyterapp.commands.execute('apputils:change-theme', {theme: 'JupyterLab Dark'})")
    deadline = time.monotonic() + 60
    while _mean_channel(page.evaluate(_BACKGROUND)) >= 80 and time.monotonic() < deadline:
        time.sleep(0.5)
    background = page.evaluate(_BACKGROUND)
    assert _mean_channel(background) < 80, f"the dark theme is not active (background {background})"
    failed = _report(page, ALGORITHM)
    for part in (".cvkit-summary", ".cvkit-mistake", "table.cvkit-cases td", "pre.cvkit-message",
                 "figcaption"):
        element = failed.locator(part).first
        ratio = _contrast(page, element)
        assert ratio >= 4.5, f"{part}: contrast {ratio:.2f} with the dark background is below WCAG AA (4.5)"
    # the exercises before the failing one passed: their reports are the passed style
    passed = page.locator("section.cvkit-report.cvkit-passed")
    assert passed.count() >= 5
    assert _contrast(page, passed.first.locator(".cvkit-summary")) >= 4.5
    failed.screenshot(path=str(ARTEFACTS / "dark-wrong-report.png"))


def test_formgrader_lists_the_autograded_samples(browser, course):
    from nbgrader.api import Gradebook

    with Gradebook(course.db_url) as gradebook:
        submissions = list(gradebook.assignment_submissions(CHAPTER))
        expected = {s.student.id: (s.score, s.max_score) for s in submissions}
        # written answers wait for the instructor (manual grading in this very formgrader)
        to_mark = {s.student.id: sum(g.max_score for nb in s.notebooks for g in nb.grades if g.needs_manual_grade)
                   for s in submissions}
    assert set(expected) == {"sample_complete", "sample_mistakes", "sample_blank"}
    # (a blank answer is a zero without marking; an open task is always marked by hand)
    assert to_mark["sample_complete"] > to_mark["sample_blank"]
    complete, top = expected["sample_complete"]
    assert complete == top - to_mark["sample_complete"] > expected["sample_mistakes"][0] > 0
    env = course.env()
    with jupyter_lab(course.root, env=env) as (url, token):
        # the formgrader's own API calls carry no token: authenticate every request
        context = browser.new_context(viewport={"width": 1400, "height": 900},
                                      extra_http_headers={"Authorization": f"token {token}"})
        page = context.new_page()
        page.set_default_timeout(60_000)
        rows = page.locator("table tbody tr")
        _retry("the formgrader's submission list", page, "formgrader-submissions",
               lambda: page.goto(f"{url}/formgrader/manage_submissions/{CHAPTER}"),
               lambda: rows.filter(has_text="sample_mistakes").first.wait_for(timeout=30_000))
        for student, (score, max_score) in expected.items():
            row = rows.filter(has_text=student).first
            text = " ".join(row.text_content().split())
            shown = f"{round(score, 2):g} / {round(max_score, 2):g}"  # formgrader rounds to 2 places
            assert shown in text, f"{student}: expected {shown!r} in {text!r}"
        page.screenshot(path=str(ARTEFACTS / "formgrader-submissions.png"), full_page=True)

        # and from inside JupyterLab: the Nbgrader menu opens the formgrader in a tab
        def open_formgrader():
            page.goto(f"{url}/lab?token={token}")
            page.locator(".jp-LabShell").wait_for()
            page.evaluate("() => window.jupyterapp.commands.execute('nbgrader:open-formgrader')")

        frame = page.frame_locator("iframe").first  # the assignment's link in the table (its name is in the
        # page's collapsed "Current configuration" too, where the due-date notice's settings name it)
        _retry("the formgrader inside JupyterLab", page, "formgrader-in-jupyterlab", open_formgrader,
               lambda: frame.get_by_role("link", name=CHAPTER).first.wait_for(timeout=30_000))
        page.screenshot(path=str(ARTEFACTS / "formgrader-in-jupyterlab.png"))
        context.close()
