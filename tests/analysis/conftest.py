import json
from pathlib import Path

import pytest

from tests.analysis.walker import WALKER
from tests.conftest import write_scene_video


@pytest.fixture(scope="session")
def walker_video(tmp_path_factory) -> Path:
    """The walker scene as an MJPG AVI, written once for the analysis tests."""
    return write_scene_video(WALKER, tmp_path_factory.mktemp("video") / "walker.avi")


@pytest.fixture(scope="session")
def box_truth(tmp_path_factory) -> Path:
    """The walker's true boxes, frame by frame, in Vigil's truth format."""
    frames = {str(i): [t.box.as_list() for t in WALKER.truth(i)] for i in range(WALKER.frames)}
    path = tmp_path_factory.mktemp("truth") / "truth.json"
    path.write_text(json.dumps({"frames": frames}))
    return path
