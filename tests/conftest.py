"""Fixtures shared by every test folder: real footage, synthetic videos on disk."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from app.sources.synthetic import Scene
from app.storage.engine import Target
from tests.postgres import Cluster
from tests.postgres import missing as postgres_missing

ROOT = Path(__file__).resolve().parents[1]


def shared_data_dir() -> Path | None:
    """`../shared/data` beside the repository (or $VIGIL_SHARED_DATA), if it is there."""
    candidates = [os.environ.get("VIGIL_SHARED_DATA"), ROOT.parent / "shared" / "data"]
    for candidate in candidates:
        if candidate and Path(candidate).is_dir():
            return Path(candidate)
    return None


@pytest.fixture
def shared_data() -> Path:
    found = shared_data_dir()
    if found is None:
        pytest.skip("real footage not present: ../shared/data is absent")
    return found


def write_scene_video(scene: Scene, path: Path, fourcc: str = "MJPG") -> Path:
    """Render a synthetic scene into a real video file."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*fourcc), scene.fps, scene.size)
    assert writer.isOpened(), f"cannot write {path}"
    for frame in scene.frames_iter():
        writer.write(frame)
    writer.release()
    return path


def decode_all(path: Path) -> Iterator:
    capture = cv2.VideoCapture(str(path))
    try:
        while True:
            ok, frame = capture.read()
            if not ok:
                return
            yield frame
    finally:
        capture.release()


def lamplight(
    size: tuple[int, int], brightness: float, spread: float, centre: tuple[float, float]
) -> np.ndarray:
    """A lamp's soft spot of light on a picture of ``size`` (width, height): grey levels
    added per pixel, ``brightness`` at ``centre`` (fractions of the width and height),
    falling off as a Gaussian of ``spread`` pixels."""
    width, height = size
    rows, cols = np.mgrid[0:height, 0:width]
    distance = (cols - centre[0] * width) ** 2 + (rows - centre[1] * height) ** 2
    return brightness * np.exp(-distance / (2 * spread**2))


def lit(frame: np.ndarray, light: np.ndarray) -> np.ndarray:
    """``frame`` (BGR or grey, 8-bit) with ``light`` added to each channel."""
    added = light[..., None] if frame.ndim == 3 else light
    return np.clip(frame.astype(np.float64) + added, 0, 255).astype(np.uint8)


@pytest.fixture(scope="session")
def postgres() -> Iterator[Cluster]:
    """A real PostgreSQL server for the session (tests/postgres.py); skipped with the reason
    where one cannot be made."""
    reason = postgres_missing()
    if reason:
        pytest.skip(reason)
    cluster = Cluster().start()
    try:
        yield cluster
    finally:
        cluster.stop()


@pytest.fixture
def postgres_url(postgres: Cluster) -> Iterator[str]:
    """A fresh database of its own for the test, dropped after it: its URL."""
    url = postgres.database()
    yield url
    postgres.drop(url)


@pytest.fixture(params=["sqlite", "postgresql"])
def db_target(request: pytest.FixtureRequest, tmp_path: Path) -> Target:
    """Where a fresh database is, for a test run on both: a SQLite file, or a PostgreSQL
    database of its own (skipped where PostgreSQL cannot be run)."""
    if request.param == "sqlite":
        return tmp_path / "v.db"
    url: str = request.getfixturevalue("postgres_url")
    return url
