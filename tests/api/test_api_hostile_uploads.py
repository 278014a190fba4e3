"""Hostile uploads: each fails alone with one readable line, or is refused with a 4xx,
while the server, a live camera and another analysis carry on.

Every file here is a real one: AVIs written by OpenCV then cut or patched, an MJPEG
AVI assembled byte by byte whose frames really are 12000x12000, and a decoder crash
made by signalling the analysis process itself.
"""

from __future__ import annotations

import io
import os
import signal
import struct
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np
import psutil
import pytest

from app.api.routes.analyses import display_name
from tests.api.vigil_livekit import MjpegCamera, Running, add_camera, wait_for, write_video

Upload = tuple[str, bytes]


def _post(server: Running, name: str, content: bytes) -> httpx.Response:
    return httpx.post(
        f"{server.base}/api/analyses",
        files={"file": (name, content, "video/x-msvideo")},
        timeout=30,
    )


def _upload(server: Running, name: str, content: bytes) -> str:
    response = _post(server, name, content)
    assert response.status_code == 202, response.text
    return str(response.json()["id"])


def _analysis(server: Running, analysis_id: str) -> dict[str, Any]:
    body: dict[str, Any] = httpx.get(f"{server.base}/api/analyses/{analysis_id}").json()
    return body


def _finished(server: Running, analysis_id: str, timeout: float = 120) -> dict[str, Any]:
    result: dict[str, Any] = wait_for(
        lambda: (a := _analysis(server, analysis_id))["status"] in ("done", "failed") and a,
        timeout,
        f"analysis {analysis_id} to finish",
        0.2,
    )
    return result


def _assert_readable(error: str | None, tmp_path: Path) -> str:
    """What a person reads: one short line, no traceback, no path on the server."""
    assert error, "a failed analysis must say why"
    assert "\n" not in error and len(error) < 300, error
    assert "Traceback" not in error and str(tmp_path) not in error, error
    return error


# Real files, made hostile --------------------------------------------------------------


def _truncated(video: bytes) -> bytes:
    """The first third of a real AVI: the header promises frames the file no longer has."""
    return video[: len(video) // 3]


def _lying_header(video: bytes) -> bytes:
    """A real AVI whose headers claim 444444 frames at a million frames per second."""
    data = bytearray(video)
    avih = data.find(b"avih") + 8
    struct.pack_into("<I", data, avih, 1)  # dwMicroSecPerFrame
    struct.pack_into("<I", data, avih + 16, 444444)  # dwTotalFrames
    strh = data.find(b"strh") + 8
    struct.pack_into("<II", data, strh + 20, 1, 1_000_000)  # dwScale, dwRate
    struct.pack_into("<I", data, strh + 32, 444444)  # dwLength
    return bytes(data)


def _absurd_header_size(video: bytes) -> bytes:
    """A real AVI whose headers claim 100000x100000 frames (they hold 320x240 JPEGs)."""
    data = bytearray(video)
    struct.pack_into("<II", data, data.find(b"avih") + 8 + 32, 100000, 100000)
    struct.pack_into("<ii", data, data.find(b"strf") + 8 + 4, 100000, 100000)
    return bytes(data)


def _chunk(tag: bytes, body: bytes) -> bytes:
    return tag + struct.pack("<I", len(body)) + body + b"\0" * (len(body) % 2)


def _grey_jpeg(width: int, height: int) -> bytes:
    """A valid baseline greyscale JPEG of mid grey: a few bits per 8x8 block at any size."""
    dqt = b"\xff\xdb" + struct.pack(">HB", 67, 0) + b"\x01" * 64
    sof = b"\xff\xc0" + struct.pack(">HBHHB", 11, 8, height, width, 1) + b"\x01\x11\x00"
    # The standard luminance Huffman tables (JPEG Annex K.3).
    dc_counts = bytes([0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0])
    ac_counts = bytes([0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7D])
    ac_symbols = bytes.fromhex(
        "01020300041105122131410613516107227114328191a1082342b1c11552d1f0"
        "2433627282090a161718191a25262728292a3435363738393a434445464748494a"
        "535455565758595a636465666768696a737475767778797a838485868788898a"
        "92939495969798999aa2a3a4a5a6a7a8a9aab2b3b4b5b6b7b8b9bac2c3c4c5c6"
        "c7c8c9cad2d3d4d5d6d7d8d9dae1e2e3e4e5e6e7e8e9eaf1f2f3f4f5f6f7f8f9fa"
    )
    tables = b"\x00" + dc_counts + bytes(range(12)) + b"\x10" + ac_counts + ac_symbols
    dht = b"\xff\xc4" + struct.pack(">H", 2 + len(tables)) + tables
    sos = b"\xff\xda" + struct.pack(">HB", 8, 1) + b"\x01\x00\x00\x3f\x00"
    blocks = -(-width // 8) * -(-height // 8)
    # Each block is DC difference 0 (code 00) then end of block (code 1010): six bits,
    # so four blocks are exactly these three bytes.
    scan = b"\x28\xa2\x8a" * -(-blocks // 4)
    return b"\xff\xd8" + dqt + sof + dht + sos + scan + b"\xff\xd9"


def _mjpeg_avi(width: int, height: int, frames: int, fps: int = 15) -> bytes:
    """A well-formed MJPEG AVI, honest headers and all, whose frames are width x height."""
    jpeg = _grey_jpeg(width, height)
    avih = struct.pack(
        "<10I", 1_000_000 // fps, 0, 0, 0x10, frames, 0, 1, len(jpeg), width, height
    ) + bytes(16)
    strh = b"vidsMJPG" + struct.pack(
        "<IHHIIIIIIiI4H", 0, 0, 0, 0, 1, fps, 0, frames, len(jpeg), -1, 0, 0, 0, width, height
    )
    strf = struct.pack(
        "<IiiHH4sIiiII", 40, width, height, 1, 24, b"MJPG", width * height * 3, 0, 0, 0, 0
    )
    stream = _chunk(b"LIST", b"strl" + _chunk(b"strh", strh) + _chunk(b"strf", strf))
    header = _chunk(b"LIST", b"hdrl" + _chunk(b"avih", avih) + stream)
    frame = _chunk(b"00dc", jpeg)
    movi = _chunk(b"LIST", b"movi" + frame * frames)
    index = b"".join(
        b"00dc" + struct.pack("<III", 0x10, 4 + i * len(frame), len(jpeg)) for i in range(frames)
    )
    body = b"AVI " + header + movi + _chunk(b"idx1", index)
    return b"RIFF" + struct.pack("<I", len(body)) + body


def _png() -> bytes:
    ok, data = cv2.imencode(".png", np.full((240, 320, 3), 90, np.uint8))
    assert ok
    return data.tobytes()


def _zip() -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("clip.avi", b"not really\n" * 100)
    return buffer.getvalue()


# A live camera beside the uploads ------------------------------------------------------


@contextmanager
def _live_camera(server: Running) -> Iterator[Callable[[], int]]:
    """A real MJPEG camera on loopback, added and activated; yields its frames processed."""
    camera = MjpegCamera().start()
    try:
        cam_id = add_camera(server.base, camera.url, "door", activate=True)

        def view() -> dict[str, Any]:
            return dict(httpx.get(f"{server.base}/api/cameras/{cam_id}").json())

        def processed() -> int:
            now = view()
            assert now["state"] == "live", now
            return int(now["processed"])

        wait_for(lambda: view()["processed"] > 0, 15, "the camera to process frames")
        yield processed
    finally:
        camera.stop()


def _assert_still_serving(server: Running, processed: Callable[[], int]) -> None:
    health = httpx.get(f"{server.base}/api/health")
    assert health.status_code == 200 and health.json()["status"] == "ok"
    before = processed()
    wait_for(lambda: processed() > before, 10, "the camera to keep processing frames")


# The tests -----------------------------------------------------------------------------


def test_hostile_files_fail_alone_while_a_camera_and_an_analysis_carry_on(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    server = serve(analysis_workers=2)
    video = write_video(tmp_path / "clip.avi", frames=60).read_bytes()
    failing: dict[str, tuple[bytes, str]] = {
        "random.avi": (os.urandom(64 * 1024), "not a video FFmpeg can decode: random.avi"),
        "cut-in-header.avi": (video[:300], "not a video FFmpeg can decode"),
        "picture.avi": (_png(), "picture.avi holds only one decodable frame"),
        "notes.avi": (b"this is not a video\n" * 200, "not a video FFmpeg can decode"),
        "archive.avi": (_zip(), "not a video FFmpeg can decode"),
        # 5 MB that decode to 432 MB a frame: refused from the header, before a frame is read.
        "bomb.avi": (_mjpeg_avi(12000, 12000, 3), "frames of 12000x12000 are too large"),
    }
    with _live_camera(server) as processed:
        beside = _upload(server, "beside.avi", write_video(tmp_path / "long.avi", 600).read_bytes())
        failed_ids = {name: _upload(server, name, data) for name, (data, _) in failing.items()}
        truncated = _upload(server, "truncated.avi", _truncated(video))
        lying = _upload(server, "lying.avi", _lying_header(video))
        absurd = _upload(server, "absurd.avi", _absurd_header_size(video))

        for name, analysis_id in failed_ids.items():
            result = _finished(server, analysis_id)
            assert result["status"] == "failed", (name, result)
            assert failing[name][1] in _assert_readable(result["error"], tmp_path), name
            assert result["report"] is None
            stream = httpx.get(f"{server.base}/api/analyses/{analysis_id}/stream.mjpg")
            assert stream.status_code == 404, name
            assert stream.json()["detail"] == "no frames to show: the analysis is failed"

        # Decoded until the reader stops, whatever the header says: what is there is analysed.
        report = _finished(server, truncated)["report"]
        assert report is not None and 0 < report["frames"] < 60 == report["header_frames"]
        report = _finished(server, lying)["report"]
        assert report is not None and report["frames"] == 60
        assert report["header_frames"] == 444444 and 0 < report["fps"] <= 1000
        report = _finished(server, absurd)["report"]
        assert report is not None and report["size"] == [320, 240] and report["frames"] == 60

        done = _finished(server, beside)
        assert done["status"] == "done" and done["report"]["frames"] == 600
        _assert_still_serving(server, processed)


def test_upload_names_cannot_escape_the_analyses_folder(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    data_dir = tmp_path / "data"
    server = serve(data_dir)
    video = write_video(tmp_path / "clip.avi", frames=20).read_bytes()
    names = {
        "../../escaped-up.avi": "escaped-up.avi",
        "..\\..\\escaped-back.avi": "escaped-back.avi",
        "/tmp/escaped-abs.avi": "escaped-abs.avi",
        "..": "upload",
    }
    ids = {name: _upload(server, name, video) for name in names}
    for name, analysis_id in ids.items():
        result = _finished(server, analysis_id)
        assert result["status"] == "done", result
        assert result["filename"] == names[name]
        kept = sorted(p.name for p in (data_dir / "analyses" / analysis_id).iterdir())
        assert kept == [f"input{Path(names[name]).suffix or '.bin'}", "out"], kept
    assert not list(tmp_path.parent.rglob("escaped*")), "an upload left its folder"
    assert not list(Path("/tmp").glob("escaped-abs*"))


@pytest.mark.parametrize(
    ("sent", "shown"),
    [
        ("C:\\Users\\ann\\clip.avi", "clip.avi"),
        ("evil\n\x00name\x1b[31m.avi", "evilname[31m.avi"),
        ("a/..", "upload"),
        ("x" * 500 + ".avi", "x" * 200),
        (None, "upload"),
    ],
)
def test_upload_names_are_shown_without_folders_or_control_characters(
    sent: str | None, shown: str
) -> None:
    # Clients percent-encode control characters in the multipart header; this is the rest.
    assert display_name(sent) == shown


def test_too_large_frames_are_refused_by_the_size_cap(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    server = serve(max_upload_pixels=320 * 240 - 1)
    analysis_id = _upload(server, "clip.avi", write_video(tmp_path / "c.avi", 20).read_bytes())
    result = _finished(server, analysis_id)
    assert result["status"] == "failed"
    assert "frames of 320x240 are too large: at most 76,799 pixels" in _assert_readable(
        result["error"], tmp_path
    )


def test_memory_cap_stops_a_decoder_that_allocates_without_bound(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    # With the size cap lifted, these frames need gigabytes: the process' own limit stops it.
    server = serve(max_upload_pixels=10**9, analysis_memory_mb=1500)
    analysis_id = _upload(server, "bomb.avi", _mjpeg_avi(12000, 12000, 3))
    result = _finished(server, analysis_id)
    assert result["status"] == "failed"
    error = _assert_readable(result["error"], tmp_path)
    assert error == "bomb.avi needs more memory than an analysis may use (1500 MB)"
    after = _upload(server, "next.avi", write_video(tmp_path / "n.avi", 20).read_bytes())
    assert _finished(server, after)["status"] == "done"


def _analysis_process(analysis_id: str) -> psutil.Process | None:
    """The server's child process analysing ``analysis_id`` (the server runs in this process)."""
    for child in psutil.Process().children(recursive=True):
        try:
            if any(f"{os.sep}{analysis_id}{os.sep}" in part for part in child.cmdline()):
                return child
        except psutil.NoSuchProcess:
            continue
    return None


def _crash_beside_another(
    server: Running, video: bytes, sig: signal.Signals, tmp_path: Path
) -> str:
    """Signal one analysis' process while another runs; that one's error, the other done."""
    beside = _upload(server, "beside.avi", video)
    victim = _upload(server, "victim.avi", video)
    child = wait_for(lambda: _analysis_process(victim), 30, "the analysis process")
    wait_for(lambda: _analysis(server, beside)["status"] == "running", 30, "both to run")
    reached = wait_for(lambda: _analysis(server, victim)["progress"], 30, "some progress")
    child.send_signal(sig)
    result = _finished(server, victim)
    assert result["status"] == "failed"
    assert result["progress"] >= reached  # It keeps how far it got.
    assert _finished(server, beside)["status"] == "done"
    wait_for(lambda: _analysis_process(victim) is None, 10, "the child to be reaped")
    return _assert_readable(result["error"], tmp_path)


def test_decoder_crash_fails_that_analysis_alone(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    server = serve(analysis_workers=2)
    long_video = write_video(tmp_path / "long.avi", frames=900).read_bytes()
    expected = {
        signal.SIGSEGV: "the decoder crashed (signal 11, SIGSEGV) on this file",
        signal.SIGKILL: "the analysis process was killed (signal 9, SIGKILL)",
    }
    with _live_camera(server) as processed:
        for sig, reason in expected.items():
            error = _crash_beside_another(server, long_video, sig, tmp_path)
            assert error.startswith(reason), error
        after = _upload(server, "next.avi", write_video(tmp_path / "n.avi", 30).read_bytes())
        assert _finished(server, after)["status"] == "done"
        _assert_still_serving(server, processed)


def test_a_file_sent_without_a_file_name_is_refused_briefly(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    # A multipart part with an empty file name reaches the app as a plain form field.
    server = serve()
    video = write_video(tmp_path / "clip.avi", frames=20).read_bytes()
    response = _post(server, "", video)
    assert response.status_code == 422
    assert len(response.content) < 2000, "the file came back in the error"
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "file"]
    assert error["msg"] == "expected a file: a multipart part with a file name"
    assert error["input"].endswith(" characters)")
