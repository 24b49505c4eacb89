"""Grades to an LMS through LTI 1.3 Assignment and Grade Services (AGS): ``cvkit course push --lti
CONFIG``.

cvkit acts as an LTI tool that has been registered with the platform (Canvas, Moodle, ...) as a
*service* client: it gets an access token with OAuth 2 client credentials, authenticating with a
JSON Web Token it signs with its private key (RS256, ``private_key_jwt``), for the scopes
:data:`SCOPES`; it finds or creates one line item per assignment (matched by ``resourceId`` or
``tag``, both the assignment id: a second push creates no new line item) and posts one score
per student to it.

A score is what the student earned (after the late penalty; :mod:`cvkit.course.lms`):
``gradingProgress`` ``FullyGraded`` with ``scoreGiven``; ``PendingManual`` *without* a score
while written answers wait for a hand mark; a submission not graded, not graded yet, or none at
all posts nothing and is reported. Posting a score is idempotent (the platform keeps the
latest), so a failed request is simply repeated: 429, 5xx and network errors are retried with
backoff; any other refusal (e.g. 422 for one user) is reported for that student and the others
are still posted.

The configuration is a TOML file; see :data:`KEYS` and docs/lms.md.
"""
from __future__ import annotations

import base64
import csv
import ipaddress
import json
import time
import urllib.error
import urllib.parse
import urllib.request
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .._text import printable
from .lms import GradeSheet

SCOPE_LINEITEM = "https://purl.imsglobal.org/spec/lti-ags/scope/lineitem"
SCOPE_SCORE = "https://purl.imsglobal.org/spec/lti-ags/scope/score"
SCOPES = (SCOPE_LINEITEM, SCOPE_SCORE)
LINEITEM_TYPE = "application/vnd.ims.lis.v2.lineitem+json"
CONTAINER_TYPE = "application/vnd.ims.lis.v2.lineitemcontainer+json"
SCORE_TYPE = "application/vnd.ims.lis.v1.score+json"
ASSERTION_TYPE = "urn:ietf:params:oauth:client-assertion-type:jwt-bearer"
RETRIED = {429, 500, 502, 503, 504}

#: the configuration's keys → what they are (required ones have no default)
KEYS = {
    "client_id": "the tool's client id on the platform (required)",
    "token_url": "the platform's OAuth 2 token endpoint (required)",
    "lineitems_url": "the course's line items endpoint (AGS 'lineitems' of the course context; required)",
    "private_key": "the tool's RSA private key, PEM file (relative to the config file; required)",
    "roster": "CSV with the columns student_id and lti_user_id (relative to the config file; required)",
    "audience": "the 'aud' of the signed assertion (default: token_url)",
    "key_id": "the 'kid' of the signed assertion: the key's id in the tool's JWKS (default: none)",
    "retries": "how many times a request that failed for a passing reason is repeated (default 4)",
    "backoff": "seconds before the first repeat, doubled each time (default 1)",
    "timeout": "seconds a request may take (default 30)",
}


@dataclass
class LtiConfig:
    client_id: str
    token_url: str
    lineitems_url: str
    private_key: Path
    roster: Path
    audience: str = ""
    key_id: str = ""
    retries: int = 4
    backoff: float = 1.0
    timeout: float = 30.0


def _url(value: Any, key: str, where: Path) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"{where}: {key} must be a URL")
    parts = urllib.parse.urlsplit(value.strip())
    if parts.scheme == "https" and parts.hostname:
        return value.strip()
    loopback = parts.hostname in ("localhost",)
    try:
        loopback = loopback or ipaddress.ip_address(parts.hostname or "").is_loopback
    except ValueError:
        pass
    if parts.scheme == "http" and loopback:
        return value.strip()
    raise ValueError(f"{where}: {key} must be an https:// URL (http:// only on this machine), got {value!r}")


def load_config(path: str | Path) -> LtiConfig:
    """Read and check an LTI configuration (TOML; :data:`KEYS`). Errors name the key."""
    import tomllib

    where = Path(path)
    try:
        data = tomllib.loads(where.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(f"--lti {where}: no such file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"--lti {where}: not a TOML file: {error}") from None
    data = data.get("lti", data) if isinstance(data.get("lti"), dict) else data
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)}; the keys: {', '.join(KEYS)}")
    missing = [k for k in ("client_id", "token_url", "lineitems_url", "private_key", "roster") if not data.get(k)]
    if missing:
        raise ValueError(f"{where}: missing {', '.join(missing)} ({'; '.join(f'{k}: {KEYS[k]}' for k in missing)})")
    base = where.resolve().parent
    files = {}
    for key in ("private_key", "roster"):
        file = base / str(data[key])
        if not file.is_file():
            raise FileNotFoundError(f"{where}: {key} = {data[key]!r}: no such file ({file})")
        files[key] = file
    numbers: dict[str, float] = {}
    for key, default in (("retries", 4), ("backoff", 1.0), ("timeout", 30.0)):
        value = data.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value < 0 \
                or (key == "retries" and value != int(value)):
            raise ValueError(f"{where}: {key} must be a number ≥ 0{' (whole)' * (key == 'retries')} ({KEYS[key]}), "
                             f"got {value!r}")
        numbers[key] = float(value)
    token_url = _url(data["token_url"], "token_url", where)
    return LtiConfig(client_id=str(data["client_id"]), token_url=token_url,
                     lineitems_url=_url(data["lineitems_url"], "lineitems_url", where),
                     private_key=files["private_key"], roster=files["roster"],
                     audience=str(data.get("audience") or token_url), key_id=str(data.get("key_id", "")),
                     retries=int(numbers["retries"]), backoff=numbers["backoff"], timeout=numbers["timeout"])


def read_roster(path: Path) -> dict[str, str]:
    """cvkit's student id → the LTI user id (``sub`` of the platform's launches)."""
    text = path.read_bytes().decode("utf-8-sig")
    reader = csv.DictReader(text.splitlines())
    names = [n.strip() for n in reader.fieldnames or []]
    if "student_id" not in names or "lti_user_id" not in names:
        raise ValueError(f"roster {path}: needs the columns student_id and lti_user_id; it has {', '.join(names) or 'none'}")
    found = {}
    for row in reader:
        row = {(k or "").strip(): (v or "").strip() for k, v in row.items()}
        if row.get("student_id") and row.get("lti_user_id"):
            found[row["student_id"]] = row["lti_user_id"]
    return found


# ------------------------------------------------------------------------------------- the token

def _b64(data: bytes) -> str:
    return base64.urlsafe_b64encode(data).rstrip(b"=").decode("ascii")


def client_assertion(config: LtiConfig, now: float | None = None) -> str:
    """The signed JWT (RS256) that authenticates cvkit at the token endpoint (RFC 7523)."""
    try:
        from cryptography.hazmat.primitives import hashes, serialization
        from cryptography.hazmat.primitives.asymmetric import padding, rsa
    except ImportError:
        raise RuntimeError("cvkit course push --lti signs with the cryptography package: pip install "
                           "'cvkit[lms]'") from None

    try:
        key = serialization.load_pem_private_key(config.private_key.read_bytes(), password=None)
    except (ValueError, TypeError) as error:
        raise ValueError(f"private_key {config.private_key}: not an unencrypted PEM private key ({error})") from None
    if not isinstance(key, rsa.RSAPrivateKey):
        raise ValueError(f"private_key {config.private_key}: RS256 needs an RSA key")
    issued = int(time.time() if now is None else now)
    header = {"alg": "RS256", "typ": "JWT", **({"kid": config.key_id} if config.key_id else {})}
    claims = {"iss": config.client_id, "sub": config.client_id, "aud": config.audience, "iat": issued,
              "exp": issued + 300, "jti": uuid.uuid4().hex}
    signing_input = f"{_b64(json.dumps(header).encode())}.{_b64(json.dumps(claims).encode())}"
    signature = key.sign(signing_input.encode("ascii"), padding.PKCS1v15(), hashes.SHA256())
    return f"{signing_input}.{_b64(signature)}"


class PlatformError(RuntimeError):
    """A request the platform refused (after the retries): ``status`` (0: no answer) and what it said."""

    def __init__(self, status: int, message: str):
        super().__init__(f"HTTP {status}: {message}" if status else message)
        self.status = status


@dataclass
class Response:
    status: int
    headers: Any
    body: bytes

    def json(self) -> Any:
        return json.loads(self.body.decode("utf-8")) if self.body else None


class Client:
    """The platform, as cvkit talks to it: a token, requests repeated on passing failures."""

    def __init__(self, config: LtiConfig, sleep: Callable[[float], None] = time.sleep):
        self.config = config
        self.sleep = sleep
        self.token = ""
        self.retried = 0

    def _send(self, method: str, url: str, headers: dict[str, str], body: bytes | None) -> Response:
        request = urllib.request.Request(url, data=body, method=method, headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=self.config.timeout) as reply:
                return Response(reply.status, reply.headers, reply.read())
        except urllib.error.HTTPError as error:
            return Response(error.code, error.headers, error.read() or b"")

    def request(self, method: str, url: str, headers: dict[str, str], body: bytes | None = None,
                auth: bool = True, retries: int | None = None) -> Response:
        """``method`` ``url``, repeated (with backoff; ``retries`` times, default the
        configuration's) on 429, 5xx and network errors, with a new token once on a 401; a
        refusal raises :class:`PlatformError`."""
        retries = self.config.retries if retries is None else retries
        delay = self.config.backoff
        renewed = False
        attempt = 0
        while True:
            sent = dict(headers)
            if auth:
                if not self.token:
                    self.authenticate()
                sent["Authorization"] = f"Bearer {self.token}"
            try:
                reply = self._send(method, url, sent, body)
            except (urllib.error.URLError, OSError) as error:
                reply, problem = None, f"cannot reach {url}: {getattr(error, 'reason', error)}"
            if reply is not None and reply.status == 401 and auth and not renewed:
                renewed, self.token = True, ""
                continue
            if reply is not None and reply.status < 400:
                return reply
            if reply is not None:
                problem = reply.body.decode("utf-8", "replace")[:300].strip() or "no details"
            if (reply is None or reply.status in RETRIED) and attempt < retries:
                attempt += 1
                self.retried += 1
                wait = delay
                if reply is not None and reply.headers is not None:
                    try:
                        wait = max(wait, min(60.0, float(reply.headers.get("Retry-After", 0))))
                    except (TypeError, ValueError):
                        pass
                self.sleep(wait)
                delay *= 2
                continue
            raise PlatformError(reply.status if reply is not None else 0, f"{method} {url}: {problem}")

    def authenticate(self) -> None:
        """An access token for :data:`SCOPES` (client credentials, signed client assertion)."""
        form = urllib.parse.urlencode({"grant_type": "client_credentials", "client_assertion_type": ASSERTION_TYPE,
                                       "client_assertion": client_assertion(self.config),
                                       "scope": " ".join(SCOPES)}).encode("ascii")
        try:
            reply = self.request("POST", self.config.token_url, {
                "Content-Type": "application/x-www-form-urlencoded", "Accept": "application/json"}, form, auth=False)
        except PlatformError as error:
            raise RuntimeError(f"token_url {self.config.token_url} refused cvkit's client assertion: {error} (check "
                               "client_id, key_id, the public key registered for the tool, and that it may use the "
                               "AGS scopes lineitem and score)") from None
        token = (reply.json() or {}).get("access_token")
        if not token:
            raise RuntimeError(f"token_url {self.config.token_url}: no access_token in its answer")
        self.token = str(token)


# ------------------------------------------------------------------------------------- the push

@dataclass
class Outcome:
    """What happened to one student's grade of one assignment."""

    student: str
    assignment: str
    status: str  # posted | pending | skipped | failed
    detail: str = ""


@dataclass
class PushReport:
    outcomes: list[Outcome] = field(default_factory=list)
    created: list[str] = field(default_factory=list)  # assignments whose line item was made now
    reused: list[str] = field(default_factory=list)
    lines: list[str] = field(default_factory=list)
    retried: int = 0

    @property
    def failed(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.status == "failed"]


def _next_link(headers: Any) -> str | None:
    """The ``rel="next"`` URL of a ``Link`` header (paged line item containers)."""
    for part in (headers.get("Link", "") if headers is not None else "").split(","):
        url, _, params = part.partition(";")
        if 'rel="next"' in params.replace(" ", "") or "rel=next" in params.replace(" ", ""):
            return url.strip().strip("<>")
    return None


def _same_origin(url: str, base: str, what: str) -> str:
    """``url`` when it is on the host of ``base`` (the token goes nowhere else), else RuntimeError."""
    a, b = urllib.parse.urlsplit(url), urllib.parse.urlsplit(base)
    if (a.scheme, a.netloc) != (b.scheme, b.netloc):
        raise RuntimeError(f"the platform gave {what} {url!r}, not on the host of lineitems_url ({b.netloc}): "
                           "cvkit sends its access token nowhere else")
    return url


def line_items(client: Client) -> list[dict[str, Any]]:
    """Every line item of the course (all pages)."""
    items: list[dict[str, Any]] = []
    url: str | None = client.config.lineitems_url
    seen = set()
    while url and url not in seen:
        _same_origin(url, client.config.lineitems_url, "a next page of line items")
        seen.add(url)
        reply = client.request("GET", url, {"Accept": CONTAINER_TYPE})
        page = reply.json()
        if not isinstance(page, list):
            raise RuntimeError(f"lineitems_url {url}: expected a JSON list of line items, got {type(page).__name__}")
        items += [item for item in page if isinstance(item, dict)]
        url = _next_link(reply.headers)
    return items


def _matching(items: list[dict[str, Any]], assignment: str) -> dict[str, Any] | None:
    """The line item of ``assignment``: its ``resourceId`` or its ``tag`` is the assignment id."""
    return next((i for i in items if assignment in (i.get("resourceId"), i.get("tag")) and i.get("id")), None)


def _create_line_item(client: Client, body: dict[str, Any]) -> str:
    """Make the line item ``body`` and return its id. A POST that failed for a passing reason may
    have made it all the same (the answer lost): before asking again, the line items are read and
    one made meanwhile is taken, so that repeats never make a second one."""
    delay = client.config.backoff
    for attempt in range(client.config.retries + 1):
        try:
            reply = client.request("POST", client.config.lineitems_url,
                                   {"Content-Type": LINEITEM_TYPE, "Accept": LINEITEM_TYPE},
                                   json.dumps(body).encode("utf-8"), retries=0)
        except PlatformError as error:
            if (error.status and error.status not in RETRIED) or attempt == client.config.retries:
                raise
            client.retried += 1
            client.sleep(delay)
            delay *= 2
            found = _matching(line_items(client), body["resourceId"])
            if found is not None:
                return str(found["id"])
            continue
        made = reply.json() or {}
        if not isinstance(made, dict) or not made.get("id"):
            raise RuntimeError(f"lineitems_url {client.config.lineitems_url}: the new line item for "
                               f"{body['resourceId']} has no id")
        return str(made["id"])
    raise AssertionError("unreachable")  # pragma: no cover


def scores_url(line_item: str) -> str:
    """The scores endpoint of a line item: its URL with ``/scores`` added to the path."""
    parts = urllib.parse.urlsplit(line_item)
    return urllib.parse.urlunsplit(parts._replace(path=parts.path.rstrip("/") + "/scores"))


def _timestamp() -> str:
    import datetime as _dt

    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")


def push(sheet: GradeSheet, config: LtiConfig, sleep: Callable[[float], None] = time.sleep) -> PushReport:
    """Post ``sheet`` to the platform of ``config``; see the module docstring."""
    report = PushReport()
    report.lines += sheet.notes
    roster = read_roster(config.roster)
    client = Client(config, sleep)
    existing = line_items(client)
    items: dict[str, str] = {}
    for assignment in sheet.assignments:
        top = sheet.points_possible.get(assignment)
        match = _matching(existing, assignment)
        if match is not None:
            items[assignment] = _same_origin(str(match["id"]), config.lineitems_url, "a line item")
            report.reused.append(assignment)
            if top is not None and match.get("scoreMaximum") not in (None, top):
                report.lines.append(f"{assignment}: the platform's line item has scoreMaximum {match['scoreMaximum']}, "
                                    f"the course {top:g}: change it on the platform")
            continue
        if top is None:
            report.lines.append(f"{assignment}: no line item made (no points possible: not built)")
            continue
        body = {"scoreMaximum": top, "label": sheet.titles.get(assignment) or assignment, "resourceId": assignment,
                "tag": assignment}
        items[assignment] = _same_origin(_create_line_item(client, body), config.lineitems_url, "a line item")
        report.created.append(assignment)
    for student in sheet.students:
        user = roster.get(student)
        if not user:
            for assignment in sheet.assignments:
                report.outcomes.append(Outcome(student, assignment, "skipped",
                                               f"no lti_user_id in the roster {config.roster.name}"))
            continue
        for assignment in sheet.assignments:
            grade = sheet.grade(student, assignment)
            if assignment not in items:
                report.outcomes.append(Outcome(student, assignment, "skipped", "no line item"))
                continue
            if grade.points is None and not grade.pending:
                report.outcomes.append(Outcome(student, assignment, "skipped", f"nothing posted: {grade.reason}"))
                continue
            score: dict[str, Any] = {"userId": user, "timestamp": _timestamp()}
            if grade.pending:
                score.update(activityProgress="Submitted", gradingProgress="PendingManual",
                             comment="written answers still to be marked by hand")
            else:
                score.update(scoreGiven=grade.points, scoreMaximum=sheet.points_possible.get(assignment),
                             activityProgress="Completed", gradingProgress="FullyGraded")
                if grade.penalty:
                    score["comment"] = f"after a late penalty of {grade.penalty:g} point{'s' * (grade.penalty != 1)}"
            try:
                client.request("POST", scores_url(items[assignment]), {"Content-Type": SCORE_TYPE},
                               json.dumps(score).encode("utf-8"))
            except PlatformError as error:
                report.outcomes.append(Outcome(student, assignment, "failed", printable(str(error))))
                continue
            report.outcomes.append(Outcome(student, assignment, "pending" if grade.pending else "posted",
                                           "PendingManual" if grade.pending else f"{grade.points:g}"))
    for student in sorted(set(roster) - set(sheet.students)):
        report.lines.append(f"{printable(student)} is in the LTI roster but not in the course: nothing posted")
    report.retried = client.retried
    return report
