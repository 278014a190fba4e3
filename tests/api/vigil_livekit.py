"""Real parts for the live tests: videos with known motion, a uvicorn server, an MJPEG camera.

Imported by the conftests of tests/api, tests/workers and tests/sources.
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np
import uvicorn
import websockets

from app.api.app import SERVER_OPTIONS, create_app
from app.core.config import Settings

WIDTH, HEIGHT, FPS = 320, 240, 15.0
MOTION_FIRST, MOTION_LAST = 6, 36
"""Frames in which the square is on screen (the rest of the loop is still)."""


def background(seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    coarse = cv2.resize(rng.normal(0, 1, (15, 20)), (WIDTH, HEIGHT), interpolation=cv2.INTER_CUBIC)
    return np.clip(110 + 18 * coarse / coarse.std(), 0, 255).astype(np.uint8)


def square_box(index: int) -> tuple[int, int, int, int] | None:
    """Where the moving square is in frame ``index`` (x, y, w, h), None when absent."""
    if not MOTION_FIRST <= index <= MOTION_LAST:
        return None
    return (20 + 6 * (index - MOTION_FIRST), 90, 40, 40)


def frame_at(index: int, base: np.ndarray | None = None, value: int = 230) -> np.ndarray:
    gray = (background() if base is None else base).copy()
    box = square_box(index)
    if box is not None:
        x, y, w, h = box
        gray[y : y + h, x : x + w] = value
    return cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)


def write_video(path: Path, frames: int = 45, value: int = 230) -> Path:
    """An MJPG AVI, 320x240 at 15 fps: a bright square crosses in frames 6..36, still otherwise."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), FPS, (WIDTH, HEIGHT))
    assert writer.isOpened()
    base = background()
    for i in range(frames):
        writer.write(frame_at(i, base, value))
    writer.release()
    return path


def free_socket(port: int = 0) -> socket.socket:
    """A socket bound on 127.0.0.1 at ``port`` (0: a free one; a port just used is
    reusable at once)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind(("127.0.0.1", port))
    return sock


def free_port() -> int:
    """A port on 127.0.0.1 that nothing listens on (for a server to restart at, or a
    camera that never answers)."""
    probe = free_socket()
    port: int = probe.getsockname()[1]
    probe.close()
    return port


def wait_for(
    condition: Callable[[], Any], timeout: float, what: str, interval: float = 0.05
) -> Any:
    """Poll until ``condition()`` is truthy; its value, or AssertionError after ``timeout``."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(interval)


ROOT = Path(__file__).resolve().parents[2]


def hold_answers(page: Any, url: Any, method: str = "GET") -> list[tuple[Any, Any]]:
    """Hold back from ``page`` the server's answers to its ``method`` requests to ``url``
    (a glob or a compiled pattern): each is answered at once, as things stand then, and
    given to the page only when the test fulfils its route (other requests go through).
    The (route, answer) pairs, in the order asked; the page's waits let them come."""
    held: list[tuple[Any, Any]] = []
    page.route(
        url,
        lambda route: (
            held.append((route, route.fetch()))
            if route.request.method == method
            else route.continue_()
        ),
    )
    return held


PICTURES_SHOWN = (
    "[...document.querySelectorAll('.card canvas.live')].filter(c => Number(c.dataset.drawn) > 0)"
)
"""The camera cards whose live picture has drawn a frame (from /ws/live)."""


def wait_for_pictures(
    page: Any, count: int, timeout_ms: int = 30000, at_least: bool = False
) -> None:
    """Until ``count`` camera pictures (``at_least``: that many or more) show a frame."""
    page.wait_for_function(
        f"() => {PICTURES_SHOWN}.length {'>=' if at_least else '==='} {count}", timeout=timeout_ms
    )


def wait_for_picture(page: Any, camera_id: int, timeout_ms: int = 20000) -> None:
    """Until camera ``camera_id``'s card shows a frame."""
    page.wait_for_function(
        f"() => Number(document.querySelector('.card[data-id=\"{camera_id}\"] canvas.live')"
        "?.dataset.drawn) > 0",
        timeout=timeout_ms,
    )


def show_cameras(server: Running, page: Any, source: str, count: int) -> list[int]:
    """``count`` cameras of ``source`` (cam0, cam1, ...) shown on a freshly opened page,
    each with a picture (only cards on screen get frames: each is scrolled into view in
    turn, then the page goes back to the top); their ids."""
    ids = [add_camera(server.base, source, name=f"cam{i}") for i in range(count)]
    page.goto(server.base + "/")
    for camera_id in ids:
        page.locator(f'.card[data-id="{camera_id}"] .picture').scroll_into_view_if_needed()
        wait_for_picture(page, camera_id, timeout_ms=30000)
    page.evaluate("window.scrollTo(0, 0)")
    return ids


def add_camera(
    base: str, source: str, name: str = "lane", activate: bool = False, **extra: Any
) -> int:
    """POST a camera (``extra``: more of its fields) and, if asked, activate it; its id."""
    added = httpx.post(f"{base}/api/cameras", json={"name": name, "source": source, **extra})
    assert added.status_code == 200, added.text
    camera_id = int(added.json()["id"])
    if activate:
        httpx.post(f"{base}/api/cameras/{camera_id}/activate").raise_for_status()
    return camera_id


def add_snapshot(
    server: Running, camera_id: int, ts: float, kind: str = "frame", event_id: int | None = None
) -> int:
    """A snapshot stored as a camera stores one (a small grey JPEG, file and row); its id."""
    services = server.server.config.app.state.services
    jpeg = cv2.imencode(".jpg", np.full((48, 64, 3), 90, np.uint8))[1].tobytes()
    path = services.snapshots.save(camera_id, ts, kind, jpeg, event_id)
    return int(services.database.add_snapshot(camera_id, event_id, ts, kind, path, len(jpeg)))


def watch_analysis_live(server: Running, page: Any, analysis_id: str = "a1") -> None:
    """An analysis running on the server that ``page`` hears of on /ws, as of an upload:
    its panel shows it running, with its live stream (which takes a connection)."""
    services = server.server.config.app.state.services
    services.database.add_analysis(analysis_id, "clip.avi", {})
    services.database.update_analysis(analysis_id, status="running")
    services.bus.publish({"type": "status", "analysis_id": analysis_id, "status": "running"})
    page.wait_for_selector(f'.analysis[data-id="{analysis_id}"] .status.badge-running')


@contextmanager
def serve_process(
    data_dir: Path, own_group: bool = False, log: Path | None = None, port: int = 0, **env: str
) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """``vigil serve`` as its own process on ``port`` (0: a free one), answering; ``env``
    adds variables.

    Yields the process (stdout and stderr together, as text, or into the file ``log``, for
    a long run nobody reads as it goes) and its base URL; killed at the end if still
    running. ``own_group``: in a process group of its own (with its camera processes), to
    be signalled as a service manager does.
    """
    if not port:
        sock = free_socket()
        port = sock.getsockname()[1]
        sock.close()
    output = log.open("a") if log is not None else subprocess.PIPE
    process = subprocess.Popen(
        [sys.executable, "-m", "app", "serve", "--port", str(port), "--data", str(data_dir)],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT), **env},
        stdout=output,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=own_group,
    )
    if log is not None:
        output.close()  # type: ignore[union-attr]
    base = f"http://127.0.0.1:{port}"

    def healthy() -> bool:
        if process.poll() is not None:
            said = log.read_text()[-3000:] if log is not None else process.stdout.read()  # type: ignore[union-attr]
            raise AssertionError(f"vigil serve exited: {said}")
        try:
            return httpx.get(f"{base}/api/health", timeout=1).status_code == 200
        except httpx.HTTPError:
            return False

    try:
        wait_for(healthy, 30, "vigil serve to answer", 0.2)
        yield process, base
    finally:
        if process.poll() is None:
            process.kill()
        process.wait(10)


def live_settings(data_dir: Path, **overrides: Any) -> Settings:
    values: dict[str, Any] = {
        "data_dir": data_dir,
        "demo_camera": False,
        "quiet_s": 0.5,
        "reconnect_min_s": 0.2,
        "reconnect_max_s": 1.0,
        "status_interval_s": 0.25,
        "open_timeout_ms": 2000,
        "read_timeout_ms": 1500,
        "camera_processes": 1,  # Each costs a start-up; tests/api/test_api_processes.py uses two.
    }
    values.update(overrides)
    return Settings(**values)


@dataclass
class Running:
    base: str
    ws: str
    server: uvicorn.Server
    thread: threading.Thread

    def stop(self, timeout: float = 15.0) -> float:
        started = time.monotonic()
        self.server.should_exit = True
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "uvicorn did not stop"
        return time.monotonic() - started


@contextmanager
def running_server(settings: Settings, port: int = 0, graceful_s: int = 3) -> Iterator[Running]:
    """A real uvicorn on 127.0.0.1 at ``port`` (0: a free one), as ``vigil serve`` runs it."""
    sock = free_socket(port)
    port = sock.getsockname()[1]
    config = uvicorn.Config(
        create_app(settings),
        log_level="warning",
        timeout_graceful_shutdown=graceful_s,
        lifespan="on",
        **SERVER_OPTIONS,
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    running = Running(f"http://127.0.0.1:{port}", f"ws://127.0.0.1:{port}/ws", server, thread)
    try:
        wait_for(lambda: server.started or not thread.is_alive(), 20, "uvicorn to start")
        assert server.started, "uvicorn failed to start"
        yield running
    finally:
        if thread.is_alive():
            running.stop()
        sock.close()


class WsClient:
    """A /ws client in its own thread, collecting every JSON message."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.messages: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._connected = threading.Event()
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)

    def __enter__(self) -> WsClient:
        self._thread.start()
        wait_for(lambda: self._connected.is_set() or self.error, 10, "the WebSocket to connect")
        if self.error:
            raise self.error
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)

    async def _run(self) -> None:
        try:
            async with websockets.connect(self.url) as socket_:
                self._connected.set()
                while not self._stop.is_set():
                    try:
                        raw = await asyncio.wait_for(socket_.recv(), 0.2)
                    except TimeoutError:
                        continue
                    message = json.loads(raw)
                    message["_received"] = time.time()
                    with self._lock:
                        self.messages.append(message)
        except websockets.ConnectionClosed:
            pass
        except BaseException as exc:
            self.error = exc

    def of_type(self, kind: str, **match: Any) -> list[dict[str, Any]]:
        with self._lock:
            return [
                m
                for m in self.messages
                if m.get("type") == kind and all(m.get(k) == v for k, v in match.items())
            ]

    def wait(self, kind: str, timeout: float, count: int = 1, **match: Any) -> list[dict[str, Any]]:
        return wait_for(
            lambda: len(self.of_type(kind, **match)) >= count and self.of_type(kind, **match),
            timeout,
            f"{count} {kind} {match} on /ws",
        )


class MjpegCamera:
    """A real HTTP MJPEG camera on loopback, serving ``frame_at`` frames; stop() and start() it.

    ``mode`` makes it misbehave as real cameras do: ``"silent"`` accepts connections
    and never answers, ``"stall"`` stops in the middle of a frame, ``"garbage"`` sends
    parts that are not JPEGs; ``"normal"`` again and it behaves. With ``auth`` (user,
    password) it answers 401 to a request without that HTTP basic authorisation.
    """

    def __init__(self, fps: float = FPS, auth: tuple[str, str] | None = None) -> None:
        self.fps = fps
        self.auth = auth
        self.refused = 0
        self.port = 0
        self._server: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None
        self.alive = threading.Event()
        self.served = 0
        self.mode = "normal"

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/video.mjpg"

    def start(self) -> MjpegCamera:
        camera = self
        base = background()
        noise = np.random.default_rng(5)

        def misbehaving(mode: str) -> bool:
            return camera.alive.is_set() and camera.mode == mode

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args: Any) -> None:
                pass

            def do_GET(self) -> None:
                if camera.auth is not None:
                    token = base64.b64encode(":".join(camera.auth).encode()).decode()
                    if self.headers.get("Authorization") != f"Basic {token}":
                        camera.refused += 1
                        self.send_response(401)
                        self.send_header("WWW-Authenticate", 'Basic realm="camera"')
                        self.send_header("Content-Length", "0")
                        self.end_headers()
                        return
                while misbehaving("silent"):
                    time.sleep(0.05)
                self.send_response(200)
                self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=cam")
                self.end_headers()
                index = 0
                try:
                    while camera.alive.is_set():
                        ok, data = cv2.imencode(".jpg", frame_at(index % 45, base))
                        assert ok
                        part = data.tobytes()
                        if camera.mode == "garbage":
                            part = noise.integers(0, 256, len(part), dtype=np.uint8).tobytes()
                        head = (
                            b"--cam\r\nContent-Type: image/jpeg\r\n"
                            + f"Content-Length: {len(part)}\r\n\r\n".encode()
                        )
                        if camera.mode == "stall":
                            self.wfile.write(head + part[: len(part) // 2])
                            self.wfile.flush()
                            while misbehaving("stall"):
                                time.sleep(0.05)
                            return  # This connection is spoilt; the client reconnects.
                        self.wfile.write(head + part + b"\r\n")
                        self.wfile.flush()
                        camera.served += 1
                        index += 1
                        time.sleep(1 / camera.fps)
                except OSError:
                    pass

        address = ("127.0.0.1", self.port)
        server = ThreadingHTTPServer(address, Handler, bind_and_activate=False)
        server.allow_reuse_address = True
        server.daemon_threads = True
        server.server_bind()
        server.server_activate()
        self.port = server.server_address[1]
        self._server = server
        self.alive.set()
        self._thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """The camera dies: open streams are cut and new connections refused."""
        self.alive.clear()
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None
        if self._thread is not None:
            self._thread.join(5)


def read_mjpeg_frames(response_iter: Iterator[bytes], count: int) -> list[np.ndarray]:
    """Decode ``count`` JPEG parts from a multipart/x-mixed-replace body."""
    buffer = b""
    frames: list[np.ndarray] = []
    for chunk in response_iter:
        buffer += chunk
        while True:
            start = buffer.find(b"\xff\xd8")
            end = buffer.find(b"\xff\xd9", start + 2)
            if start < 0 or end < 0:
                break
            jpeg, buffer = buffer[start : end + 2], buffer[end + 2 :]
            image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
            assert image is not None, "a part of the stream is not a JPEG"
            frames.append(image)
            if len(frames) >= count:
                return frames
    raise AssertionError(f"stream ended after {len(frames)} frames")


def set_hidden(page: Any, hidden: bool) -> None:
    """The page goes to the background (or comes back), as a tab switch tells it."""
    page.evaluate(
        """(hidden) => {
          if (hidden) {
            Object.defineProperty(document, 'hidden', { configurable: true, get: () => true });
            Object.defineProperty(document, 'visibilityState',
              { configurable: true, get: () => 'hidden' });
          } else {
            delete document.hidden;
            delete document.visibilityState;
          }
          document.dispatchEvent(new Event('visibilitychange'));
        }""",
        hidden,
    )
