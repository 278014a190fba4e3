"""How many live cameras one Vigil process sustains, and Vigil's CPU per frame beside Motion's.

    python bench/bench_cameras.py [--quick] [--warmup S] [--window S] [--repeat R]
                                  [--max-cameras N] [--data DIR] [--synthetic]

Every camera is a thread that decodes a looping 640x480 MJPG AVI with
cv2.VideoCapture and paces itself to 25 fps like a real camera (when it falls
behind it does not sleep, catching up at most a second, as Vigil's camera
worker does), then runs Vigil's default Pipeline on every frame, and with a
viewer also draws the detections and encodes a JPEG (quality 80) per frame.

(a) CPU per 640x480 frame: decode only, decode + pipeline (Vigil's worker
    loop), + viewer; one paced camera in a worker process; and the Motion
    daemon (/usr/bin/motion) on the same clip in the same run.
(b) The largest number N of such cameras for which every camera reaches
    >= 24 fps over the measured window, with the cameras as threads of one
    process and spread over two processes (multiprocessing, spawn), each with
    OpenCV's own thread count and with cv2.setNumThreads(1), without and with
    a viewer per camera.

See bench/README.md for what each figure means.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import math
import multiprocessing as mp
import os
import re
import subprocess
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, Literal

import cv2
from _common import (
    Cell,
    add_data_argument,
    fmt,
    make_pipeline,
    median,
    print_environment,
    print_table,
)
from bench_pipeline import load_footage, ping_pong, resized, write_mjpg

from app.vision.motion import DEFAULT_METHOD
from app.vision.types import Image
from app.workers.hub import LiveFrame

FPS = 25.0
SIZE = (640, 480)
SOURCE_FRAMES = 300
"""Source frames taken from the clip; played forwards then backwards (~24 s at 25 fps)."""
SUSTAINED_FPS = 24.0
CATCH_UP_S = 1.0
"""A camera that falls behind catches up at most this much (as app.workers.camera does)."""
VIEWER_QUALITY = 80
MOTION = Path("/usr/bin/motion")
GUESS_SHARE = 0.8
"""The first search starts at the cameras this share of the CPUs would carry."""
START_LEAD_S = 0.3
"""Between 'every worker is ready' and the common start time."""

Work = Literal["decode", "detect", "view"]
WORK_LABELS: dict[Work, str] = {
    "decode": "decode only",
    "detect": "decode + pipeline (worker loop, no viewer)",
    "view": "decode + pipeline + viewer (annotate, JPEG q80)",
}


# --- one camera -------------------------------------------------------------------------


class Camera:
    """A looping file read like a live camera, and the work done on each of its frames."""

    def __init__(self, clip: Path, work: Work) -> None:
        self.clip = clip
        self.work = work
        self.capture = self._open()
        self.pipeline = make_pipeline(DEFAULT_METHOD, FPS)

    def _open(self) -> cv2.VideoCapture:
        capture = cv2.VideoCapture(str(self.clip))
        if not capture.isOpened():
            raise RuntimeError(f"OpenCV cannot open {self.clip}")
        return capture

    def read(self) -> Image:
        ok, frame = self.capture.read()
        if not ok:  # End of the file: start it again, as a camera would keep streaming.
            self.capture.release()
            self.capture = self._open()
            ok, frame = self.capture.read()
            if not ok:
                raise RuntimeError(f"OpenCV cannot decode {self.clip}")
        return frame

    def step(self) -> None:
        """One frame: decode, and detect (and draw + encode for a viewer) as ``work`` says."""
        frame = self.read()
        if self.work == "decode":
            return
        result = self.pipeline.process(frame)
        if self.work == "view":
            live = LiveFrame(
                result.index,
                result.time_s,
                frame,
                result.detections,
                self.pipeline.tracker.trails(),
                quality=VIEWER_QUALITY,
            )
            live.jpeg()

    def close(self) -> None:
        self.capture.release()


# --- paced cameras in a worker process -----------------------------------------------------


@dataclass(frozen=True)
class Windows:
    """``count`` consecutive measuring windows of ``length`` seconds after ``warmup``."""

    warmup: float
    length: float
    count: int = 1

    def bounds(self, t0: float) -> list[float]:
        first = t0 + self.warmup
        return [first + k * self.length for k in range(self.count + 1)]

    def index(self, t0: float, now: float) -> int | None:
        k = math.floor((now - t0 - self.warmup) / self.length)
        return k if 0 <= k < self.count else None


@dataclass(frozen=True)
class TrialSpec:
    """What one worker process runs in one trial."""

    clip: Path
    work: Work
    offsets: tuple[float, ...]
    """One per camera: its first frame is due this long after the common start."""
    windows: Windows


@dataclass(frozen=True)
class WorkerResult:
    frames: list[list[int]]
    """Per camera, frames processed in each window."""
    cpu_s: list[float]
    """Process CPU seconds (all threads) in each window."""
    errors: list[str]
    """Tracebacks of camera threads that failed."""


def pace(
    camera: Camera,
    t0: float,
    offset: float,
    windows: Windows,
    counts: list[int],
    errors: list[str],
) -> None:
    """Camera thread: ``paced_loop``, its failure recorded for the parent to report."""
    try:
        paced_loop(camera, t0, offset, windows, counts)
    except Exception:
        errors.append(traceback.format_exc())


def paced_loop(
    camera: Camera, t0: float, offset: float, windows: Windows, counts: list[int]
) -> None:
    """Process frames at FPS from ``t0 + offset`` to the end of the last window."""
    period = 1.0 / FPS
    end = windows.bounds(t0)[-1]
    due = t0 + offset
    while (now := time.monotonic()) < end:
        if due > now:
            time.sleep(due - now)
        due = max(due + period, time.monotonic() - CATCH_UP_S)
        camera.step()
        k = windows.index(t0, time.monotonic())
        if k is not None:
            counts[k] += 1


def sleep_until(moment: float) -> None:
    delay = moment - time.monotonic()
    if delay > 0:
        time.sleep(delay)


def run_paced(
    cameras: Sequence[Camera], offsets: Sequence[float], t0: float, windows: Windows
) -> WorkerResult:
    """Every camera in its own thread; the process's CPU time sampled at each window bound."""
    counts = [[0] * windows.count for _ in cameras]
    errors: list[str] = []
    threads = [
        threading.Thread(target=pace, args=(cam, t0, off, windows, cnt, errors), daemon=True)
        for cam, off, cnt in zip(cameras, offsets, counts, strict=True)
    ]
    for thread in threads:
        thread.start()
    marks = []
    for bound in windows.bounds(t0):
        sleep_until(bound)
        marks.append(time.process_time())
    for thread in threads:
        thread.join()
    return WorkerResult(counts, [b - a for a, b in itertools.pairwise(marks)], errors)


def worker_main(conn: Connection, cv_threads: int | None) -> None:
    """A worker process: set OpenCV's threads, then run trials until told to stop (None)."""
    if cv_threads is not None:
        cv2.setNumThreads(cv_threads)
    conn.send(cv2.getNumThreads())
    while (spec := conn.recv()) is not None:
        cameras = [Camera(spec.clip, spec.work) for _ in spec.offsets]
        conn.send("ready")
        t0 = conn.recv()
        conn.send(run_paced(cameras, spec.offsets, t0, spec.windows))
        for camera in cameras:
            camera.close()


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
            proc.join(5)
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

    fps: list[list[float]]
    """Per window, every camera's frames per second."""
    cpu_s: list[float]
    """Per window, CPU seconds of all the worker processes together."""
    frames: list[int]
    """Per window, frames processed by all cameras."""
    machine: list[float]
    """Per window, CPUs busy on the whole machine (this benchmark and any other work)."""
    window_s: float

    @property
    def sustained(self) -> bool:
        return all(min(fps, default=0.0) >= SUSTAINED_FPS for fps in self.fps)

    def ms_per_frame(self) -> list[float]:
        return [
            1000 * c / f if f else float("nan")
            for c, f in zip(self.cpu_s, self.frames, strict=True)
        ]


def run_trial(group: WorkerGroup, clip: Path, cameras: int, work: Work, windows: Windows) -> Trial:
    period = 1.0 / FPS
    offsets = [i * period / cameras for i in range(cameras)]  # Real cameras are not in phase.
    share = len(group.conns)
    specs = [TrialSpec(clip, work, tuple(offsets[p::share]), windows) for p in range(share)]
    t0 = group.start(specs)
    marks = []
    for bound in windows.bounds(t0):
        sleep_until(bound)
        marks.append(machine_jiffies())
    results = group.results()
    for result in results:
        if result.errors:
            raise SystemExit(f"a camera thread failed:\n{result.errors[0]}")
    fps = [
        [r.frames[c][k] / windows.length for r in results for c in range(len(r.frames))]
        for k in range(windows.count)
    ]
    cpu = [sum(r.cpu_s[k] for r in results) for k in range(windows.count)]
    frames = [sum(counts[k] for r in results for counts in r.frames) for k in range(windows.count)]
    machine = [busy_cores(a, b) for a, b in itertools.pairwise(marks)]
    return Trial(fps, cpu, frames, machine, windows.length)


# --- (a) CPU per frame --------------------------------------------------------------------


def cpu_per_frame(clip: Path, work: Work, frames: int) -> float:
    """Milliseconds of this process's CPU per frame, unpaced, after a short warm-up."""
    camera = Camera(clip, work)
    for _ in range(10):
        camera.step()
    start = time.process_time()
    for _ in range(frames):
        camera.step()
    spent = time.process_time() - start
    camera.close()
    return 1000 * spent / frames


def breakdown(clip: Path, frames: int, repeats: int, cv_threads: int) -> dict[Work, float]:
    """Median ms per frame of each kind of work, run round-robin ``repeats`` times."""
    previous = cv2.getNumThreads()
    cv2.setNumThreads(cv_threads)
    samples: dict[Work, list[float]] = {work: [] for work in WORK_LABELS}
    try:
        for _ in range(repeats):
            for work in WORK_LABELS:
                samples[work].append(cpu_per_frame(clip, work, frames))
    finally:
        cv2.setNumThreads(previous)
    return {work: median(values) for work, values in samples.items()}


def proc_cpu_seconds(pid: int) -> float:
    """utime + stime of a process (all its threads) from /proc/PID/stat."""
    stat = Path(f"/proc/{pid}/stat").read_text()
    fields = stat.rsplit(")", 1)[1].split()  # Fields from the 3rd (state) on.
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def motion_version() -> str:
    run = subprocess.run([str(MOTION), "-h"], capture_output=True, text=True, timeout=10)
    found = re.search(r"Version\s+([\d.]+)", run.stdout + run.stderr)
    return found.group(1) if found else "?"


def motion_config(clip: Path, folder: Path) -> Path:
    """The config of NOTES.md: the clip as a network camera, detection on, no outputs."""
    lines = [
        "daemon off",
        f"log_file {folder / 'motion.log'}",
        "log_level 6",
        f"target_dir {folder / 'out'}",
        f"netcam_url file://{clip}",
        f"netcam_params capture_rate={FPS:g}",
        f"width {SIZE[0]}",
        f"height {SIZE[1]}",
        f"framerate {FPS:g}",
        "threshold 1500",
        "despeckle_filter EedDl",
        "picture_output off",
        "movie_output off",
        "webcontrol_port 0",
        "stream_port 0",
    ]
    (folder / "out").mkdir(exist_ok=True)
    path = folder / "motion.conf"
    path.write_text("\n".join(lines) + "\n")
    return path


@dataclass(frozen=True)
class MotionRun:
    ms_per_frame: list[float]
    """Per window: CPU ms / (window seconds x FPS)."""
    log_problems: list[str]


def measure_motion(clip: Path, folder: Path, windows: Windows) -> MotionRun:
    """Motion's CPU over each window, frames taken as window x FPS (it paces itself)."""
    config = motion_config(clip, folder)
    proc = subprocess.Popen(
        [str(MOTION), "-n", "-c", str(config)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    marks = []
    try:
        for bound in windows.bounds(time.monotonic()):
            sleep_until(bound)
            if proc.poll() is not None:
                raise SystemExit(f"motion exited early ({proc.returncode}); see {config}")
            marks.append(proc_cpu_seconds(proc.pid))
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    per_frame = [1000 * (b - a) / (windows.length * FPS) for a, b in itertools.pairwise(marks)]
    log = folder / "motion.log"
    text = log.read_text(errors="replace") if log.exists() else ""
    problems = [line for line in text.splitlines() if re.search(r"\[(ERR|WRN|ALR|CRT|EMG)\]", line)]
    return MotionRun(per_frame, problems)


@dataclass(frozen=True)
class PacedRow:
    """One camera paced at FPS in a fresh worker process."""

    work: Work
    cv_threads: int | None
    reported_threads: int
    trial: Trial

    @property
    def label(self) -> str:
        return f"Vigil {WORK_LABELS[self.work]}"

    @property
    def how(self) -> str:
        fps = median([f for window in self.trial.fps for f in window])
        how = "default" if self.cv_threads is None else "set"
        return f"OpenCV {self.reported_threads} threads ({how}), {fps:.1f} fps"

    @property
    def ms(self) -> float:
        return median(self.trial.ms_per_frame())


def measure_paced(clip: Path, windows: Windows) -> list[PacedRow]:
    """Decode only and the worker loop, with OpenCV's threads, then the loop with one."""
    rows = []
    plan: tuple[tuple[int | None, tuple[Work, ...]], ...] = (
        (None, ("decode", "detect")),
        (1, ("detect",)),
    )
    for cv_threads, works in plan:
        with worker_group(1, cv_threads) as group:
            for work in works:
                trial = run_trial(group, clip, 1, work, windows)
                rows.append(PacedRow(work, cv_threads, group.cv_threads[0], trial))
    return rows


def measure_cpu(args: argparse.Namespace, clip: Path, tmp: Path) -> dict[str, float]:
    """Section (a); returns the figures that seed section (b)'s search."""
    default_threads = cv2.getNumThreads()
    settings = sorted({default_threads, 1}, reverse=True)
    parts = {n: breakdown(clip, args.cpu_frames, args.repeat, n) for n in settings}
    windows = Windows(args.warmup, args.cpu_window, args.repeat_windows)
    paced = measure_paced(clip, windows)
    motion: MotionRun | None = None
    if MOTION.is_file():
        motion = measure_motion(clip, tmp, Windows(args.warmup + 1, windows.length, windows.count))
    print_breakdown(args, parts)
    print_paced(args, paced, motion)
    loop = parts[default_threads]
    viewer_ms = loop["view"] - loop["detect"]
    return {"paced": paced[1].ms, "viewer_factor": paced[1].ms / (paced[1].ms + viewer_ms)}


def print_breakdown(args: argparse.Namespace, parts: dict[int, dict[Work, float]]) -> None:
    rows: list[list[Cell]] = []
    for threads, by_work in parts.items():
        for work, label in WORK_LABELS.items():
            share = by_work["decode"] / by_work[work]
            rows.append([f"Vigil {label}", threads, fmt(by_work[work], 2), f"{share:.0%}"])
    print_table(
        f"(a1) CPU per {SIZE[0]}x{SIZE[1]} frame, unpaced (as fast as it goes), one camera in "
        f"this process (median of {args.repeat} runs of {args.cpu_frames} frames)",
        ["work", "OpenCV threads", "ms CPU/frame", "decode share"],
        rows,
        note="    process CPU seconds (all threads) / frames; decode = cv2.VideoCapture.read",
    )


def print_paced(args: argparse.Namespace, paced: list[PacedRow], motion: MotionRun | None) -> None:
    motion_ms = median(motion.ms_per_frame) if motion is not None else float("nan")
    rows: list[list[Cell]] = [
        [row.label, row.how, fmt(row.ms, 2), fmt(row.ms / motion_ms, 2)] for row in paced
    ]
    if motion is not None:
        rows.append(
            [
                f"Motion {motion_version()} (decode + detect)",
                "motion -n; frames = window x 25",
                fmt(motion_ms, 2),
                "1.00",
            ]
        )
    print_table(
        f"(a2) CPU per frame of one camera paced at {FPS:g} fps in its own process, beside "
        f"Motion on the same clip (median of {args.repeat_windows} windows of "
        f"{args.cpu_window:g} s after a warm-up)",
        ["program", "how", "ms CPU/frame", "x Motion"],
        rows,
        note="    x Motion: the row's ms/frame divided by Motion's (above 1 = costs more)",
    )
    if motion is None:
        print(f"Motion: skipped, {MOTION} is absent (Debian: apt-get install motion)")
    elif motion.log_problems:
        print("Motion log errors/warnings:", *motion.log_problems[:5], sep="\n    ")


# --- (b) cameras per process model --------------------------------------------------------


@dataclass(frozen=True)
class Model:
    processes: int
    cv_threads: int | None
    """None = OpenCV's own choice."""

    def label(self, reported: int) -> str:
        who = "1 process (threads)" if self.processes == 1 else f"{self.processes} processes"
        how = "default" if self.cv_threads is None else "set"
        return f"{who}, OpenCV {reported} threads ({how})"


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
    ms_per_frame: float
    """CPU per frame of the worker processes at that N."""

    def __str__(self) -> str:
        return str(self.cameras) if self.bounded else f">={self.cameras}"


def search_model(
    args: argparse.Namespace,
    clip: Path,
    model: Model,
    works: Sequence[Work],
    guesses: dict[Work, int] | None,
    cpu: dict[str, float],
) -> tuple[str, dict[Work, Found]]:
    """Largest sustained N without and with a viewer for one process model.

    ``guesses`` are where the searches start (from models already measured); without them
    the first starts from the single camera's CPU cost and the viewer's search from the
    first's result scaled by the viewer's extra cost."""
    windows = Windows(args.warmup, args.window)
    found: dict[Work, Found] = {}
    with worker_group(model.processes, model.cv_threads) as group:
        label = model.label(group.cv_threads[0])
        print(f"\n{label}:")
        for work in works:
            tried: dict[int, Trial] = {}

            def passes(n: int, work: Work = work, tried: dict[int, Trial] = tried) -> bool:
                if n not in tried:
                    tried[n] = run_trial(group, clip, n, work, windows)
                    print_trial(n, work, tried[n])
                return tried[n].sustained

            if guesses and work in guesses:
                guess = guesses[work]
            elif work == "detect":
                guess = estimate(cpu["paced"], args.max_cameras)
            else:
                guess = math.floor(found["detect"].cameras * cpu["viewer_factor"])
            # A viewer only adds work: an N that fails without one fails with one.
            ceiling = found["detect"].cameras + 1 if work == "view" else None
            n, bounded = largest_sustained(passes, guess, ceiling, args.max_cameras)
            ms = tried[n].ms_per_frame()[0] if n in tried else float("nan")
            found[work] = Found(n, bounded, ms)
    return label, found


def print_trial(n: int, work: Work, trial: Trial) -> None:
    fps = trial.fps[0]
    load = os.getloadavg()[0]
    cores = os.cpu_count() or 1
    verdict = "sustained" if trial.sustained else "NOT sustained"
    viewer = "viewer   " if work == "view" else "no viewer"
    print(
        f"  N={n:<3d} {viewer}  fps min {min(fps):4.1f} median {median(fps):4.1f}  "
        f"CPU {trial.cpu_s[0] / trial.window_s:4.2f} of machine's {trial.machine[0]:4.2f}/{cores}  "
        f"{fmt(trial.ms_per_frame()[0], 2)} ms/frame  load {load:4.1f}  {verdict}"
    )


def estimate(ms_per_frame: float, limit: int) -> int:
    """Cameras GUESS_SHARE of the CPUs could carry at one paced camera's CPU cost per frame."""
    cores = os.cpu_count() or 1
    if not ms_per_frame > 0:
        return 1
    return max(1, min(limit, math.floor(GUESS_SHARE * cores * 1000 / (FPS * ms_per_frame))))


def measure_cameras(args: argparse.Namespace, clip: Path, cpu: dict[str, float]) -> None:
    print(
        f"\n(b) Cameras sustained: every camera >= {SUSTAINED_FPS:g} fps over {args.window:g} s "
        f"after a {args.warmup:g} s warm-up; CPU = cores used by the worker processes "
        "of the cores busy on the whole machine"
    )
    plan = search_plan(args.quick)
    results: dict[Model, dict[Work, Found]] = {}
    labels: dict[Model, str] = {}
    for model, works in plan:
        guesses = first_guesses(model, results, args.max_cameras)
        labels[model], results[model] = search_model(args, clip, model, works, guesses, cpu)
    columns: list[Work] = ["detect"] if args.quick else ["detect", "view"]
    rows = [[labels[m], *(str(results[m].get(w, "-")) for w in columns)] for m, _ in plan]
    print_table(
        f"(b) Largest N of {SIZE[0]}x{SIZE[1]} {FPS:g} fps cameras sustained",
        ["process model", "no viewer", "one viewer each"][: 1 + len(columns)],
        rows,
        note="" if args.quick else "    -: not searched (one OpenCV thread: no viewer only)",
    )


def search_plan(quick: bool) -> list[tuple[Model, tuple[Work, ...]]]:
    """Process models and what each is searched for: 1 and 2 processes with OpenCV's own
    thread count, without and with a viewer; then with one OpenCV thread, without a viewer.
    ``--quick``: OpenCV's own thread count, without a viewer."""
    if quick:
        return [(Model(1, None), ("detect",)), (Model(2, None), ("detect",))]
    both: tuple[Work, ...] = ("detect", "view")
    return [
        (Model(1, None), both),
        (Model(2, None), both),
        (Model(1, 1), ("detect",)),
        (Model(2, 1), ("detect",)),
    ]


def first_guesses(
    model: Model, results: dict[Model, dict[Work, Found]], limit: int
) -> dict[Work, int] | None:
    """Where a model's searches start: a measured model with as many processes gives its
    result; else the last measured model gives the more of its result and what the CPUs
    would carry at its CPU per frame there; None for the first model."""
    if not results:
        return None
    same = [m for m in results if m.processes == model.processes]
    if same:
        return {w: max(1, f.cameras) for w, f in results[same[-1]].items()}
    last = results[list(results)[-1]]
    return {w: max(1, f.cameras, estimate(f.ms_per_frame, limit)) for w, f in last.items()}


# --- main ---------------------------------------------------------------------------------


def make_clip(args: argparse.Namespace, folder: Path) -> tuple[Path, str]:
    """The looping camera clip (640x480, 25 fps MJPG AVI) and where its frames came from."""
    footage = load_footage(args.data, SOURCE_FRAMES, args.synthetic)
    frames = resized(ping_pong(footage.frames, 2 * len(footage.frames) - 2), SIZE)
    clip = write_mjpg(frames, folder / "camera.avi", FPS)
    return clip, (
        f"{footage.description}; {len(footage.frames)} frames played forwards then backwards, "
        f"resized to {SIZE[0]}x{SIZE[1]}, written as an MJPG AVI at {FPS:g} fps "
        f"({len(frames) / FPS:.1f} s, looped)"
    )


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter windows, ~1 minute")
    parser.add_argument("--warmup", type=float, default=None, help="seconds before measuring")
    parser.add_argument("--window", type=float, default=None, help="seconds measured per trial")
    parser.add_argument("--repeat", type=int, default=None, help="runs of each CPU figure")
    parser.add_argument("--max-cameras", type=int, default=64, help="stop climbing here")
    parser.add_argument("--synthetic", action="store_true", help="synthetic scene, not footage")
    add_data_argument(parser)
    args = parser.parse_args(argv)
    quick = args.quick
    args.warmup = args.warmup if args.warmup is not None else (1.5 if quick else 2.0)
    args.window = args.window if args.window is not None else (3.0 if quick else 4.0)
    args.repeat = args.repeat if args.repeat is not None else (3 if quick else 5)
    args.cpu_frames = 100 if quick else 150
    args.cpu_window = 2.5 if quick else 3.0
    args.repeat_windows = 2 if quick else 3
    if args.warmup < 0 or args.window <= 0 or args.repeat < 1 or args.max_cameras < 1:
        parser.error("--warmup >= 0, --window > 0, --repeat >= 1, --max-cameras >= 1")
    return args


def main(argv: Sequence[str] | None = None) -> None:
    args = parse_args(argv)
    started = time.perf_counter()
    print_environment("Vigil cameras benchmark")
    with tempfile.TemporaryDirectory(prefix="vigil-cameras-") as tmp:
        clip, description = make_clip(args, Path(tmp))
        print(f"camera: {description}")
        cpu = measure_cpu(args, clip, Path(tmp))
        measure_cameras(args, clip, cpu)
    print(f"\ndone in {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
