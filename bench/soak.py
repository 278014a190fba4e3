"""A bounded soak on loopback: does a busy `vigil serve` lose alarms, leak memory or fail?

    .venv/bin/python bench/soak.py [--minutes 3] [--cameras 4] [--viewers 12] [--ws-clients 8]
                                   [--quiet-s 0.5] [--warmup-s S] [--sample-s 2] [--poll-s 0.5]
                                   [--log FILE] [--json]

Starts `vigil serve` as its own process on a free 127.0.0.1 port with a
temporary data folder (no demo camera, VIGIL_QUIET_S short so events end and
new ones start often). This script serves each camera as an HTTP MJPEG stream
on loopback: the demo scene (a walker, a car, two people; quiet gaps between
them) looped at its own 15 fps, each camera at another point of the loop. Then,
for --minutes: every camera is active; --viewers MJPEG clients read the
annotated streams; --ws-clients WebSocket clients on /ws record every `alarm`
(by event_id and snapshot_id) and `motion_end`; one thread polls the API and
times each call; the server's RSS (children included) is sampled.

At the end the viewers leave, the cameras are stopped and, once quiet, the
alarms in the database (the `frame` snapshots: one per alarm) are compared
with those each WebSocket client received. The exit status is 1 when an alarm
or a motion_end was lost (or one arrived that the database does not hold), the
server died or could not be stopped, an API call or a stream failed, or no
alarm happened at all. Progress goes to stderr, the report to stdout (JSON
with --json). See bench/README.md.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import cv2
import psutil
from _common import REPO_ROOT, fmt, print_environment, print_table
from bench_latency import free_port, percentile, request
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

from app.sources.live import demo_scene
from app.storage.db import Database

HOST = "127.0.0.1"
CLIP_QUALITY = 85
API_PATHS = ("/api/cameras", "/api/events", "/api/snapshots", "/api/health")
START_TIMEOUT_S = 30.0
SUBSCRIBE_TIMEOUT_S = 10.0
QUIET_TIMEOUT_S = 20.0
"""After Stop, how long every event may take to end and every message to arrive."""
STOP_TIMEOUT_S = 15.0
"""SIGTERM to exit; uvicorn's graceful shutdown is 3 s, the camera workers' a few more."""
PROGRESS_EVERY_S = 30.0
ERROR_LINE = re.compile(r"ERROR|Traceback")
ERROR_LINES_SHOWN = 5


def progress(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


# --- the cameras: a looped clip served as HTTP MJPEG ------------------------------------


@dataclass(frozen=True)
class Clip:
    jpegs: list[bytes]
    fps: float
    description: str


def render_clip() -> Clip:
    """The demo scene, every frame encoded once, so serving it costs this process next to
    nothing and the server under test keeps the CPU."""
    scene = demo_scene()
    jpegs = []
    for index in range(scene.frames):
        ok, data = cv2.imencode(
            ".jpg", scene.frame(index), [cv2.IMWRITE_JPEG_QUALITY, CLIP_QUALITY]
        )
        if not ok:
            raise RuntimeError("JPEG encoding failed")
        jpegs.append(data.tobytes())
    width, height = scene.size
    description = (
        f"the demo scene, {width}x{height} at {scene.fps:g} fps, "
        f"{scene.frames / scene.fps:.0f} s loop, JPEG q{CLIP_QUALITY}"
    )
    return Clip(jpegs, scene.fps, description)


def camera_server(clip: Clip, cameras: int) -> ThreadingHTTPServer:
    """`/camera/K.mjpg` streams the clip in a loop from K/cameras of the way through it, so
    the cameras' alarms do not all fall at the same moments."""

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args: object) -> None:
            pass

        def do_GET(self) -> None:
            match = re.fullmatch(r"/camera/(\d+)\.mjpg", self.path)
            if match is None:
                self.send_error(404)
                return
            self.send_response(200)
            self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
            self.end_headers()
            index = int(match[1]) * len(clip.jpegs) // cameras
            period = 1.0 / clip.fps
            due = time.monotonic()
            with contextlib.suppress(BrokenPipeError, ConnectionResetError):
                while True:
                    data = clip.jpegs[index % len(clip.jpegs)]
                    self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\n")
                    self.wfile.write(f"Content-Length: {len(data)}\r\n\r\n".encode())
                    self.wfile.write(data + b"\r\n")
                    self.wfile.flush()
                    index += 1
                    due += period
                    time.sleep(max(0.0, due - time.monotonic()))

    server = ThreadingHTTPServer((HOST, 0), Handler)
    threading.Thread(target=server.serve_forever, name="cameras", daemon=True).start()
    return server


# --- the server under test ------------------------------------------------------------


class VigilProcess:
    """`vigil serve` in its own process, its output in a log file."""

    def __init__(self, data: Path, quiet_s: float) -> None:
        self.port = free_port()
        self.base = f"http://{HOST}:{self.port}"
        self.log_path = data / "server.log"
        env = {**os.environ, "VIGIL_DEMO_CAMERA": "false", "VIGIL_QUIET_S": str(quiet_s)}
        env.pop("VIGIL_PASSWORD", None)  # The script's own requests carry no password.
        command = [sys.executable, "-m", "app", "serve", "--host", HOST, "--port", str(self.port)]
        with self.log_path.open("wb") as log:
            self.process = subprocess.Popen(
                [*command, "--data", str(data / "vigil")],
                cwd=REPO_ROOT,
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        self.db_path = data / "vigil" / "vigil.db"
        self.exit_code: int | None = None
        self.stop_s: float | None = None
        self.killed = False

    def wait_ready(self) -> None:
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            if not self.alive():
                raise SystemExit(f"vigil serve exited at start:\n{self.log_tail()}")
            try:
                request(f"{self.base}/api/health")
                return
            except OSError:
                time.sleep(0.2)
        raise SystemExit(f"vigil serve did not answer in {START_TIMEOUT_S:g} s")

    def alive(self) -> bool:
        return self.process.poll() is None

    def _tree(self) -> list[psutil.Process]:
        """The server and every process it started (analyses run in children)."""
        parent = psutil.Process(self.process.pid)
        return [parent, *parent.children(recursive=True)]

    def rss_mb(self) -> float:
        total = 0
        for process in self._tree():
            with contextlib.suppress(psutil.NoSuchProcess):
                total += process.memory_info().rss
        return total / 1e6

    def cpu_s(self) -> float:
        """CPU seconds (user + system) used so far by the processes of ``_tree``."""
        total = 0.0
        for process in self._tree():
            with contextlib.suppress(psutil.NoSuchProcess):
                times = process.cpu_times()
                total += times.user + times.system
        return total

    def stop(self) -> None:
        """SIGTERM, as a service manager would; killed only when it hangs."""
        if self.alive():
            began = time.monotonic()
            self.process.terminate()
            try:
                self.process.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.killed = True
                self.process.kill()
                self.process.wait()
            self.stop_s = time.monotonic() - began
        self.exit_code = self.process.returncode

    def log_lines(self) -> list[str]:
        return self.log_path.read_text(errors="replace").splitlines()

    def log_tail(self, lines: int = 20) -> str:
        return "\n".join(self.log_lines()[-lines:])


def add_cameras(base: str, camera_port: int, cameras: int) -> list[int]:
    ids = []
    for k in range(cameras):
        source = f"http://{HOST}:{camera_port}/camera/{k}.mjpg"
        created = request(f"{base}/api/cameras", "POST", {"name": f"soak-{k}", "source": source})
        assert isinstance(created, dict)
        ids.append(int(created["id"]))
    return ids


# --- the load: WebSocket clients, MJPEG viewers, API polling, RSS samples ----------------


class WsClient:
    """One /ws connection recording every alarm (event_id, snapshot_id) and motion_end."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.alarms: list[tuple[int, int]] = []
        self.ends: list[int] = []
        self.messages = 0
        self.subscribed = asyncio.Event()
        self.closing = False
        self.error: str | None = None

    async def run(self) -> None:
        try:
            async with connect(self.url, max_size=None) as socket:
                async for raw in socket:
                    self.record(json.loads(raw))
        except (OSError, ConnectionClosed) as exc:
            self.error = f"{type(exc).__name__}: {exc}"
        if not self.closing and self.error is None:
            self.error = "the server closed the connection"

    def record(self, message: dict[str, Any]) -> None:
        self.messages += 1
        kind = message.get("type")
        if kind == "status":  # The server subscribes a client before it sends the status.
            self.subscribed.set()
        elif kind == "alarm":
            self.alarms.append((int(message["event_id"]), int(message["snapshot_id"])))
        elif kind == "motion_end":
            self.ends.append(int(message["event_id"]))


class Viewer:
    """One `stream.mjpg` read as fast as it comes; counts whole JPEG frames."""

    def __init__(self, port: int, camera_id: int) -> None:
        self.port = port
        self.camera_id = camera_id
        self.frames = 0
        self.bad_frames = 0
        self.first_at: float | None = None
        self.last_at: float | None = None
        self.error: str | None = None

    async def run(self) -> None:
        try:
            await self._read()
        except (OSError, ValueError, asyncio.IncompleteReadError) as exc:
            self.error = f"{type(exc).__name__}: {exc} after {self.frames} frames"

    async def _read(self) -> None:
        reader, writer = await asyncio.open_connection(HOST, self.port)
        try:
            # HTTP/1.0: the body comes as it is, not in chunks, ending when the server closes.
            path = f"/api/cameras/{self.camera_id}/stream.mjpg"
            writer.write(f"GET {path} HTTP/1.0\r\nHost: {HOST}\r\n\r\n".encode())
            head = await reader.readuntil(b"\r\n\r\n")
            if b" 200 " not in head.split(b"\r\n", 1)[0]:
                raise ValueError(f"GET {path}: {head.splitlines()[0]!r}")
            while True:
                part = await reader.readuntil(b"\r\n\r\n")
                length = re.search(rb"(?i)content-length:\s*(\d+)", part)
                if length is None:
                    raise ValueError(f"a part without Content-Length: {part[:80]!r}")
                data = await reader.readexactly(int(length[1]) + 2)
                if not (data.startswith(b"\xff\xd8") and data.endswith(b"\xff\xd9\r\n")):
                    self.bad_frames += 1
                self.frames += 1
                self.last_at = time.monotonic()
                if self.first_at is None:
                    self.first_at = self.last_at
        finally:
            writer.close()

    @property
    def fps(self) -> float:
        if self.first_at is None or self.last_at is None or self.last_at <= self.first_at:
            return 0.0
        return (self.frames - 1) / (self.last_at - self.first_at)


class ApiPoller:
    """A thread that GETs each of API_PATHS in turn every ``interval`` seconds, as open
    dashboards do, timing each call; a failed call is recorded, not retried."""

    def __init__(self, base: str, interval: float) -> None:
        self.base = base
        self.interval = interval
        self.latencies: dict[str, list[float]] = {path: [] for path in API_PATHS}
        self.failures: list[str] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="api-poller", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        while not self._stop.is_set():
            started = time.monotonic()
            for path in API_PATHS:
                self._call(path)
            self._stop.wait(max(0.0, self.interval - (time.monotonic() - started)))

    def _call(self, path: str) -> None:
        began = time.perf_counter()
        try:
            with urllib.request.urlopen(self.base + path, timeout=10) as response:
                json.loads(response.read())
        except (OSError, ValueError) as exc:  # HTTPError (4xx, 5xx) is an OSError.
            self.failures.append(f"GET {path}: {exc}")
            return
        self.latencies[path].append(time.perf_counter() - began)


@dataclass
class Run:
    """What the load phase saw."""

    started: float = 0.0
    duration_s: float = 0.0
    rss: list[tuple[float, float]] = field(default_factory=list)
    """(seconds since the load started, MB)."""
    cores: float | None = None
    """The server's CPU seconds per second of load."""
    server_died: bool = False
    quiet: bool = False
    """Every event ended and every client got everything the database holds, after Stop."""


async def sample_rss(vigil: VigilProcess, run: Run, every_s: float) -> None:
    while True:
        # A dead server not yet reaped reads as 0 MB: that is no sample.
        with contextlib.suppress(psutil.NoSuchProcess):
            if vigil.alive():
                run.rss.append((time.monotonic() - run.started, vigil.rss_mb()))
        await asyncio.sleep(every_s)


async def cancel(tasks: Sequence[asyncio.Task[None]]) -> None:
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)


async def soak(
    args: argparse.Namespace,
    vigil: VigilProcess,
    camera_ids: list[int],
    clients: list[WsClient],
    viewers: list[Viewer],
    poller: ApiPoller,
) -> Run:
    run = Run()
    # Clients first, each known to be subscribed, so none can miss the first alarm.
    client_tasks = [asyncio.create_task(client.run()) for client in clients]
    for client in clients:
        try:
            await asyncio.wait_for(client.subscribed.wait(), SUBSCRIBE_TIMEOUT_S)
        except TimeoutError:
            raise SystemExit(f"a /ws client got no status message: {client.error}") from None
    for camera_id in camera_ids:
        await asyncio.to_thread(request, f"{vigil.base}/api/cameras/{camera_id}/activate", "POST")
    run.started = time.monotonic()
    cpu_at_start = vigil.cpu_s()
    progress(f"load on: {len(camera_ids)} cameras active, {len(viewers)} viewers")
    viewer_tasks = [asyncio.create_task(viewer.run()) for viewer in viewers]
    sampler = asyncio.create_task(sample_rss(vigil, run, args.sample_s))
    poller.start()
    try:
        await hold_load(args.minutes * 60, vigil, run, clients)
    finally:
        await cancel(viewer_tasks)
        poller.stop()
    run.duration_s = time.monotonic() - run.started
    if not run.server_died:
        run.cores = (vigil.cpu_s() - cpu_at_start) / run.duration_s
        progress("viewers gone; stopping the cameras and waiting for quiet")
        for camera_id in camera_ids:
            await asyncio.to_thread(request, f"{vigil.base}/api/cameras/{camera_id}/stop", "POST")
        run.quiet = await wait_for_quiet(vigil.db_path, clients)
    await cancel([sampler])
    for client in clients:
        client.closing = True
    await cancel(client_tasks)
    return run


async def hold_load(seconds: float, vigil: VigilProcess, run: Run, clients: list[WsClient]) -> None:
    """Let the load run, checking every second that the server lives."""
    next_note = PROGRESS_EVERY_S
    while (elapsed := time.monotonic() - run.started) < seconds:
        if not vigil.alive():
            run.server_died = True
            progress(f"the server died after {elapsed:.0f} s:\n{vigil.log_tail()}")
            return
        if elapsed >= next_note:
            next_note += PROGRESS_EVERY_S
            rss = f"{run.rss[-1][1]:.0f} MB" if run.rss else "-"
            progress(f"[{elapsed:4.0f} s] {len(clients[0].alarms)} alarms so far, RSS {rss}")
        await asyncio.sleep(1.0)


async def wait_for_quiet(db_path: Path, clients: list[WsClient]) -> bool:
    """Until every event in the database has ended and every client holds every alarm and
    motion_end recorded there; False when that does not happen in QUIET_TIMEOUT_S."""
    deadline = time.monotonic() + QUIET_TIMEOUT_S
    while time.monotonic() < deadline:
        alarms, events = await asyncio.to_thread(read_database, db_path)
        ended = {event_id for event_id, ended_at in events.items() if ended_at is not None}
        if len(ended) == len(events) and all(
            alarms <= set(c.alarms) and ended <= set(c.ends) for c in clients
        ):
            return True
        await asyncio.sleep(0.25)
    return False


def read_database(db_path: Path) -> tuple[set[tuple[int, int]], dict[int, float | None]]:
    """Alarms as (event_id, snapshot_id) of the `frame` snapshots (each alarm saves exactly
    one), and every event's end time (None while it is open), straight from SQLite."""
    db = Database(db_path)
    try:
        snapshots = db.snapshots(kind="frame", limit=sys.maxsize)
        events = db.events(limit=sys.maxsize)
    finally:
        db.close()
    alarms = {(row["event_id"], row["id"]) for row in snapshots if row["event_id"] is not None}
    return alarms, {row["id"]: row["ended_at"] for row in events}


# --- the verdict ----------------------------------------------------------------------------


def rss_summary(samples: list[tuple[float, float]], warmup_s: float) -> dict[str, Any]:
    """Start (first sample after the warm-up), end, growth, and the slope of a least-squares
    line through the samples after the warm-up (one allocation early on is not a trend), and
    through their second half alone: memory that levels off shows a flat second half, a
    leak the same slope in both."""
    after = [(t, mb) for t, mb in samples if t >= warmup_s]
    start, end = (after[0][1], after[-1][1]) if after else (None, None)
    return {
        "samples": len(samples),
        "samples_fitted": len(after),
        "peak_mb": max((mb for _, mb in samples), default=None),
        "start_mb": start,
        "end_mb": end,
        "growth_mb": None if start is None or end is None else end - start,
        "mb_per_min": slope_per_min(after),
        "mb_per_min_second_half": slope_per_min(after[len(after) // 2 :]),
    }


def slope_per_min(samples: list[tuple[float, float]]) -> float | None:
    if len(samples) < 2:
        return None
    return statistics.linear_regression(
        [t / 60 for t, _ in samples], [mb for _, mb in samples]
    ).slope


def latency_summary(poller: ApiPoller) -> dict[str, Any]:
    def stats(values: list[float]) -> dict[str, Any]:
        if not values:
            return {"calls": 0, "p50_ms": None, "p95_ms": None, "max_ms": None}
        return {
            "calls": len(values),
            "p50_ms": 1000 * statistics.median(values),
            "p95_ms": 1000 * percentile(values, 0.95),
            "max_ms": 1000 * max(values),
        }

    every = [v for values in poller.latencies.values() for v in values]
    return {
        **stats(every),
        "failures": len(poller.failures),
        "first_failures": poller.failures[:ERROR_LINES_SHOWN],
        "per_path": {path: stats(values) for path, values in poller.latencies.items()},
    }


def alarm_summary(db_path: Path, clients: list[WsClient]) -> dict[str, Any]:
    """Per client: received, lost (in the database, never received), extra (received, not in
    the database) and duplicates, for alarms and for motion_end."""
    alarms, events = read_database(db_path)
    ended = {event_id for event_id, ended_at in events.items() if ended_at is not None}
    rows = []
    for client in clients:
        received, ends = set(client.alarms), set(client.ends)
        rows.append(
            {
                "alarms": len(client.alarms),
                "lost": len(alarms - received),
                "extra": len(received - alarms),
                "duplicates": len(client.alarms) - len(received),
                "motion_end": len(client.ends),
                "motion_end_lost": len(ended - ends),
                "motion_end_extra": len(ends - set(events)),
                "messages": client.messages,
                "error": client.error,
            }
        )
    return {
        "db_alarms": len(alarms),
        "db_events": len(events),
        "db_events_open": len(events) - len(ended),
        "per_client": rows,
        "lost": sum(row["lost"] for row in rows),
        "motion_end_lost": sum(row["motion_end_lost"] for row in rows),
    }


def spread(values: Sequence[float]) -> dict[str, float | None]:
    """Min, median and max; None without values (NaN is not JSON)."""
    if not values:
        return {"min": None, "median": None, "max": None}
    return {"min": min(values), "median": statistics.median(values), "max": max(values)}


def viewer_summary(viewers: list[Viewer]) -> dict[str, Any]:
    return {
        "frames": spread([viewer.frames for viewer in viewers]),
        "fps": spread([viewer.fps for viewer in viewers]),
        "bad_frames": sum(viewer.bad_frames for viewer in viewers),
        "errors": [f"camera {v.camera_id}: {v.error}" for v in viewers if v.error],
    }


def log_summary(vigil: VigilProcess) -> dict[str, Any]:
    errors = [line for line in vigil.log_lines() if ERROR_LINE.search(line)]
    return {"error_lines": len(errors), "first": errors[:ERROR_LINES_SHOWN]}


def failures(summary: dict[str, Any]) -> list[str]:
    """Why the soak failed; empty when it passed."""
    reasons = []
    alarms, server = summary["alarms"], summary["server"]
    if server["died"]:
        reasons.append("the server died during the run")
    if server["killed"]:
        reasons.append(f"the server did not stop within {STOP_TIMEOUT_S:g} s of SIGTERM")
    if alarms["db_alarms"] == 0:
        reasons.append("no alarm was recorded: nothing was tested")
    if alarms["lost"] or alarms["motion_end_lost"]:
        reasons.append(
            f"{alarms['lost']} alarms and {alarms['motion_end_lost']} motion_end lost "
            "(summed over clients)"
        )
    if any(
        row["extra"] or row["duplicates"] or row["motion_end_extra"] for row in alarms["per_client"]
    ):
        reasons.append(
            "a client received an alarm or motion_end the database does not hold, or twice"
        )
    if any(row["error"] for row in alarms["per_client"]):
        reasons.append("a WebSocket client was disconnected")
    if alarms["db_events_open"]:
        reasons.append(f"{alarms['db_events_open']} events still open after Stop")
    if summary["api"]["failures"]:
        reasons.append(f"{summary['api']['failures']} API calls failed")
    if summary["viewers"]["errors"] or summary["viewers"]["bad_frames"]:
        reasons.append("an MJPEG stream failed or delivered a broken frame")
    return reasons


# --- output ------------------------------------------------------------------------------


def print_report(summary: dict[str, Any]) -> None:
    load = summary["load"]
    print(
        f"\nsoak: {load['duration_s']:.0f} s, {load['cameras']} cameras ({load['camera']}), "
        f"{load['viewers']} viewers, {load['ws_clients']} WebSocket clients, "
        f"VIGIL_QUIET_S={load['quiet_s']:g}, warm-up {load['warmup_s']:g} s"
    )
    print(
        f"server CPU: {fmt(load['server_cores'], 2)} of {load['cpus']} cores over the load; "
        f"load average {load['load_average']:.1f} at the end"
    )
    v = summary["viewers"]
    frames, fps = v["frames"], v["fps"]
    print(
        f"viewers: frames per viewer min {fmt(frames['min'], 0)}, "
        f"median {fmt(frames['median'], 0)}, max {fmt(frames['max'], 0)}; "
        f"fps median {fmt(fps['median'], 1)}, min {fmt(fps['min'], 1)}; "
        f"broken frames {v['bad_frames']}"
    )
    for error in v["errors"]:
        print(f"  stream error: {error}")
    r = summary["rss"]
    print(
        f"server RSS (with children): start {fmt(r['start_mb'], 1)} MB (after warm-up), "
        f"end {fmt(r['end_mb'], 1)} MB, peak {fmt(r['peak_mb'], 1)} MB, "
        f"growth {fmt(r['growth_mb'], 1)} MB; trend {fmt(r['mb_per_min'], 2)} MB/min over the "
        f"{r['samples_fitted']} samples after the warm-up ({r['samples']} in all), "
        f"{fmt(r['mb_per_min_second_half'], 2)} MB/min over their second half"
    )
    api = summary["api"]
    rows = [
        [path, s["calls"], fmt(s["p50_ms"], 1), fmt(s["p95_ms"], 1), fmt(s["max_ms"], 1)]
        for path, s in [*api["per_path"].items(), ("all", api)]
    ]
    print_table(
        f"API latency, ms ({api['failures']} failed calls)",
        ["GET", "calls", "p50", "p95", "max"],
        rows,
    )
    for failure in api["first_failures"]:
        print(f"  {failure}")
    a = summary["alarms"]
    print_table(
        f"Alarms: {a['db_alarms']} in the database ({a['db_events']} events, "
        f"{a['db_events_open']} open) against each WebSocket client",
        ["client", "alarms", "lost", "extra", "dup", "motion_end", "lost", "extra", "error"],
        [
            [
                k,
                row["alarms"],
                row["lost"],
                row["extra"],
                row["duplicates"],
                row["motion_end"],
                row["motion_end_lost"],
                row["motion_end_extra"],
                row["error"] or "-",
            ]
            for k, row in enumerate(a["per_client"])
        ],
        left=1,
    )
    print(f"lost: {a['lost']} alarms, {a['motion_end_lost']} motion_end (summed over clients)")
    s, log = summary["server"], summary["log"]
    print(
        f"\nserver: {'died during the run' if s['died'] else 'alive to the end'}, "
        f"{stop_meaning(s)} with exit status {s['exit_code']} ({exit_meaning(s['exit_code'])}), "
        f"quiet after Stop: {'yes' if s['quiet_after_stop'] else 'no'}; "
        f"{log['error_lines']} ERROR/Traceback lines in its log"
    )
    for line in log["first"]:
        print(f"  {line}")
    print("\nPASS" if summary["ok"] else "FAIL: " + "; ".join(summary["failures"]))


def stop_meaning(server: dict[str, Any]) -> str:
    if server["stop_s"] is None:
        return "not running at the end"
    return f"{'killed' if server['killed'] else 'stopped'} {server['stop_s']:.1f} s after SIGTERM"


def exit_meaning(code: int | None) -> str:
    """uvicorn re-raises the signal it stopped on once shut down, so a graceful stop on
    SIGTERM ends with -15, as a process killed by it would."""
    if code is None:
        return "still running"
    return f"signal {-code}" if code < 0 else "exited"


# --- main --------------------------------------------------------------------------------


@contextlib.contextmanager
def running(server: ThreadingHTTPServer) -> Iterator[ThreadingHTTPServer]:
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=3.0, help="load time (default 3)")
    parser.add_argument("--cameras", type=int, default=4, help="cameras (default 4)")
    parser.add_argument("--viewers", type=int, default=12, help="MJPEG viewers (default 12)")
    parser.add_argument("--ws-clients", type=int, default=8, help="/ws clients (default 8)")
    parser.add_argument(
        "--quiet-s", type=float, default=0.5, help="VIGIL_QUIET_S: quiet that ends an event"
    )
    parser.add_argument(
        "--warmup-s",
        type=float,
        default=None,
        help="seconds of load before RSS counts (default: a fifth of the run, at most 30)",
    )
    parser.add_argument("--sample-s", type=float, default=2.0, help="RSS sample period")
    parser.add_argument("--poll-s", type=float, default=0.5, help="API polling period")
    parser.add_argument("--log", type=Path, default=None, help="keep the server's log here")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    args = parser.parse_args(argv)
    if args.minutes <= 0 or args.cameras < 1 or args.ws_clients < 1 or args.viewers < 0:
        parser.error("--minutes > 0, --cameras >= 1, --ws-clients >= 1, --viewers >= 0")
    if args.quiet_s <= 0 or args.sample_s <= 0 or args.poll_s <= 0:
        parser.error("--quiet-s, --sample-s and --poll-s must be > 0")
    if args.warmup_s is None:
        args.warmup_s = min(30.0, args.minutes * 60 / 5)
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if not args.json:
        print_environment("Vigil soak")
    progress("rendering the camera clip")
    clip = render_clip()
    with (
        tempfile.TemporaryDirectory(prefix="vigil-soak-") as tmp,
        running(camera_server(clip, args.cameras)) as cameras,
    ):
        vigil = VigilProcess(Path(tmp), args.quiet_s)
        try:
            vigil.wait_ready()
            progress(f"vigil serve on {vigil.base}, log {vigil.log_path}")
            camera_ids = add_cameras(vigil.base, cameras.server_address[1], args.cameras)
            clients = [
                WsClient(vigil.base.replace("http", "ws") + "/ws") for _ in range(args.ws_clients)
            ]
            viewers = [
                Viewer(vigil.port, camera_ids[k % len(camera_ids)]) for k in range(args.viewers)
            ]
            poller = ApiPoller(vigil.base, args.poll_s)
            run = asyncio.run(soak(args, vigil, camera_ids, clients, viewers, poller))
        finally:
            vigil.stop()
            if args.log is not None:
                shutil.copyfile(vigil.log_path, args.log)
        summary: dict[str, Any] = {
            "load": {
                "duration_s": run.duration_s,
                "cameras": args.cameras,
                "camera": clip.description,
                "viewers": args.viewers,
                "ws_clients": args.ws_clients,
                "quiet_s": args.quiet_s,
                "warmup_s": args.warmup_s,
                "server_cores": run.cores,
                "cpus": os.cpu_count(),
                "load_average": os.getloadavg()[0],
            },
            "viewers": viewer_summary(viewers),
            "rss": rss_summary(run.rss, args.warmup_s),
            "api": latency_summary(poller),
            "alarms": alarm_summary(vigil.db_path, clients),
            "server": {
                "died": run.server_died,
                "exit_code": vigil.exit_code,
                "stop_s": vigil.stop_s,
                "killed": vigil.killed,
                "quiet_after_stop": run.quiet,
            },
            "log": log_summary(vigil),
        }
    summary["failures"] = failures(summary)
    summary["ok"] = not summary["failures"]
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print_report(summary)
    return 0 if summary["ok"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
