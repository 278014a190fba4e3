"""A camera's recorder on real frames, a real database and real clips: what each clip holds."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import av
import cv2
import numpy as np
import pytest

from app.recording.recorder import Recorder
from app.sources.frames import DecodedFrame, JpegFrame
from app.storage import Database
from tests.api.vigil_livekit import FPS, frame_at, live_settings, wait_for

JPEGS = [cv2.imencode(".jpg", frame_at(i))[1].tobytes() for i in range(45)]


def _parts(tmp_path: Path, **settings: Any) -> tuple[Recorder, Database]:
    values = {"pre_roll_s": 1.0, "post_roll_s": 0.5, **settings}
    config = live_settings(tmp_path / "data", **values)
    db = Database(config.db_path)
    return Recorder(1, config, db), db


def _times(clip: Path) -> list[float]:
    with av.open(str(clip)) as container:
        return [float(f.pts * f.time_base) for f in container.decode(video=0)]


def _finished(db: Database, event_id: int) -> dict[str, Any]:
    return wait_for(
        lambda: (e := db.event(event_id)) is not None and e["clip_s"] is not None and e,
        15,
        f"event {event_id}'s clip to be written",
    )


def _feed(recorder: Recorder, frames: range, moving: range, t0: float = 1000.0) -> None:
    for i in frames:
        at = t0 + i / FPS
        recorder.feed(JpegFrame(JPEGS[i % 45]), i in moving, at, at + 5e8)


def test_a_clip_runs_from_the_pre_roll_to_the_post_roll(tmp_path: Path) -> None:
    recorder, db = _parts(tmp_path)
    event = db.add_event(1, 0.0, [], 1.0)
    _feed(recorder, range(30), range(0))
    recorder.start(event, 1000.0 + 30 / FPS, 5e8 + 1000.0 + 30 / FPS, FPS)
    _feed(recorder, range(30, 51), range(30, 51))  # Moving: frames 30 to 50.
    _feed(recorder, range(51, 58), range(0))  # The post-roll, 0.5 s.
    clip, clip_s = recorder.end(event, 1000.0 + 58 / FPS)  # Quiet long enough at 58.
    assert clip == f"/api/events/{event}/clip.mp4"
    _feed(recorder, range(58, 70), range(0))  # Past the post-roll: not in the clip.
    row = _finished(db, event)
    assert row["clip_error"] is None
    times = _times(Path(tmp_path / "data" / "clips" / row["clip_path"]))
    expected = [(i - 15) / FPS for i in range(15, 58)]  # A second before frame 30 to 57.
    assert np.allclose(times, expected, atol=1e-3)
    assert clip_s == row["clip_s"] == pytest.approx(43 / FPS, abs=1e-3)
    assert row["clip_started_at"] == pytest.approx(5e8 + 1000.0 + 15 / FPS)
    assert db.clip_bytes() == row["clip_bytes"] > 0


def test_an_event_that_moves_again_in_its_quiet_seconds_keeps_them(tmp_path: Path) -> None:
    recorder, db = _parts(tmp_path, pre_roll_s=0.0)
    event = db.add_event(1, 0.0, [], 1.0)
    recorder.start(event, 1000.0, 0.0, FPS)
    moving = [*range(0, 10), *range(30, 40)]  # Quiet for 20 frames between: held, then kept.
    for i in range(50):
        at = 1000.0 + i / FPS
        recorder.feed(JpegFrame(JPEGS[i % 45]), i in moving, at, at)
    recorder.end(event, 1000.0 + 50 / FPS)
    recorder.stop()
    row = _finished(db, event)
    times = _times(tmp_path / "data" / "clips" / row["clip_path"])
    assert np.allclose(times, [i / FPS for i in range(47)], atol=1e-3), "no gap, 0.5 s after"


def test_the_next_event_in_a_clips_post_roll_does_not_keep_it_open(tmp_path: Path) -> None:
    # Something crosses every 1.2 s (a looped video, a busy lane): each event ends, and the
    # next starts within the last one's post-roll. Its motion belonged to the new event,
    # whose clip has it: the ended one still ends at its post-roll (it took the new
    # event's motion as its own, and was never written).
    recorder, db = _parts(tmp_path, pre_roll_s=0.0)
    first, second = db.add_event(1, 0.0, [], 1.0), db.add_event(1, 1.0, [], 1.0)
    recorder.start(first, 1000.0, 0.0, FPS)
    _feed(recorder, range(0, 10), range(0, 10))
    _feed(recorder, range(10, 14), range(0))
    recorder.end(first, 1000.0 + 14 / FPS)  # Quiet for a few frames: over.
    _feed(recorder, range(14, 18), range(0))
    recorder.start(second, 1000.0 + 18 / FPS, 18 / FPS, FPS)  # Within the post-roll.
    _feed(recorder, range(18, 40), range(18, 40))
    row = _finished(db, first)
    times = _times(tmp_path / "data" / "clips" / row["clip_path"])
    last = 9 + int(0.5 * FPS)  # The post-roll: 0.5 s after the last moving frame, 9.
    assert np.allclose(times, [i / FPS for i in range(last + 1)], atol=1e-3)


def test_stop_ends_the_clip_with_what_it_has(tmp_path: Path) -> None:
    recorder, db = _parts(tmp_path)
    event = db.add_event(1, 0.0, [], 1.0)
    _feed(recorder, range(20), range(0))
    recorder.start(event, 1000.0 + 20 / FPS, 0.0, FPS)
    _feed(recorder, range(20, 26), range(20, 26))
    recorder.stop()
    clip, clip_s = recorder.end(event, 1000.0 + 26 / FPS)
    assert recorder.wait(10)
    row = _finished(db, event)
    assert clip is not None and clip_s == pytest.approx(21 / FPS, abs=1e-3) == row["clip_s"]
    assert len(recorder.preroll) == 0, "the pre-roll goes with detection"


def test_decoded_frames_are_recorded_too(tmp_path: Path) -> None:
    recorder, db = _parts(tmp_path, pre_roll_s=0.5)
    event = db.add_event(1, 0.0, [], 1.0)
    for i in range(20):
        if i == 10:
            recorder.start(event, 1000.0 + i / FPS, 0.0, FPS)
        recorder.feed(DecodedFrame(frame_at(i)), i >= 10, 1000.0 + i / FPS, 0.0)
    recorder.stop()
    row = _finished(db, event)
    # From frame 2, which was showing 0.5 s before frame 10 (0.53 s before it): 8 frames.
    assert len(_times(tmp_path / "data" / "clips" / row["clip_path"])) == 8 + 10
    assert recorder.preroll.nbytes == 0


def test_a_slow_encoder_costs_the_clip_frames_and_says_so(tmp_path: Path) -> None:
    """Frames fed far faster than they encode, with room for a few: the rest are left out."""
    recorder, db = _parts(tmp_path, pre_roll_s=0.0, pre_roll_mb=0.02)
    event = db.add_event(1, 0.0, [], 1.0)
    recorder.start(event, 1000.0, 0.0, FPS)
    _feed(recorder, range(300), range(300))
    recorder.stop()
    row = _finished(db, event)
    assert "frames left out" in row["clip_error"]
    dropped = int(row["clip_error"].split()[0])
    assert 0 < dropped < 300
    assert len(_times(tmp_path / "data" / "clips" / row["clip_path"])) == 300 - dropped


def test_a_refused_clip_costs_the_clip_not_the_event_until_the_disk_is_back(
    tmp_path: Path,
) -> None:
    recorder, db = _parts(tmp_path)
    blocker = recorder.store.root / "1"  # A file where the camera's folder goes.
    blocker.write_bytes(b"")
    event = db.add_event(1, 0.0, [], 1.0)
    _feed(recorder, range(10), range(0))
    recorder.start(event, 1000.0 + 10 / FPS, 0.0, FPS)
    _feed(recorder, range(10, 20), range(10, 20))
    assert recorder.end(event, 1000.0 + 20 / FPS) == (None, None)
    row = db.event(event)
    assert row is not None and row["clip_path"] is None and row["clip_error"]
    assert recorder.failure() == row["clip_error"], "the camera's storage error"

    blocker.unlink()
    again = db.add_event(1, 10.0, [], 1.0)
    recorder.start(again, 1000.0 + 20 / FPS, 0.0, FPS)
    _feed(recorder, range(20, 30), range(20, 30))
    recorder.stop()
    assert _finished(db, again)["clip_error"] is None
    assert recorder.failure() is None


def test_a_clip_of_an_event_deleted_meanwhile_goes_too(tmp_path: Path) -> None:
    recorder, db = _parts(tmp_path)
    event = db.add_event(1, 0.0, [], 1.0)
    recorder.start(event, 1000.0, 0.0, FPS)
    _feed(recorder, range(10), range(10))
    relative = db.event(event)["clip_path"]  # type: ignore[index]
    db.end_event(event, 1.0, 1.0)
    with db._tx() as conn:  # As a DELETE would, had it not waited for the clip.
        conn.execute("DELETE FROM events WHERE id = ?", (event,))
    recorder.stop()
    assert recorder.wait(10)
    assert not (recorder.store.root / relative).exists()
