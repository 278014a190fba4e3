"""Who may use Vigil, and from where: the password hash, sessions, a login throttle, ASGI guards.

The guards are pure ASGI classes: they decide on the request's headers or touch only the
``http.response.start`` message, never a body, so endless MJPEG streams pass straight through.

- ``SecurityHeaders``: nosniff, no framing, a Content-Security-Policy, no referrer.
- ``CrossOriginGuard``: a browser request from another site may not change anything or open /ws.
- ``AccessControl``: with a password, everything but the login page, health and static files
  needs a session cookie (``POST /api/login``) or HTTP basic auth with the password.
"""

from __future__ import annotations

import asyncio
import base64
import binascii
import contextlib
import hashlib
import hmac
import math
import re
import secrets
import time
from collections import OrderedDict, deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from urllib.parse import quote, urlsplit

from starlette.requests import HTTPConnection
from starlette.responses import JSONResponse, RedirectResponse, Response
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.core.config import Settings
from app.nodes.relay import RELAY_HEADER

SESSION_COOKIE = "vigil_session"

SCRYPT_N, SCRYPT_R, SCRYPT_P = 2**15, 8, 1
"""32 MiB and about 0.1 s per check: scrypt's parameters for interactive logins."""
SALT_BYTES, KEY_BYTES = 16, 32
MAX_SCRYPT_MEMORY = 256 * 1024 * 1024
"""A VIGIL_PASSWORD_HASH that would need more memory than this per check is refused."""
HASH_FORMAT = "scrypt:N:r:p:salt:key (hex), as `vigil hash-password` prints it"


def _scrypt(password: str, salt: bytes, n: int, r: int, p: int, length: int) -> bytes:
    return hashlib.scrypt(
        password.encode(), salt=salt, n=n, r=r, p=p, maxmem=MAX_SCRYPT_MEMORY, dklen=length
    )


@dataclass(frozen=True)
class PasswordHash:
    """An scrypt hash of the password; ``encode()`` gives the ``VIGIL_PASSWORD_HASH`` text."""

    n: int
    r: int
    p: int
    salt: bytes = field(repr=False)
    key: bytes = field(repr=False)

    @classmethod
    def create(cls, password: str) -> PasswordHash:
        salt = secrets.token_bytes(SALT_BYTES)
        key = _scrypt(password, salt, SCRYPT_N, SCRYPT_R, SCRYPT_P, KEY_BYTES)
        return cls(SCRYPT_N, SCRYPT_R, SCRYPT_P, salt, key)

    @classmethod
    def parse(cls, text: str) -> PasswordHash:
        """Read ``scrypt:N:r:p:salt:key``; a ValueError that does not repeat the text otherwise."""
        error = f"VIGIL_PASSWORD_HASH is not {HASH_FORMAT}"
        parts = text.strip().split(":")
        if len(parts) != 6 or parts[0] != "scrypt":
            raise ValueError(error)
        try:
            n, r, p = int(parts[1]), int(parts[2]), int(parts[3])
            salt, key = bytes.fromhex(parts[4]), bytes.fromhex(parts[5])
        except ValueError:
            raise ValueError(error) from None
        if n < 2 or n & (n - 1) or not 1 <= r <= 64 or not 1 <= p <= 16:
            raise ValueError(f"{error}: N must be a power of 2, r 1..64, p 1..16")
        if 128 * r * (n + p + 2) > MAX_SCRYPT_MEMORY:
            raise ValueError(f"{error}: N and r need more than 256 MiB")
        if len(salt) < 8 or len(key) < 16:
            raise ValueError(f"{error}: salt or key too short")
        return cls(n, r, p, salt, key)

    def encode(self) -> str:
        return f"scrypt:{self.n}:{self.r}:{self.p}:{self.salt.hex()}:{self.key.hex()}"

    def verify(self, password: str) -> bool:
        """Slow on purpose (scrypt), then compared in constant time."""
        candidate = _scrypt(password, self.salt, self.n, self.r, self.p, len(self.key))
        return hmac.compare_digest(candidate, self.key)


class Sessions:
    """Random session tokens, kept only as SHA-256 digests; one unused for ``idle_s`` ends."""

    LIMIT = 1000
    """Most sessions kept at once; logging in beyond it ends the least recently used."""

    def __init__(self, idle_s: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.idle_s = idle_s
        self.clock = clock
        self._last_used: OrderedDict[bytes, float] = OrderedDict()  # oldest use first

    @staticmethod
    def _digest(token: str) -> bytes:
        return hashlib.sha256(token.encode()).digest()

    def create(self) -> str:
        now = self.clock()
        while self._last_used and (
            len(self._last_used) >= self.LIMIT
            or now - next(iter(self._last_used.values())) > self.idle_s
        ):
            self._last_used.popitem(last=False)
        token = secrets.token_urlsafe(32)
        self._last_used[self._digest(token)] = now
        return token

    def touch(self, token: str) -> bool:
        """Whether ``token`` is a live session; using it keeps it alive."""
        digest = self._digest(token)
        last = self._last_used.get(digest)
        now = self.clock()
        if last is None or now - last > self.idle_s:
            self._last_used.pop(digest, None)
            return False
        self._last_used[digest] = now
        self._last_used.move_to_end(digest)
        return True

    def end(self, token: str) -> None:
        self._last_used.pop(self._digest(token), None)


class LoginThrottle:
    """At most ``limit`` wrong passwords per client address in ``window_s``; a success resets."""

    def __init__(
        self, limit: int, window_s: float, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.limit = limit
        self.window_s = window_s
        self.clock = clock
        self._failures: dict[str, deque[float]] = {}

    def retry_after(self, client: str) -> float | None:
        """Seconds until ``client`` may try again, None when it may now."""
        failures = self._failures.get(client)
        if not failures:
            return None
        now = self.clock()
        while failures and now - failures[0] >= self.window_s:
            failures.popleft()
        if len(failures) < self.limit:
            return None
        return failures[0] + self.window_s - now

    def failed(self, client: str) -> None:
        if len(self._failures) > 10_000:  # Forget addresses whose failures are all old.
            now = self.clock()
            self._failures = {
                c: f for c, f in self._failures.items() if f and now - f[-1] < self.window_s
            }
        self._failures.setdefault(client, deque()).append(self.clock())

    def succeeded(self, client: str) -> None:
        self._failures.pop(client, None)


class ThrottledError(Exception):
    def __init__(self, retry_after: float) -> None:
        super().__init__(f"retry after {retry_after:.0f} s")
        self.retry_after = max(1, math.ceil(retry_after))


class Access:
    """One app's password (as a hash), sessions and login throttle."""

    def __init__(
        self, password: PasswordHash, session_hours: float, max_failures: int, window_s: float
    ) -> None:
        self.password = password
        self.sessions = Sessions(session_hours * 3600)
        self.throttle = LoginThrottle(max_failures, window_s)
        # Each check takes 32 MiB and a core for 0.1 s: a flood queues instead of piling up.
        self._hashing = asyncio.Semaphore(2)
        # The password that last passed, as a keyed digest: a script sending it with
        # every request (basic auth) is checked in microseconds, not a scrypt each.
        self._key = secrets.token_bytes(32)
        self._accepted: bytes | None = None

    @classmethod
    def from_settings(cls, settings: Settings) -> Access | None:
        """None without a password; ValueError for a bad VIGIL_PASSWORD_HASH or both set."""
        if settings.password and settings.password_hash:
            raise ValueError("set VIGIL_PASSWORD or VIGIL_PASSWORD_HASH, not both")
        if settings.password_hash:
            password = PasswordHash.parse(settings.password_hash)
        elif settings.password:
            password = PasswordHash.create(settings.password)
        else:
            return None
        return cls(
            password, settings.session_hours, settings.login_max_failures, settings.login_window_s
        )

    async def verify(self, client: str, password: str) -> bool:
        """Check a password sent by ``client``; ThrottledError after too many wrong ones."""
        self._refuse_if_throttled(client)
        digest = hmac.new(self._key, password.encode(), hashlib.sha256).digest()
        if self._accepted is not None and hmac.compare_digest(digest, self._accepted):
            self.throttle.succeeded(client)
            return True
        async with self._hashing:
            self._refuse_if_throttled(client)  # Failures may have come in while queued.
            ok = await asyncio.to_thread(self.password.verify, password)
        if ok:
            self._accepted = digest
            self.throttle.succeeded(client)
        else:
            self.throttle.failed(client)
        return ok

    def _refuse_if_throttled(self, client: str) -> None:
        wait = self.throttle.retry_after(client)
        if wait is not None:
            raise ThrottledError(wait)


def client_address(connection: HTTPConnection) -> str:
    return connection.client.host if connection.client else "unknown"


def local_path(target: str) -> str:
    """``target`` when it is a path on this server, else ``/``: no open redirect after login."""
    if not target.startswith("/") or target.startswith(("//", "/\\")) or not target.isprintable():
        return "/"
    return target


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", []):
        if key == name:
            text: str = value.decode("latin-1")
            return text
    return None


class SessionEndedError(Exception):
    """The session of an open stream or socket ended (log out, expiry)."""


async def _close_websocket(send: Send) -> None:
    """Refuse a WebSocket before accepting it: the client gets HTTP 403 (policy violation)."""
    await send({"type": "websocket.close", "code": 1008})


class AccessControl:
    """Needs a session cookie or HTTP basic auth with the password, except on open paths;
    or, from another node of the site relaying, this node's ``relay_token`` (``app.nodes.relay``).

    Without either: a page redirects to /login (303), an API call or a stream is 401 JSON,
    /ws is closed with 1008 before it is accepted.
    """

    OPEN = frozenset({"/api/health", "/login", "/api/login", "/api/logout", "/favicon.ico"})

    def __init__(self, app: ASGIApp, access: Access, relay_token: str) -> None:
        self.app = app
        self.access = access
        self.relay_token = relay_token.encode()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        path = scope.get("path", "")
        if (
            scope["type"] not in ("http", "websocket")
            or path in self.OPEN
            or path.startswith("/static/")
        ):
            await self.app(scope, receive, send)
            return
        if self._from_a_node(scope):
            await self.app(scope, receive, send)
            return
        connection = HTTPConnection(scope)
        token = connection.cookies.get(SESSION_COOKIE)
        if token and self.access.sessions.touch(token):
            refusal = None
            send = self._ending_with_session(token, send)
        else:
            refusal = await self._without_session(connection)
        if refusal is None:
            with contextlib.suppress(SessionEndedError):
                await self.app(scope, receive, send)
        elif scope["type"] == "websocket":
            await _close_websocket(send)
        else:
            await refusal(scope, receive, send)

    def _from_a_node(self, scope: Scope) -> bool:
        shown = _header(scope, RELAY_HEADER.encode())
        return bool(self.relay_token) and hmac.compare_digest(
            (shown or "").encode("latin-1"), self.relay_token
        )

    def _ending_with_session(self, token: str, send: Send) -> Send:
        """A stream or a socket lasts as long as its session: logging out ends it."""
        sessions = self.access.sessions

        async def checked_send(message: Message) -> None:
            ongoing = message["type"] == "websocket.send" or (
                message["type"] == "http.response.body" and message.get("more_body")
            )
            if ongoing and not sessions.touch(token):
                if message["type"] == "websocket.send":
                    await send({"type": "websocket.close", "code": 1008})
                else:
                    await send({"type": "http.response.body", "body": b"", "more_body": False})
                raise SessionEndedError
            await send(message)

        return checked_send

    async def _without_session(self, connection: HTTPConnection) -> Response | None:
        """None when basic auth carries the password, else the answer that refuses."""
        scope = connection.scope
        password = _basic_auth_password(connection.headers.get("authorization"))
        if password is None:
            if scope["type"] == "http" and _wants_page(scope):
                target = quote(connection.url.path, safe="/")
                if connection.url.query:
                    target += quote("?" + connection.url.query, safe="")
                return RedirectResponse(f"/login?next={target}", status_code=303)
            return _refuse(401, "log in first: POST /api/login, or basic auth with the password")
        try:
            if await self.access.verify(client_address(connection), password):
                return None
        except ThrottledError as throttled:
            return too_many_attempts(throttled)
        return _refuse(401, "wrong password")


def _wants_page(scope: Scope) -> bool:
    """A browser's GET of a page, which a login answers; not the API or ``/metrics``."""
    path = scope["path"]
    return (
        scope["method"] in ("GET", "HEAD") and not path.startswith("/api/") and path != "/metrics"
    )


def _basic_auth_password(header: str | None) -> str | None:
    if header is None or header[:6].lower() != "basic ":
        return None
    try:
        decoded = base64.b64decode(header[6:].strip(), validate=True).decode()
    except (binascii.Error, ValueError):
        return ""  # Present but unreadable: a wrong password, not an absent one.
    return decoded.partition(":")[2]


def _refuse(status: int, detail: str, headers: dict[str, str] | None = None) -> Response:
    return JSONResponse({"detail": detail}, status_code=status, headers=headers)


def too_many_attempts(throttled: ThrottledError) -> Response:
    return _refuse(
        429,
        f"too many wrong passwords: try again in {throttled.retry_after} s",
        {"Retry-After": str(throttled.retry_after)},
    )


def cross_site(scope: Scope) -> bool:
    """Whether a browser says this request comes from another site (or another origin).

    Fetch metadata first (every current browser sends it), the Origin header for older
    ones; a client that sends neither (curl, scripts) is not a browser being abused.
    """
    fetch_site = _header(scope, b"sec-fetch-site")
    if fetch_site is not None:
        return fetch_site not in ("same-origin", "none")
    origin = _header(scope, b"origin")
    if origin is None:
        return False
    parts = urlsplit(origin)
    if parts.scheme not in ("http", "https") or not parts.netloc:
        return True  # "null" (a sandboxed frame, a file:// page) or garbage.
    default_port = ":443" if parts.scheme == "https" else ":80"
    host = (_header(scope, b"host") or "").lower().removesuffix(default_port)
    return parts.netloc.lower().removesuffix(default_port) != host


class CrossOriginGuard:
    """403 for a cross-site POST/PUT/PATCH/DELETE; a cross-site /ws handshake is closed (1008).

    Without it any web page could make a visitor's browser add a camera, upload a file or
    press Activate on a Vigil at 127.0.0.1, password or not.
    """

    SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "websocket" and cross_site(scope):
            await _close_websocket(send)
            return
        if (
            scope["type"] == "http"
            and scope["method"] not in self.SAFE_METHODS
            and cross_site(scope)
        ):
            refusal = _refuse(
                403, "cross-site request refused: use Vigil's own page, or a client without Origin"
            )
            await refusal(scope, receive, send)
            return
        await self.app(scope, receive, send)


DASHBOARD_CSP = (
    "default-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; "
    "frame-ancestors 'none'"
)
"""Scripts, styles, pictures and the /ws connection from Vigil itself, nothing inline."""
REPORT_CSP = (
    "default-src 'none'; style-src 'unsafe-inline'; img-src data:; base-uri 'none'; "
    "form-action 'none'; frame-ancestors 'none'"
)
"""report.html is one self-contained file (an inline style sheet, data: charts) with no script."""
REPORT_PATH = re.compile(r"/api/analyses/[^/]+/report\.html")


class SecurityHeaders:
    """nosniff, no framing, a Content-Security-Policy and no referrer on every HTTP response.

    ``loose_paths`` (FastAPI's /docs pages load their scripts from a CDN) keep only the
    no-framing part of the policy. A response that sets its own header keeps it.
    """

    def __init__(self, app: ASGIApp, loose_paths: Iterable[str | None] = ()) -> None:
        self.app = app
        self.loose_paths = frozenset(p for p in loose_paths if p)

    def _policy(self, path: str) -> str:
        if REPORT_PATH.fullmatch(path):
            return REPORT_CSP
        if path in self.loose_paths:
            return "frame-ancestors 'none'"
        return DASHBOARD_CSP

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        extra = [
            (b"x-content-type-options", b"nosniff"),
            (b"x-frame-options", b"DENY"),
            (b"content-security-policy", self._policy(scope["path"]).encode()),
            (b"referrer-policy", b"no-referrer"),
        ]

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                present = {name.lower() for name, _ in headers}
                headers += [(name, value) for name, value in extra if name not in present]
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, send_with_headers)
