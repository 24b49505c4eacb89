"""A course on JupyterHub, round trip with real components (issue 33, items 4 and 5).

The test installs JupyterHub's proxy the way the browser test installs Chromium (Debian's
``node-configurable-http-proxy`` with apt-get when it is missing, by ``cvkit hub init``'s own
code; JupyterHub itself comes with the suite's ``test`` extra), makes five local Unix accounts (removed afterwards) — an
instructor, the instructor of a second course, three students — runs ``cvkit hub init`` and
starts the hub with ``cvkit hub start`` on 127.0.0.1 (free ports), as root, with
LocalProcessSpawner. Then a semester, each step as the account that does it:

- the instructors build and release a tiny chapter (``cvkit course build``, ``nbgrader
  release_assignment``), each in their own course;
- ada works through the hub's REST API and her own JupyterLab server (started by the hub):
  the Assignments panel's endpoints list her courses and fetch, JupyterLab's contents API
  saves her answers, the panel's endpoint submits and fetches her feedback; bob uses
  ``nbgrader`` as in a JupyterLab terminal (with a token of his, as the terminal has one) and
  sees only his course; cyd logs in to the hub in Chromium with her Unix password and uses
  JupyterLab's Assignments panel (its Fetch, Submit and Fetch Feedback buttons; a terminal
  instead where Playwright or Chromium is missing). bob makes a typical mistake, cyd submits
  after the due date (moved to the past in the course's ``plan.toml`` before she does);
- the instructor collects, grades with ``cvkit course grade`` (sandboxed, as the instructor),
  writes the pages again with plain ``nbgrader generate_feedback`` (as after marking written
  answers in the formgrader, which the test finds serving the course in the instructor's
  JupyterLab) and releases them with ``nbgrader release_feedback``; each student fetches theirs and
  sees their own score, the mistake named, the late penalty — nothing of anyone else's;
- bob submits again after the collection: the next ``cvkit course grade`` says to collect it;
  his new hand-in lacks ``submission_secret.txt`` (as from nbgrader < 0.9.3): the grade run
  says that plain ``release_feedback`` stops at it and gives the command that releases
  everyone else's, which works; the other grades are untouched.

Also: the exchange's and the course folder's permissions as nbgrader and privacy need them,
what students cannot read or list, and clear messages for a broken exchange, a second hub on
the same ports and accounts that do not exist or are root.
"""
from __future__ import annotations

import datetime as dt
import json
import os
import pwd
import re
import secrets
import shutil
import socket
import stat
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
import uuid
from pathlib import Path

import pytest
from course_helpers import SETUP, TEMPORAL_MEAN, exercise_cells, new_cell, new_notebook, write_project
from course_helpers import TEMPORAL_MEAN_LOOP as RIGHT  # a right answer
from user_helpers import make_user, remove_user, runuser

pytestmark = pytest.mark.slow
pytest.importorskip("jupyterhub", reason="JupyterHub comes with the test extra (pip install -e .[test])")

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
ASSIGNMENT = "ch99_tiny"
NOTEBOOK = f"{ASSIGNMENT}.ipynb"
COURSE, OTHER = "ipcv", "ipcv-lab"
PLAN = f"""[course]
id = "cvkit-tiny"

[[assignment]]
id = "{ASSIGNMENT}"
due = "2031-01-01 00:00:00 UTC"

[late]
policy = "per_hour"
points_per_hour = 1
"""
SUMMED = RIGHT.replace("return total / len(stack)", "return total")  # the bank's "sum, not mean"
MISTAKE = "sum, not mean"
WRITTEN = "why_mean"  # a written answer, marked by a teaching assistant in the shared formgrader


def source_notebook():
    return new_notebook([
        new_cell("# A tiny chapter", cell_type="markdown"), new_cell(SETUP, "setup"),
        *exercise_cells("filters.temporal_mean", "temporal_mean", TEMPORAL_MEAN),
        new_cell("**Question.** Why does averaging frames reduce noise?", cell_type="markdown"),
        new_cell("**Model answer.** Independent noise averages out: its standard deviation falls as 1/√N.",
                 WRITTEN, solution=True, grade=True, points=1, cell_type="markdown"),
    ], ids=True)


def answered(notebook: dict, answer: str) -> dict:
    """The fetched notebook with its answer cells written (the code, and a sentence)."""
    notebook = json.loads(json.dumps(notebook))
    for cell in notebook["cells"]:
        if cell["metadata"].get("nbgrader", {}).get("solution"):
            cell["source"] = answer if cell["cell_type"] == "code" else "Noise of different frames cancels out."
    return notebook


# ---------------------------------------------------------------------------- the machine
def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture(scope="module")
def proxy():
    """configurable-http-proxy: Debian's package, installed with apt-get when missing (as root), by
    the code ``cvkit hub init`` uses, as the browser test installs Chromium."""
    from cvkit.course.hub import HubSetupError, proxy_command

    try:
        return proxy_command(install=os.geteuid() == 0)
    except HubSetupError as error:
        if os.geteuid() == 0 and shutil.which("apt-get"):
            pytest.fail(str(error))
        pytest.skip(f"no proxy, and apt-get needs root to install it: {error}")


@pytest.fixture(scope="module")
def accounts():
    """Six local accounts (homes private, as cvkit hub check asks), removed afterwards."""
    made = {}
    try:
        for role in ("ins", "lab", "ada", "bob", "cyd", "tae"):
            made[role] = make_user()
            os.chmod(made[role].pw_dir, 0o700)
        yield made
    finally:
        for user in made.values():
            remove_user(user)


@pytest.fixture(scope="module")
def place():
    """A folder every account can reach (pytest's own tmp tree is root's only), removed after."""
    folder = Path(tempfile.mkdtemp(prefix="cvkit-hub-"))
    folder.chmod(0o755)
    project = write_project(folder / "project", PLAN, {f"{ASSIGNMENT}/{NOTEBOOK}": source_notebook()})
    for path in [project, *project.rglob("*")]:
        path.chmod(0o755 if path.is_dir() else 0o644)
    if not os.stat(ROOT).st_mode & 0o005 or not os.access(sys.executable, os.X_OK):
        pytest.fail(f"the project {ROOT} and its environment must be readable by other users for this test")
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


def cvkit(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """The ``cvkit`` command (as root)."""
    return subprocess.run([str(BIN / "cvkit"), *args], capture_output=True, text=True, cwd=cwd or "/",
                          timeout=600, env={**os.environ, "PATH": f"{BIN}:{os.environ.get('PATH', '')}"})


class Hub:
    """A running hub: its settings, URL, the test's admin token, and who is who."""

    def __init__(self, settings, users, token, log):
        self.settings, self.users, self.token, self.log = settings, users, token, log
        self.url = f"http://127.0.0.1:{settings.port}"
        self.user_tokens: dict[str, str] = {}

    def api(self, method: str, path: str, body=None, token: str | None = None, raw: bool = False):
        """A request to the hub (``/hub/api/...``) or a user's server (``/user/...``)."""
        data = json.dumps(body).encode() if body is not None else None
        request = urllib.request.Request(self.url + path, data=data, method=method, headers={
            "Authorization": f"token {token or self.token}", "Content-Type": "application/json"})
        with urllib.request.urlopen(request, timeout=120) as reply:
            content = reply.read()
        return content if raw else json.loads(content or b"null")

    def user_token(self, name: str) -> str:
        """A token of ``name``, made with the hub's API (as a JupyterLab terminal has one)."""
        if name not in self.user_tokens:
            self.user_tokens[name] = self.api("POST", f"/hub/api/users/{name}/tokens",
                                              {"note": "cvkit hub test", "expires_in": 3600})["token"]
        return self.user_tokens[name]

    def start_server(self, name: str) -> None:
        self.api("POST", f"/hub/api/users/{name}/server", {})
        deadline = time.monotonic() + 180
        while True:
            server = self.api("GET", f"/hub/api/users/{name}")["servers"].get("")
            if server and server.get("ready"):
                return
            assert time.monotonic() < deadline, f"{name}'s server did not start:\n{self.log.read_text()[-3000:]}"
            time.sleep(0.5)

    def jupyter_config_path(self, name: str) -> str:
        """What the hub gives ``name``'s server (jupyterhub_config.py's jupyter_config_path)."""
        jupyter = Path(self.settings.folder) / "jupyter"
        parts = ([jupyter / "users" / name, jupyter / "instructor"] if name in self.settings.instructors
                 else [jupyter / "student"])
        return os.pathsep.join(str(p) for p in [*parts, jupyter / "common"])

    def run_as(self, role: str, *argv: str, cwd: Path | None = None, check: bool = True,
               timeout: float = 600) -> subprocess.CompletedProcess:
        """``argv`` as the account of ``role``, with the environment of a terminal in its JupyterLab."""
        user = self.users[role]
        env = {"HOME": user.pw_dir, "USER": user.pw_name, "LOGNAME": user.pw_name, "LANG": "C.UTF-8",
               "PATH": f"{BIN}:/usr/local/bin:/usr/bin:/bin", "MPLBACKEND": "Agg",
               "JUPYTER_CONFIG_PATH": self.jupyter_config_path(user.pw_name),
               "JUPYTERHUB_API_URL": f"http://127.0.0.1:{self.settings.hub_port}/hub/api",
               "JUPYTERHUB_USER": user.pw_name, "JUPYTERHUB_API_TOKEN": self.user_token(user.pw_name)}
        done = subprocess.run([runuser(), "-u", user.pw_name, "--", *argv], cwd=cwd or user.pw_dir, env=env,
                              capture_output=True, text=True, timeout=timeout)
        if check:
            assert done.returncode == 0, f"{role}: {' '.join(argv)} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
        return done


@pytest.fixture(scope="module")
def hub(proxy, accounts, place):
    """``cvkit hub init`` for two courses, then ``cvkit hub start`` on free ports of 127.0.0.1."""
    from cvkit.course.hub import load_settings

    names = {role: user.pw_name for role, user in accounts.items()}
    folder = place / "hub"
    done = cvkit("hub", "init", "--hub-dir", str(folder), "--project", str(place / "project"),
                 "--course", COURSE, "--course", OTHER,
                 "--instructor", f"{COURSE}={names['ins']}", "--instructor", f"{OTHER}={names['lab']}",
                 "--student", f"{COURSE}={names['ada']},{names['bob']}", "--student", f"{COURSE}={names['cyd']}",
                 "--student", f"{OTHER}={names['ada']}", "--grader", f"{COURSE}={names['tae']}",
                 "--ip", "127.0.0.1", "--port", str(_free_port()), "--hub-port", str(_free_port()),
                 "--proxy-api-port", str(_free_port()))
    assert done.returncode == 0, done.stdout + done.stderr
    settings = load_settings(folder)
    token = secrets.token_hex(32)
    # the test drives the hub with an API token of its own: a service, as an administrator adds one
    (folder / "jupyterhub_config.d" / "90-test.py").write_text(
        f"c.JupyterHub.services.append({{'name': 'cvkit-test', 'api_token': {token!r}}})  # noqa: F821\n"
        "c.JupyterHub.load_roles.append({'name': 'cvkit-test', 'services': ['cvkit-test'], 'scopes': "
        "['admin:users', 'admin:servers', 'tokens', 'read:users']})  # noqa: F821\n")
    log = place / "hub.log"
    with log.open("w") as handle:
        server = subprocess.Popen([str(BIN / "cvkit"), "hub", "start", "--hub-dir", str(folder)], cwd="/",
                                  stdout=handle, stderr=subprocess.STDOUT, start_new_session=True,
                                  env={**os.environ, "PATH": f"{BIN}:{os.environ.get('PATH', '')}"})
    running = Hub(settings, accounts, token, log)
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                running.api("GET", "/hub/api/users")
                break
            except (OSError, urllib.error.HTTPError):
                pass
            assert server.poll() is None, f"the hub stopped:\n{log.read_text()[-3000:]}"
            assert time.monotonic() < deadline, f"the hub did not start in 120 s:\n{log.read_text()[-3000:]}"
            time.sleep(0.5)
        yield running
    finally:
        server.terminate()  # the hub stops the users' servers and the proxy it started
        try:
            server.wait(timeout=60)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait(timeout=30)


# ---------------------------------------------------------------------------- the Assignments panel
CHROMIUM_FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage"]
ARTEFACTS = Path(os.environ.get("CVKIT_ARTEFACTS", ROOT / "artefacts")) / "hub"


def _chromium() -> str | None:
    """Debian's Chromium, installed with apt-get when missing (as tests/system/test_browser.py does)."""
    found = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
    if found is None and shutil.which("apt-get") and os.geteuid() == 0:
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        subprocess.run(["apt-get", "-o", "DPkg::Lock::Timeout=900", "install", "-y", "-q", "--no-install-recommends",
                        "chromium"], capture_output=True, env=env, timeout=900)
        found = shutil.which("chromium")
    return found


class Panel:
    """One student in Chromium: logged in to the hub with their Unix password, JupyterLab's
    Nbgrader menu → Assignment List, and its buttons."""

    def __init__(self, hub: Hub, role: str, chromium: str, sync_api) -> None:
        self.name = hub.users[role].pw_name
        password = secrets.token_urlsafe(16)
        subprocess.run(["chpasswd"], input=f"{self.name}:{password}\n", text=True, check=True, capture_output=True)
        ARTEFACTS.mkdir(parents=True, exist_ok=True)
        self.playwright = sync_api.sync_playwright().start()
        self.browser = self.playwright.chromium.launch(executable_path=chromium, headless=True, args=CHROMIUM_FLAGS)
        self.page = self.browser.new_page(viewport={"width": 1400, "height": 900})
        self.page.set_default_timeout(120_000)
        self.page.goto(f"{hub.url}/hub/login")
        self.page.fill("#username_input", self.name)
        self.page.fill("#password_input", password)
        self.page.click("#login_submit")
        self.page.wait_for_url(re.compile(f"/user/{self.name}/lab"), timeout=180_000)
        self.page.locator(".jp-LabShell").wait_for()
        self.page.locator(".lm-MenuBar-itemLabel", has_text=re.compile("^Nbgrader$")).click()
        self.page.locator(".lm-Menu-itemLabel", has_text=re.compile("^Assignment List$")).click()

    def _row(self, listing: str):
        return self.page.locator(f"#{listing} .list_item", has_text=ASSIGNMENT).first

    def fetch(self) -> None:
        self._row("released_assignments_list").get_by_role("button", name="Fetch").click()
        self._row("fetched_assignments_list").wait_for()

    def submit(self) -> str:
        self._row("fetched_assignments_list").get_by_role("button", name="Submit").click()
        row = self._row("submitted_assignments_list")
        row.wait_for()
        self.page.screenshot(path=str(ARTEFACTS / "assignments-panel-submitted.png"))
        return " ".join(row.text_content().split())

    def fetch_feedback(self) -> str:
        self.page.locator("#refresh_assignments_list").click()
        self._row("submitted_assignments_list").get_by_role("button", name="Fetch Feedback").click()
        link = self.page.locator("#submitted_assignments_list a", has_text=re.compile("view feedback")).first
        link.click()  # the file browser goes to the fetched page's folder
        page = self.page.locator(".jp-DirListing-item", has_text=f"{ASSIGNMENT}.html").first
        page.wait_for()
        self.page.screenshot(path=str(ARTEFACTS / "assignments-panel-feedback.png"))
        return " ".join(self.page.locator(".jp-FileBrowser-crumbs").first.text_content().split())

    def close(self) -> None:
        self.browser.close()
        self.playwright.stop()


def _panel(hub: Hub, role: str) -> Panel | None:
    """The Assignments panel of ``role`` in Chromium, or None without Playwright or Chromium."""
    try:
        from playwright import sync_api
    except ImportError:
        return None
    chromium = _chromium()
    return Panel(hub, role, chromium, sync_api) if chromium else None


# ---------------------------------------------------------------------------- the semester
def _scores(folder: Path) -> dict[str, dict]:
    from nbgrader.api import Gradebook

    with Gradebook(f"sqlite:///{folder / 'gradebook.db'}") as gradebook:
        return {s.student.id: {"raw": s.score, "max": s.max_score, "penalty": s.late_submission_penalty,
                               "timestamp": s.timestamp} for s in gradebook.assignment_submissions(ASSIGNMENT)}


def _text(html: str) -> str:
    import html as html_module

    return html_module.unescape(re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html)))


#: what the teaching assistant gives each written answer, and says
MARKS = {"ada": (1.0, "Right: the noise's standard deviation falls as 1/sqrt(N)."),
         "bob": (0.5, "Half right: say why the noise cancels."), "cyd": (1.0, "Good.")}


def mark_written_answers(hub: Hub, users: dict) -> dict:
    """The teaching assistant marks every written answer in the course's shared formgrader (a hub
    service), with the formgrader's own API as its page uses it; a student tries the same."""
    service = f"/services/{COURSE}/formgrader/api"
    token = hub.user_token(users["tae"])
    done: dict = {"refused": {}}
    for who in ("bob", "lab"):  # a student of the course; the instructor of another course
        try:
            hub.api("GET", f"{service}/submissions/{ASSIGNMENT}", token=hub.user_token(users[who]))
            done["refused"][who] = "allowed"
        except urllib.error.HTTPError as error:
            done["refused"][who] = error.code
    notebooks = hub.api("GET", f"{service}/submitted_notebooks/{ASSIGNMENT}/{ASSIGNMENT}", token=token)
    by_name = {users[role]: role for role in MARKS}
    for notebook in notebooks:
        role = by_name[notebook["student"]]
        grades = hub.api("GET", f"{service}/grades?submission_id={notebook['id']}", token=token)
        comments = hub.api("GET", f"{service}/comments?submission_id={notebook['id']}", token=token)
        (grade,) = [g for g in grades if g["name"] == WRITTEN]
        (comment,) = [c for c in comments if c["name"] == WRITTEN]
        score, words = MARKS[role]
        hub.api("PUT", f"{service}/grade/{grade['id']}", {"manual_score": score}, token=token)
        hub.api("PUT", f"{service}/comment/{comment['id']}", {"manual_comment": words}, token=token)
    done["listed"] = sorted(by_name[n["student"]] for n in notebooks)
    request = urllib.request.Request(f"{hub.url}/services/{COURSE}/formgrader/manage_assignments",
                                     headers={"Authorization": f"token {token}"})
    with urllib.request.urlopen(request, timeout=120) as reply:  # the page, in a tab of its own
        done["page"] = (reply.status, "formgrader" in reply.read().decode().lower())
    return done


@pytest.fixture(scope="module")
def semester(hub):
    """Release, fetch, answer, submit, collect, grade, release and fetch feedback (module docstring)."""
    users = {role: user.pw_name for role, user in hub.users.items()}
    course = Path(pwd.getpwnam(users["ins"]).pw_dir) / COURSE
    other = Path(pwd.getpwnam(users["lab"]).pw_dir) / OTHER
    for role, folder in (("ins", course), ("lab", other)):
        hub.run_as(role, "cvkit", "course", "build", "--course-dir", ".", cwd=folder)
        hub.run_as(role, "nbgrader", "release_assignment", ASSIGNMENT, cwd=folder)
    seen: dict = {}

    # ada: her own JupyterLab, through the hub (the Assignments panel's and JupyterLab's endpoints)
    ada = users["ada"]
    hub.start_server(ada)
    token = hub.user_token(ada)
    seen["ada courses"] = hub.api("GET", f"/user/{ada}/courses", token=token)
    listed = hub.api("GET", f"/user/{ada}/assignments?course_id={COURSE}", token=token)
    seen["ada released"] = [(a["course_id"], a["assignment_id"], a["status"]) for a in listed["value"]]
    hub.api("POST", f"/user/{ada}/assignments/fetch", {"course_id": COURSE, "assignment_id": ASSIGNMENT}, token=token)
    path = f"/user/{ada}/api/contents/{COURSE}/{ASSIGNMENT}/{NOTEBOOK}"
    fetched = hub.api("GET", path, token=token)["content"]
    hub.api("PUT", path, {"type": "notebook", "format": "json", "content": answered(fetched, RIGHT)}, token=token)
    seen["ada submit"] = hub.api("POST", f"/user/{ada}/assignments/submit",
                                 {"course_id": COURSE, "assignment_id": ASSIGNMENT}, token=token)

    # bob: nbgrader in a terminal of his JupyterLab; he takes one course only
    seen["bob list"] = hub.run_as("bob", "nbgrader", "list").stderr
    seen["bob other course"] = hub.run_as("bob", "nbgrader", "fetch_assignment", ASSIGNMENT, "--course", OTHER,
                                          check=False)
    hub.run_as("bob", "nbgrader", "fetch_assignment", ASSIGNMENT, "--course", COURSE)
    work = Path(pwd.getpwnam(users["bob"]).pw_dir) / COURSE / ASSIGNMENT / NOTEBOOK
    work.write_text(json.dumps(answered(json.loads(work.read_text()), SUMMED)))  # his file, rewritten in place
    hub.run_as("bob", "nbgrader", "submit", ASSIGNMENT, "--course", COURSE)

    # the instructor moves the due date to now: cyd hands in after it
    due = dt.datetime.now(dt.timezone.utc).replace(microsecond=0) + dt.timedelta(seconds=2)
    plan = course / "plan.toml"
    plan.write_text(re.sub(r'due = ".*"', f'due = "{due:%Y-%m-%d %H:%M:%S} UTC"', plan.read_text()))
    while dt.datetime.now(dt.timezone.utc) <= due + dt.timedelta(seconds=1):
        time.sleep(0.2)
    work = Path(pwd.getpwnam(users["cyd"]).pw_dir) / COURSE / ASSIGNMENT / NOTEBOOK
    panel = _panel(hub, "cyd")  # cyd works in JupyterLab's Assignments panel, in Chromium (if it is here)
    seen["cyd used"] = "the Assignments panel" if panel else "a terminal"
    if panel:
        panel.fetch()
    else:
        hub.run_as("cyd", "nbgrader", "fetch_assignment", ASSIGNMENT, "--course", COURSE)
    work.write_text(json.dumps(answered(json.loads(work.read_text()), RIGHT)))
    if panel:
        seen["cyd panel"] = panel.submit()
    else:
        hub.run_as("cyd", "nbgrader", "submit", ASSIGNMENT, "--course", COURSE)

    # the instructor: collect, grade (sandboxed, as the instructor), release the feedback
    seen["collect"] = hub.run_as("ins", "cvkit", "course", "collect", "--assignment", ASSIGNMENT, cwd=course)
    seen["grade"] = hub.run_as("ins", "cvkit", "course", "grade", "--course-dir", ".", "--workers", "2", cwd=course)
    seen["marked"] = mark_written_answers(hub, users)
    # after marking written answers in the formgrader, the pages are written again by plain nbgrader
    # (with cvkit's configuration: sanitised, hidden tests removed), the secrets kept
    hub.run_as("ins", "nbgrader", "generate_feedback", ASSIGNMENT, "--force", cwd=course)
    seen["release"] = hub.run_as("ins", "nbgrader", "release_feedback", ASSIGNMENT, cwd=course)
    seen["scores"] = _scores(course)

    # the instructor's JupyterLab: nbgrader's course list finds the formgrader, which lists the graded work
    instructor = users["ins"]
    hub.start_server(instructor)
    grader = hub.user_token(instructor)
    seen["formgraders"] = hub.api("GET", f"/user/{instructor}/formgraders", token=grader)
    seen["formgrader"] = hub.api("GET", f"/user/{instructor}/formgrader/api/submissions/{ASSIGNMENT}", token=grader)
    request = urllib.request.Request(f"{hub.url}/user/{instructor}/formgrader/manage_assignments",
                                     headers={"Authorization": f"token {grader}"})
    with urllib.request.urlopen(request, timeout=120) as reply:
        seen["formgrader page"] = (reply.status, reply.headers.get("Content-Security-Policy"))
    hub.start_server(users["tae"])
    seen["ta formgraders"] = hub.api("GET", f"/user/{users['tae']}/formgraders", token=hub.user_token(users["tae"]))

    # the students fetch their feedback: ada in her JupyterLab, bob and cyd in a terminal
    hub.api("POST", f"/user/{ada}/assignments/fetch_feedback", {"course_id": COURSE, "assignment_id": ASSIGNMENT},
            token=token)
    hub.run_as("bob", "nbgrader", "fetch_feedback", ASSIGNMENT, "--course", COURSE)
    if panel:
        seen["cyd feedback link"] = panel.fetch_feedback()
        panel.close()
    else:
        hub.run_as("cyd", "nbgrader", "fetch_feedback", ASSIGNMENT, "--course", COURSE)
    seen["feedback"] = {}
    for role in ("ada", "bob", "cyd"):
        pages = sorted((Path(pwd.getpwnam(users[role]).pw_dir) / COURSE / ASSIGNMENT / "feedback").glob("*/*.html"))
        seen["feedback"][role] = [_text(p.read_text()) for p in pages]
    return {"course": course, "other": other, "users": users, "seen": seen, "due": due.replace(tzinfo=None)}


def test_hub_init_writes_the_exchange_and_course_folders_nbgrader_needs(hub):
    """The exchange as nbgrader's own commands make it (not group-shared), course folders
    private to their instructor, each role's extensions, and ``cvkit hub check`` content."""
    settings, users = hub.settings, {role: user.pw_name for role, user in hub.users.items()}
    exchange = Path(settings.exchange)

    def owner_mode(path):
        info = path.stat()
        return pwd.getpwuid(info.st_uid).pw_name, f"{stat.S_IMODE(info.st_mode):04o}"

    assert owner_mode(exchange) == ("root", "1777")
    for course_id, instructor in ((COURSE, users["ins"]), (OTHER, users["lab"])):
        assert owner_mode(exchange / course_id) == (instructor, "0755")
        assert owner_mode(exchange / course_id / "outbound") == (instructor, "0755")
        assert owner_mode(exchange / course_id / "inbound") == (instructor, "2733")
        assert owner_mode(exchange / course_id / "feedback") == (instructor, "0711")
        folder = Path(pwd.getpwnam(instructor).pw_dir) / course_id
        assert owner_mode(folder) == (instructor, "0700")
        assert f'id = "{course_id}"' in (folder / "plan.toml").read_text()
        assert f"c.Exchange.root = {str(exchange)!r}" in (folder / "nbgrader_config.py").read_text()
    jupyter = Path(settings.folder) / "jupyter"
    student = json.loads((jupyter / "student" / "labconfig" / "page_config.json").read_text())["disabledExtensions"]
    assert {k for k, v in student.items() if v} == {"@jupyter/nbgrader:formgrader", "@jupyter/nbgrader:course-list",
                                                   "@jupyter/nbgrader:create-assignment"}
    teacher = json.loads((jupyter / "instructor" / "labconfig" / "page_config.json").read_text())["disabledExtensions"]
    assert not any(teacher.values())
    common = (jupyter / "common" / "nbgrader_config.py").read_text()
    assert "c.Authenticator.plugin_class = JupyterHubAuthPlugin" in common and "course_id" not in common
    done = cvkit("hub", "check", "--hub-dir", settings.folder, "--running")
    assert (done.returncode, done.stdout.strip()) == (0, f"the hub in {settings.folder} is set up as cvkit hub init "
                                                         "made it"), done.stdout + done.stderr


def test_students_see_their_own_courses_only(semester):
    seen, users = semester["seen"], semester["users"]
    assert seen["ada courses"] == {"success": True, "value": [COURSE, OTHER]}
    assert seen["ada released"] == [(COURSE, ASSIGNMENT, "released")]
    assert f"{OTHER} {ASSIGNMENT}" not in seen["bob list"] and f"{COURSE} {ASSIGNMENT}" in seen["bob list"]
    refused = seen["bob other course"]
    assert refused.returncode != 0 and "You do not have access to this course." in refused.stderr
    assert not (Path(pwd.getpwnam(users["bob"]).pw_dir) / OTHER).exists()


def test_grades_penalty_and_named_mistake(semester):
    seen, users = semester["seen"], semester["users"]
    assert seen["ada submit"]["success"] is True
    collected = seen["collect"].stdout  # cvkit course collect, from nbgrader's exchange
    assert all(f"collected {users[r]}: {NOTEBOOK}" in collected for r in ("ada", "bob", "cyd")), collected
    assert "3 hand-ins collected" in collected
    scores = seen["scores"]
    assert set(scores) == {users["ada"], users["bob"], users["cyd"]}
    # 3 points of checks, and the written answer the teaching assistant marked (MARKS)
    assert scores[users["ada"]]["raw"] == pytest.approx(3 + 1) and scores[users["ada"]]["penalty"] == 0
    # "sum, not mean": the visible test fails; of the ten hidden cases only the single frame passes
    assert scores[users["bob"]]["raw"] == pytest.approx(0.2 + 0.5) and scores[users["bob"]]["penalty"] == 0
    assert scores[users["cyd"]]["raw"] == pytest.approx(3 + 1)
    assert scores[users["cyd"]]["penalty"] == pytest.approx(1)  # one started hour late, 1 point an hour
    assert scores[users["ada"]]["timestamp"] < semester["due"] < scores[users["cyd"]]["timestamp"]
    grade = seen["grade"].stdout
    assert f"{users['bob']} · temporal_mean: mistake “{MISTAKE}”" in grade
    assert "exchange:" not in grade and "without submission_secret.txt" not in grade  # nothing to report
    assert (f"late: {users['cyd']} {ASSIGNMENT}: −1 point (handed in 0 h 00 min after the due date; the table "
            "shows the points before it)") in grade
    # nbgrader's formgrader lists a submission as autograded only when submitted/…/timestamp.txt
    # says what the gradebook recorded: cvkit made it so (the student's own file is kept aside)
    for role in ("ada", "bob", "cyd"):
        stamp = semester["course"] / "submitted" / users[role] / ASSIGNMENT / "timestamp.txt"
        assert stamp.read_text() == f"{scores[users[role]]['timestamp']:%Y-%m-%d %H:%M:%S.%f} UTC"


def test_the_assignments_panel_in_chromium(semester):
    """cyd fetched, submitted and fetched her feedback with the panel's buttons."""
    seen = semester["seen"]
    if seen["cyd used"] != "the Assignments panel":
        pytest.skip("Playwright or Chromium is not here: cyd used a terminal")
    assert ASSIGNMENT in seen["cyd panel"] and "UTC" in seen["cyd panel"]  # the submission, with its time
    # "(view feedback)" opened the folder of her page in JupyterLab's file browser
    # (its breadcrumbs shorten the middle: "/ … /feedback/<time of her submission>/"), listing the page
    assert re.fullmatch(r".*/feedback/\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d+ UTC/", seen["cyd feedback link"])


def test_the_instructor_grades_written_answers_in_the_formgrader(hub, semester):
    """The formgrader runs in the instructor's own server, on the course folder: it lists every
    submission as autograded, with the gradebook's scores. JupyterHub forbids framing its pages
    on one origin (frame-ancestors 'none'), so it opens in a browser tab of its own."""
    seen, users = semester["seen"], semester["users"]
    instructor = users["ins"]
    shared = {"course_id": COURSE, "url": f"{hub.url}/services/{COURSE}/lab?formgrader=true", "kind": "jupyterhub"}
    assert seen["formgraders"] == {"success": True, "value": [
        {"course_id": COURSE, "url": f"{hub.url}/user/{instructor}/formgrader", "kind": "local"}, shared]}
    listed = {s["student"]: (s["autograded"], s["score"], s["max_score"]) for s in seen["formgrader"]}
    scores = seen["scores"]
    assert listed == {users[r]: (True, pytest.approx(scores[users[r]]["raw"]), 4.0) for r in ("ada", "bob", "cyd")}
    assert seen["formgrader page"] == (200, "frame-ancestors 'none'")


def test_a_teaching_assistant_marks_written_answers_in_the_shared_formgrader(hub, semester):
    """The course's teaching assistant (an account of their own, not the instructor's) finds the
    course's shared formgrader in their course list and marks every written answer there; a
    student and another course's instructor are refused; the marks and comments reach the
    gradebook and the students' pages."""
    seen, users = semester["seen"], semester["users"]
    assert seen["ta formgraders"] == {"success": True, "value": [
        {"course_id": COURSE, "url": f"{hub.url}/services/{COURSE}/lab?formgrader=true", "kind": "jupyterhub"}]}
    assert seen["marked"]["listed"] == ["ada", "bob", "cyd"]
    assert seen["marked"]["refused"] == {"bob": 403, "lab": 403}
    assert seen["marked"]["page"] == (200, True)
    from nbgrader.api import Gradebook

    with Gradebook(f"sqlite:///{semester['course'] / 'gradebook.db'}") as gradebook:
        for role, (score, words) in MARKS.items():
            grade = gradebook.find_grade(WRITTEN, ASSIGNMENT, ASSIGNMENT, users[role])
            comment = gradebook.find_comment(WRITTEN, ASSIGNMENT, ASSIGNMENT, users[role])
            assert (grade.manual_score, grade.needs_manual_grade, comment.manual_comment) == (score, False, words)
    for role, (score, words) in MARKS.items():
        page = seen["feedback"][role][0]
        assert words in page and all(w not in page for r, (_, w) in MARKS.items() if r != role)


def test_each_student_fetches_their_own_feedback(semester):
    users, pages = semester["users"], semester["seen"]["feedback"]
    assert [len(pages[role]) for role in ("ada", "bob", "cyd")] == [1, 1, 1]
    ada, bob, cyd = pages["ada"][0], pages["bob"][0], pages["cyd"][0]
    assert f"{ASSIGNMENT} (Score: 4.0 / 4.0)" in ada and MISTAKE not in ada
    assert f"{ASSIGNMENT} (Score: 0.7 / 4.0)" in bob and MISTAKE in bob
    assert f"{ASSIGNMENT} (Score: 3.0 / 4.0)" in cyd and "Late submission penalty (Score: -1.0)" in cyd
    assert "Late submission penalty" not in ada + bob
    for role, page in (("ada", ada), ("bob", bob), ("cyd", cyd)):
        others = [users[r] for r in ("ada", "bob", "cyd", "ins", "tae") if r != role]
        assert not [name for name in others if name in page], role


def _probe(hub, role: str, paths: dict[str, Path]) -> dict[str, str]:
    """What ``role`` gets trying to list a folder (``ls:``) or read a file: "ok" or the error's name."""
    script = ("import json, os, sys\nout = {}\n"
              "for key, path in json.loads(sys.argv[1]).items():\n"
              "    try:\n"
              "        os.listdir(path) if key.startswith('ls:') else open(path, 'rb').read(1)\n"
              "        out[key] = 'ok'\n"
              "    except OSError as error:\n"
              "        out[key] = type(error).__name__\n"
              "print(json.dumps(out))\n")
    done = hub.run_as(role, sys.executable, "-c", script, json.dumps({k: str(v) for k, v in paths.items()}))
    return json.loads(done.stdout)


def test_students_cannot_reach_each_others_work_the_salt_or_the_gradebook(hub, semester):
    users, course = semester["users"], semester["course"]
    exchange = Path(hub.settings.exchange) / COURSE
    ada_home = Path(pwd.getpwnam(users["ada"]).pw_dir)
    inbound = sorted((exchange / "inbound").iterdir())
    mine = [p for p in inbound if p.name.startswith(f"{users['bob']}+")]
    paths = {
        "ls:inbound": exchange / "inbound", "ls:feedback": exchange / "feedback",
        "ls:course": course, "salt": course / ".grading_salt", "gradebook": course / "gradebook.db",
        "ada's collected": course / "submitted" / users["ada"] / ASSIGNMENT / NOTEBOOK,
        "ada's feedback page": course / "feedback" / users["ada"] / ASSIGNMENT / f"{ASSIGNMENT}.html",
        "ada's notebook": ada_home / COURSE / ASSIGNMENT / NOTEBOOK,
        "ls:ada's nbgrader cache": ada_home / ".local" / "share" / "jupyter" / "nbgrader_cache",
        "released": exchange / "outbound" / ASSIGNMENT / NOTEBOOK,
        "his own hand-in": mine[0] / NOTEBOOK,
    }
    assert _probe(hub, "bob", paths) == {
        "ls:inbound": "PermissionError", "ls:feedback": "PermissionError", "ls:course": "PermissionError",
        "salt": "PermissionError", "gradebook": "PermissionError", "ada's collected": "PermissionError",
        "ada's feedback page": "PermissionError", "ada's notebook": "PermissionError",
        "ls:ada's nbgrader cache": "PermissionError", "released": "ok", "his own hand-in": "ok",
    }
    assert len(inbound) == 3 and len(mine) == 1  # one hand-in each, named <student>+<assignment>+<time>+<random>
    assert stat.S_IMODE((course / ".grading_salt").stat().st_mode) == 0o600


# ---------------------------------------------------------------------------- what goes wrong
@pytest.fixture(scope="module")
def second_round(hub, semester):
    """bob submits again after the collection; his new hand-in arrives without its secret."""
    users, course = semester["users"], semester["course"]
    before = _scores(course)
    work = Path(pwd.getpwnam(users["bob"]).pw_dir) / COURSE / ASSIGNMENT / NOTEBOOK
    work.write_text(json.dumps(answered(json.loads(work.read_text()), RIGHT)))
    hub.run_as("bob", "nbgrader", "submit", ASSIGNMENT, "--course", COURSE)
    seen = {"waiting": hub.run_as("ins", "cvkit", "course", "grade", "--course-dir", ".", cwd=course),
            "unchanged": _scores(course)}
    hub.run_as("ins", "nbgrader", "collect", "--update", ASSIGNMENT, cwd=course)
    # as if handed in with nbgrader older than 0.9.3 (or copied by hand): no submission_secret.txt
    (course / "submitted" / users["bob"] / ASSIGNMENT / "submission_secret.txt").unlink()
    seen["regrade"] = hub.run_as("ins", "cvkit", "course", "grade", "--course-dir", ".", cwd=course)
    seen["scores"] = _scores(course)
    feedback = Path(hub.settings.exchange) / COURSE / "feedback"
    seen["released before"] = {p.name: p.read_bytes() for p in feedback.iterdir()}
    seen["plain release"] = hub.run_as("ins", "nbgrader", "release_feedback", ASSIGNMENT, cwd=course, check=False)
    command = re.search(r"release everyone else's with: (nbgrader release_feedback \S+ \S+);",
                        seen["regrade"].stdout)
    seen["command"] = command.group(1) if command else ""
    seen["release others"] = hub.run_as("ins", *seen["command"].split(), cwd=course, check=False)
    seen["released after"] = {p.name: p.read_bytes() for p in feedback.iterdir()}
    return {"before": before, **seen}


def test_a_submission_after_the_collection_is_reported_with_what_to_do(semester, second_round):
    bob, course = semester["users"]["bob"], semester["course"]
    out = " ".join(second_round["waiting"].stdout.split())
    assert (f"exchange: {bob} submitted {ASSIGNMENT} again after the collection (1 newer submission; graded: the one "
            f"received {second_round['before'][bob]['timestamp']:%Y-%m-%d %H:%M:%S} UTC): to grade the newest (it came "
            f"after the due date: it will be graded late), run nbgrader collect --update {ASSIGNMENT} in {course}, "
            "then cvkit course grade") in out
    assert second_round["unchanged"] == second_round["before"]


def test_a_missing_secret_is_reported_and_everyone_elses_feedback_still_goes_out(semester, second_round):
    users, course = semester["users"], semester["course"]
    bob = users["bob"]
    out = " ".join(second_round["regrade"].stdout.split())
    assert "autograded 1 submission " in out
    assert (f"feedback: {bob} handed in {ASSIGNMENT} without submission_secret.txt (submitted with nbgrader older "
            f"than 0.9.3, or placed by hand): nbgrader release_feedback {ASSIGNMENT} stops at the first such page; "
            f"release everyone else's with: nbgrader release_feedback {ASSIGNMENT} "
            f"--CourseDirectory.student_id_exclude={bob}; for {bob}: ask them to submit again") in out
    scores = second_round["scores"]
    # bob's new hand-in is right, and late; his written answer keeps the assistant's mark (nbgrader keeps
    # hand marks when it grades a submission again); everyone else's grade is as it was
    assert scores[bob]["raw"] == pytest.approx(3 + 0.5) and scores[bob]["penalty"] == pytest.approx(1)
    assert {s: v for s, v in scores.items() if s != bob} == {s: v for s, v in second_round["before"].items() if s != bob}
    plain = second_round["plain release"]
    assert plain.returncode != 0 and "submission_secret.txt" in plain.stdout + plain.stderr
    assert second_round["command"] == f"nbgrader release_feedback {ASSIGNMENT} --CourseDirectory.student_id_exclude={bob}"
    assert second_round["release others"].returncode == 0, second_round["release others"].stderr[-2000:]
    # ada's and cyd's pages are there as before (and bob's earlier one), none lost
    assert set(second_round["released before"]) <= set(second_round["released after"])
    assert len(second_round["released after"]) == 3


def test_a_broken_exchange_a_second_hub_and_wrong_accounts_are_refused_clearly(hub, place):
    settings = hub.settings
    inbound = Path(settings.exchange) / COURSE / "inbound"
    inbound.chmod(0o777)
    try:
        done = cvkit("hub", "check", "--hub-dir", settings.folder, "--running")
    finally:
        inbound.chmod(0o2733)
    assert done.returncode == 1
    assert (f"!! the exchange's inbound of {COURSE} {inbound} is mode 0777, not 2733 (chmod 2733 {inbound}): "
            "students may write their submissions there but never list them") in done.stdout
    # the hub runs: a second one on the same ports cannot start, and says why
    done = cvkit("hub", "start", "--hub-dir", settings.folder)
    assert done.returncode == 2
    assert (f"the hub's address: port {settings.port} on 127.0.0.1 is in use (Address already in use): stop what "
            "uses it (a hub already running?) or run cvkit hub init again with another --port") in done.stderr
    missing = f"nobody{uuid.uuid4().hex[:6]}"
    done = cvkit("hub", "init", "--hub-dir", str(place / "other-hub"), "--project", str(place / "project"),
                 "--course", "c1", "--instructor", hub.users["ins"].pw_name, "--student", missing)
    assert done.returncode == 2
    assert (f"cvkit: error: student of c1 {missing!r} has no Unix account on this machine: create it first "
            f"(useradd --create-home {missing})") in done.stderr
    done = cvkit("hub", "init", "--hub-dir", str(place / "other-hub"), "--course", "c1", "--instructor", "root")
    assert done.returncode == 2 and "the instructor of c1 'root' is root: the hub never runs" in done.stderr
    assert not (place / "other-hub" / "jupyterhub_config.py").exists()
