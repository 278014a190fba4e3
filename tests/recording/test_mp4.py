"""H.264 in fragmented MP4 written and decoded back: sizes, times, ranges, and clips cut short."""

from __future__ import annotations

import errno
import io
from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from app.recording.mp4 import ClipFrame, H264Writer, decoded_clip_frame
from app.storage.clips import clip_length_s, complete_length, repair
from tests.api.vigil_livekit import FPS, HEIGHT, WIDTH, frame_at, square_box


def _jpeg(index: int) -> bytes:
    return cv2.imencode(".jpg", frame_at(index))[1].tobytes()


def _decode(path: Path) -> tuple[list[np.ndarray], list[float], av.video.stream.VideoStream]:
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        frames, times = [], []
        for frame in container.decode(stream):
            frames.append(frame.to_ndarray(format="bgr24"))
            times.append(float(frame.pts * frame.time_base))
        return frames, times, stream


def _square(picture: np.ndarray) -> tuple[int, int, int, int] | None:
    """The bright square's box in a decoded frame (the background stays below 200)."""
    ys, xs = np.nonzero(cv2.cvtColor(picture, cv2.COLOR_BGR2GRAY) > 200)
    if len(xs) < 100:
        return None
    return int(xs.min()), int(ys.min()), int(xs.max() - xs.min() + 1), int(ys.max() - ys.min() + 1)


def _write(path: Path, frames: list[ClipFrame | np.ndarray], times: list[float]) -> H264Writer:
    with path.open("wb", buffering=0) as file:
        writer = H264Writer(file, FPS)
        for frame, at in zip(frames, times, strict=True):
            writer.write(frame, at)
        writer.close()
    return writer


def test_jpeg_frames_keep_their_size_times_and_pictures(tmp_path: Path) -> None:
    """A JPEG camera's frames: decoded straight to YUV, kept full-range; times as they came."""
    times = [100.0 + i / FPS + (0.01 if i % 7 == 0 else 0.0) for i in range(45)]
    frames = [ClipFrame(t, t + 1e9, (WIDTH, HEIGHT), jpeg=_jpeg(i)) for i, t in enumerate(times)]
    writer = _write(tmp_path / "c.mp4", list(frames), times)
    decoded, pts, stream = _decode(tmp_path / "c.mp4")
    assert len(decoded) == 45 == writer.frames
    assert decoded[0].shape == (HEIGHT, WIDTH, 3)
    assert stream.codec_context.pix_fmt == "yuvj420p"
    assert np.allclose(pts, np.array(times) - times[0], atol=1e-4), "the real times, not a rate"
    assert writer.length_s == pytest.approx(times[-1] - times[0] + 1 / FPS)
    assert clip_length_s(tmp_path / "c.mp4") == pytest.approx(writer.length_s, abs=0.07)
    for index, picture in enumerate(decoded):
        truth = square_box(index)
        found = _square(picture)
        if truth is None:
            assert found is None, index
        else:
            assert found is not None and np.allclose(found, truth, atol=2), (index, found, truth)
    grey = cv2.cvtColor(decoded[0], cv2.COLOR_BGR2GRAY).astype(int)
    original = cv2.cvtColor(frame_at(0), cv2.COLOR_BGR2GRAY).astype(int)
    assert np.abs(grey - original).mean() < 4, "levels kept (full range both ways)"


def test_decoded_frames_are_kept_as_i420_and_odd_sizes_grow_a_pixel(tmp_path: Path) -> None:
    picture = frame_at(10)
    kept = decoded_clip_frame(picture, 1.0, 2.0)
    assert kept.pixels is not None and kept.pixels.shape == (HEIGHT * 3 // 2, WIDTH)
    assert kept.nbytes == WIDTH * HEIGHT * 3 // 2, "half of BGR"
    _write(tmp_path / "even.mp4", [kept, decoded_clip_frame(frame_at(11), 1.1, 2.1)], [1.0, 1.1])
    decoded, _, stream = _decode(tmp_path / "even.mp4")
    assert len(decoded) == 2 and stream.codec_context.pix_fmt == "yuv420p"
    assert np.allclose(_square(decoded[0]), square_box(10), atol=2)

    odd = np.ascontiguousarray(picture[:239, :319])
    frames = [decoded_clip_frame(odd, 1.0, 2.0), odd]  # Kept as BGR, or given as a picture.
    _write(tmp_path / "odd.mp4", frames, [1.0, 1.1])
    decoded, _, _ = _decode(tmp_path / "odd.mp4")
    assert [d.shape for d in decoded] == [(240, 320, 3)] * 2


def test_each_fragment_reaches_the_file_as_it_is_made(tmp_path: Path) -> None:
    """A keyframe a second: by two seconds of frames, the first second is on disk whole."""
    path = tmp_path / "live.mp4"
    with path.open("wb", buffering=0) as file:
        writer = H264Writer(file, FPS)
        for i in range(int(2.5 * FPS)):
            writer.write(ClipFrame(i / FPS, 0.0, (WIDTH, HEIGHT), jpeg=_jpeg(i)), i / FPS)
        on_disk = complete_length(path)
        assert on_disk > 0 and path.stat().st_size >= on_disk
        # What is on disk now plays, while the clip goes on.
        copy = tmp_path / "so-far.mp4"
        copy.write_bytes(path.read_bytes()[:on_disk])
        assert 1.0 <= clip_length_s(copy) < 2.5
        writer.close()
    assert complete_length(path) == path.stat().st_size, "finished: every box whole"


class _FullDisk(io.RawIOBase):
    """A file whose disk fills after ``room`` bytes."""

    def __init__(self, target: io.RawIOBase, room: int) -> None:
        self.target, self.room = target, room

    def writable(self) -> bool:
        return True

    def write(self, data: bytes) -> int:  # type: ignore[override]
        if len(data) > self.room:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.room -= len(data)
        return self.target.write(data) or 0

    def fileno(self) -> int:
        return self.target.fileno()


def test_a_disk_that_fills_mid_clip_leaves_a_clip_that_plays_to_there(tmp_path: Path) -> None:
    path = tmp_path / "full.mp4"
    with path.open("wb", buffering=0) as target:
        writer = H264Writer(_FullDisk(target, 60_000), FPS)  # type: ignore[arg-type]
        with pytest.raises(OSError) as raised:
            for i in range(int(6 * FPS)):
                writer.write(ClipFrame(i / FPS, 0.0, (WIDTH, HEIGHT), jpeg=_jpeg(i % 45)), i / FPS)
        assert raised.value.errno == errno.ENOSPC
        writer.abandon()
    kept = repair(path)
    assert 0 < kept <= 60_000 and path.stat().st_size == kept
    decoded, times, _ = _decode(path)
    assert len(decoded) >= FPS and times[-1] < 6, "the seconds written before the disk filled"


def test_a_cut_clip_is_repaired_to_its_last_whole_fragment(tmp_path: Path) -> None:
    whole = tmp_path / "whole.mp4"
    times = [i / FPS for i in range(int(4 * FPS))]
    frames = [ClipFrame(t, 0.0, (WIDTH, HEIGHT), jpeg=_jpeg(i % 45)) for i, t in enumerate(times)]
    _write(whole, list(frames), times)
    data = whole.read_bytes()
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(data[: len(data) * 2 // 3])  # Mid-fragment, as a kill leaves it.
    good = repair(cut)
    assert 0 < good < len(data) * 2 // 3 and cut.stat().st_size == good
    decoded, _, _ = _decode(cut)
    assert 1.0 <= clip_length_s(cut) <= 3.0
    assert len(decoded) == pytest.approx(clip_length_s(cut) * FPS, abs=1)
    header_only = tmp_path / "header.mp4"
    header_only.write_bytes(data[:600])
    assert repair(header_only) == 0 and not header_only.exists(), "nothing to play: gone"
