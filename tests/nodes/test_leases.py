"""Cameras placed on nodes by lease (app/nodes/leases.py), on both databases: a node takes
what it may, nodes share by capacity, a dead node's cameras go to the living within a lease,
one that comes back takes a share back a few at a time without any camera going back and
forth, pins hold, and (PostgreSQL) nodes renewing at the same moment never claim one camera
twice."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest

from app.nodes.leases import HANDOVER, Leases, Node, site
from app.storage import Database
from app.storage.engine import Target

LEASE_S = 1.0


@pytest.fixture
def db(db_target: Target) -> Iterator[Database]:
    database = Database(db_target)
    yield database
    database.close()


def _node(db: Database, name: str, capacity: int = 20) -> Leases:
    return Leases(db, Node(name, f"http://{name}:8000", capacity), LEASE_S)


def _cameras(db: Database, count: int) -> list[int]:
    return [db.add_camera(f"cam{i}", "demo", "adaptive", 100.0) for i in range(count)]


def _rounds(nodes: list[Leases], count: int) -> list[dict[str, list[int]]]:
    """``count`` renewals of every node in turn; what each held after each round."""
    history = []
    for _ in range(count):
        history.append({n.node.name: n.renew() for n in nodes})
    return history


def _moves(history: list[dict[str, list[int]]]) -> dict[int, int]:
    """How many times each camera changed hands over the rounds."""
    holder: dict[int, str] = {}
    moves: dict[int, int] = {}
    for held in history:
        for name, ids in held.items():
            for camera in ids:
                if holder.get(camera, name) != name:
                    moves[camera] = moves.get(camera, 0) + 1
                holder[camera] = name
    return moves


def test_a_lone_node_takes_every_camera_up_to_its_capacity(db: Database) -> None:
    ids = _cameras(db, 5)
    small = _node(db, "north", capacity=3)
    assert small.renew() == ids[:3]
    assert small.renew() == ids[:3], "it keeps what it has"
    (north,) = site(db, LEASE_S)
    assert (north["name"], north["url"]) == ("north", "http://north:8000")
    assert north["cameras"] == ids[:3]
    assert north["load"] == 1.0 and north["alive"] and north["capacity"] == 3
    assert [c["node"] for c in db.cameras()] == ["north"] * 3 + [None] * 2


def test_nodes_share_by_capacity_and_settle_without_a_camera_going_back_and_forth(
    db: Database,
) -> None:
    ids = _cameras(db, 12)
    north, south, east = _node(db, "north"), _node(db, "south"), _node(db, "east", capacity=40)
    assert north.renew() == ids, "alone, it takes all"
    history = _rounds([north, south, east], 8)
    # Shares by capacity: 12 x 20/80 = 3, 3, and 6; each camera on one node only.
    assert {k: len(v) for k, v in history[-1].items()} == {"north": 3, "south": 3, "east": 6}
    assert sorted(c for held in history[-1].values() for c in held) == ids
    assert all(n <= 1 for n in _moves(history).values()), "no camera came back"
    # North let go of at most HANDOVER a renewal, so the others took over gradually.
    counts = [len(h["north"]) for h in history]
    assert all(a - b <= HANDOVER for a, b in zip([12, *counts], counts, strict=False))
    assert _rounds([north, south, east], 3)[-1] == history[-1], "settled: nothing moves"
    loads = {n["name"]: n["load"] for n in site(db, LEASE_S)}
    assert loads == {"north": 0.15, "south": 0.15, "east": 0.15}


def test_a_dead_nodes_cameras_go_to_the_living_and_it_takes_a_share_back(db: Database) -> None:
    ids = _cameras(db, 12)
    nodes = [_node(db, name) for name in ("north", "south", "east")]
    settled = _rounds(nodes, 6)[-1]
    assert sorted(len(v) for v in settled.values()) == [4, 4, 4]
    east_had = settled["east"]

    time.sleep(LEASE_S / 2)  # East dies: it renews no more.
    north, south = _rounds(nodes[:2], 1)[-1].values()
    assert not set(east_had) & set(north + south), "not before its lease runs out"
    time.sleep(LEASE_S / 2 + 0.1)
    after = _rounds(nodes[:2], 1)[-1]
    assert sorted(after["north"] + after["south"]) == ids, "all of them at the next renewal"
    assert sorted(len(v) for v in after.values()) == [6, 6]
    assert {n["name"]: n["alive"] for n in site(db, LEASE_S)}["east"] is False

    history = _rounds(nodes, 6)  # East is back.
    assert [len(h["east"]) for h in history[:3]] == [0, 2 * HANDOVER, 4]
    assert sorted(len(v) for v in history[-1].values()) == [4, 4, 4]
    assert all(n <= 1 for n in _moves([after, *history]).values()), "no camera came back"


def test_a_node_that_leaves_frees_its_cameras_at_once(db: Database) -> None:
    ids = _cameras(db, 4)
    north, south = _node(db, "north"), _node(db, "south")
    _rounds([north, south], 4)
    north.leave()
    assert south.renew() == ids, "without waiting for north's leases to run out"
    assert [n["name"] for n in site(db, LEASE_S)] == ["south"]


def test_a_pinned_camera_runs_only_on_its_node(db: Database) -> None:
    usb, *others = _cameras(db, 3)
    north, south = _node(db, "north", capacity=1), _node(db, "south", capacity=1)
    assert north.renew() == [usb]
    db.update_camera(usb, pinned_to="south")
    assert north.renew() == [others[0]], "north lets it go, and takes another"
    assert south.renew() == [usb], "south takes it, whatever its share"
    north.leave()
    south.leave()
    db.update_camera(usb, pinned_to="west")  # A node that is not there.
    assert north.renew() == [others[0]] and south.renew() == [others[1]]
    assert db.camera(usb)["node"] is None  # type: ignore[index]


def test_nodes_renewing_at_the_same_moment_never_hold_one_camera_twice(
    postgres_url: str,
) -> None:
    """Four nodes, each with its own connections as separate machines would have, renewing
    together in threads: SKIP LOCKED, no waiting on each other, no camera held twice."""
    setup = Database(postgres_url)
    ids = _cameras(setup, 40)
    dbs = [Database(postgres_url) for _ in range(4)]
    nodes = [_node(d, f"n{i}", capacity=15) for i, d in enumerate(dbs)]
    results: list[list[list[int]]] = [[] for _ in nodes]
    start = threading.Barrier(len(nodes))

    def run(index: int) -> None:
        for _ in range(10):
            start.wait(10)
            results[index].append(nodes[index].renew())

    threads = [threading.Thread(target=run, args=(i,)) for i in range(len(nodes))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    for rounds in zip(*results, strict=True):
        held = [camera for ids_ in rounds for camera in ids_]
        assert len(held) == len(set(held)), "a camera held by two nodes at once"
    final = [r[-1] for r in results]
    assert sorted(c for held in final for c in held) == ids and all(len(f) == 10 for f in final)
    for d in (setup, *dbs):
        d.close()
