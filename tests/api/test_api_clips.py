"""Event clips on a real server and a file camera with known motion: decoded back and checked
against the video's truth; Range requests; deleting events; the activity history; a disk
that refuses clips."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import av
import cv2
import httpx
import numpy as np
import pytest

from tests.api.vigil_livekit import (
    FPS,
    MOTION_LAST,
    Running,
    WsClient,
    add_camera,
    live_settings,
    running_server,
    square_box,
    wait_for,
    write_video,
)

PRE_ROLL_S, POST_ROLL_S = 1.0, 0.5
LOOP = 75
"""Frames in the camera's loop: the square crosses in 6..36, then 2.9 s of still scene."""


def _square_index(picture: np.ndarray) -> int | None:
    """Which frame of the loop ``picture`` shows, from where its square is (None: none)."""
    ys, xs = np.nonzero(cv2.cvtColor(picture, cv2.COLOR_BGR2GRAY) > 200)
    if len(xs) < 400:
        return None
    index = round((int(xs.min()) - 20) / 6) + 6
    truth = square_box(index)
    found = (int(xs.min()), int(ys.min()), int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1)
    assert truth is not None and np.allclose(found, truth, atol=3), (found, truth)
    return index


def decode(data: bytes, path: Path) -> tuple[list[np.ndarray], list[float], float]:
    """Frames, their times (s) and the clip's length as its container says."""
    path.write_bytes(data)
    with av.open(str(path)) as container:
        frames, times = [], []
        for frame in container.decode(video=0):
            frames.append(frame.to_ndarray(format="bgr24"))
            times.append(float(frame.pts * frame.time_base))
        assert container.duration is not None
        return frames, times, container.duration / 1e6


class Recorded:
    """A server whose camera recorded two events; the second, from a still scene, is ``event``."""

    def __init__(self, server: Running, camera_id: int, ws: WsClient, folder: Path) -> None:
        self.server, self.camera_id, self.ws, self.folder = server, camera_id, ws, folder
        self.base = server.base
        ends = ws.wait("motion_end", 45, count=2, camera_id=camera_id)
        self.end = ends[1]
        self.first_end = ends[0]
        url = f"{self.base}/api/events/{self.end['event_id']}"
        self.event: dict[str, Any] = wait_for(
            lambda: (e := httpx.get(url).json())["clip_s"] is not None and e,
            10,
            "the clip to be written",
        )
        self.clip_written_after_s = time.time() - self.end["_received"]
        self.clip = httpx.get(self.base + self.event["clip"]).content


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Recorded]:
    folder = tmp_path_factory.mktemp("clips")
    video = write_video(folder / "door.avi", frames=LOOP)
    settings = live_settings(
        folder / "data", pre_roll_s=PRE_ROLL_S, post_roll_s=POST_ROLL_S, quiet_s=0.5
    )
    with running_server(settings) as server, WsClient(server.ws) as ws:
        camera_id = add_camera(server.base, f"file://{video}", "door", activate=True)
        yield Recorded(server, camera_id, ws, folder)


def test_a_clip_is_written_within_2_s_of_motion_end_and_motion_end_names_it(
    recorded: Recorded,
) -> None:
    end, event = recorded.end, recorded.event
    assert end["clip"] == f"/api/events/{end['event_id']}/clip.mp4" == event["clip"]
    assert recorded.clip_written_after_s < 2.0
    assert end["clip_s"] == pytest.approx(event["clip_s"], abs=1 / FPS)
    assert event["clip_error"] is None and event["clip_bytes"] == len(recorded.clip)
    assert event["snapshot"] is not None
    assert "clip_path" not in event, "the API shows its URL, not where it lies"


def test_the_clip_decodes_to_its_length_at_the_cameras_rate(recorded: Recorded) -> None:
    frames, times, duration = decode(recorded.clip, recorded.folder / "a.mp4")
    clip_s = recorded.event["clip_s"]
    assert abs(len(frames) - clip_s * FPS) <= 1, (len(frames), clip_s)
    assert duration == pytest.approx(clip_s, abs=1 / FPS)
    assert frames[0].shape == (240, 320, 3), "the camera's own size"
    steps = np.diff(times)
    assert np.median(steps) == pytest.approx(1 / FPS, abs=0.01), "the camera's own rate"


def test_the_clip_starts_the_pre_roll_before_the_first_moving_frame(recorded: Recorded) -> None:
    """Its first frame is the one showing ``PRE_ROLL_S`` before the event's, so at most a
    frame period earlier (and a few ms of a loaded machine's timing); what it shows is the
    still scene, and the frame that far into the clip is the event's first."""
    event = recorded.event
    pre_roll = event["started_at"] - event["clip_started_at"]
    assert PRE_ROLL_S <= pre_roll < PRE_ROLL_S + 1 / FPS + 0.02, pre_roll
    frames, times, _ = decode(recorded.clip, recorded.folder / "b.mp4")
    shown = [_square_index(f) for f in frames]
    assert shown[0] is None, "the pre-roll: the scene before the square came"
    first_box = event["boxes"][0]  # Where the detector first saw it, at the event's start.
    first_moving = round((first_box[0] - 20) / 6) + 6
    at_event_start = int(np.argmin(np.abs(np.array(times) - pre_roll)))
    assert shown[at_event_start] is not None
    assert abs(shown[at_event_start] - first_moving) <= 1


def test_the_moving_object_is_in_the_clip_frame_for_frame(recorded: Recorded) -> None:
    """Each frame of the square's crossing, where the video's truth puts it, none lost; then
    the post-roll of still scene."""
    frames, _, _ = decode(recorded.clip, recorded.folder / "c.mp4")
    shown = [_square_index(f) for f in frames]
    seen = [i for i in shown if i is not None]
    assert seen == list(range(seen[0], MOTION_LAST + 1)), seen
    after = len(shown) - 1 - shown.index(MOTION_LAST)
    assert abs(after - POST_ROLL_S * FPS) <= 1, after
    assert all(i is None for i in shown[shown.index(MOTION_LAST) + 1 :])


def test_range_requests_answer_206_with_the_right_bytes(recorded: Recorded) -> None:
    url, whole = recorded.base + recorded.event["clip"], recorded.clip
    size = len(whole)
    plain = httpx.get(url)
    assert plain.status_code == 200 and plain.headers["content-type"] == "video/mp4"
    assert plain.headers["accept-ranges"] == "bytes"
    asked = {
        "bytes=0-99": (0, 99),
        f"bytes={size - 500}-": (size - 500, size - 1),
        "bytes=-300": (size - 300, size - 1),
        f"bytes=1000-{size + 5000}": (1000, size - 1),
    }
    for header, (first, last) in asked.items():
        part = httpx.get(url, headers={"Range": header})
        assert part.status_code == 206, header
        assert part.headers["content-range"] == f"bytes {first}-{last}/{size}"
        assert part.content == whole[first : last + 1]
        assert int(part.headers["content-length"]) == last - first + 1
    refused = httpx.get(url, headers={"Range": f"bytes={size}-"})
    assert refused.status_code == 416 and refused.headers["content-range"] == f"bytes */{size}"
    several = httpx.get(url, headers={"Range": "bytes=0-9,20-29"})
    assert several.status_code == 200 and several.content == whole, "served whole"


def test_activity_has_the_motion_and_the_events_of_each_second(recorded: Recorded) -> None:
    base, camera_id = recorded.base, recorded.camera_id
    event = recorded.event
    since = int(event["started_at"]) - 5
    wait_for(  # Written ten seconds at a time.
        lambda: any(
            s["motion"]
            for s in httpx.get(
                f"{base}/api/cameras/{camera_id}/activity",
                params={"since": since, "until": since + 10, "step": 1},
            ).json()["steps"]
        ),
        15,
        "the event's seconds in the activity history",
    )
    answer = httpx.get(
        f"{base}/api/cameras/{camera_id}/activity",
        params={"since": since, "until": since + 10, "step": 1},
    ).json()
    steps = answer["steps"]
    assert [s["ts"] for s in steps] == list(range(since, since + 10))
    started = int(event["started_at"]) - since
    assert steps[started]["events"] == 1 and steps[started]["motion"] > 0
    ended = int(event["ended_at"]) - since
    moving = [s["motion"] for s in steps[started : ended + 1]]
    # The square: 40x40 px of 320x240; detection's box is a little larger.
    assert all(0.015 < m < 0.05 for m in moving), moving
    whole = httpx.get(
        f"{base}/api/cameras/{camera_id}/activity",
        params={"since": since, "until": since + 10, "step": 10},
    ).json()["steps"]
    assert len(whole) == 1
    assert whole[0]["motion"] == max(s["motion"] for s in steps if s["motion"] is not None)
    assert whole[0]["events"] == sum(s["events"] for s in steps)


@pytest.mark.parametrize(
    ("params", "says"),
    [
        ({"step": 0.5}, "step must be at least 1"),
        ({"since": 100, "until": 100}, "must be before until"),
        ({"since": 0, "until": 10**9, "step": 1}, "at most 10,000"),
        ({"since": "nan"}, "finite"),
        ({"step": "fast"}, "valid number"),
    ],
)
def test_activity_refuses_what_it_cannot_answer(
    recorded: Recorded, params: dict[str, Any], says: str
) -> None:
    answer = httpx.get(f"{recorded.base}/api/cameras/{recorded.camera_id}/activity", params=params)
    assert answer.status_code == 422 and says in answer.text, answer.text
    unknown = httpx.get(f"{recorded.base}/api/cameras/999/activity")
    assert unknown.status_code == 404


def test_deleting_events_takes_their_clips_and_snapshots(recorded: Recorded) -> None:
    base = recorded.base
    services = recorded.server.server.config.app.state.services
    gone, other = recorded.end["event_id"], recorded.first_end["event_id"]
    rows = {e: services.database.event(e) for e in (gone, other)}
    clip_files = {e: services.clips.path(rows[e]["clip_path"]) for e in rows}
    snapshot = httpx.get(f"{base}/api/events/{gone}").json()["snapshot"]
    assert clip_files[gone].is_file() and httpx.get(base + snapshot).status_code == 200

    answer = httpx.delete(f"{base}/api/events/{gone}")
    assert answer.status_code == 200 and answer.json() == {"deleted": [gone], "ongoing": []}
    assert not clip_files[gone].exists()
    assert httpx.get(base + snapshot).status_code == 404
    assert httpx.get(f"{base}/api/events/{gone}/clip.mp4").status_code == 404
    assert httpx.delete(f"{base}/api/events/{gone}").status_code == 404
    recorded.ws.wait("snapshots_deleted", 5)

    going_on = services.database.add_event(recorded.camera_id, time.time(), [], 1.0)
    bulk = httpx.post(f"{base}/api/events/delete", json={"ids": [other, going_on, 10**9]})
    assert bulk.json() == {"deleted": [other], "ongoing": [going_on]}
    assert not clip_files[other].exists()
    assert httpx.delete(f"{base}/api/events/{going_on}").status_code == 409
    assert httpx.post(f"{base}/api/events/delete", json={"ids": ["1"]}).status_code == 422


def test_a_disk_that_refuses_clips_costs_them_not_the_events(serve: Any, tmp_path: Path) -> None:
    server = serve(tmp_path / "data", pre_roll_s=PRE_ROLL_S, post_roll_s=POST_ROLL_S)
    video = write_video(tmp_path / "door.avi", frames=LOOP)
    camera_id = add_camera(server.base, f"file://{video}", "door")
    blocker = tmp_path / "data" / "clips" / str(camera_id)  # mkdir fails, even for root.
    blocker.write_bytes(b"")
    with WsClient(server.ws) as ws:
        httpx.post(f"{server.base}/api/cameras/{camera_id}/activate").raise_for_status()
        end = ws.wait("motion_end", 30, camera_id=camera_id)[0]
        assert end["clip"] is None and end["clip_s"] is None
        event = httpx.get(f"{server.base}/api/events/{end['event_id']}").json()
        assert event["clip"] is None and event["clip_error"].startswith("cannot write")
        assert event["snapshot"] is not None, "the event and its pictures stand"
        failing = ws.wait("status", 5, camera_id=camera_id, storage_error=event["clip_error"])
        assert failing
        health = httpx.get(f"{server.base}/api/health").json()
        assert health["storage"]["error"] == event["clip_error"]
        clip = httpx.get(f"{server.base}/api/events/{end['event_id']}/clip.mp4")
        assert clip.status_code == 404 and "cannot write" in clip.json()["detail"]

        blocker.unlink()
        ws.wait("status", 20, camera_id=camera_id, storage_error=None)
        recovered = ws.wait("motion_end", 20, count=2, camera_id=camera_id)[1]
        assert recovered["clip"] is not None
