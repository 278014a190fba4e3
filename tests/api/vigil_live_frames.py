"""/ws/live clients for tests: one that reads every message, one that never reads."""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import threading
import time
from contextlib import ExitStack
from typing import Any
from urllib.parse import urlsplit

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from tests.api.vigil_livekit import wait_for


def parse_live(message: bytes) -> tuple[dict[str, Any], bytes]:
    """A /ws/live message's header and JPEG."""
    (length,) = struct.unpack(">I", message[:4])
    return json.loads(message[4 : 4 + length].decode()), message[4 + length :]


def watch_message(cameras: list[int], width: int = 640) -> str:
    return json.dumps({"type": "watch", "cameras": cameras, "width": width})


class LiveViewer:
    """A /ws/live client in its own thread, keeping every frame: (received, header, jpeg)."""

    def __init__(self, url: str, **connect_args: Any) -> None:
        self.url = url
        self.connect_args = connect_args
        self.frames: list[tuple[float, dict[str, Any], bytes]] = []
        self.closed: ConnectionClosed | None = None
        self._lock = threading.Lock()
        self._socket: ClientConnection | None = None
        self._stack = ExitStack()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> LiveViewer:
        self._socket = self._stack.enter_context(
            connect(self.url, open_timeout=10, **self.connect_args)
        )
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stack.close()
        self._thread.join(5)

    @property
    def extensions(self) -> list[str]:
        """The extensions the server took of those offered: websockets' client offers
        permessage-deflate, as every browser does."""
        assert self._socket is not None
        return [extension.name for extension in self._socket.protocol.extensions]

    def watch(self, cameras: list[int], width: int = 640) -> None:
        assert self._socket is not None
        self._socket.send(watch_message(cameras, width))

    def send(self, text: str | bytes) -> None:
        assert self._socket is not None
        self._socket.send(text)

    def _run(self) -> None:
        assert self._socket is not None
        try:
            for message in self._socket:
                assert isinstance(message, bytes), "a /ws/live message is binary"
                header, jpeg = parse_live(message)
                with self._lock:
                    self.frames.append((time.monotonic(), header, jpeg))
        except ConnectionClosed as closed:
            self.closed = closed
        else:
            self.closed = self._socket.protocol.close_exc  # type: ignore[assignment]

    def of(self, camera_id: int, since: float = 0.0) -> list[tuple[float, dict[str, Any], bytes]]:
        with self._lock:
            return [f for f in self.frames if f[1]["camera_id"] == camera_id and f[0] >= since]

    def wait(self, camera_id: int, count: int, timeout: float = 15.0) -> list[Any]:
        return wait_for(
            lambda: len(found := self.of(camera_id)) >= count and found,
            timeout,
            f"{count} live frames of camera {camera_id}",
        )


class StuckViewer:
    """A /ws/live client that asks for cameras, then never reads a byte: a raw socket with
    a small receive buffer, so the server's writes back up at once."""

    def __init__(self, url: str, cameras: list[int]) -> None:
        parts = urlsplit(url)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        self.sock.settimeout(10)
        self.sock.connect((parts.hostname, parts.port))
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall(
            (
                f"GET {parts.path} HTTP/1.1\r\nHost: {parts.netloc}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                "Sec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        answer = b""
        while b"\r\n\r\n" not in answer:
            answer += self.sock.recv(1)  # Byte by byte: not a byte of a frame is read.
        assert answer.startswith(b"HTTP/1.1 101"), answer
        self.sock.sendall(masked_text_frame(watch_message(cameras)))

    def close(self) -> None:
        self.sock.close()


def masked_text_frame(text: str) -> bytes:
    """A client's WebSocket text frame (masked, as a client's must be)."""
    payload = text.encode()
    mask = os.urandom(4)
    masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    if len(payload) < 126:
        head = struct.pack(">BB", 0x81, 0x80 | len(payload))
    else:
        head = struct.pack(">BBH", 0x81, 0x80 | 126, len(payload))
    return head + mask + masked
