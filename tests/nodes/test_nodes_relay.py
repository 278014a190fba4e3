"""Any node serves the whole site (app/nodes/relay.py, live_relay.py): two real servers with
a password, sharing a real PostgreSQL, each running one camera pinned to it. Through north,
south's camera is shown as south shows it; its live frames come over north's /ws/live byte
for byte, its MJPEG stream and single frames from north's routes; its snapshots, zip and
clip (with ranges) are south's files, fetched from south; deleted through north, they go
from south's disk. A request claiming to be a node
without that node's token is refused. Once south is gone, north says so at once, naming it,
and never hangs. And a page on north shows south's camera live, saying where it runs."""

from __future__ import annotations

import base64
import io
import zipfile
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import httpx
import pytest

from app.nodes.relay import RELAY_HEADER
from tests.api.test_api_ws_live import file_packets
from tests.api.vigil_live_frames import LiveViewer
from tests.api.vigil_livekit import (
    Running,
    free_port,
    live_settings,
    running_server,
    wait_for,
    wait_for_picture,
    write_video,
)

PASSWORD = "correct horse"
AUTH = httpx.BasicAuth("vigil", PASSWORD)
BASIC = "Basic " + base64.b64encode(f"vigil:{PASSWORD}".encode()).decode()
LOOP = 75


class Site:
    """North and south, each running one activated camera pinned to it."""

    def __init__(
        self, stack: ExitStack, tmp_path: Path, postgres_url: str, **overrides: Any
    ) -> None:
        self.stack = stack
        self.data = {name: tmp_path / name for name in ("north", "south")}
        self.servers: dict[str, Running] = {}
        for name, folder in self.data.items():
            port = free_port()
            settings = live_settings(
                folder,
                database_url=postgres_url,
                node_name=name,
                port=port,
                lease_s=3.0,
                password=PASSWORD,
                **overrides,
            )
            self.servers[name] = stack.enter_context(running_server(settings, port=port))
        self.video = write_video(tmp_path / "door.avi", frames=LOOP)
        self.cameras = {}
        for name in self.servers:
            camera = self.add(f"{name} door")
            self.patch(camera, pinned_to=name)
            self.cameras[name] = camera
        for name, camera in self.cameras.items():
            wait_for(
                lambda n=name, c=camera: (
                    self.camera(n, c)["state"] == "live" and self.camera(n, c)["node"] == n
                ),
                20,
                f"{name}'s camera live on {name}",
            )
            self.post(f"/api/cameras/{camera}/activate")

    @property
    def north(self) -> str:
        return self.servers["north"].base

    @property
    def south(self) -> str:
        return self.servers["south"].base

    def add(self, name: str) -> int:
        added = httpx.post(
            f"{self.north}/api/cameras",
            json={"name": name, "source": f"file://{self.video}"},
            auth=AUTH,
        )
        assert added.status_code == 200, added.text
        return int(added.json()["id"])

    def patch(self, camera: int, **changes: Any) -> None:
        httpx.patch(
            f"{self.north}/api/cameras/{camera}", json=changes, auth=AUTH
        ).raise_for_status()

    def post(self, path: str) -> None:
        httpx.post(self.north + path, auth=AUTH).raise_for_status()

    def camera(self, node: str, camera: int) -> dict[str, Any]:
        answer: dict[str, Any] = self.get(node, f"/api/cameras/{camera}").json()
        return answer

    def get(self, node: str, path: str, **options: Any) -> httpx.Response:
        return httpx.get(self.servers[node].base + path, auth=AUTH, timeout=20, **options)


@pytest.fixture
def site(postgres_url: str, tmp_path: Path) -> Iterator[Site]:
    with ExitStack() as stack:
        yield Site(stack, tmp_path, postgres_url)


def _recorded_event(site: Site, camera: int) -> dict[str, Any]:
    """An event of ``camera`` that has ended, with its clip written and its snapshots."""

    def found() -> dict[str, Any] | None:
        listed = site.get("north", f"/api/events?camera_id={camera}").json()
        return next((e for e in listed if e["clip_s"] is not None and e["snapshot"]), None)

    event: dict[str, Any] = wait_for(found, 45, "an event of south's camera with its clip")
    return event


def test_north_serves_south_cameras_pictures_snapshots_and_clips(site: Site) -> None:
    camera = site.cameras["south"]
    shown = site.camera("north", camera)
    assert (shown["node"], shown["state"]) == ("south", "live")

    # Live frames over north's /ws/live: the file's own JPEGs, through two nodes untouched.
    packets = file_packets(site.video)
    url = site.servers["north"].ws + "/live"
    with LiveViewer(url, additional_headers={"Authorization": BASIC}) as viewer:
        viewer.watch([camera, site.cameras["north"]])
        frames = viewer.wait(camera, 10)
        viewer.wait(site.cameras["north"], 10)
    for _, header, jpeg in frames:
        assert header["camera_id"] == camera
        assert jpeg == packets[(header["frame"] - 1) % LOOP]

    # MJPEG stream and a single frame of south's camera, from north.
    with httpx.stream(
        "GET", f"{site.north}/api/cameras/{camera}/stream.mjpg", auth=AUTH, timeout=10
    ) as stream:
        assert stream.status_code == 200
        assert stream.headers["content-type"].startswith("multipart/x-mixed-replace")
        first = next(stream.iter_bytes())
        assert first.startswith(b"--frame\r\nContent-Type: image/jpeg")
    frame = site.get("north", f"/api/cameras/{camera}/frame.jpg")
    assert frame.status_code == 200 and frame.content[:2] == b"\xff\xd8"

    # South's snapshots and clip: its files, on its disk only, served by north.
    event = _recorded_event(site, camera)
    assert event["node"] == "south"
    path = event["snapshot"]
    snapshot = int(path.rsplit("/", 1)[1].removesuffix(".jpg"))
    from_south = site.get("south", path)
    assert from_south.status_code == 200
    assert site.get("north", path).content == from_south.content
    assert not (site.data["north"] / "snapshots" / str(camera)).exists()  # Only south has it.

    packed = site.get("north", f"/api/snapshots.zip?camera_id={camera}")
    with zipfile.ZipFile(io.BytesIO(packed.content)) as archive:
        names = [n for n in archive.namelist() if f"{snapshot:06d}-" in n]
        assert len(names) == 1 and archive.read(names[0]) == from_south.content

    clip_path = f"/api/events/{event['id']}/clip.mp4"
    whole = site.get("south", clip_path).content
    assert site.get("north", clip_path).content == whole
    part = site.get("north", clip_path, headers={"Range": "bytes=100-299"})
    assert part.status_code == 206
    assert part.headers["content-range"] == f"bytes 100-299/{len(whole)}"
    assert part.content == whole[100:300]

    # Another node's token is what lets a relayed request in, and nothing else does.
    forged = httpx.get(f"{site.south}{path}", headers={RELAY_HEADER: "guess"})
    assert forged.status_code == 401
    listed = httpx.get(f"{site.north}/api/nodes", auth=AUTH).text
    assert "token" not in listed

    # Deleted through north, the event's files go from south's disk at its next renewal.
    def files_on_south() -> list[Path]:
        south = site.data["south"]
        return [
            *(south / "snapshots" / str(camera)).rglob(f"*-e{event['id']}-*.jpg"),
            *(south / "clips" / str(camera)).rglob(f"*-e{event['id']}.mp4"),
        ]

    kept = [p.suffix for p in files_on_south()]  # Two pictures an alarm, and the clip.
    assert kept.count(".jpg") >= 2 and kept.count(".mp4") == 1
    deleted = httpx.delete(f"{site.north}/api/events/{event['id']}", auth=AUTH)
    assert deleted.json()["deleted"] == [event["id"]]
    wait_for(lambda: not files_on_south(), 10, "south to delete the event's files")
    assert site.get("north", path).status_code == 404

    # South goes: north says at once what it cannot serve, and why.
    other = _recorded_event(site, camera)["snapshot"]
    site.servers["south"].stop()
    gone = site.get("north", other)
    assert gone.status_code in (502, 503)
    assert "node south" in gone.json()["detail"]
    assert site.get("north", f"/api/cameras/{camera}/frame.jpg").status_code in (502, 503)
    assert site.get("north", f"/api/cameras/{site.cameras['north']}/frame.jpg").status_code == 200


def test_a_page_on_north_shows_south_camera_live_and_where_it_runs(site: Site, page: Any) -> None:
    camera = site.cameras["south"]
    page.request.post(f"{site.north}/api/login", data={"password": PASSWORD})
    page.goto(site.north + "/")
    card = page.locator(f'.card[data-id="{camera}"]')
    card.locator(".picture").scroll_into_view_if_needed()
    wait_for_picture(page, camera)
    wait_for(lambda: card.locator(".node").is_visible(), 20, "the card to say its node")
    assert card.locator(".node").inner_text() == "on south"
    assert card.locator(".state").inner_text() == "live"
    other = page.locator(f'.card[data-id="{site.cameras["north"]}"] .node')
    assert other.inner_text() == "on north"


def test_an_analysis_run_on_south_is_served_by_north(site: Site, tmp_path: Path) -> None:
    video = write_video(tmp_path / "clip.avi", frames=60)
    with video.open("rb") as handle:
        uploaded = httpx.post(
            f"{site.south}/api/analyses",
            files={"file": (video.name, handle, "video/x-msvideo")},
            auth=AUTH,
            timeout=30,
        )
    assert uploaded.status_code == 202, uploaded.text
    analysis = uploaded.json()["id"]
    done = wait_for(
        lambda: (
            (a := site.get("north", f"/api/analyses/{analysis}").json())["status"] == "done" and a
        ),
        60,
        "the analysis to be done, as north shows it",
    )
    assert done["node"] == "south" and done["report"]["frames"] == 60
    assert done == site.get("south", f"/api/analyses/{analysis}").json()
    for output in ("tracks.csv", "report.html", "annotated.mp4"):
        path = f"/api/analyses/{analysis}/{output}"
        assert site.get("north", path).content == site.get("south", path).content, output
    assert not (site.data["north"] / "analyses" / analysis).exists()


def test_with_a_media_folder_they_share_north_serves_south_files_without_south(
    postgres_url: str, tmp_path: Path
) -> None:
    with ExitStack() as stack:
        site = Site(stack, tmp_path, postgres_url, media_dir=tmp_path / "nfs")
        event = _recorded_event(site, site.cameras["south"])
        snapshot = site.get("south", event["snapshot"]).content
        clip = site.get("south", event["clip"]).content
        site.servers["south"].stop()
        assert site.get("north", event["snapshot"]).content == snapshot
        assert site.get("north", event["clip"]).content == clip
