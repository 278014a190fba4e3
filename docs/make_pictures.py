"""Draw the pictures of docs/detection.md from synthetic scenes (app/sources/synthetic.py).

    .venv/bin/python docs/make_pictures.py

Writes docs/pictures/: one picture per pipeline stage, for one frame of the ``crossing``
scene, and one picture per mechanism of the ``adaptive`` method, each beside what the
paper's ``frame-difference`` makes of the same frame. Deterministic: the scenes are
seeded, so the same code draws the same pictures.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from app.sources.synthetic import Scene, standard_scenes
from app.vision.annotate import Annotator, difference_picture, overlay_mask
from app.vision.histogram import grey_histogram, grey_stats, render_histogram
from app.vision.pipeline import FrameResult, Pipeline, PipelineConfig

OUT = Path(__file__).resolve().parent / "pictures"
JPEG_QUALITY = 80
STAGE_SCENE, STAGE_FRAME = "crossing", 40
LABEL_HEIGHT = 18


class Tap:
    """A pipeline stage that keeps what it was last given and what it gave back."""

    def __init__(self, stage: Callable[..., Any]) -> None:
        self.stage = stage
        self.given: Any = None
        self.gave: Any = None

    def __call__(self, image: Any, *args: Any) -> Any:
        self.given = image
        self.gave = self.stage(image, *args)
        return self.gave


def run(scene: Scene, method: str, last: int) -> tuple[Pipeline, FrameResult, dict[str, Tap]]:
    """``scene`` through a pipeline up to frame ``last``; its taps hold that frame's stages."""
    pipeline = Pipeline(PipelineConfig(method=method), scene.fps)
    taps = {"denoise": Tap(pipeline.denoise), "morphology": Tap(pipeline.morphology)}
    pipeline.denoise, pipeline.morphology = taps["denoise"], taps["morphology"]
    result = None
    for index in range(last + 1):
        result = pipeline.process(scene.frame(index))
    assert result is not None
    return pipeline, result, taps


def save(name: str, image: np.ndarray) -> None:
    path = OUT / name
    params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if path.suffix == ".jpg" else []
    if not cv2.imwrite(str(path), image, params):
        raise OSError(f"cannot write {path}")
    print(f"{path.relative_to(OUT.parent.parent)}  {path.stat().st_size // 1024} KB")


def labelled(image: np.ndarray, label: str) -> np.ndarray:
    picture = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    band = np.full((LABEL_HEIGHT, picture.shape[1], 3), 255, np.uint8)
    cv2.putText(band, label, (4, 13), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([band, picture])


def stage_pictures() -> None:
    scene = standard_scenes()[STAGE_SCENE]
    pipeline, result, taps = run(scene, "adaptive", STAGE_FRAME)
    frame = scene.frame(STAGE_FRAME)
    save("stage-1-frame.jpg", frame)
    save(
        "stage-2-histogram.png",
        render_histogram(grey_histogram(result.gray), grey_stats(result.gray)),
    )
    save("stage-3-denoised.jpg", taps["denoise"].gave)
    save("stage-4-difference.png", difference_picture(result.difference, scene.size))
    save("stage-5-threshold.png", taps["morphology"].given)
    save("stage-6-morphology.png", taps["morphology"].gave)
    annotated = Annotator()(frame, result.detections, pipeline.tracker.trails())
    save("stage-7-tracked.jpg", annotated)


@dataclass(frozen=True)
class Mechanism:
    picture: str
    scene: Scene
    frames: tuple[int, ...]
    """A row of pictures for each: the frame, then each method's mask over it."""


def mechanism_pictures() -> None:
    scenes = standard_scenes()
    mechanisms = [
        Mechanism("adaptive-slow-uniform.jpg", scenes["slow-uniform"], (90,)),
        Mechanism("adaptive-light-switch.jpg", scenes["light-switch-crossing"], (30, 32)),
        Mechanism("adaptive-knocked.jpg", scenes["knocked"], (45,)),
        Mechanism("adaptive-swaying.jpg", scenes["swaying"], (100,)),
        Mechanism("adaptive-waiting.jpg", scenes["waiting"], (90,)),
    ]
    for mechanism in mechanisms:
        rows = []
        for index in mechanism.frames:
            frame = mechanism.scene.frame(index)
            row = [labelled(frame, f"frame {index}")]
            for method in ("frame-difference", "adaptive"):
                _, result, _ = run(mechanism.scene, method, index)
                row.append(labelled(overlay_mask(frame, result.mask), method))
            rows.append(np.hstack(row))
        save(mechanism.picture, np.vstack(rows))


if __name__ == "__main__":
    OUT.mkdir(exist_ok=True)
    stage_pictures()
    mechanism_pictures()
