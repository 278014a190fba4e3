"""Quality on real footage with ground truth (../shared/data); skipped when it is absent."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from app.analysis.runner import scan_background
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


def f_measure(
    data: Path, sequence: str, method: str, scan: bool = False, warm: bool = True
) -> float:
    """Pixel F-measure, after the warm-up (``warm``, not for the one Wallflower frame) or
    over every scored frame; ``scan``: the pipeline first scans the frames for the empty
    scene, as ``vigil analyze`` does."""
    input_rel, truth_rel = SEQUENCES[sequence]
    source = open_input(data / input_rel)
    truth = load_truth(data / truth_rel, source.frame_numbers)
    pipeline = Pipeline(PipelineConfig(method=method), fps=source.fps)
    if scan:
        scan_background(pipeline, source.frames(), source.fps)
    scorer = Scorer(truth, 100.0, source.size)
    for frame in source.frames():
        result = pipeline.process(frame)
        scorer.add(result.index, [d.box for d in result.detections], result.mask)
    pixels = scorer.pixels_warm if warm and sequence != "wallflower" else scorer.pixels
    return pixels.f_measure


@pytest.mark.shared_data
@pytest.mark.parametrize("sequence", sorted(SEQUENCES))
def test_default_method_beats_mog2_on_real_footage(shared_data, sequence):
    ours = f_measure(shared_data, sequence, "adaptive")
    mog2 = f_measure(shared_data, sequence, "mog2")
    assert ours > mog2, f"{sequence}: adaptive F={ours:.3f}, MOG2 F={mog2:.3f}"


@pytest.mark.shared_data
@pytest.mark.parametrize("sequence", ["traffic", "fall"])
def test_background_scan_gains_on_footage_that_starts_with_cars_in_view(shared_data, sequence):
    # Both CDnet subsets start mid-sequence, cars in view, with nothing to learn from first.
    scanned = f_measure(shared_data, sequence, "adaptive", scan=True, warm=False)
    plain = f_measure(shared_data, sequence, "adaptive", scan=False, warm=False)
    assert scanned > plain, f"{sequence}: F {scanned:.3f} with the scan, {plain:.3f} without"


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
