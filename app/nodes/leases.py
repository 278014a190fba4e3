"""Cameras placed on nodes by lease, in the shared database: no election of our own, only
row locks (``SELECT ... FOR UPDATE SKIP LOCKED``) and the database's clock.

Each node calls ``Leases.renew()`` every ``lease_s / 3`` seconds. In one transaction it
says it is alive (its ``nodes`` row), extends the leases of the cameras it holds, and
then, against its share of the site:

- its share is the site's cameras (those that may run on a live node) times its capacity
  over the live nodes' capacity, rounded up, at most its capacity: a node at its share
  carries the site's mean load;
- below its share it claims free cameras (never leased, let go, or whose lease ran out:
  their node is dead) up to it, those pinned to it first and whatever its share;
- above it, it lets go of at most ``HANDOVER`` cameras per renewal, for the nodes below
  theirs to claim. So a node that comes back takes cameras over a few at a time, and only
  while it is below the mean: none ever goes back and forth.

A node that stops renewing is dead once ``lease_s`` has passed: its leases and its row
run out together, and the live nodes claim its cameras at their next renewal (within
``lease_s`` plus one renewal of its death). Times are the database's clock, one for every
node: the machines' clocks need not agree.

On SQLite (one machine, no ``VIGIL_DATABASE_URL``) the same statements run serialised by
its write lock; ``vigil serve`` does not use them there: the node is alone and runs every
camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Connection, Double, FunctionElement, Select, delete, func, select, update
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.ext.compiler import compiles
from sqlalchemy.sql.compiler import SQLCompiler

from app.storage.db import Database
from app.storage.engine import POSTGRESQL, reader
from app.storage.schema import cameras, nodes

HANDOVER = 2
"""Cameras a node above its share lets go of per renewal."""
RENEWALS_PER_LEASE = 3
"""A node renews this many times per lease: a late renewal or two cost it nothing."""


@dataclass(frozen=True)
class Node:
    name: str
    url: str
    capacity: int
    """Cameras it runs at most (``VIGIL_NODE_CAMERAS``), at least 1."""
    relay_token: str = ""
    """What the other nodes show it to be relayed its pictures and files (app.nodes.relay)."""


class Leases:
    """``node``'s leases in ``db``, each ``lease_s`` long."""

    def __init__(self, db: Database, node: Node, lease_s: float) -> None:
        if node.capacity < 1:
            raise ValueError("a node's capacity is at least one camera")
        self.db = db
        self.node = node
        self.lease_s = lease_s

    @property
    def period_s(self) -> float:
        """How often to ``renew()``."""
        return self.lease_s / RENEWALS_PER_LEASE

    def renew(self) -> list[int]:
        """One renewal (see the module); the ids of the cameras this node holds after it."""
        me = self.node.name
        c = cameras.c
        with self.db.transaction() as conn:
            now = float(conn.execute(select(DatabaseNow())).scalar_one())
            self._say_alive(conn, now, load=None)
            # A camera pinned to another node meanwhile goes, for that node to claim.
            conn.execute(
                update(cameras)
                .where(c.node == me, c.pinned_to.is_not(None), c.pinned_to != me)
                .values(node=None, lease_until=None)
            )
            statement = (
                update(cameras)
                .where(c.node == me)
                .values(lease_until=now + self.lease_s)
                .returning(c.id, c.pinned_to)
            )
            held = {int(i): pin for i, pin in conn.execute(statement)}
            share = self._share(conn, now)
            if len(held) > share:
                movable = sorted(i for i, pin in held.items() if pin is None)
                for camera_id in movable[::-1][: min(HANDOVER, len(held) - share)]:
                    del held[camera_id]
                    conn.execute(
                        update(cameras).where(c.id == camera_id).values(node=None, lease_until=None)
                    )
            else:
                for camera_id in self._claim(conn, now, share, len(held)):
                    held[camera_id] = None
            self._say_alive(conn, now, load=len(held) / self.node.capacity)
        return sorted(held)

    def leave(self) -> None:
        """This node stops: its cameras are free for the others' next renewal at once, not
        once their leases run out, and its row goes."""
        me = self.node.name
        with self.db.transaction() as conn:
            conn.execute(
                update(cameras).where(cameras.c.node == me).values(node=None, lease_until=None)
            )
            conn.execute(delete(nodes).where(nodes.c.name == me))

    def _say_alive(self, conn: Connection, now: float, load: float | None) -> None:
        node = self.node
        dialect = postgresql if conn.dialect.name == POSTGRESQL else sqlite
        statement = dialect.insert(nodes).values(
            name=node.name,
            url=node.url,
            capacity=node.capacity,
            renewed_at=now,
            load=load or 0.0,
            relay_token=node.relay_token,
        )
        changed: dict[str, Any] = {
            "url": node.url,
            "capacity": node.capacity,
            "renewed_at": now,
            "relay_token": node.relay_token,
        }
        if load is not None:
            changed["load"] = load
        conn.execute(statement.on_conflict_do_update(index_elements=[nodes.c.name], set_=changed))

    def _share(self, conn: Connection, now: float) -> int:
        """The cameras this node should hold: its part of the site's, by capacity."""
        alive = nodes.c.renewed_at >= now - self.lease_s
        live = {
            n: int(cap)
            for n, cap in conn.execute(select(nodes.c.name, nodes.c.capacity).where(alive))
        }
        c = cameras.c
        placeable = conn.execute(
            select(func.count())
            .select_from(cameras)
            .where(c.pinned_to.is_(None) | c.pinned_to.in_(list(live)))
        ).scalar_one()
        capacity = self.node.capacity
        return min(capacity, math.ceil(placeable * capacity / sum(live.values())))

    def _claim(self, conn: Connection, now: float, share: int, held: int) -> list[int]:
        """Claim the free cameras pinned to this node, then others up to ``share`` (with the
        ``held`` it has); those another node is claiming now are skipped, not waited for."""
        c = cameras.c
        free = c.node.is_(None) | (c.lease_until < now)  # This node's own were just renewed.
        claimed = self._take(conn, now, select(c.id).where(free, c.pinned_to == self.node.name))
        wanted = share - held - len(claimed)
        if wanted > 0:
            others = select(c.id).where(free, c.pinned_to.is_(None)).limit(wanted)
            claimed += self._take(conn, now, others)
        return claimed

    def _take(self, conn: Connection, now: float, query: Select[Any]) -> list[int]:
        c = cameras.c
        locked = query.order_by(c.id).with_for_update(skip_locked=True)
        ids = [int(i) for i in conn.execute(locked).scalars()]
        if ids:
            statement = update(cameras).where(c.id.in_(ids))
            conn.execute(statement.values(node=self.node.name, lease_until=now + self.lease_s))
        return ids


def site(db: Database, lease_s: float) -> list[dict[str, Any]]:
    """The site's nodes (``GET /api/nodes``), by name: each with the cameras it holds,
    its load and last renewal, and whether it is alive (renewed within ``lease_s``)."""
    c = cameras.c
    with reader(db.engine).connect() as conn:
        now = float(conn.execute(select(DatabaseNow())).scalar_one())
        rows = conn.execute(select(nodes).order_by(nodes.c.name)).mappings().all()
        held = conn.execute(
            select(c.node, c.id).where(c.node.is_not(None), c.lease_until >= now).order_by(c.id)
        ).all()
    return [
        {
            "name": row["name"],
            "url": row["url"],
            "cameras": [i for n, i in held if n == row["name"]],
            "renewed_at": row["renewed_at"],
            "load": row["load"],
            "capacity": row["capacity"],
            "alive": row["renewed_at"] >= now - lease_s,
        }
        for row in rows
    ]


class DatabaseNow(FunctionElement[float]):
    """The database's clock, in seconds since the epoch: one clock for every node."""

    type = Double()
    name = "db_now"
    inherit_cache = True


@compiles(DatabaseNow)
def _now_sqlite(element: DatabaseNow, compiler: SQLCompiler, **kw: Any) -> str:
    return "((julianday('now') - 2440587.5) * 86400.0)"


@compiles(DatabaseNow, "postgresql")
def _now_postgres(element: DatabaseNow, compiler: SQLCompiler, **kw: Any) -> str:
    # The time now, not the transaction's start: a renewal that waited is not backdated.
    return "CAST(extract(epoch FROM clock_timestamp()) AS DOUBLE PRECISION)"
