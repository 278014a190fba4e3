"""The whole server on PostgreSQL (``VIGIL_DATABASE_URL``), on a real uvicorn and as
``vigil serve``: a camera activated, its alarm, event, snapshot and clip, every row in
PostgreSQL and none in SQLite; restarted on the same database; the password never shown."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import httpx
import psycopg
import pytest

from app.storage import migrate
from tests.api.vigil_livekit import (
    ROOT,
    WsClient,
    add_camera,
    free_port,
    live_settings,
    running_server,
    serve_process,
    wait_for,
    write_video,
)
from tests.postgres import Cluster


def _rows(url: str, sql: str) -> list[tuple[object, ...]]:
    with psycopg.connect(url) as conn:
        return conn.execute(sql).fetchall()  # type: ignore[arg-type]


def test_activate_alarm_event_snapshot_and_clip_live_in_postgresql(
    postgres: Cluster, postgres_url: str, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="vigil")
    video = write_video(tmp_path / "door.avi", frames=75)
    data = tmp_path / "data"
    settings = live_settings(data, database_url=postgres_url, pre_roll_s=1.0, post_roll_s=0.5)
    with running_server(settings) as server, WsClient(server.ws) as ws:
        health = httpx.get(f"{server.base}/api/health")
        assert health.json()["database"] == {"engine": "postgresql"}
        assert postgres.password not in health.text
        said = [r.getMessage() for r in caplog.records]
        assert f"database: postgresql, {postgres_url.replace(postgres.password, '***')}" in said
        assert f"database: schema migrated from none to {migrate.head()}" in said
        assert not [line for line in said if postgres.password in line]
        camera = add_camera(server.base, f"file://{video}", "door", activate=True)
        alarm = ws.wait("alarm", 30, camera_id=camera)[0]
        snapshot = httpx.get(server.base + alarm["snapshot"])
        assert snapshot.status_code == 200 and snapshot.content[:2] == b"\xff\xd8"
        end = ws.wait("motion_end", 30, camera_id=camera)[0]
        assert end["event_id"] == alarm["event_id"]
        url = f"{server.base}/api/events/{end['event_id']}"
        event = wait_for(
            lambda: (e := httpx.get(url).json())["clip_s"] is not None and e, 15, "the clip"
        )
        clip = httpx.get(server.base + event["clip"])
        assert clip.status_code == 200 and clip.content[4:8] == b"ftyp"
        assert len(clip.content) == event["clip_bytes"] > 0
        storage = httpx.get(f"{server.base}/api/health").json()["storage"]
        assert storage["clips_mb"] > 0 and storage["snapshots_mb"] > 0

    # Written by the camera's process and the server, all in PostgreSQL.
    ((name, active),) = _rows(postgres_url, "SELECT name, active FROM cameras")
    assert (name, active) == ("door", 1)
    events = _rows(postgres_url, "SELECT id, ended_at, clip_bytes FROM events ORDER BY id")
    assert events[0][0] == alarm["event_id"] and all(e[1] is not None for e in events)
    snapshots = _rows(postgres_url, "SELECT event_id, size FROM snapshots")
    assert {e for e, _ in snapshots} >= {alarm["event_id"]}
    (totals,) = _rows(
        postgres_url,
        "SELECT (SELECT SUM(bytes) FROM snapshot_usage), (SELECT SUM(size) FROM snapshots),"
        " (SELECT SUM(bytes) FROM clip_usage), (SELECT SUM(clip_bytes) FROM events)",
    )
    assert totals[0] == totals[1] and totals[2] == totals[3] >= event["clip_bytes"]
    assert _rows(postgres_url, "SELECT COUNT(*) FROM activity")[0][0] > 0
    assert not (data / "vigil.db").exists(), "nothing in SQLite"


def test_serve_on_postgresql_keeps_its_cameras_across_restarts_and_hides_the_password(
    postgres: Cluster, postgres_url: str, tmp_path: Path
) -> None:
    env = {"VIGIL_DATABASE_URL": postgres_url, "VIGIL_DEMO_CAMERA": "false"}
    with serve_process(tmp_path / "first", **env) as (process, base):
        camera = add_camera(base, "demo", "lane")
        assert httpx.get(f"{base}/api/health").json()["database"] == {"engine": "postgresql"}
        process.kill()
        output = process.communicate(timeout=10)[0]
    assert postgres.password not in output
    # Another data folder, the same database: a second node's view, one at a time.
    with serve_process(tmp_path / "second", **env) as (process, base):
        cameras = httpx.get(f"{base}/api/cameras").json()
        assert [(c["id"], c["name"]) for c in cameras] == [(camera, "lane")]
        process.kill()
        output = process.communicate(timeout=10)[0]
    assert postgres.password not in output


def test_serve_refuses_a_database_it_cannot_use_in_one_line_without_its_password(
    postgres: Cluster, tmp_path: Path
) -> None:
    secret = "hunter2-secret"
    closed = f"postgresql://vigil:{secret}@127.0.0.1:{free_port()}/vigil"
    wrong = postgres.url("postgres", password=secret)
    for url, reason in (
        ("mysql://vigil:hunter2-secret@host/vigil", "VIGIL_DATABASE_URL"),
        (closed, "Connection refused"),
        (wrong, "password authentication failed"),
    ):
        done = subprocess.run(
            [sys.executable, "-m", "app", "serve", "--port", str(free_port())],
            cwd=ROOT,
            env={
                **os.environ,
                "PYTHONPATH": str(ROOT),
                "VIGIL_DATA_DIR": str(tmp_path),
                "VIGIL_DATABASE_URL": url,
            },
            capture_output=True,
            text=True,
            timeout=60,
        )
        output = done.stdout + done.stderr
        assert done.returncode == 2 and reason in output, output
        assert len(output.strip().splitlines()) == 1 and secret not in output, output
