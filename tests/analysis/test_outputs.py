"""annotated.avi as written and decoded back: the input's size, frame for frame."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from app.analysis.outputs import AnnotatedVideo
from tests.conftest import decode_all


def _picture(size: tuple[int, int], seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noise = rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8)
    return cv2.GaussianBlur(noise, (0, 0), 2)


@pytest.mark.parametrize("size", [(251, 191), (320, 241), (33, 17), (320, 240)])
def test_the_annotated_video_keeps_the_input_size(tmp_path: Path, size: tuple[int, int]) -> None:
    frames = [_picture(size, seed) for seed in range(3)]
    video = AnnotatedVideo(tmp_path / "annotated.avi", 15.0, size)
    for frame in frames:
        video.write(frame)
    video.close()
    decoded = list(decode_all(tmp_path / "annotated.avi"))
    assert len(decoded) == 3
    for written, back in zip(frames, decoded, strict=True):
        assert back.shape == written.shape
        assert cv2.PSNR(written, back) > 30


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
