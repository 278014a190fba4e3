"""Uploads run in a child process: progress relayed, a crash reported, the server unharmed."""

from __future__ import annotations

import asyncio
import json
import sys
from pathlib import Path
from typing import Any

from app.storage import Database
from app.workers.analysis import AnalysisManager
from app.workers.bus import EventBus
from tests.api.vigil_livekit import wait_for, write_video
from tests.sources.damaged_video import garble_frames


class CrashingManager(AnalysisManager):
    """Its child dies the way a decoder with heap corruption does: SIGABRT, no message."""

    def command(self, input_path: Path, out_dir: Path, options: dict[str, Any]) -> list[str]:
        return [
            sys.executable,
            "-c",
            "import os, sys; sys.stderr.write('free(): invalid pointer\\n');"
            " sys.stderr.flush(); os.abort()",
        ]


def _run(manager: AnalysisManager, db: Database, folder: Path, video: Path) -> list[dict]:
    messages: list[dict] = []

    async def follow() -> None:
        queue = manager.bus.subscribe()
        db.add_analysis("a1", video.name, {"min_area": 50})
        (folder / "a1").mkdir(parents=True)
        (folder / "a1" / "input.avi").write_bytes(video.read_bytes())
        manager.submit("a1")
        while True:
            message = await asyncio.wait_for(queue.get(), 60)
            assert message is not None
            messages.append(message)
            if message.get("status") in ("done", "failed"):
                return

    manager.start()
    try:
        asyncio.run(follow())
    finally:
        manager.stop()
    return messages


def test_analysis_in_child_process(tmp_path: Path) -> None:
    db = Database(tmp_path / "v.db")
    manager = AnalysisManager(db, EventBus(), tmp_path / "analyses")
    messages = _run(manager, db, tmp_path / "analyses", write_video(tmp_path / "v.avi", 60))
    assert messages[-1]["status"] == "done"
    progress = [m["progress"] for m in messages if m["type"] == "progress"]
    assert progress[0] == 0.0 and progress[-1] == 1.0 and progress == sorted(progress)
    row = db.analysis("a1")
    assert row is not None and row["status"] == "done" and row["progress"] == 1.0
    out = tmp_path / "analyses" / "a1" / "out"
    assert (out / "tracks.csv").is_file() and (out / "annotated.avi").is_file()
    assert (out / "live.jpg").is_file()


def test_an_upload_with_a_damaged_frame_is_analysed_and_the_warning_reaches_its_status(
    tmp_path: Path,
) -> None:
    db = Database(tmp_path / "v.db")
    manager = AnalysisManager(db, EventBus(), tmp_path / "analyses")
    damaged = garble_frames(write_video(tmp_path / "v.avi", 60), [12], tmp_path / "damaged.avi")
    messages = _run(manager, db, tmp_path / "analyses", damaged)
    final = messages[-1]
    assert final["status"] == "done" and final["error"] is None
    (warning,) = final["warnings"]
    assert warning.startswith("1 frame did not decode and was skipped: frame 12")
    report = json.loads((tmp_path / "analyses" / "a1" / "out" / "report.json").read_text())
    assert report["warnings"] == [warning]  # What GET /api/analyses/{id} shows as its report.
    assert report["frames"] == 59 and report["skipped_frames"] == [12]
    assert report["frames_read"] == report["header_frames"] == 60


def test_crashing_child_fails_with_reason(tmp_path: Path) -> None:
    db = Database(tmp_path / "v.db")
    manager = CrashingManager(db, EventBus(), tmp_path / "analyses")
    messages = _run(manager, db, tmp_path / "analyses", write_video(tmp_path / "v.avi", 5))
    assert messages[-1]["status"] == "failed"
    row = db.analysis("a1")
    assert row is not None and row["status"] == "failed"
    assert "crashed" in row["error"] and "invalid pointer" in row["error"]
    wait_for(lambda: not manager._children, 5, "the child to be reaped")
