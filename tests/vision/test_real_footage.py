"""Quality on real footage with ground truth (../shared/data); skipped when it is absent."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from app.analysis.scoring import Scorer
from app.analysis.truth import load_truth
from app.sources.files import open_input
from app.vision.pipeline import Pipeline, PipelineConfig
from tests.conftest import ROOT

# (input, truth) inside ../shared/data
SEQUENCES = {
    "traffic": ("cdnet-traffic/input", "cdnet-traffic"),
    "fall": ("cdnet-fall/input", "cdnet-fall"),
    "wallflower": (
        "wallflower-waving-trees/input",
        "wallflower-waving-trees/hand_segmented_00247.png",
    ),
}


def f_measure(data: Path, sequence: str, method: str) -> float:
    input_rel, truth_rel = SEQUENCES[sequence]
    source = open_input(data / input_rel)
    truth = load_truth(data / truth_rel, source.frame_numbers)
    pipeline = Pipeline(PipelineConfig(method=method), fps=source.fps)
    scorer = Scorer(truth, 100.0, source.size)
    for frame in source.frames():
        result = pipeline.process(frame)
        scorer.add(result.index, [d.box for d in result.detections], result.mask)
    pixels = scorer.pixels_warm if sequence != "wallflower" else scorer.pixels
    return pixels.f_measure


@pytest.mark.shared_data
@pytest.mark.parametrize("sequence", sorted(SEQUENCES))
def test_default_method_beats_mog2_on_real_footage(shared_data, sequence):
    ours = f_measure(shared_data, sequence, "adaptive")
    mog2 = f_measure(shared_data, sequence, "mog2")
    assert ours > mog2, f"{sequence}: adaptive F={ours:.3f}, MOG2 F={mog2:.3f}"


@pytest.mark.shared_data
def test_analyze_on_cdnet_traffic_video_reports_pixel_scores(shared_data, tmp_path):
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "app",
            "analyze",
            str(shared_data / "cdnet-traffic" / "traffic.avi"),
            "--out",
            str(tmp_path),
            "--truth",
            str(shared_data / "cdnet-traffic"),
            "--quiet",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=240,
    )
    assert result.returncode == 0, result.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["frames"] == 101
    assert report["evaluation"]["pixels_after_warm_up"]["f_measure"] > 0.7
