"""The snapshot listing in pages: ``until``/``until_id`` (and ``since``/``since_id``) as a
cursor, through snapshots that share a time at a page's edge; the zip of a run of pages."""

from __future__ import annotations

import io
import zipfile
from collections.abc import Callable
from typing import Any

import httpx

from tests.api.vigil_livekit import Running, add_snapshot

T0 = 1_800_000_000.0


def listing(base: str, **params: Any) -> list[dict[str, Any]]:
    answer = httpx.get(f"{base}/api/snapshots", params=params)
    assert answer.status_code == 200, answer.text
    rows: list[dict[str, Any]] = answer.json()
    return rows


def test_pages_by_cursor_skip_none_and_repeat_none_where_times_are_shared(
    serve: Callable[..., Running],
) -> None:
    server = serve()
    base = server.base
    # Ten snapshots, five of them at one time (ids in between one another's).
    times = [T0, T0 + 1, T0 + 2, T0 + 2, T0 + 2, T0 + 2, T0 + 2, T0 + 3, T0 + 4, T0 + 5]
    ids = [add_snapshot(server, 1, ts) for ts in times]
    everything = listing(base)
    assert [s["id"] for s in everything] == ids[::-1]  # Newest first, then by id.

    pages: list[list[int]] = []
    params: dict[str, Any] = {"limit": 3}
    for _ in range(len(ids)):  # At most (a cursor that moves on no more ends it too).
        page = listing(base, **params)
        if not page:
            break
        pages.append([s["id"] for s in page])
        last = page[-1]
        params = {"limit": 3, "until": last["ts"], "until_id": last["id"] - 1}
    assert [i for page in pages for i in page] == ids[::-1], pages
    assert len(pages) == 4  # 3 + 3 + 3 + 1, two page edges inside the shared time.

    # The existing filters mean what they meant: until alone includes its whole time.
    assert len(listing(base, until=T0 + 2)) == 7
    assert len(listing(base, since=T0 + 2)) == 8
    # since_id settles the shared time from below, as until_id does from above.
    from_middle = listing(base, since=T0 + 2, since_id=ids[4])
    assert [s["id"] for s in from_middle] == ids[:3:-1]
    window = listing(base, since=T0 + 2, since_id=ids[3], until=T0 + 2, until_id=ids[5])
    assert [s["id"] for s in window] == [ids[5], ids[4], ids[3]]

    # The zip of a run of pages: exactly those snapshots.
    newest, oldest = everything[1], everything[6]
    run = {"until": newest["ts"], "until_id": newest["id"], "since": oldest["ts"]}
    answer = httpx.get(f"{base}/api/snapshots.zip", params={**run, "since_id": oldest["id"]})
    names = zipfile.ZipFile(io.BytesIO(answer.content)).namelist()
    assert sorted(int(n.split("/")[1].split("-")[0]) for n in names) == sorted(ids[3:9])


def test_a_cursor_id_without_its_time_is_refused(serve: Callable[..., Running]) -> None:
    server = serve()
    for url in ("/api/snapshots", "/api/snapshots.zip"):
        for name, other in (("until_id", "since"), ("since_id", "until")):
            refused = httpx.get(f"{server.base}{url}", params={name: 3, other: T0})
            assert refused.status_code == 422, (url, name, refused.text)
            assert f"{name} needs {name[:-3]}" in refused.text
        refused = httpx.get(f"{server.base}{url}", params={"until": T0, "until_id": -1})
        assert refused.status_code == 422, refused.text
