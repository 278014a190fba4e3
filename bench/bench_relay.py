"""What a page on another node costs: a camera's live frames relayed between nodes (issue 31,
docs/scaling.md "Any node serves the whole site").

Starts a PostgreSQL cluster (initdb in a temporary folder, as the tests do) and two real
``vigil serve`` nodes on loopback, ``south`` and ``north``, with one activated 640x480
25 fps MJPG file camera (the shared footage, or the synthetic scene) pinned to south.
A /ws/live reader in a process of its own watches the camera (as a page does):

- ``direct``: the reader on south, the node that runs the camera;
- ``relayed``: the reader on north, which takes the frames from south's /ws/live and
  passes them on.

Over ``--repeat`` windows of ``--window`` seconds each: the frames a second the reader
got, and the CPU per frame delivered of each node's server process and of south's camera
process (all their threads, from /proc). The medians are printed; the relay's own cost
is north's server CPU per frame, beside south's server CPU per frame for its one client.

    .venv/bin/python bench/bench_relay.py [--window 10] [--repeat 5] [--data DIR] [--synthetic]

It holds /tmp/vigil/bench.lock while it runs (and waits for another's to go first).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import httpx
from _common import add_data_argument, bench_lock, fmt, median, print_environment, print_table
from _served import cpu_seconds, descendants, viewers
from bench_pipeline import load_footage, resized, write_mjpg

from tests.api.vigil_livekit import add_camera, free_port, serve_process, wait_for
from tests.postgres import Cluster

SIZE = (640, 480)
FPS = 25.0
FRAMES = 300
WARMUP_S = 3.0


@dataclass(frozen=True)
class Node:
    """A node as the bench sees it: its port (the viewers connect there) and server pid."""

    port: int
    pid: int


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--window", type=float, default=10.0, help="seconds per window")
    parser.add_argument("--repeat", type=int, default=5, help="windows per case")
    parser.add_argument("--synthetic", action="store_true", help="synthetic scene, not footage")
    add_data_argument(parser)
    args = parser.parse_args()
    with bench_lock("bench_relay.py"), tempfile.TemporaryDirectory(prefix="vigil-relay-") as tmp:
        print_environment("bench_relay.py: a camera's live frames relayed between two nodes")
        run(Path(tmp), args)


def run(folder: Path, args: argparse.Namespace) -> None:
    footage = load_footage(args.data, FRAMES, args.synthetic)
    print(footage.description)
    clip = write_mjpg(resized(footage.frames, SIZE), folder / "clip.avi", FPS)
    cluster = Cluster().start()
    try:
        env = {
            "VIGIL_DATABASE_URL": cluster.database(),
            "VIGIL_DEMO_CAMERA": "false",
            "VIGIL_CAMERA_PROCESSES": "1",
            "VIGIL_CLIPS": "false",
        }
        ports = {name: free_port() for name in ("south", "north")}
        bases: dict[str, str] = {}
        with (
            serve_process(folder / "south", port=ports["south"], VIGIL_NODE_NAME="south", **env)
            as (south, bases["south"]),
            serve_process(folder / "north", port=ports["north"], VIGIL_NODE_NAME="north", **env)
            as (north, bases["north"]),
        ):  # fmt: skip
            nodes = {
                "south": Node(ports["south"], south.pid),
                "north": Node(ports["north"], north.pid),
            }
            camera = add_camera(bases["north"], f"file://{clip}", "relayed")
            url = f"{bases['north']}/api/cameras/{camera}"
            httpx.patch(url, json={"pinned_to": "south"}).raise_for_status()
            httpx.post(f"{url}/activate").raise_for_status()
            wait_for(
                lambda: (c := httpx.get(url).json())["node"] == "south" and c["state"] == "live",
                60,
                "the camera live on south",
            )
            rows = [measure(case, nodes, camera, args) for case in ("south", "north")]
    finally:
        cluster.stop()
    direct, relayed = rows
    print_table(
        f"CPU per frame delivered to one /ws/live reader, ms (median of {args.repeat} windows"
        f" of {args.window:g} s; a {SIZE[0]}x{SIZE[1]} {FPS:g} fps camera, activated, on south)",
        ["reader on", "frames/s", "south server", "south camera process", "north server"],
        [["south (direct)", *direct], ["north (relayed)", *relayed]],
        note="north's server, less its figure in the direct row, is the relay's own cost",
    )
    added = relayed[3] - direct[3]
    print(
        f"relay: north's server {fmt(added, 3)} ms more a frame with the page on it"
        f" ({fmt(relayed[3], 3)} against {fmt(direct[3], 3)}); south's server serving a page"
        f" itself: {fmt(direct[1], 3)} ms a frame ({added / direct[1]:.2f}x)"
    )


def measure(
    reader_on: str, nodes: dict[str, Node], camera: int, args: argparse.Namespace
) -> list[float]:
    """[frames/s, south server, south camera process, north server] ms a frame, medians."""
    south = nodes["south"].pid
    processes = {"south": [south], "camera": descendants(south), "north": [nodes["north"].pid]}
    samples: dict[str, list[float]] = {"fps": [], "south": [], "camera": [], "north": []}
    with viewers(nodes[reader_on].port, "live", [camera]) as reader:
        time.sleep(WARMUP_S)
        for _ in range(args.repeat):
            cpu = {k: sum(cpu_seconds(p) for p in pids) for k, pids in processes.items()}
            got, _ = reader.counts()
            start = time.monotonic()
            time.sleep(args.window)
            elapsed = time.monotonic() - start
            frames = reader.counts()[0][0] - got[0]
            if frames <= 0:
                raise SystemExit(f"the reader on {reader_on} got no frame in {args.window} s")
            samples["fps"].append(frames / elapsed)
            for key, pids in processes.items():
                used = sum(cpu_seconds(p) for p in pids) - cpu[key]
                samples[key].append(used * 1000 / frames)
    return [median(samples[k]) for k in ("fps", "south", "camera", "north")]


if __name__ == "__main__":
    main()
