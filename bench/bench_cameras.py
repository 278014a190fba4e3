"""How many live cameras one machine sustains with Vigil's camera workers; CPU beside Motion.

    python bench/bench_cameras.py [--quick] [--warmup S] [--window S] [--repeat R]
                                  [--max-cameras N] [--data DIR] [--synthetic] [--only a|a3]

Every camera is Vigil's own ``app.workers.camera.CameraWorker`` reading a
looping 640x480 25 fps MJPG AVI (``file://CLIP``): it takes the file's JPEGs
undecoded, paces itself at the file's frame rate, decodes nothing while it is
neither activated nor watched, decodes grey at reduced scale for detection
when activated, and saves its alarms (events, snapshots) in a database and
snapshot folder that the process's cameras share, as the server's do; each
trial starts with empty ones. Camera i plays copy i % 4 of the clip, each
copy starting a quarter of the loop further on. A viewer is what the MJPEG
route does for one client: it awaits each new frame of the camera's hub and
asks for its JPEG (drawn and encoded once, or the camera's own JPEG when
nothing is drawn on it).

(a) CPU per 640x480 frame of one camera paced at 25 fps in a worker process:
    idle (live, not activated) and activated, each unwatched and with one
    viewer, with OpenCV's own thread count and with cv2.setNumThreads(1);
    and the Motion daemon (/usr/bin/motion) on the same clip in the same run;
    and, as a floor, decoding and segmentation alone (the default method, paced).
(a2) CPU per frame at load: 8 activated cameras in one worker process (OpenCV
    1 thread), and Motion with the same 8 cameras in one daemon.
    ``--only a3``: that section alone (about 3 minutes); ``--only a``: (a) alone.
(b) The largest number N of activated cameras for which every camera runs
    detection on >= 24 frames per second over the measured window (and, with
    a viewer, every viewer gets >= 24 pictures a second), with the
    cameras as threads of one process and spread over two processes
    (multiprocessing, spawn), OpenCV at the server's thread count (its
    ``opencv_threads`` setting, 1 by default), unwatched and with one viewer
    per camera.

See bench/README.md for what each figure means.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import dataclasses
import itertools
import math
import multiprocessing as mp
import os
import re
import sqlite3
import subprocess
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import _served
import cv2
from _common import Cell, add_data_argument, fmt, median, print_environment, print_table
from bench_pipeline import load_footage, ping_pong, resized, write_mjpg

from app.core.config import Settings
from app.sources.frames import JpegFrame
from app.sources.live import FileSource
from app.storage import Database, SnapshotStore
from app.vision.motion import DEFAULT_METHOD
from app.vision.motion.frame_difference import FrameDifference
from app.vision.pipeline import Pipeline, PipelineConfig, warm_up
from app.workers.bus import EventBus
from app.workers.camera import CameraWorker
from app.workers.hub import FrameHub, viewer_jpeg

FPS = 25.0
SIZE = (640, 480)
SOURCE_FRAMES = 300
"""Source frames taken from the clip; played forwards then backwards (~24 s at 25 fps)."""
CLIP_PHASES = 4
"""Copies of the loop written, each starting 1/CLIP_PHASES of it after the one before:
camera i plays copy i % CLIP_PHASES, so cameras do not all see the same moment (and alarm
together). A single camera plays copy 0, as Motion does."""
SUSTAINED_FPS = 24.0
AT_LOAD_CAMERAS = 8
"""Cameras of section (a2): several sharing one process, as on a machine with real work
(a lone camera pays for waking from idle on every frame)."""
MOTION = Path("/usr/bin/motion")
GUESS_SHARE = 0.8
"""A search starts at the cameras this share of the CPUs left free would carry."""
START_LEAD_S = 0.3
"""Between 'every worker process is ready' and the common start time."""
STOP_TIMEOUT_S = 5.0
MOTION_EXTRA_WARMUP_S = 1.0
MOTION_PICTURES = {
    "off": ["picture_output off"],
    # A picture of each event's first motion frame.
    "first": ["picture_output first"],
    # What a Vigil alarm saves, on every frame with motion: the picture with a red box
    # round the motion, at quality 90, its motion picture beside it, and a database row
    # for each (SQLite, as Vigil's default).
    "every": [
        "picture_output on",
        "picture_output_motion on",
        "picture_quality 90",
        "locate_motion_mode on",
        "locate_motion_style redbox",
        "database_type sqlite3",
        "sql_log_picture on",
        "sql_query insert into pictures (camera, file, frame, kind, at) values "
        "(%t, '%f', %q, %n, '%Y-%m-%d %T')",
    ],
}
"""Motion's picture options: ``off`` as (a) runs it; ``first`` one picture per event;
``every`` what Vigil saves on an alarm, saved on every frame with motion."""
MOTION_TABLE = "create table if not exists pictures (camera, file, frame, kind, at)"


@dataclass(frozen=True)
class Mode:
    """What a camera does: detection on (activated) or off, one viewer or none, and the
    segmentation method it detects with."""

    activated: bool
    watched: bool
    method: str = DEFAULT_METHOD
    viewer: str = "mjpeg"
    """What watches: ``mjpeg`` (in a worker process: the MJPEG route's work, minus the
    socket; in the server: a ``stream.mjpg`` client) or ``live`` (a /ws/live client)."""
    served: bool = False
    """In a real ``vigil serve`` (``_served.py``) rather than a bare worker process."""
    clips: bool = False
    """Whether events are recorded as clips (``VIGIL_CLIPS``). Off but in one row: Motion,
    beside it, writes no movies, and the capacity targets predate clips."""

    @property
    def label(self) -> str:
        state = "activated" if self.activated else "idle"
        method = "" if self.method == DEFAULT_METHOD else f", {self.method}"
        where = "vigil serve: " if self.served else ""
        method += ", recording clips" if self.clips else ""
        if not self.watched:
            watched = "unwatched"
        elif self.viewer == "live":
            watched = "one /ws/live viewer (a page)"
        else:
            watched = "one MJPEG viewer" + ("" if self.served else " (in process)")
        return f"{where}{state}, {watched}{method}"


IDLE = Mode(activated=False, watched=False)
ACTIVE = Mode(activated=True, watched=False)
ACTIVE_WATCHED = Mode(activated=True, watched=True)
IDLE_WATCHED = Mode(activated=False, watched=True)
SERVED_ACTIVE = Mode(activated=True, watched=False, served=True)
SERVED_PAGE = Mode(activated=True, watched=True, viewer="live", served=True)
SERVED_MJPEG = Mode(activated=True, watched=True, served=True)
SERVED_IDLE = Mode(activated=False, watched=False, served=True)
SERVED_IDLE_PAGE = Mode(activated=False, watched=True, viewer="live", served=True)
SERVED_MODES = (SERVED_ACTIVE, SERVED_PAGE, SERVED_MJPEG, SERVED_IDLE, SERVED_IDLE_PAGE)
SERVED_ROUNDS = 3
"""Trials of each served mode, the modes' order turned each round. One trial's CPU per
frame moved with the moment more than a page adds: the same camera unwatched, 1.68 and
2.18 ms in two trials of one server, a page's trials between them."""
"""The rows of table (a) from a real server (one camera process), in the order they run."""
VIEWER_TARGET = 1.15
"""A page viewer's camera: at most this times the CPU per frame of the camera unwatched."""
SLOW_FPS = 5.0
"""Motion detects every frame up to 5 fps (above, 3 frames a second): table (a3)'s rate."""
SLOW_TARGET = 0.6
"""Vigil's CPU per frame at SLOW_FPS: at most this times Motion's."""
CHEAPEST_METHOD = FrameDifference.name
ACTIVE_CHEAPEST = Mode(activated=True, watched=False, method=CHEAPEST_METHOD)
"""Activated with the cheapest segmentation (one difference and threshold per pixel):
about what every stage but the model costs (a noisier mask makes later stages dearer)."""
ACTIVE_RECORDING = Mode(activated=True, watched=False, clips=True)
"""Activated, each event recorded as an H.264 clip (the server's default)."""
CPU_MODES = (IDLE, ACTIVE, ACTIVE_RECORDING, ACTIVE_CHEAPEST, ACTIVE_WATCHED, IDLE_WATCHED)
"""The rows of table (a), in the order they run."""


# --- real camera workers in a worker process ----------------------------------------------


@dataclass(frozen=True)
class Windows:
    """``count`` consecutive measuring windows of ``length`` seconds after ``warmup``."""

    warmup: float
    length: float
    count: int = 1

    def bounds(self, t0: float) -> list[float]:
        first = t0 + self.warmup
        return [first + k * self.length for k in range(self.count + 1)]


@dataclass(frozen=True)
class TrialSpec:
    """What one worker process runs in one trial."""

    clips: tuple[Path, ...]
    """One per camera: the file it plays."""
    offsets: tuple[float, ...]
    """One per camera: its worker starts this long after the common start."""
    mode: Mode
    windows: Windows
    folder: Path
    """Where the process makes this trial's data folder (database, snapshots)."""


@dataclass(frozen=True)
class WorkerResult:
    """One worker process's counts, per camera and window."""

    read: list[list[int]]
    """Frames the camera read (``CameraWorker.frames``)."""
    processed: list[list[int]]
    """Frames run through detection (``CameraWorker.processed``)."""
    served: list[list[int]]
    """JPEGs its viewer got (all zero when unwatched)."""
    cpu_s: list[float]
    """Per window, process CPU seconds (all threads: cameras, viewers, event loop)."""
    seconds: list[float]
    """Per window, its length as this process sampled it (a busy process wakes late)."""
    alarms: int
    """Alarms (each one saved frame snapshot) over all the windows."""
    problems: list[str]
    """A camera not live at a window bound (its state and reason), a viewer's traceback."""


class Viewers:
    """One viewer per hub, as ``app/api/routes/streams.py`` serves MJPEG, minus the socket.

    An asyncio event loop in its own thread (the server's loop); each viewer awaits
    ``hub.next`` and gets the frame's JPEG with ``viewer_jpeg``, like the route.
    A viewer ends when its hub closes (the camera stops).
    """

    def __init__(self, hubs: Sequence[FrameHub]) -> None:
        self.hubs = hubs
        self.served = [0] * len(hubs)
        self.errors: list[str] = []
        self._thread = threading.Thread(
            target=asyncio.run, args=(self._watch_all(),), name="viewers", daemon=True
        )
        self._thread.start()

    async def _watch_all(self) -> None:
        await asyncio.gather(*(self._watch(i, hub) for i, hub in enumerate(self.hubs)))

    async def _watch(self, index: int, hub: FrameHub) -> None:
        seq = 0
        try:
            with hub.watch("picture"):
                while not hub.closed:
                    item = await hub.next(seq, 1.0)
                    if item is None:
                        continue
                    seq = item.seq
                    await viewer_jpeg(item, "picture")
                    self.served[index] += 1
        except Exception:
            self.errors.append(traceback.format_exc())

    def join(self, timeout: float) -> None:
        self._thread.join(timeout)


@dataclass(frozen=True)
class Mark:
    """The counters of one process at one window bound."""

    cpu_s: float
    at: float
    """time.monotonic() when sampled."""
    wall: float
    read: list[int]
    processed: list[int]
    served: list[int]


class LiveCameras:
    """A trial's cameras in this process: real CameraWorkers on the clip, sharing one
    database, snapshot store and event bus in ``data_dir`` as the server's cameras do."""

    def __init__(self, spec: TrialSpec, data_dir: Path) -> None:
        self.spec = spec
        self.settings = Settings(data_dir=data_dir, demo_camera=False, clips=spec.mode.clips)
        self.db = Database(self.settings.db_path)
        snapshots = SnapshotStore(self.settings.snapshots_dir)
        bus = EventBus()
        self.workers: list[CameraWorker] = []
        self.started: list[CameraWorker] = []
        for index, clip in enumerate(spec.clips):
            camera_id = self.db.add_camera(
                f"bench {index}",
                f"file://{clip}",
                spec.mode.method,
                self.settings.default_min_area,
            )
            row = self.db.camera(camera_id)
            assert row is not None
            row["active"] = spec.mode.activated
            self.workers.append(CameraWorker(row, self.settings, self.db, snapshots, bus))

    def run(self, t0: float) -> WorkerResult:
        """Start each camera at ``t0`` + its offset, count at every window bound, stop them."""
        viewers = Viewers([w.hub for w in self.workers]) if self.spec.mode.watched else None
        for offset, worker in zip(self.spec.offsets, self.workers, strict=True):  # Ascending.
            sleep_until(t0 + offset)
            worker.start()
            self.started.append(worker)
        marks: list[Mark] = []
        problems: list[str] = []
        for bound in self.spec.windows.bounds(t0):
            sleep_until(bound)
            marks.append(self._mark(viewers))
            problems += [
                f"camera {i} {w.state}: {w.reason}"
                for i, w in enumerate(self.workers)
                if w.state != "live"
            ]
        self._stop()
        if viewers is not None:
            viewers.join(STOP_TIMEOUT_S)
            problems += viewers.errors
        frames = self.db.snapshots(
            since=marks[0].wall, until=marks[-1].wall, kind="frame", limit=1_000_000
        )
        return WorkerResult(
            read=per_window([m.read for m in marks]),
            processed=per_window([m.processed for m in marks]),
            served=per_window([m.served for m in marks]),
            cpu_s=[b.cpu_s - a.cpu_s for a, b in itertools.pairwise(marks)],
            seconds=[b.at - a.at for a, b in itertools.pairwise(marks)],
            alarms=len(frames),
            problems=problems,
        )

    def _mark(self, viewers: Viewers | None) -> Mark:
        return Mark(
            cpu_s=time.process_time(),
            at=time.monotonic(),
            wall=time.time(),
            read=[w.frames for w in self.workers],
            processed=[w.processed for w in self.workers],
            served=list(viewers.served) if viewers else [0] * len(self.workers),
        )

    def _stop(self) -> None:
        for worker in self.workers:
            worker.request_stop()
        for worker in self.started:
            worker.join(STOP_TIMEOUT_S)

    def close(self) -> None:
        self._stop()
        self.db.close()


def per_window(counters: Sequence[list[int]]) -> list[list[int]]:
    """Per camera, the increase over each window of a counter sampled at every bound."""
    return [
        [after[c] - before[c] for before, after in itertools.pairwise(counters)]
        for c in range(len(counters[0]))
    ]


def sleep_until(moment: float) -> None:
    delay = moment - time.monotonic()
    if delay > 0:
        time.sleep(delay)


def worker_main(conn: Connection, cv_threads: int | None) -> None:
    """A worker process: set OpenCV's threads, then run trials until told to stop (None)."""
    if cv_threads is not None:
        cv2.setNumThreads(cv_threads)
    # As the server's camera process does: compiling the kernels (a machine's first run, or
    # after an edit) must not fall in a trial's windows.
    warm_up()
    conn.send(cv2.getNumThreads())
    while (spec := conn.recv()) is not None:
        with tempfile.TemporaryDirectory(prefix="data-", dir=spec.folder) as data_dir:
            cameras = LiveCameras(spec, Path(data_dir))
            try:
                conn.send("ready")
                conn.send(cameras.run(conn.recv()))
            finally:
                cameras.close()


class WorkerGroup:
    """Worker processes (spawned once, reused for every trial of one process model)."""

    def __init__(self, processes: int, cv_threads: int | None) -> None:
        context = mp.get_context("spawn")
        self.conns: list[Connection] = []
        self.procs: list[mp.process.BaseProcess] = []
        for _ in range(processes):
            parent, child = context.Pipe()
            proc = context.Process(target=worker_main, args=(child, cv_threads), daemon=True)
            proc.start()
            child.close()
            self.conns.append(parent)
            self.procs.append(proc)
        self.cv_threads: list[int] = [self._recv(conn) for conn in self.conns]

    def _recv(self, conn: Connection) -> Any:
        try:
            return conn.recv()
        except EOFError:
            raise SystemExit("a worker process died; see its error above") from None

    def start(self, specs: Sequence[TrialSpec]) -> float:
        """Every worker sets up its cameras, then all start at the returned moment."""
        for conn, spec in zip(self.conns, specs, strict=True):
            conn.send(spec)
        for conn in self.conns:
            self._recv(conn)
        t0 = time.monotonic() + START_LEAD_S
        for conn in self.conns:
            conn.send(t0)
        return t0

    def results(self) -> list[WorkerResult]:
        return [self._recv(conn) for conn in self.conns]

    def close(self) -> None:
        for conn in self.conns:
            with contextlib.suppress(OSError):
                conn.send(None)
        for proc in self.procs:
            proc.join(STOP_TIMEOUT_S)
            if proc.is_alive():
                proc.terminate()


@contextlib.contextmanager
def worker_group(processes: int, cv_threads: int | None) -> Iterator[WorkerGroup]:
    group = WorkerGroup(processes, cv_threads)
    try:
        yield group
    finally:
        group.close()


def machine_jiffies() -> tuple[int, int]:
    """(busy, total) clock ticks of all CPUs since boot, from /proc/stat."""
    ticks = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:9]]
    idle = ticks[3] + ticks[4]  # idle + iowait
    return sum(ticks) - idle, sum(ticks)


def busy_cores(before: tuple[int, int], after: tuple[int, int]) -> float:
    total = after[1] - before[1]
    return (os.cpu_count() or 1) * (after[0] - before[0]) / total if total else float("nan")


@dataclass(frozen=True)
class Trial:
    """N cameras over a group's processes, measured over the windows."""

    mode: Mode
    read_fps: list[list[float]]
    """Per window, every camera's frames read per second."""
    processed_fps: list[list[float]]
    """Per window, every camera's frames through detection per second."""
    viewer_fps: list[list[float]]
    """Per window, every camera's viewer's JPEGs per second."""
    cpu_s: list[float]
    """Per window, CPU seconds of all the worker processes together."""
    frames: list[int]
    """Per window, frames read by all cameras."""
    machine: list[float]
    """Per window, CPUs busy on the whole machine (this benchmark and any other work)."""
    alarms: int
    """Alarms saved by all cameras over the windows."""
    cores: list[float]
    """Per window, CPUs the worker processes used (their CPU seconds per second)."""

    @property
    def sustained(self) -> bool:
        """Every camera ran detection on >= SUSTAINED_FPS frames a second in every window,
        and where watched, its viewer got as many pictures: a viewer takes the latest
        frame, so one that falls behind skips frames and would spare the CPU their JPEGs."""
        rates = self.processed_fps + (self.viewer_fps if self.mode.watched else [])
        return all(min(fps, default=0.0) >= SUSTAINED_FPS for fps in rates)

    def ms_per_frame(self) -> list[float]:
        """Per window, worker processes' CPU milliseconds per frame read."""
        return [
            1000 * c / f if f else float("nan")
            for c, f in zip(self.cpu_s, self.frames, strict=True)
        ]


def run_trial(
    group: WorkerGroup,
    clips: Sequence[Path],
    folder: Path,
    cameras: int,
    mode: Mode,
    windows: Windows,
) -> Trial:
    """N cameras, camera i playing clips[i % len(clips)] and started i/N of a frame period
    after the first (real cameras are not in phase), dealt alternately to the processes."""
    period = 1.0 / FPS
    offsets = [i * period / cameras for i in range(cameras)]
    played = [clips[i % len(clips)] for i in range(cameras)]
    share = len(group.conns)
    specs = [
        TrialSpec(tuple(played[p::share]), tuple(offsets[p::share]), mode, windows, folder)
        for p in range(share)
    ]
    t0 = group.start(specs)
    marks = []
    for bound in windows.bounds(t0):
        sleep_until(bound)
        marks.append(machine_jiffies())
    results = group.results()
    for result in results:
        if result.problems:
            raise SystemExit("a camera or viewer failed:\n" + "\n".join(result.problems[:5]))

    def fps(counts: Callable[[WorkerResult], list[list[int]]]) -> list[list[float]]:
        return [
            [camera[k] / r.seconds[k] for r in results for camera in counts(r)]
            for k in range(windows.count)
        ]

    return Trial(
        mode=mode,
        read_fps=fps(lambda r: r.read),
        processed_fps=fps(lambda r: r.processed),
        viewer_fps=fps(lambda r: r.served),
        cpu_s=[sum(r.cpu_s[k] for r in results) for k in range(windows.count)],
        frames=[sum(c[k] for r in results for c in r.read) for k in range(windows.count)],
        machine=[busy_cores(a, b) for a, b in itertools.pairwise(marks)],
        alarms=sum(r.alarms for r in results),
        cores=[sum(r.cpu_s[k] / r.seconds[k] for r in results) for k in range(windows.count)],
    )


# --- (a) CPU per frame beside Motion ------------------------------------------------------


def proc_cpu_seconds(pid: int) -> float:
    """CPU time of a process, all its threads: the nanoseconds on a CPU that
    /proc/PID/task/*/schedstat counts (a thread that ends takes its time with it:
    Motion's live as long as it runs), else utime + stime from /proc/PID/stat, in
    clock ticks (10 ms: about a tenth of what Motion uses in a 3 s window, so its
    figure would move in steps of 0.13 ms a frame)."""
    tasks = Path(f"/proc/{pid}/task")
    if (tasks / str(pid) / "schedstat").exists():
        nanoseconds = 0
        for task in tasks.iterdir():
            with contextlib.suppress(OSError, ValueError, IndexError):  # It just ended.
                nanoseconds += int((task / "schedstat").read_text().split()[0])
        return nanoseconds / 1e9
    stat = Path(f"/proc/{pid}/stat").read_text()
    fields = stat.rsplit(")", 1)[1].split()  # Fields from the 3rd (state) on.
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def proc_read_bytes(pid: int) -> int:
    """Bytes a process has read (``rchar`` of /proc/PID/io: every read call, files too)."""
    for line in Path(f"/proc/{pid}/io").read_text().splitlines():
        if line.startswith("rchar:"):
            return int(line.split()[1])
    raise RuntimeError(f"no rchar in /proc/{pid}/io")


def bytes_per_frame(clips: Sequence[Path]) -> float:
    """The clips' mean file bytes per frame (an MJPG AVI is almost all JPEGs)."""
    frames = 0
    for clip in clips:
        capture = cv2.VideoCapture(str(clip), cv2.CAP_FFMPEG)
        frames += int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        capture.release()
    return sum(clip.stat().st_size for clip in clips) / max(frames, 1)


def motion_version() -> str:
    run = subprocess.run([str(MOTION), "-h"], capture_output=True, text=True, timeout=10)
    found = re.search(r"Version\s+([\d.]+)", run.stdout + run.stderr)
    return found.group(1) if found else "?"


def motion_config(
    clips: Sequence[Path], folder: Path, fps: float = FPS, pictures: str = "off"
) -> Path:
    """The config of NOTES.md: each clip a network camera, detection on, no outputs. One
    camera is configured in the main file, as NOTES.md has it; more, one file each."""
    cameras = [
        [
            f"netcam_url file://{clip}",
            f"netcam_params capture_rate={fps:g}",
            f"width {SIZE[0]}",
            f"height {SIZE[1]}",
            f"framerate {fps:g}",
            "threshold 1500",
            "despeckle_filter EedDl",
            *MOTION_PICTURES[pictures],
            f"database_dbname {folder / 'motion.db'}",
            "movie_output off",
            f"target_dir {folder / 'out'}",
        ]
        for clip in clips
    ]
    lines = [
        "daemon off",
        f"log_file {folder / 'motion.log'}",
        "log_level 6",
        "webcontrol_port 0",
        "stream_port 0",
    ]
    if len(cameras) == 1:
        lines += cameras[0]
    else:
        for number, camera in enumerate(cameras, start=1):
            path = folder / f"motion-camera-{number}.conf"
            path.write_text("\n".join([*camera, f"camera_id {number}", "stream_port 0"]) + "\n")
            lines.append(f"camera {path}")
    (folder / "out").mkdir(exist_ok=True)
    with contextlib.closing(sqlite3.connect(folder / "motion.db")) as db:
        db.execute(MOTION_TABLE)
    path = folder / "motion.conf"
    path.write_text("\n".join(lines) + "\n")
    return path


@dataclass(frozen=True)
class MotionRun:
    ms_per_frame: list[float]
    """Per window: CPU ms / (window seconds x FPS x cameras)."""
    read_fps: float
    """Per camera over all the windows (its reads come in blocks of several frames): the
    clip bytes it read / bytes per frame / seconds. A check that Motion took every frame,
    which its ms per frame assumes."""
    log_problems: list[str]
    fps: float = FPS
    """The rate it was run at."""
    pictures: int = 0
    """Pictures it saved over the windows (a motion picture counts as one)."""

    @property
    def problems(self) -> list[str]:
        """The first of its log's errors and warnings (the cause, if any, comes first), and
        a reading rate below the sustained one."""
        late = f"Motion read {self.read_fps:.1f} fps per camera: its ms per frame is too low"
        slow = self.read_fps < self.fps * SUSTAINED_FPS / FPS
        return self.log_problems[:4] + ([late] if slow else [])


def measure_motion(
    clips: Sequence[Path], folder: Path, windows: Windows, fps: float = FPS, pictures: str = "off"
) -> MotionRun:
    """Motion's CPU over each of Vigil's ``windows`` with a camera per clip, frames taken
    as window x FPS per camera (it paces itself), after a warm-up a second longer (its
    cameras connect once it has started)."""
    windows = Windows(windows.warmup + MOTION_EXTRA_WARMUP_S, windows.length, windows.count)
    config = motion_config(clips, folder, fps, pictures)
    proc = subprocess.Popen(
        [str(MOTION), "-n", "-c", str(config)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    marks = []
    read = []
    saved = []
    try:
        for bound in windows.bounds(time.monotonic()):
            sleep_until(bound)
            if proc.poll() is not None:
                raise SystemExit(f"motion exited early ({proc.returncode}); see {config}")
            marks.append(proc_cpu_seconds(proc.pid))
            read.append(proc_read_bytes(proc.pid))
            saved.append(sum(1 for _ in (folder / "out").rglob("*.jpg")))
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    frames = windows.length * fps * len(clips)
    per_frame = [1000 * (b - a) / frames for a, b in itertools.pairwise(marks)]
    seconds = windows.length * windows.count * len(clips)
    read_fps = (read[-1] - read[0]) / bytes_per_frame(clips) / seconds
    log = folder / "motion.log"
    text = log.read_text(errors="replace") if log.exists() else ""
    problems = [line for line in text.splitlines() if re.search(r"\[(ERR|WRN|ALR|CRT|EMG)\]", line)]
    return MotionRun(per_frame, read_fps, problems, fps, saved[-1] - saved[0])


@dataclass(frozen=True)
class PacedRow:
    """One camera paced at FPS in a worker process, in one mode, over R windows."""

    cv_threads: int | None
    """None = OpenCV's own choice."""
    reported_threads: int
    trial: Trial

    @property
    def label(self) -> str:
        return f"Vigil {self.trial.mode.label}"

    @property
    def threads(self) -> str:
        return f"{self.reported_threads} ({'default' if self.cv_threads is None else 'set'})"

    @property
    def ms(self) -> float:
        """Median over the windows of CPU ms per frame read."""
        return median(self.trial.ms_per_frame())


@dataclass(frozen=True)
class ServedRow:
    """One camera in a real ``vigil serve`` (one camera process), in one mode."""

    trial: Trial
    camera_ms: list[float]
    """Per window, the camera process's CPU ms per frame read (the rest is the server's)."""

    @property
    def label(self) -> str:
        return f"Vigil {self.trial.mode.label}"

    threads = "1 (server)"

    @property
    def ms(self) -> float:
        return median(self.trial.ms_per_frame())

    @property
    def camera(self) -> float:
        return median(self.camera_ms)


def served_trial(
    server: _served.Server, clips: Sequence[Path], mode: Mode, windows: Windows
) -> tuple[Trial, list[float]]:
    """Cameras of ``clips`` in ``server`` (camera i on clips[i]), measured over ``windows``
    once all are live; the trial, and per window the camera processes' ms per frame."""
    bounds = windows.bounds(0.0)
    result = _served.run_served(
        server,
        clips,
        mode.activated,
        mode.viewer if mode.watched else None,
        bounds,
        machine_jiffies,
    )
    frames = [
        sum(fps) * seconds for fps, seconds in zip(result.read_fps, result.seconds, strict=True)
    ]
    trial = Trial(
        mode=mode,
        read_fps=result.read_fps,
        processed_fps=result.processed_fps,
        viewer_fps=result.viewer_fps,
        cpu_s=result.cpu_s,
        frames=[round(f) for f in frames],
        machine=[busy_cores(a, b) for a, b in itertools.pairwise(result.marks)],
        alarms=result.alarms,
        cores=[c / t for c, t in zip(result.cpu_s, result.seconds, strict=True)],
    )
    camera_ms = [
        1000 * c / f if f else float("nan")
        for c, f in zip(result.camera_cpu_s, frames, strict=True)
    ]
    return trial, camera_ms


def measure_served_paced(clip: Path, folder: Path, windows: Windows) -> list[ServedRow]:
    """Every mode of SERVED_MODES: one camera in ``vigil serve`` with one camera process,
    in SERVED_ROUNDS rounds, each in another order; a mode's row is over all its windows."""
    runs: dict[Mode, list[tuple[Trial, list[float]]]] = {mode: [] for mode in SERVED_MODES}
    with _served.served(1, folder) as server:
        for turn in range(SERVED_ROUNDS):
            for mode in SERVED_MODES[turn:] + SERVED_MODES[:turn]:
                runs[mode].append(served_trial(server, [clip], mode, windows))
    return [
        ServedRow(merged([trial for trial, _ in found]), [ms for _, c in found for ms in c])
        for found in runs.values()
    ]


def merged(trials: Sequence[Trial]) -> Trial:
    """The trials of one mode as one: their windows together, their alarms summed."""
    joined: dict[str, Any] = {"mode": trials[0].mode, "alarms": sum(t.alarms for t in trials)}
    for field in dataclasses.fields(Trial):
        if field.name not in joined:
            joined[field.name] = [w for t in trials for w in getattr(t, field.name)]
    return Trial(**joined)


def median_fps(series: list[list[float]]) -> float:
    """The median over every window and camera of a Trial's per-window fps lists."""
    return median([f for window in series for f in window])


def measure_paced(clip: Path, folder: Path, windows: Windows) -> list[PacedRow]:
    """Every mode of CPU_MODES with OpenCV's own threads, then with one thread."""
    rows = []
    for cv_threads in (None, 1):
        with worker_group(1, cv_threads) as group:
            for mode in CPU_MODES:
                trial = run_trial(group, [clip], folder, 1, mode, windows)
                rows.append(PacedRow(cv_threads, group.cv_threads[0], trial))
    return rows


@dataclass(frozen=True)
class Floor:
    """``segmentation_floor``'s figures: thread CPU ms per frame, the median over the windows."""

    decode_ms: float
    """The JPEG decoded to grey at detection size."""
    segment_ms: float
    """That grey prepared (denoised) and segmented."""

    @property
    def ms(self) -> float:
        return self.decode_ms + self.segment_ms


def segmentation_floor(
    clip: Path, windows: Windows, fps: float = FPS
) -> tuple[list[float], list[float]]:
    """Per window, the thread CPU milliseconds per frame of what no activated camera
    with the default method can skip: its JPEG decoded to grey at detection size (as the
    camera decodes it), and that grey prepared (denoised) and segmented, one frame every
    frame period; the two apart. Run in a spawned process with one OpenCV thread.
    Reading, the stages after segmentation, alarms and waking up are left out, so a
    camera costs more."""
    cv2.setNumThreads(1)
    warm_up()
    source = FileSource(clip)
    jpegs = []
    for _ in range(SOURCE_FRAMES):
        frame = source.read()
        if not isinstance(frame, JpegFrame):
            raise SystemExit(f"{clip} does not hand over JPEGs")
        jpegs.append(frame.jpeg)
    source.close()
    pipeline = Pipeline(PipelineConfig(grey_stats=False), fps)
    bounds = windows.bounds(time.monotonic())
    decoding = [0.0] * windows.count
    segmenting = [0.0] * windows.count
    frames = [0] * windows.count
    due = time.monotonic()
    for jpeg in itertools.cycle(jpegs):
        due += 1.0 / fps
        sleep_until(due)
        if due >= bounds[-1]:
            break
        start = time.thread_time()
        gray = JpegFrame(jpeg).gray(pipeline.config.detect_width)
        decoded = time.thread_time()
        pipeline.method.apply(pipeline.prepare(gray))
        window = sum(due >= bound for bound in bounds) - 1
        if window >= 0:
            decoding[window] += decoded - start
            segmenting[window] += time.thread_time() - decoded
            frames[window] += 1

    def per_frame(cpu: list[float]) -> list[float]:
        return [1000 * c / n if n else float("nan") for c, n in zip(cpu, frames, strict=True)]

    return per_frame(decoding), per_frame(segmenting)


def measure_floor(clip: Path, windows: Windows, fps: float = FPS) -> Floor:
    """``segmentation_floor`` in a spawned process."""
    with mp.get_context("spawn").Pool(1) as pool:
        decoding, segmenting = pool.apply(segmentation_floor, (clip, windows, fps))
    return Floor(median(decoding), median(segmenting))


@dataclass(frozen=True)
class CpuFigures:
    """What section (a) hands to (b)'s search, from one camera with one OpenCV thread."""

    unwatched_guess: int
    """``capacity`` of the activated, unwatched camera."""
    viewer_factor: float
    """Activated unwatched ms / activated watched ms: the share of cameras a viewer leaves."""
    page_factor: float
    """The same in ``vigil serve`` with a /ws/live viewer (a page)."""


def measure_one_camera(
    args: argparse.Namespace, clips: Sequence[Path], tmp: Path
) -> tuple[list[PacedRow], list[ServedRow]]:
    """Section (a), printed."""
    windows = Windows(args.warmup, args.cpu_window, args.repeat)
    paced = measure_paced(clips[0], tmp, windows)
    # Frames in the server are counted from its status messages, one each STATUS_INTERVAL_S:
    # windows of at least 3 s.
    per_round = max(1, math.ceil(args.repeat / SERVED_ROUNDS))
    served_windows = Windows(args.warmup, max(args.cpu_window, 3.0), per_round)
    served = measure_served_paced(clips[0], tmp, served_windows)
    floor = measure_floor(clips[0], windows)
    motion: MotionRun | None = None
    if MOTION.is_file():
        motion = measure_motion(clips[:1], tmp, windows)
    print_paced(args, paced, served, motion, floor)
    return paced, served


def measure_cpu(
    args: argparse.Namespace, clips: Sequence[Path], slow_clip: Path, tmp: Path
) -> CpuFigures:
    """Sections (a), (a2) and (a3); returns the figures that seed section (b)'s search."""
    paced, served = measure_one_camera(args, clips, tmp)
    windows = Windows(args.warmup, args.cpu_window, args.repeat)
    measure_at_load(args, clips, tmp, windows)
    measure_slow(args, slow_clip, tmp)
    one = {row.trial.mode: row for row in paced if row.cv_threads == 1}
    by_mode = {row.trial.mode: row for row in served}
    return CpuFigures(
        capacity(one[ACTIVE].trial, args.max_cameras),
        one[ACTIVE].ms / one[ACTIVE_WATCHED].ms,
        by_mode[SERVED_ACTIVE].ms / by_mode[SERVED_PAGE].ms,
    )


def measure_slow(args: argparse.Namespace, clip: Path, tmp: Path) -> None:
    """Section (a3): one activated camera paced at SLOW_FPS (OpenCV 1 thread), the default
    method and the cheapest, beside Motion on the same clip at the same rate: below 5 fps
    Motion detects every frame, as Vigil does, so their CPU per frame compare like for
    like (above, Motion detects 3 frames a second)."""
    windows = Windows(args.warmup + 1.0, args.slow_window, args.repeat)
    with worker_group(1, 1) as group:
        trials = [
            run_trial(group, [clip], tmp, 1, mode, windows) for mode in (ACTIVE, ACTIVE_CHEAPEST)
        ]
    frames = [sum(trial.frames) for trial in trials]
    alarm_share = [trial.alarms / n for trial, n in zip(trials, frames, strict=True)]
    rows: list[list[Cell]] = [
        [
            f"Vigil {trial.mode.label}",
            fmt(median_fps(trial.read_fps), 2),
            fmt(median_fps(trial.processed_fps), 2),
            fmt(2 * share, 3),  # Each alarm saves two pictures.
            fmt(median(trial.ms_per_frame()), 2),
        ]
        for trial, share in zip(trials, alarm_share, strict=True)
    ]
    runs: dict[str, MotionRun] = {}
    if MOTION.is_file():
        runs = {
            pictures: measure_motion([clip], tmp, windows, SLOW_FPS, pictures)
            for pictures in MOTION_PICTURES
        }
    floor = measure_floor(clip, windows, SLOW_FPS)
    rows.append(
        [
            f"Vigil decoding and segmentation alone ({DEFAULT_METHOD}, thread CPU)",
            "-",
            "-",
            "-",
            fmt(floor.ms, 2),
        ]
    )
    motion_frames = windows.length * windows.count * SLOW_FPS
    what = {
        "off": "pictures off",
        "first": "a picture per event",
        "every": "an alarm's pictures and rows on every motion frame",
    }
    for pictures, run in runs.items():
        rows.append(
            [
                f"Motion {motion_version()} ({what[pictures]})",
                fmt(run.read_fps, 2),
                f"{SLOW_FPS:g}",
                fmt(run.pictures / motion_frames, 3),
                fmt(median(run.ms_per_frame), 2),
            ]
        )
    print_table(
        f"(a3) CPU per {SIZE[0]}x{SIZE[1]} frame at {SLOW_FPS:g} fps, both detecting every "
        f"frame (one camera, OpenCV 1 thread; median of {args.repeat} windows of "
        f"{args.slow_window:g} s)",
        ["program", "read fps", "detect fps", "pictures/frame", "ms CPU/frame"],
        rows,
        note=f"    the clip: every 5th frame of (a)'s, written at {SLOW_FPS:g} fps",
    )
    if not runs:
        print(f"Motion: skipped, {MOTION} is absent")
        return
    motion_ms = {pictures: median(run.ms_per_frame) for pictures, run in runs.items()}
    vigil_ms = [median(trial.ms_per_frame()) for trial in trials]
    for index, label in enumerate(("Vigil activated", "  with frame-difference")):
        ratio = vigil_ms[index] / motion_ms["off"]
        verdict = "met" if ratio <= SLOW_TARGET else "NOT met"
        target = f" (target <= {SLOW_TARGET:g}: {verdict})" if index == 0 else ""
        print(f"{label} / Motion at {SLOW_FPS:g} fps, CPU per frame: {fmt(ratio, 2)}{target}")
    print(
        f"  decoding and segmentation alone: {fmt(floor.ms / motion_ms['off'], 2)} x Motion "
        f"(decoding {fmt(floor.decode_ms, 2)} ms, denoising and segmentation "
        f"{fmt(floor.segment_ms, 2)}); alarms on {fmt(100 * alarm_share[0], 1)}% of the frames "
        "(each two JPEG snapshots and rows, which Motion, pictures off, does not make)"
    )
    print(
        "  Vigil activated / Motion saving a picture per event: "
        f"{fmt(vigil_ms[0] / motion_ms['first'], 2)}"
    )
    # Motion's cost per picture saved (its "every" run over its "off" run), at the share of
    # frames on which Vigil saved pictures: Motion saving what Vigil saves, as often.
    every = runs["every"].pictures / motion_frames
    if every > 0:
        per_picture = (motion_ms["every"] - motion_ms["off"]) / every
        as_vigil = motion_ms["off"] + per_picture * 2 * alarm_share[0]
        print(
            f"  Vigil activated / Motion saving as many pictures as Vigil: "
            f"{fmt(vigil_ms[0] / as_vigil, 2)} (Motion {fmt(as_vigil, 2)} ms: its picture "
            f"costs {fmt(per_picture, 2)} ms with its row, from its runs pictures off and on "
            "every motion frame)"
        )
    print_motion_problems(runs["off"])


def measure_at_load(
    args: argparse.Namespace, clips: Sequence[Path], tmp: Path, windows: Windows
) -> None:
    """Section (a2): CPU per frame with AT_LOAD_CAMERAS activated cameras sharing one
    process (Vigil: one worker process, OpenCV 1 thread; Motion: one daemon with a camera
    per clip), camera i playing clips[i % len(clips)] in both."""
    with worker_group(1, 1) as group:
        trials = [
            run_trial(group, clips, tmp, AT_LOAD_CAMERAS, mode, windows)
            for mode in (ACTIVE, ACTIVE_CHEAPEST)
        ]
    vigil_ms = [median(trial.ms_per_frame()) for trial in trials]
    motion: MotionRun | None = None
    rows: list[list[Cell]] = [
        [
            f"Vigil, {trial.mode.label}, {AT_LOAD_CAMERAS} cameras in 1 process",
            fmt(median_fps(trial.processed_fps), 1),
            fmt(ms, 2),
        ]
        for trial, ms in zip(trials, vigil_ms, strict=True)
    ]
    if MOTION.is_file():
        played = [clips[i % len(clips)] for i in range(AT_LOAD_CAMERAS)]
        motion = measure_motion(played, tmp, windows)
        rows.append(
            [
                f"Motion {motion_version()}, {AT_LOAD_CAMERAS} cameras",
                f"{FPS:g} (read {fmt(motion.read_fps, 1)})",
                fmt(median(motion.ms_per_frame), 2),
            ]
        )
    print_table(
        f"(a2) CPU per frame at load: {AT_LOAD_CAMERAS} cameras in one process (median of "
        f"{args.repeat} windows of {args.cpu_window:g} s after a {args.warmup:g} s warm-up)",
        ["program", "detect fps", "ms CPU/frame"],
        rows,
        note="    ms CPU/frame: the process's CPU / frames (Motion's: window x FPS x cameras)",
    )
    if motion is None:
        return
    motion_ms = median(motion.ms_per_frame)
    print(f"Vigil / Motion at load, CPU per frame: {fmt(vigil_ms[0] / motion_ms, 2)}")
    print(f"  the same with {CHEAPEST_METHOD}: {fmt(vigil_ms[1] / motion_ms, 2)}")
    print_motion_problems(motion)


def print_viewers(paced: list[PacedRow], served: list[ServedRow]) -> None:
    """What a viewer costs: each watched row over the same camera unwatched."""
    by_mode = {row.trial.mode: row for row in served}
    bare, page = by_mode[SERVED_ACTIVE], by_mode[SERVED_PAGE]
    ratio = page.ms / bare.ms
    verdict = "met" if ratio <= VIEWER_TARGET else "NOT met"
    print(
        f"A page (/ws/live) on an activated camera, vigil serve: {fmt(page.ms, 2)} ms/frame "
        f"over {fmt(bare.ms, 2)} unwatched = {fmt(ratio, 2)} x (target <= "
        f"{VIEWER_TARGET:g}: {verdict})\n"
        f"    the camera process {fmt(bare.camera, 2)} -> {fmt(page.camera, 2)} ms, the server "
        f"{fmt(bare.ms - bare.camera, 2)} -> {fmt(page.ms - page.camera, 2)} ms"
    )
    mjpeg = by_mode[SERVED_MJPEG]
    one = {row.trial.mode: row for row in paced if row.cv_threads == 1}
    print(
        f"An MJPEG viewer (stream.mjpg) on it: {fmt(mjpeg.ms / bare.ms, 2)} x in vigil serve; "
        f"{fmt(one[ACTIVE_WATCHED].ms / one[ACTIVE].ms, 2)} x in process (the route's work "
        "without its pipe, server or socket, OpenCV 1 thread)"
    )


def print_motion_problems(motion: MotionRun) -> None:
    if motion.problems:
        print("Motion's problems:", *motion.problems, sep="\n    ")


def print_paced(
    args: argparse.Namespace,
    paced: list[PacedRow],
    served: list[ServedRow],
    motion: MotionRun | None,
    floor: Floor,
) -> None:
    motion_ms = median(motion.ms_per_frame) if motion is not None else float("nan")
    both: list[PacedRow | ServedRow] = [*paced, *served]
    rows: list[list[Cell]] = [
        [
            row.label,
            row.threads,
            fmt(median_fps(row.trial.read_fps), 1),
            fmt(median_fps(row.trial.processed_fps), 1),
            fmt(median_fps(row.trial.viewer_fps), 1) if row.trial.mode.watched else "-",
            fmt(row.ms, 2),
            fmt(row.ms / motion_ms, 2),
        ]
        for row in both
    ]
    if motion is not None:
        rows.append(
            [
                f"Motion {motion_version()} (detection on, above 5 fps on 3 frames a second)",
                "-",
                fmt(motion.read_fps, 1),
                "3",
                "-",
                fmt(motion_ms, 2),
                "1.00",
            ]
        )
    print_table(
        f"(a) CPU per {SIZE[0]}x{SIZE[1]} frame of one camera paced at {FPS:g} fps in its own "
        f"process, beside Motion on the same clip (median of {args.repeat} windows of "
        f"{args.cpu_window:g} s after a {args.warmup:g} s warm-up)",
        [
            "program",
            "OpenCV threads",
            "read fps",
            "detect fps",
            "viewer fps",
            "ms CPU/frame",
            "x Motion",
        ],
        rows,
        note=(
            "    ms CPU/frame: worker process CPU (all threads) / frames read; Motion's frames"
            f" = window x {FPS:g}\n    (its read fps: clip bytes it read / bytes per frame, a"
            " check)\n    vigil serve: the server's CPU and its camera process's (all threads)"
            f" / frames read, the median of {SERVED_ROUNDS} trials' windows, the modes in turn"
            "\n    x Motion: the row's ms/frame divided by Motion's"
            " (above 1 = costs more); Motion detects 3 of the 25 frames a second, see (a3)"
        ),
    )
    print_viewers(paced, served)
    recording = [
        f"{fmt(clip.ms, 2)} over {fmt(bare.ms, 2)} ms with OpenCV {bare.threads}"
        for bare in paced
        if bare.trial.mode == ACTIVE
        for clip in paced
        if clip.trial.mode == ACTIVE_RECORDING and clip.threads == bare.threads
    ]
    print(f"Recording each event as a clip (the rows above record none): {', '.join(recording)}")
    if motion is None:
        print(f"Motion: skipped, {MOTION} is absent (Debian: apt-get install motion)")
    else:
        for mode, label in (
            (ACTIVE, "Vigil activated unwatched"),
            (ACTIVE_CHEAPEST, "  the same"),
        ):
            ratios = ", ".join(
                f"{fmt(row.ms / motion_ms, 2)} with OpenCV {row.threads}"
                for row in paced
                if row.trial.mode == mode
            )
            print(f"{label} ({mode.method}) / Motion, CPU per frame: {ratios}")

    def share(ms: float) -> str:
        return f" = {fmt(ms / motion_ms, 2)} x Motion" if motion is not None else ""

    print(
        f"Decoding and segmentation alone ({DEFAULT_METHOD}, paced at {FPS:g} fps, OpenCV 1 "
        f"thread, thread CPU): {fmt(floor.ms, 2)} ms/frame{share(floor.ms)}\n"
        f"    decoding to grey at detection size {fmt(floor.decode_ms, 2)} ms"
        f"{share(floor.decode_ms)}; denoising and segmentation {fmt(floor.segment_ms, 2)} ms"
        f"{share(floor.segment_ms)}\n"
        "    what an activated camera cannot skip: reading, the stages after segmentation,"
        " alarms and waking up come on top"
    )
    if motion is not None:
        print_motion_problems(motion)


# --- (b) cameras per process model --------------------------------------------------------


def largest_sustained(
    passes: Callable[[int], bool], guess: int, ceiling: int | None, limit: int
) -> tuple[int, bool]:
    """The largest N that passes: from ``guess``, climb (or descend) in doubling steps, then
    bisect. ``ceiling`` is an N known to fail. Returns (N, whether a failing N was seen)."""
    lo, hi = 0, ceiling
    n = max(1, min(guess, limit, hi - 1 if hi else limit))
    if hi is not None and hi <= 1:
        return 0, True
    step = 1
    cap = limit if hi is None else min(limit, hi - 1)
    if passes(n):
        lo = n
        while lo < cap:
            n = min(lo + step, cap)
            if not passes(n):
                hi = n
                break
            lo, step = n, step * 2
    else:
        hi = n
        while lo == 0 and (n := hi - step) >= 1:
            if passes(n):
                lo = n
            else:
                hi, step = n, step * 2
    while hi is not None and hi - lo > 1:
        mid = (lo + hi) // 2
        if passes(mid):
            lo = mid
        else:
            hi = mid
    return lo, hi is not None


@dataclass(frozen=True)
class Found:
    """The largest sustained N of one search."""

    cameras: int
    bounded: bool
    """False when the search stopped at --max-cameras without a failure."""
    trial: Trial | None
    """The trial of that N (None for N = 0)."""

    def __str__(self) -> str:
        return str(self.cameras) if self.bounded else f">={self.cameras}"


def server_cv_threads() -> int | None:
    """OpenCV threads per process in (b): what ``vigil serve`` sets before its cameras start
    (``Settings.opencv_threads``, so ``VIGIL_OPENCV_THREADS`` counts; 0 = OpenCV's own
    choice, None here)."""
    return Settings().opencv_threads or None


def model_label(processes: int, cv_threads: int) -> str:
    who = "1 process (threads)" if processes == 1 else f"{processes} processes"
    return f"{who}, OpenCV {cv_threads} thread{'s' if cv_threads != 1 else ''}"


def search_model(
    args: argparse.Namespace,
    clips: Sequence[Path],
    folder: Path,
    processes: int,
    modes: Sequence[Mode],
    guesses: dict[Mode, int],
) -> tuple[str, dict[Mode, Found]]:
    """Largest sustained N of activated cameras, for each mode, over ``processes`` processes.

    ``guesses`` are where the searches start; a mode without one (the viewer, for the first
    model) starts from the unwatched result scaled by the viewer's cost in (a)."""
    windows = Windows(args.warmup, args.window)
    with worker_group(processes, server_cv_threads()) as group:
        label = model_label(processes, group.cv_threads[0])
        print(f"\n{label}:")
        found = search(
            lambda n, mode: run_trial(group, clips, folder, n, mode, windows),
            modes,
            guesses,
            args.max_cameras,
        )
    return label, found


def search(
    trial: Callable[[int, Mode], Trial], modes: Sequence[Mode], guesses: dict[Mode, int], limit: int
) -> dict[Mode, Found]:
    """For each mode in turn (unwatched first), the largest N of cameras ``trial`` sustains."""
    found: dict[Mode, Found] = {}
    for mode in modes:
        tried: dict[int, Trial] = {}

        def passes(n: int, mode: Mode = mode, tried: dict[int, Trial] = tried) -> bool:
            if n not in tried:
                tried[n] = trial(n, mode)
                print_trial(n, tried[n])
            return tried[n].sustained

        # A viewer only adds work: an N that fails without one fails with one.
        unwatched = next((f for m, f in found.items() if not m.watched), None)
        ceiling = None
        if mode.watched and unwatched is not None and unwatched.bounded:
            ceiling = unwatched.cameras + 1
        n, bounded = largest_sustained(passes, guesses[mode], ceiling, limit)
        found[mode] = Found(n, bounded, tried.get(n))
    return found


def search_served_model(
    args: argparse.Namespace,
    clips: Sequence[Path],
    folder: Path,
    processes: int,
    guesses: dict[Mode, int],
) -> tuple[str, dict[Mode, Found]]:
    """As ``search_model``, in a real ``vigil serve`` with ``processes`` camera processes:
    unwatched, then with a /ws/live viewer per camera (a page each)."""
    windows = Windows(args.warmup, args.window)
    label = f"vigil serve, {processes} camera process{'es' if processes > 1 else ''}"
    print(f"\n{label} (OpenCV {Settings().opencv_threads or 'default'} thread(s) each):")
    with _served.served(processes, folder) as server:
        found = search(
            lambda n, mode: served_trial(
                server, [clips[i % len(clips)] for i in range(n)], mode, windows
            )[0],
            (SERVED_ACTIVE, SERVED_PAGE),
            guesses,
            args.max_cameras,
        )
    return label, found


def print_trial(n: int, trial: Trial) -> None:
    detect = trial.processed_fps[0]
    watched = (
        ("one page  " if trial.mode.viewer == "live" else "one viewer")
        if trial.mode.watched
        else "unwatched "
    )
    viewer = f"viewer fps {median(trial.viewer_fps[0]):4.1f}  " if trial.mode.watched else ""
    cores = os.cpu_count() or 1
    verdict = "sustained" if trial.sustained else "NOT sustained"
    print(
        f"  N={n:<3d} {watched}  detect fps min {min(detect):4.1f} "
        f"median {median(detect):4.1f}  {viewer}"
        f"CPU {trial.cores[0]:4.2f} of machine's {trial.machine[0]:4.2f}/{cores}  "
        f"{fmt(trial.ms_per_frame()[0], 2)} ms/frame  {trial.alarms} alarms  "
        f"load {os.getloadavg()[0]:4.1f}  {verdict}"
    )


def capacity(trial: Trial, limit: int) -> int:
    """Cameras that GUESS_SHARE of the CPUs other work left free during ``trial`` would carry
    at the trial's CPU per frame (medians over its windows); from 1 to ``limit``."""
    others = median(
        [max(0.0, busy - ours) for busy, ours in zip(trial.machine, trial.cores, strict=True)]
    )
    free = max(0.0, (os.cpu_count() or 1) - others)
    ms = median(trial.ms_per_frame())
    if not ms > 0:
        return 1
    return max(1, min(limit, math.floor(GUESS_SHARE * free * 1000 / (FPS * ms))))


def measure_cameras(
    args: argparse.Namespace, clips: Sequence[Path], folder: Path, cpu: CpuFigures
) -> None:
    """Section (b): one process, then two, each searched unwatched then watched; then the
    same in a real ``vigil serve`` with one and two camera processes, a page each."""
    print(
        f"\n(b) Cameras sustained: every activated camera runs detection on >= "
        f"{SUSTAINED_FPS:g} fps (and its viewer, where it has one, gets >= {SUSTAINED_FPS:g} "
        f"pictures a second) over {args.window:g} s after a {args.warmup:g} s warm-up; "
        "CPU = cores used by the worker processes (in vigil serve: the server and its camera "
        "processes) of the cores busy on the whole machine"
    )
    modes = (ACTIVE,) if args.quick else (ACTIVE, ACTIVE_WATCHED)
    results: dict[int, dict[Mode, Found]] = {}
    labels: dict[int, str] = {}
    for processes in (1, 2):
        guesses = next_guesses(results, cpu, args.max_cameras)
        labels[processes], results[processes] = search_model(
            args, clips, folder, processes, modes, guesses
        )
    rows: list[list[Cell]] = [
        [labels[p], *(str(results[p][m]) for m in modes), "MJPEG (in process)"] for p in results
    ]
    if not args.quick:
        for processes in (1, 2):
            unwatched = results[processes][ACTIVE].cameras
            guesses = {
                SERVED_ACTIVE: max(1, unwatched),
                SERVED_PAGE: max(1, math.floor(unwatched * cpu.page_factor)),
            }
            label, found = search_served_model(args, clips, folder, processes, guesses)
            rows.append(
                [label, str(found[SERVED_ACTIVE]), str(found[SERVED_PAGE]), "/ws/live (a page)"]
            )
    print_table(
        f"(b) Largest N of activated {SIZE[0]}x{SIZE[1]} {FPS:g} fps cameras sustained",
        [*["process model", "unwatched", "one viewer each"][: 1 + len(modes)], "the viewer"],
        rows if len(modes) > 1 else [[r[0], r[1], r[-1]] for r in rows],
    )


def next_guesses(
    results: dict[int, dict[Mode, Found]], cpu: CpuFigures, limit: int
) -> dict[Mode, int]:
    """Where a model's searches start. The first model: the ``capacity`` of (a)'s activated
    camera with one OpenCV thread, and that times (a)'s viewer factor with a viewer. A later
    one: the more of the last model's result and the ``capacity`` of its trial there."""
    if not results:
        return {
            ACTIVE: cpu.unwatched_guess,
            ACTIVE_WATCHED: max(1, math.floor(cpu.unwatched_guess * cpu.viewer_factor)),
        }
    last = results[list(results)[-1]]
    return {
        mode: max(1, found.cameras, capacity(found.trial, limit) if found.trial else 1)
        for mode, found in last.items()
    }


# --- main ---------------------------------------------------------------------------------


def make_clips(args: argparse.Namespace, folder: Path) -> tuple[list[Path], Path, str]:
    """The looping camera clip (640x480, 25 fps MJPG AVI), first, then its copies starting
    1/CLIP_PHASES, 2/CLIP_PHASES... of the loop further on; (a3)'s clip at SLOW_FPS (every
    5th frame of the loop); and where the frames came from."""
    footage = load_footage(args.data, SOURCE_FRAMES, args.synthetic)
    frames = resized(ping_pong(footage.frames, 2 * len(footage.frames) - 2), SIZE)
    clips = []
    for phase in range(CLIP_PHASES):
        start = phase * len(frames) // CLIP_PHASES
        loop = frames[start:] + frames[:start]  # The loop has no cut, so neither has this.
        clips.append(write_mjpg(loop, folder / f"camera-{phase}.avi", FPS))
    step = round(FPS / SLOW_FPS)
    slow = write_mjpg(frames[::step], folder / "camera-slow.avi", SLOW_FPS)
    return (
        clips,
        slow,
        (
            f"{footage.description}; {len(footage.frames)} frames played forwards then backwards, "
            f"resized to {SIZE[0]}x{SIZE[1]}, written as an MJPG AVI at {FPS:g} fps "
            f"({len(frames) / FPS:.1f} s, looped), and {CLIP_PHASES - 1} copies starting "
            f"{len(frames) / FPS / CLIP_PHASES:.1f} s apart for the cameras of (b)"
        ),
    )


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter windows, ~3 minutes")
    parser.add_argument("--warmup", type=float, default=None, help="seconds before measuring")
    parser.add_argument("--window", type=float, default=None, help="seconds measured per trial")
    parser.add_argument("--repeat", type=int, default=None, help="windows of each CPU figure")
    parser.add_argument("--max-cameras", type=int, default=64, help="stop climbing here")
    parser.add_argument("--synthetic", action="store_true", help="synthetic scene, not footage")
    parser.add_argument("--only", choices=["a", "a3"], help="run this section alone")
    add_data_argument(parser)
    args = parser.parse_args(argv)
    quick = args.quick
    args.warmup = args.warmup if args.warmup is not None else (2.0 if quick else 2.5)
    args.window = args.window if args.window is not None else (2.0 if quick else 4.0)
    args.repeat = args.repeat if args.repeat is not None else (3 if quick else 5)
    args.cpu_window = 1.0 if quick else 3.0
    args.slow_window = 3.0 if quick else 6.0
    if args.warmup < 0 or args.window <= 0 or args.repeat < 1 or args.max_cameras < 1:
        parser.error("--warmup >= 0, --window > 0, --repeat >= 1, --max-cameras >= 1")
    return args


def main(argv: Sequence[str] | None = None) -> None:
    args = parse_args(argv)
    started = time.perf_counter()
    print_environment("Vigil cameras benchmark")
    with tempfile.TemporaryDirectory(prefix="vigil-cameras-") as tmp:
        clips, slow_clip, description = make_clips(args, Path(tmp))
        print(f"camera: {description}")
        if args.only == "a":
            measure_one_camera(args, clips, Path(tmp))
        elif args.only == "a3":
            measure_slow(args, slow_clip, Path(tmp))
        else:
            cpu = measure_cpu(args, clips, slow_clip, Path(tmp))
            measure_cameras(args, clips, Path(tmp), cpu)
    print(f"\ndone in {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
