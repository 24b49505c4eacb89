"""When a submission was received: trusted data, never what the student wrote.

A late penalty depends on one time, and nbgrader takes it from the submission's
``timestamp.txt``. Where students hand in zips, or submit through nbgrader's exchange (where
``nbgrader submit`` runs as the student), they write that file themselves: "1970-01-01" would
remove any penalty, "not a date" would stop nbgrader. So cvkit decides the time a submission
was received (:func:`received_time`) from what students cannot write, first match wins:

1. **the instructor's list**, ``<course>/submission_times.csv`` with the columns
   ``student_id,assignment,timestamp`` (ISO 8601 with a time zone, ``2027-03-08T23:59:00+01:00``
   or ``…Z``). A malformed row stops grading with a message naming the line
   (:class:`SubmissionTimesError`); a changed row changes the submission's journal hash
   (:func:`listed_stamp`), so the submission is regraded by the next ``cvkit course grade``;
2. **nbgrader's exchange**, where the course has one (``<Exchange.root>/<course id>/inbound``):
   the inode change time (ctime) of the notebooks of the earliest inbound folder of this
   student and assignment whose notebooks are byte for byte those collected. Students create
   those files but cannot set a ctime back; the time in the folder's name is theirs, not used;
3. **cvkit's own record**, written by :meth:`cvkit.course.Course.submit` (its ``received_at``,
   default the moment of the call) for the files it placed;
4. **the collection**: the latest ctime of the submission's files in ``submitted/`` when cvkit
   first saw this version of them.

Times of 2–4 are recorded at first sight in ``<course>/.cvkit/received.json``, keyed by a hash
of the submission's files (``timestamp.txt`` left out), so later runs, a cleaned-up exchange or
a ``chmod`` do not move them; a new version of the files gets a new time. The writer gives
nbgrader this time as the staged ``timestamp.txt`` (:func:`nbgrader_timestamp`): the student's
file never reaches nbgrader, and a missing or garbage one never keeps a submission from being
graded.

Once a submission is recorded, its collected ``timestamp.txt`` is made that trusted time too
(:func:`settle_stamp`), the student's own file kept in ``<course>/.cvkit/claims/``: nbgrader
takes the time in ``submitted/`` as the truth elsewhere (its formgrader lists a submission as
autograded only when that file and the gradebook agree; ``nbgrader collect --update`` compares
it with a newer hand-in), and on a hub the student's ``timestamp.txt`` (written when ``nbgrader
submit`` started) never equals the exchange's record of the hand-in.

The student's ``timestamp.txt`` is only a cross-check (:func:`cross_check`): read with a size
limit, it flags the submission for the instructor — never lowering a penalty — when it is
unreadable, before the assignment's release, later than the received time, or (where that
time is an exact record: list or exchange) earlier than it, by more than
:data:`TOLERANCE` for clock skew; and, where the only record is a collection after the due
date, when it claims a time by the due date (the submission is graded late: the instructor's
list can say otherwise). The release is the earliest modification time seen of the
release notebooks (``release/<assignment>``, the exchange's ``outbound/<assignment>``),
recorded so that a rebuild does not move it later.
"""
from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import io
import json
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

from ..sandbox.isolation import collect_files
from .files import write_whole

if TYPE_CHECKING:
    from .state import CourseState

__all__ = ["LIST_NAME", "STAMP_FILE", "TOLERANCE", "Received", "SubmissionTimesError", "checked_time", "cross_check",
           "exchange_time", "listed_stamp", "nbgrader_timestamp", "read_claim", "read_list", "received_time",
           "record_submitted", "release_time", "settle_stamp"]

#: the instructor's list of submission times, in the course folder
LIST_NAME = "submission_times.csv"
#: the student's claim (and the file nbgrader reads)
STAMP_FILE = "timestamp.txt"
#: clock skew allowed between the student's claim and the trusted time
TOLERANCE = _dt.timedelta(minutes=5)
#: longest ``timestamp.txt`` read (nbgrader writes about 30 bytes)
CLAIM_LIMIT = 1024
#: how nbgrader writes ``timestamp.txt`` (``Exchange.timestamp_format``)
NBGRADER_FORMAT = "%Y-%m-%d %H:%M:%S.%f %Z"
#: the columns of the instructor's list
COLUMNS = ("student_id", "assignment", "timestamp")

#: where a trusted time comes from → how flags name it
SOURCES = {
    "list": f"the instructor's list {LIST_NAME}",
    "exchange": "nbgrader's exchange",
    "submitted": "cvkit's record of the hand-in",
    "collected": "the collection into submitted/",
}
_EXACT = ("list", "exchange")
_UTC = _dt.timezone.utc
_DATE_TIME = re.compile(r"^\d{4}-\d{2}-\d{2}[ T]\d{1,2}:\d{2}")


class SubmissionTimesError(ValueError):
    """The instructor's ``submission_times.csv`` cannot be read; the message names each bad line."""


@dataclass(frozen=True)
class Received:
    """The trusted time a submission was received.

    Attributes
    ----------
    at : datetime
        Naive UTC (nbgrader's convention).
    source : str
        A key of :data:`SOURCES`: ``"list"``, ``"exchange"``, ``"submitted"`` or ``"collected"``.
    """

    at: _dt.datetime
    source: str

    @property
    def exact(self) -> bool:
        """A record of the hand-in itself (list, exchange), not a later moment (collection)."""
        return self.source in _EXACT

    def describe(self) -> str:
        """``"2030-01-01 02:30:00 UTC (nbgrader's exchange)"``."""
        return f"{_shown(self.at)} ({SOURCES.get(self.source, self.source)})"


# ---------------------------------------------------------------------------- times as text
def _shown(moment: _dt.datetime) -> str:
    return moment.strftime("%Y-%m-%d %H:%M:%S UTC")


def nbgrader_timestamp(moment: _dt.datetime) -> str:
    """``moment`` (naive UTC or aware) as nbgrader writes ``timestamp.txt``:
    ``"2030-01-01 02:30:00.000000 UTC"``."""
    return _naive_utc(moment).replace(tzinfo=_UTC).strftime(NBGRADER_FORMAT)


def _naive_utc(moment: _dt.datetime) -> _dt.datetime:
    if moment.tzinfo is None:
        return moment
    return (moment - (moment.utcoffset() or _dt.timedelta(0))).replace(tzinfo=None)


def _parse_iso(text: str) -> _dt.datetime:
    """An ISO 8601 date and time with a zone, as naive UTC (ValueError saying what is wrong)."""
    import dateutil.parser

    if not _DATE_TIME.match(text):
        raise ValueError(f"{text[:40]!r} is not an ISO 8601 date and time such as 2027-03-08T23:59:00+01:00")
    try:
        moment = dateutil.parser.isoparse(text.replace(" ", "T", 1))
    except (ValueError, OverflowError) as error:
        raise ValueError(f"{text[:40]!r} is not an ISO 8601 date and time ({error})") from None
    if moment.tzinfo is None:
        raise ValueError(f"{text[:40]!r} has no time zone; write it with an offset (+01:00) or Z for UTC")
    return _naive_utc(moment)


def _from_ctime(seconds: float) -> _dt.datetime:
    return _dt.datetime.fromtimestamp(seconds, tz=_UTC).replace(tzinfo=None)


# ---------------------------------------------------------------------------- the instructor's list
_lists: dict[str, tuple[str, dict[tuple[str, str], _dt.datetime]]] = {}


def read_list(path: str | os.PathLike[str]) -> dict[tuple[str, str], _dt.datetime]:
    """The instructor's list of submission times (parsed again only when its content changes).

    Parameters
    ----------
    path : path
        A CSV file with a header naming ``student_id``, ``assignment`` and ``timestamp`` (other
        columns are allowed and ignored), one row per submission; the timestamp ISO 8601 with
        a time zone.

    Returns
    -------
    dict
        (student, assignment) → naive UTC time; empty when the file does not exist.

    Raises
    ------
    SubmissionTimesError
        Naming the file and every malformed line: a missing column, a row of the wrong length,
        an empty id, a time that is not ISO 8601 or has no zone, a submission listed twice.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return {}
    key = hashlib.sha256(data).hexdigest()
    cached = _lists.get(str(path))
    if cached is not None and cached[0] == key:
        return cached[1]
    times = _parse_list(path, data)
    _lists[str(path)] = (key, times)
    return times


def _parse_list(path: Path, data: bytes) -> dict[tuple[str, str], _dt.datetime]:
    expected = ("one row per submission, student_id,assignment,timestamp, the timestamp ISO 8601 with a "
                "time zone (e.g. ada,ch03_filtering,2027-03-08T23:59:00+01:00)")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise SubmissionTimesError(f"{path}: not UTF-8 text ({error}); expected {expected}") from None
    reader = csv.reader(io.StringIO(text, newline=""))
    problems: list[str] = []
    times: dict[tuple[str, str], _dt.datetime] = {}
    lines: dict[tuple[str, str], int] = {}
    header: list[str] | None = None
    try:
        for row in reader:
            line = reader.line_num
            if not any(cell.strip() for cell in row):
                continue
            if header is None:
                header = [cell.strip().lower() for cell in row]
                missing = [c for c in COLUMNS if c not in header]
                if missing:
                    raise SubmissionTimesError(
                        f"{path} line {line}: the header must name the columns {', '.join(COLUMNS)} "
                        f"(missing {', '.join(missing)}); expected {expected}")
                continue
            if len(row) != len(header):
                problems.append(f"line {line}: {len(row)} cells, the header has {len(header)}")
                continue
            cells = dict(zip(header, (cell.strip() for cell in row)))
            student, assignment = cells["student_id"], cells["assignment"]
            if not student or not assignment:
                problems.append(f"line {line}: empty {'student_id' if not student else 'assignment'}")
                continue
            try:
                moment = _parse_iso(cells["timestamp"])
            except ValueError as error:
                problems.append(f"line {line}: timestamp {error}")
                continue
            if (student, assignment) in lines:
                problems.append(f"line {line}: {student} {assignment} is listed already on line "
                                f"{lines[(student, assignment)]}")
                continue
            lines[(student, assignment)] = line
            times[(student, assignment)] = moment
    except csv.Error as error:
        problems.append(f"line {reader.line_num}: not CSV ({error})")
    if header is None and text.strip():
        raise SubmissionTimesError(f"{path}: no header; expected {expected}")
    if problems:
        shown = problems[:20] + ([f"... and {len(problems) - 20} more"] if len(problems) > 20 else [])
        raise SubmissionTimesError(f"{path}: {len(problems)} malformed row{'s' * (len(problems) != 1)} "
                                   f"(expected {expected}):\n  " + "\n  ".join(shown))
    return times


def listed_stamp(root: str | os.PathLike[str], student: str, assignment: str) -> str:
    """The instructor's listed time of a submission as the journal hashes it (ISO, UTC), or
    ``""`` when it is not listed. Raises :class:`SubmissionTimesError` for a malformed list."""
    moment = read_list(Path(root) / LIST_NAME).get((student, assignment))
    return moment.isoformat() + "Z" if moment is not None else ""


# ---------------------------------------------------------------------------- cvkit's records
class _Records:
    """``.cvkit/received.json``: per submission the trusted time of a version of its files,
    per assignment the earliest release seen."""

    def __init__(self, root: Path) -> None:
        self.path = Path(root) / ".cvkit" / "received.json"

    def load(self) -> dict[str, dict[str, Any]]:
        try:
            data = json.loads(self.path.read_text())
        except (OSError, ValueError):
            data = {}
        data = data if isinstance(data, dict) else {}
        return {part: data[part] if isinstance(data.get(part), dict) else {} for part in ("submissions", "releases")}

    def save(self, data: Mapping[str, Any]) -> None:
        write_whole(self.path, json.dumps(data, indent=1, sort_keys=True))

    def submission(self, student: str, assignment: str, version: str) -> Received | None:
        entry = self.load()["submissions"].get(f"{student}/{assignment}")
        if not isinstance(entry, dict) or entry.get("files") != version or entry.get("source") not in SOURCES:
            return None
        try:
            return Received(_parse_iso(str(entry.get("at"))), str(entry["source"]))
        except ValueError:
            return None

    def put(self, student: str, assignment: str, version: str, when: Received) -> Received:
        data = self.load()
        data["submissions"][f"{student}/{assignment}"] = {"files": version, "source": when.source,
                                                          "at": when.at.isoformat() + "Z"}
        self.save(data)
        return when

    def release(self, assignment: str, seen: _dt.datetime | None) -> _dt.datetime | None:
        """The earliest release of ``assignment`` recorded or ``seen`` now (recorded)."""
        data = self.load()
        try:
            recorded = _parse_iso(str(data["releases"][assignment])) if assignment in data["releases"] else None
        except ValueError:
            recorded = None
        earliest = min((t for t in (recorded, seen) if t is not None), default=None)
        if earliest is not None and earliest != recorded:
            data["releases"][assignment] = earliest.isoformat() + "Z"
            self.save(data)
        return earliest


def _version(files: Mapping[str, bytes], refused: list[str]) -> str:
    """A hash of a submission's files and refused entries, ``timestamp.txt`` left out."""
    digest = hashlib.sha256()
    for name, data in sorted(files.items()):
        if name != STAMP_FILE:
            digest.update(os.fsencode(name) + b"\0" + len(data).to_bytes(8, "big"))
            digest.update(data)
    for note in refused:
        if not note.startswith(f"{STAMP_FILE}: "):
            digest.update(os.fsencode(note) + b"\0")
    return digest.hexdigest()


def _submission(root: Path, student: str, assignment: str,
                course: CourseState | None = None) -> tuple[Path, dict[str, bytes], str]:
    folder = root / "submitted" / student / assignment
    files, refused = course.submission_snapshot(student, assignment) if course is not None else collect_files(folder)
    return folder, files, _version(files, refused)


def record_submitted(root: str | os.PathLike[str], student: str, assignment: str,
                     received_at: _dt.datetime) -> Received:
    """Record that the files now in ``submitted/<student>/<assignment>`` were received at
    ``received_at`` (an aware date-time): what :meth:`cvkit.course.Course.submit` does."""
    moment = checked_time(received_at)
    root = Path(root)
    _, _, version = _submission(root, student, assignment)
    return _Records(root).put(student, assignment, version, Received(moment, "submitted"))


def checked_time(value: Any, name: str = "received_at") -> _dt.datetime:
    """``value`` as naive UTC when it is a ``datetime`` with a time zone; else a ValueError
    naming ``name`` (a naive time could be local or UTC: the grade must not guess)."""
    if not isinstance(value, _dt.datetime) or value.tzinfo is None or value.utcoffset() is None:
        raise ValueError(f"{name} must be a datetime with a time zone, e.g. "
                         f"datetime(2027, 3, 8, 23, 59, tzinfo=timezone.utc); got {value!r}")
    return _naive_utc(value)


# ---------------------------------------------------------------------------- nbgrader's exchange
def _exchange_folder(course: CourseState) -> Path | None:
    """``<Exchange.root>/<course id>`` of the course's nbgrader configuration, when it exists."""
    from nbgrader.exchange.default.exchange import Exchange

    config = course.config()
    root = config.Exchange.root if "root" in config.Exchange else Exchange.class_traits()["root"].default_value
    course_id = config.CourseDirectory.course_id if "course_id" in config.CourseDirectory else ""
    course_id = course_id or course.plan().course_id
    if not root or not course_id:
        return None
    folder = Path(root) / course_id
    return folder if folder.is_dir() else None


_listings: dict[str, tuple[tuple[int, int, int], list[str]]] = {}


def _names(folder: Path) -> list[str]:
    """The entries of an inbound folder (read again when its modification time, link count
    or size change: a new submission folder changes them); none when unreadable."""
    try:
        info = folder.stat()
        changed = (info.st_mtime_ns, info.st_nlink, info.st_size)
        cached = _listings.get(str(folder))
        if cached is None or cached[0] != changed:
            cached = (changed, sorted(os.listdir(folder)))
            _listings[str(folder)] = cached
        return cached[1]
    except OSError:
        return []


def _same_file(path: Path, data: bytes) -> float | None:
    """The ctime of ``path`` when it is a regular file (not a link) holding exactly ``data``."""
    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    try:
        info = os.fstat(descriptor)
        if not stat.S_ISREG(info.st_mode) or info.st_size != len(data):
            return None
        with os.fdopen(os.dup(descriptor), "rb") as handle:
            if handle.read(len(data) + 1) != data:
                return None
        return info.st_ctime
    finally:
        os.close(descriptor)


def exchange_time(inbound: str | os.PathLike[str], student: str, assignment: str,
                  notebooks: Mapping[str, bytes]) -> _dt.datetime | None:
    """When nbgrader's exchange received these notebooks from ``student``.

    Parameters
    ----------
    inbound : path
        The course's ``<Exchange.root>/<course id>/inbound``.
    student, assignment : str
        Inbound folders ``<student>+<assignment>+<timestamp>+<random>`` are searched.
    notebooks : mapping
        Name (relative to the submission folder) → bytes of the collected notebooks.

    Returns
    -------
    datetime or None
        Naive UTC: of the inbound folders holding every notebook byte for byte (regular files,
        not links), the earliest; of its notebooks, the latest inode change time. None when no
        folder matches (or the folder cannot be read).
    """
    if not notebooks:
        return None
    inbound = Path(inbound)
    prefix = f"{student}+{assignment}+"
    best: float | None = None
    for name in _names(inbound):
        folder = inbound / name
        if not name.startswith(prefix) or folder.is_symlink() or not folder.is_dir():
            continue
        times = [_same_file(folder / relative, data) for relative, data in notebooks.items()]
        if all(t is not None for t in times):
            latest = max(t for t in times if t is not None)
            best = latest if best is None else min(best, latest)
    return _from_ctime(best) if best is not None else None


# ---------------------------------------------------------------------------- the received time
def received_time(course: CourseState, student: str, assignment: str) -> Received:
    """The trusted time ``student``'s submission of ``assignment`` was received (see the module
    docstring for the order of the sources); recorded at first sight.

    Raises
    ------
    SubmissionTimesError
        When the instructor's list is malformed.
    """
    root = course.root
    listed = read_list(root / LIST_NAME).get((student, assignment))
    if listed is not None:
        return Received(listed, "list")
    folder, files, version = _submission(root, student, assignment, course)
    records = _Records(root)
    recorded = records.submission(student, assignment, version)
    if recorded is not None and recorded.source == "exchange":
        return recorded
    exchange = _exchange_folder(course)
    notebooks = {name: data for name, data in files.items() if name.endswith(".ipynb")}
    found = exchange_time(exchange / "inbound", student, assignment, notebooks) if exchange is not None else None
    if found is not None:
        return records.put(student, assignment, version, Received(found, "exchange"))
    if recorded is not None:
        return recorded
    ctimes = []
    for name in files:
        if name != STAMP_FILE:
            try:
                ctimes.append((folder / name).lstat().st_ctime)
            except OSError:
                continue
    collected = _from_ctime(max(ctimes)) if ctimes else _dt.datetime.now(_UTC).replace(tzinfo=None)
    return records.put(student, assignment, version, Received(collected, "collected"))


def release_time(course: CourseState, assignment: str) -> _dt.datetime | None:
    """The earliest release of ``assignment`` seen (naive UTC): modification times of the
    release notebooks (``release/<assignment>``, the exchange's ``outbound/<assignment>``),
    recorded so that a later rebuild does not move it; None when it was never built here."""
    folders = [course.root / "release" / assignment]
    exchange = _exchange_folder(course)
    if exchange is not None:
        folders.append(exchange / "outbound" / assignment)
    times = []
    for folder in folders:
        for path in folder.glob("*.ipynb"):
            try:
                times.append(path.stat().st_mtime)
            except OSError:
                continue
    seen = _from_ctime(min(times)) if times else None
    return _Records(course.root).release(assignment, seen)


# ---------------------------------------------------------------------------- the cross-check
def read_claim(path: str | os.PathLike[str]) -> tuple[_dt.datetime | None, str]:
    """The time a student's ``timestamp.txt`` claims, read as nbgrader would (naive UTC).

    Returns
    -------
    (datetime or None, str)
        The claimed time and ``""``; or None and why it is unreadable (``"not UTF-8 text"``,
        ``"not a date and time"``, …; never the file's content); (None, ``""``) when there is
        no such regular file (a link or device is refused, and flagged, by the collection).
    """
    from nbgrader.utils import parse_utc

    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None, ""
    try:
        if not stat.S_ISREG(os.fstat(descriptor).st_mode):
            return None, ""
        with os.fdopen(os.dup(descriptor), "rb") as handle:
            data = handle.read(CLAIM_LIMIT + 1)
    finally:
        os.close(descriptor)
    if len(data) > CLAIM_LIMIT:
        return None, f"longer than {CLAIM_LIMIT} bytes"
    try:
        text = data.decode("utf-8").strip()
    except UnicodeDecodeError:
        return None, "not UTF-8 text"
    if not text:
        return None, "empty"
    if not _DATE_TIME.match(text):
        return None, "not a date and time"
    try:
        claim = parse_utc(text)
    except Exception:  # noqa: BLE001 - dateutil raises ValueError, OverflowError, TypeError …
        return None, "not a date and time"
    return (claim, "") if isinstance(claim, _dt.datetime) else (None, "not a date and time")


def _claim_copy(root: Path, student: str, assignment: str) -> Path:
    """Where the student's own ``timestamp.txt`` is kept once :func:`settle_stamp` replaced it."""
    return Path(root) / ".cvkit" / "claims" / student / assignment / STAMP_FILE


def _read_stamp(path: Path) -> bytes | None:
    """The bytes of ``path`` when it is a regular file (not a link), at most CLAIM_LIMIT + 1."""
    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(descriptor).st_mode):
            return None
        with os.fdopen(os.dup(descriptor), "rb") as handle:
            return handle.read(CLAIM_LIMIT + 1)
    finally:
        os.close(descriptor)


def settle_stamp(root: str | os.PathLike[str], student: str, assignment: str, when: Received) -> bool:
    """Make ``submitted/<student>/<assignment>/timestamp.txt`` say the trusted time ``when`` (the
    time nbgrader recorded), keeping the student's own file in ``.cvkit/claims/`` for
    :func:`cross_check` (see the module docstring). Returns True when the file was changed.
    Something else than a file or a link in its place (a folder: refused and flagged by the
    collection) is left alone, and a file that cannot be written never stops the recording."""
    root = Path(root)
    path = root / "submitted" / student / assignment / STAMP_FILE
    ours = nbgrader_timestamp(when.at)
    try:
        info: os.stat_result | None = path.lstat()
    except OSError:
        info = None
    if info is not None and not (stat.S_ISREG(info.st_mode) or stat.S_ISLNK(info.st_mode)):
        return False
    data = _read_stamp(path)
    if data is not None and data.strip() == ours.encode():
        return False
    copy = _claim_copy(root, student, assignment)
    try:
        if data is not None:
            copy.parent.mkdir(parents=True, exist_ok=True)
            copy.write_bytes(data)
        elif copy.exists():
            copy.unlink()
        write_whole(path, ours)  # a link in its place is replaced, never followed
    except OSError:
        return False
    return True


def cross_check(course: CourseState, student: str, assignment: str, when: Received | None = None) -> list[str]:
    """Flags for the instructor (``"(notebook): submission time: …"``) when the student's
    ``timestamp.txt`` is implausible next to the trusted time ``when`` (default
    :func:`received_time`): unreadable, before the release, later than ``when``, or earlier than an
    exact ``when`` (list, exchange), by more than :data:`TOLERANCE`; and when the only record is
    the collection, after the due date, while the claim is on time (the instructor may know
    better: their list wins). No file, no flag. The grade never depends on it."""
    claim, problem = read_claim(course.root / "submitted" / student / assignment / STAMP_FILE)
    copy = _claim_copy(course.root, student, assignment)
    if copy.is_file():  # the file says the trusted time (settle_stamp): the student's own is kept
        when = when if when is not None else received_time(course, student, assignment)
        if claim is not None and nbgrader_timestamp(claim) == nbgrader_timestamp(when.at):
            claim, problem = read_claim(copy)
    if claim is None and not problem:
        return []
    when = when if when is not None else received_time(course, student, assignment)
    graded = f"graded as received at {when.describe()}"
    if claim is None:
        return [f"(notebook): submission time: timestamp.txt is unreadable ({problem}); {graded}"]
    says = f"timestamp.txt says {_shown(claim)}"
    release = release_time(course, assignment)
    if release is not None and claim < min(release, when.at) - TOLERANCE:
        return [f"(notebook): submission time: {says}, before the assignment was released "
                f"({_shown(release)}); {graded}"]
    if claim > when.at + TOLERANCE:
        return [f"(notebook): submission time: {says}, after the submission was received; {graded}"]
    if when.exact and claim < when.at - TOLERANCE:
        return [f"(notebook): submission time: {says}, earlier than the record of its hand-in; {graded}"]
    due = course.plan().due(assignment)
    if when.source == "collected" and due is not None and claim <= due < when.at:
        # no record of the hand-in but its collection, after the due date: late, maybe wrongly
        return [f"(notebook): submission time: {says}, by the due date, but the only record of the hand-in "
                f"is its collection, after it; {graded}; if it was on time, list its time in {LIST_NAME}"]
    return []


def place_submission(course: CourseState, student: str, assignment: str, notebooks: Mapping[str, Any],
                     received_at: _dt.datetime | None = None) -> Path:
    """Place a submission (``{filename: notebook json}``) in ``submitted/`` as nbgrader's collect
    would, and record when it was received (in ``.cvkit/``, out of the student's folder; the
    ``timestamp.txt`` written here, as nbgrader's, is only a cross-check). See
    :meth:`cvkit.course.Course.submit`."""
    moment = checked_time(_dt.datetime.now(_dt.timezone.utc) if received_at is None else received_at)
    folder = course.root / "submitted" / student / assignment
    folder.mkdir(parents=True, exist_ok=True)
    for name, nb in notebooks.items():  # each whole: a grading run may be reading the folder
        write_whole(folder / name, json.dumps(nb, indent=1))
    write_whole(folder / STAMP_FILE, nbgrader_timestamp(moment))
    record_submitted(course.root, student, assignment, moment.replace(tzinfo=_dt.timezone.utc))
    return folder
