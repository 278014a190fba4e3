"""Cameras in worker processes: the process model of ``vigil serve``.

One process with a thread per camera is bound by the GIL at 20-30 activated
640x480 cameras on two cores, where two processes carry 26-36, the cores then all
but full (``bench/bench_cameras.py``, as a shared machine's speed varies).
So the cameras run in up to ``camera_processes`` processes (default: one per CPU),
each a set of ``CameraWorker`` threads, started as cameras need them. The server
keeps a ``RemoteCamera`` per camera with the face the API uses (``Camera``: hub,
status, activate, settings).
A pipe per process carries commands one way and, the other way, status and
alarm messages and the MJPEG pictures that someone watches (encoded in the camera
process, only while watched); a second pipe carries /ws/live messages, read by the
server's event loop (``app.workers.live_pipe``). Each process opens the same SQLite database (WAL)
and snapshot folder, so an alarm's rows are committed before its message leaves.
A camera process that dies is started again with its cameras, which meanwhile
say why they are down.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import multiprocessing
import os
import signal
import threading
import time
from multiprocessing.connection import Connection
from multiprocessing.reduction import DupFd
from typing import Any, Protocol

import cv2

from app.core.config import Settings
from app.events.messages import CameraStatus, Wire, WsMessage
from app.recording.recorder import clip_url
from app.storage.clips import ClipStore, finish_unfinished
from app.storage.db import Database
from app.storage.files import SnapshotStore
from app.vision.pipeline import warm_up
from app.workers.analysis import signal_label
from app.workers.bus import EventBus
from app.workers.camera import (
    DETECTION_WARMING,
    CameraWorker,
    motion_end_message,
    status_fields,
)
from app.workers.frame_sender import FrameSender, Link
from app.workers.hub import FrameHub, Kind, SentFrame
from app.workers.live_pipe import LivePipeReader, LivePipeWriter

log = logging.getLogger("vigil.cameras")

_generations = itertools.count(1)

RESTART_DELAY_S = 1.0
"""Wait before starting a camera process that died again (a crash loop stays cheap)."""
KILLED_WAIT_S = 2.0
"""How long a killed camera process may take to be gone."""


class Camera(Protocol):
    """A camera as the API sees it, wherever its worker runs."""

    camera_id: int
    hub: FrameHub

    @property
    def state(self) -> str: ...

    @property
    def reason(self) -> str: ...

    def status(self) -> dict[str, Any]: ...

    def set_active(self, active: bool) -> None: ...

    def update(self, **changes: Any) -> None: ...


class _Inherited:
    """A file descriptor of the server's for a process it starts: an int there, the same
    file duplicated into it when pickled for the start."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return (_detach, (DupFd(self.fd),))


def _detach(duplicate: Any) -> int:
    return int(duplicate.detach())


def _stderr() -> _Inherited | None:
    """The server's stderr for a camera process, if it has one open."""
    try:
        os.fstat(2)
    except OSError:
        return None
    return _Inherited(2)


# --- the camera process --------------------------------------------------------------------


class _WorkerLink:
    """One worker's messages (status, alarms, motion_end), tagged with its generation: the
    server drops what an earlier worker of the same camera id still had in flight.

    A message crosses in its wire form, a plain dict: pickled in about a fifth of the
    time its model takes, at half the size."""

    def __init__(self, link: Link, generation: int) -> None:
        self._link = link
        self._generation = generation

    def publish(self, message: WsMessage) -> None:
        self._link.send(("message", self._generation, message.wire()))


def run_cameras(
    conn: Connection,
    settings: Settings,
    live_conn: Connection | None = None,
    stderr: int | None = None,
) -> None:
    """The camera process: run the cameras the server sends until it says exit or is gone.
    ``live_conn``: the live pipe's writing end (/ws/live messages); ``stderr``: the
    server's, to log to (a forked process has its forkserver's, as it was at its start)."""
    if stderr is not None:
        os.dup2(stderr, 2)
        os.close(stderr)
    # Ctrl-C reaches the whole process group; the server decides when cameras stop. A
    # SIGTERM to the group (systemd) stops cleanly: open events end, exit status 0.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _exit_cleanly)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if settings.opencv_threads:
        cv2.setNumThreads(settings.opencv_threads)
    # A process starts with its first camera (CameraProcess.add): load the detection
    # kernels now, beside it; a camera activated meanwhile waits for them.
    DETECTION_WARMING.set()

    def warm() -> None:
        try:
            warm_up()
        except Exception:  # Cameras then compile in their first call, as without it.
            log.exception("warming up the detection kernels failed")
        finally:
            DETECTION_WARMING.clear()

    threading.Thread(target=warm, name="warm-up", daemon=True).start()
    link = Link(conn)
    db = Database(settings.database, migrate=False, node=settings.node)  # Migrated already.
    snapshots = SnapshotStore(settings.snapshots_dir)
    clips = ClipStore(settings.clips_dir)
    sender = FrameSender(link, LivePipeWriter(live_conn) if live_conn is not None else None)
    workers: dict[int, CameraWorker] = {}

    def remove(camera_id: int) -> None:
        worker = workers.pop(camera_id, None)
        if worker is not None:
            worker.request_stop()

    try:
        while True:
            try:
                command = conn.recv()
            except (EOFError, OSError):
                return  # The server is gone (killed): stop too.
            op, *args = command
            if op == "exit":
                return
            if op == "start":
                row, generation, recovering = args
                remove(row["id"])
                worker_link = _WorkerLink(link, generation)
                # The process before this one, or the node before this one, died with its
                # events open.
                if recovering:
                    _end_events(db, worker_link, row["id"], clips)
                sender.start(row["id"], generation)
                worker = CameraWorker(row, settings, db, snapshots, worker_link)
                worker.hub.on_publish = lambda item, cid=row["id"]: sender.offer(cid, item)
                workers[row["id"]] = worker
                worker.start()
            elif op == "remove":
                remove(args[0])
            elif (worker_or_none := workers.get(args[0])) is not None:
                if op == "active":
                    worker_or_none.set_active(args[1])
                elif op == "update":
                    worker_or_none.update(**args[1])
                elif op == "watch":
                    sender.watch(*args)
    finally:
        for worker in workers.values():
            worker.request_stop()
        deadline = time.monotonic() + settings.read_timeout_ms / 1000 + 1.0
        stopped = all(w.join(max(0.0, deadline - time.monotonic())) for w in workers.values())
        sender.stop()
        if stopped:
            db.close()


def _end_events(
    db: Database, link: _WorkerLink, camera_id: int, clips: ClipStore | None = None
) -> None:
    """The camera's process (or node) died: its open events end, and its clips being
    recorded are finished as far as they got (those on this node's disk)."""
    if clips is not None:
        finish_unfinished(db, clips, camera_id)
    for event in db.close_open_events(camera_id):
        duration_s = event["ended_at"] - event["started_at"]
        clip = clip_url(event["id"]) if event["clip_path"] else None
        link.publish(
            motion_end_message(
                camera_id,
                event["id"],
                event["ended_at"],
                duration_s,
                event["max_area"],
                clip,
                event["clip_s"] if clip else None,
                node=db.node,
            )
        )


def _exit_cleanly(signum: int, frame: Any) -> None:
    raise SystemExit(0)


# --- the server's side -----------------------------------------------------------------------


class RemoteCamera:
    """A camera whose worker runs in a camera process; its state as last reported."""

    def __init__(self, row: dict[str, Any], process: CameraProcess) -> None:
        self.camera_id: int = row["id"]
        self.row = dict(row)
        self.process = process
        self.generation = next(_generations)
        """Tells this camera's worker from an earlier one of the same id (its messages and
        frames may still be on their way after a ``PATCH source``)."""
        self.hub = FrameHub()
        self.hub.on_watch = self._send_watching
        self.storage_error: str | None = None
        self._seq = 0  # The server numbers frames: a restarted process starts again at 1.
        # Until the camera process reports: a new camera's.
        self._status: dict[str, Any] = status_fields(self.camera_id)

    @property
    def state(self) -> str:
        return str(self._status["state"])

    @property
    def reason(self) -> str:
        return str(self._status["reason"])

    def status(self) -> dict[str, Any]:
        return {
            **self._status,
            "active": bool(self.row.get("active")),
            "viewers": self.hub.viewers,
            "process": self.process.index,
        }

    def set_active(self, active: bool) -> None:
        self.row["active"] = active
        self.process.send(("active", self.camera_id, active))

    def update(self, **changes: Any) -> None:
        self.row.update(changes)
        self.process.send(("update", self.camera_id, changes))

    def start_command(self, recovering: bool = False) -> tuple[Any, ...]:
        return ("start", self.row, self.generation, recovering)

    def watch_command(self) -> tuple[Any, ...]:
        hub = self.hub
        return ("watch", self.camera_id, self.generation, dict(hub.watching), hub.live_width)

    def _send_watching(self, _: dict[Kind, int]) -> None:
        self.process.send(self.watch_command())

    def received(self, picture: bytes | None, histogram: bytes | None) -> None:
        self._seq += 1
        self.hub.publish(SentFrame(self._seq, picture, histogram))

    def reported(self, message: Wire) -> Wire:
        """A status message from the camera process (its wire form): kept, and completed
        for /ws with what the server knows (``active``, ``viewers``, ``process``)."""
        if "storage_error" in message:
            self.storage_error = message["storage_error"]
        self._status = {k: v for k, v in message.items() if k not in ("type", "storage_error")}
        return {**message, **self.status()}


class CameraProcess:
    """One camera process, from the server: starts it, sends commands, hears it, restarts it.

    ``loop``: the server's event loop, which reads the process's live pipe (/ws/live
    messages) and serves their clients; without one, a thread reads it."""

    def __init__(
        self,
        index: int,
        settings: Settings,
        bus: EventBus,
        loop: asyncio.AbstractEventLoop | None = None,
    ) -> None:
        self.index = index
        self.settings = settings
        self.bus = bus
        self.loop = loop
        self._live: LivePipeReader | None = None
        self.cameras: dict[int, RemoteCamera] = {}
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self._conn: Connection | None = None
        self._process: multiprocessing.process.BaseProcess | None = None

    def start(self) -> None:
        context = _camera_context()
        ours, theirs = context.Pipe()
        live_ours, live_theirs = context.Pipe(duplex=False)
        process = context.Process(
            target=run_cameras,
            args=(theirs, self.settings, live_theirs, _stderr()),
            name=f"vigil-cameras-{self.index}",
            daemon=True,
        )
        process.start()
        theirs.close()
        live_theirs.close()
        self._live = LivePipeReader(live_ours, self._live_frame, self.loop)
        receiver = threading.Thread(
            target=self._receive, args=(ours, process), name=process.name, daemon=True
        )
        receiver.start()  # Before the replay: a child can block on a full pipe otherwise.
        with self._lock:  # Replayed whole, before any later command.
            self._conn, self._process = ours, process
            if self._stopping.is_set():
                self._send_locked(("exit",))
            for camera in self.cameras.values():  # After a restart: the cameras as they were.
                self._send_locked(camera.start_command(recovering=True))
                self._send_locked(camera.watch_command())

    @property
    def started(self) -> bool:
        return self._process is not None

    def add(self, camera: RemoteCamera, recovering: bool = False) -> None:
        """Run ``camera`` here; ``recovering``: its open events (and clips) are ended first."""
        if not self.started:
            self.start()
        with self._lock:
            self.cameras[camera.camera_id] = camera
            self._send_locked(camera.start_command(recovering))

    def remove(self, camera_id: int) -> None:
        with self._lock:
            camera = self.cameras.pop(camera_id, None)
            if camera is not None:
                self._send_locked(("remove", camera_id))
        if camera is not None:
            camera.hub.close()

    def send(self, command: tuple[Any, ...]) -> None:
        with self._lock:
            self._send_locked(command)

    def _send_locked(self, command: tuple[Any, ...]) -> None:
        # A dead process's pipe refuses; its restart sends every camera again.
        with contextlib.suppress(OSError, ValueError):
            if self._conn is not None:
                self._conn.send(command)

    def request_stop(self) -> None:
        """Ask the process to stop its cameras and exit (``wait`` for it)."""
        with self._lock:
            self._stopping.set()
            self._send_locked(("exit",))
        for camera in list(self.cameras.values()):
            camera.hub.close()

    def wait(self, timeout: float) -> bool:
        """True when the process exited within ``timeout``; else it is killed.

        The receiver joins (reaps) the process when its pipe closes; this only watches
        the sentinel, which tells of the exit without reaping it. Joining here as well
        raced the receiver for the exit status, and the loser took a process already
        gone for one still running.
        """
        with self._lock:
            process = self._process
        if process is None:
            return True
        if multiprocessing.connection.wait([process.sentinel], timeout):
            return True
        log.warning("camera process %s did not stop in %.1f s: killed", self.index, timeout)
        process.kill()
        multiprocessing.connection.wait([process.sentinel], KILLED_WAIT_S)
        return False

    def _receive(self, conn: Connection, process: multiprocessing.process.BaseProcess) -> None:
        while True:
            try:
                item = conn.recv()
            except (EOFError, OSError):
                break
            if item[0] == "message":
                self._forward(item[1], item[2])
            elif item[0] == "frame":
                _, camera_id, generation, picture, histogram = item
                camera = self.cameras.get(camera_id)
                if camera is not None and camera.generation == generation:
                    camera.received(picture, histogram)
        conn.close()
        process.join(5.0)
        # Status 0: asked to exit, or stopped by SIGTERM with the server (systemd).
        if self._stopping.is_set() or process.exitcode == 0:
            return
        self._restart(_exit_reason(process.exitcode))

    def _live_frame(self, camera_id: int, generation: int, message: bytes) -> None:
        camera = self.cameras.get(camera_id)
        if camera is not None and camera.generation == generation:
            camera.hub.offer_live(message)

    def _forward(self, generation: int, message: Wire) -> None:
        camera = self.cameras.get(message.get("camera_id", -1))
        if camera is None or camera.generation != generation:
            # Removed or replaced meanwhile: its last words concern nobody, but for the
            # end of an event it raised, which clients showed and wait to see end.
            if message.get("type") == "motion_end":
                self.bus.publish(message)
            return
        if message.get("type") == "status":
            message = camera.reported(message)
        self.bus.publish(message)

    def _restart(self, reason: str) -> None:
        log.error("camera process %s %s; starting it again", self.index, reason)
        for camera in list(self.cameras.values()):
            down = {**camera.status(), "state": "error", "reason": f"camera process {reason}"}
            self.bus.publish(camera.reported(CameraStatus(**down).wire()))
        if not self._stopping.wait(RESTART_DELAY_S):
            self.start()


def _camera_context() -> multiprocessing.context.ForkServerContext:
    """Camera processes are forked from a forkserver that has imported what they run
    (``app.workers.camera_forkserver``): never forked from the threaded server itself."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["app.workers.camera_forkserver"])
    return context


def _exit_reason(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        return f"died ({signal_label(exitcode)})"
    return f"exited (status {exitcode})"


def default_processes() -> int:
    return max(1, os.cpu_count() or 1)
