"""The FastAPI application: ``create_app(settings)``, served by ``vigil serve``."""

from __future__ import annotations

import asyncio
import base64
import binascii
import contextlib
import secrets
import signal
import threading
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from fastapi import FastAPI
from fastapi.responses import JSONResponse, PlainTextResponse
from fastapi.staticfiles import StaticFiles
from starlette.types import ASGIApp, Receive, Scope, Send

import app as vigil_package
from app.api.routes import analyses, cameras, events, health, pages, snapshots, streams, ws
from app.api.services import Services
from app.core.config import Settings

PACKAGE_DIR = Path(vigil_package.__file__).resolve().parent
STATIC_DIR = PACKAGE_DIR / "static"
TEMPLATES_DIR = PACKAGE_DIR / "templates"


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()
    services = Services(settings)

    @asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        await asyncio.to_thread(services.start)
        restore = _end_streams_on_signal(services)
        try:
            yield
        finally:
            restore()
            await asyncio.to_thread(services.stop)

    application = FastAPI(title="Vigil", version=vigil_package.__version__, lifespan=lifespan)
    application.state.services = services
    application.state.settings = settings
    for module in (health, cameras, streams, analyses, events, snapshots, ws, pages):
        application.include_router(module.router)
    if STATIC_DIR.is_dir():
        application.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    application.add_middleware(UploadLimit, limit=settings.max_upload_mb * 1024 * 1024)
    if settings.password:
        application.add_middleware(BasicAuth, password=settings.password)
    return application


class UploadLimit:
    """Refuse an upload whose Content-Length is over the limit before a byte of it is read."""

    SLACK = 1 << 20
    """Room for the multipart headers and the form's other fields."""

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app = app
        self.limit = limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if (
            scope["type"] == "http"
            and scope["method"] == "POST"
            and (scope["path"].rstrip("/") == "/api/analyses")
        ):
            length = dict(scope.get("headers", [])).get(b"content-length", b"")
            if length.isdigit() and int(length) > self.limit + self.SLACK:
                refusal = JSONResponse(
                    {"detail": f"upload larger than {self.limit // (1024 * 1024)} MB"},
                    status_code=413,
                    headers={"Connection": "close"},
                )
                await refusal(scope, receive, send)
                return
        await self.app(scope, receive, send)


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


class BasicAuth:
    """HTTP basic auth (any user name, the configured password) on everything but health."""

    def __init__(self, app: ASGIApp, password: str) -> None:
        self.app = app
        self.password = password.encode()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket") or scope["path"] == "/api/health":
            await self.app(scope, receive, send)
            return
        if self._authorised(scope):
            await self.app(scope, receive, send)
            return
        if scope["type"] == "websocket":
            await send({"type": "websocket.close", "code": 1008})
            return
        refusal = PlainTextResponse(
            "password required",
            status_code=401,
            headers={"WWW-Authenticate": 'Basic realm="vigil"'},
        )
        await refusal(scope, receive, send)

    def _authorised(self, scope: Scope) -> bool:
        for name, value in scope.get("headers", []):
            if name == b"authorization" and value[:6].lower() == b"basic ":
                try:
                    decoded = base64.b64decode(value[6:], validate=True)
                except (binascii.Error, ValueError):
                    return False
                _, _, password = decoded.partition(b":")
                return secrets.compare_digest(password, self.password)
        return False
