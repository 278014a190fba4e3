"""Access control against a real uvicorn: login sessions, basic auth, throttle, CSRF, headers.

Plus no path traversal, `vigil hash-password` with VIGIL_PASSWORD_HASH, and the login page and
dashboard in Chromium under the Content-Security-Policy.
"""

from __future__ import annotations

import asyncio
import base64
import http.client
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from app.api.security import Access, PasswordHash
from tests.api.vigil_livekit import (
    ROOT,
    Running,
    read_mjpeg_frames,
    serve_process,
    wait_for_pictures,
)

PASSWORD = "correct horse"


@contextmanager
def logged_in(server: Running) -> Iterator[httpx.Client]:
    """A client holding the session cookie of a JSON login."""
    with httpx.Client(base_url=server.base, timeout=10) as client:
        response = client.post("/api/login", json={"password": PASSWORD})
        assert response.status_code == 200, response.text
        yield client


def cookie_header(client: httpx.Client) -> dict[str, str]:
    return {"Cookie": f"vigil_session={client.cookies['vigil_session']}"}


def ws_status(url: str, **kwargs: Any) -> int:
    """101 when /ws accepts the handshake, else the HTTP status it was refused with."""
    try:
        with connect(url, open_timeout=10, **kwargs):
            return 101
    except InvalidStatus as refused:
        return refused.response.status_code


def raw_get(server: Running, target: str) -> tuple[int, bytes]:
    """GET ``target`` byte for byte: no client-side normalisation of ``..`` or ``%2e``."""
    connection = http.client.HTTPConnection(server.base.removeprefix("http://"), timeout=10)
    try:
        connection.request("GET", target)
        response = connection.getresponse()
        return response.status, response.read()
    finally:
        connection.close()


def test_without_a_session_pages_redirect_and_the_rest_is_refused(
    serve: Callable[..., Running],
) -> None:
    server = serve(password=PASSWORD, demo_camera=True)
    base = server.base

    page = httpx.get(f"{base}/?tab=alarms")
    assert page.status_code == 303
    assert page.headers["location"] == "/login?next=/%3Ftab%3Dalarms"
    for path in ("/api/cameras", "/api/events", "/api/snapshots", "/api/analyses/abc"):
        refused = httpx.get(base + path)
        assert refused.status_code == 401, path
        assert "log in" in refused.json()["detail"]
    # Streams, single pictures and downloads: 401 before a byte of picture or file.
    for path in (
        "/api/cameras/1/stream.mjpg",
        "/api/cameras/1/frame.jpg",
        "/api/snapshots/1.jpg",
        "/api/snapshots.zip",
        "/api/analyses/abc/tracks.csv",
    ):
        assert httpx.get(base + path).status_code == 401, path
    written = httpx.post(f"{base}/api/cameras", json={"name": "x", "source": "demo"})
    assert written.status_code == 401
    assert ws_status(server.ws) == 403

    # Open to all: health, the login page and its form, static files.
    assert httpx.get(f"{base}/api/health").json()["status"] == "ok"
    login_page = httpx.get(f"{base}/login?next=/")
    assert login_page.status_code == 200 and 'type="password"' in login_page.text
    assert httpx.get(f"{base}/static/app.css").status_code == 200
    icon = httpx.get(f"{base}/favicon.ico")  # No 404 in the console of a page that names none.
    assert icon.status_code == 200 and icon.headers["content-type"] == "image/svg+xml"

    # The refused write did nothing: only the demo camera is there once logged in.
    with logged_in(server) as client:
        assert [c["source"] for c in client.get("/api/cameras").json()] == ["demo"]


def test_login_sets_a_strict_session_cookie_and_logout_ends_it(
    serve: Callable[..., Running],
) -> None:
    server = serve(password=PASSWORD, demo_camera=True)
    wrong = httpx.post(f"{server.base}/api/login", json={"password": "wrong"})
    assert wrong.status_code == 401 and wrong.json() == {"detail": "wrong password"}
    assert "set-cookie" not in wrong.headers
    # A field the login has no use for ("remember me") is refused, as in every JSON body.
    extra = httpx.post(f"{server.base}/api/login", json={"password": PASSWORD, "remember": 1})
    assert extra.status_code == 422 and "unknown field 'remember'" in extra.json()["detail"]
    assert "set-cookie" not in extra.headers
    right = httpx.post(f"{server.base}/api/login", json={"password": PASSWORD})
    flags = {part.strip().lower() for part in right.headers["set-cookie"].split(";")[1:]}
    assert flags == {"httponly", "path=/", "samesite=strict"}  # no Secure over plain http

    with logged_in(server) as client:
        cookie = client.cookies["vigil_session"]
        assert len(cookie) >= 40 and cookie != right.cookies["vigil_session"]
        cameras = client.get("/api/cameras")
        assert cameras.status_code == 200 and cameras.json()[0]["source"] == "demo"
        dashboard = client.get("/")
        assert dashboard.status_code == 200 and "Log out" in dashboard.text
        camera_id = cameras.json()[0]["id"]
        with client.stream("GET", f"/api/cameras/{camera_id}/stream.mjpg") as stream:
            assert stream.status_code == 200
            read_mjpeg_frames(stream.iter_bytes(), 1)
        assert ws_status(server.ws, additional_headers=cookie_header(client)) == 101

        logout = client.post("/api/logout")
        assert logout.status_code == 204
        assert 'vigil_session=""' in logout.headers["set-cookie"]
    # The old token is dead on the server, even when a client keeps sending it.
    stale = {"vigil_session": cookie}
    assert httpx.get(f"{server.base}/api/cameras", cookies=stale).status_code == 401
    assert ws_status(server.ws, additional_headers={"Cookie": f"vigil_session={cookie}"}) == 403
    forged = {"vigil_session": "forged"}
    assert httpx.get(f"{server.base}/api/cameras", cookies=forged).status_code == 401
    # Other sessions live on.
    alive = {"vigil_session": right.cookies["vigil_session"]}
    assert httpx.get(f"{server.base}/api/cameras", cookies=alive).status_code == 200


def test_logging_out_ends_the_streams_and_sockets_of_that_session(
    serve: Callable[..., Running],
) -> None:
    server = serve(password=PASSWORD, demo_camera=True)
    with logged_in(server) as client:
        camera_id = client.get("/api/cameras").json()[0]["id"]
        watching, ended = threading.Event(), threading.Event()

        def watch() -> None:
            try:
                with client.stream("GET", f"/api/cameras/{camera_id}/stream.mjpg") as stream:
                    chunks = stream.iter_bytes()
                    read_mjpeg_frames(chunks, 1)
                    watching.set()
                    for _ in chunks:
                        pass
            finally:
                ended.set()

        viewer = threading.Thread(target=watch, daemon=True)
        viewer.start()
        with connect(server.ws, open_timeout=10, additional_headers=cookie_header(client)) as ws:
            ws.recv(timeout=10)  # A status message: the socket is live.
            # The demo camera's first picture may take a while on a slow machine.
            assert watching.wait(20), "the stream showed no picture"
            time.sleep(0.5)
            assert not ended.is_set()
            assert client.post("/api/logout").status_code == 204
            with pytest.raises(ConnectionClosed) as closed:
                while True:
                    ws.recv(timeout=10)
            assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008
        assert ended.wait(10), "the MJPEG stream outlived the session"


def test_login_form_redirects_back_but_never_off_site(serve: Callable[..., Running]) -> None:
    server = serve(password=PASSWORD)
    url = f"{server.base}/api/login"
    back = httpx.post(url, data={"password": PASSWORD, "next": "/?tab=alarms"})
    assert back.status_code == 303 and back.headers["location"] == "/?tab=alarms"
    assert "vigil_session=" in back.headers["set-cookie"]
    for target in ("//evil.example/", "https://evil.example/", "/\\evil.example"):
        sent = httpx.post(url, data={"password": PASSWORD, "next": target})
        assert sent.headers["location"] == "/", target
    wrong = httpx.post(url, data={"password": "nope", "next": "/"})
    assert wrong.status_code == 401 and "Wrong password" in wrong.text
    assert "set-cookie" not in wrong.headers
    # A logged-in visitor of /login goes straight on; the form's logout leads back to /login.
    with httpx.Client(base_url=server.base, cookies=back.cookies) as client:
        assert client.get("/login?next=/").headers["location"] == "/"
        form = {"Content-Type": "application/x-www-form-urlencoded"}  # what a browser sends
        out = client.post("/api/logout", headers=form)
        assert out.status_code == 303 and out.headers["location"] == "/login"
        assert client.get("/").headers["location"] == "/login?next=/"
    too_big = httpx.post(url, data={"password": "x" * 10_000})
    assert too_big.status_code == 413


def test_idle_sessions_expire(serve: Callable[..., Running]) -> None:
    server = serve(password=PASSWORD, session_hours=1.5 / 3600)
    with logged_in(server) as client:
        for _ in range(5):  # In use for 3 s, longer than the idle limit: still valid.
            time.sleep(0.6)
            assert client.get("/api/cameras").status_code == 200
        time.sleep(2.5)
        assert client.get("/api/cameras").status_code == 401


def test_basic_auth_still_works_for_scripts(serve: Callable[..., Running]) -> None:
    server = serve(password=PASSWORD, demo_camera=True)
    cameras = httpx.get(f"{server.base}/api/cameras", auth=("any", PASSWORD))
    assert cameras.status_code == 200
    assert httpx.get(f"{server.base}/api/cameras", auth=("any", "wrong")).status_code == 401
    camera_id = cameras.json()[0]["id"]
    with httpx.stream(
        "GET", f"{server.base}/api/cameras/{camera_id}/stream.mjpg", auth=("", PASSWORD)
    ) as stream:
        read_mjpeg_frames(stream.iter_bytes(), 1)
    token = base64.b64encode(f":{PASSWORD}".encode()).decode()
    assert ws_status(server.ws, additional_headers={"Authorization": f"Basic {token}"}) == 101


def test_a_script_sending_the_password_each_time_costs_one_scrypt(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    hashed: list[str] = []
    verify = PasswordHash.verify

    def counted(self: PasswordHash, password: str) -> bool:
        hashed.append(password)
        return verify(self, password)

    monkeypatch.setattr(PasswordHash, "verify", counted)
    access = Access(PasswordHash.create(PASSWORD), 1.0, 5, 60.0)
    assert all(asyncio.run(access.verify("10.0.0.1", PASSWORD)) for _ in range(5))
    assert hashed == [PASSWORD]
    # A wrong password is hashed (and counted against its sender) every time.
    assert not any(asyncio.run(access.verify("10.0.0.2", "wrong")) for _ in range(2))
    assert hashed == [PASSWORD, "wrong", "wrong"]


def test_wrong_passwords_are_throttled_per_client_address(serve: Callable[..., Running]) -> None:
    server = serve(password=PASSWORD, login_max_failures=3, login_window_s=3)
    url = f"{server.base}/api/login"
    # A success resets the count: 2 wrong, right, 2 wrong is never throttled.
    for password in ("a", "b", PASSWORD, "c", "d"):
        expected = 200 if password == PASSWORD else 401
        assert httpx.post(url, json={"password": password}).status_code == expected
    assert httpx.post(url, json={"password": "e"}).status_code == 401  # the third in a row
    throttled = httpx.post(url, json={"password": PASSWORD})  # even the right one now
    assert throttled.status_code == 429
    retry_after = int(throttled.headers["retry-after"])
    assert 1 <= retry_after <= 3 and "try again" in throttled.json()["detail"]
    # Basic auth is no way around it, and the login form says so too.
    basic = httpx.get(f"{server.base}/api/cameras", auth=("", PASSWORD))
    assert basic.status_code == 429 and "retry-after" in basic.headers
    form = httpx.post(url, data={"password": PASSWORD})
    assert form.status_code == 429 and "Too many wrong passwords" in form.text

    # Another address is not held back by this one's failures.
    other = httpx.Client(transport=httpx.HTTPTransport(local_address="127.0.0.2"))
    with other:
        assert other.post(url, json={"password": PASSWORD}).status_code == 200

    time.sleep(retry_after + 0.2)
    assert httpx.post(url, json={"password": PASSWORD}).status_code == 200


@pytest.mark.parametrize("password", [None, PASSWORD])
def test_cross_site_writes_and_sockets_are_refused(
    serve: Callable[..., Running], password: str | None, tmp_path: Path
) -> None:
    server = serve(password=password)
    host = server.base.removeprefix("http://")
    add = {"name": "cam", "source": str(tmp_path / "absent.avi")}  # a camera that costs no CPU
    anonymous = httpx.Client(base_url=server.base, timeout=10)
    with logged_in(server) if password else anonymous as client:
        for headers in (
            {"Sec-Fetch-Site": "cross-site"},
            {"Sec-Fetch-Site": "same-site"},
            {"Origin": "http://evil.example"},
            {"Origin": f"http://{host}.evil.example"},
            {"Origin": "null"},
        ):
            refused = client.post("/api/cameras", json=add, headers=headers)
            assert refused.status_code == 403, headers
            assert "cross-site" in refused.json()["detail"]
        upload = client.post(
            "/api/analyses",
            files={"file": ("x.avi", b"RIFF")},
            headers={"Sec-Fetch-Site": "cross-site"},
        )
        assert upload.status_code == 403
        assert client.get("/api/cameras").json() == []  # nothing was added

        # The page's own requests, and clients that send neither header, pass.
        for headers in (
            {"Sec-Fetch-Site": "same-origin", "Origin": f"http://{host}"},
            {"Origin": f"http://{host}"},
            {},
        ):
            assert client.post("/api/cameras", json=add, headers=headers).status_code == 200
        assert len(client.get("/api/cameras", headers={"Sec-Fetch-Site": "cross-site"}).json()) == 3

        auth = cookie_header(client) if password else {}
        assert ws_status(server.ws, additional_headers=auth, origin="http://evil.example") == 403
        assert ws_status(server.ws, additional_headers=auth, origin=f"http://{host}") == 101


def test_security_headers_on_pages_api_and_streams(serve: Callable[..., Running]) -> None:
    server = serve(demo_camera=True)
    camera_id = httpx.get(f"{server.base}/api/cameras").json()[0]["id"]

    def assert_headers(headers: httpx.Headers) -> str:
        assert headers["x-content-type-options"] == "nosniff"
        assert headers["x-frame-options"] == "DENY"
        assert headers["referrer-policy"] == "no-referrer"
        csp = headers["content-security-policy"]
        assert "frame-ancestors 'none'" in csp
        return csp

    for path in ("/", "/api/health", "/api/cameras/999", "/static/js/main.js", "/login"):
        csp = assert_headers(httpx.get(server.base + path).headers)
        assert "default-src 'self'" in csp and "unsafe-inline" not in csp, path
    # An endless MJPEG stream gets them too, and still streams.
    with httpx.stream(
        "GET", f"{server.base}/api/cameras/{camera_id}/stream.mjpg", timeout=10
    ) as stream:
        assert_headers(stream.headers)
        assert len(read_mjpeg_frames(stream.iter_bytes(), 3)) == 3
    # FastAPI's /docs page loads its scripts from a CDN: it is only kept out of frames.
    assert assert_headers(httpx.get(f"{server.base}/docs").headers) == "frame-ancestors 'none'"
    # The analysis report is one file with an inline style sheet and data: charts, no script.
    report = assert_headers(httpx.get(f"{server.base}/api/analyses/ab12/report.html").headers)
    assert "style-src 'unsafe-inline'" in report and "script-src" not in report
    assert "default-src 'none'" in report


def test_no_file_outside_the_data_folder_is_served(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    data = tmp_path / "data"
    server = serve(data)
    (tmp_path / "secret.txt").write_text("TOP-SECRET")
    (tmp_path / "secret.jpg").write_text("TOP-SECRET")
    targets = [
        "/api/snapshots/../../secret.jpg",
        "/api/snapshots/..%2f..%2fsecret.jpg",
        "/api/snapshots/%2e%2e%2f%2e%2e%2fsecret.jpg",
        "/api/snapshots/%252e%252e%252fsecret.jpg",
        "/api/snapshots/..%5c..%5csecret.jpg",
        "/api/snapshots/..%2fvigil.db",
        "/api/analyses/../../secret.txt",
        "/api/analyses/..%2f..%2f/tracks.csv",
        "/api/analyses/%2e%2e/report.html",
        "/api/analyses/..%2f..%2fsecret.txt%00/annotated.avi",
        "/static/../../secret.txt",
        "/static/..%2f..%2f..%2fsecret.txt",
        "/static/%2e%2e/%2e%2e/secret.txt",
        "/static/../cli.py",
        "/static/..%2fcli.py",
        f"/static/{tmp_path}/secret.txt",
        "/static//etc/passwd",
    ]
    for target in targets:
        status, body = raw_get(server, target)
        assert status in (404, 422), (target, status)
        assert b"TOP-SECRET" not in body and b"SQLite" not in body and b"import" not in body


def test_open_static_prefix_is_no_way_around_the_password(serve: Callable[..., Running]) -> None:
    server = serve(password=PASSWORD)
    for target in ("/static/../api/cameras", "/static/..%2fapi/cameras", "/login/../api/cameras"):
        status, body = raw_get(server, target)
        assert status in (303, 401, 404), target
        assert b"[" not in body, target


def test_hash_password_command_and_a_serve_process_with_the_hash(tmp_path: Path) -> None:
    made = subprocess.run(
        [sys.executable, "-m", "app", "hash-password"],
        input=PASSWORD + "\n", capture_output=True, text=True, cwd=ROOT, timeout=60,
    )  # fmt: skip
    assert made.returncode == 0, made.stderr
    password_hash = made.stdout.strip()
    assert re.fullmatch(r"scrypt:32768:8:1:[0-9a-f]{32}:[0-9a-f]{64}", password_hash)
    again = subprocess.run(
        [sys.executable, "-m", "app", "hash-password"],
        input=PASSWORD + "\n", capture_output=True, text=True, cwd=ROOT, timeout=60,
    )  # fmt: skip
    assert again.stdout.strip() != password_hash  # a fresh salt each time

    env = {k: v for k, v in os.environ.items() if not k.startswith("VIGIL_")}
    bad = password_hash[:-6] + "zzzzzz"
    both = {"VIGIL_PASSWORD_HASH": password_hash, "VIGIL_PASSWORD": PASSWORD}
    for extra in ({"VIGIL_PASSWORD_HASH": bad}, both):
        refused = subprocess.run(
            [sys.executable, "-m", "app", "serve", "--host", "0.0.0.0", "--data", str(tmp_path)],
            capture_output=True, text=True, cwd=ROOT, env={**env, **extra}, timeout=60,
        )  # fmt: skip
        assert refused.returncode == 2
        assert len(refused.stderr.strip().splitlines()) == 1, refused.stderr
        assert "VIGIL_PASSWORD" in refused.stderr
        assert bad not in refused.stderr and password_hash not in refused.stderr

    serving = serve_process(tmp_path, VIGIL_PASSWORD_HASH=password_hash, VIGIL_DEMO_CAMERA="0")
    with serving as (process, base):
        assert httpx.get(f"{base}/api/cameras", auth=("", PASSWORD)).status_code == 200
        assert httpx.post(f"{base}/api/login", json={"password": "nope"}).status_code == 401
        assert httpx.post(f"{base}/api/login", json={"password": PASSWORD}).status_code == 200
        process.terminate()
        output, _ = process.communicate(timeout=15)
    assert PASSWORD not in output and password_hash not in output


@pytest.mark.browser
def test_login_and_dashboard_in_chromium_under_the_policy(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve(password=PASSWORD, demo_camera=True)
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.on(
        "console",
        lambda m: errors.append(m.text) if "Content Security Policy" in m.text else None,
    )

    page.goto(server.base + "/")
    assert page.url.endswith("/login?next=/")
    page.fill("#password", "wrong")
    page.click("button[type=submit]")
    page.wait_for_selector(".form-error")
    assert "Wrong password" in page.inner_text(".form-error")
    page.fill("#password", PASSWORD)
    page.click("button[type=submit]")
    page.wait_for_url(server.base + "/")

    # The whole dashboard works under the policy: pictures, live socket, chart, alarm, gallery.
    wait_for_pictures(page, 1, timeout_ms=20000, at_least=True)
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    page.wait_for_selector(".card .motion canvas", timeout=10000)
    page.locator(".card button.toggle").first.click()
    page.wait_for_selector("#alarm-list li img", timeout=30000)
    page.click("#gallery-filter button[type=submit]")
    page.wait_for_selector("#thumbs figure img", timeout=10000)
    assert page.evaluate("window.__csp") == []
    # The stylesheet (not an inline style, which the policy refuses) sizes the inputs.
    width_em = page.locator("#upload input[name=sensitivity]").evaluate(
        "e => parseFloat(getComputedStyle(e).width) / parseFloat(getComputedStyle(e).fontSize)"
    )
    assert width_em == pytest.approx(5.0, abs=0.05)

    # The session ends behind the page's back: its next request sends it to /login.
    page.context.clear_cookies()
    page.click("#gallery-filter button[type=submit]")
    page.wait_for_url(re.compile(r".*/login\?next=%2F$"), timeout=10000)
    page.fill("#password", PASSWORD)
    page.click("button[type=submit]")
    page.wait_for_url(server.base + "/")

    # Log out: back to the login page, and the dashboard is closed again.
    page.click("#logout")
    page.wait_for_url(re.compile(r".*/login$"))
    page.goto(server.base + "/")
    assert "/login" in page.url
    assert page.evaluate("window.__csp") == [] and errors == []


def test_no_log_out_button_without_a_password(serve: Callable[..., Running]) -> None:
    server = serve()
    dashboard = httpx.get(f"{server.base}/")
    assert dashboard.status_code == 200 and "Log out" not in dashboard.text
    assert httpx.get(f"{server.base}/login").headers["location"] == "/"
    assert httpx.post(f"{server.base}/api/login", json={"password": "x"}).status_code == 404
