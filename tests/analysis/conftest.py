from pathlib import Path

import pytest

from tests.analysis.test_cli_analyze import WALKER
from tests.conftest import write_scene_video


@pytest.fixture(scope="session")
def walker_video(tmp_path_factory) -> Path:
    """The walker scene as an MJPG AVI, written once for the analysis tests."""
    return write_scene_video(WALKER, tmp_path_factory.mktemp("video") / "walker.avi")
