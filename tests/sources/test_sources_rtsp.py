"""A real RTSP camera on loopback (skipped where gst-rtsp-server is not installed)."""

from __future__ import annotations

import itertools
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.sources.live import CaptureSource, SourceError, open_source, parse_source
from tests.api.vigil_livekit import free_socket

SYSTEM_PYTHON = "/usr/bin/python3"
SERVER = Path(__file__).with_name("rtsp_camera.py")


def _have_rtsp_server() -> bool:
    try:
        probe = subprocess.run(
            [
                SYSTEM_PYTHON,
                "-c",
                "import gi; gi.require_version('GstRtspServer', '1.0');"
                " from gi.repository import GstRtspServer",
            ],
            capture_output=True,
            timeout=20,
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return probe.returncode == 0


pytestmark = pytest.mark.skipif(
    not _have_rtsp_server(), reason="gst-rtsp-server (python3-gi) is not installed"
)


@pytest.fixture
def rtsp_url() -> Iterator[tuple[str, subprocess.Popen[str]]]:
    sock = free_socket()
    port = sock.getsockname()[1]
    sock.close()
    process = subprocess.Popen(
        [SYSTEM_PYTHON, str(SERVER), str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert process.stdout is not None
        assert process.stdout.readline().strip() == "ready"
        yield f"rtsp://127.0.0.1:{port}/cam", process
    finally:
        process.kill()
        process.wait(5)


def test_rtsp_camera_frames_and_loss(rtsp_url: tuple[str, subprocess.Popen[str]]) -> None:
    url, process = rtsp_url
    spec = parse_source(url)
    assert spec.kind == "rtsp"
    source = open_source(spec, 5000, 2000)
    assert isinstance(source, CaptureSource)
    frames = [source.read() for _ in range(10)]
    assert all(f.image().shape == (240, 320, 3) for f in frames)
    assert any((a.image() != b.image()).any() for a, b in itertools.pairwise(frames)), (
        "the ball moves"
    )
    process.kill()
    process.wait(5)
    started = time.monotonic()
    with pytest.raises(SourceError):
        for _ in range(200):
            source.read()
    assert time.monotonic() - started < 10
    source.close()
