"""A course on JupyterHub: what ``cvkit hub init`` writes, what ``cvkit hub check`` verifies and
what ``cvkit course grade`` tells the instructor about nbgrader's exchange.

One hub serves one or more courses. Each course has one instructor account (an ordinary Unix
user, never root) who owns the course folder (``~instructor/<course id>`` by default) and the
course's folders in nbgrader's exchange, students (Unix accounts) and, optionally, graders
(teaching assistants, co-instructors: hub accounts). A course with graders gets nbgrader's
*shared formgrader*: a JupyterHub service named after the course, a JupyterLab running as the
instructor account on the course folder, which every member of ``formgrade-<course>`` (the
instructor and the graders) opens at ``/services/<course>/formgrader``; nobody else may. The hub runs as root
with JupyterHub's ``LocalProcessSpawner``: every user's JupyterLab runs as that user, from the
Python environment cvkit is installed in (so ``cvkit`` and ``nbgrader`` are there for all).

What :func:`init_hub` writes (``docs/deploy-jupyterhub.md`` explains each):

- ``<hub>/jupyterhub_config.py`` (the hub, the proxy, the users, nbgrader's groups, the scopes
  of the servers' tokens), ``<hub>/jupyterhub_config.d/`` (the hub administrator's additions,
  loaded last), ``<hub>/jupyterhub.service`` (a systemd unit) and ``<hub>/cvkit-hub.json`` (the
  settings, read by ``cvkit hub check`` and ``cvkit hub start``); ``<hub>/state/`` (root only:
  the hub's database and cookie secret);
- Jupyter configuration per role, given to each server by ``JUPYTER_CONFIG_PATH``:
  ``<hub>/jupyter/common`` (nbgrader's exchange and course id), ``<hub>/jupyter/student`` and
  ``<hub>/jupyter/instructor`` (which nbgrader extensions each role sees, in JupyterLab and on the
  server), ``<hub>/jupyter/users/<instructor>`` (the formgrader's course);
- nbgrader's exchange (``root`` owner, mode ``1777``: everyone may create, nobody may remove
  another's folder) and, per course, ``<exchange>/<course>`` owned by its instructor with
  ``outbound`` 0755, ``inbound`` 2733 (students write their submissions, cannot list them) and
  ``feedback`` 0711 (students read their own page by its secret name, cannot list);
- the course folder, private to its instructor (mode 0700: the gradebook, the grading salt and
  the submissions are nobody else's), with cvkit's ``nbgrader_config.py`` (plus the exchange)
  and a ``plan.toml`` naming the course.
"""
from __future__ import annotations

import datetime as _dt
import errno
import json
import os
import pprint
import re
import shutil
import socket
import stat
import subprocess
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Sequence

from .._text import printable
from .files import write_whole

if TYPE_CHECKING:
    from .state import CourseState

__all__ = ["HubCourse", "HubSettings", "HubSetupError", "SETTINGS_FILE", "check_hub", "course_folder",
           "courses_from_options", "exchange_notes", "init_hub", "load_settings", "proxy_command", "start_problems"]

#: the settings of a hub, in its folder (read by ``cvkit hub check`` and ``cvkit hub start``)
SETTINGS_FILE = "cvkit-hub.json"
#: nbgrader's JupyterLab plugins (``jupyter labextension disable @jupyter/nbgrader:<name>``)
LAB_PLUGINS = ("formgrader", "assignment-list", "course-list", "create-assignment", "validate-assignment")
#: nbgrader's server extensions (``nbgrader.server_extensions.<name>``)
SERVER_EXTENSIONS = ("formgrader", "assignment_list", "course_list", "validate_assignment")
#: what each role sees: students fetch, validate, submit and fetch feedback; instructors also
#: grade, create assignments and list their courses (and see the Assignments panel as students do)
#: graders (TAs) grade in the course's shared formgrader; their own server only lists the courses
#: they grade (nbgrader's course list links each shared formgrader)
ROLE_PLUGINS = {"student": ("assignment-list", "validate-assignment"), "instructor": LAB_PLUGINS,
                "grader": ("course-list", "assignment-list", "validate-assignment")}
ROLE_SERVER_EXTENSIONS = {"student": ("assignment_list", "validate_assignment"), "instructor": SERVER_EXTENSIONS,
                          "grader": ("course_list", "assignment_list", "validate_assignment")}
#: the exchange's modes, as nbgrader's own release_assignment makes them (not group-shared)
EXCHANGE_MODES = {"root": 0o1777, "course": 0o755, "outbound": 0o755, "inbound": 0o2733, "feedback": 0o711}
#: the Debian package of the proxy (bookworm names it so; ``configurable-http-proxy`` on npm)
PROXY_PACKAGE = "node-configurable-http-proxy"
_NAME = re.compile(r"^[a-z_][a-z0-9_.-]*[$]?$")
_COURSE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class HubSetupError(RuntimeError):
    """What is wrong with a hub's settings or machine, and what to do about it."""


@dataclass(frozen=True)
class HubCourse:
    """One course on the hub.

    Attributes
    ----------
    id : str
        nbgrader's course id (the exchange folder's name, the ``nbgrader-<id>`` group).
    instructor : str
        The Unix account that owns the course folder and the exchange's course folders.
    students : tuple of str
        Unix accounts of the students.
    folder : str
        The course folder (default ``~instructor/<id>``).
    graders : tuple of str
        Hub accounts that grade the course (teaching assistants) in its shared formgrader.
    formgrader_port : int
        The port on 127.0.0.1 of the shared formgrader (a course with graders; chosen by
        :func:`init_hub` when 0).
    """

    id: str
    instructor: str
    students: tuple[str, ...]
    folder: str
    graders: tuple[str, ...] = ()
    formgrader_port: int = 0

    @property
    def shared_formgrader(self) -> bool:
        """Graders share the course's formgrader (a JupyterHub service named after the course)."""
        return bool(self.graders)


@dataclass(frozen=True)
class HubSettings:
    """Everything ``cvkit hub init`` was told (saved as ``<folder>/cvkit-hub.json``).

    Attributes
    ----------
    folder : str
        The hub's folder.
    courses : tuple of HubCourse
    exchange : str
        nbgrader's exchange root (default ``<folder>/exchange``).
    ip, port : str, int
        Where the hub is reached (the proxy's public address).
    hub_port, proxy_api_port : int
        The hub's own API and the proxy's API, on 127.0.0.1.
    subdomain_host : str
        ``https://hub.example.org`` to give every user a subdomain of their own (the formgrader
        then shows inside JupyterLab); empty for one origin (the formgrader opens in a tab).
    python_bin : str
        The ``bin`` folder of the Python environment with cvkit, JupyterHub and nbgrader.
    project : str
        The cvkit checkout with ``lectures/`` and ``autograders/``.
    proxy : list of str
        The proxy's command (:func:`proxy_command`).
    """

    folder: str
    courses: tuple[HubCourse, ...]
    exchange: str
    ip: str = "127.0.0.1"
    port: int = 8000
    hub_port: int = 8081
    proxy_api_port: int = 8001
    subdomain_host: str = ""
    python_bin: str = field(default_factory=lambda: str(Path(sys.executable).parent))
    project: str = ""
    proxy: tuple[str, ...] = ()

    @property
    def multi_course(self) -> bool:
        """Several courses: nbgrader asks JupyterHub's groups who takes which course."""
        return len(self.courses) > 1

    @property
    def instructors(self) -> dict[str, HubCourse]:
        return {course.instructor: course for course in self.courses}

    @property
    def students(self) -> list[str]:
        return sorted({s for course in self.courses for s in course.students})

    @property
    def graders(self) -> list[str]:
        """Accounts that grade a course without owning one (their own server has the grader role)."""
        return sorted({g for course in self.courses for g in course.graders} - set(self.instructors))

    @property
    def url(self) -> str:
        return self.subdomain_host or f"http://{self.ip or '0.0.0.0'}:{self.port}"

    def to_json(self) -> str:
        data = asdict(self)
        data["courses"] = [asdict(c) for c in self.courses]
        return json.dumps(data, indent=1) + "\n"


def load_settings(folder: str | os.PathLike[str]) -> HubSettings:
    """The settings ``cvkit hub init`` saved in ``folder`` (HubSetupError naming the file)."""
    path = Path(folder) / SETTINGS_FILE
    try:
        data = json.loads(path.read_text())
        courses = tuple(HubCourse(c["id"], c["instructor"], tuple(c["students"]), c["folder"],
                                  tuple(c.get("graders", ())), int(c.get("formgrader_port", 0)))
                        for c in data.pop("courses"))
        data["proxy"] = tuple(data.get("proxy", ()))
        return HubSettings(courses=courses, **data)
    except FileNotFoundError:
        raise HubSetupError(f"{path} does not exist: run cvkit hub init --hub-dir {folder} first") from None
    except (ValueError, KeyError, TypeError) as error:
        raise HubSetupError(f"{path} is not the settings cvkit hub init writes ({error}): run cvkit hub init "
                            "again") from None


# ---------------------------------------------------------------------------- the options
def _split(values: Iterable[str], courses: Sequence[str], what: str) -> dict[str, list[str]]:
    """``COURSE=NAME`` or (one course) ``NAME`` options → course → names."""
    found: dict[str, list[str]] = {c: [] for c in courses}
    for value in values:
        course, sep, name = value.rpartition("=")
        if not sep:
            if len(courses) != 1:
                raise ValueError(f"--{what} {value}: with several courses, say which: --{what} COURSE={value} "
                                 f"(courses: {', '.join(courses)})")
            course = courses[0]
        if course not in found:
            raise ValueError(f"--{what} {value}: no course {course!r} (courses: {', '.join(courses)})")
        for part in filter(None, (p.strip() for p in name.split(","))):
            if part not in found[course]:
                found[course].append(part)
    return found


def courses_from_options(courses: Sequence[str], instructors: Sequence[str], students: Sequence[str],
                         folders: Sequence[str] = (), graders: Sequence[str] = ()) -> tuple[HubCourse, ...]:
    """The courses of ``cvkit hub init``'s options.

    Parameters
    ----------
    courses : sequence of str
        Course ids.
    instructors, students : sequence of str
        ``COURSE=USER`` (``USER`` alone with one course; ``USER1,USER2`` for several).
    folders : sequence of str
        ``COURSE=FOLDER`` (``FOLDER`` alone with one course); default ``~instructor/<course>``.
    graders : sequence of str
        ``COURSE=USER[,USER]`` (``USER`` alone with one course): teaching assistants.

    Raises
    ------
    ValueError
        Naming the option that is wrong and how to write it.
    """
    courses = list(dict.fromkeys(courses))
    if not courses:
        raise ValueError("no course: name one with --course ID (e.g. --course ipcv-2027)")
    for course in courses:
        if not _COURSE.match(course):
            raise ValueError(f"--course {course!r}: a course id is letters, digits, '_', '.', '-' "
                             "(nbgrader uses it as a folder name and in '+'-separated submission names)")
    teachers = _split(instructors, courses, "instructor")
    taught = _split(students, courses, "student")
    places = _split(folders, courses, "course-dir")
    helpers = _split(graders, courses, "grader")
    made = []
    seen: dict[str, str] = {}
    for course in courses:
        if len(teachers[course]) != 1:
            raise ValueError(f"course {course}: give exactly one instructor account (--instructor "
                             f"{'' if len(courses) == 1 else course + '='}USER), got {len(teachers[course])}; "
                             "nbgrader's formgrader and exchange belong to one account per course")
        instructor = teachers[course][0]
        if instructor in seen:
            raise ValueError(f"{instructor} is the instructor of {seen[instructor]} and {course}: nbgrader's "
                             "formgrader serves one course per server; make one instructor account per course "
                             f"(e.g. grader-{course})")
        seen[instructor] = course
        both = sorted(set(taught[course]) & {instructor})
        if both:
            raise ValueError(f"course {course}: {both[0]} cannot be its instructor and one of its students")
        both = sorted(set(taught[course]) & set(helpers[course]))
        if both:
            raise ValueError(f"course {course}: {both[0]} cannot grade it and take it (--grader and --student); "
                             "a grader would see every classmate's work and the grading salt")
        if instructor in helpers[course]:
            raise ValueError(f"course {course}: {instructor} is its instructor, who grades anyway: leave them out "
                             "of --grader")
        if len(places[course]) > 1:
            raise ValueError(f"course {course}: one --course-dir, got {len(places[course])}")
        folder = places[course][0] if places[course] else ""
        made.append(HubCourse(course, instructor, tuple(taught[course]), folder, tuple(helpers[course])))
    return tuple(made)


# ---------------------------------------------------------------------------- the machine
def _account(name: str, role: str) -> Any:
    import pwd

    if not _NAME.match(name) or "+" in name or "*" in name:
        raise HubSetupError(f"{role} {printable(name)!r} is not a Unix user name nbgrader can use (lower-case "
                            "letters, digits, '_', '.', '-'; no '+' or '*')")
    try:
        account = pwd.getpwnam(name)
    except KeyError:
        raise HubSetupError(f"{role} {name!r} has no Unix account on this machine: create it first "
                            f"(useradd --create-home {name}); the hub runs every user's JupyterLab as their "
                            "own account") from None
    if account.pw_uid == 0:
        raise HubSetupError(f"{role} {name!r} is root: the hub never runs a user's server as root; "
                            "make an ordinary account (useradd --create-home grader)")
    return account


def _find_proxy() -> str | None:
    return shutil.which("configurable-http-proxy") or next(
        (p for p in ("/usr/bin/configurable-http-proxy", "/usr/local/bin/configurable-http-proxy")
         if os.access(p, os.X_OK)), None)


def proxy_command(install: bool = False) -> tuple[str, ...]:
    """The command that runs configurable-http-proxy on this machine.

    Debian's ``node-configurable-http-proxy`` installs its modules in ``/usr/share/nodejs``,
    which only Debian's own ``node`` searches: with another Node.js (NodeSource's, nvm's) the
    proxy stops with "Cannot find module", and runs with ``NODE_PATH=/usr/share/nodejs``.

    Parameters
    ----------
    install : bool
        When the proxy is missing, install Debian's package with apt-get (as root, where there
        is apt-get), as cvkit installs bubblewrap.

    Raises
    ------
    HubSetupError
        When no proxy is installed or it does not run, saying how to install it.
    """
    found = _find_proxy()
    install_hint = (f"install it: apt-get install {PROXY_PACKAGE} (Debian and Ubuntu) or "
                    "npm install -g configurable-http-proxy")
    if found is None and install and shutil.which("apt-get") and os.geteuid() == 0:
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        apt = ["apt-get", "-o", "DPkg::Lock::Timeout=900", "install", "-y", "-q", "--no-install-recommends",
               PROXY_PACKAGE]
        done = subprocess.run(apt, capture_output=True, text=True, env=env, timeout=900)
        if done.returncode != 0:  # stale package lists: refresh them once
            subprocess.run(["apt-get", "-o", "DPkg::Lock::Timeout=900", "update", "-q"], capture_output=True,
                           env=env, timeout=900)
            done = subprocess.run(apt, capture_output=True, text=True, env=env, timeout=900)
        found = _find_proxy()
        if found is None:
            last = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
            raise HubSetupError(f"apt-get could not install {PROXY_PACKAGE} ({last[0][:200]}): run apt-get install "
                                f"{PROXY_PACKAGE} to see why, or npm install -g configurable-http-proxy")
    if found is None:
        raise HubSetupError(f"configurable-http-proxy (JupyterHub's proxy) is not installed: {install_hint}")
    tries: list[tuple[str, ...]] = [(found,)]
    if Path("/usr/share/nodejs/configurable-http-proxy").is_dir():
        tries.append(("/usr/bin/env", "NODE_PATH=/usr/share/nodejs", found))
    output = ""
    for command in tries:
        try:
            done = subprocess.run([*command, "--version"], capture_output=True, text=True, timeout=60)
        except OSError as error:
            output = str(error)
            continue
        if done.returncode == 0:
            return command
        output = (done.stderr or done.stdout).strip()
    raise HubSetupError(f"{found} does not run ({output.splitlines()[-1] if output else 'no output'}): "
                        f"reinstall it, {install_hint}")


def _reachable(path: Path) -> str | None:
    """Why other users cannot reach ``path`` (a parent without o+x), or None."""
    for folder in [path, *path.parents]:
        try:
            mode = folder.stat().st_mode
        except OSError:
            return f"{folder} does not exist"
        if not mode & stat.S_IXOTH:
            return f"{folder} has mode {stat.S_IMODE(mode):04o}: other users cannot pass through it"
    return None


def _port_problem(ip: str, port: int) -> str | None:
    with socket.socket(socket.AF_INET6 if ":" in ip else socket.AF_INET) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((ip or "0.0.0.0", port))
        except OSError as error:
            where = f"port {port} on {ip or 'all addresses'}"
            if error.errno == errno.EADDRINUSE:
                return f"{where} is in use ({error.strerror})"
            return f"{where} cannot be listened on ({error.strerror})"
    return None


def course_folder(course: HubCourse) -> Path:
    """The course folder of ``course``: its ``folder``, else ``~instructor/<course id>``."""
    return Path(course.folder) if course.folder else Path(course_home(course)) / course.id


def course_home(course: HubCourse) -> str:
    """The home of the course's instructor account (the root of its formgraders' servers)."""
    import pwd

    return pwd.getpwnam(course.instructor).pw_dir


def _free_port(taken: set[int]) -> int:
    while True:
        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            port = sock.getsockname()[1]
        if port not in taken:
            return port


# ---------------------------------------------------------------------------- writing
def _write(path: Path, text: str, mode: int = 0o644, written: list[Path] | None = None) -> None:
    write_whole(path, text, mode=mode)
    if written is not None:
        written.append(path)


def _folder(path: Path, mode: int, uid: int = 0, gid: int = 0) -> None:
    """``path`` made (with its parents) and given exactly ``mode``, ``uid`` and ``gid``."""
    path.mkdir(parents=True, exist_ok=True)
    os.chown(path, uid, gid, follow_symlinks=False)
    path.chmod(mode)


def _nbgrader_common(settings: HubSettings) -> str:
    lines = ["# generated by cvkit hub init: nbgrader's settings for every user of this hub",
             "c = get_config()  # noqa: F821",
             f"c.Exchange.root = {settings.exchange!r}",
             "# who takes which course: the JupyterHub groups nbgrader-<course> (students) and formgrade-<course>",
             "# (instructors), asked with the token of the user's server (or of a JupyterLab terminal); a user",
             "# outside a course can neither list, fetch nor submit its assignments",
             "from nbgrader.auth import JupyterHubAuthPlugin  # noqa: E402",
             "c.Authenticator.plugin_class = JupyterHubAuthPlugin",
             "# assignments are fetched into ~/<course>/<assignment>: two courses may name an assignment alike,",
             "# and adding a course later moves nobody's folders",
             "c.Exchange.path_includes_course = True"]
    if not settings.multi_course:
        lines += ["# one course: nbgrader's commands need no --course",
                  f"c.CourseDirectory.course_id = {settings.courses[0].id!r}"]
    return "\n".join(lines) + "\n"


def _formgrader_config(course_config: Path) -> str:
    """The instructor's nbgrader configuration for their server (the formgrader, the course list):
    the course's own, without leaving the grading switch on for the instructor's own kernels."""
    return ("# generated by cvkit hub init: the formgrader of this instructor serves this course\n"
            "import os as _os\n"
            "_trusted = _os.environ.get('CVKIT_TRUSTED_GRADING')\n"
            f"load_subconfig({str(course_config)!r})  # noqa: F821\n"
            "# the course's configuration tells nbgrader's kernels that checks are decided outside them; the\n"
            "# instructor's own notebooks in this server must keep checking for themselves\n"
            "if _trusted is None:\n    _os.environ.pop('CVKIT_TRUSTED_GRADING', None)\n")


def _role_files(settings: HubSettings, base: Path, written: list[Path]) -> None:
    _write(base / "common" / "nbgrader_config.py", _nbgrader_common(settings), written=written)
    for role in ROLE_PLUGINS:
        disabled = {f"@jupyter/nbgrader:{p}": p not in ROLE_PLUGINS[role] for p in LAB_PLUGINS}
        _write(base / role / "labconfig" / "page_config.json",
               json.dumps({"disabledExtensions": disabled}, indent=1) + "\n", written=written)
        extensions = {f"nbgrader.server_extensions.{e}": e in ROLE_SERVER_EXTENSIONS[role] for e in SERVER_EXTENSIONS}
        server: dict[str, Any] = {"ServerApp": {"jpserver_extensions": extensions}}
        if role == "instructor" and settings.subdomain_host:
            # every user has an origin of their own: the formgrader may show in a frame of the
            # instructor's own JupyterLab (frame-ancestors 'self' is that origin only)
            server["ServerApp"]["tornado_settings"] = {"headers": {"Content-Security-Policy": "frame-ancestors 'self'"}}
        _write(base / role / "jupyter_server_config.json", json.dumps(server, indent=1) + "\n", written=written)
    for course in settings.courses:
        _write(base / "users" / course.instructor / "nbgrader_config.py",
               _formgrader_config(course_folder(course) / "nbgrader_config.py"), written=written)


def _hub_config(settings: HubSettings) -> str:
    folder = Path(settings.folder)
    jupyter = folder / "jupyter"
    python_bin = settings.python_bin
    users = sorted({c.instructor for c in settings.courses} | set(settings.students) | set(settings.graders))
    groups = {}
    for course in settings.courses:
        groups[f"nbgrader-{course.id}"] = {"users": sorted(course.students)}
        groups[f"formgrade-{course.id}"] = {"users": [course.instructor, *sorted(course.graders)]}
    instructors = sorted(settings.instructors)
    graders = settings.graders
    shared = [course for course in settings.courses if course.shared_formgrader]
    services, service_roles = [], []
    for course in shared:
        services.append({
            "name": course.id, "display": True, "oauth_no_confirm": True,
            "url": f"http://127.0.0.1:{course.formgrader_port}",
            "command": [str(Path(python_bin) / "jupyterhub-singleuser"), f"--ServerApp.port={course.formgrader_port}",
                        "--ServerApp.ip=127.0.0.1"],
            "user": course.instructor, "cwd": course_home(course),
            "environment": {"JUPYTER_CONFIG_PATH": os.pathsep.join(
                                str(jupyter / part) for part in ("users/" + course.instructor, "instructor", "common")),
                            "PATH": f"{python_bin}:/usr/local/bin:/usr/bin:/bin", "LANG": "C.UTF-8",
                            "JUPYTERHUB_DEFAULT_URL": "/formgrader"}})
        service_roles.append({"name": f"formgrade-{course.id}", "groups": [f"formgrade-{course.id}"],
                              "description": f"open the shared formgrader of {course.id}",
                              "scopes": [f"access:services!service={course.id}"]})
        service_roles.append({"name": f"service-{course.id}", "services": [course.id],
                              "description": "nbgrader's course list in the shared formgrader",
                              "scopes": ["list:services", "read:services", "read:users:name", "read:users:groups"]})
    bind = f"http://{settings.ip}:{settings.port}"
    subdomains = (f"c.JupyterHub.subdomain_host = {settings.subdomain_host!r}" if settings.subdomain_host
                  else "# one origin for every user (cvkit hub init --subdomain-host gives each user a subdomain)")
    return f'''# generated by cvkit hub init on {_dt.date.today().isoformat()}: a JupyterHub for the course(s)
# {", ".join(c.id for c in settings.courses)}. Run `cvkit hub init` again to change it; put your own settings in
# {folder / "jupyterhub_config.d"}/*.py (loaded last, kept by cvkit hub init).
# docs/deploy-jupyterhub.md explains every line.
import glob
import os

c = get_config()  # noqa: F821

HUB = {str(folder)!r}
JUPYTER = {str(jupyter)!r}
INSTRUCTORS = {instructors!r}
GRADERS = {graders!r}  # teaching assistants: they grade in the shared formgrader of their courses

# ----------------------------------------------------------------- where the hub listens
c.JupyterHub.bind_url = {bind!r}
{subdomains}
c.JupyterHub.hub_ip = "127.0.0.1"
c.JupyterHub.hub_port = {settings.hub_port}
c.ConfigurableHTTPProxy.api_url = "http://127.0.0.1:{settings.proxy_api_port}"
c.ConfigurableHTTPProxy.command = {list(settings.proxy)!r}
c.ConfigurableHTTPProxy.pid_file = os.path.join(HUB, "state", "proxy.pid")
c.JupyterHub.pid_file = os.path.join(HUB, "state", "jupyterhub.pid")
c.JupyterHub.db_url = "sqlite:///" + os.path.join(HUB, "state", "jupyterhub.sqlite")
c.JupyterHub.cookie_secret_file = os.path.join(HUB, "state", "jupyterhub_cookie_secret")

# ----------------------------------------------------------------- who may log in (their Unix passwords)
c.JupyterHub.authenticator_class = "pam"
c.PAMAuthenticator.open_sessions = False  # no login session per server (fails in containers, not needed)
c.Authenticator.allowed_users = set({users!r})
c.Authenticator.admin_users = set()  # no hub administrator: instructors are ordinary users

# ----------------------------------------------------------------- every user's JupyterLab, as that user
c.JupyterHub.spawner_class = "localprocess"
c.Spawner.cmd = [{str(Path(python_bin) / "jupyterhub-singleuser")!r}]
c.Spawner.default_url = "/lab"
c.Spawner.start_timeout = 120
c.Spawner.http_timeout = 120


def jupyter_config_path(spawner):
    """Each role's Jupyter configuration: which nbgrader extensions it sees, and for an
    instructor the formgrader's course; then nbgrader's exchange, for everyone."""
    name = spawner.user.name
    if name in INSTRUCTORS:
        parts = [os.path.join(JUPYTER, "users", name), os.path.join(JUPYTER, "instructor")]
    elif name in GRADERS:
        parts = [os.path.join(JUPYTER, "grader")]
    else:
        parts = [os.path.join(JUPYTER, "student")]
    return os.pathsep.join(parts + [os.path.join(JUPYTER, "common")])


c.Spawner.environment = {{
    "JUPYTER_CONFIG_PATH": jupyter_config_path,
    "PATH": {python_bin!r} + ":/usr/local/bin:/usr/bin:/bin",
    "LANG": "C.UTF-8",
}}

# ----------------------------------------------------------------- nbgrader's courses
# groups nbgrader-<course> (students) and formgrade-<course> (instructors): nbgrader's
# JupyterHubAuthPlugin reads them to show each user their own courses
c.JupyterHub.load_groups = {json.dumps(groups, indent=4)}
# nbgrader's JupyterHubAuthPlugin asks the hub for the user's groups with the token of the user's
# server (JupyterHub >= 2 lets every token read its own user's name and groups; listed below all
# the same); nbgrader's course list, in an instructor's or grader's server, also asks for the hub's
# services (GET /hub/api/services) and their addresses, which needs list:services and read:services:
# without them the list shows an error
c.JupyterHub.load_roles = [
    {{"name": "cvkit-instructors", "description": "nbgrader's course list may list the hub's services",
     "scopes": ["list:services", "read:services"], "users": INSTRUCTORS + GRADERS}},
]
# the shared formgrader of each course with graders: a JupyterLab running as the course's instructor
# account on the course folder, a service only the members of formgrade-<course> may open
# (nbgrader's "one class, multiple graders"); its own token may list the services and read names
c.JupyterHub.services = {pprint.pformat(services, width=110, sort_dicts=False)}
c.JupyterHub.load_roles += {pprint.pformat(service_roles, width=110, sort_dicts=False)}


def server_token_scopes(spawner):
    scopes = ["users:activity!user", "access:servers!server", "read:users:name!user", "read:users:groups!user"]
    if spawner.user.name in INSTRUCTORS or spawner.user.name in GRADERS:
        scopes += ["list:services", "read:services"]  # the shared formgraders' addresses (their prefix)
    return scopes


c.Spawner.server_token_scopes = server_token_scopes

# ----------------------------------------------------------------- the hub administrator's additions
for extra in sorted(glob.glob(os.path.join(HUB, "jupyterhub_config.d", "*.py"))):
    load_subconfig(extra)  # noqa: F821
'''


def _systemd_unit(settings: HubSettings) -> str:
    cvkit = Path(settings.python_bin) / "cvkit"
    return f"""# generated by cvkit hub init: systemctl link {Path(settings.folder) / 'jupyterhub.service'}
[Unit]
Description=JupyterHub of the cvkit course(s) {", ".join(c.id for c in settings.courses)}
After=network.target

[Service]
User=root
WorkingDirectory={settings.folder}
ExecStart={cvkit} hub start --hub-dir {settings.folder}
Restart=on-failure

[Install]
WantedBy=multi-user.target
"""


def _course_setup(settings: HubSettings, course: HubCourse, written: list[Path]) -> None:
    """The course folder (cvkit's, private to the instructor) and the course's exchange folders."""
    from .plan import plan_toml, read_plan
    from .state import CourseState

    account = _account(course.instructor, f"the instructor of {course.id}")
    folder = course_folder(course)
    project = Path(settings.project)
    fresh = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    made = CourseState(folder, project=project)
    plan_file = folder / "plan.toml"
    if plan_file.exists():
        plan = read_plan(plan_file)
        if plan.course_id and plan.course_id != course.id:
            raise HubSetupError(f"{plan_file} names the course {plan.course_id!r}, the hub's is {course.id!r}: "
                                f"change its [course] id (or the --course option)")
        if not plan.course_id:
            raise HubSetupError(f"{plan_file} has no [course] id: add [course] id = {json.dumps(course.id)} to it")
    else:
        plan = read_plan(made.plan_path, [p.name for p in sorted(made.source_dir.glob('ch*_*')) if p.is_dir()])
        _write(plan_file, plan_toml(plan, course.id), written=written)
    config = folder / "nbgrader_config.py"
    text = config.read_text()
    marker = "\n# cvkit hub init: nbgrader's exchange of this hub\n"
    block = f"{marker}c.Exchange.root = {settings.exchange!r}  # noqa: F821\n"
    if marker in text:
        text = text[:text.index(marker)]
    _write(config, text.rstrip("\n") + "\n" + block, mode=0o644, written=written)
    for path in [folder, *folder.rglob("*")]:
        os.chown(path, account.pw_uid, account.pw_gid, follow_symlinks=False)
    folder.chmod(0o700)  # the gradebook, the salt, every submission: the instructor's only
    if fresh:
        written.append(folder)
    exchange = Path(settings.exchange) / course.id
    _folder(exchange, EXCHANGE_MODES["course"], account.pw_uid, account.pw_gid)
    for part in ("outbound", "inbound", "feedback"):
        _folder(exchange / part, EXCHANGE_MODES[part], account.pw_uid, account.pw_gid)


def init_hub(settings: HubSettings) -> tuple[list[Path], list[str]]:
    """Write what a JupyterHub needs for ``settings``' courses (see the module docstring).

    Returns
    -------
    (list of Path, list of str)
        What was written, and warnings for the hub administrator (each saying what to do).

    Raises
    ------
    HubSetupError
        Before writing anything, when it cannot be done: not root, an account missing or root,
        no proxy, a folder users cannot reach.
    """
    if os.geteuid() != 0:
        raise HubSetupError("cvkit hub init must run as root: it makes the exchange and the course folders for "
                            "their owners, and the hub it sets up runs as root to start each user's server as them")
    folder = Path(settings.folder).resolve()
    project = Path(settings.project).resolve()
    for course in settings.courses:
        _account(course.instructor, f"the instructor of {course.id}")
        for student in course.students:
            _account(student, f"student of {course.id}")
        for grader in course.graders:
            _account(grader, f"grader of {course.id}")
    taken = {settings.port, settings.hub_port, settings.proxy_api_port} | {c.formgrader_port for c in settings.courses}
    courses = []
    for course in settings.courses:
        if course.shared_formgrader and not course.formgrader_port:
            course = HubCourse(**{**asdict(course), "formgrader_port": _free_port(taken)})
            taken.add(course.formgrader_port)
        courses.append(course)
    settings = HubSettings(**{**asdict(settings), "courses": tuple(courses)})
    proxy = settings.proxy or proxy_command(install=True)
    folder.mkdir(parents=True, exist_ok=True)
    for what, path in (("the hub folder", folder), ("the Python environment", Path(settings.python_bin)),
                       ("the cvkit project", project), ("the exchange", Path(settings.exchange).parent)):
        problem = _reachable(path)
        if problem:
            raise HubSetupError(f"every user's server needs {what} ({path}), but {problem}: make it (and its "
                                "parents) o+x, or choose another place")
    settings = HubSettings(**{**asdict(settings), "courses": settings.courses, "folder": str(folder),
                              "project": str(project), "proxy": tuple(proxy),
                              "exchange": str(Path(settings.exchange).resolve())})
    written: list[Path] = []
    _folder(folder, 0o755)
    _folder(folder / "state", 0o700)
    (folder / "jupyterhub_config.d").mkdir(exist_ok=True)
    _folder(Path(settings.exchange), EXCHANGE_MODES["root"])
    for course in settings.courses:
        _course_setup(settings, course, written)
    _role_files(settings, folder / "jupyter", written)
    _write(folder / "jupyterhub_config.py", _hub_config(settings), written=written)
    _write(folder / "jupyterhub.service", _systemd_unit(settings), written=written)
    _write(folder / SETTINGS_FILE, settings.to_json(), written=written)
    warnings = check_hub(settings, ports=False)
    import pwd

    for course in settings.courses:
        home = Path(pwd.getpwnam(course.instructor).pw_dir).resolve()
        place = course_folder(course).resolve()
        if home not in place.parents:
            warnings.append(f"the course folder {place} of {course.id} is not inside {course.instructor}'s home "
                            f"{home}: nbgrader's formgrader only serves a course folder inside the server's root "
                            "(the home); choose a --course-dir there")
    return written, warnings


# ---------------------------------------------------------------------------- checking
def _mode_problem(path: Path, mode: int, owner: str, what: str, why: str) -> str | None:
    import pwd

    try:
        info = path.lstat()
    except FileNotFoundError:
        return f"{what} {path} does not exist: run cvkit hub init again"
    if stat.S_ISLNK(info.st_mode) or not stat.S_ISDIR(info.st_mode):
        return f"{what} {path} is not a folder: remove it and run cvkit hub init again"
    try:
        found = pwd.getpwuid(info.st_uid).pw_name
    except KeyError:
        found = str(info.st_uid)
    problems = []
    if found != owner:
        problems.append(f"owned by {found}, not {owner} (chown {owner} {path})")
    if stat.S_IMODE(info.st_mode) != mode:
        problems.append(f"mode {stat.S_IMODE(info.st_mode):04o}, not {mode:04o} (chmod {mode:04o} {path}): {why}")
    return f"{what} {path} is " + "; ".join(problems) if problems else None


def check_hub(settings: HubSettings, ports: bool = True) -> list[str]:
    """What is wrong with a hub set up by ``cvkit hub init``, each problem with what to do.

    Checks the exchange's owners and modes (nbgrader's own, see :data:`EXCHANGE_MODES`), that
    course folders and users' homes are private, that the proxy runs, and (``ports``) that the
    hub's ports are free.
    """
    problems: list[str | None] = []
    exchange = Path(settings.exchange)
    problems.append(_mode_problem(exchange, EXCHANGE_MODES["root"], "root", "the exchange",
                                  "nbgrader needs everyone to write it, and the sticky bit keeps a student from "
                                  "removing or replacing a course's folder"))
    whys = {"course": "the course's own folder", "outbound": "students read the released assignments",
            "inbound": "students may write their submissions there but never list them",
            "feedback": "students read their own page by its secret name but never list them"}
    for course in settings.courses:
        base = exchange / course.id
        problems.append(_mode_problem(base, EXCHANGE_MODES["course"], course.instructor,
                                      f"the exchange folder of {course.id}", whys["course"]))
        for part in ("outbound", "inbound", "feedback"):
            problems.append(_mode_problem(base / part, EXCHANGE_MODES[part], course.instructor,
                                          f"the exchange's {part} of {course.id}", whys[part]))
        folder = course_folder(course)
        try:
            mode = stat.S_IMODE(folder.stat().st_mode)
        except OSError:
            problems.append(f"the course folder {folder} of {course.id} does not exist: run cvkit hub init again")
            continue
        if mode & 0o077:
            problems.append(f"the course folder {folder} of {course.id} has mode {mode:04o}: other users can reach "
                            f"the gradebook, the grading salt and every submission; chmod 0700 {folder}")
    import pwd

    for name in sorted(set(settings.students) | set(settings.instructors)):
        try:
            home = Path(pwd.getpwnam(name).pw_dir)
            mode = stat.S_IMODE(home.stat().st_mode)
        except (KeyError, OSError):
            problems.append(f"user {name} has no account or home: create it (useradd --create-home {name})")
            continue
        if mode & 0o007:
            problems.append(f"the home {home} of {name} has mode {mode:04o}: other users can read what {name} "
                            f"fetched, wrote and submitted (and their nbgrader cache, with the secret that "
                            f"fetches their feedback); chmod 0700 {home}")
    try:
        if not settings.proxy:
            proxy_command()
        else:
            subprocess.run([*settings.proxy, "--version"], capture_output=True, check=True, timeout=60)
    except HubSetupError as error:
        problems.append(str(error))
    except (OSError, subprocess.SubprocessError):
        problems.append(f"the proxy {' '.join(settings.proxy)} does not run: install it again "
                        f"(apt-get install {PROXY_PACKAGE}) and run cvkit hub init again")
    if ports:
        problems += start_problems(settings)
    return [p for p in problems if p]


def start_problems(settings: HubSettings) -> list[str]:
    """Why the hub could not start now: not root, or one of its ports taken."""
    problems = []
    if os.geteuid() != 0:
        problems.append("the hub must run as root (LocalProcessSpawner starts each user's server as that user)")
    for what, ip, port, option in (("the hub's address", settings.ip, settings.port, "--port"),
                                   ("the hub's API", "127.0.0.1", settings.hub_port, "--hub-port"),
                                   ("the proxy's API", "127.0.0.1", settings.proxy_api_port, "--proxy-api-port")):
        problem = _port_problem(ip, port)
        if problem:
            problems.append(f"{what}: {problem}: stop what uses it (a hub already running?) or run cvkit hub init "
                            f"again with another {option}")
    for course in settings.courses:
        problem = _port_problem("127.0.0.1", course.formgrader_port) if course.shared_formgrader else None
        if problem:
            problems.append(f"the shared formgrader of {course.id}: {problem}: stop what uses it (a hub already "
                            f"running?) or set \"formgrader_port\" of {course.id} in {Path(settings.folder) / SETTINGS_FILE} "
                            "to a free port and run cvkit hub init again")
    return problems


# ---------------------------------------------------------------------------- the exchange, for grading
def exchange_notes(course: CourseState, assignments: Iterable[str]) -> list[str]:
    """What the instructor must know about nbgrader's exchange before feedback goes back, for
    ``assignments`` of a course on a hub (nothing for a course without an exchange):

    - a submission in the exchange that was not collected (a student submitted again after the
      collection, or was never collected): ``nbgrader collect --update``;
    - a graded submission without ``submission_secret.txt`` (submitted with nbgrader older than
      0.9.3, or placed by hand): ``nbgrader release_feedback`` stops at it (it opens that file
      for every page), so the command to release everyone else's is given, and what to do for
      that student.
    """
    from .received import _exchange_folder, _names, exchange_time

    exchange = _exchange_folder(course)
    if exchange is None:
        return []
    inbound = exchange / "inbound"
    notes: list[str] = []
    names = _names(inbound)
    missing: dict[str, list[str]] = {}
    for assignment in sorted(set(assignments)):
        empty = {key.partition("/")[0] for key in course.without_notebooks([assignment])}  # named by the grade run
        collected = {s for s, a in course.submissions([assignment])} | empty
        submitted: dict[str, list[str]] = {}
        for name in names:
            student, _, rest = name.partition("+")
            if rest.startswith(f"{assignment}+"):
                submitted.setdefault(student, []).append(name)
        for student in sorted(set(submitted) - collected):
            notes.append(f"exchange: {printable(student)} submitted {assignment} ({len(submitted[student])} time"
                         f"{'s' * (len(submitted[student]) != 1)}) but nothing was collected: run nbgrader collect "
                         f"{assignment} in {course.root}, then cvkit course grade")
        for student in sorted((collected - empty) & set(submitted)):
            files = course.submission_files(student, assignment)
            notebooks = {n: d for n, d in files.items() if n.endswith(".ipynb")}
            when = exchange_time(inbound, student, assignment, notebooks)
            if when is None:
                continue
            newer = [n for n in submitted[student] if not _same_as(inbound / n, notebooks)
                     and (_ctime(inbound / n) or when) > when]
            if newer:
                due = course.plan().due(assignment)
                latest = max(_ctime(inbound / n) or when for n in newer)
                late = " (it came after the due date: it will be graded late)" if due and latest > due else ""
                notes.append(f"exchange: {printable(student)} submitted {assignment} again after the collection "
                             f"({len(newer)} newer submission{'s' * (len(newer) != 1)}; graded: the one received "
                             f"{when:%Y-%m-%d %H:%M:%S} UTC): to grade the newest{late}, run nbgrader collect "
                             f"--update {assignment} in {course.root}, then cvkit course grade (only that submission "
                             "is graded again)")
        for student in sorted(collected - empty):
            folder = course.root / "submitted" / student / assignment
            if not (folder / "submission_secret.txt").is_file():
                missing.setdefault(assignment, []).append(student)
    for assignment, students in sorted(missing.items()):
        shown = ", ".join(printable(s) for s in students)
        notes.append(f"feedback: {shown} handed in {assignment} without submission_secret.txt (submitted with nbgrader "
                     f"older than 0.9.3, or placed by hand): nbgrader release_feedback {assignment} stops at the first "
                     f"such page; release everyone else's with: nbgrader release_feedback {assignment} "
                     f"--CourseDirectory.student_id_exclude={','.join(students)}; for {shown}: ask them to submit "
                     f"again (nbgrader 0.9.3 or later), or give them their page from "
                     f"{course.root / 'feedback'}/<student>/{assignment}/")
    return notes


def _ctime(path: Path) -> _dt.datetime | None:
    try:
        return _dt.datetime.fromtimestamp(path.lstat().st_ctime, tz=_dt.timezone.utc).replace(tzinfo=None)
    except OSError:
        return None


def _same_as(folder: Path, notebooks: dict[str, bytes]) -> bool:
    """True when ``folder`` holds exactly these notebooks, byte for byte."""
    from .received import _same_file

    return bool(notebooks) and all(_same_file(folder / n, d) is not None for n, d in notebooks.items())
