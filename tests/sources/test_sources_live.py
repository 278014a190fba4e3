"""Live sources: parsing, the demo scene, a looped file, a real HTTP MJPEG camera on loopback."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import cv2
import numpy as np
import pytest

from app.sources.frames import FrameError, JpegFrame
from app.sources.live import (
    CaptureSource,
    DemoSource,
    FileSource,
    FolderSource,
    SourceError,
    open_source,
    parse_source,
    why_not_open,
    with_stored_password,
    without_password,
)
from tests.api.vigil_livekit import FPS, MjpegCamera, write_video


@pytest.mark.parametrize(
    ("text", "kind", "target"),
    [
        ("demo", "demo", "demo"),
        (" DEMO ", "demo", "demo"),
        ("0", "device", "0"),
        ("/dev/video2", "device", "/dev/video2"),
        ("rtsp://cam.local:554/stream", "rtsp", "rtsp://cam.local:554/stream"),
        ("http://10.0.0.5/video.mjpg", "http", "http://10.0.0.5/video.mjpg"),
        ("https://cam.example/mjpg", "http", "https://cam.example/mjpg"),
        ("file:///srv/clips/a%20b.avi", "file", "/srv/clips/a b.avi"),
        ("file://localhost/srv/x.avi", "file", "/srv/x.avi"),
        ("/srv/clips/x.avi", "file", "/srv/clips/x.avi"),
    ],
)
def test_parse_source(text: str, kind: str, target: str) -> None:
    spec = parse_source(text)
    assert (spec.kind, spec.target) == (kind, target)


@pytest.mark.parametrize(
    "text",
    [
        "",
        "   ",
        "ftp://x/y",
        "http://",
        "http://cam:99999/x",
        "rtsp://cam:0x/live",
        "http://cam:0/x",
    ],
)
def test_parse_source_rejects(text: str) -> None:
    with pytest.raises(ValueError):
        parse_source(text)


@pytest.mark.parametrize("text", ["-1", " -2 ", "-0", "-10", "1000", "99999999999999999999"])
def test_a_device_index_out_of_range_is_refused_not_taken_for_a_file(text: str) -> None:
    with pytest.raises(ValueError, match=r"device index .* 0 to 999"):
        parse_source(text)


@pytest.mark.parametrize(
    "source",
    ["http://admin:s3cret@/video.mjpg", "rtsp://admin:s3cret@/live", "rtsp://admin:s3cret@:554/x"],
)
def test_parse_source_reasons_leave_out_passwords(source: str) -> None:
    with pytest.raises(ValueError, match="no host") as refused:
        parse_source(source)
    assert "s3cret" not in str(refused.value)


@pytest.mark.parametrize(
    ("source", "logged"),
    [
        ("rtsp://admin:s3cret@10.0.0.5:554/live", "rtsp://admin:***@10.0.0.5:554/live"),
        ("http://u:p%40ss:word@cam/video.mjpg?x=1", "http://u:***@cam/video.mjpg?x=1"),
        ("http://viewer@cam/video.mjpg", "http://viewer@cam/video.mjpg"),
        ("rtsp://cam/live", "rtsp://cam/live"),
        ("/videos/yard.avi", "/videos/yard.avi"),
        # The API shows sources so too: whatever has no password comes back exactly.
        ("demo", "demo"),
        ("0", "0"),
        ("/dev/video0", "/dev/video0"),
        ("file:///x.avi", "file:///x.avi"),
        ("rtsp://127.0.0.1:8554/x", "rtsp://127.0.0.1:8554/x"),
        ("http://h/x?", "http://h/x?"),
        ("rtsp://cam/stream@2", "rtsp://cam/stream@2"),  # An @ in the path: no user.
        ("rtsp://[fe80::1]:554/live", "rtsp://[fe80::1]:554/live"),
        ("https://viewer:@cam/a", "https://viewer:***@cam/a"),  # Empty, still a password.
        ("https://:pw@cam/a", "https://:***@cam/a"),
        ("RTSP://Admin:pw@Cam/A", "RTSP://Admin:***@Cam/A"),
        ("rtsp://admin:p@ss@cam/a@b", "rtsp://admin:***@cam/a@b"),  # The last @ ends it.
        ("rtsp://admin:pw@[fe80::1%25eth0]:554/live", "rtsp://admin:***@[fe80::1%25eth0]:554/live"),
        ("rtsp://admin:pw@[::1]/x#frag", "rtsp://admin:***@[::1]/x#frag"),
        ("http://cam/v.cgi?user=admin&pwd=pw&x=1", "http://cam/v.cgi?user=admin&pwd=***&x=1"),
        ("http://cam/v?Password=pw#top", "http://cam/v?Password=***#top"),
        ("http://cam/v?passes=1&pass=pw", "http://cam/v?passes=1&pass=***"),
        ("http://cam/pwd=x/v", "http://cam/pwd=***/v"),  # Path parameters too:
        (
            "rtsp://dvr:554/user=admin&password=pw&channel=1&stream=0.sdp",  # XMEye DVRs,
            "rtsp://dvr:554/user=admin&password=***&channel=1&stream=0.sdp",
        ),
        ("http://cam/v.cgi?loginuse=a&loginpas=pw", "http://cam/v.cgi?loginuse=a&loginpas=***"),
        ("http://cam/v?user=a;pwd=pw;res=1", "http://cam/v?user=a;pwd=***;res=1"),
        ("http://cam/compwd=x", "http://cam/compwd=x"),  # Not a parameter's whole name.
        ("http://cam/v?token=t0k&auth=u:p", "http://cam/v?token=***&auth=***"),
    ],
)
def test_sources_are_shown_without_passwords(source: str, logged: str) -> None:
    assert without_password(source) == logged


STORED = "rtsp://admin:s3cret@10.0.0.5:554/stream"


@pytest.mark.parametrize(
    ("sent", "stored", "kept"),
    [
        ("rtsp://admin:***@10.0.0.5:554/stream", STORED, STORED),  # As the API shows it.
        (STORED, STORED, STORED),
        ("rtsp://admin:new@10.0.0.5:554/stream", STORED, "rtsp://admin:new@10.0.0.5:554/stream"),
        ("rtsp://10.0.0.6/stream", STORED, "rtsp://10.0.0.6/stream"),
        ("demo", STORED, "demo"),
        ("rtsp://admin:***@10.0.0.5:554/sub", STORED, "rtsp://admin:s3cret@10.0.0.5:554/sub"),
        ("RTSP://admin:***@10.0.0.5:554/x", STORED, "RTSP://admin:s3cret@10.0.0.5:554/x"),
        ("rtsp://admin:***@[::1]/b", "rtsp://admin:pw@[::1]/a", "rtsp://admin:pw@[::1]/b"),
        (
            "http://cam/v.cgi?user=admin&pwd=***&res=2",
            "http://cam/v.cgi?user=admin&pwd=pw",
            "http://cam/v.cgi?user=admin&pwd=pw&res=2",
        ),
        ("rtsp://admin:***@cam/x", "rtsp://admin:***@cam/x", "rtsp://admin:***@cam/x"),
    ],
)
def test_a_source_sent_back_masked_keeps_its_password(sent: str, stored: str, kept: str) -> None:
    assert with_stored_password(sent, stored) == kept


@pytest.mark.parametrize(
    "sent",
    [
        "rtsp://admin:***@10.0.0.6:554/stream",  # Another host,
        "rtsp://admin:***@10.0.0.5:8554/stream",  # port,
        "rtsp://root:***@10.0.0.5:554/stream",  # user,
        "rtsps://admin:***@10.0.0.5:554/stream",  # scheme.
        "rtsp://admin:s3cret@10.0.0.5:554/stream?pwd=***",  # No such password stored.
    ],
)
def test_the_mask_never_sends_the_password_elsewhere(sent: str) -> None:
    with pytest.raises(ValueError, match="type the password") as refused:
        with_stored_password(sent, STORED)
    assert "s3cret" not in str(refused.value)
    with pytest.raises(ValueError, match="type the password"):
        with_stored_password(sent, "demo")


def test_the_mask_keeps_a_parameter_password_to_its_user() -> None:
    stored = "http://cam/v.cgi?user=admin&pwd=s3cret"
    kept = with_stored_password("http://cam/v.cgi?user=admin&pwd=***&res=2", stored)
    assert kept == "http://cam/v.cgi?user=admin&pwd=s3cret&res=2"
    with pytest.raises(ValueError, match="type the password"):
        with_stored_password("http://cam/v.cgi?user=root&pwd=***", stored)


def test_demo_loops_with_motion() -> None:
    source = DemoSource()
    assert source.paced and source.fps == 15.0
    frames = [source.read() for _ in range(source.scene.frames + 3)]
    assert frames[0].image().shape == (480, 640, 3)
    assert (frames[-3].image() == frames[0].image()).all(), "the scene loops"
    assert len({len(source.scene.truth(i)) for i in range(source.scene.frames)}) > 1
    assert max(len(source.scene.truth(i)) for i in range(source.scene.frames)) >= 2


def test_file_loops_at_its_own_rate(tmp_path: Path) -> None:
    source = open_source(parse_source(f"file://{write_video(tmp_path / 'x.avi', frames=10)}"))
    assert isinstance(source, FileSource)
    assert source.paced and source.fps == pytest.approx(FPS)
    frames = [source.read() for _ in range(25)]  # Two and a half loops.
    assert all(f.image().shape == (240, 320, 3) for f in frames)
    source.close()


def test_a_file_deleted_under_its_camera_is_named_at_the_next_loop(tmp_path: Path) -> None:
    video = write_video(tmp_path / "x.avi", frames=3)
    source = open_source(parse_source(f"file://{video}"))
    for _ in range(3):  # The whole loop, read while the file is there.
        source.read()
    video.unlink()
    with pytest.raises(SourceError, match="file not found"):
        source.read()
    source.close()


def test_a_folder_of_images_loops_by_name(tmp_path: Path) -> None:
    """A folder of pictures is a file source: its images in name order (2 before 10, JPEG
    and PNG alike), looped at 25 fps; a picture that does not decode is a bad frame."""
    folder = tmp_path / "frames"
    folder.mkdir()
    for index in range(12):
        picture = np.full((48, 64, 3), 20 * index, np.uint8)
        cv2.imwrite(str(folder / f"f{index}.{'png' if index % 2 else 'jpg'}"), picture)
    (folder / "f5.png").write_bytes(b"not a picture")
    (folder / "readme.txt").write_text("not a frame")
    source = open_source(parse_source(f"file://{folder}"))
    assert isinstance(source, FolderSource)
    assert source.paced and source.fps == 25.0
    assert source.description == "folder frames: 12 images at 25 fps"
    levels = []
    for index in range(30):  # Two and a half loops.
        try:
            frame = source.read()
            levels.append(round(float(frame.image().mean()) / 20))
        except FrameError:
            levels.append(None)
            continue
        # A JPEG is handed over undecoded, as a camera's are: an idle camera decodes none.
        assert isinstance(frame, JpegFrame) == (index % 12 % 2 == 0)
    loop = [0, 1, 2, 3, 4, None, 6, 7, 8, 9, 10, 11]
    assert levels == (loop * 3)[:30]
    source.close()
    (folder / "f5.png").unlink()
    cv2.imwrite(str(folder / "f99.png"), np.zeros((96, 128, 3), np.uint8))
    again = open_source(parse_source(str(folder)))
    for _ in range(11):
        assert again.read().image().shape == (48, 64, 3)
    # A camera whose resolution was changed goes on at the new size, loop after loop.
    assert again.read().image().shape == (96, 128, 3)
    assert again.read().image().shape == (48, 64, 3), "then it goes on, from the first"
    for name in [p.name for p in folder.iterdir()]:
        (folder / name).unlink()
    for _ in range(11):
        with contextlib.suppress(FrameError):  # Gone since the loop began.
            again.read()
    with pytest.raises(SourceError, match="no image frames in folder"):
        again.read()
    again.close()
    (tmp_path / "empty").mkdir()
    with pytest.raises(SourceError, match="no image frames in folder"):
        open_source(parse_source(str(tmp_path / "empty")))


def with_orientation(jpeg: bytes, orientation: int) -> bytes:
    """``jpeg`` with an EXIF segment saying how to turn it (6: a quarter turn clockwise)."""
    ifd = b"\x00\x01" + b"\x01\x12\x00\x03\x00\x00\x00\x01" + bytes([0, orientation, 0, 0])
    tiff = b"MM\x00\x2a\x00\x00\x00\x08" + ifd + b"\x00\x00\x00\x00"
    segment = b"Exif\x00\x00" + tiff
    return jpeg[:2] + b"\xff\xe1" + (len(segment) + 2).to_bytes(2, "big") + segment + jpeg[2:]


def test_a_jpeg_turned_by_exif_is_upright_in_a_folder_and_as_its_header_from_a_camera(
    tmp_path: Path,
) -> None:
    # A phone picture is stored sideways with a tag to turn it. In a folder it is
    # upright, as `vigil analyze` reads it; a camera's JPEG is the picture its header
    # describes, or boxes found on one would be drawn on the other.
    picture = np.zeros((48, 64, 3), np.uint8)
    picture[:, :32] = 250
    ok, encoded = cv2.imencode(".jpg", picture)
    assert ok
    turned = with_orientation(encoded.tobytes(), 6)
    folder = tmp_path / "phone"
    folder.mkdir()
    for index in range(2):
        (folder / f"{index}.jpg").write_bytes(turned)
    frame = open_source(parse_source(str(folder))).read()
    assert frame.size == (48, 64) and frame.image().shape == (64, 48, 3)
    assert frame.image()[:32].mean() > 200 and frame.image()[32:].mean() < 50
    assert JpegFrame(turned).size == (64, 48)
    assert JpegFrame(turned).image().shape == (48, 64, 3)
    assert JpegFrame(turned).gray(32).shape == (24, 32)  # Detection's scaled decode too.


def test_file_errors_are_readable(tmp_path: Path) -> None:
    with pytest.raises(SourceError, match="file not found"):
        open_source(parse_source(str(tmp_path / "none.avi")))
    junk = tmp_path / "junk.avi"
    junk.write_bytes(b"not a video at all" * 100)
    with pytest.raises(SourceError):
        source = open_source(parse_source(str(junk)))
        source.read()


def test_missing_device_is_an_error() -> None:
    with pytest.raises(SourceError, match="no camera"):
        open_source(parse_source("7"))


def test_http_mjpeg_camera() -> None:
    camera = MjpegCamera().start()
    try:
        source = open_source(parse_source(camera.url), 3000, 2000)
        assert isinstance(source, CaptureSource) and not source.paced
        frames = [source.read() for _ in range(5)]
        assert all(f.image().shape == (240, 320, 3) for f in frames)
        camera.stop()  # The camera dies: read() gives up within the read timeout.
        started = time.monotonic()
        with pytest.raises(SourceError, match="stream lost"):
            for _ in range(100):
                source.read()
        assert time.monotonic() - started < 6
        source.close()
    finally:
        camera.stop()


def test_unreachable_stream_fails_fast() -> None:
    camera = MjpegCamera().start()
    url = camera.url
    camera.stop()  # Nobody listens on that port any more.
    started = time.monotonic()
    with pytest.raises(SourceError, match="cannot open stream"):
        open_source(parse_source(url), 1000, 1000)
    assert time.monotonic() - started < 5


def test_device_path_uses_the_capture_code_path(tmp_path: Path) -> None:
    # No /dev/video* here: a device given by path goes through the same capture code.
    source = CaptureSource.device(str(write_video(tmp_path / "dev.avi", frames=5)))
    assert not source.paced
    assert source.read().image().shape == (240, 320, 3)
    source.close()


def test_settings_from_environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from app.core.config import Settings

    monkeypatch.setenv("VIGIL_PORT", "9123")
    monkeypatch.setenv("VIGIL_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("VIGIL_PASSWORD", "pw")
    settings = Settings()
    assert (settings.port, settings.data_dir, settings.password) == (9123, tmp_path, "pw")
    assert settings.db_path == tmp_path / "vigil.db"
    assert Settings(port=1).port == 1


def test_why_a_network_camera_did_not_open_is_named(tmp_path: Path) -> None:
    """Asked again after FFmpeg failed, a camera says why: a refused login, a page that is
    not a picture stream, a port where nothing listens. Never with the password."""
    camera = MjpegCamera(auth=("admin", "right-pw")).start()
    page = tmp_path / "site"
    page.mkdir()
    (page / "index.html").write_text("<html>a router's login page</html>")
    web = ThreadingHTTPServer(
        ("127.0.0.1", 0), partial(SimpleHTTPRequestHandler, directory=str(page))
    )
    threading.Thread(target=web.serve_forever, daemon=True).start()
    with socket.socket() as unused:
        unused.bind(("127.0.0.1", 0))
        closed = unused.getsockname()[1]  # Nothing listens once this closes.
    try:
        wrong = why_not_open(f"http://admin:wrong-pw@127.0.0.1:{camera.port}/video.mjpg", 2000)
        assert "refused the user and password (HTTP 401)" in wrong and "wrong-pw" not in wrong
        right = why_not_open(f"http://admin:right-pw@127.0.0.1:{camera.port}/video.mjpg", 2000)
        assert right == ""  # It serves the stream: nothing more to say.
        html = why_not_open(f"http://127.0.0.1:{web.server_address[1]}/", 2000)
        assert "text/html, not a picture stream" in html
        missing = why_not_open(f"http://127.0.0.1:{web.server_address[1]}/x.mjpg", 2000)
        assert "HTTP 404" in missing
        for scheme in ("http", "rtsp"):
            refused = why_not_open(f"{scheme}://u:pw@127.0.0.1:{closed}/live", 2000)
            assert refused == f": nothing listens on port {closed}"
    finally:
        camera.stop()
        web.shutdown()
        web.server_close()
