"""The scene sweep (bench/scenes.py): it scores per object per frame, counts tracks and
events, and compares with its baseline down to the digests, whatever the process count.
The sweep itself is a benchmark, not a test."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from app.sources.synthetic import MovingObject, Scene
from app.vision.detections import Box, Detection
from app.vision.pipeline import FrameResult

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import scenes


def _result(index: int, detections: list[Detection]) -> FrameResult:
    mask = np.zeros((4, 4), np.uint8)
    return FrameResult(index, index / 2.0, detections, mask, mask, mask, None, 10.0, False, 1.0)


def test_the_sweep_counts_per_object_per_frame_tracks_and_events():
    # 2 fps, one object from frame 0 to 19: found in frames 0-9 as track 1, missed in
    # 10-14, and in 15-19 track 2 reports a box beside it (a false alarm and a miss).
    scene = Scene(
        "counted", fps=2.0, frames=20, objects=(MovingObject((50, 50), (0.0, 0.0), (20, 20), 200),)
    )
    tally = scenes.Tally(scene, "test", "none")
    truth = scene.truth(0)[0].box
    beside = Box(truth.x + 40, truth.y, truth.w, truth.h)
    for index in range(20):
        if index < 10:
            found = [Detection(truth, truth.center, truth.area, track_id=1)]
        elif index < 15:
            found = []
        else:
            found = [Detection(beside, beside.center, beside.area, track_id=2)]
        tally.add(_result(index, found))
    outcome = tally.finish("input")
    assert (outcome.tp, outcome.fp, outcome.fn) == (10, 5, 10)
    assert (outcome.tracks, outcome.events, outcome.objects) == (2, 2, 1)
    assert outcome.counts.detection_rate == 0.5
    assert outcome.counts.false_alarm_rate == pytest.approx(1 / 3)


def test_the_sweep_compares_with_its_baseline_down_to_the_digests(tmp_path, capsys):
    # The smallest scene of the sweep, end to end: written as the baseline in one process,
    # then compared in two (spawned), with the same digests.
    baseline = tmp_path / "baseline.json"
    common = ["--scenes", "box-on-plain-wall", "--method", "adaptive", "--baseline", str(baseline)]
    assert scenes.main([*common, "--write-baseline"]) == 0
    assert scenes.main([*common, "--jobs", "2", "--check"]) == 0
    assert "identical (1 scene runs, counts and digests)" in capsys.readouterr().out

    (outcome,) = scenes.run_scene(scenes.sweep()["box-on-plain-wall"], ["adaptive"])
    stored = scenes.load_baseline(baseline)
    assert stored["adaptive"]["box-on-plain-wall"] == outcome.record()
    assert outcome.tp + outcome.fn == sum(
        len(SCENE.truth(i))
        for SCENE in [scenes.sweep()["box-on-plain-wall"].scene]
        for i in range(30)
    )

    stored["adaptive"]["box-on-plain-wall"]["masks"] = "0" * 40
    changes = scenes.compare([outcome], stored)
    assert [c.what for c in changes] == [["masks"]]
    assert scenes.verdict([outcome], changes).startswith(
        "1 scenes changed (of 1 compared); 1 of them in digests only"
    )
    stored["adaptive"]["box-on-plain-wall"]["tp"] = outcome.tp - 1
    (change,) = scenes.compare([outcome], stored)
    assert change.what == ["tp", "masks"]
    assert scenes.change_rows([change])[0][4] == f"{outcome.tracks} -> {outcome.tracks}"
