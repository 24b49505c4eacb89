"""What ``cvkit hub init`` writes and what the exchange tells the instructor, without a hub
(``tests/system/test_hub_round_trip.py`` runs the real one): the options, the generated files, a
course folder's configuration for plain ``nbgrader``, the plan it gets, the notes about hand-ins
that were not collected or came without their secret, and the collected ``timestamp.txt`` made
the trusted time (nbgrader's formgrader needs it), the student's own kept for the cross-check.
"""
import datetime as dt
import json
import os
import re
from pathlib import Path

import pytest
from test_course_scaling import ASSIGNMENT
from test_course_scaling import project  # noqa: F401  (the tiny chapter's project, a fixture)

from cvkit.cli import main
from cvkit.course import Course, received
from cvkit.course.hub import (
    HubCourse, HubSettings, HubSetupError, _hub_config, _role_files, courses_from_options, exchange_notes,
    load_settings,
)
from cvkit.course.plan import LatePolicy, Plan, PlannedAssignment, plan_toml, read_plan

NOTEBOOK = f"{ASSIGNMENT}.ipynb"


# ---------------------------------------------------------------------------- the options
def test_one_course_takes_plain_names():
    (course,) = courses_from_options(["ipcv"], ["grader"], ["ada,bob", "cyd", "ada"])
    assert course == HubCourse("ipcv", "grader", ("ada", "bob", "cyd"), "")


def test_several_courses_say_whose_is_whose():
    courses = courses_from_options(["ipcv", "lab"], ["ipcv=grader", "lab=grader-lab"],
                                   ["ipcv=ada,bob", "lab=ada"], ["lab=/srv/lab"])
    assert courses == (HubCourse("ipcv", "grader", ("ada", "bob"), ""),
                       HubCourse("lab", "grader-lab", ("ada",), "/srv/lab"))


@pytest.mark.parametrize("courses, instructors, students, message", [
    ([], [], [], "no course: name one with --course ID"),
    (["ipcv+1"], ["g"], [], "--course 'ipcv+1': a course id is letters, digits"),
    (["a", "b"], ["a=g", "b=h"], ["ada"], "--student ada: with several courses, say which: --student COURSE=ada"),
    (["a"], ["b=g"], [], "--instructor b=g: no course 'b' (courses: a)"),
    (["a"], [], [], "course a: give exactly one instructor account (--instructor USER), got 0"),
    (["a"], ["g,h"], [], "course a: give exactly one instructor account (--instructor USER), got 2"),
    (["a", "b"], ["a=g", "b=g"], [], "g is the instructor of a and b: nbgrader's formgrader serves one course per "
                                     "server; make one instructor account per course (e.g. grader-b)"),
    (["a"], ["g"], ["ada,g"], "course a: g cannot be its instructor and one of its students"),
])
def test_wrong_options_say_what_to_write(courses, instructors, students, message):
    with pytest.raises(ValueError) as caught:
        courses_from_options(courses, instructors, students)
    assert str(caught.value).startswith(message)


def test_a_missing_hub_says_to_make_it(tmp_path):
    with pytest.raises(HubSetupError, match=f"{tmp_path / 'cvkit-hub.json'} does not exist: run cvkit hub init "
                                            f"--hub-dir {tmp_path} first"):
        load_settings(tmp_path)
    (tmp_path / "cvkit-hub.json").write_text("{}")
    with pytest.raises(HubSetupError, match="is not the settings cvkit hub init writes"):
        load_settings(tmp_path)


@pytest.mark.skipif(os.geteuid() == 0, reason="as root cvkit hub init would go on")
def test_hub_init_needs_root(tmp_path, capsys):
    status = main(["hub", "init", "--hub-dir", str(tmp_path / "hub"), "--course", "c", "--instructor", "g"])
    assert status == 2 and "cvkit hub init must run as root" in capsys.readouterr().err


# ---------------------------------------------------------------------------- the files
def _settings(tmp_path, *courses, subdomain=""):
    return HubSettings(folder=str(tmp_path / "hub"), courses=courses, exchange=str(tmp_path / "exchange"),
                       port=8123, hub_port=8124, proxy_api_port=8125, subdomain_host=subdomain,
                       project=str(tmp_path), proxy=("/usr/bin/configurable-http-proxy",))


def test_each_role_sees_its_own_extensions(tmp_path):
    settings = _settings(tmp_path, HubCourse("ipcv", "grader", ("ada",), str(tmp_path / "ipcv")))
    written: list = []
    _role_files(settings, tmp_path / "jupyter", written)
    page = {role: json.loads((tmp_path / "jupyter" / role / "labconfig" / "page_config.json").read_text())
            for role in ("student", "instructor")}
    assert page["student"]["disabledExtensions"] == {
        "@jupyter/nbgrader:formgrader": True, "@jupyter/nbgrader:assignment-list": False,
        "@jupyter/nbgrader:course-list": True, "@jupyter/nbgrader:create-assignment": True,
        "@jupyter/nbgrader:validate-assignment": False}
    assert not any(page["instructor"]["disabledExtensions"].values())
    server = json.loads((tmp_path / "jupyter" / "student" / "jupyter_server_config.json").read_text())["ServerApp"]
    assert server == {"jpserver_extensions": {
        "nbgrader.server_extensions.formgrader": False, "nbgrader.server_extensions.assignment_list": True,
        "nbgrader.server_extensions.course_list": False, "nbgrader.server_extensions.validate_assignment": True}}
    instructor = json.loads((tmp_path / "jupyter" / "instructor" / "jupyter_server_config.json").read_text())
    assert "tornado_settings" not in instructor["ServerApp"]  # one origin: JupyterHub's frame-ancestors 'none' stays
    common = (tmp_path / "jupyter" / "common" / "nbgrader_config.py").read_text()
    assert f"c.Exchange.root = {str(tmp_path / 'exchange')!r}" in common
    assert "c.CourseDirectory.course_id = 'ipcv'" in common and "c.Exchange.path_includes_course = True" in common
    formgrader = (tmp_path / "jupyter" / "users" / "grader" / "nbgrader_config.py").read_text()
    assert f"load_subconfig({str(tmp_path / 'ipcv' / 'nbgrader_config.py')!r})" in formgrader
    assert len(written) == 8  # common, the instructor's formgrader, three roles' lab and server settings


def test_subdomains_let_the_formgrader_show_in_the_instructors_jupyterlab(tmp_path):
    settings = _settings(tmp_path, HubCourse("a", "g", (), str(tmp_path / "a")), HubCourse("b", "h", (), str(tmp_path / "b")),
                         subdomain="https://hub.example.org")
    _role_files(settings, tmp_path / "jupyter", [])
    instructor = json.loads((tmp_path / "jupyter" / "instructor" / "jupyter_server_config.json").read_text())
    assert instructor["ServerApp"]["tornado_settings"] == {"headers": {"Content-Security-Policy": "frame-ancestors 'self'"}}
    student = json.loads((tmp_path / "jupyter" / "student" / "jupyter_server_config.json").read_text())
    assert "tornado_settings" not in student["ServerApp"]
    assert "course_id" not in (tmp_path / "jupyter" / "common" / "nbgrader_config.py").read_text()  # several courses
    assert "c.JupyterHub.subdomain_host = 'https://hub.example.org'" in _hub_config(settings)


def test_the_hub_configuration_runs(tmp_path):
    """jupyterhub_config.py, run as JupyterHub runs it: the settings each server gets."""
    from traitlets.config import Config

    settings = _settings(tmp_path, HubCourse("ipcv", "grader", ("ada", "bob"), str(tmp_path / "ipcv")))
    config = Config()
    namespace = {"get_config": lambda: config, "c": config, "load_subconfig": lambda name: None}
    exec(compile(_hub_config(settings), "jupyterhub_config.py", "exec"), namespace)
    assert config.JupyterHub.bind_url == "http://127.0.0.1:8123"
    assert config.Authenticator.allowed_users == {"ada", "bob", "grader"}
    assert config.Authenticator.admin_users == set()
    assert config.JupyterHub.load_groups == {"nbgrader-ipcv": {"users": ["ada", "bob"]},
                                             "formgrade-ipcv": {"users": ["grader"]}}
    assert config.ConfigurableHTTPProxy.command == ["/usr/bin/configurable-http-proxy"]

    class Spawner:
        def __init__(self, name):
            self.user = type("User", (), {"name": name})()

    hub = tmp_path / "hub" / "jupyter"
    path = config.Spawner.environment["JUPYTER_CONFIG_PATH"]
    assert path(Spawner("ada")) == f"{hub / 'student'}:{hub / 'common'}"
    assert path(Spawner("grader")) == f"{hub / 'users' / 'grader'}:{hub / 'instructor'}:{hub / 'common'}"
    assert config.Spawner.environment["PATH"].startswith(f"{settings.python_bin}:")
    assert "list:services" in config.Spawner.server_token_scopes(Spawner("grader"))
    assert "list:services" not in config.Spawner.server_token_scopes(Spawner("ada"))


def test_teaching_assistants_grade_in_the_courses_shared_formgrader(tmp_path):
    """A course with graders: a service named after the course runs a JupyterLab as the
    instructor account on its home (the course folder inside), which only formgrade-<course> opens;
    the graders' own servers list the courses they grade and nothing else of nbgrader's."""
    import pwd

    from traitlets.config import Config

    owner = pwd.getpwuid(os.getuid()).pw_name  # any account with a home: only its home is read
    (shared, alone) = courses_from_options(["ipcv", "lab"], [f"ipcv={owner}", "lab=grader-lab"], ["ipcv=ada", "lab=ada"],
                                           graders=["ipcv=tim,tia", "ipcv=tim"])
    assert shared.graders == ("tim", "tia") and alone.graders == () and shared.shared_formgrader
    shared = HubCourse(**{**shared.__dict__, "folder": str(tmp_path / "ipcv"), "formgrader_port": 8200})
    alone = HubCourse(**{**alone.__dict__, "folder": str(tmp_path / "lab")})
    settings = _settings(tmp_path, shared, alone)
    config = Config()
    namespace = {"get_config": lambda: config, "c": config, "load_subconfig": lambda name: None}
    exec(compile(_hub_config(settings), "jupyterhub_config.py", "exec"), namespace)
    assert config.Authenticator.allowed_users == {"ada", owner, "grader-lab", "tim", "tia"}
    assert config.JupyterHub.load_groups["formgrade-ipcv"] == {"users": [owner, "tia", "tim"]}
    assert config.JupyterHub.load_groups["formgrade-lab"] == {"users": ["grader-lab"]}
    (service,) = config.JupyterHub.services
    hub = tmp_path / "hub" / "jupyter"
    assert service["name"] == "ipcv" and service["user"] == owner and service["url"] == "http://127.0.0.1:8200"
    assert service["cwd"] == pwd.getpwnam(owner).pw_dir and service["oauth_no_confirm"] is True
    assert service["command"][0].endswith("jupyterhub-singleuser") and "--ServerApp.port=8200" in service["command"]
    assert service["environment"]["JUPYTER_CONFIG_PATH"] == f"{hub / 'users' / owner}:{hub / 'instructor'}:{hub / 'common'}"
    roles = {role["name"]: role for role in config.JupyterHub.load_roles}
    assert roles["formgrade-ipcv"]["groups"] == ["formgrade-ipcv"]
    assert roles["formgrade-ipcv"]["scopes"] == ["access:services!service=ipcv"]
    assert "formgrade-lab" not in roles  # no graders: the instructor's own formgrader, as before
    assert roles["service-ipcv"]["services"] == ["ipcv"] and "list:services" in roles["service-ipcv"]["scopes"]

    class Spawner:
        def __init__(self, name):
            self.user = type("User", (), {"name": name})()

    path = config.Spawner.environment["JUPYTER_CONFIG_PATH"]
    assert path(Spawner("tim")) == f"{hub / 'grader'}:{hub / 'common'}"
    assert "list:services" in config.Spawner.server_token_scopes(Spawner("tim"))
    _role_files(settings, hub, [])
    grader = json.loads((hub / "grader" / "labconfig" / "page_config.json").read_text())["disabledExtensions"]
    assert {k for k, v in grader.items() if v} == {"@jupyter/nbgrader:formgrader", "@jupyter/nbgrader:create-assignment"}
    server = json.loads((hub / "grader" / "jupyter_server_config.json").read_text())["ServerApp"]["jpserver_extensions"]
    assert server["nbgrader.server_extensions.course_list"] and not server["nbgrader.server_extensions.formgrader"]


@pytest.mark.parametrize("graders, students, message", [
    (["ipcv=ada"], ["ipcv=ada"], "ada cannot grade it and take it (--grader and --student)"),
    (["ipcv=grader"], [], "grader is its instructor, who grades anyway: leave them out of --grader"),
    (["other=tim"], [], "--grader other=tim: no course 'other'"),
])
def test_wrong_graders_say_what_to_write(graders, students, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        courses_from_options(["ipcv"], ["grader"], students, graders=graders)


# ---------------------------------------------------------------------------- the course folder
def test_the_course_plan_names_the_course_and_reads_back(tmp_path):
    plan = Plan((PlannedAssignment("ch03", 'Filters "and" more', dt.datetime(2027, 3, 8, 22, 59)),
                 PlannedAssignment("ch04")), LatePolicy("per_hour", 0.5), "cvkit-ipcv", "IPCV")
    path = tmp_path / "plan.toml"
    path.write_text(plan_toml(plan, "ipcv-2027"))
    again = read_plan(path)
    assert (again.course_id, again.title, again.assignments, again.late) == (
        "ipcv-2027", "IPCV", plan.assignments, plan.late)
    path.write_text('[course]\nid = "a+b"\n')
    with pytest.raises(ValueError, match=r"\[course\] id must be letters, digits"):
        read_plan(path)


def test_plain_nbgrader_in_a_course_folder_works_on_that_folder(project, tmp_path):  # noqa: F811
    """The course folder's nbgrader_config.py roots the project's configuration there (it read
    the project's autograders/ before), names the plan's course, and leaves the environment as
    it found it."""
    from traitlets.config.loader import PyFileConfigLoader

    folder = tmp_path / "course"
    Course(folder, project=project)
    (folder / "plan.toml").write_text(f'[course]\nid = "ipcv"\n\n[[assignment]]\nid = "{ASSIGNMENT}"\n')
    saved = os.environ.pop("CVKIT_COURSE_ROOT", None)
    try:
        config = PyFileConfigLoader("nbgrader_config.py", path=str(folder)).load_config()
        assert "CVKIT_COURSE_ROOT" not in os.environ
    finally:
        os.environ.pop("CVKIT_TRUSTED_GRADING", None)
        if saved is not None:
            os.environ["CVKIT_COURSE_ROOT"] = saved
    assert config.CourseDirectory.root == str(folder.resolve())
    assert config.CourseDirectory.db_url == f"sqlite:///{folder.resolve() / 'gradebook.db'}"
    assert config.CourseDirectory.course_id == "ipcv"


# ---------------------------------------------------------------------------- the exchange's notes
@pytest.fixture
def course(project, tmp_path):  # noqa: F811 - the imported fixture
    """A course folder whose configuration has an exchange, as cvkit hub init writes it."""
    folder = tmp_path / "course"
    made = Course(folder, project=project)
    (folder / "plan.toml").write_text(f'[course]\nid = "ipcv"\n\n[[assignment]]\nid = "{ASSIGNMENT}"\n'
                                      'due = "2030-01-01 00:00:00 UTC"\n')
    with (folder / "nbgrader_config.py").open("a") as handle:
        handle.write(f"c.Exchange.root = {str(tmp_path / 'exchange')!r}\n")
    made.inbound = tmp_path / "exchange" / "ipcv" / "inbound"
    made.inbound.mkdir(parents=True)
    return made


def _hand_in(inbound, student, when, notebook, secret=True):
    folder = inbound / f"{student}+{ASSIGNMENT}+{when} UTC+AbCdEfGhIjKl"
    folder.mkdir()
    (folder / NOTEBOOK).write_bytes(notebook)
    (folder / "timestamp.txt").write_text(f"{when} UTC")
    if secret:
        (folder / "submission_secret.txt").write_text("0" * 128)
    return folder


def _collect(course, hand_in):
    target = course.root / "submitted" / hand_in.name.split("+")[0] / ASSIGNMENT
    target.mkdir(parents=True)
    for path in hand_in.iterdir():
        (target / path.name).write_bytes(path.read_bytes())


def test_hand_ins_not_collected_and_without_secret_are_named_with_what_to_do(course):
    ada = _hand_in(course.inbound, "ada", "2029-12-31 10:00:00.000000", b'{"cells": []}')
    _collect(course, ada)
    old = _hand_in(course.inbound, "bob", "2029-12-31 11:00:00.000000", b'{"v": 1}', secret=False)
    _collect(course, old)
    _hand_in(course.inbound, "bob", "2030-01-01 01:00:00.000000", b'{"v": 2}')
    _hand_in(course.inbound, "cyd", "2029-12-31 12:00:00.000000", b'{"v": 3}')
    notes = exchange_notes(course, [ASSIGNMENT])
    when = received.exchange_time(course.inbound, "bob", ASSIGNMENT, {NOTEBOOK: b'{"v": 1}'})
    assert notes == [
        f"exchange: cyd submitted {ASSIGNMENT} (1 time) but nothing was collected: run nbgrader collect {ASSIGNMENT} "
        f"in {course.root}, then cvkit course grade",
        f"exchange: bob submitted {ASSIGNMENT} again after the collection (1 newer submission; graded: the one received "
        f"{when:%Y-%m-%d %H:%M:%S} UTC): to grade the newest, run nbgrader collect --update {ASSIGNMENT} in "
        f"{course.root}, then cvkit course grade (only that submission is graded again)",
        f"feedback: bob handed in {ASSIGNMENT} without submission_secret.txt (submitted with nbgrader older than 0.9.3, "
        f"or placed by hand): nbgrader release_feedback {ASSIGNMENT} stops at the first such page; release everyone "
        f"else's with: nbgrader release_feedback {ASSIGNMENT} --CourseDirectory.student_id_exclude=bob; for bob: ask "
        f"them to submit again (nbgrader 0.9.3 or later), or give them their page from "
        f"{course.root / 'feedback'}/<student>/{ASSIGNMENT}/",
    ]


def test_a_course_without_an_exchange_has_no_notes(project, tmp_path):  # noqa: F811
    course = Course(tmp_path / "bench", project=project)
    course.submit("ada", ASSIGNMENT, {NOTEBOOK: {"cells": []}})  # no secret: lab-bench hand-ins never have one
    assert exchange_notes(course, [ASSIGNMENT]) == []


def test_the_collected_time_becomes_the_trusted_one_and_the_claim_is_kept(course):
    """What nbgrader's formgrader needs (its time and the gradebook's agree), with the cross-check
    still reading what the student wrote."""
    hand_in = _hand_in(course.inbound, "ada", "1970-01-01 00:00:00.000000", b'{"cells": []}')
    _collect(course, hand_in)
    when = received.received_time(course, "ada", ASSIGNMENT)
    assert when.source == "exchange"
    flags = received.cross_check(course, "ada", ASSIGNMENT, when)
    assert flags and "timestamp.txt says 1970-01-01 00:00:00 UTC" in flags[0]
    assert received.settle_stamp(course.root, "ada", ASSIGNMENT, when) is True
    stamp = course.root / "submitted" / "ada" / ASSIGNMENT / "timestamp.txt"
    assert stamp.read_text() == received.nbgrader_timestamp(when.at)
    assert (course.root / ".cvkit" / "claims" / "ada" / ASSIGNMENT / "timestamp.txt").read_text() == \
        "1970-01-01 00:00:00.000000 UTC"
    assert received.cross_check(course, "ada", ASSIGNMENT, when) == flags
    assert received.settle_stamp(course.root, "ada", ASSIGNMENT, when) is False  # already so
    stamp.unlink()
    stamp.symlink_to(Path("/etc/hostname"))  # a link in its place is replaced, never written through
    assert received.settle_stamp(course.root, "ada", ASSIGNMENT, when) is True
    assert not stamp.is_symlink() and stamp.read_text() == received.nbgrader_timestamp(when.at)
    stamp.unlink()
    stamp.mkdir()  # a folder in its place (refused and flagged by the collection) is left alone
    assert received.settle_stamp(course.root, "ada", ASSIGNMENT, when) is False and stamp.is_dir()


def test_a_hand_in_without_a_notebook_is_named_never_graded(course, capsys):
    hand_in = _hand_in(course.inbound, "dan", "2029-12-31 10:00:00.000000", b"%PDF-1.4")
    (hand_in / NOTEBOOK).rename(hand_in / "answers.pdf")
    _collect(course, hand_in)
    assert course.without_notebooks() == {f"dan/{ASSIGNMENT}": ["answers.pdf"]}
    assert course.submissions() == [] and exchange_notes(course, [ASSIGNMENT]) == []
    assert main(["course", "grade", "--course-dir", str(course.root)]) == 1
    out = capsys.readouterr().out
    assert (f"not graded: dan/{ASSIGNMENT} holds no notebook (answers.pdf): nothing to grade; ask dan to hand in "
            "the assignment's notebooks (nbgrader submit hands in the assignment's folder as fetched)") in out
