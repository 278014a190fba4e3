"""`vigil evaluate`: score an existing `vigil analyze` output folder against truth."""

from __future__ import annotations

import csv
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import cv2

from app.analysis.outputs import write_json
from app.analysis.scoring import Scorer
from app.analysis.truth import load_truth
from app.vision.detections import Box


class EvaluationError(ValueError):
    """The output folder cannot be scored; the message says why."""


def evaluate(out_dir: Path, truth_path: Path) -> dict[str, Any]:
    """Score tracks.csv (and masks/, when the analysis wrote them); writes evaluation.json."""
    report_path, tracks_path = out_dir / "report.json", out_dir / "tracks.csv"
    if not report_path.is_file() or not tracks_path.is_file():
        raise EvaluationError(
            f"{out_dir} is not a `vigil analyze` output (no report.json/tracks.csv)"
        )
    try:
        report = json.loads(report_path.read_text())
        # tracks.csv and truth go by decode index: the frames read, less the ones that
        # did not decode (reports before those keys: every frame decoded).
        frames_read = int(report.get("frames_read", report["frames"]))
        skipped = {int(index) for index in report.get("skipped_frames", [])}
        min_area = float(report["settings"]["min_area"])
        width, height = (int(side) for side in report["size"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise EvaluationError(f"cannot read {report_path}: {exc}") from None
    truth = load_truth(truth_path, report.get("frame_numbers"))
    truth.check_size((width, height))
    boxes = _boxes_by_frame(tracks_path)
    masks_dir = out_dir / "masks"
    scorer = Scorer(truth, min_area, (width, height))
    for index in truth.frames:
        if index >= frames_read or index in skipped:
            continue
        mask_path = masks_dir / f"{index:06d}.png"
        mask = cv2.imread(str(mask_path), cv2.IMREAD_GRAYSCALE) if mask_path.is_file() else None
        scorer.add(index, boxes.get(index, []), mask)
    result = scorer.as_dict()
    result["masks_scored"] = masks_dir.is_dir()
    write_json(out_dir / "evaluation.json", result)
    return result


def _boxes_by_frame(path: Path) -> dict[int, list[Box]]:
    boxes: dict[int, list[Box]] = defaultdict(list)
    try:
        with path.open(newline="") as handle:
            for row in csv.DictReader(handle):
                boxes[int(row["frame"])].append(
                    Box(int(row["x"]), int(row["y"]), int(row["w"]), int(row["h"]))
                )
    except (OSError, ValueError, KeyError) as exc:
        raise EvaluationError(f"cannot read {path}: {exc}") from None
    return boxes
