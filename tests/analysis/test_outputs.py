"""annotated.avi as written and decoded back: frame for frame with the input."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from app.analysis.outputs import AnnotatedVideo
from tests.conftest import decode_all


def _picture(size: tuple[int, int], seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noise = rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8)
    return cv2.GaussianBlur(noise, (0, 0), 2)


def test_missing_decode_indices_repeat_the_previous_frame(tmp_path: Path) -> None:
    size = (64, 48)
    frames = {i: _picture(size, i) for i in (1, 2, 5)}  # 0, 3, 4 and 6 did not decode
    video = AnnotatedVideo(tmp_path / "annotated.avi", 15.0, size)
    for index, frame in frames.items():
        video.write(frame, index)
    video.pad_to(7)
    video.close()
    decoded = list(decode_all(tmp_path / "annotated.avi"))
    stands_for = [1, 1, 2, 2, 2, 5, 5]
    assert len(decoded) == len(stands_for)
    for back, index in zip(decoded, stands_for, strict=True):
        assert cv2.PSNR(frames[index], back) > 30
