"""Nodes as servers (app/nodes/keeper.py): two real servers sharing one real PostgreSQL run
each camera once; a camera activated on the node that does not run it alarms on the one
that does, which names itself in the event; a node that stops hands its cameras over at
once; a node taking over a dead node's camera ends the event it left open (motion_end);
over the broker every node shows every alarm; a node cut off from the database stops its
cameras once its leases have run out."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import httpx
from sqlalchemy import update

from app.storage import Database
from app.storage.schema import cameras
from tests.api.vigil_livekit import (
    Running,
    WsClient,
    add_camera,
    free_port,
    live_settings,
    running_server,
    wait_for,
    write_video,
)
from tests.mqtt.mosquitto import Mosquitto, retained
from tests.notify.receivers import WebhookReceiver
from tests.postgres import Cluster

LEASE_S = 3.0


def _node(tmp_path: Path, name: str, postgres_url: str | None, **more: Any) -> Any:
    """A node's settings; in a site, on a port of its own, the node's address
    (``http://127.0.0.1:<port>``) as the others reach it: ``_serve`` runs it there."""
    port = free_port() if postgres_url else 8000  # Alone: the default, never served.
    return live_settings(
        tmp_path / name,
        database_url=postgres_url,
        node_name=name,
        port=port,
        lease_s=LEASE_S,
        **more,
    )


def _serve(settings: Any) -> Any:
    return running_server(settings, port=settings.port if settings.database_url else 0)


def _live(base: str, node: str) -> list[int]:
    """The cameras ``node`` (served at ``base``) runs and shows live."""
    listed = httpx.get(f"{base}/api/cameras").json()
    return sorted(c["id"] for c in listed if c["state"] == "live" and c["node"] == node)


def _spread_evenly(north: Running, south: Running, ids: list[int]) -> dict[str, list[int]]:
    """Node name -> the cameras it runs live, once ``ids`` run half on each."""
    each = len(ids) // 2
    return wait_for(
        lambda: (
            (r := {"north": _live(north.base, "north"), "south": _live(south.base, "south")})
            and sorted(r["north"] + r["south"]) == ids
            and len(r["north"]) == len(r["south"]) == each
            and r
        ),
        30,
        f"{each} camera(s) live on each node",
    )


def test_two_nodes_run_each_camera_once_and_its_activation_and_pin_follow_it(
    postgres_url: str, tmp_path: Path
) -> None:
    video = write_video(tmp_path / "door.avi", frames=75)
    north_settings = _node(tmp_path, "north", postgres_url)
    south_settings = _node(tmp_path, "south", postgres_url)
    with (
        _serve(north_settings) as north,
        _serve(south_settings) as south,
        WsClient(south.ws) as south_ws,
    ):
        ids = [add_camera(north.base, f"file://{video}", f"cam{i}") for i in range(4)]
        running = _spread_evenly(north, south, ids)
        for server in (north, south):  # Both say where each camera runs.
            shown = {c["id"]: c["node"] for c in httpx.get(f"{server.base}/api/cameras").json()}
            assert shown == {i: n for n, held in running.items() for i in held}
        # North shows a camera south runs as south does: live, with its frame rate.
        elsewhere = wait_for(
            lambda: (
                (c := httpx.get(f"{north.base}/api/cameras/{running['south'][0]}").json())
                and c["state"] == "live"
                and c
            ),
            10,
            "north to show south's camera live",
        )
        assert elsewhere["node"] == "south" and elsewhere["fps"] > 0
        site = httpx.get(f"{south.base}/api/nodes").json()
        assert [(n["name"], n["cameras"], n["alive"]) for n in site] == [
            ("north", running["north"], True),
            ("south", running["south"], True),
        ]
        assert site[0]["url"] == north.base and site[0]["load"] == 2 / site[0]["capacity"]
        assert time.time() - site[1]["renewed_at"] < LEASE_S

        camera = running["south"][0]  # Activated on north, which does not run it.
        httpx.post(f"{north.base}/api/cameras/{camera}/activate").raise_for_status()
        alarm = south_ws.wait("alarm", 30, camera_id=camera)[0]
        event = httpx.get(f"{north.base}/api/events/{alarm['event_id']}").json()
        assert event["node"] == "south"

        usb = running["north"][0]  # Pinned to south (through north): it moves there.
        pinned = httpx.patch(f"{north.base}/api/cameras/{usb}", json={"pinned_to": "south"})
        assert pinned.json()["pinned_to"] == "south"
        wait_for(
            lambda: (
                _live(south.base, "south") == sorted([usb, *running["south"]])
                and _live(north.base, "north") == running["north"][1:]
            ),
            15,
            "the pinned camera on south",
        )

        stopped = time.monotonic()
        north.stop()  # Stopping, north gives its leases up: south need not wait for them.
        wait_for(lambda: _live(south.base, "south") == ids, 15, "south to run all four")
        assert time.monotonic() - stopped < LEASE_S + 5
        (alone,) = httpx.get(f"{south.base}/api/nodes").json()
        assert (alone["name"], alone["cameras"]) == ("south", ids)


def test_a_node_taking_over_ends_the_event_its_dead_node_left_open(
    postgres_url: str, tmp_path: Path
) -> None:
    video = write_video(tmp_path / "door.avi")
    with _serve(_node(tmp_path, "south", postgres_url)) as south, WsClient(south.ws) as ws:
        # As a node "ghost" killed during an event leaves it: its lease ran out, the
        # event is open.
        ghost = Database(postgres_url, migrate=False, node="ghost")
        camera = ghost.add_camera("door", f"file://{video}", "adaptive", 100.0)
        opened = ghost.add_event(camera, time.time() - 20, [[10, 10, 40, 40]], 1600.0)
        with ghost.transaction() as conn:
            lapsed = {"node": "ghost", "lease_until": time.time() - 5}
            conn.execute(update(cameras).where(cameras.c.id == camera).values(**lapsed))

        end = ws.wait("motion_end", 20, camera_id=camera)[0]
        assert end["event_id"] == opened
        event = ghost.event(opened)
        assert event is not None and event["ended_at"] == event["started_at"]
        assert event["node"] == "ghost"  # Made by ghost, ended by south.
        wait_for(lambda: _live(south.base, "south") == [camera], 15, "south to run the camera")
        assert httpx.get(f"{south.base}/api/cameras/{camera}").json()["node"] == "south"
        ghost.close()


def test_without_a_shared_database_the_node_is_alone_with_every_camera(tmp_path: Path) -> None:
    video = write_video(tmp_path / "door.avi")
    settings = _node(tmp_path, "lone", None)  # SQLite: no leases, every camera runs here.
    with _serve(settings) as server:
        ids = [add_camera(server.base, f"file://{video}", f"cam{i}") for i in range(2)]
        wait_for(lambda: _live(server.base, "lone") == ids, 15, "both cameras live")
        (node,) = httpx.get(f"{server.base}/api/nodes").json()
        assert (node["name"], node["cameras"], node["alive"]) == ("lone", ids, True)
        assert node["url"] == "http://127.0.0.1:8000"  # VIGIL_HOST and VIGIL_PORT's
        assert node["load"] == 2 / node["capacity"]
        assert {c["node"] for c in httpx.get(f"{server.base}/api/cameras").json()} == {"lone"}


def test_every_node_shows_every_alarm_and_only_the_cameras_node_notifies(
    postgres_url: str, tmp_path: Path
) -> None:
    """Over a real Mosquitto: each node's /ws carries the other node's alarms and
    motion_end (naming that node), once; a notification target of the site hears of each
    event once, from the camera's node; neither node removes the other's cameras from the
    broker; one node stopping leaves the site online."""
    broker = Mosquitto(tmp_path / "broker").start()
    webhook = WebhookReceiver().start()
    video = write_video(tmp_path / "door.avi", frames=300)  # One crossing every 20 s.
    shared = {"mqtt_url": broker.url, "mqtt_reconnect_max_s": 1.0, "notify_urls": webhook.url()}
    try:
        with (
            _serve(_node(tmp_path, "north", postgres_url, **shared)) as north,
            _serve(_node(tmp_path, "south", postgres_url, **shared)) as south,
            WsClient(north.ws) as north_ws,
            WsClient(south.ws) as south_ws,
        ):
            ids = [add_camera(north.base, f"file://{video}", f"cam{i}") for i in range(2)]
            running = _spread_evenly(north, south, ids)
            for camera in ids:
                httpx.post(f"{north.base}/api/cameras/{camera}/activate").raise_for_status()
            for name, ws in (("north", north_ws), ("south", south_ws)):
                for node, (camera,) in running.items():
                    alarm = ws.wait("alarm", 30, camera_id=camera)[0]
                    assert alarm["node"] == node, name
                    end = ws.wait("motion_end", 30, camera_id=camera)[0]
                    assert (end["event_id"], end["node"]) == (alarm["event_id"], node)
                alarms = [(m["event_id"], m["ts"]) for m in ws.of_type("alarm")]
                assert len(alarms) == len(set(alarms)), f"an alarm twice on {name}'s /ws"
            hooks = webhook.wait(2, 15)
            time.sleep(2)
            assert len(webhook.received()) == len(hooks) == 2, "one message per event"
            held = retained(broker.port, ("vigil/cameras/+/active",))
            assert held == {f"vigil/cameras/{camera}/active": b"ON" for camera in ids}

            north.stop()  # It says offline as it goes; the site is not: south says so.
            wait_for(
                lambda: retained(broker.port, ("vigil/status",)) == {"vigil/status": b"online"},
                10,
                "south to say the site is online",
            )
    finally:
        webhook.stop()
        broker.stop()


def test_a_node_cut_off_from_the_database_stops_its_cameras_when_its_leases_run_out(
    tmp_path: Path,
) -> None:
    """Past its leases, the others may have taken its cameras: a node that cannot renew
    must not run them too. Until then they go on: a database restarting costs nothing."""
    cluster = Cluster().start()  # Its own: this test stops it.
    try:
        video = write_video(tmp_path / "door.avi")
        with _serve(_node(tmp_path, "north", cluster.database())) as north:
            camera = add_camera(north.base, f"file://{video}", "door")
            wait_for(lambda: _live(north.base, "north") == [camera], 20, "the camera live")
            cameras = north.server.config.app.state.services.cameras  # type: ignore[attr-defined]
            cluster.stop()
            cut = time.monotonic()
            time.sleep(LEASE_S / 2)
            assert [c.camera_id for c in cameras.all()] == [camera], "it goes on meanwhile"
            wait_for(lambda: not cameras.all(), LEASE_S + 5, "the camera to stop")
            stopped_after = time.monotonic() - cut
            period = LEASE_S / 3
            assert LEASE_S - period - 0.5 <= stopped_after <= LEASE_S + period + 1.0
    finally:
        cluster.stop()


def test_a_notification_target_added_through_one_node_hears_the_others_cameras(
    postgres_url: str, tmp_path: Path
) -> None:
    webhook = WebhookReceiver().start()
    video = write_video(tmp_path / "door.avi", frames=300)  # One crossing every 20 s.
    try:
        with (
            _serve(_node(tmp_path, "north", postgres_url)) as north,
            _serve(_node(tmp_path, "south", postgres_url)) as south,
        ):
            camera = add_camera(south.base, f"file://{video}", "door")
            placed = wait_for(
                lambda: [n for n, s in (("north", north), ("south", south)) if _live(s.base, n)],
                20,
                "the camera live on one node",
            )
            runs, other = (north, south) if placed == ["north"] else (south, north)
            added = httpx.post(f"{other.base}/api/notifications", json={"url": webhook.url()})
            assert added.status_code == 201, added.text
            target = added.json()["id"]
            wait_for(
                lambda: (
                    [t["id"] for t in httpx.get(f"{runs.base}/api/notifications").json()]
                    == [target]
                ),
                10,
                "the target known where the camera runs",
            )
            httpx.post(f"{other.base}/api/cameras/{camera}/activate").raise_for_status()
            (hook,) = webhook.wait(1, 30)
            assert "door" in hook.body["title"]

            assert httpx.delete(f"{other.base}/api/notifications/{target}").status_code == 204
            wait_for(
                lambda: httpx.get(f"{runs.base}/api/notifications").json() == [],
                10,
                "the target gone where the camera runs",
            )
    finally:
        webhook.stop()
