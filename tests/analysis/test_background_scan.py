"""Offline mode looks ahead: objects already in view at the first frame are motion, not
background that leaves a ghost behind."""

from __future__ import annotations

import json
from dataclasses import replace

import cv2
import pytest

from app.analysis import runner
from app.analysis.metrics import ObjectCounts
from app.analysis.runner import scan_background
from app.sources.synthetic import Scene, in_view_scenes
from app.vision.pipeline import Pipeline, PipelineConfig
from app.vision.scene_background import LEAST_SAMPLES
from tests.analysis.walker import vigil
from tests.conftest import write_scene_video

IN_VIEW = in_view_scenes()


def counts(scene: Scene, scan: bool) -> ObjectCounts:
    frames = list(scene.frames_iter())
    pipeline = Pipeline(fps=scene.fps)
    if scan:
        assert scan_background(pipeline, frames, scene.fps).scene is not None
    found = ObjectCounts()
    for index, frame in enumerate(frames):
        result = pipeline.process(frame)
        found.add([t.box for t in scene.truth(index)], [d.box for d in result.detections])
    return found


@pytest.mark.parametrize("name", sorted(IN_VIEW))
def test_objects_in_view_at_the_first_frame_are_found_without_ghosts(name):
    scene = IN_VIEW[name]
    scanned = counts(scene, scan=True)
    assert scanned.detection_rate >= 0.95 and scanned.false_alarm_rate <= 0.03, scanned
    # Learning the first frame as the scene, as a live camera must, does worse.
    first_frame = counts(scene, scan=False)
    assert first_frame.tp <= scanned.tp and first_frame.fp >= scanned.fp, first_frame


def test_learning_the_first_frame_misses_and_sees_ghosts_in_such_scenes():
    # The fault the scan mends, pooled over the scenes.
    pooled = ObjectCounts()
    for scene in IN_VIEW.values():
        found = counts(scene, scan=False)
        pooled.tp, pooled.fp, pooled.fn = (
            pooled.tp + found.tp,
            pooled.fp + found.fp,
            pooled.fn + found.fn,
        )
    assert pooled.false_alarm_rate >= 0.2 and pooled.detection_rate <= 0.9, pooled


def test_a_scan_of_too_few_frames_leaves_the_start_to_the_model():
    scene = IN_VIEW["two-ways-in-view"]
    frames = list(scene.frames_iter())[:6]
    pipeline = Pipeline(fps=scene.fps)
    scan = scan_background(pipeline, frames, scene.fps)
    assert (scan.frames, scan.samples, scan.scene) == (6, 6, None)
    # Learned, as without a scan: started from a scene, the two objects would be motion
    # (a first frame's detections would not tell: a track is reported from its second).
    assert cv2.countNonZero(pipeline.process(frames[0]).mask) == 0


def test_a_method_that_cannot_start_from_a_scene_is_not_scanned_for(tmp_path):
    video = write_scene_video(IN_VIEW["two-ways-in-view"], tmp_path / "two-ways.avi")
    run = vigil("analyze", video, "--out", tmp_path / "out", "--method", "knn", "--quiet")
    assert run.returncode == 0, run.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["background_scan"] is None
    assert report["settings"]["background_scan"] is False


def test_vigil_analyze_scans_first_and_reports_it(tmp_path):
    # A dark, uniform car drives off its first-frame spot: where it passes over its own
    # first picture, a model that learned frame 0 sees nothing.
    scene = IN_VIEW["dark-car-in-view"]
    video = write_scene_video(scene, tmp_path / "dark-car.avi")
    truth = tmp_path / "truth.json"
    boxes = {str(i): [t.box.as_list() for t in scene.truth(i)] for i in range(scene.frames)}
    truth.write_text(json.dumps({"frames": boxes}))

    def analyse(out: str, *options: str) -> dict:
        run = vigil(
            "analyze", video, "--out", tmp_path / out, "--truth", truth, "--quiet", *options
        )
        assert run.returncode == 0, run.stderr
        return json.loads((tmp_path / out / "report.json").read_text())

    report = analyse("scanned")
    scan = report["background_scan"]
    assert scan["used"] and not scan["view_changed"]
    assert scan["frames"] == scene.frames and 32 <= scan["samples"] < 64
    assert report["settings"]["background_scan"] is True
    objects = report["evaluation"]["objects"]
    assert objects["detection_rate"] >= 0.95 and objects["false_alarm_rate"] <= 0.03
    [track] = report["tracks"]  # One car, one track, at its true speed.
    assert track["mean_speed_px_s"] == pytest.approx(15.0, rel=0.05)

    plain = analyse("plain", "--no-background-scan")
    assert plain["background_scan"] is None
    assert plain["settings"]["background_scan"] is False
    assert plain["evaluation"]["objects"]["false_alarm_rate"] >= 0.1


def test_the_scan_keeps_what_fits_its_memory_of_large_frames(monkeypatch):
    # Frames detected at full size: 640x480 here, as 4K would be against the real budget.
    scene = replace(IN_VIEW["box-in-view"], size=(640, 480))
    monkeypatch.setattr(runner, "BACKGROUND_SCAN_BYTES", 4 * 2**20)
    pipeline = Pipeline(PipelineConfig(detect_width=0), fps=scene.fps)
    scan = scan_background(pipeline, scene.frames_iter(), scene.fps)
    assert scan.frames == scene.frames
    assert LEAST_SAMPLES <= scan.samples < 2 * LEAST_SAMPLES  # 10 fit at least, 6 by size.
    assert scan.scene is not None
