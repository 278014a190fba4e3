"""Where a page viewer's CPU goes: one activated camera in ``vigil serve``, by process.

    python bench/profile_viewer.py [--seconds S] [--rounds R] [--perf] [--data DIR] [--synthetic]

The camera of ``bench_cameras.py``'s (a) (the looping 640x480 25 fps MJPG clip) in a real
``vigil serve`` with one camera process, activated. Alternately unwatched and with one
/ws/live viewer (a raw socket in another process, as ``bench_cameras.py`` reads), R rounds
of S seconds each (default 3 of 10), it counts the CPU of the server and of its camera
process (every thread's, ``_served.cpu_seconds``), per frame the camera read, and prints
the median of the rounds for each, and what the viewer adds.

``--perf``: also ``perf record`` each process during the last round of each mode and
print the symbols that took the most of its samples (the kernel's, Python's and the
libraries'), to see what the viewer's share is made of.
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from _common import add_data_argument, print_environment, print_table
from _served import Server, cpu_seconds, descendants, viewers
from bench_cameras import make_clips

SETTLE_S = 3.0
PERF_TOP = 25


@contextlib.contextmanager
def perf_recording(pids: dict[str, int], folder: Path, label: str) -> Iterator[None]:
    runs = {
        role: subprocess.Popen(
            [
                "perf",
                "record",
                "-q",
                "-F",
                "2999",
                "-g",
                "-p",
                str(pid),
                "-o",
                str(folder / f"{label}-{role}.data"),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for role, pid in pids.items()
    }
    try:
        yield
    finally:
        for run in runs.values():
            run.send_signal(2)
            run.wait(30)


def perf_top(path: Path) -> str:
    report = subprocess.run(
        ["perf", "report", "-i", str(path), "--stdio", "--no-children", "-g", "none",
         "--sort", "dso,sym", "--percent-limit", "1"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    lines = [line for line in report.stdout.splitlines() if line and not line.startswith("#")]
    return "\n".join(lines[:PERF_TOP])


def measure(
    server: Server, camera_id: int, watched: bool, seconds: float, perf: Path | None
) -> tuple[dict[str, float], int]:
    """CPU seconds of the server and of its camera process over ``seconds``, and the
    frames the camera read meanwhile."""
    # The camera process is the descendant that works now (its forkserver only waits,
    # having spent its CPU on imports at the start).
    found = {pid: cpu_seconds(pid) for pid in descendants(server.process.pid)}
    time.sleep(0.5)
    camera = max(found, key=lambda pid: cpu_seconds(pid) - found[pid])
    pids = {"server": server.process.pid, "camera": camera}
    with viewers(server.port, "live", [camera_id]) if watched else contextlib.nullcontext():
        time.sleep(SETTLE_S)
        label = "watched" if watched else "unwatched"
        recording = perf_recording(pids, perf, label) if perf else contextlib.nullcontext()
        with recording:
            before = {role: cpu_seconds(pid) for role, pid in pids.items()}
            frames_before = (server.statuses.latest(camera_id) or {}).get("frames", 0)
            time.sleep(seconds)
            after = {role: cpu_seconds(pid) for role, pid in pids.items()}
            frames_after = (server.statuses.latest(camera_id) or {}).get("frames", 0)
    if frames_after <= frames_before:
        raise SystemExit("the camera read no frame in a round")
    return {role: after[role] - before[role] for role in pids}, frames_after - frames_before


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--perf", action="store_true", help="perf record the last rounds")
    parser.add_argument("--synthetic", action="store_true", help="synthetic scene, not footage")
    add_data_argument(parser)
    args = parser.parse_args()
    print_environment("Vigil page viewer profile")
    with tempfile.TemporaryDirectory(prefix="vigil-viewer-") as tmp:
        folder = Path(tmp)
        clips, _, description = make_clips(args, folder)
        print(f"camera: {description}")
        server = Server(1, folder)
        try:
            (camera_id,) = server.add(clips[:1], activated=True)
            server.wait_live([camera_id], activated=True)
            per_frame: dict[str, dict[str, list[float]]] = {"unwatched": {}, "watched": {}}
            for round_ in range(args.rounds):
                for mode in per_frame:
                    last = round_ == args.rounds - 1
                    perf = folder if args.perf and last else None
                    used, frames = measure(server, camera_id, mode == "watched", args.seconds, perf)
                    for name, seconds in used.items():
                        per_frame[mode].setdefault(name, []).append(1000 * seconds / frames)
        finally:
            server.close()
        rows = []
        totals = dict.fromkeys(per_frame, 0.0)
        for role in ("camera", "server"):
            cells = [statistics.median(by_role[role]) for by_role in per_frame.values()]
            for mode, value in zip(per_frame, cells, strict=True):
                totals[mode] += value
            rows.append([role, *(f"{c:.3f}" for c in cells), f"{cells[1] - cells[0]:+.3f}"])
        rows.append(["all", *(f"{totals[m]:.3f}" for m in per_frame),
                     f"{totals['watched'] - totals['unwatched']:+.3f}"])  # fmt: skip
        print_table(
            f"ms CPU per frame read, median of {args.rounds} rounds of {args.seconds:g} s",
            ["process", "unwatched", "one /ws/live viewer", "viewer adds"],
            rows,
        )
        print(f"viewer / unwatched: {totals['watched'] / totals['unwatched']:.2f} x")
        if args.perf:
            for data in sorted(folder.glob("*.data")):
                print(f"\nperf, {data.stem} (share of its samples):\n{perf_top(data)}")


if __name__ == "__main__":
    main()
