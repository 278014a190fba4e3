"""The FastAPI application: ``create_app(settings)``, served by ``vigil serve``."""

from __future__ import annotations

import asyncio
import contextlib
import json
import signal
import threading
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from fastapi.exceptions import RequestValidationError
from fastapi.staticfiles import StaticFiles
from starlette.types import ASGIApp, Message, Receive, Scope, Send

import app as vigil_package
from app.api.routes import (
    analyses,
    auth,
    cameras,
    events,
    health,
    live,
    metrics,
    nodes,
    notifications,
    pages,
    snapshots,
    streams,
    ws,
)
from app.api.routes.inputs import validation_error
from app.api.security import Access, AccessControl, CrossOriginGuard, SecurityHeaders
from app.api.services import Services
from app.core.config import Settings
from app.core.paths import STATIC_DIR

SERVER_OPTIONS: dict[str, Any] = {
    # websockets' sans-I/O protocol: of those uvicorn offers, the one that spends the
    # least CPU on a frame.
    "ws": "websockets-sansio",
    # No permessage-deflate, which every browser asks for: it deflated each /ws/live JPEG
    # (compressed already) again, about 0.4 ms of the server's CPU a 640x480 frame, for
    # nothing (bench/profile_viewer.py). /ws's JSON messages are small.
    "ws_per_message_deflate": False,
}
"""uvicorn's options for Vigil's app: ``vigil serve``'s, and the tests' servers'."""


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()
    access = Access.from_settings(settings)  # ValueError for a bad VIGIL_PASSWORD_HASH
    # From here on only the hash is kept: nothing the app holds can show the password.
    # Bandit's B105 reads this as a hard-coded password; it clears them.
    forget = {"password": None, "password_hash": None}  # nosec B105
    settings = settings.model_copy(update=forget)
    services = Services(settings)

    @asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        services.loop = asyncio.get_running_loop()  # It reads the live frames.
        # MQTT and the notifier hear the bus from before the cameras start, as /ws does.
        mqtt = services.mqtt
        if mqtt is not None:
            mqtt.subscribe(services.bus)
        heard = services.bus.subscribe()
        await asyncio.to_thread(services.start)
        if mqtt is not None:
            mqtt.start()
        notifying = asyncio.create_task(services.notifier.follow(heard), name="notifier")
        restore = _end_streams_on_signal(services)
        try:
            yield
        finally:
            restore()
            if mqtt is not None:  # Its events end and it says offline, then the cameras stop.
                await mqtt.stop()
            await asyncio.to_thread(services.stop)  # Closes the bus: the notifier's end.
            if services.relay is not None:
                await services.relay.close()
            notifying.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await notifying
            services.bus.unsubscribe(heard)

    application = FastAPI(title="Vigil", version=vigil_package.__version__, lifespan=lifespan)
    application.state.services = services
    application.state.settings = settings
    application.state.access = access
    routers = (health, metrics, auth, cameras, streams, analyses, events, snapshots)
    for module in (*routers, notifications, nodes, ws, live, pages):
        application.include_router(module.router)
    application.add_exception_handler(RequestValidationError, validation_error)
    if STATIC_DIR.is_dir():
        application.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    # The last added runs first: headers on every answer, then the cross-site check,
    # then the login check, so a stranger gets 401 rather than 413 for a big upload.
    application.add_middleware(BodyLimit, upload_limit=settings.max_upload_mb * 1024 * 1024)
    if access is not None:
        application.add_middleware(AccessControl, access=access, relay_token=services.relay_token)
    application.add_middleware(CrossOriginGuard)
    docs = (application.docs_url, application.redoc_url, application.swagger_ui_oauth2_redirect_url)
    application.add_middleware(SecurityHeaders, loose_paths=docs)
    return application


class BodyTooLargeError(Exception):
    """A request body went past its limit while arriving."""


class BodyLimit:
    """Refuse request bodies over their limit, so nothing past it is read or spooled to disk.

    Uploads (``POST /api/analyses``) may be ``upload_limit`` bytes, a login
    ``auth.MAX_LOGIN_BODY`` (the route is open to all), any other body (JSON)
    ``other_limit``. A declared Content-Length over the limit is refused before a
    byte is read; a body without one (chunked) is counted as it arrives and cut off at
    the limit, the app's answer to the aborted read replaced by the 413.
    """

    SLACK = 1 << 20
    """Room for an upload's multipart headers and the form's other fields."""

    def __init__(self, app: ASGIApp, upload_limit: int, other_limit: int = 1 << 20) -> None:
        self.app = app
        self.limits = {
            "/api/analyses": (
                upload_limit + self.SLACK,
                f"upload larger than {upload_limit // (1 << 20)} MB",
            ),
            "/api/login": (auth.MAX_LOGIN_BODY, "a login is a password, not a file"),
        }
        self.other = (other_limit, f"request body larger than {other_limit // 1024} KB")

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] in ("GET", "HEAD", "OPTIONS"):
            await self.app(scope, receive, send)
            return
        limit, detail = self.limits.get(scope["path"].rstrip("/"), self.other)

        def refusal() -> tuple[Message, Message]:
            return _json_refusal(detail)

        length = dict(scope.get("headers", [])).get(b"content-length", b"")
        if length.isdigit() and int(length) > limit:
            for message in refusal():
                await send(message)
            return
        received = 0
        refused = False

        async def counting_receive() -> Message:
            nonlocal received, refused
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    refused = True
                    raise BodyTooLargeError
            return message

        async def replacing_send(message: Message) -> None:
            if not refused:
                await send(message)
            elif message["type"] == "http.response.start":
                await send(refusal()[0])
            elif message["type"] == "http.response.body" and not message.get("more_body"):
                await send(refusal()[1])

        try:
            await self.app(scope, counting_receive, replacing_send)
        except BodyTooLargeError:
            for message in refusal():
                await send(message)


def _json_refusal(detail: str) -> tuple[Message, Message]:
    """The two ASGI messages of a 413 that closes the connection (the rest is not read)."""
    body = json.dumps({"detail": detail}).encode()
    headers = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(body)).encode()),
        (b"connection", b"close"),
    ]
    start: Message = {"type": "http.response.start", "status": 413, "headers": headers}
    return start, {"type": "http.response.body", "body": body}


def _end_streams_on_signal(services: Services) -> Callable[[], None]:
    """On Ctrl-C or SIGTERM, end every MJPEG stream at once, then let the server stop.

    uvicorn waits for open responses before it shuts down, and an MJPEG stream
    never ends by itself. The server's own signal handler (uvicorn installs it
    before the app starts) is chained, not replaced. Outside the main thread
    (tests run uvicorn in a thread) nothing is installed.
    """
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    installed: dict[int, Any] = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous = signal.getsignal(sig)
        if not callable(previous):
            continue

        def handler(signum: int, frame: Any, previous: Callable[..., Any] = previous) -> None:
            services.end_streams()
            previous(signum, frame)

        signal.signal(sig, handler)
        installed[sig] = previous

    def restore() -> None:
        for sig, previous in installed.items():
            with contextlib.suppress(ValueError):
                signal.signal(sig, previous)

    return restore
