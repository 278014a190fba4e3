"""Uploads: analysed in a separate process to done with progress; a corrupt file fails alone."""

from __future__ import annotations

import csv
import io
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx

from tests.api.vigil_livekit import Running, WsClient, wait_for, write_video


def _upload(server: Running, path: Path, **fields: Any) -> str:
    with path.open("rb") as handle:
        response = httpx.post(
            f"{server.base}/api/analyses",
            data=fields,
            files={"file": (path.name, handle, "video/x-msvideo")},
            timeout=30,
        )
    assert response.status_code == 202, response.text
    return str(response.json()["id"])


def _finished(server: Running, analysis_id: str, timeout: float = 60) -> dict[str, Any]:
    def state() -> dict[str, Any] | None:
        body = httpx.get(f"{server.base}/api/analyses/{analysis_id}").json()
        return body if body["status"] in ("done", "failed") else None

    result: dict[str, Any] = wait_for(state, timeout, f"analysis {analysis_id} to finish", 0.2)
    return result


def test_upload_is_analysed_with_progress(serve: Callable[..., Running], tmp_path: Path) -> None:
    server = serve()
    video = write_video(tmp_path / "clip.avi", frames=150)
    with WsClient(server.ws) as ws:
        analysis_id = _upload(server, video, min_area="50")
        result = _finished(server, analysis_id)
        assert result["status"] == "done", result["error"]
        progress = [m["progress"] for m in ws.wait("progress", 5, count=2, analysis_id=analysis_id)]
    assert progress == sorted(progress) and progress[-1] == 1.0
    assert result["progress"] == 1.0 and result["error"] is None
    report = result["report"]
    assert report["frames"] == 150 and report["tracks"], "the square should be tracked"
    assert report["input"] == "clip.avi"  # as uploaded, not where the server keeps it
    assert report["settings"]["min_area"] == 50
    tracks = httpx.get(f"{server.base}/api/analyses/{analysis_id}/tracks.csv")
    rows = list(csv.DictReader(io.StringIO(tracks.text)))
    assert rows and set(rows[0]) >= {"frame", "track_id", "speed_px_s"}
    avi = httpx.get(f"{server.base}/api/analyses/{analysis_id}/annotated.avi")
    assert avi.status_code == 200 and avi.content[:4] == b"RIFF"
    mp4_url = server.base + result["links"]["annotated_mp4"]
    mp4 = httpx.get(mp4_url)
    assert mp4.status_code == 200 and mp4.headers["content-type"] == "video/mp4"
    assert mp4.content[4:8] == b"ftyp"
    part = httpx.get(mp4_url, headers={"Range": "bytes=8-1007"})
    assert part.status_code == 206 and part.content == mp4.content[8:1008]
    assert part.headers["content-range"] == f"bytes 8-1007/{len(mp4.content)}"
    # The chapters the page offers: events.json's events.
    assert [e["start_time_s"] for e in result["events"]] and result["events"][0]["id"] == 1
    with httpx.stream("GET", f"{server.base}/api/analyses/{analysis_id}/stream.mjpg") as r:
        body = b"".join(r.iter_bytes())  # A finished analysis: its last frame, then the end.
    assert body.count(b"\xff\xd8") == 1
    listed = httpx.get(f"{server.base}/api/analyses").json()
    assert [a["id"] for a in listed] == [analysis_id]


def test_corrupt_upload_fails_alone(serve: Callable[..., Running], tmp_path: Path) -> None:
    server = serve()
    junk = tmp_path / "broken.avi"
    junk.write_bytes(b"RIFF\x00\x00\x00\x00AVI LIST" + bytes(range(256)) * 40)
    bad = _upload(server, junk)
    good = _upload(server, write_video(tmp_path / "ok.avi", frames=30))
    failed = _finished(server, bad)
    assert failed["status"] == "failed"
    assert failed["error"] and "\n" not in failed["error"] and len(failed["error"]) < 300
    assert "decode" in failed["error"] or "frames" in failed["error"]
    assert _finished(server, good)["status"] == "done"
    assert httpx.get(f"{server.base}/api/health").json()["status"] == "ok"
    missing = httpx.get(f"{server.base}/api/analyses/{bad}/tracks.csv")
    assert missing.status_code == 404 and "failed" in missing.json()["detail"]


def test_upload_limits(serve: Callable[..., Running], tmp_path: Path) -> None:
    server = serve(max_upload_mb=1)
    big = tmp_path / "big.avi"
    big.write_bytes(b"\0" * (1024 * 1024 + 10))
    with big.open("rb") as handle:
        response = httpx.post(f"{server.base}/api/analyses", files={"file": ("big.avi", handle)})
    assert response.status_code == 413
    empty = httpx.post(f"{server.base}/api/analyses", files={"file": ("e.avi", b"")})
    assert empty.status_code == 422
    odd = httpx.post(
        f"{server.base}/api/analyses", files={"file": ("x.avi", b"x")}, data={"method": "magic"}
    )
    assert odd.status_code == 422
    # A minimum area no frame can hold, and fields the upload does not know (misspelt).
    for fields, named in (
        ({"min_area": "1e26"}, "min_area"),
        ({"min-area": "50"}, "min-area"),
        ({"sensitivity": "10", "mask": "x"}, "mask"),
        ({"detect_width": "7"}, "detect_width is 0 (full size) or 32 to 7680 pixels, not 7"),
        ({"detect_width": "9000"}, "detect_width"),
    ):
        refused = httpx.post(
            f"{server.base}/api/analyses", files={"file": ("x.avi", b"x")}, data=fields
        )
        assert refused.status_code == 422 and named in refused.json()["detail"], refused.text
    assert httpx.get(f"{server.base}/api/analyses/ffff").status_code == 404


def test_oversized_upload_refused_before_reading(serve: Callable[..., Running]) -> None:
    import socket
    from urllib.parse import urlparse

    server = serve(max_upload_mb=1)
    url = urlparse(server.base)
    with socket.create_connection((url.hostname, url.port), timeout=10) as conn:
        conn.sendall(
            b"POST /api/analyses HTTP/1.1\r\nHost: x\r\n"
            b"Content-Type: multipart/form-data; boundary=b\r\n"
            + f"Content-Length: {50 * 1024 * 1024}\r\n\r\n".encode()
            + b"x" * 1024
        )
        reply = conn.recv(65536)  # Answered without the other 50 MB being sent.
    assert reply.startswith(b"HTTP/1.1 413") and b"1 MB" in reply


def test_chunked_upload_past_the_limit_is_cut_off_unspooled(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    """No Content-Length to refuse by: the body is counted as it arrives and cut at 1 MB."""
    import socket
    from urllib.parse import urlparse

    server = serve(tmp_path / "data", max_upload_mb=1)
    url = urlparse(server.base)
    head = (
        b'--b\r\nContent-Disposition: form-data; name="file"; filename="big.avi"\r\n'
        b"Content-Type: video/x-msvideo\r\n\r\n"
    )
    chunk = b"x" * 65536
    with socket.create_connection((url.hostname, url.port), timeout=10) as conn:
        conn.sendall(
            b"POST /api/analyses HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n"
            b"Content-Type: multipart/form-data; boundary=b\r\n\r\n"
            + f"{len(head):x}\r\n".encode()
            + head
            + b"\r\n"
        )
        sent = 0
        try:
            while sent < 800:  # 50 MB offered; the server stops reading at about 2.
                conn.sendall(f"{len(chunk):x}\r\n".encode() + chunk + b"\r\n")
                sent += 1
        except OSError:
            pass  # The server answered and closed: what we want.
        reply = conn.recv(65536)
    assert reply.startswith(b"HTTP/1.1 413") and b"1 MB" in reply
    assert sent < 800, "the server read the whole body before refusing it"
    analyses = tmp_path / "data" / "analyses"
    assert not any(analyses.rglob("input*")), "nothing of the refused upload is kept"
    assert httpx.get(f"{server.base}/api/health").json()["status"] == "ok"


def test_json_bodies_are_capped_too(serve: Callable[..., Running]) -> None:
    server = serve()
    huge = b'{"name": "' + b"x" * (2 << 20) + b'"}'
    declared = httpx.post(f"{server.base}/api/cameras", content=huge)
    assert declared.status_code == 413 and "KB" in declared.json()["detail"]
    streamed = httpx.post(
        f"{server.base}/api/cameras",
        content=iter([huge[i : i + 65536] for i in range(0, len(huge), 65536)]),
        headers={"Content-Type": "application/json"},
    )
    assert streamed.status_code == 413
    assert httpx.get(f"{server.base}/api/cameras").json() == []


def test_an_upload_takes_a_detection_width_and_a_min_area_of_0(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    # The report's warning of objects too small at the detection size names the width
    # to use, which the upload refused; and a min area of 0 became the default 100.
    server = serve()
    video = write_video(tmp_path / "clip.avi", frames=30)
    result = _finished(server, _upload(server, video, min_area="0", detect_width="0"))
    assert result["status"] == "done", result["error"]
    settings = result["report"]["settings"]
    assert settings["min_area"] == 0 and settings["detect_width"] == 0
