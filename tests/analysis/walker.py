"""The analysis tests' scene, and `vigil` run as a user runs it (a real process)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from app.sources.synthetic import MovingObject, Scene
from tests.conftest import ROOT

# Someone steps out at frame 3 and walks right at a known speed until frame 50.
WALKER = Scene(
    name="walker",
    size=(320, 240),
    fps=15.0,
    frames=75,
    objects=(MovingObject((0, 100), (60.0, 0.0), (30, 44), 210, first_frame=3, last_frame=50),),
)


def vigil(*args: str | Path, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=240,
    )
