"""The course plan, ``plan.toml``: the one source of truth for what is graded and when it is due.

``plan.toml`` lists the assignments (``[[assignment]]``: ``id``, ``title``, ``due``) and the
late-submission policy (``[late]``). cvkit and plain nbgrader read the same plan:

- :func:`configure_nbgrader`, called by ``autograders/nbgrader_config.py``, makes the due dates
  of nbgrader's own gradebook (``Assignment.duedate``) equal to the plan's (creating the
  assignments nbgrader does not know yet) and configures nbgrader's late penalties
  (``AssignLatePenalties.plugin_class``), so that ``nbgrader generate_assignment``,
  ``nbgrader autograde`` and the formgrader agree with ``cvkit course ...``;
- :class:`~cvkit.course.Course` grades only the assignments of the plan: a submission of a
  chapter that is not in it is listed as not graded (:func:`not_in_plan`), never as a zero.

The plan of a course is ``<course folder>/plan.toml`` when there is one, else the project's
``autograders/plan.toml`` (:func:`plan_path`).

A due date is a TOML string ``"YYYY-MM-DD HH:MM:SS <zone>"`` with a zone name (``UTC``,
``Europe/Berlin``), an ISO 8601 string with an offset (``"2027-03-01T23:59:00+01:00"``) or a
TOML date-time; a date-time without a zone is UTC, as in nbgrader. nbgrader stores due dates
as naive UTC date-times, and so does :class:`Plan`.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

try:  # Python ≥ 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10: every chapter of lectures/, no due dates
    tomllib = None

__all__ = ["LATE_POLICIES", "Plan", "PlannedAssignment", "LatePolicy", "plan_path", "read_plan", "parse_due",
           "plan_toml", "not_in_plan", "sync_due_dates", "configure_nbgrader", "plan_data", "switch_table"]

#: the late-submission policies of ``[late] policy``
LATE_POLICIES = ("none", "zero", "per_hour")
_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


@dataclass(frozen=True)
class PlannedAssignment:
    """One ``[[assignment]]`` of the plan.

    Attributes
    ----------
    id : str
        The assignment (the folder name in ``lectures/``).
    title : str
        Its title.
    due : datetime or None
        Its due date, naive UTC (nbgrader's convention); None for no due date.
    """

    id: str
    title: str = ""
    due: _dt.datetime | None = None


@dataclass(frozen=True)
class LatePolicy:
    """The ``[late]`` table of the plan: how nbgrader's ``AssignLatePenalties`` treats a late
    submission (see :class:`cvkit.course.nbgrader_plugins.LatePenalty`).

    Attributes
    ----------
    policy : {"none", "zero", "per_hour"}
        ``none``: no penalty; ``zero``: a late notebook scores zero; ``per_hour``:
        ``points_per_hour`` for every started hour late, at most the notebook's score.
    points_per_hour : float
        Points taken per started hour (``per_hour`` only).
    """

    policy: str = "none"
    points_per_hour: float = 1.0


@dataclass(frozen=True)
class Extension:
    """One ``[[extension]]`` of the plan: ``student`` may hand ``assignment`` in until ``until``
    (naive UTC) without a late penalty; nbgrader's gradebook records it as the submission's
    ``extension`` (``until`` − the due date).

    Attributes
    ----------
    student, assignment : str
    until : datetime
        The student's own due date, naive UTC, after the assignment's.
    reason : str
        Why (for the instructor's records; never shown to other students).
    """

    student: str
    assignment: str
    until: _dt.datetime
    reason: str = ""


@dataclass(frozen=True)
class Plan:
    """A course plan read from ``plan.toml`` (:func:`read_plan`).

    Attributes
    ----------
    assignments : tuple of PlannedAssignment
        In the plan's order.
    late : LatePolicy
        The late-submission policy.
    course_id, title : str
        The ``[course]`` table (both optional).
    path : Path or None
        Where the plan was read from (None: no plan file, every chapter of ``lectures/``).
    extensions : tuple of Extension
        Per-student due dates (``[[extension]]``).
    timezone : str
        The course's time zone (``[course] timezone``, an IANA name such as ``Europe/Berlin``):
        the released notebooks show due dates in it and in UTC.
    """

    assignments: tuple[PlannedAssignment, ...] = ()
    late: LatePolicy = field(default_factory=LatePolicy)
    course_id: str = ""
    title: str = ""
    path: Path | None = None
    extensions: tuple[Extension, ...] = ()
    timezone: str = "UTC"

    def extension(self, student: str, assignment: str) -> Extension | None:
        """The extension of ``student`` for ``assignment`` (None when they have none)."""
        return next((e for e in self.extensions if e.student == student and e.assignment == assignment), None)

    def ids(self) -> list[str]:
        """The assignment ids, in the plan's order."""
        return [a.id for a in self.assignments]

    def get(self, assignment: str) -> PlannedAssignment | None:
        """The planned assignment ``assignment`` (None when it is not in the plan)."""
        return next((a for a in self.assignments if a.id == assignment), None)

    def due(self, assignment: str) -> _dt.datetime | None:
        """The due date of ``assignment`` (naive UTC), None when it has none or is not planned."""
        planned = self.get(assignment)
        return planned.due if planned is not None else None

    @property
    def name(self) -> str:
        """How messages name the plan: its file name (``plan.toml``)."""
        return self.path.name if self.path is not None else "plan.toml"


def plan_path(course_root: str | os.PathLike[str], project: str | os.PathLike[str]) -> Path:
    """The plan of a course: ``<course_root>/plan.toml`` when there is one, else the project's
    ``autograders/plan.toml``.

    Parameters
    ----------
    course_root : path
        The course folder.
    project : path
        The checkout holding ``autograders/``.

    Returns
    -------
    Path
        The plan file (which may not exist).
    """
    own = Path(course_root) / "plan.toml"
    return own if own.is_file() else Path(project) / "autograders" / "plan.toml"


def parse_due(value: Any, where: str = "due") -> _dt.datetime | None:
    """A due date as nbgrader stores it: a naive UTC date-time.

    Parameters
    ----------
    value : str, datetime or None
        ``"YYYY-MM-DD HH:MM:SS <zone name>"``, an ISO 8601 string (with or without an offset)
        or a date-time; without a zone, UTC. None or ``""``: no due date.
    where : str
        How error messages name the value (e.g. ``"plan.toml: assignment 'ch03' due"``).

    Returns
    -------
    datetime or None

    Raises
    ------
    ValueError
        For anything else, naming ``where``.

    Examples
    --------
    >>> parse_due("2027-03-01 23:59:00 UTC")
    datetime.datetime(2027, 3, 1, 23, 59)
    >>> parse_due("2027-03-01T23:59:00+01:00")
    datetime.datetime(2027, 3, 1, 22, 59)
    """
    if value is None or value == "":
        return None
    expected = ("a date and time such as \"2027-03-01 23:59:00 UTC\", \"2027-03-01 23:59:00 Europe/Berlin\" "
                "or \"2027-03-01T23:59:00+01:00\"")
    if isinstance(value, _dt.datetime):
        moment = value
    elif isinstance(value, str):
        moment = _parse_text(value.strip(), where, expected)
    else:
        raise ValueError(f"{where} must be {expected}, got {value!r}")
    if moment.tzinfo is not None:
        offset = moment.utcoffset() or _dt.timedelta(0)
        moment = (moment - offset).replace(tzinfo=None)
    return moment


def _parse_text(text: str, where: str, expected: str) -> _dt.datetime:
    import dateutil.parser
    import dateutil.tz

    parts = text.split(" ")
    zone: Any = None
    if len(parts) == 3 and re.fullmatch(r"[A-Za-z][A-Za-z0-9_/+-]*", parts[2]):
        zone = dateutil.tz.UTC if parts[2].upper() in ("UTC", "GMT", "Z") else dateutil.tz.gettz(parts[2])
        if zone is None:
            raise ValueError(f"{where}: unknown time zone {parts[2]!r} in {text!r}; write {expected}")
        text = " ".join(parts[:2])
    elif len(parts) == 3:
        raise ValueError(f"{where} must be {expected} (a zone name, or an offset written as +01:00 right after "
                         f"the time), got {text!r}")
    if not re.match(r"^\d{4}-\d{2}-\d{2}[ T]\d{1,2}:\d{2}", text):
        raise ValueError(f"{where} must be {expected} (a date alone is not enough), got {text!r}")
    try:
        moment = dateutil.parser.isoparse(text.replace(" ", "T", 1))
    except (ValueError, OverflowError) as error:
        raise ValueError(f"{where} must be {expected}, got {text!r} ({error})") from None
    return moment.replace(tzinfo=zone) if zone is not None else moment


def _late_policy(table: Any, name: str) -> LatePolicy:
    if table is None:
        return LatePolicy()
    if not isinstance(table, Mapping):
        raise ValueError(f"{name}: [late] must be a table with policy = \"none\" | \"zero\" | \"per_hour\"")
    unknown = sorted(set(table) - {"policy", "points_per_hour"})
    if unknown:
        raise ValueError(f"{name}: [late] has unknown key(s) {', '.join(unknown)}; expected policy and points_per_hour")
    policy = table.get("policy", "none")
    if policy not in LATE_POLICIES:
        raise ValueError(f"{name}: [late] policy must be one of {', '.join(map(repr, LATE_POLICIES))}, got {policy!r}")
    points = table.get("points_per_hour", 1.0)
    if isinstance(points, bool) or not isinstance(points, (int, float)) or not math.isfinite(points) or points <= 0:
        raise ValueError(f"{name}: [late] points_per_hour must be a number > 0 (points per started hour late), "
                         f"got {points!r}")
    return LatePolicy(str(policy), float(points))


def _assignments(entries: Any, name: str) -> tuple[PlannedAssignment, ...]:
    if not isinstance(entries, list):
        raise ValueError(f"{name}: [[assignment]] must be a list of tables with an id")
    planned: list[PlannedAssignment] = []
    for number, entry in enumerate(entries, 1):
        if not isinstance(entry, Mapping):
            raise ValueError(f"{name}: assignment #{number} must be a table with an id")
        assignment_id = entry.get("id")
        if not isinstance(assignment_id, str) or not _ID.match(assignment_id):
            raise ValueError(f"{name}: assignment #{number} id must be a folder name of lectures/ such as "
                             f"\"ch03_filtering\", got {assignment_id!r}")
        if any(p.id == assignment_id for p in planned):
            raise ValueError(f"{name}: assignment {assignment_id!r} is listed twice")
        title = entry.get("title", "")
        if not isinstance(title, str):
            raise ValueError(f"{name}: assignment {assignment_id!r} title must be a string, got {title!r}")
        due = parse_due(entry.get("due"), f"{name}: assignment {assignment_id!r} due")
        planned.append(PlannedAssignment(assignment_id, title, due))
    return tuple(planned)


def _zone(name: str) -> Any:
    import dateutil.tz

    return dateutil.tz.UTC if name.upper() in ("UTC", "GMT", "Z") else dateutil.tz.gettz(name)


def _extensions(entries: Any, assignments: tuple[PlannedAssignment, ...], name: str) -> tuple[Extension, ...]:
    if not isinstance(entries, list):
        raise ValueError(f"{name}: [[extension]] must be a list of tables (student, assignment, until or days)")
    planned = {a.id: a for a in assignments}
    found: list[Extension] = []
    for number, entry in enumerate(entries, 1):
        where = f"{name}: extension #{number}"
        if not isinstance(entry, Mapping):
            raise ValueError(f"{where} must be a table with student, assignment and until (or days)")
        unknown = sorted(set(entry) - {"student", "assignment", "until", "days", "hours", "reason"})
        if unknown:
            raise ValueError(f"{where}: unknown key {unknown[0]!r} (student, assignment, until or days/hours, reason)")
        student, assignment = entry.get("student"), entry.get("assignment")
        if not isinstance(student, str) or not student.strip():
            raise ValueError(f"{where}: student must be a student id, got {student!r}")
        if assignment not in planned:
            raise ValueError(f"{where} ({student}): assignment must be one of the plan's ({', '.join(planned)}), "
                             f"got {assignment!r}")
        due = planned[assignment].due
        if due is None:
            raise ValueError(f"{where} ({student}, {assignment}): {assignment} has no due date to extend")
        if ("until" in entry) == ("days" in entry or "hours" in entry):
            raise ValueError(f"{where} ({student}, {assignment}): give until = \"2027-03-05 23:59:00 UTC\", or "
                             "days (and/or hours) after the due date — one of them")
        if "until" in entry:
            until = parse_due(entry["until"], f"{where} ({student}, {assignment}) until")
        else:
            amounts = [entry.get(k, 0) for k in ("days", "hours")]
            if not all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in amounts):
                raise ValueError(f"{where} ({student}, {assignment}): days and hours must be numbers, got {amounts}")
            until = due + _dt.timedelta(days=amounts[0], hours=amounts[1])
        assert until is not None
        if until <= due:
            raise ValueError(f"{where} ({student}, {assignment}): the extension ends {until:%Y-%m-%d %H:%M} UTC, not "
                             f"after the due date {due:%Y-%m-%d %H:%M} UTC")
        if any(e.student == student and e.assignment == assignment for e in found):
            raise ValueError(f"{where}: {student} has two extensions for {assignment}: keep one")
        reason = entry.get("reason", "")
        found.append(Extension(student, str(assignment), until, reason if isinstance(reason, str) else str(reason)))
    return tuple(found)


def read_plan(path: str | os.PathLike[str], chapters: Iterable[str] = ()) -> Plan:
    """Read and check a ``plan.toml``.

    Parameters
    ----------
    path : path
        The plan file.
    chapters : iterable of str, optional
        The plan when ``path`` does not exist (or Python 3.10 cannot read TOML): these
        assignments, without due dates.

    Returns
    -------
    Plan

    Raises
    ------
    ValueError
        When the file is not valid TOML or a value is not what the plan expects, naming the
        file, the assignment and the key.
    """
    path = Path(path)
    if not path.is_file() or tomllib is None:
        return Plan(tuple(PlannedAssignment(c) for c in chapters))
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{path}: not valid TOML ({error})") from None
    name = str(path)
    course = data.get("course", {})
    if not isinstance(course, Mapping):
        raise ValueError(f"{name}: [course] must be a table (id, title)")
    if "id" in course and (not isinstance(course["id"], str) or not _ID.match(course["id"])):
        raise ValueError(f"{name}: [course] id must be letters, digits, '_', '.' and '-' (nbgrader's course id, "
                         f"a folder name of its exchange), got {course['id']!r}")
    zone = course.get("timezone", "UTC")
    if not isinstance(zone, str) or _zone(zone) is None:
        raise ValueError(f"{name}: [course] timezone must be a time zone name such as \"Europe/Berlin\" or \"UTC\", "
                         f"got {zone!r}")
    assignments = _assignments(data.get("assignment", []), name)
    return Plan(assignments, _late_policy(data.get("late"), name), str(course.get("id", "")),
                str(course.get("title", "")), path, _extensions(data.get("extension", []), assignments, name), zone)


def plan_data(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The TOML data of a plan file, for the optional tables other modules read themselves
    (``[class_notes]``, ``[leaderboard]``): ``{}`` when there is no file (or Python 3.10 cannot
    read TOML).

    Raises
    ------
    ValueError
        When the file is not valid TOML, naming it.
    """
    path = Path(path)
    if tomllib is None or not path.is_file():
        return {}
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"{path}: not valid TOML ({error})") from None


def switch_table(data: Mapping[str, Any], table: str, count: str, default: int, floor: int, why: str,
                 where: str = "plan.toml") -> tuple[bool, int]:
    """An optional feature's table of a plan's TOML ``data``: ``enabled`` (true/false, absent:
    false) and ``count``, a whole number of at least ``floor`` (absent: ``default``; ``why`` says
    why not fewer). Returns ``(enabled, count)``.

    Raises
    ------
    ValueError
        Naming the table and the key, when a value is not of that kind or the table has another key.
    """
    found = data.get(table, {})
    if not isinstance(found, Mapping):
        raise ValueError(f"{where}: [{table}] must be a table (enabled, {count})")
    unknown = sorted(set(found) - {"enabled", count})
    if unknown:
        raise ValueError(f"{where}: [{table}] has unknown key(s) {', '.join(unknown)}; expected enabled and {count}")
    enabled = found.get("enabled", False)
    if not isinstance(enabled, bool):
        raise ValueError(f"{where}: [{table}] enabled must be true or false, got {enabled!r}")
    least = found.get(count, default)
    if isinstance(least, bool) or not isinstance(least, int) or least < floor:
        raise ValueError(f"{where}: [{table}] {count} must be a whole number of at least {floor} ({why}), "
                         f"got {least!r}")
    return enabled, least


def _toml_string(text: str) -> str:
    """``text`` as a TOML basic string (JSON's escapes are TOML's)."""
    import json

    return json.dumps(text, ensure_ascii=False)


def plan_toml(plan: Plan, course_id: str | None = None) -> str:
    """``plan`` written as a ``plan.toml`` (due dates in UTC), with ``course_id`` as its
    ``[course] id`` when given: the plan of a course folder made from the project's plan.

    Examples
    --------
    >>> print(plan_toml(Plan((PlannedAssignment("ch03", "Filters", parse_due("2027-03-01 23:59:00 UTC")),)),
    ...                  "ipcv-2027"), end="")
    [course]
    id = "ipcv-2027"
    <BLANKLINE>
    [[assignment]]
    id = "ch03"
    title = "Filters"
    due = "2027-03-01 23:59:00 UTC"
    <BLANKLINE>
    [late]
    policy = "none"
    points_per_hour = 1.0
    """
    lines = ["[course]", f"id = {_toml_string(course_id or plan.course_id)}"]
    if plan.title:
        lines.append(f"title = {_toml_string(plan.title)}")
    if plan.timezone != "UTC":
        lines.append(f"timezone = {_toml_string(plan.timezone)}")
    for planned in plan.assignments:
        lines += ["", "[[assignment]]", f"id = {_toml_string(planned.id)}"]
        if planned.title:
            lines.append(f"title = {_toml_string(planned.title)}")
        if planned.due is not None:
            lines.append(f"due = \"{planned.due:%Y-%m-%d %H:%M:%S} UTC\"")
    lines += ["", "[late]", f"policy = {_toml_string(plan.late.policy)}",
              f"points_per_hour = {plan.late.points_per_hour!r}"]
    for extension in plan.extensions:
        lines += ["", "[[extension]]", f"student = {_toml_string(extension.student)}",
                  f"assignment = {_toml_string(extension.assignment)}", f"until = \"{extension.until:%Y-%m-%d %H:%M:%S} UTC\""]
        if extension.reason:
            lines.append(f"reason = {_toml_string(extension.reason)}")
    return "\n".join(lines) + "\n"


def not_in_plan(assignment: str, plan: Plan) -> str:
    """Why a submission of ``assignment`` is not graded when the plan does not list it."""
    return f"chapter {assignment} is not in {plan.name}"


def sync_due_dates(db_url: str, plan: Plan, assignments: Iterable[str] | None = None,
                   course_id: str | None = None) -> list[str]:
    """Make the due dates of nbgrader's gradebook equal to the plan's.

    Parameters
    ----------
    db_url : str
        The gradebook's SQLAlchemy URL.
    plan : Plan
        The plan.
    assignments : iterable of str, optional
        Only these assignments of the plan (e.g. those with a folder in ``lectures/``);
        default all of them.
    course_id : str, optional
        nbgrader's course id for assignments created here.

    Returns
    -------
    list of str
        What changed (``"ch03: due 2027-03-08 23:59:00"``, ``"ch03: created"``); nothing is
        written when the gradebook already agrees.
    """
    from nbgrader.api import MissingEntry

    chosen = None if assignments is None else set(assignments)
    wanted = [a for a in plan.assignments if chosen is None or a.id in chosen]
    changes = []
    with gradebook_of(db_url, course_id) as gradebook:
        for planned in wanted:
            try:
                found = gradebook.find_assignment(planned.id)
            except MissingEntry:
                gradebook.add_assignment(planned.id, duedate=planned.due)
                changes.append(f"{planned.id}: created, due {planned.due or 'never'}")
                continue
            if found.duedate != planned.due:
                found.duedate = planned.due
                gradebook.db.commit()
                changes.append(f"{planned.id}: due {planned.due or 'never'}")
    return changes


def nbgrader_schema_version() -> str:
    """The alembic revision of the gradebook schema of the installed nbgrader (its scripts' head),
    read in this process: what nbgrader's ``get_alembic_version`` gets from the ``alembic heads``
    command, a Python process of its own that costs seconds of CPU."""
    from alembic.script import ScriptDirectory
    from nbgrader.dbutil import ALEMBIC_DIR

    head = ScriptDirectory(ALEMBIC_DIR).get_current_head()
    if not head:
        raise RuntimeError(f"nbgrader's schema scripts in {ALEMBIC_DIR} have no single head revision")
    return head


def stamp_new_gradebook(db_url: str) -> bool:
    """Give a database without tables the schema version nbgrader would give it (True when it
    did). nbgrader's ``Gradebook`` stamps a new database with the ``alembic_version`` table
    itself, but runs the ``alembic`` command to learn the version; a database that already has
    a table it leaves alone, so the version stamped here spares that process (and nbgrader's
    tables are created as usual). A database with tables is not touched."""
    from sqlalchemy import create_engine, inspect, text
    from sqlalchemy.exc import SQLAlchemyError

    engine = create_engine(db_url, future=True)
    try:
        if inspect(engine).get_table_names():
            return False
        version = nbgrader_schema_version()
        try:
            with engine.begin() as connection:  # the very statements of nbgrader's Gradebook
                connection.execute(text("CREATE TABLE alembic_version (version_num VARCHAR(32) NOT NULL);"))
                connection.execute(text("INSERT INTO alembic_version (version_num) VALUES (:version);"),
                                   {"version": version})
        except SQLAlchemyError:
            if "alembic_version" in inspect(engine).get_table_names():
                return False  # another process made it in the meantime
            raise
        return True
    finally:
        engine.dispose()


@contextlib.contextmanager
def gradebook_of(db_url: str, course_id: str | None = None) -> Iterator[Any]:
    """nbgrader's ``Gradebook`` at ``db_url``, made if it does not exist yet (stamped with the
    schema version first, :func:`stamp_new_gradebook`, so that nbgrader needs no ``alembic``
    process)."""
    from nbgrader.api import Gradebook

    stamp_new_gradebook(db_url)
    with Gradebook(db_url, **({"course_id": course_id} if course_id else {})) as gradebook:
        yield gradebook


def configure_nbgrader(c: Any, root: str | os.PathLike[str], project: str | os.PathLike[str],
                       source_dir: str | os.PathLike[str], db_url: str, course_id: str | None = None) -> Plan:
    """What ``autograders/nbgrader_config.py`` takes from the plan, for every nbgrader command.

    nbgrader's course id becomes the plan's ``[course] id`` when it has one, the gradebook's due
    dates become the plan's (:func:`sync_due_dates`, for the assignments with a folder in
    ``source_dir``), nbgrader's ``AssignLatePenalties`` uses
    :class:`cvkit.course.nbgrader_plugins.LatePenalty` with the plan's ``[late]`` policy, and
    :class:`~cvkit.course.nbgrader_plugins.PlanExtensions` records the plan's extensions.

    Parameters
    ----------
    c : traitlets.config.Config
        The configuration being loaded.
    root, project, source_dir : path
        The course folder, the checkout (for its ``autograders/plan.toml``) and the source
        notebooks' folder.
    db_url : str
        The gradebook.
    course_id : str, optional
        nbgrader's course id when the plan names none.

    Returns
    -------
    Plan
    """
    from .nbgrader_plugins import LatePenalty

    source = Path(source_dir)
    plan = read_plan(plan_path(root, project), sorted(p.name for p in source.glob("ch*_*") if p.is_dir()))
    if plan.course_id:  # the plan names the course: nbgrader's course id (the exchange's folder) is its
        course_id = c.CourseDirectory.course_id = plan.course_id
    sync_due_dates(db_url, plan, [a for a in plan.ids() if (source / a).is_dir()], course_id)
    c.AssignLatePenalties.plugin_class = LatePenalty
    c.LatePenalty.policy = plan.late.policy
    c.LatePenalty.points_per_hour = plan.late.points_per_hour
    c.PlanExtensions.extensions = {f"{e.student}/{e.assignment}": f"{e.until:%Y-%m-%d %H:%M:%S}" for e in plan.extensions}
    # the released notebooks say when they are due and what lateness costs
    from .nbgrader_plugins import DueDateNotice, late_policy_sentence

    c.DueDateNotice.due = {a.id: f"{a.due:%Y-%m-%d %H:%M:%S}" for a in plan.assignments if a.due is not None}
    c.DueDateNotice.timezone = plan.timezone
    c.DueDateNotice.late = late_policy_sentence(plan.late.policy, plan.late.points_per_hour)
    if DueDateNotice not in (c.GenerateAssignment.preprocessors if "preprocessors" in c.GenerateAssignment else []):
        from nbgrader.converters import GenerateAssignment

        steps = list(c.GenerateAssignment.preprocessors if "preprocessors" in c.GenerateAssignment
                     else GenerateAssignment.class_traits()["preprocessors"].default())
        steps.insert(steps.index(next(s for s in steps if s.__name__ == "ClearOutput")) + 1, DueDateNotice)
        c.GenerateAssignment.preprocessors = steps
    return plan
