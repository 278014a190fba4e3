"""Where one activated camera's CPU goes at 5 fps, frame by frame: section (a3)'s camera,
timed inside.

    python bench/profile_slow.py [--seconds S] [--method NAME] [--data DIR] [--synthetic]

The camera of ``bench_cameras.py``'s (a3): a real ``CameraWorker`` on the 5 fps clip
(every 5th frame of the footage's loop), activated, unwatched, in a spawned process with
one OpenCV thread, its database and snapshots in a temporary folder. After a warm-up, for
S seconds (default 60), it counts:

- each thread's CPU (``/proc/self/task/TID/schedstat``: nanoseconds on a CPU), and the
  whole process's (``time.process_time``), per frame read;
- in the camera's thread, the CPU (``time.thread_time``) of each step of a frame, each
  timed without the steps inside it (``alarm`` is its snapshots, rows and message apart
  from the colour decode, drawing, encoding, files and rows listed under it).
  ``loop, wake-up and the rest`` is the thread's CPU that no step took: pacing, waking
  from the sleep between frames, the loop.

These wrap the methods of the classes in this process only (a profile, not a measure of
the same thing as (a3): the timing itself costs a little). See bench/README.md.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import tempfile
import threading
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
from _common import add_data_argument, print_environment, print_table
from bench_cameras import ACTIVE, SLOW_FPS, LiveCameras, TrialSpec, Windows, make_clips

import app.workers.camera as camera_module
from app.events.alarm import AlarmLogic
from app.recording.activity import ActivityLog
from app.recording.recorder import Recorder
from app.sources.frames import JpegFrame
from app.sources.live import FileSource
from app.storage.db import Database
from app.storage.files import SnapshotStore
from app.vision.annotate import Annotator
from app.vision.blobs import BlobExtractor
from app.vision.morphology import Morphology
from app.vision.motion import create_method
from app.vision.pipeline import Pipeline, warm_up
from app.vision.tracker import Tracker
from app.vision.zones import IgnoreZones
from app.workers.camera import CameraWorker
from app.workers.hub import FrameHub

WARMUP_S = 5.0


class StepClock:
    """Thread CPU of each wrapped call in one thread, less the wrapped calls inside it."""

    def __init__(self) -> None:
        self.thread_id: int | None = None
        self.spent: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self._inner: list[float] = []
        """Per open call, the CPU of the wrapped calls inside it so far."""

    def wrap(self, owner: Any, name: str, step: str) -> None:
        inner_fn: Callable[..., Any] = getattr(owner, name)

        def timed(*args: Any, **kwargs: Any) -> Any:
            if threading.get_ident() != self.thread_id:
                return inner_fn(*args, **kwargs)
            self._inner.append(0.0)
            start = time.thread_time()
            try:
                return inner_fn(*args, **kwargs)
            finally:
                total = time.thread_time() - start
                inside = self._inner.pop()
                self.spent[step] += total - inside
                self.calls[step] += 1
                if self._inner:
                    self._inner[-1] += total

        setattr(owner, name, timed)

    def reset(self) -> None:
        self.spent.clear()
        self.calls.clear()


STEPS: list[tuple[Any, str, str]] = [
    (FileSource, "read", "read the file's next JPEG"),
    (JpegFrame, "gray", "decode grey at detection size"),
    (Pipeline, "_prepare", "denoise"),
    (Pipeline, "process", "pipeline, the rest (grey, countNonZero, result)"),
    (IgnoreZones, "__call__", "ignore zones"),
    (Morphology, "__call__", "morphology"),
    (BlobExtractor, "__call__", "blobs"),
    (Tracker, "update", "tracker"),
    (Tracker, "trails", "tracker trails"),
    (AlarmLogic, "update", "alarm logic"),
    (CameraWorker, "_alarm", "alarm: the rest (boxes, message, bus)"),
    (JpegFrame, "image", "alarm: decode colour"),
    (Annotator, "__call__", "alarm: draw"),
    (camera_module, "difference_picture", "alarm: difference picture"),
    (camera_module, "encode_jpeg", "alarm: encode 2 JPEGs (q90)"),
    (SnapshotStore, "save", "alarm: write 2 files"),
    (Database, "add_event", "db: add_event"),
    (Database, "add_snapshots", "db: add_snapshots (an alarm's 2 rows)"),
    (Database, "end_event", "db: end_event"),
    (Database, "add_activity", "db: add_activity"),
    (CameraWorker, "_record_start", "record start"),
    (CameraWorker, "_motion_end", "motion end (row, message)"),
    (Recorder, "feed", "recorder feed (pre-roll)"),
    (ActivityLog, "note", "activity note"),
    (FrameHub, "publish", "hub publish"),
    (CameraWorker, "_publish_status", "status message"),
    (camera_module, "_glance", "glance"),
    (CameraWorker, "_apply_pending", "apply pending"),
    (CameraWorker, "_handle", "handle: the rest (fps, LiveFrame, motion share)"),
]


def thread_cpu(native_id: int) -> float:
    return int(Path(f"/proc/self/task/{native_id}/schedstat").read_text().split()[0]) / 1e9


def profile(clip: Path, folder: Path, method: str, seconds: float) -> dict[str, Any]:
    """In a spawned process: the camera's CPU per frame, by thread and by step."""
    cv2.setNumThreads(1)
    warm_up()
    clock = StepClock()
    for owner, name, step in STEPS:
        clock.wrap(owner, name, step)
    # The method's apply: the class the pipeline will create.
    clock.wrap(type(create_method(method, None, SLOW_FPS)), "apply", "segment")
    mode = ACTIVE if method == ACTIVE.method else type(ACTIVE)(True, False, method)
    spec = TrialSpec((clip,), (0.0,), mode, Windows(WARMUP_S, seconds), folder)
    with tempfile.TemporaryDirectory(prefix="data-", dir=folder) as data_dir:
        cameras = LiveCameras(spec, Path(data_dir))
        worker = cameras.workers[0]
        worker.start()
        clock.thread_id = worker._thread.ident
        time.sleep(WARMUP_S)

        def sample() -> tuple[dict[str, float], float, int]:
            threads = {
                t.name: thread_cpu(t.native_id) for t in threading.enumerate() if t.native_id
            }
            return threads, time.process_time(), worker.frames

        clock.reset()
        before = sample()
        time.sleep(seconds)
        after = sample()
        steps, calls = dict(clock.spent), dict(clock.calls)
        alarms = worker.alarms
        cameras.close()
    frames = after[2] - before[2]
    threads = {name: after[0][name] - before[0].get(name, 0.0) for name in after[0]}
    return {
        "frames": frames,
        "process": after[1] - before[1],
        "threads": threads,
        "camera_thread": worker._thread.name,
        "steps": steps,
        "calls": calls,
        "alarms_total": alarms,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="seconds measured")
    parser.add_argument("--method", default=ACTIVE.method, help="segmentation method")
    parser.add_argument("--synthetic", action="store_true", help="synthetic scene, not footage")
    add_data_argument(parser)
    args = parser.parse_args()
    print_environment("Vigil: one activated camera at 5 fps, profiled")
    with tempfile.TemporaryDirectory(prefix="vigil-profile-") as tmp:
        _, slow_clip, description = make_clips(args, Path(tmp))
        print(f"camera: {description}; every 5th frame at {SLOW_FPS:g} fps")
        with mp.get_context("spawn").Pool(1) as pool:
            found = pool.apply(profile, (slow_clip, Path(tmp), args.method, args.seconds))
    frames = found["frames"]

    def ms(seconds: float) -> str:
        return f"{1000 * seconds / frames:.3f}"

    camera_cpu = found["threads"][found["camera_thread"]]
    steps = found["steps"]
    rows = [[step, str(found["calls"][step]), ms(cpu)] for step, cpu in steps.items()]
    rows.sort(key=lambda row: -float(row[2]))
    rows.append(["loop, wake-up and the rest", "-", ms(camera_cpu - sum(steps.values()))])
    print_table(
        f"The camera thread's CPU per frame ({frames} frames in {args.seconds:g} s, "
        f"{args.method}; alarms so far {found['alarms_total']})",
        ["step", "calls", "ms/frame"],
        rows,
    )
    thread_rows = [[name, ms(cpu)] for name, cpu in found["threads"].items()]
    named = sum(found["threads"].values())
    thread_rows.append(["other threads (not Python's)", ms(found["process"] - named)])
    thread_rows.append(["the process", ms(found["process"])])
    print_table("CPU per frame by thread", ["thread", "ms/frame"], thread_rows)


if __name__ == "__main__":
    main()
