"""Cameras in a real ``vigil serve``, watched by real clients: for ``bench_cameras.py``.

A viewer of the dashboard costs the server more than the camera process's work: the
frame crosses a pipe to the server, whose event loop sends it over a socket. So these
figures run the whole stack as a user does: ``vigil serve`` as its own process (with its
camera processes), cameras added and activated over its API, and viewers in another
process, each a raw socket reading as fast as the network gives:

- ``live``: a /ws/live client watching one camera (a page showing it);
- ``mjpeg``: a ``GET /api/cameras/{id}/stream.mjpg`` client (VLC, Home Assistant).

The CPU counted is the server's and its camera processes' (all their threads), from
/proc; the viewers' process is not the server's cost and is not counted (it runs on the
same cores, so it is in the machine's busy figure). Frames read and detected come from
the cameras' ``status`` messages on /ws, timestamped on arrival (one every
``STATUS_INTERVAL_S``): a rate is the change between the first and the last status of a
window over the time between their arrivals.
"""

from __future__ import annotations

import base64
import contextlib
import itertools
import json
import multiprocessing as mp
import os
import selectors
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import httpx
from websockets.sync.client import connect

REPO = Path(__file__).resolve().parent.parent
STATUS_INTERVAL_S = 0.5
START_TIMEOUT_S = 60.0
LIVE_WIDTH = 640
BROWSER_EXTENSIONS = "permessage-deflate; client_max_window_bits"
"""What Chromium and Firefox offer on every WebSocket: a server that takes it compresses
each frame it sends (a viewer's frames are counted, never inflated)."""
"""The width a viewer asks for: a card on a page, at most the camera's 640."""


def descendants(pid: int) -> list[int]:
    """Every descendant of ``pid``: the server's camera processes (children of its
    forkserver) and the rest."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        with contextlib.suppress(OSError, IndexError, ValueError):
            stat = (entry / "stat").read_text()
            parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    found: list[int] = []
    frontier = [pid]
    while frontier:
        below = [child for child, parent in parents.items() if parent in frontier]
        found += below
        frontier = below
    return found


def cpu_seconds(pid: int) -> float:
    """All the threads' CPU time of ``pid`` (``/proc/PID/task/*/schedstat``, ns)."""
    total = 0
    tasks = Path(f"/proc/{pid}/task")
    for task in tasks.iterdir():
        with contextlib.suppress(OSError, ValueError, IndexError):
            total += int((task / "schedstat").read_text().split()[0])
    return total / 1e9


class Statuses:
    """The cameras' ``status`` messages on /ws, each with its arrival time."""

    def __init__(self, ws_url: str) -> None:
        self.seen: dict[int, list[tuple[float, dict[str, Any]]]] = {}
        self._lock = threading.Lock()
        self._socket = connect(ws_url, open_timeout=10, max_size=None)
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        with contextlib.suppress(Exception):
            for raw in self._socket:
                message = json.loads(raw)
                if message.get("type") == "status" and "camera_id" in message:
                    with self._lock:
                        self.seen.setdefault(message["camera_id"], []).append(
                            (time.monotonic(), message)
                        )

    def between(
        self, camera_id: int, start: float, end: float
    ) -> list[tuple[float, dict[str, Any]]]:
        with self._lock:
            return [s for s in self.seen.get(camera_id, []) if start <= s[0] <= end]

    def latest(self, camera_id: int) -> dict[str, Any] | None:
        with self._lock:
            found = self.seen.get(camera_id)
            return found[-1][1] if found else None

    def close(self) -> None:
        self._socket.close()
        self._thread.join(5)


class Server:
    """``vigil serve`` in its own process on a free port, with ``processes`` camera
    processes and a fresh data folder; its cameras added over the API."""

    def __init__(self, processes: int, folder: Path, extra_env: dict[str, str] | None = None):
        probe = socket.socket()
        probe.bind(("127.0.0.1", 0))
        self.port = probe.getsockname()[1]
        probe.close()
        self.base = f"http://127.0.0.1:{self.port}"
        self._data = tempfile.TemporaryDirectory(prefix="served-", dir=folder)
        env = {
            **os.environ,
            "PYTHONPATH": str(REPO),
            "VIGIL_DEMO_CAMERA": "false",
            "VIGIL_CAMERA_PROCESSES": str(processes),
            "VIGIL_STATUS_INTERVAL_S": str(STATUS_INTERVAL_S),
            "VIGIL_CLIPS": "false",  # As the in-process rows (Mode.clips).
            **(extra_env or {}),
        }
        command = [sys.executable, "-m", "app", "serve", "--port", str(self.port)]
        self.process = subprocess.Popen(
            [*command, "--data", self._data.name],
            cwd=REPO,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        self.client = httpx.Client(base_url=self.base, timeout=30)
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            if self.process.poll() is not None:
                raise SystemExit(f"vigil serve exited ({self.process.returncode})")
            with contextlib.suppress(httpx.HTTPError):
                if self.client.get("/api/health").status_code == 200:
                    break
            if time.monotonic() > deadline:
                raise SystemExit("vigil serve did not answer")
            time.sleep(0.2)
        self.statuses = Statuses(f"ws://127.0.0.1:{self.port}/ws")

    def cpu_seconds(self) -> float:
        """The server's CPU time and its camera processes' (all threads)."""
        pids = [self.process.pid, *descendants(self.process.pid)]
        total = 0.0
        for pid in pids:
            with contextlib.suppress(OSError):
                total += cpu_seconds(pid)
        return total

    def add(self, clips: Sequence[Path], activated: bool) -> list[int]:
        ids = []
        for index, clip in enumerate(clips):
            answer = self.client.post(
                "/api/cameras", json={"name": f"bench {index}", "source": f"file://{clip}"}
            )
            answer.raise_for_status()
            ids.append(answer.json()["id"])
        if activated:
            for camera_id in ids:
                self.client.post(f"/api/cameras/{camera_id}/activate").raise_for_status()
        return ids

    def wait_live(self, ids: Sequence[int], activated: bool, timeout: float = 60.0) -> None:
        """Until every camera is live and, if activated, detecting (its kernels loaded)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            ready = 0
            for camera_id in ids:
                status = self.statuses.latest(camera_id) or {"state": None}
                live = status["state"] == "live" and not status["reason"]
                ready += live and (not activated or status["processed"] > 0)
            if ready == len(ids):
                return
            time.sleep(0.2)
        raise SystemExit(f"cameras not live and detecting after {timeout:g} s")

    def remove(self, ids: Sequence[int]) -> None:
        for camera_id in ids:
            self.client.delete(f"/api/cameras/{camera_id}")

    def close(self) -> None:
        self.statuses.close()
        self.client.close()
        self.process.terminate()
        try:
            self.process.wait(15)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self._data.cleanup()


@contextlib.contextmanager
def served(processes: int, folder: Path) -> Iterator[Server]:
    server = Server(processes, folder)
    try:
        yield server
    finally:
        server.close()


def rates(server: Server, ids: Sequence[int], start: float, end: float, field: str) -> list[float]:
    """Per camera, ``field`` (``frames`` or ``processed``) per second between ``start``
    and ``end`` (monotonic), from its status messages; 0 without two of them."""
    found = []
    for camera_id in ids:
        statuses = server.statuses.between(camera_id, start, end)
        if len(statuses) < 2 or statuses[-1][0] <= statuses[0][0]:
            found.append(0.0)
            continue
        (t0, first), (t1, last) = statuses[0], statuses[-1]
        found.append((last[field] - first[field]) / (t1 - t0))
    return found


# --- viewers, in a process of their own ----------------------------------------------------


class _LiveReader:
    """A /ws/live connection watching one camera, read raw: each binary message counted."""

    def __init__(self, port: int, camera_id: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=10)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall(
            (
                f"GET /ws/live HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                f"Sec-WebSocket-Extensions: {BROWSER_EXTENSIONS}\r\n"
                "Sec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        head = b""
        while b"\r\n\r\n" not in head:
            head += self.sock.recv(1)
        if not head.startswith(b"HTTP/1.1 101"):
            raise RuntimeError(f"/ws/live refused: {head[:40]!r}")
        watch = {"type": "watch", "cameras": [camera_id], "width": LIVE_WIDTH}
        self.sock.sendall(_client_frame(0x1, json.dumps(watch).encode()))
        self.sock.setblocking(False)
        self.buffer = bytearray()
        self.count = 0

    def read(self) -> None:
        data = self.sock.recv(1 << 20)
        if not data:
            raise RuntimeError("/ws/live closed")
        self.buffer += data
        while True:
            frame = _server_frame(self.buffer)
            if frame is None:
                return
            opcode, payload, used = frame
            del self.buffer[:used]
            if opcode == 0x2:
                self.count += 1
            elif opcode == 0x9:  # A keepalive ping: answer, or the server closes.
                self.sock.setblocking(True)
                self.sock.sendall(_client_frame(0xA, payload))
                self.sock.setblocking(False)
            elif opcode == 0x8:
                raise RuntimeError("/ws/live closed by the server")


def _client_frame(opcode: int, payload: bytes) -> bytes:
    mask = os.urandom(4)
    masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    if len(payload) < 126:
        head = struct.pack(">BB", 0x80 | opcode, 0x80 | len(payload))
    else:
        head = struct.pack(">BBH", 0x80 | opcode, 0x80 | 126, len(payload))
    return head + mask + masked


def _server_frame(buffer: bytearray) -> tuple[int, bytes, int] | None:
    """(opcode, payload, bytes used) of the whole frame at the start of ``buffer``, if any."""
    if len(buffer) < 2:
        return None
    opcode, length, at = buffer[0] & 0x0F, buffer[1] & 0x7F, 2
    if length == 126:
        if len(buffer) < 4:
            return None
        (length,), at = struct.unpack_from(">H", buffer, 2), 4
    elif length == 127:
        if len(buffer) < 10:
            return None
        (length,), at = struct.unpack_from(">Q", buffer, 2), 10
    if len(buffer) < at + length:
        return None
    payload = bytes(buffer[at : at + length]) if opcode in (0x8, 0x9) else b""
    return opcode, payload, at + length


BOUNDARY = b"--frame\r\n"


class _MjpegReader:
    """A ``stream.mjpg`` client of one camera, read raw: each part counted."""

    def __init__(self, port: int, camera_id: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=10)
        self.sock.sendall(
            f"GET /api/cameras/{camera_id}/stream.mjpg HTTP/1.1\r\n"
            f"Host: 127.0.0.1:{port}\r\n\r\n".encode()
        )
        self.sock.setblocking(False)
        self.tail = b""
        self.count = 0

    def read(self) -> None:
        data = self.sock.recv(1 << 20)
        if not data:
            raise RuntimeError("stream.mjpg closed")
        joined = self.tail + data
        self.count += joined.count(BOUNDARY)
        self.tail = joined[-(len(BOUNDARY) - 1) :]


def viewers_main(conn: Connection, port: int, kind: str, ids: list[int]) -> None:
    """The viewers' process: one reader per camera; answers each "count" with every
    reader's messages so far; ends on None."""
    reader_type = _LiveReader if kind == "live" else _MjpegReader
    readers = [reader_type(port, camera_id) for camera_id in ids]
    selector = selectors.DefaultSelector()
    for reader in readers:
        selector.register(reader.sock, selectors.EVENT_READ, reader)
    selector.register(conn.fileno(), selectors.EVENT_READ, None)
    conn.send("ready")
    error = None
    while True:
        for key, _ in selector.select():
            if key.data is None:
                if conn.recv() is None:
                    for reader in readers:
                        reader.sock.close()
                    return
                conn.send(([r.count for r in readers], error, time.process_time()))
                continue
            try:
                key.data.read()
            except BlockingIOError:
                pass
            except (OSError, RuntimeError) as failed:
                error = error or str(failed)
                selector.unregister(key.fileobj)


@dataclass
class Viewers:
    """A process of viewers, one per camera; ``counts()`` says what each has had so far."""

    conn: Connection
    process: mp.process.BaseProcess

    def counts(self) -> tuple[list[int], float]:
        """Messages each viewer got, and the viewers' process's CPU seconds."""
        self.conn.send("count")
        counts, error, cpu = self.conn.recv()
        if error:
            raise SystemExit(f"a viewer failed: {error}")
        return counts, cpu

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.conn.send(None)
        self.process.join(5)
        if self.process.is_alive():
            self.process.terminate()


@contextlib.contextmanager
def viewers(port: int, kind: str, ids: Sequence[int]) -> Iterator[Viewers]:
    """A process of viewers of the server on ``port``, one per camera of ``ids``."""
    context = mp.get_context("spawn")
    ours, theirs = context.Pipe()
    process = context.Process(target=viewers_main, args=(theirs, port, kind, list(ids)))
    process.start()
    theirs.close()
    if ours.recv() != "ready":
        raise SystemExit("the viewers did not start")
    group = Viewers(ours, process)
    try:
        yield group
    finally:
        group.close()


# --- one trial: cameras in the server, measured over windows -------------------------------


@dataclass(frozen=True)
class ServedResult:
    """A trial's counts, per window (and per camera where a list of lists)."""

    read_fps: list[list[float]]
    processed_fps: list[list[float]]
    viewer_fps: list[list[float]]
    cpu_s: list[float]
    """The server's and its camera processes' CPU seconds."""
    camera_cpu_s: list[float]
    """The camera processes' alone."""
    seconds: list[float]
    alarms: int
    marks: list[Any]
    """What ``mark()`` returned at each window bound."""


def run_served(
    server: Server,
    clips: Sequence[Path],
    activated: bool,
    kind: str | None,
    bounds_after: Sequence[float],
    mark: Callable[[], Any] = lambda: None,
) -> ServedResult:
    """Cameras of ``clips`` added (and activated) in ``server``, watched by a ``kind``
    viewer each (None: unwatched), measured between window bounds ``bounds_after`` seconds
    after they are all live and detecting; removed afterwards."""
    ids = server.add(clips, activated)
    try:
        server.wait_live(ids, activated)
        with viewers(server.port, kind, ids) if kind else contextlib.nullcontext() as watching:
            start = time.monotonic()
            samples = []
            for after in bounds_after:
                delay = start + after - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                counts = watching.counts()[0] if watching is not None else [0] * len(ids)
                pids = descendants(server.process.pid)
                camera_cpu = sum(_cpu_or_zero(pid) for pid in pids)
                server_cpu = _cpu_or_zero(server.process.pid)
                samples.append(
                    (time.monotonic(), server_cpu + camera_cpu, camera_cpu, counts, mark())
                )
        time.sleep(1.5 * STATUS_INTERVAL_S)  # The last status of the last window comes.
        for camera_id in ids:
            status = server.statuses.latest(camera_id)
            if status is None or status["state"] != "live":
                state = status and (status["state"], status["reason"])
                raise SystemExit(f"camera {camera_id} in the server: {state}")
        windows = list(itertools.pairwise(samples))
        alarms = 0
        for camera_id in ids:
            seen = server.statuses.between(camera_id, samples[0][0], samples[-1][0])
            if len(seen) >= 2:
                alarms += seen[-1][1]["alarms"] - seen[0][1]["alarms"]
        return ServedResult(
            read_fps=[rates(server, ids, a[0], b[0], "frames") for a, b in windows],
            processed_fps=[rates(server, ids, a[0], b[0], "processed") for a, b in windows],
            viewer_fps=[
                [(n1 - n0) / (b[0] - a[0]) for n0, n1 in zip(a[3], b[3], strict=True)]
                for a, b in windows
            ],
            cpu_s=[b[1] - a[1] for a, b in windows],
            camera_cpu_s=[b[2] - a[2] for a, b in windows],
            seconds=[b[0] - a[0] for a, b in windows],
            alarms=alarms,
            marks=[s[4] for s in samples],
        )
    finally:
        server.remove(ids)


def _cpu_or_zero(pid: int) -> float:
    try:
        return cpu_seconds(pid)
    except OSError:
        return 0.0
