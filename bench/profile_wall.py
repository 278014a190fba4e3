"""Where a wall of cameras on one page costs: the wall test's scene, by process.

    python bench/profile_wall.py [--cameras N] [--seconds S] [--rounds R]

N cameras (default 16) in a real ``vigil serve`` with two camera processes, each playing
the Chromium wall test's clip (``tests/api/vigil_livekit.write_video``: 320x240 at 15
fps, a square crossing it every 3 s), activated; Chromium at 1280x800 shows them on
``/#wall``. The server runs as ``bench_cameras.py``'s (``_served.Server``: a status
every 0.5 s, no clips), not with the test's settings (a status every 0.25 s), so its
page gets fewer /ws messages than the test's. Once every camera keeps its rate, for R
rounds (default 3) of S seconds (default 8) it counts the frames each camera's canvas
drew, and the CPU of each process that does the work: Chromium's by kind (its renderer,
GPU, browser and utility processes), Playwright's driver, the server, its camera
processes (and their forkserver). It prints each round and the medians.

A profile, not a benchmark: it shows where the machine goes while the wall test runs,
to tell a page's change from the moment's noise (run it on both revisions, in turn).
Needs Chromium (``chromium`` on the PATH) and Playwright.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import shutil
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from _common import bench_lock, print_environment, print_table
from _served import REPO, Server, cpu_seconds, descendants
from playwright.sync_api import sync_playwright

sys.path.insert(0, str(REPO))
from tests.api.vigil_livekit import wait_for, write_video  # the test's own clip

CAMERA_FPS = 14  # The clip's 15 fps, read back by the camera's own count.
DRAWN = (
    "() => [...document.querySelectorAll('.card canvas.live')].map(c => Number(c.dataset.drawn))"
)


def chromium_kind(pid: int) -> str:
    """'renderer', 'gpu-process', 'utility'... from a Chromium process's command line
    (which Chromium rewrites: one string, its arguments apart by spaces)."""
    with contextlib.suppress(OSError):
        found = re.search(rb"--type=([\w-]+)", Path(f"/proc/{pid}/cmdline").read_bytes())
        if found:
            return found.group(1).decode()
    return "browser"


def cpu_by_role(server: Server) -> dict[str, float]:
    """CPU seconds so far: the server, its camera processes, and the rest of this
    script's descendants: Chromium's processes by kind, Playwright's driver."""
    roles: dict[str, float] = defaultdict(float)
    roles["server"] = cpu_seconds(server.process.pid)
    served = descendants(server.process.pid)
    for pid in served:
        with contextlib.suppress(OSError):
            roles["camera processes"] += cpu_seconds(pid)
    for pid in descendants(os.getpid()):
        if pid == server.process.pid or pid in served:
            continue
        with contextlib.suppress(OSError):
            comm = Path(f"/proc/{pid}/comm").read_text().strip()
            role = "playwright" if comm.startswith("node") else f"chromium {chromium_kind(pid)}"
            roles[role] += cpu_seconds(pid)
    return roles


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cameras", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("needs Chromium (chromium on the PATH)")
    print_environment(f"Vigil: {args.cameras} activated cameras on a wall at 1280x800, profiled")
    with tempfile.TemporaryDirectory(prefix="wall-") as folder, sync_playwright() as playwright:
        clip = write_video(Path(folder) / "motion.avi")
        server = Server(2, Path(folder))
        try:
            ids = server.add([clip] * args.cameras, activated=True)
            server.wait_live(ids, activated=True)
            browser = playwright.chromium.launch(executable_path=chromium)
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            page.goto(server.base + "/#wall")
            page.wait_for_function(f"() => ({DRAWN})().filter(n => n > 0).length === {len(ids)}")
            cameras = server.client.get
            wait_for(
                lambda: min(c["fps"] for c in cameras("/api/cameras").json()) >= CAMERA_FPS,
                60,
                "every camera at its rate",
            )
            rounds: list[tuple[list[float], dict[str, float]]] = []
            for _ in range(args.rounds):
                drawn0, cpu0, t0 = page.evaluate(DRAWN), cpu_by_role(server), time.monotonic()
                page.wait_for_timeout(args.seconds * 1000)
                drawn1, cpu1 = page.evaluate(DRAWN), cpu_by_role(server)
                took = time.monotonic() - t0
                rates = [(b - a) / took for a, b in zip(drawn0, drawn1, strict=True)]
                cores = {role: (cpu1[role] - cpu0.get(role, 0.0)) / took for role in cpu1}
                rounds.append((rates, cores))
            browser.close()
        finally:
            server.close()
    roles = sorted({role for _, cores in rounds for role in cores})
    headers = ["round", "drawn/s least", "drawn/s median", *roles, "all"]
    rows: list[list[object]] = []
    for index, (rates, cores) in enumerate(rounds, 1):
        values = [cores.get(role, 0.0) for role in roles]
        rows.append([index, min(rates), statistics.median(rates), *values, sum(values)])
    medians = [
        statistics.median(float(row[column]) for row in rows) for column in range(1, len(headers))
    ]
    rows.append(["median", *medians])
    print_table(
        "Frames drawn a second per camera, and CPU (cores) by process",
        headers,
        rows,
        note=f"    {args.rounds} rounds of {args.seconds:g} s, {len(ids)} cameras, 2 processes",
    )


if __name__ == "__main__":
    with bench_lock("profile_wall"):
        main()
