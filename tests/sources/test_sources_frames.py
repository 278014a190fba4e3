"""Frames decoded only as far as needed: JPEG packets from MJPEG sources, reduced grey decode."""

from __future__ import annotations

import contextlib
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from app.sources.frames import DecodedFrame, FrameError, JpegFrame, jpeg_size
from app.sources.live import FileSource
from app.sources.synthetic import MovingObject, Scene
from tests.conftest import write_scene_video

SCENE = Scene(
    name="vga",
    size=(640, 480),
    fps=25.0,
    frames=12,
    objects=(MovingObject((50, 200), (100.0, 0.0), (60, 90), 220),),
)


def encoded(image: np.ndarray, *params: int) -> bytes:
    ok, data = cv2.imencode(".jpg", image, list(params))
    assert ok
    return data.tobytes()


def test_mjpg_file_frames_arrive_undecoded_and_decode_as_asked(tmp_path: Path) -> None:
    source = FileSource(write_scene_video(SCENE, tmp_path / "vga.avi"))
    frame = source.read()
    source.close()
    assert isinstance(frame, JpegFrame) and frame.jpeg is not None
    assert frame.size == (640, 480)
    gray = frame.gray(320)  # Half scale, straight from the DCT.
    assert gray.shape == (240, 320)
    image = frame.image()
    assert image.shape == (480, 640, 3)
    shrunk = cv2.resize(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), (320, 240), cv2.INTER_AREA)
    assert np.abs(gray.astype(int) - shrunk.astype(int)).mean() < 3
    assert frame.gray(320).shape == (480, 640)  # Decoded in full: grey comes from that.


@pytest.mark.parametrize(("width", "height"), [(640, 480), (1920, 1080), (33, 17)])
@pytest.mark.parametrize("progressive", [0, 1])
def test_jpeg_size_is_read_from_the_header(width: int, height: int, progressive: int) -> None:
    image = np.full((height, width, 3), 90, np.uint8)
    data = encoded(image, cv2.IMWRITE_JPEG_PROGRESSIVE, progressive)
    assert jpeg_size(data) == (width, height)
    frame = JpegFrame(data)
    assert frame.gray(320).shape[1] >= min(320, width)
    assert frame.gray(320).shape[1] < 640 or width < 640


def test_grey_from_a_large_frame_uses_the_largest_reduction_that_is_wide_enough() -> None:
    frame = JpegFrame(encoded(np.zeros((1080, 1920, 3), np.uint8)))
    assert frame.gray(320).shape == (270, 480)  # A quarter: an eighth would be 240 wide.


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"", "not a JPEG"),
        (b"GIF89a....", "not a JPEG"),
        (b"\xff\xd8\xff\xe0\x00\x10JFIF", "without a frame header"),
        (b"\xff\xd8\x00\x00\x00\x00", "corrupt"),
        (b"\xff\xd8\xff\xc0\x00\x11\x08\x00\x00\x02\x80\x03", "claiming 640x0"),
        (b"\xff\xd8\xff\xc0\x00\x11\x08\xff\xff\xff\xff\x03", "claiming 65535x65535"),
    ],
)
def test_garbage_is_a_frame_error_with_a_reason(data: bytes, reason: str) -> None:
    with pytest.raises(FrameError, match=reason):
        JpegFrame(data)


def test_a_jpeg_with_a_good_header_and_no_picture_fails_when_decoded() -> None:
    data = encoded(np.zeros((48, 64, 3), np.uint8))
    header_only = data[: data.index(b"\xff\xda")] + b"\xff\xd9"
    frame = JpegFrame(header_only)
    with pytest.raises(FrameError, match="does not decode"):
        frame.image()


@given(st.binary(max_size=300))
def test_any_bytes_give_a_frame_or_a_frame_error(data: bytes) -> None:
    for candidate in (data, b"\xff\xd8" + data):
        try:
            frame = JpegFrame(candidate)
        except FrameError:
            continue
        with contextlib.suppress(FrameError):
            frame.gray(320)
        with contextlib.suppress(FrameError):
            frame.image()


def opencv_colour(data: bytes) -> np.ndarray | None:
    """The picture OpenCV decodes (as the header's size says, EXIF aside)."""
    flags = cv2.IMREAD_COLOR | cv2.IMREAD_IGNORE_ORIENTATION
    return cv2.imdecode(np.frombuffer(data, np.uint8), flags)


@pytest.mark.parametrize(
    "params",
    [
        [cv2.IMWRITE_JPEG_QUALITY, 80],
        [cv2.IMWRITE_JPEG_PROGRESSIVE, 1],
        [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444],
        [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422],
    ],
)
@pytest.mark.parametrize("grey_jpeg", [False, True])
def test_the_colour_picture_is_opencv_s_pixel_for_pixel(params: list[int], grey_jpeg: bool) -> None:
    picture = SCENE.frame(3)
    data = encoded(cv2.cvtColor(picture, cv2.COLOR_BGR2GRAY) if grey_jpeg else picture, *params)
    image = JpegFrame(data).image()
    assert image.shape == (480, 640, 3) and image.dtype == np.uint8
    reference = opencv_colour(data)
    assert reference is not None
    np.testing.assert_array_equal(image, reference)


def damaged(data: bytes) -> bytes:
    """``data`` with three bits flipped in its scan: a camera's bit errors."""
    flipped = bytearray(data)
    scan = flipped.index(b"\xff\xda")
    for at in (scan + 400, scan + 2000, len(flipped) - 300):
        flipped[at] ^= 0x10
    return bytes(flipped)


def jfif_2_01(data: bytes) -> bytes:
    """``data`` claiming JFIF 2.01, a version libjpeg warns of and decodes."""
    assert data[6:11] == b"JFIF\x00"
    return data[:11] + b"\x02" + data[12:]


@pytest.mark.parametrize("odd", [damaged, jfif_2_01], ids=["bit errors", "JFIF 2.01"])
def test_a_jpeg_that_libjpeg_warns_about_gives_the_picture_opencv_gives(
    odd: Callable[[bytes], bytes],
) -> None:
    """Bit errors spoil part of a frame, not all of it; an odd header none of it: the
    picture is what libjpeg makes of it, as the grey of detection is, not a frame error."""
    data = odd(encoded(SCENE.frame(3)))
    reference = opencv_colour(data)
    assert reference is not None  # OpenCV decodes it, with a warning.
    np.testing.assert_array_equal(JpegFrame(data).image(), reference)
    assert JpegFrame(data).gray(320).shape == (240, 320)


def test_a_cut_off_jpeg_is_a_frame_error_in_colour_as_in_grey() -> None:
    data = encoded(SCENE.frame(3))
    cut = data[: len(data) * 2 // 3]
    assert opencv_colour(cut) is None
    with pytest.raises(FrameError, match="does not decode"):
        JpegFrame(cut).image()
    with pytest.raises(FrameError, match="does not decode"):
        JpegFrame(cut).gray(320)


@pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="needs the ffmpeg binary for H.264")
def test_frames_of_a_non_jpeg_stream_arrive_decoded(tmp_path: Path) -> None:
    mjpg = write_scene_video(SCENE, tmp_path / "vga.avi")
    h264 = tmp_path / "vga.mp4"
    subprocess.run(
        ["ffmpeg", "-loglevel", "error", "-y", "-i", str(mjpg), "-c:v", "libx264", str(h264)],
        check=True,
    )
    source = FileSource(h264)
    frame = source.read()
    source.close()
    assert isinstance(frame, DecodedFrame) and frame.jpeg is None
    assert frame.size == (640, 480) and frame.gray(320).shape == (480, 640)
