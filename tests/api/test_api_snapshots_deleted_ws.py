"""``snapshots_deleted`` on /ws: every way snapshots go (bulk delete, DELETE, retention)
tells the pages which went, so none keeps showing one its browser had already loaded."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import httpx
import pytest

from app.api.services import DELETED_IDS_PER_MESSAGE
from tests.api.vigil_livekit import Running, WsClient, add_snapshot, wait_for

DAY = 86400.0


def told_deleted(ws: WsClient) -> list[list[int]]:
    """The ids of each ``snapshots_deleted`` message so far, each sorted, in order."""
    return [sorted(m["ids"]) for m in ws.of_type("snapshots_deleted")]


def listed(server: Running) -> set[int]:
    answer = httpx.get(f"{server.base}/api/snapshots", params={"limit": 10000})
    return {s["id"] for s in answer.json()}


def test_a_delete_tells_ws_exactly_the_snapshots_it_deleted(
    serve: Callable[..., Running],
) -> None:
    server = serve()
    now = time.time()
    ids = [add_snapshot(server, 1, now + i) for i in range(4)]
    missing = max(ids) + 1000
    with WsClient(server.ws) as ws:
        bulk = httpx.post(
            f"{server.base}/api/snapshots/delete", json={"ids": [ids[0], missing, ids[1]]}
        )
        assert sorted(bulk.json()["deleted"]) == ids[:2]
        ws.wait("snapshots_deleted", 10)
        assert told_deleted(ws) == [ids[:2]], "the one that did not exist is left out"

        httpx.delete(f"{server.base}/api/snapshots/{ids[2]}").raise_for_status()
        ws.wait("snapshots_deleted", 10, count=2)
        assert told_deleted(ws) == [ids[:2], [ids[2]]]

        # Deleting nothing tells nothing: the next message on this socket is the next delete.
        nothing = httpx.post(f"{server.base}/api/snapshots/delete", json={"ids": [missing]})
        assert nothing.json()["deleted"] == []
        assert httpx.delete(f"{server.base}/api/snapshots/{ids[0]}").status_code == 404
        httpx.delete(f"{server.base}/api/snapshots/{ids[3]}").raise_for_status()
        ws.wait("snapshots_deleted", 10, count=3)
        assert told_deleted(ws) == [ids[:2], [ids[2]], [ids[3]]]


def test_a_large_delete_is_told_in_messages_of_bounded_size(
    serve: Callable[..., Running],
) -> None:
    server = serve()
    db = server.server.config.app.state.services.database
    count = DELETED_IDS_PER_MESSAGE + 5
    # Rows without files, as a file lost to a crash leaves them: the delete goes alike.
    ids = [
        db.add_snapshot(1, None, 1000.0 + i, "frame", f"1/none-{i}.jpg", 10) for i in range(count)
    ]
    with WsClient(server.ws) as ws:
        answer = httpx.post(f"{server.base}/api/snapshots/delete", json={"ids": ids}, timeout=30)
        assert len(answer.json()["deleted"]) == count
        ws.wait("snapshots_deleted", 10, count=2)
        time.sleep(0.3)  # No third message comes.
        told = told_deleted(ws)
    assert [len(t) for t in told] == [DELETED_IDS_PER_MESSAGE, 5]
    assert sorted(i for t in told for i in t) == sorted(ids)


def add_sized_snapshot(server: Running, ts: float, size: int) -> int:
    """A snapshot of camera 1 whose file (and row) is ``size`` bytes; its id."""
    services = server.server.config.app.state.services
    path = services.snapshots.save(1, ts, "frame", bytes(size), None)
    return int(services.database.add_snapshot(1, None, ts, "frame", path, size))


@pytest.mark.parametrize(
    "retention",
    [
        pytest.param({"retention_days": 1, "retention_mb": 0}, id="by-age"),
        pytest.param({"retention_days": 0, "retention_mb": 2500 / 2**20}, id="by-size"),
    ],
)
def test_retention_tells_ws_exactly_the_snapshots_it_pruned(
    serve: Callable[..., Running], retention: dict[str, Any]
) -> None:
    # The server's own retention pass, every 0.2 s, on snapshots added while it runs.
    server = serve(retention_interval_s=0.2, **retention)
    now = time.time()
    with WsClient(server.ws) as ws:
        if retention["retention_days"]:  # Two of two days ago go, today's two stay.
            gone = [add_sized_snapshot(server, now - 2 * DAY + i, 1000) for i in range(2)]
            kept = [add_sized_snapshot(server, now + i, 1000) for i in range(2)]
        else:  # Four of 1000 bytes under a cap of 2500: the oldest two go.
            gone = [add_sized_snapshot(server, now + i, 1000) for i in range(2)]
            kept = [add_sized_snapshot(server, now + 2 + i, 1000) for i in range(2)]
        wait_for(lambda: listed(server) == set(kept), 10, "the retention pass")
        wait_for(
            lambda: sorted(i for t in told_deleted(ws) for i in t) == gone,
            10,
            "every pruned snapshot told, once",
        )
        time.sleep(0.6)  # Three more passes, which delete nothing: they tell nothing.
        told = told_deleted(ws)
    assert sorted(i for t in told for i in t) == gone
    assert all(told), "a message of no ids"
