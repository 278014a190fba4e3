"""Real receivers of notifications on loopback: an HTTP server for Apprise's JSON webhooks
(``json://``) and an SMTP server (aiosmtpd) for e-mail (``mailto://``)."""

from __future__ import annotations

import base64
import email
import email.policy
import json
import threading
import time
from dataclasses import dataclass, field
from email.message import EmailMessage
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from aiosmtpd.controller import Controller

from tests.api.vigil_livekit import free_port, wait_for


@dataclass
class Hook:
    """One webhook call as it arrived."""

    path: str
    body: dict[str, Any]
    at: float

    @property
    def attachments(self) -> list[tuple[str, str, bytes]]:
        """(file name, MIME type, bytes) of each attachment."""
        return [
            (a["filename"], a["mimetype"], base64.b64decode(a["base64"]))
            for a in self.body.get("attachments", [])
        ]


@dataclass
class WebhookReceiver:
    """A JSON webhook on 127.0.0.1 for Apprise's ``json://`` URLs.

    ``mode``: ``"ok"`` answers 200; ``"hang"`` reads the request and never answers (until
    stopped); ``"error"`` answers 500. ``fail_next`` answers that many requests with 500
    first, then as ``mode`` says.
    """

    mode: str = "ok"
    fail_next: int = 0
    calls: list[Hook] = field(default_factory=list)
    attempts: int = 0
    port: int = 0
    _server: ThreadingHTTPServer | None = None
    _stopping: threading.Event = field(default_factory=threading.Event)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def url(self, path: str = "hook", query: str = "") -> str:
        return f"json://127.0.0.1:{self.port}/{path}{'?' + query if query else ''}"

    def start(self) -> WebhookReceiver:
        receiver = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args: Any) -> None:
                pass

            def do_POST(self) -> None:
                length = int(self.headers.get("Content-Length", 0))
                raw = self.rfile.read(length)
                with receiver._lock:
                    receiver.attempts += 1
                    failing = receiver.fail_next > 0
                    receiver.fail_next -= 1 if failing else 0
                if receiver.mode == "hang" and not failing:
                    receiver._stopping.wait(60)
                    return
                if failing or receiver.mode == "error":
                    self.send_response(500)
                    self.send_header("Content-Length", "0")
                    self.end_headers()
                    return
                with receiver._lock:
                    receiver.calls.append(Hook(self.path, json.loads(raw), time.time()))
                self.send_response(200)
                self.send_header("Content-Length", "0")
                self.end_headers()

        server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        server.daemon_threads = True
        self.port = server.server_address[1]
        self._server = server
        threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True).start()
        return self

    def stop(self) -> None:
        self._stopping.set()
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()

    def received(self) -> list[Hook]:
        with self._lock:
            return list(self.calls)

    def wait(self, count: int = 1, timeout: float = 15.0) -> list[Hook]:
        return wait_for(
            lambda: len(self.received()) >= count and self.received(),
            timeout,
            f"{count} webhook call(s) at port {self.port}",
        )


class _Inbox:
    def __init__(self) -> None:
        self.mails: list[EmailMessage] = []
        self.envelopes: list[tuple[str, list[str]]] = []
        self.lock = threading.Lock()

    async def handle_DATA(self, server: Any, session: Any, envelope: Any) -> str:  # noqa: N802 (aiosmtpd calls it so)
        message = email.message_from_bytes(envelope.content, policy=email.policy.default)
        assert isinstance(message, EmailMessage)
        with self.lock:
            self.mails.append(message)
            self.envelopes.append((envelope.mail_from, list(envelope.rcpt_tos)))
        return "250 OK"


class MailReceiver:
    """A real SMTP server (aiosmtpd) on 127.0.0.1, no TLS, no login: it keeps every mail."""

    def __init__(self) -> None:
        self.port = free_port()
        self.inbox = _Inbox()
        self._controller = Controller(self.inbox, hostname="127.0.0.1", port=self.port)

    def url(self, to: str = "me@example.com", sender: str = "vigil@example.com") -> str:
        """Apprise's URL for it: plain SMTP (``mode=insecure``), from ``sender`` to ``to``."""
        return f"mailto://127.0.0.1:{self.port}?mode=insecure&from={sender}&to={to}"

    def start(self) -> MailReceiver:
        self._controller.start()
        return self

    def stop(self) -> None:
        self._controller.stop()

    def received(self) -> list[EmailMessage]:
        with self.inbox.lock:
            return list(self.inbox.mails)

    def wait(self, count: int = 1, timeout: float = 15.0) -> list[EmailMessage]:
        return wait_for(
            lambda: len(self.received()) >= count and self.received(),
            timeout,
            f"{count} mail(s) at port {self.port}",
        )
