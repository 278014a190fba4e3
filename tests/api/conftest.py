from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest

from tests.api.vigil_livekit import Running, live_settings, running_server, write_video


@pytest.fixture
def motion_video(tmp_path: Path) -> Path:
    return write_video(tmp_path / "motion.avi")


@pytest.fixture
def serve(tmp_path: Path) -> Iterator[Callable[..., Running]]:
    """Start a real uvicorn with a data folder in tmp_path; stopped at the end of the test."""
    with ExitStack() as stack:

        def start(data_dir: Path | None = None, **overrides: Any) -> Running:
            settings = live_settings(data_dir or tmp_path / "data", **overrides)
            return stack.enter_context(running_server(settings))

        yield start
