"""Helpers shared by the benchmark scripts: paths, data lookup, pipelines, tables.

Importing this module puts the repository root on ``sys.path``, so the
scripts run as ``python bench/NAME.py`` from anywhere without installing Vigil.
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import os
import platform
import statistics
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO

REPO_ROOT = Path(__file__).resolve().parent.parent
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from app.analysis.runner import scan_background  # noqa: E402
from app.vision.motion import DEFAULT_METHOD, METHODS  # noqa: E402
from app.vision.motion.adaptive import MECHANISMS, AdaptiveBackground, AdaptiveConfig  # noqa: E402
from app.vision.pipeline import FrameResult, Pipeline, PipelineConfig  # noqa: E402
from app.vision.types import Image  # noqa: E402

DATA_CANDIDATES = (REPO_ROOT.parent / "shared" / "data",)
"""Where the shared real footage is looked for when ``--data`` is not given."""

Cell = str | int | float | None


# --- data ------------------------------------------------------------------


def add_data_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--data",
        type=Path,
        default=None,
        help="folder of shared real footage (default: ../shared/data beside the repo)",
    )


def data_candidates(explicit: Path | None) -> tuple[Path, ...]:
    """The folders looked at, in order: ``--data`` alone when given."""
    return (explicit,) if explicit is not None else DATA_CANDIDATES


def find_data_dir(explicit: Path | None) -> Path | None:
    """The shared data folder, or None when there is none."""
    for candidate in data_candidates(explicit):
        if candidate.is_dir():
            return candidate.resolve()
    return None


def no_data_reason(explicit: Path | None) -> str:
    looked = ", ".join(str(p) for p in data_candidates(explicit))
    return f"no shared data folder (looked at {looked}; give --data DIR)"


# --- pipelines --------------------------------------------------------------


def method_names() -> list[str]:
    """Every public method, the default first."""
    return [DEFAULT_METHOD] + [name for name in METHODS if name != DEFAULT_METHOD]


def method_label(name: str) -> str:
    return f"{name} (default)" if name == DEFAULT_METHOD else name


WITHOUT = "-without-"
"""``adaptive-without-NAME``: the default method with its mechanism NAME switched off
(``AdaptiveConfig``), to measure what the mechanism is worth."""


def without(mechanism: str) -> str:
    return f"{DEFAULT_METHOD}{WITHOUT}{mechanism}"


def parse_methods(parser: argparse.ArgumentParser, text: str) -> list[str]:
    """The comma-separated methods of ``text``; an unknown one is the parser's error."""
    methods = [m.strip() for m in text.split(",") if m.strip()]
    known = [*method_names(), *(without(mechanism) for mechanism in MECHANISMS)]
    unknown = [m for m in methods if m not in known]
    if unknown:
        parser.error(
            f"unknown method(s) {', '.join(unknown)}; choose from {', '.join(method_names())}"
        )
    return methods


def make_pipeline(method: str, fps: float) -> Pipeline:
    """Vigil's pipeline with its default settings and the given method (or the default one
    without a mechanism: ``WITHOUT``)."""
    name, _, mechanism = method.partition(WITHOUT)
    pipeline = Pipeline(PipelineConfig(method=name), fps=fps)
    if mechanism:
        config = AdaptiveConfig(**{mechanism: False})
        pipeline.method = AdaptiveBackground(fps=fps, config=config)
    return pipeline


def run_pipeline(
    method: str, frames: Sequence[Image], fps: float, background_scan: bool = False
) -> Iterator[FrameResult]:
    """Results of a fresh pipeline over ``frames``, one per frame, in order; with
    ``background_scan``, the pipeline first scans them for the empty scene, as
    ``vigil analyze`` does for a method that can start from it (a live camera cannot)."""
    pipeline = make_pipeline(method, fps)
    if background_scan and pipeline.starts_from_scene:
        scan_background(pipeline, frames, fps)
    for frame in frames:
        yield pipeline.process(frame)


# --- numbers and tables ------------------------------------------------------


def median(values: Sequence[float]) -> float:
    return statistics.median(values) if values else float("nan")


def fmt(value: float | None, digits: int = 3) -> str:
    """A number for a table cell; '-' for a missing or undefined value."""
    if value is None or value != value:
        return "-"
    return f"{value:.{digits}f}"


def print_table(
    title: str,
    headers: Sequence[str],
    rows: Sequence[Sequence[Cell]],
    note: str = "",
    left: int = 1,
) -> None:
    """A plain-text table: the first ``left`` columns left-aligned, the rest right-aligned."""
    cells = [[_cell(c) for c in row] for row in rows]
    widths = [max(len(h), *(len(row[i]) for row in cells)) for i, h in enumerate(headers)]
    print(f"\n{title}")
    if note:
        print(note)
    print(_line(headers, widths, left))
    print("  ".join("-" * w for w in widths))
    for row in cells:
        print(_line(row, widths, left))


def _cell(value: Cell) -> str:
    if isinstance(value, float):
        return fmt(value)
    return "-" if value is None else str(value)


def _line(cells: Sequence[str], widths: Sequence[int], left: int) -> str:
    padded = (
        c.ljust(w) if i < left else c.rjust(w)
        for i, (c, w) in enumerate(zip(cells, widths, strict=True))
    )
    return "  ".join(padded).rstrip()


BENCH_LOCK = Path("/tmp/vigil/bench.lock")


@contextlib.contextmanager
def bench_lock(name: str) -> Iterator[None]:
    """The machine's timing runs take turns (``flock /tmp/vigil/bench.lock COMMAND`` takes
    the same lock): wait for whoever holds it, then hold it."""
    BENCH_LOCK.parent.mkdir(parents=True, exist_ok=True)
    with BENCH_LOCK.open("a") as handle:
        if not _try_lock(handle):
            print(f"{name}: waiting for {BENCH_LOCK} (another timing run)", flush=True)
            fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _try_lock(handle: IO[str]) -> bool:
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


def print_environment(title: str) -> None:
    """Versions, threads and the machine's load: figures compare only like with like."""
    load = ", ".join(f"{value:.1f}" for value in os.getloadavg())
    print(title)
    print(
        f"python {platform.python_version()}, numpy {np.__version__}, "
        f"OpenCV {cv2.__version__} ({cv2.getNumThreads()} threads), "
        f"{os.cpu_count()} CPUs, {platform.machine()} {platform.system()}, "
        f"load average {load} at start"
    )
