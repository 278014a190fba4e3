"""The default method's speed here against another git revision's, in one run.

    python bench/revision_speed.py --base REV [--rounds 5] [--frames 300] [--data DIR]

Checks REV out into a temporary worktree and times the segmentation stage (the
method's ``apply`` on frames as the pipeline prepares them, 320 wide) in both trees,
alternately, ``--rounds`` times each, in fresh processes: back to back, and paced as a
live camera's frames are (40 ms apart, when its images and code have gone cold). Each
round prints a median per frame; the summary prints the median of the rounds and the
ratio this tree / REV. The frames are the first ``--frames`` of the BGSLibrary clip
(a street; the shared data), or the synthetic crossing scene without it. What a
refactoring claims to cost nothing must show a ratio near 1 here.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACE_S = 0.04


def measure(frames_wanted: int, data: Path | None) -> dict[str, float]:
    """Median ms per frame of the default method's ``apply``, back to back and paced."""
    from _common import find_data_dir

    from app.sources.files import open_input
    from app.sources.synthetic import standard_scenes
    from app.vision.motion import DEFAULT_METHOD, create_method
    from app.vision.pipeline import Pipeline, warm_up

    warm_up()
    found = find_data_dir(data)
    clip = found / "clips" / "bgslibrary-video02.avi" if found else None
    if clip is not None and clip.exists():
        video = open_input(clip)
        frames, fps = list(itertools.islice(video.frames(), frames_wanted)), video.fps
    else:
        scene = standard_scenes()["crossing"]
        frames, fps = list(scene.frames_iter()), scene.fps
    pipeline = Pipeline(fps=fps)
    prepared = [pipeline.prepare(frame) for frame in frames]
    figures = {}
    for mode, pause in (("back_to_back_ms", 0.0), ("paced_ms", PACE_S)):
        method = create_method(DEFAULT_METHOD, fps=fps)
        times = []
        for gray in prepared:
            if pause:
                time.sleep(pause)
            start = time.perf_counter()
            method.apply(gray)
            times.append(time.perf_counter() - start)
        figures[mode] = 1000 * statistics.median(times[10:])
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", help="the git revision to compare with (e.g. HEAD~3)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--data", type=Path)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(measure(args.frames, args.data)))
        return
    if not args.base:
        parser.error("--base REV is required")
    with tempfile.TemporaryDirectory() as folder:
        base_tree = Path(folder) / "base"
        subprocess.run(
            [
                "git",
                "-C",
                str(ROOT),
                "worktree",
                "add",
                "--detach",
                "-q",
                str(base_tree),
                args.base,
            ],
            check=True,
        )
        try:
            compare(base_tree, args)
        finally:
            subprocess.run(
                ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base_tree)]
            )


def compare(base_tree: Path, args: argparse.Namespace) -> None:
    trees = {"this tree": ROOT, args.base: base_tree}
    rounds: dict[str, list[dict[str, float]]] = {name: [] for name in trees}
    script = str(Path(__file__).resolve())
    command = [sys.executable, "-P", script, "--child", "--frames", str(args.frames)]
    # Both trees read the same frames: the shared data as this tree finds it (a worktree
    # elsewhere has no ../shared beside it, and would fall back to the synthetic scene).
    from _common import find_data_dir

    data = find_data_dir(args.data)
    if data is not None:
        command += ["--data", str(data.resolve())]
    clip = data / "clips" / "bgslibrary-video02.avi" if data else None
    shown = clip if clip is not None and clip.exists() else "the synthetic crossing scene"
    print(f"frames: the first {args.frames} of {shown}")
    for round_number in range(args.rounds):
        for name, tree in trees.items():
            environment = {**os.environ, "PYTHONPATH": f"{tree}:{tree / 'bench'}"}
            output = subprocess.run(
                command, cwd=tree, env=environment, capture_output=True, text=True, check=True
            ).stdout
            figures = json.loads(output.strip().splitlines()[-1])
            rounds[name].append(figures)
            print(f"round {round_number + 1} {name:>12}: " + _figures(figures), flush=True)
    medians = {
        name: {mode: statistics.median(r[mode] for r in results) for mode in results[0]}
        for name, results in rounds.items()
    }
    for name, figures in medians.items():
        print(f"median {name:>12}: " + _figures(figures))
    this, base = medians["this tree"], medians[args.base]
    print(
        "ratio this tree / base: "
        + ", ".join(f"{mode} {this[mode] / base[mode]:.3f}" for mode in this)
    )


def _figures(figures: dict[str, float]) -> str:
    return ", ".join(f"{mode} {value:.3f}" for mode, value in figures.items())


if __name__ == "__main__":
    main()
