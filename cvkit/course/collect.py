"""Hand-ins into the course from the command line (``cvkit course collect``).

Three sources, one rule — a student's hand-in is taken whole or not at all, and whatever is
refused is listed with the reason:

- **nbgrader's exchange** (a course on a hub): nbgrader's own ``collect`` (the latest hand-in of
  each student, or with ``update`` the newer ones), which keeps its ``submission_secret.txt``;
- **an LMS download** — a zip or a folder: files named as Canvas names them
  (``<login>[_LATE]_<user id>_<submission id>_<file name>``), folders as Moodle names them
  (``<Full Name>_<id>_assignsubmission_file_/<file>``), or one folder per student
  (``<student>/<file>``); another naming is given as a regular expression with the groups
  ``student_id`` and ``file_id`` (as nbgrader's ``zip_collect`` takes it). A ``roster`` CSV
  (``lms,student_id``) maps the LMS's names to the course's ids;
- **one student's notebook** (``student`` given).

Every file is checked before anything is placed: a path that leaves its folder (``../``, an
absolute path, a link), a file that is not a notebook of the release, a notebook that does not
parse, a file over :data:`MAX_FILE_BYTES`, a student id cvkit cannot use. A student whose hand-in
has one bad file is not imported at all. Each accepted hand-in is written to a folder of its own
next to ``submitted/`` and moved in place with one rename, with the time it was received (the
collection, or the time given) and a ``submission_secret.txt`` so that nbgrader's
``release_feedback`` can hand its page back through an exchange. A student already collected is
left as is unless ``update``.
"""
from __future__ import annotations

import csv
import datetime as _dt
import io
import json
import os
import re
import secrets
import shutil
import stat
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, Iterable, Mapping

from .._text import name_problem, printable

if TYPE_CHECKING:
    from .state import CourseState

__all__ = ["Collected", "LMS_PATTERNS", "MAX_FILE_BYTES", "collect_exchange", "collect_files"]

#: the largest file taken from a download (a chapter notebook with its outputs is a few MB)
MAX_FILE_BYTES = 50 << 20
#: how LMS downloads name a student's files (tried in this order)
LMS_PATTERNS = {
    "canvas": r"^(?P<student_id>[^/_]+)(?:_LATE)?_\d+_\d+_(?P<file_id>[^/]+)$",
    "moodle": r"^(?P<student_id>[^/]+?)_\d+_assignsubmission_file_/(?P<file_id>[^/]+)$",
    "folders": r"^(?P<student_id>[^/]+)/(?P<file_id>[^/]+)$",
}
_PLAIN_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.@-]*$")
_RENUMBERED = re.compile(r"^(?P<stem>.+?)-\d+(?P<ext>\.ipynb)$")  # Canvas: chapter-1.ipynb for a resubmission


@dataclass
class Collected:
    """What one collection did: (student, file names) imported, students left as they were,
    and what was refused (printable lines, each with its reason)."""

    imported: list[tuple[str, list[str]]] = field(default_factory=list)
    unchanged: list[str] = field(default_factory=list)
    kept: list[str] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)

    def lines(self) -> list[str]:
        out = [f"collected {s}: {', '.join(files)}" for s, files in self.imported]
        out += [f"unchanged {s}: the same files as collected before" for s in self.unchanged]
        out += [f"kept {s}: collected before, with other files (collect again with --update to replace them)"
                for s in self.kept]
        out += [f"!! refused {line}" for line in self.refused]
        return out


# ---------------------------------------------------------------------------- reading the source
def _entries(source: Path, refused: list[str]) -> list[tuple[str, bytes]]:
    """(relative path, bytes) of every file of ``source`` (a zip, a folder or one file), the
    student's own zips inside opened one level; unsafe entries refused."""
    if source.is_symlink():
        refused.append(f"{printable(str(source))}: a symbolic link (not followed)")
        return []
    if not source.exists():
        raise FileNotFoundError(f"{source} does not exist: give a zip, a folder or a notebook")
    if source.is_dir():
        found = []
        for path in sorted(source.rglob("*")):
            name = path.relative_to(source).as_posix()
            info = path.lstat()
            if stat.S_ISDIR(info.st_mode):
                continue
            if stat.S_ISLNK(info.st_mode) or not stat.S_ISREG(info.st_mode):
                refused.append(f"{printable(name)}: not a plain file (links are not followed)")
            elif any(p.is_symlink() for p in path.relative_to(source).parents if str(p) != "."):
                refused.append(f"{printable(name)}: inside a linked folder (not followed)")
            elif info.st_size > MAX_FILE_BYTES:
                refused.append(f"{printable(name)}: {info.st_size} bytes, more than {MAX_FILE_BYTES} (not read)")
            else:
                found += _expand(name, path.read_bytes(), refused)
        return found
    if source.suffix.lower() == ".zip":
        return _from_zip(source.name, source.read_bytes(), refused, prefix="")
    return [(source.name, source.read_bytes())]


def _expand(name: str, data: bytes, refused: list[str]) -> list[tuple[str, bytes]]:
    if name.lower().endswith(".zip"):
        return _from_zip(name, data, refused, prefix=name[:-4] + "/")
    return [(name, data)]


def _from_zip(name: str, data: bytes, refused: list[str], prefix: str) -> list[tuple[str, bytes]]:
    try:
        archive = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile:
        refused.append(f"{printable(name)}: not a zip file that can be read")
        return []
    found = []
    with archive:
        for info in archive.infolist():
            inner = info.filename
            shown = printable(prefix + inner)
            if info.is_dir():
                continue
            path = PurePosixPath(inner.replace("\\", "/"))
            kind = info.external_attr >> 16
            if path.is_absolute() or ".." in path.parts or re.match(r"^[A-Za-z]:", inner):
                refused.append(f"{shown}: a path outside its folder (not extracted)")
            elif stat.S_ISLNK(kind):
                refused.append(f"{shown}: a symbolic link (not extracted)")
            elif info.file_size > MAX_FILE_BYTES:
                refused.append(f"{shown}: {info.file_size} bytes, more than {MAX_FILE_BYTES} (not extracted)")
            else:
                with archive.open(info) as handle:
                    content = handle.read(MAX_FILE_BYTES + 1)
                if len(content) > MAX_FILE_BYTES:
                    refused.append(f"{shown}: more than {MAX_FILE_BYTES} bytes once unpacked (not extracted)")
                    continue
                if prefix == "" and inner.lower().endswith(".zip"):
                    found += _from_zip(inner, content, refused, prefix=inner[:-4] + "/")
                else:
                    found.append((prefix + path.as_posix(), content))
    return found


def _roster(path: Path | None) -> dict[str, str]:
    if path is None:
        return {}
    with open(path, newline="", encoding="utf-8-sig") as handle:
        reader = csv.DictReader(handle)
        if not reader.fieldnames or not {"lms", "student_id"} <= set(reader.fieldnames):
            raise ValueError(f"roster {path}: a CSV with the columns lms and student_id (the LMS's name of each "
                             f"student, the course's id), got {reader.fieldnames}")
        return {row["lms"].strip(): row["student_id"].strip() for row in reader if row.get("lms")}


def _owner(name: str, patterns: Iterable[str]) -> tuple[str, str] | None:
    for pattern in patterns:
        match = re.match(pattern, name, re.IGNORECASE)
        if match:
            return match.group("student_id").strip(), match.group("file_id")
    return None


# ---------------------------------------------------------------------------- placing a hand-in
def _place(course: CourseState, student: str, assignment: str, files: Mapping[str, bytes], received_at: _dt.datetime,
           update: bool, result: Collected, secret: str | None = None) -> None:
    from . import received

    target = course.root / "submitted" / student / assignment
    if target.exists():
        same = all((target / n).is_file() and (target / n).read_bytes() == d for n, d in files.items())
        if same:
            result.unchanged.append(student)
            return
        if not update:
            result.kept.append(student)
            return
    staging = course.root / ".cvkit" / "incoming" / f"{student}-{assignment}-{secrets.token_hex(4)}"
    staging.mkdir(parents=True)
    try:
        for name, data in files.items():
            (staging / name).write_bytes(data)
        (staging / received.STAMP_FILE).write_text(received.nbgrader_timestamp(received_at))
        (staging / "submission_secret.txt").write_text(secret or secrets.token_hex(16))
        target.parent.mkdir(parents=True, exist_ok=True)
        if target.exists():
            old = target.with_name(f".{assignment}.replaced-{secrets.token_hex(4)}")
            os.replace(target, old)
            os.replace(staging, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(staging, target)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    received.record_submitted(course.root, student, assignment, received_at)
    result.imported.append((student, sorted(files)))


def _notebook_name(file_id: str, release: list[str]) -> str | None:
    """The release notebook a file of the download is: its own name, Canvas's renumbered name
    (``ch03_filtering-1.ipynb``), or the only notebook of a one-notebook chapter."""
    if file_id in release:
        return file_id
    renumbered = _RENUMBERED.match(file_id)
    if renumbered and renumbered["stem"] + renumbered["ext"] in release:
        return renumbered["stem"] + renumbered["ext"]
    if file_id.lower().endswith(".ipynb") and len(release) == 1:
        return release[0]
    return None


def collect_files(course: CourseState, assignment: str, source: str | os.PathLike[str], *, student: str | None = None,
                  pattern: str | None = None, roster: str | os.PathLike[str] | None = None,
                  received_at: _dt.datetime | None = None, update: bool = False) -> Collected:
    """Hand-ins of ``assignment`` from a zip, a folder or one notebook (module docstring).

    Parameters
    ----------
    course : CourseState
    assignment : str
        A chapter of the plan, already built (its release names the notebooks).
    source : path
        A zip, a folder, or (with ``student``) one notebook.
    student : str, optional
        Every file of ``source`` is this student's.
    pattern : str, optional
        A regular expression with the groups ``student_id`` and ``file_id``, matched against
        each file's path in ``source``; default: :data:`LMS_PATTERNS`.
    roster : path, optional
        A CSV with columns ``lms`` and ``student_id``: the LMS's names → the course's ids.
    received_at : datetime, optional
        When the hand-ins arrived, with a time zone (e.g. the LMS's deadline export); default now.
    update : bool
        Replace a student's hand-in collected before with different files.
    """
    from . import received
    from .state import refused_student_ids

    if assignment not in course.plan().ids():
        raise ValueError(f"{assignment} is not in {course.plan().name}: add it there first")
    release = [p.name for p in course.release_notebooks(assignment)]
    if not release:
        raise FileNotFoundError(f"{assignment} has no release yet: run cvkit course build --assignment {assignment}")
    if pattern is not None:
        try:
            compiled = re.compile(pattern)
        except re.error as error:
            raise ValueError(f"--pattern {pattern!r} is not a regular expression: {error}") from None
        if not {"student_id", "file_id"} <= set(compiled.groupindex):
            raise ValueError(f"--pattern {pattern!r} needs the groups (?P<student_id>...) and (?P<file_id>...)")
    moment = received.checked_time(received_at or _dt.datetime.now(_dt.timezone.utc))
    result = Collected()
    names = _roster(Path(roster) if roster else None)
    entries = _entries(Path(source), result.refused)
    by_student: dict[str, dict[str, bytes]] = {}
    bad: dict[str, list[str]] = {}
    for name, data in entries:
        shown = printable(name)
        if student is not None:
            owner: tuple[str, str] | None = (student, PurePosixPath(name).name)
        else:
            owner = _owner(name, [pattern] if pattern else LMS_PATTERNS.values())
        if owner is None:
            result.refused.append(f"{shown}: whose is it? (the name matches no known LMS naming: give --pattern, "
                                  "or --student for one student's files)")
            continue
        who, file_id = owner
        who = names.get(who, who)
        if PurePosixPath(file_id).name.startswith("."):
            continue  # __MACOSX/._ files, .DS_Store: not the student's work
        notebook = _notebook_name(file_id, release)
        if notebook is None:
            bad.setdefault(who, []).append(f"{shown}: not a notebook of {assignment} ({', '.join(release)})")
            continue
        try:
            parsed = json.loads(data.decode("utf-8"))
            if not isinstance(parsed, dict) or not isinstance(parsed.get("cells"), list):
                raise ValueError("no cells")
        except (UnicodeDecodeError, ValueError):
            bad.setdefault(who, []).append(f"{shown}: not a notebook that can be read (JSON with cells)")
            continue
        if notebook in by_student.get(who, {}):
            bad.setdefault(who, []).append(f"{shown}: a second file for {notebook}")
            continue
        by_student.setdefault(who, {})[notebook] = data
    problems = refused_student_ids(set(by_student) | set(bad))
    for who in sorted(set(by_student) | set(bad)):
        reasons = bad.get(who, [])
        problem = problems.get(who) or (f"the student id {printable(who)!r} {name_problem(who)}"
                                        if name_problem(who) else None)
        if problem is None and not _PLAIN_ID.match(who):
            problem = (f"{printable(who)!r} is not a student id (letters, digits, '_', '.', '@', '-'): map the LMS's "
                       "names to your students' ids with --roster (a CSV with the columns lms and student_id)")
        if problem:
            reasons = [problem, *reasons]
        if reasons:
            result.refused.append(f"{printable(who)}: nothing imported — " + "; ".join(reasons))
            continue
        _place(course, who, assignment, by_student[who], moment.replace(tzinfo=_dt.timezone.utc), update, result)
    return result


def collect_exchange(course: CourseState, assignment: str, update: bool = False) -> Collected:
    """nbgrader's own ``collect`` from the course's exchange (a course on a hub)."""
    from .received import _exchange_folder

    if _exchange_folder(course) is None:
        raise FileNotFoundError("this course has no nbgrader exchange (a course on a hub: docs/deploy-jupyterhub.md); "
                                "collect from an LMS download with --from ZIP_OR_FOLDER")
    def stamps() -> dict[str, bytes]:
        found = {}
        for student, _ in course.submissions([assignment]):
            stamp = course.root / "submitted" / student / assignment / "timestamp.txt"
            found[student] = stamp.read_bytes() if stamp.is_file() else b""
        return found

    before = stamps()
    outcome = course.nbgrader_api().collect(assignment, update=update)
    result = Collected()
    if not outcome.get("success"):
        result.refused.append(f"nbgrader collect {assignment}: {(outcome.get('error') or outcome.get('log') or '')[-500:]}")
        return result
    for student, stamp in sorted(stamps().items()):
        if before.get(student) != stamp:
            files = sorted(p.name for p in (course.root / "submitted" / student / assignment).glob("*.ipynb"))
            result.imported.append((student, files))
        else:
            result.unchanged.append(student)
    return result
