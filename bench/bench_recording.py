"""What event clips cost: CPU per frame while recording and not, encoder settings, memory.

    python bench/bench_recording.py [--warmup S] [--window S] [--windows N] [--frames N]

(a) libx264's settings on a JPEG camera's frames (640x480, q80, a scene with noise and a
    moving object), one thread: CPU per frame to decode the JPEG to YUV and encode it
    (``app.recording.mp4.H264Writer``, as a clip does), and the bytes a second at 25 fps,
    per preset and CRF. The defaults (VIGIL_CLIP_PRESET, VIGIL_CLIP_CRF) are chosen by it.
(b) CPU per frame of an activated JPEG camera (``CameraWorker`` on a looping 640x480 25 fps
    MJPG AVI, paced, as ``bench_cameras.py`` runs it), each in a process of its own, all in
    the same run: with clips (VIGIL_CLIPS=true) and without, on a scene where something
    always moves (the one with clips records all the time: one long event) and on a still
    scene (it keeps its pre-roll, and records nothing). Process CPU (every thread, the
    clip's encoder too) over each window, per frame detected; medians over the windows.
(c) The pre-roll's memory per camera (3 s): a JPEG camera's (measured in the run of (b))
    and a decoded camera's (I420), with what keeping a decoded frame costs per frame.
(d) The activity history's disk use: a camera-day of rows (one a second), in SQLite.
"""

from __future__ import annotations

import argparse
import itertools
import multiprocessing as mp
import os
import sqlite3
import statistics
import tempfile
import time
from fractions import Fraction
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import av
import cv2
import numpy as np
from _common import fmt, median, print_environment, print_table

from app.core.config import Settings
from app.recording.mp4 import ClipFrame, EncoderSettings, H264Writer, decoded_clip_frame
from app.recording.preroll import PreRoll
from app.sources.synthetic import MovingObject, Scene
from app.storage import Database, SnapshotStore
from app.vision.motion import DEFAULT_METHOD
from app.vision.pipeline import warm_up
from app.workers.bus import EventBus
from app.workers.camera import CameraWorker

FPS = 25.0
SIZE = (640, 480)
LOOP_FRAMES = 250
"""Ten seconds at 25 fps, looped."""
PRESETS = ("ultrafast", "superfast", "veryfast")
CRFS = (23, 26, 28)


def moving_scene(moving: bool) -> Scene:
    """640x480 at 25 fps, textured, with camera noise; with ``moving``, two objects that
    are in view the whole loop (so an activated camera's event never ends)."""
    objects = (
        (
            MovingObject((20, 150), (50.0, 0.0), (60, 120), 200),
            MovingObject((560, 300), (-40.0, 0.0), (80, 60), 60),
        )
        if moving
        else ()
    )
    return Scene(
        "moving" if moving else "still",
        size=SIZE,
        fps=FPS,
        frames=LOOP_FRAMES,
        noise_sigma=2.0,
        objects=objects,
    )


def write_clip(scene: Scene, path: Path) -> list[bytes]:
    """The scene as JPEGs (q80, as a camera sends them), muxed as they are into an MJPG AVI
    (the camera of (b) hands over these very bytes); the JPEGs."""
    jpegs = [
        cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 80])[1].tobytes()
        for frame in scene.frames_iter()
    ]
    with av.open(str(path), "w", format="avi") as container:
        stream = container.add_stream("mjpeg", rate=int(FPS))
        stream.width, stream.height = SIZE
        stream.pix_fmt = "yuvj420p"
        for index, jpeg in enumerate(jpegs):
            packet = av.Packet(jpeg)
            packet.stream = stream
            packet.pts = packet.dts = index
            packet.time_base = Fraction(1, int(FPS))
            packet.is_keyframe = True
            container.mux(packet)
    return jpegs


# --- (a) encoder settings ----------------------------------------------------------------


def encode_cost(jpegs: list[bytes], settings: EncoderSettings, folder: Path) -> tuple[float, float]:
    """(CPU ms per frame, KB per second at 25 fps) of a clip of ``jpegs``."""
    path = folder / f"{settings.preset}-{settings.crf}.mp4"
    started = time.thread_time()
    with path.open("wb", buffering=0) as file:
        writer = H264Writer(file, FPS, settings)
        for i, jpeg in enumerate(jpegs):
            writer.write(ClipFrame(i / FPS, 0.0, SIZE, jpeg=jpeg), i / FPS)
        writer.close(durable=False)
    cpu_ms = (time.thread_time() - started) * 1000 / len(jpegs)
    return cpu_ms, path.stat().st_size / 1024 / (len(jpegs) / FPS)


def measure_encoders(jpegs: list[bytes], folder: Path, repeat: int) -> None:
    rows = []
    for preset in PRESETS:
        for crf in CRFS:
            runs = [encode_cost(jpegs, EncoderSettings(preset, crf), folder) for _ in range(repeat)]
            cpu = median([r[0] for r in runs])
            rows.append((preset, crf, fmt(cpu, 2), fmt(runs[0][1], 0), fmt(cpu * FPS / 10, 1)))
    print_table(
        "(a) libx264 on a JPEG camera's frames, 640x480, one thread",
        ("preset", "crf", "CPU ms/frame", "KB/s at 25 fps", "% of a core at 25 fps"),
        rows,
        f"{len(jpegs)} frames, decode (MJPEG to YUV) and encode; median of {repeat}",
        left=2,
    )
    defaults = Settings()
    print(f"defaults: VIGIL_CLIP_PRESET={defaults.clip_preset}, VIGIL_CLIP_CRF={defaults.clip_crf}")


# --- (b) a camera with clips and without ---------------------------------------------------


def camera_main(conn: Connection, clip: str, clips: bool, folder: str, window: float) -> None:
    """One activated camera in this process; sends (CPU s, frames detected, pre-roll bytes)
    at each window's end until told to stop."""
    warm_up()
    cv2.setNumThreads(1)
    settings = Settings(data_dir=Path(folder), clips=clips, demo_camera=False)
    db = Database(settings.db_path)
    camera_id = db.add_camera("cam", f"file://{clip}", DEFAULT_METHOD, 100.0)
    row = db.camera(camera_id)
    assert row is not None
    row["active"] = True
    worker = CameraWorker(row, settings, db, SnapshotStore(settings.snapshots_dir), EventBus())
    worker.start()
    try:
        while not conn.poll(window):
            conn.send((time.process_time(), worker.processed, worker.recorder.preroll.nbytes))
    finally:
        worker.request_stop()
        worker.join(5)


def measure_cameras(
    clips: dict[str, Path], folder: Path, warmup: float, window: float, windows: int
) -> dict[str, Any]:
    context = mp.get_context("spawn")
    runs = {}
    for scene, clip in clips.items():
        for recording in (True, False):
            ours, theirs = context.Pipe()
            data = folder / f"{scene}-{recording}"
            process = context.Process(
                target=camera_main, args=(theirs, str(clip), recording, str(data), window)
            )
            process.start()
            runs[(scene, recording)] = (process, ours)
    samples: dict[tuple[str, bool], list[tuple[float, int, int]]] = {k: [] for k in runs}
    deadline = time.monotonic() + warmup + window * (windows + 1)
    while time.monotonic() < deadline:
        for key, (_, conn) in runs.items():
            while conn.poll(0):
                samples[key].append(conn.recv())
        time.sleep(0.05)
    for process, conn in runs.values():
        conn.send("stop")
        process.join(10)
    skip = int(warmup / window)
    results: dict[str, Any] = {}
    for key, got in samples.items():
        got = got[skip:]
        per_frame = [
            (b[0] - a[0]) * 1000 / (b[1] - a[1]) for a, b in itertools.pairwise(got) if b[1] > a[1]
        ]
        fps = [(b[1] - a[1]) / window for a, b in itertools.pairwise(got)]
        results[key] = (per_frame, median(fps), max((g[2] for g in got), default=0))
    return results


def print_cameras(results: dict[Any, Any], windows: int, window: float) -> None:
    rows = []
    for scene in ("moving", "still"):
        with_clips, without = results[(scene, True)], results[(scene, False)]
        extra = median(with_clips[0]) - median(without[0])
        for recording, (per_frame, fps, _) in ((True, with_clips), (False, without)):
            spread = f"{min(per_frame):.2f}-{max(per_frame):.2f}" if per_frame else "-"
            rows.append(
                (
                    scene,
                    "on" if recording else "off",
                    fmt(median(per_frame), 2),
                    spread,
                    fmt(fps, 1),
                    fmt(extra, 2) if recording else "",
                )
            )
    print_table(
        "(b) an activated JPEG camera, 640x480 at 25 fps: CPU per frame, clips on and off",
        ("scene", "clips", "CPU ms/frame", "windows' range", "frames/s", "clips' cost ms"),
        rows,
        f"process CPU (all threads) per frame detected, median of {windows} windows of "
        f"{window:g} s; four cameras, one process each, in the same run; 'moving' records "
        "all the time (one long event), 'still' keeps only its pre-roll",
        left=2,
    )


# --- (c) pre-roll memory -------------------------------------------------------------------


def preroll_memory(jpeg_bytes: int, scene: Scene) -> None:
    frames = [scene.frame(i) for i in range(60)]
    started = time.thread_time()
    kept = [decoded_clip_frame(f, 0.0, 0.0) for f in frames * 5]
    convert_ms = (time.thread_time() - started) * 1000 / len(kept)
    rows = [("JPEG camera, 25 fps (its own JPEGs, q80; run (b))", fmt(jpeg_bytes / 2**20, 1), "0")]
    for fps in (15.0, 25.0):
        preroll = PreRoll(3.0, 2**40)
        for i in range(int(4 * fps)):
            frame = kept[i % len(kept)]
            preroll.add(ClipFrame(i / fps, 0.0, SIZE, pixels=frame.pixels))
        rows.append(
            (
                f"decoded camera, {fps:g} fps (I420)",
                fmt(preroll.nbytes / 2**20, 1),
                fmt(convert_ms, 3),
            )
        )
    print_table(
        "(c) the pre-roll's memory per camera, 3 s at 640x480",
        ("camera", "MB", "CPU ms/frame to keep"),
        rows,
        "a decoded frame is kept as I420 (cv2.cvtColor), half of BGR; a JPEG by reference",
    )


# --- (d) activity history ------------------------------------------------------------------


def activity_disk(folder: Path) -> None:
    path = folder / "activity.db"
    db = Database(path)
    db.close()
    before = path.stat().st_size
    rng = np.random.default_rng(1)
    db = Database(path)
    motion = np.where(rng.random(86400) < 0.1, rng.random(86400) * 0.05, 0.0)
    for start in range(0, 86400, 3600):
        db.add_activity(
            1, [(1_700_000_000 + s, float(round(motion[s], 6))) for s in range(start, start + 3600)]
        )
    db.close()
    raw = sqlite3.connect(path)
    raw.execute("VACUUM")
    raw.close()
    grown = (path.stat().st_size - before) / 2**20
    print_table(
        "(d) the activity history's disk use",
        ("rows", "MB per camera-day"),
        [("86400 (one a second; 10 % of them moving)", fmt(grown, 2))],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--warmup", type=float, default=10.0, help="seconds before measuring")
    parser.add_argument("--window", type=float, default=4.0, help="seconds per window")
    parser.add_argument("--windows", type=int, default=10, help="windows measured")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each encoder setting")
    args = parser.parse_args()
    print_environment("bench_recording.py: what event clips cost")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        moving, still = moving_scene(True), moving_scene(False)
        jpegs = write_clip(moving, folder / "moving.avi")
        write_clip(still, folder / "still.avi")
        print(f"JPEG frames: {statistics.mean(map(len, jpegs)) / 1024:.1f} KB on average")
        results = measure_cameras(
            {"moving": folder / "moving.avi", "still": folder / "still.avi"},
            folder,
            args.warmup,
            args.window,
            args.windows,
        )
        print_cameras(results, args.windows, args.window)
        measure_encoders(jpegs, folder, args.repeat)
        preroll_memory(results[("still", True)][2], moving)
        activity_disk(folder)
        print(f"\nload average at the end: {', '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
