"""Alarm latency: from the camera frame where motion starts to the `alarm` on /ws, to
`motion ON` on the MQTT broker, and to a notification webhook's arrival.

Runs `vigil serve` as its own process on loopback, with one camera reading an
HTTP MJPEG camera that this script serves (640x480 at 25 fps). The camera
shows a still, noisy scene; every few seconds a square starts crossing it.
The latency of each event is the time from the moment the first frame with
the square left this script's socket to the moment the `alarm` message
arrived on /ws, the retained `ON` of `vigil/cameras/<id>/motion` arrived at
an MQTT client (where Debian's `mosquitto` is installed: this script starts
one on a free port), and the JSON webhook of a notification target (a
receiver this script serves, through Apprise, with the snapshot attached)
arrived. Prints p50 and p95 of each in milliseconds and in frame periods;
the targets: /ws and MQTT p95 <= 2 frame periods, the webhook p95 < 500 ms.

    .venv/bin/python bench/bench_latency.py [--alarms 20] [--fps 25]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import aiomqtt
import cv2
import numpy as np
import websockets
from _common import REPO_ROOT

from app.vision.pipeline import warm_up

WIDTH, HEIGHT = 640, 480
QUIET_S = 0.5


class Scene:
    """Frames on demand; `start_motion` makes the next frame the first with a moving square."""

    def __init__(self) -> None:
        rng = np.random.default_rng(3)
        texture = cv2.GaussianBlur(rng.normal(110, 40, (HEIGHT, WIDTH)), (0, 0), 6)
        self.background = np.clip(texture, 0, 255).astype(np.uint8)
        self.rng = rng
        self.lock = threading.Lock()
        self.motion_frame = -1  # frames into the current motion; -1 = still
        self.first_motion_sent: float | None = None

    def start_motion(self) -> None:
        with self.lock:
            self.motion_frame = 0
            self.first_motion_sent = None

    def stop_motion(self) -> None:
        with self.lock:
            self.motion_frame = -1

    def next_jpeg(self) -> tuple[bytes, bool]:
        noise = self.rng.normal(0, 2, (HEIGHT, WIDTH))
        frame = np.clip(self.background + noise, 0, 255).astype(np.uint8)
        with self.lock:
            step = self.motion_frame
            if step >= 0:
                x = 40 + 12 * step
                frame[200:260, x : x + 50] = 240
                self.motion_frame += 1
        ok, encoded = cv2.imencode(
            ".jpg", cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR), [cv2.IMWRITE_JPEG_QUALITY, 85]
        )
        assert ok
        return encoded.tobytes(), step == 0


def mjpeg_server(scene: Scene, fps: float) -> ThreadingHTTPServer:
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args: object) -> None:
            pass

        def do_GET(self) -> None:
            self.send_response(200)
            self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
            self.end_headers()
            period = 1.0 / fps
            next_at = time.monotonic()
            try:
                while True:
                    data, first_motion = scene.next_jpeg()
                    self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\n")
                    self.wfile.write(f"Content-Length: {len(data)}\r\n\r\n".encode())
                    self.wfile.write(data + b"\r\n")
                    self.wfile.flush()
                    if first_motion:
                        scene.first_motion_sent = time.time()
                    next_at += period
                    time.sleep(max(0.0, next_at - time.monotonic()))
            except (BrokenPipeError, ConnectionResetError):
                return

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


class Arrivals:
    """When each message of one kind arrived (``time.time()``), from any thread."""

    def __init__(self) -> None:
        self.times: list[float] = []
        self._lock = threading.Lock()

    def note(self) -> None:
        with self._lock:
            self.times.append(time.time())

    def first_after(self, moment: float, timeout: float) -> float | None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                later = [t for t in self.times if t >= moment]
            if later:
                return min(later)
            time.sleep(0.005)
        return None


def webhook_receiver(arrivals: Arrivals) -> ThreadingHTTPServer:
    """A JSON webhook for Apprise's ``json://`` URLs: notes each POST once read whole."""

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args: object) -> None:
            pass

        def do_POST(self) -> None:
            self.rfile.read(int(self.headers.get("Content-Length", 0)))
            arrivals.note()
            self.send_response(200)
            self.end_headers()

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


def start_mosquitto(folder: Path) -> tuple[subprocess.Popen[bytes], int] | None:
    """Debian's Mosquitto on a free loopback port, or None where it is not installed."""
    binary = shutil.which("mosquitto") or (
        "/usr/sbin/mosquitto" if Path("/usr/sbin/mosquitto").exists() else None
    )
    if binary is None:
        return None
    port = free_port()
    config = folder / "mosquitto.conf"
    config.write_text(
        f"listener {port} 127.0.0.1\nallow_anonymous true\nuser {os.environ.get('USER', 'root')}\n"
    )
    broker = subprocess.Popen(
        [binary, "-c", str(config)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        with socket.socket() as sock:
            if sock.connect_ex(("127.0.0.1", port)) == 0:
                return broker, port
        time.sleep(0.1)
    broker.kill()
    raise SystemExit("mosquitto did not start")


async def follow_motion(port: int, arrivals: Arrivals, ready: asyncio.Event) -> None:
    """Notes each ``ON`` of any camera's motion topic."""
    async with aiomqtt.Client("127.0.0.1", port) as client:
        await client.subscribe("vigil/cameras/+/motion", qos=1)
        ready.set()
        async for message in client.messages:
            if message.payload == b"ON" and not message.retain:
                arrivals.note()


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def request(url: str, method: str = "GET", body: dict[str, object] | None = None) -> object:
    data = json.dumps(body).encode() if body is not None else None
    req = urllib.request.Request(
        url, data=data, method=method, headers={"Content-Type": "application/json"}
    )
    with urllib.request.urlopen(req, timeout=10) as response:
        return json.loads(response.read() or b"null")


def start_vigil(port: int, data: Path, mqtt_port: int | None) -> subprocess.Popen[bytes]:
    env = {**os.environ, "VIGIL_DEMO_CAMERA": "false", "VIGIL_QUIET_S": str(QUIET_S)}
    if mqtt_port is not None:
        env["VIGIL_MQTT_URL"] = f"mqtt://127.0.0.1:{mqtt_port}"
    process = subprocess.Popen(
        [sys.executable, "-m", "app", "serve", "--port", str(port), "--data", str(data)],
        cwd=REPO_ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        try:
            request(f"http://127.0.0.1:{port}/api/health")
            return process
        except OSError:
            time.sleep(0.2)
    process.kill()
    raise SystemExit("vigil serve did not start")


async def measure(
    base: str, scene: Scene, alarms: int, mqtt_port: int | None, hooks: Arrivals
) -> dict[str, list[float]]:
    """Per path, each event's latency (seconds) from its first moving frame."""
    ws_alarms, mqtt_on = Arrivals(), Arrivals()
    latencies: dict[str, list[float]] = {"/ws alarm": [], "MQTT motion ON": [], "webhook": []}
    followers = []
    if mqtt_port is not None:
        ready = asyncio.Event()
        followers.append(asyncio.create_task(follow_motion(mqtt_port, mqtt_on, ready)))
        await asyncio.wait_for(ready.wait(), 10)
    async with websockets.connect(base.replace("http", "ws") + "/ws") as ws:

        async def follow_ws() -> None:
            async for raw in ws:
                if json.loads(raw).get("type") == "alarm":
                    ws_alarms.note()

        followers.append(asyncio.create_task(follow_ws()))
        for _ in range(alarms):
            await asyncio.sleep(QUIET_S + 1.0)  # the previous event ends; the model settles
            scene.start_motion()
            while scene.first_motion_sent is None:
                await asyncio.sleep(0.005)
            sent = scene.first_motion_sent
            paths = {"/ws alarm": ws_alarms, "webhook": hooks}
            if mqtt_port is not None:
                paths["MQTT motion ON"] = mqtt_on
            for name, arrivals in paths.items():
                arrived = await asyncio.to_thread(arrivals.first_after, sent, 10.0)
                if arrived is not None:
                    latencies[name].append(arrived - sent)
            scene.stop_motion()
    for task in followers:
        task.cancel()
    return {name: values for name, values in latencies.items() if values}


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--alarms", type=int, default=20, help="alarms to time (default 20)")
    parser.add_argument("--fps", type=float, default=25.0, help="camera frame rate (default 25)")
    args = parser.parse_args()

    # The detection kernels compiled (or found in the cache) first, as `make run` does: a
    # server that compiles them on start detects seconds late until it has.
    warm_up()
    scene = Scene()
    camera = mjpeg_server(scene, args.fps)
    hooks = Arrivals()
    hook_server = webhook_receiver(hooks)
    port = free_port()
    with tempfile.TemporaryDirectory() as data:
        broker = start_mosquitto(Path(data))
        mqtt_port = broker[1] if broker else None
        vigil = start_vigil(port, Path(data), mqtt_port)
        base = f"http://127.0.0.1:{port}"
        try:
            hook_url = f"json://127.0.0.1:{hook_server.server_address[1]}/hook"
            request(f"{base}/api/notifications", "POST", {"url": hook_url})
            camera_url = f"http://127.0.0.1:{camera.server_address[1]}/camera.mjpg"
            created = request(
                f"{base}/api/cameras", "POST", {"name": "bench", "source": camera_url}
            )
            assert isinstance(created, dict)
            request(f"{base}/api/cameras/{created['id']}/activate", "POST")
            time.sleep(2.0)  # connect and learn the scene
            latencies = asyncio.run(measure(base, scene, args.alarms, mqtt_port, hooks))
        finally:
            vigil.terminate()
            vigil.wait(10)
            if broker:
                broker[0].terminate()
            camera.shutdown()
            hook_server.shutdown()
    period_ms = 1000.0 / args.fps
    print(
        f"alarm latency from the first moving frame, {args.alarms} events, {WIDTH}x{HEIGHT} "
        f"MJPEG camera at {args.fps:g} fps over loopback, load average {os.getloadavg()[0]:.1f}"
    )
    if mqtt_port is None:
        print("  (no MQTT: mosquitto is not installed)")
    targets = {"/ws alarm": 2 * period_ms, "MQTT motion ON": 2 * period_ms, "webhook": 500.0}
    for name, values in latencies.items():
        p50, p95 = 1000 * statistics.median(values), 1000 * percentile(values, 0.95)
        verdict = "met" if p95 <= targets[name] else "NOT met"
        print(
            f"  {name:15} {len(values):3} events  p50 {p50:6.1f} ms = {p50 / period_ms:.2f} "
            f"frame periods  p95 {p95:6.1f} ms = {p95 / period_ms:.2f}  "
            f"(target p95 <= {targets[name]:.0f} ms: {verdict})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
