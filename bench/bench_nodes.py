"""Several machines: what placing cameras by lease costs, and how fast a dead node's cameras
come back (issue 31, docs/scaling.md).

Starts a PostgreSQL cluster (initdb in a temporary folder, as the tests do), a Mosquitto
and ``--nodes`` real ``vigil serve`` processes on loopback sharing them, with ``--cameras``
file cameras (a synthetic AVI each: a square crosses every 3 s). Then:

(a) the coordination's cost, cameras not activated: over ``--window`` seconds, the rows
    PostgreSQL wrote and the transactions it committed (``pg_stat_database``), and the
    messages the broker carried (a client subscribed to ``#``), per camera and second;
(b) the same with every camera activated: events, snapshots and activity added; and the
    connections the nodes hold open;
(c) ``--kills`` times, a node killed (SIGKILL to its process group), round-robin: the
    time from the kill until every camera is live again on the others, then the time the
    node, restarted, takes to be back to an even share. p50 and p95 of each.

    .venv/bin/python bench/bench_nodes.py [--nodes 3] [--cameras 12] [--kills 6]
        [--window 30] [--lease 10]

It holds /tmp/vigil/bench.lock while it runs (and waits for another's to go first).
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

import httpx
import psycopg
from _common import bench_lock, print_environment, print_table

from tests.api.vigil_livekit import (
    add_camera,
    free_port,
    serve_process,
    wait_for,
    write_video,
)
from tests.mqtt.mosquitto import Mosquitto, Watcher
from tests.postgres import Cluster


class Site:
    """The nodes, started and restarted on their own ports, logging into the folder."""

    def __init__(self, folder: Path, names: list[str], env: dict[str, str]) -> None:
        self.folder = folder
        self.names = names
        self.env = env
        self.ports = {name: free_port() for name in names}
        self.processes: dict[str, subprocess.Popen[str]] = {}
        self.bases: dict[str, str] = {}
        self.stack = ExitStack()

    def start(self, name: str) -> None:
        process, base = self.stack.enter_context(
            serve_process(
                self.folder / name,
                own_group=True,
                log=self.folder / f"{name}.log",
                port=self.ports[name],
                VIGIL_NODE_NAME=name,
                **self.env,
            )
        )
        self.processes[name], self.bases[name] = process, base

    def kill(self, name: str) -> None:
        os.killpg(self.processes[name].pid, signal.SIGKILL)
        self.processes[name].wait(10)
        del self.bases[name]

    def placement(self, names: list[str] | None = None) -> dict[str, list[int]]:
        """The cameras each node shows live (a node that does not answer: none)."""
        placed = {}
        for name in names or list(self.bases):
            try:
                cameras = httpx.get(f"{self.bases[name]}/api/cameras", timeout=5).json()
            except httpx.HTTPError:
                cameras = []
            placed[name] = sorted(c["id"] for c in cameras if c["state"] == "live")
        return placed


def each_once(placed: dict[str, list[int]], ids: list[int]) -> bool:
    return sorted(i for held in placed.values() for i in held) == ids


def even(placed: dict[str, list[int]], ids: list[int]) -> bool:
    counts = [len(held) for held in placed.values()]
    return each_once(placed, ids) and max(counts) - min(counts) <= 1


def database_counts(url: str) -> tuple[int, int]:
    """(transactions committed, rows written) of the database so far."""
    with psycopg.connect(url, autocommit=True) as conn:
        conn.execute("SELECT pg_stat_clear_snapshot()")
        row = conn.execute(
            "SELECT xact_commit, tup_inserted + tup_updated + tup_deleted"
            " FROM pg_stat_database WHERE datname = current_database()"
        ).fetchone()
    assert row is not None
    return int(row[0]), int(row[1])


def connections(url: str) -> int:
    """Vigil's connections to the database now (every node's server and camera processes)."""
    with psycopg.connect(url, autocommit=True) as conn:
        row = conn.execute(
            "SELECT COUNT(*) FROM pg_stat_activity"
            " WHERE datname = current_database() AND application_name = 'vigil'"
        ).fetchone()
    assert row is not None
    return int(row[0])


def measure(url: str, mqtt: Watcher, cameras: int, window_s: float) -> list[float]:
    """Per camera and second over the window: commits, rows written, broker messages."""
    time.sleep(1.5)  # Statistics reach pg_stat_database about a second late.
    commits, rows = database_counts(url)
    messages = mqtt.mark()
    time.sleep(window_s)
    sent = mqtt.mark() - messages
    time.sleep(1.5)
    commits_after, rows_after = database_counts(url)
    per = cameras * window_s
    return [(commits_after - commits) / per, (rows_after - rows) / per, sent / per]


def percentile(values: list[float], share: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(share * (len(ordered) - 1)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, default=3)
    parser.add_argument("--cameras", type=int, default=12)
    parser.add_argument("--kills", type=int, default=6)
    parser.add_argument("--window", type=float, default=30.0, help="seconds per cost window")
    parser.add_argument("--lease", type=float, default=10.0, help="VIGIL_LEASE_S")
    args = parser.parse_args()
    with bench_lock("bench_nodes.py"), tempfile.TemporaryDirectory(prefix="vigil-nodes-") as tmp:
        print_environment("bench_nodes.py: leases and failover across vigil serve nodes")
        run(Path(tmp), args)


def run(folder: Path, args: argparse.Namespace) -> None:
    cluster = Cluster().start()
    broker = Mosquitto(folder / "broker").start()
    names = [f"node{i}" for i in range(args.nodes)]
    try:
        url = cluster.database()
        env = {
            "VIGIL_DATABASE_URL": url,
            "VIGIL_MQTT_URL": broker.url,
            "VIGIL_DEMO_CAMERA": "false",
            "VIGIL_CAMERA_PROCESSES": "1",
            "VIGIL_CLIPS": "false",
            "VIGIL_QUIET_S": "0.5",
            "VIGIL_LEASE_S": str(args.lease),
        }
        site = Site(folder, names, env)
        with site.stack, Watcher(broker.port) as mqtt:
            for name in names:
                site.start(name)
            videos = [write_video(folder / f"cam{i}.avi") for i in range(args.cameras)]
            first = site.bases[names[0]]
            ids = [add_camera(first, f"file://{v}", f"cam{i}") for i, v in enumerate(videos)]
            wait_for(lambda: even(site.placement(), ids), 120, "the cameras placed evenly", 0.5)
            idle = measure(url, mqtt, len(ids), args.window)
            for camera in ids:
                httpx.post(f"{first}/api/cameras/{camera}/activate").raise_for_status()
            time.sleep(5)
            active = measure(url, mqtt, len(ids), args.window)
            open_now = connections(url)
            print_table(
                f"(a, b) per camera and second, {args.nodes} nodes, {len(ids)} cameras,"
                f" VIGIL_LEASE_S={args.lease:g}, over {args.window:g} s",
                ["cameras", "PostgreSQL commits", "rows written", "broker messages"],
                [["not activated (leases only)", *idle], ["activated", *active]],
                note=f"PostgreSQL connections open: {open_now} ({open_now / args.nodes:g} a node)",
            )
            returns, shares = kills(site, names, ids, args.kills)
    finally:
        broker.stop()
        cluster.stop()
    print_table(
        f"(c) {len(returns)} kills (SIGKILL to a node's process group), seconds",
        ["from", "p50", "p95", "min", "max"],
        [
            ["kill to every camera live again", *_spread(returns)],
            ["restart to an even share again", *_spread(shares)],
        ],
    )


def kills(
    site: Site, names: list[str], ids: list[int], count: int
) -> tuple[list[float], list[float]]:
    returns: list[float] = []
    shares: list[float] = []
    for index in range(count):
        victim = names[index % len(names)]
        survivors = [n for n in names if n != victim]
        site.kill(victim)
        killed = time.monotonic()
        wait_for(lambda s=survivors: each_once(site.placement(s), ids), 60, "return", 0.1)
        returns.append(time.monotonic() - killed)
        restarted = time.monotonic()
        site.start(victim)
        wait_for(lambda: even(site.placement(), ids), 120, "an even share", 0.25)
        shares.append(time.monotonic() - restarted)
        print(f"kill {index + 1}: {victim}: back in {returns[-1]:.1f} s,"
              f" even again {shares[-1]:.1f} s after its restart", flush=True)  # fmt: skip
    return returns, shares


def _spread(values: list[float]) -> list[float]:
    return [
        statistics.median(values),
        percentile(values, 0.95),
        min(values),
        max(values),
    ]


if __name__ == "__main__":
    main()
