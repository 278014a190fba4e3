"""Where a page viewer's CPU goes: one activated camera in ``vigil serve``, by thread.

    python bench/profile_viewer.py [--seconds S] [--rounds R] [--perf] [--data DIR] [--synthetic]

The camera of ``bench_cameras.py``'s (a) (the looping 640x480 25 fps MJPG clip) in a real
``vigil serve`` with one camera process, activated. Alternately unwatched and with one
/ws/live viewer (a raw socket in another process, as ``bench_cameras.py`` reads), R rounds
of S seconds each (default 3 of 10), it counts each thread's CPU of the server and of its
camera process (``/proc/PID/task/TID/schedstat``), per frame the camera read, and prints
the median of the rounds by thread, and what the viewer adds.

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
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path

from _common import add_data_argument, print_environment, print_table
from _served import Server, descendants, viewers
from bench_cameras import make_clips

SETTLE_S = 3.0
PERF_TOP = 25


def thread_cpu(pid: int) -> dict[str, float]:
    """CPU seconds of each thread of ``pid`` by thread name (threads of one name summed)."""
    found: dict[str, float] = defaultdict(float)
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(OSError, ValueError, IndexError):
            name = (task / "comm").read_text().strip()
            found[name] += int((task / "schedstat").read_text().split()[0]) / 1e9
    return found


def snapshot(processes: dict[str, int]) -> dict[str, float]:
    return {
        f"{role}: {name}": seconds
        for role, pid in processes.items()
        for name, seconds in thread_cpu(pid).items()
    }


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
) -> tuple[dict[str, float], float]:
    """CPU seconds by thread over ``seconds``, and the frames the camera read meanwhile."""
    pids = {"server": server.process.pid}
    camera_pids = [pid for pid in descendants(server.process.pid) if thread_cpu(pid)]
    # The camera process is the one descendant that works (the forkserver only waits).
    pids["camera"] = max(camera_pids, key=lambda pid: sum(thread_cpu(pid).values()))
    with viewers(server.port, "live", [camera_id]) if watched else contextlib.nullcontext():
        time.sleep(SETTLE_S)
        label = "watched" if watched else "unwatched"
        recording = perf_recording(pids, perf, label) if perf else contextlib.nullcontext()
        with recording:
            before, start = snapshot(pids), time.monotonic()
            frames_before = (server.statuses.latest(camera_id) or {}).get("frames", 0)
            time.sleep(seconds)
            after, end = snapshot(pids), time.monotonic()
            frames_after = (server.statuses.latest(camera_id) or {}).get("frames", 0)
    used = {name: after[name] - before.get(name, 0.0) for name in after}
    frames = frames_after - frames_before or 25.0 * (end - start)
    return used, frames


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
        names = sorted(set(per_frame["unwatched"]) | set(per_frame["watched"]))
        rows = []
        totals = dict.fromkeys(per_frame, 0.0)
        for name in names:
            cells = []
            for mode, by_name in per_frame.items():
                value = statistics.median(by_name.get(name, [0.0]))
                totals[mode] += value
                cells.append(value)
            if max(cells) >= 0.005:
                rows.append([name, *(f"{c:.3f}" for c in cells), f"{cells[1] - cells[0]:+.3f}"])
        rows.append(["all", *(f"{totals[m]:.3f}" for m in per_frame),
                     f"{totals['watched'] - totals['unwatched']:+.3f}"])  # fmt: skip
        print_table(
            f"ms CPU per frame read, median of {args.rounds} rounds of {args.seconds:g} s",
            ["process: thread", "unwatched", "one /ws/live viewer", "viewer adds"],
            rows,
        )
        print(f"viewer / unwatched: {totals['watched'] / totals['unwatched']:.2f} x")
        if args.perf:
            for data in sorted(folder.glob("*.data")):
                print(f"\nperf, {data.stem} (share of its samples):\n{perf_top(data)}")


if __name__ == "__main__":
    main()
