"""A small LTI 1.3 platform for the tests, on 127.0.0.1 in a thread: the OAuth 2 token endpoint of
LTI's service clients (client credentials with a client assertion JWT, RFC 7523, which it
VERIFIES with the tool's public key: signature RS256, iss, sub, aud, exp, a jti used once; and
the scopes asked for) and Assignment and Grade Services' line items and scores endpoints, with
their media types. It records the exact JSON it receives; it can refuse one user's scores (422)
and fail passingly (503) a given number of times."""
from __future__ import annotations

import base64
import json
import threading
import time
import urllib.parse
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import padding, rsa

LINEITEM = "application/vnd.ims.lis.v2.lineitem+json"
CONTAINER = "application/vnd.ims.lis.v2.lineitemcontainer+json"
SCORE = "application/vnd.ims.lis.v1.score+json"
SCOPE_LINEITEM = "https://purl.imsglobal.org/spec/lti-ags/scope/lineitem"
SCOPE_SCORE = "https://purl.imsglobal.org/spec/lti-ags/scope/score"
ACTIVITY = {"Initialized", "Started", "InProgress", "Submitted", "Completed"}
GRADING = {"FullyGraded", "Pending", "PendingManual", "Failed", "NotReady"}


def new_key() -> tuple[bytes, rsa.RSAPublicKey]:
    """A fresh RSA key: (private key PEM, public key)."""
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                            serialization.NoEncryption())
    return pem, key.public_key()


def _unb64(text: str) -> bytes:
    return base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))


class Platform:
    def __init__(self, client_id: str, public_key: rsa.RSAPublicKey, page_size: int = 2):
        self.client_id = client_id
        self.public_key = public_key
        self.page_size = page_size
        self.tokens: dict[str, set[str]] = {}
        self.jtis: set[str] = set()
        self.line_items: list[dict] = []
        self.scores: list[tuple[str, dict]] = []  # (line item id, the score's JSON as received)
        self.requests: list[dict] = []  # method, path, content type, accept, status
        self.token_requests: list[dict] = []
        self.refuse_users: set[str] = set()
        self.unavailable: dict[str, int] = {}  # userId → how many of its score posts get a 503 first
        self.lose_created = 0  # how many line items are made but answered with a 503 (the answer lost)
        self.lock = threading.RLock()
        self.server = ThreadingHTTPServer(("127.0.0.1", 0), self._handler())
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    def __enter__(self) -> Platform:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.server.shutdown()
        self.server.server_close()
        self.thread.join()

    @property
    def token_url(self) -> str:
        return f"{self.url}/token"

    @property
    def lineitems_url(self) -> str:
        return f"{self.url}/courses/7/lineitems"

    def add_line_item(self, **fields) -> dict:
        item = {"id": f"{self.lineitems_url}/{len(self.line_items) + 1}", **fields}
        self.line_items.append(item)
        return item

    # ------------------------------------------------------------------ checks
    def verify_assertion(self, jwt: str) -> str:
        """'' when the client assertion is good, else why not."""
        try:
            header_b64, claims_b64, signature_b64 = jwt.split(".")
            header = json.loads(_unb64(header_b64))
            claims = json.loads(_unb64(claims_b64))
            signature = _unb64(signature_b64)
        except (ValueError, TypeError):
            return "malformed JWT"
        if header.get("alg") != "RS256":
            return f"alg {header.get('alg')!r}, not RS256"
        try:
            self.public_key.verify(signature, f"{header_b64}.{claims_b64}".encode("ascii"), padding.PKCS1v15(),
                                   hashes.SHA256())
        except InvalidSignature:
            return "bad signature"
        now = time.time()
        if claims.get("iss") != self.client_id or claims.get("sub") != self.client_id:
            return "iss/sub is not the client id"
        if claims.get("aud") not in (self.token_url, [self.token_url]):
            return f"aud {claims.get('aud')!r} is not the token endpoint"
        if not isinstance(claims.get("exp"), int) or claims["exp"] < now or claims["exp"] > now + 3600:
            return "exp missing or out of range"
        if not isinstance(claims.get("iat"), int) or claims["iat"] > now + 60:
            return "iat missing or in the future"
        if not claims.get("jti") or claims["jti"] in self.jtis:
            return "jti missing or used before"
        self.jtis.add(claims["jti"])
        return ""

    def _handler(self):
        platform = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):  # quiet
                pass

            def _reply(self, status: int, body=None, content_type: str = "application/json", headers=None):
                data = b"" if body is None else json.dumps(body).encode("utf-8")
                self.send_response(status)
                if data:
                    self.send_header("Content-Type", content_type)
                for key, value in (headers or {}).items():
                    self.send_header(key, value)
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)
                with platform.lock:
                    platform.requests.append({"method": self.command, "path": self.path, "status": status,
                                              "content_type": self.headers.get("Content-Type"),
                                              "accept": self.headers.get("Accept")})

            def _body(self) -> bytes:
                return self.rfile.read(int(self.headers.get("Content-Length") or 0))

            def _scopes(self) -> set[str] | None:
                auth = self.headers.get("Authorization", "")
                return platform.tokens.get(auth[7:]) if auth.startswith("Bearer ") else None

            def do_POST(self):
                path = urllib.parse.urlsplit(self.path).path
                body = self._body()
                if path == "/token":
                    return self._token(body)
                scopes = self._scopes()
                if scopes is None:
                    return self._reply(401, {"error": "no valid token"})
                if path == urllib.parse.urlsplit(platform.lineitems_url).path:
                    if SCOPE_LINEITEM not in scopes:
                        return self._reply(403, {"error": "scope"})
                    if self.headers.get("Content-Type") != LINEITEM:
                        return self._reply(415, {"error": f"Content-Type {self.headers.get('Content-Type')}"})
                    item = json.loads(body)
                    if not isinstance(item.get("scoreMaximum"), (int, float)) or item["scoreMaximum"] <= 0 \
                            or not item.get("label"):
                        return self._reply(400, {"error": "scoreMaximum > 0 and label required"})
                    with platform.lock:
                        made = platform.add_line_item(**item)
                        if platform.lose_created > 0:
                            platform.lose_created -= 1
                            return self._reply(503, {"error": "made, but the answer was lost"})
                    return self._reply(201, made, LINEITEM)
                if path.endswith("/scores"):
                    return self._score(path[: -len("/scores")], body, scopes)
                return self._reply(404, {"error": "not found"})

            def do_GET(self):
                parts = urllib.parse.urlsplit(self.path)
                scopes = self._scopes()
                if scopes is None:
                    return self._reply(401, {"error": "no valid token"})
                if parts.path != urllib.parse.urlsplit(platform.lineitems_url).path:
                    return self._reply(404, {"error": "not found"})
                if CONTAINER not in (self.headers.get("Accept") or ""):
                    return self._reply(406, {"error": "Accept"})
                page = int(urllib.parse.parse_qs(parts.query).get("page", ["0"])[0])
                size = platform.page_size
                items = platform.line_items[page * size:(page + 1) * size]
                headers = {}
                if (page + 1) * size < len(platform.line_items):
                    headers["Link"] = f'<{platform.lineitems_url}?page={page + 1}>; rel="next"'
                return self._reply(200, items, CONTAINER, headers)

            def _token(self, body: bytes):
                form = {k: v[0] for k, v in urllib.parse.parse_qs(body.decode("ascii")).items()}
                with platform.lock:
                    platform.token_requests.append(form)
                    why = ""
                    if self.headers.get("Content-Type") != "application/x-www-form-urlencoded":
                        why = "form expected"
                    elif form.get("grant_type") != "client_credentials":
                        why = "grant_type"
                    elif form.get("client_assertion_type") != "urn:ietf:params:oauth:client-assertion-type:jwt-bearer":
                        why = "client_assertion_type"
                    else:
                        why = platform.verify_assertion(form.get("client_assertion", ""))
                    scopes = set(form.get("scope", "").split())
                    if not why and scopes != {SCOPE_LINEITEM, SCOPE_SCORE}:  # cvkit needs (and asks for) both
                        why = f"scopes {sorted(scopes)}"
                    if why:
                        return self._reply(401, {"error": "invalid_client", "error_description": why})
                    token = f"token-{len(platform.tokens) + 1}"
                    platform.tokens[token] = scopes
                return self._reply(200, {"access_token": token, "token_type": "Bearer", "expires_in": 3600,
                                         "scope": " ".join(sorted(scopes))})

            def _score(self, item_id_path: str, body: bytes, scopes: set[str]):
                if SCOPE_SCORE not in scopes:
                    return self._reply(403, {"error": "scope"})
                if self.headers.get("Content-Type") != SCORE:
                    return self._reply(415, {"error": f"Content-Type {self.headers.get('Content-Type')}"})
                item_id = f"{platform.url}{item_id_path}"
                if not any(i["id"] == item_id for i in platform.line_items):
                    return self._reply(404, {"error": "no such line item"})
                score = json.loads(body)
                problems = [k for k in ("userId", "timestamp", "activityProgress", "gradingProgress") if k not in score]
                if score.get("activityProgress") not in ACTIVITY or score.get("gradingProgress") not in GRADING:
                    problems.append("progress values")
                if "scoreGiven" in score and not isinstance(score.get("scoreMaximum"), (int, float)):
                    problems.append("scoreGiven without scoreMaximum")
                if problems:
                    return self._reply(400, {"error": ", ".join(problems)})
                user = score["userId"]
                with platform.lock:
                    if platform.unavailable.get(user, 0) > 0:
                        platform.unavailable[user] -= 1
                        return self._reply(503, {"error": "try again"}, headers={"Retry-After": "0"})
                    if user in platform.refuse_users:
                        return self._reply(422, {"error": f"user {user} is not enrolled"})
                    platform.scores.append((item_id, score))
                return self._reply(204)

        return Handler
