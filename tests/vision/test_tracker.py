import math
import random

import pytest

from app.vision.detections import Box, Detection
from app.vision.tracker import SMALL_ASSIGNMENT, Tracker, TrackerConfig

FPS = 10.0


def det(x, y, w=20, h=20):
    return Detection(Box(round(x), round(y), w, h), (x + w / 2, y + h / 2), float(w * h))


def run(tracker, frames):
    return [tracker.update(dets, i / FPS) for i, dets in enumerate(frames)]


def test_ids_persist_and_speed_is_distance_times_frame_rate():
    tracker = Tracker()
    frames = [[det(10 + 3 * i, 50)] for i in range(20)]  # 3 px per frame at 10 fps = 30 px/s
    out = run(tracker, frames)
    assert out[0] == []  # not yet confirmed: one sighting could be a flicker
    ids = {d.track_id for frame in out[1:] for d in frame}
    assert ids == {1}
    last = out[-1][0]
    assert last.distance_px == pytest.approx(3.0)
    assert last.speed_px_s == pytest.approx(30.0, rel=0.01)


def streak(x, y):
    """A raindrop's streak: as long as its fall while the shutter is open, 6 x 24 px."""
    return det(x, y, 6, 24)


def test_what_jumps_past_its_own_length_each_frame_is_not_reported():
    # Drops falling 34 px a frame at 25 fps (850 px/s), each box left behind by the
    # next, beside a walker 8 px a frame.
    tracker = Tracker()
    frames = [
        [streak(100, 10 + 34 * i), streak(300, 40 + 34 * i), det(20 + 8 * i, 200, 30, 70)]
        for i in range(12)
    ]
    out = [tracker.update(dets, i / 25.0) for i, dets in enumerate(frames)]
    assert {d.track_id for frame in out for d in frame} == {1}
    assert all(d.box.w == 30 for frame in out for d in frame)


def test_a_fast_object_is_reported_where_frames_are_too_far_apart_to_tell():
    # A motorbike 40 px long at 10 fps, 42 px a frame: it does not overlap itself.
    tracker = Tracker()
    out = [tracker.update([det(42 * i, 50, 40, 30)], i / 10.0) for i in range(6)]
    assert [d.track_id for frame in out[1:] for d in frame] == [1] * 5


@pytest.mark.parametrize("objects", [3, 12])
def test_a_crowd_keeps_its_ids_and_speeds(objects):
    """A few objects (each pairing checked one by one) and a crowd (past
    SMALL_ASSIGNMENT pairs, checked all at once) keep their ids and speeds."""
    assert 3 * 3 <= SMALL_ASSIGNMENT < 12 * 12
    tracker = Tracker()
    # Rows 60 px apart; each object moves 2 px/frame right and 1, 2 or 3 px/frame down.
    drops = [1 + row % 3 for row in range(objects)]
    frames = [
        [det(10 + 2 * i, 60 * row + drops[row] * i) for row in range(objects)] for i in range(15)
    ]
    out = run(tracker, frames)
    assert [len(frame) for frame in out[1:]] == [objects] * 14
    row_of = {d.track_id: round(d.box.y / 60) for d in out[1]}
    assert sorted(row_of.values()) == list(range(objects))
    for frame in out[2:]:
        for d in frame:
            step = math.hypot(2, drops[row_of[d.track_id]])
            assert d.distance_px == pytest.approx(step, abs=0.6)  # Boxes snap to pixels.
    for d in out[-1]:
        step = math.hypot(2, drops[row_of[d.track_id]])
        assert d.speed_px_s == pytest.approx(step * FPS, rel=0.01)


def test_both_gate_checks_allow_the_same_pairs():
    """The plain and the vectorised check agree, pairs at the gate's edge included."""
    rng = random.Random(7)
    tracker = Tracker()
    for _ in range(200):
        tracker.update([det(rng.uniform(0, 300), rng.uniform(0, 200)) for _ in range(6)], 0.0)
    tracks = list(tracker.tracks.values())
    predictions = [track.predict(0.1) for track in tracks]
    detections = [det(rng.uniform(0, 300), rng.uniform(0, 200)) for _ in range(30)]
    # Detections on a track's gate (25 px + 20 px x (0.5 + 0.25 x missed) away), and just
    # inside it (all at one time: frames count as at 25 fps).
    x, y = predictions[0]
    gate = TrackerConfig().gate_px + 20 * (0.5 + 0.25 * tracks[0].missed)
    for reach in (gate, gate - 1e-6):
        detections.append(
            Detection(Box(round(x + reach) - 10, round(y) - 10, 20, 20), (x + reach, y), 400.0)
        )
    plain = tracker._allowed_pairs(detections, tracks, predictions)
    vectorised = tracker._allowed_pairs_vectorised(detections, tracks, predictions)
    assert [(d, t) for d, t, _ in plain] == [(d, t) for d, t, _ in vectorised]
    assert [c for _, _, c in plain] == pytest.approx([c for _, _, c in vectorised])
    assert (len(detections) - 1, 0) in {(d, t) for d, t, _ in plain}  # Just inside.


def test_two_objects_crossing_keep_their_ids():
    tracker = Tracker()
    frames = []
    for i in range(30):
        a, b = det(10 + 4 * i, 50), det(130 - 4 * i, 50)
        if abs(a.box.x - b.box.x) < 20:  # they overlap: the detector sees one merged blob
            x0 = min(a.box.x, b.box.x)
            merged_w = max(a.box.x, b.box.x) + 20 - x0
            frames.append(
                [Detection(Box(x0, 50, merged_w, 20), (x0 + merged_w / 2, 60), 20.0 * merged_w)]
            )
        else:
            frames.append([a, b])
    out = run(tracker, frames)
    before = {d.track_id: d.centroid[0] for d in out[5]}
    after = {d.track_id: d.centroid[0] for d in out[-1]}
    left_id = min(before, key=before.get)
    assert set(before) == set(after) == {1, 2}
    assert after[left_id] > after[3 - left_id]  # the one that started left ended right
    assert all(len(frame) == 2 for frame in out[2:])  # both reported through the crossing
    # Each gets its share of the merged blob's pixels, which its piece of the box holds.
    assert all(d.area <= d.box.area for frame in out for d in frame)


def test_an_object_split_in_two_for_a_while_is_one_object_again_when_it_joins_up():
    tracker = Tracker()
    frames = []
    for i in range(30):
        x = 10 + 4 * i  # 40 px/s
        if i < 10:  # Its middle matches the background: two pieces, moving as one.
            frames.append([det(x, 50, 18, 20), det(x + 22, 50, 18, 20)])
        else:
            frames.append([det(x, 50, 40, 20)])
    out = run(tracker, frames)
    assert all(len(frame) == 2 for frame in out[2:10])
    for frame in out[12:]:  # Not two pieces coasting on, cut smaller each frame.
        assert len(frame) == 1
        assert (frame[0].box.w, frame[0].box.h) == (40, 20)
    assert out[-1][0].speed_px_s == pytest.approx(40.0, abs=2.0)


def test_an_object_that_breaks_into_pieces_stays_one_track_with_one_box():
    tracker = Tracker()
    frames = []
    for i in range(30):
        x = 10 + 3 * i
        if 10 <= i < 20:  # Its middle matches the background: head and legs apart.
            frames.append([det(x, 40, 20, 18), det(x, 72, 20, 18)])
        else:
            frames.append([det(x, 40, 20, 50)])
    out = run(tracker, frames)
    for i, frame in enumerate(out[1:], start=1):
        assert [d.track_id for d in frame] == [1]
        assert frame[0].box == Box(10 + 3 * i, 40, 20, 50)
    assert out[-1][0].speed_px_s == pytest.approx(30.0, rel=0.01)


def test_an_object_that_comes_into_view_beside_a_tracked_one_has_its_own_track():
    tracker = Tracker()
    frames = [
        [det(10 + 3 * i, 40, 20, 50)] + ([det(36 + 3 * i, 40, 20, 50)] if i >= 10 else [])
        for i in range(20)
    ]
    out = run(tracker, frames)
    assert [d.track_id for d in out[-1]] == [1, 2]
    assert [d.box.w for d in out[-1]] == [20, 20]


def test_a_cyclist_following_a_lorry_into_view_is_not_taken_for_a_piece_of_it():
    tracker = Tracker()
    frames = [
        [det(10 + 3 * i, 100, 160, 80)] + ([det(3 * i - 20, 130, 20, 40)] if i >= 5 else [])
        for i in range(20)
    ]
    out = run(tracker, frames)
    assert [(d.track_id, d.box.w) for d in out[-1]] == [(1, 160), (2, 20)]


@pytest.mark.parametrize("lorry_first", [True, False])
def test_a_piece_joins_its_own_object_whichever_blob_comes_first(lorry_first):
    """A walker splits beside a lorry: its legs are its own, not the lorry's."""
    tracker = Tracker()
    frames = []
    for i in range(24):
        lorry = det(10 + 3 * i, 100, 160, 80)
        x = 174 + 3 * i
        walker = (
            [det(x, 110, 20, 18), det(x, 142, 20, 18)] if 10 <= i < 16 else [det(x, 110, 20, 50)]
        )
        frames.append([lorry, *walker] if lorry_first else [*walker, lorry])
    out = run(tracker, frames)
    for frame in out[10:16]:
        assert sorted((d.box.w, d.box.h) for d in frame) == [(20, 50), (160, 80)]


def test_object_hidden_for_a_few_frames_keeps_its_id():
    tracker = Tracker()
    frames = [[det(10 + 5 * i, 30)] if not 10 <= i < 14 else [] for i in range(25)]
    out = run(tracker, frames)
    assert {d.track_id for frame in out for d in frame} == {1}


@pytest.mark.parametrize("fps", [25.0, 60.0])
def test_someone_hidden_by_a_post_for_a_fifth_of_a_second_keeps_the_id(fps):
    # Walking 100 px/s behind a post: 5 frames unseen at 25 fps, 12 at 60.
    tracker = Tracker()
    hidden = (1.0, 1.2)
    out = [
        tracker.update(
            [] if hidden[0] <= i / fps < hidden[1] else [det(100 * i / fps, 50)], i / fps
        )
        for i in range(round(2 * fps))
    ]
    assert {d.track_id for frame in out for d in frame} == {1}


@pytest.mark.parametrize("start", range(2, 40, 7))
def test_hidden_for_as_long_as_8_frames_at_25_fps_keeps_the_id_at_50(start):
    # 16 frames at 50 fps, however far into the clip (the times' rounding aside).
    tracker = Tracker()
    for i in range(start):
        tracker.update([det(100, 50)], i / 50)
    for i in range(start, start + 16):
        tracker.update([], i / 50)
    (back,) = tracker.update([det(100, 50)], (start + 16) / 50)
    assert back.track_id == 1


def test_a_jittery_25_fps_camera_counts_frames_and_frozen_times_drop_tracks():
    tracker = Tracker()
    rng = random.Random(1)
    time_s = 0.0
    for _ in range(50):
        time_s += 0.04 + rng.gauss(0.0, 0.005)
        tracker.update([det(100, 50)], time_s)
    assert tracker.frames_per_reference() == 1.0
    for _ in range(9):  # A source that repeats one time: tracks still end, by frames.
        tracker.update([], time_s)
    assert not tracker.tracks


def test_object_gone_too_long_gets_a_new_id():
    tracker = Tracker(TrackerConfig(max_missed=3))
    frames = [[det(50, 50)]] * 5 + [[]] * 6 + [[det(50, 50)]] * 3
    out = run(tracker, frames)
    assert out[-1][0].track_id == 2


def test_objects_entering_and_leaving():
    tracker = Tracker()
    frames = []
    for i in range(40):
        dets = [det(5 * i, 10)] if i < 25 else []
        if i >= 15:
            dets.append(det(200 - 4 * (i - 15), 100))
        frames.append(dets)
    out = run(tracker, frames)
    assert {d.track_id for d in out[20]} == {1, 2}
    assert {d.track_id for d in out[-1]} == {2}


def test_velocity_is_smoothed_against_centroid_jitter():
    tracker = Tracker()
    jitter = [0, 2, -2, 1, -1, 2, -2, 0, 1, -1] * 3
    out = run(tracker, [[det(10 + 4 * i + jitter[i], 40)] for i in range(30)])
    speeds = [frame[0].speed_px_s for frame in out[8:]]
    assert max(abs(s - 40.0) for s in speeds) < 6.0
    raw = [frame[0].distance_px * FPS for frame in out[8:]]
    assert max(abs(r - 40.0) for r in raw) > 15.0  # the unsmoothed step is far noisier


def test_distance_is_euclidean():
    tracker = Tracker()
    out = run(tracker, [[det(10 + 3 * i, 10 + 4 * i)] for i in range(5)])
    assert out[-1][0].distance_px == pytest.approx(math.hypot(3, 4))
