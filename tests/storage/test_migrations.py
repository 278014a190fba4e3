"""Migrations on both databases: a SQLite database written before migrations upgrades in
place with every row; a fresh database gets the schema that app/storage/schema.py defines;
migrating again changes nothing; of two processes starting at once one migrates; camera
processes wait for the schema; a schema newer than this release's is refused. And what the
nodes will use: rows one transaction locks, another skips.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import psycopg
import pytest
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import select, text

from app.storage import Database, migrate
from app.storage import engine as engines
from app.storage.engine import Target
from app.storage.schema import cameras, metadata
from tests.storage.conftest import raw_rows

ROOT = Path(__file__).resolve().parents[2]
BEFORE = Path(__file__).with_name("data") / "before_migrations.db"
"""Written by Vigil's Database before migrations (data/make_before_migrations.py)."""
TABLES = (
    "cameras",
    "events",
    "snapshots",
    "snapshot_usage",
    "clip_usage",
    "analyses",
    "notification_targets",
    "activity",
    "nodes",
    "file_deletions",
)


def _dump(target: Target, tables: tuple[str, ...] = TABLES) -> dict[str, list[tuple[object, ...]]]:
    """Every row of every table, as the database's own driver reads them."""
    return {table: sorted(raw_rows(target, f"SELECT * FROM {table}"), key=repr) for table in tables}


def _schema(target: Target) -> list[tuple[object, ...]]:
    """The database's own description of its tables, indexes and triggers."""
    if isinstance(target, Path):
        return sorted(raw_rows(target, "SELECT type, name, sql FROM sqlite_master"), key=repr)
    return sorted(
        raw_rows(
            target,
            "SELECT table_name, column_name, data_type, is_nullable, column_default"
            " FROM information_schema.columns WHERE table_schema = 'public'",
        )
        + raw_rows(target, "SELECT indexname, indexdef FROM pg_indexes WHERE schemaname = 'public'")
        + raw_rows(target, "SELECT tgname, tgrelid::regclass::text FROM pg_trigger")
        + raw_rows(target, "SELECT * FROM alembic_version"),
        key=repr,
    )


def _differences(db: Database) -> list[Any]:
    """How the database's tables differ from app/storage/schema.py's, as Alembic compares
    them. Left out: SQLite's primary keys, which its tables have always declared without NOT
    NULL (an INTEGER PRIMARY KEY is the rowid, never null)."""
    with db.engine.connect() as conn:
        context = MigrationContext.configure(conn, opts={"compare_type": True})
        found = compare_metadata(context, metadata)
    primary = {(t.name, c.name) for t in metadata.tables.values() for c in t.primary_key}
    return [
        d
        for d in found
        if not (
            db.dialect == "sqlite"
            and isinstance(d, list)
            and d[0][0] == "modify_nullable"
            and (d[0][2], d[0][3]) in primary
        )
    ]


def test_a_database_from_before_migrations_upgrades_in_place_with_every_row(
    tmp_path: Path,
) -> None:
    path = tmp_path / "vigil.db"
    shutil.copy(BEFORE, path)
    old_tables = TABLES[:-2]  # No nodes then.
    before = _dump(path, old_tables)
    assert before["events"] and before["snapshots"] and before["activity"]

    db = Database(path)

    assert db.revision == migrate.head()
    # Every row as it was, the columns added since null (no node, no lease, no pin).
    added = {"cameras": 3, "events": 1, "snapshots": 1, "analyses": 1}
    after = _dump(path, old_tables)
    assert {t: [r[: len(r) - added.get(t, 0)] for r in rows] for t, rows in after.items()} == before
    assert {r[len(r) - n :] for t, n in added.items() for r in after[t]} == {
        (None,),
        (None, None, None),
    }
    assert _dump(path, ("nodes", "file_deletions")) == {"nodes": [], "file_deletions": []}
    assert sorted(p.name for p in tmp_path.iterdir() if p.suffix == ".db") == ["vigil.db"]
    assert _differences(db) == []
    door, yard = db.cameras()
    assert (door["name"], door["sensitivity"], door["active"], door["show_mask"]) == (
        "door",
        40.0,
        True,
        True,
    )
    assert door["mask"] == [[[0, 0], [10, 0], [10, 10]]] and yard["mask"] == []
    assert [e["ended_at"] is None for e in db.events()] == [True, False, False, False]
    assert db.snapshot_bytes() == 20_480 + 3_100 + 20_101 + 18_000 + 17_777
    assert db.clip_bytes() == 48_213
    assert [e["id"] for e in db.unfinished_clips()] == [2]
    assert db.activity(door["id"], 1_700_000_000, 1_700_000_200, 100) == {
        0: (0.5, 1),
        1: (0.01, 1),
    }
    assert [t["origin"] for t in db.targets()] == ["api", "env"]
    assert db.analysis("a1")["options"] == {"method": "adaptive", "sensitivity": None}  # type: ignore[index]
    # The triggers it had still keep the totals.
    db.add_snapshot(yard["id"], None, 1_700_000_600.0, "frame", "y.jpg", 1_000)
    db.delete_events([1])
    assert db.snapshot_bytes() == 79_458 + 1_000 and db.clip_bytes() == 0
    db.close()

    again = Database(path)
    assert again.revision == migrate.head() and again.snapshot_bytes() == 80_458
    again.close()


def test_a_database_of_the_first_schema_gains_nodes_leases_and_pins(db_target: Target) -> None:
    """Upgraded from 0001 with its rows: they name no node (made before nodes); what is
    added from then on names the node that made it."""
    engine = engines.create(db_target)
    with engines.writer(engine).begin() as conn:
        cfg = migrate.config()
        cfg.attributes["connection"] = conn
        command.upgrade(cfg, "0001")
        conn.execute(
            text(
                "INSERT INTO cameras (name, source, method, created_at)"
                " VALUES ('door', 'demo', 'adaptive', 1)"
            )
        )
        conn.execute(text("INSERT INTO events (camera_id, started_at) VALUES (1, 2)"))
        conn.execute(text("INSERT INTO snapshots (camera_id, ts, path) VALUES (1, 2, 'old.jpg')"))
    engine.dispose()

    db = Database(db_target, node="north")

    assert db.revision == migrate.head() == "0003"
    assert _differences(db) == []
    door = db.camera(1)
    assert door is not None
    assert (door["name"], door["node"], door["lease_until"], door["pinned_to"]) == (
        "door",
        None,
        None,
        None,
    )
    (old_event,) = db.events()
    (old_snapshot,) = db.snapshots()
    assert old_event["node"] is None and old_snapshot["node"] is None
    event = db.add_event(1, 3.0, [], 10.0)
    snapshot = db.add_snapshot(1, event, 3.0, "frame", "new.jpg", 5)
    assert db.event(event)["node"] == "north"  # type: ignore[index]
    assert db.snapshot(snapshot)["node"] == "north"  # type: ignore[index]
    assert db.update_camera(1, pinned_to="north")["pinned_to"] == "north"  # type: ignore[index]
    db.close()


def test_a_fresh_database_gets_the_schema_of_the_tables(db_target: Target) -> None:
    db = Database(db_target)
    assert db.revision == migrate.head()
    assert _differences(db) == []
    assert db.cameras() == [] and db.snapshot_bytes() == 0 and db.clip_bytes() == 0
    if db.dialect == "postgresql":
        slots = raw_rows(db_target, "SELECT COUNT(*), SUM(bytes) FROM snapshot_usage")
        assert slots == [(16, 0)]
        triggers = raw_rows(db_target, "SELECT tgname FROM pg_trigger WHERE NOT tgisinternal")
        assert len(triggers) == 5
    db.close()


def test_migrating_again_changes_nothing(db_target: Target) -> None:
    assert migrate.upgrade(db_target) == (None, migrate.head())
    schema = _schema(db_target)
    db = Database(db_target)
    camera = db.add_camera("door", "demo", "adaptive", 100.0)
    db.add_snapshot(camera, None, 1.0, "frame", "a.jpg", 10)
    rows = _dump(db_target)
    db.close()
    assert migrate.upgrade(db_target) == (migrate.head(), migrate.head())
    assert Database(db_target).revision == migrate.head()
    assert _schema(db_target) == schema
    assert _dump(db_target) == rows


UPGRADE = """
import sys
from pathlib import Path
from app.storage import migrate
target = sys.argv[1]
print("ready", flush=True)
print(migrate.upgrade(Path(target) if sys.argv[2] == "sqlite" else target), flush=True)
"""


def test_of_two_processes_starting_at_once_one_migrates(db_target: Target) -> None:
    """Both start while a third holds the migration's lock; once it lets go, one migrates
    and the other finds the schema done (without the lock, both would make the tables)."""
    sqlite = isinstance(db_target, Path)
    with _holding_the_migration_lock(db_target) as waiting:
        processes = [
            subprocess.Popen(
                [sys.executable, "-c", UPGRADE, str(db_target), "sqlite" if sqlite else "pg"],
                cwd=ROOT,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            for _ in range(2)
        ]
        for process in processes:
            assert process.stdout is not None
            assert process.stdout.readline().strip() == "ready", process.stderr
        waiting(2)
    results = []
    for process in processes:
        out, err = process.communicate(timeout=120)
        assert process.returncode == 0, err
        results.append(out.strip())
    head = migrate.head()
    assert sorted(results) == sorted([f"(None, '{head}')", f"('{head}', '{head}')"])
    assert Database(db_target).revision == head


class _holding_the_migration_lock:  # noqa: N801 (a context manager, named as one reads)
    """The lock a migration takes, held by the test: SQLite's write lock, PostgreSQL's
    advisory lock. ``waiting(n)`` returns once ``n`` others wait for it (as far as can be
    seen: PostgreSQL lists its waiters, SQLite does not)."""

    def __init__(self, target: Target) -> None:
        self.target = target

    def __enter__(self) -> Any:
        if isinstance(self.target, Path):
            import sqlite3

            self.conn: Any = sqlite3.connect(self.target, isolation_level=None)
            self.conn.execute("PRAGMA journal_mode=WAL")  # As Vigil's databases are.
            self.conn.execute("BEGIN IMMEDIATE")
        else:
            self.conn = psycopg.connect(self.target, autocommit=True)
            self.conn.execute("SELECT pg_advisory_lock(%s)", (migrate.LOCK_KEY,))
        return self.waiting

    def waiting(self, count: int) -> None:
        if isinstance(self.target, Path):
            time.sleep(1.0)  # Both have printed "ready"; give them time to reach the lock.
            return
        deadline = time.monotonic() + 30
        query = "SELECT COUNT(*) FROM pg_locks WHERE locktype = 'advisory' AND NOT granted"
        while self.conn.execute(query).fetchone()[0] < count:
            assert time.monotonic() < deadline, "the processes never waited for the lock"
            time.sleep(0.05)

    def __exit__(self, *exc: object) -> None:
        if isinstance(self.target, Path):
            self.conn.execute("COMMIT")
        self.conn.close()


def test_a_camera_process_waits_for_the_server_to_migrate(
    db_target: Target, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(migrate, "CHECK_TIMEOUT_S", 0.5)
    with pytest.raises(migrate.SchemaError, match="`vigil serve` migrates it at start"):
        Database(db_target, migrate=False)
    monkeypatch.setattr(migrate, "CHECK_TIMEOUT_S", 30.0)
    with ThreadPoolExecutor(1) as pool:
        camera_process = pool.submit(Database, db_target, migrate=False)
        time.sleep(0.5)
        assert not camera_process.done(), "it waits while the schema is not there"
        server = Database(db_target)
        opened = camera_process.result(timeout=30)
    camera = server.add_camera("door", "demo", "adaptive", 100.0)
    assert opened.camera(camera)["name"] == "door"  # type: ignore[index]
    opened.close()
    server.close()


def test_a_schema_newer_than_this_release_is_refused(db_target: Target) -> None:
    Database(db_target).close()
    statement = "UPDATE alembic_version SET version_num = '9999'"
    if isinstance(db_target, Path):
        import sqlite3

        with sqlite3.connect(db_target) as conn:
            conn.execute(statement)
        conn.close()
    else:
        with psycopg.connect(db_target) as pg:
            pg.execute(statement)
    for camera_process in (False, True):
        with pytest.raises(migrate.SchemaError, match="newer than this Vigil's"):
            Database(db_target, migrate=not camera_process)


def test_rows_one_transaction_locks_another_skips(postgres_url: str) -> None:
    """What nodes placing cameras will do (issue 31): each claims the cameras no other is
    claiming at that moment, ``FOR UPDATE SKIP LOCKED``, without waiting for one another."""
    first_node, second_node = Database(postgres_url), Database(postgres_url)
    ids = [first_node.add_camera(f"cam{i}", "demo", "adaptive", 100.0) for i in range(3)]
    claim = select(cameras.c.id).order_by(cameras.c.id).limit(2).with_for_update(skip_locked=True)
    claimed = threading.Event()
    release = threading.Event()
    first: list[int] = []

    def hold() -> None:
        with first_node.transaction() as conn:
            first.extend(conn.execute(claim).scalars())
            claimed.set()
            release.wait(10)

    holder = threading.Thread(target=hold)
    holder.start()
    assert claimed.wait(10)
    with second_node.transaction() as conn:
        second = list(conn.execute(claim).scalars())
        waited = conn.execute(text("SELECT 1")).scalar()
    release.set()
    holder.join(10)
    assert first == ids[:2] and second == ids[2:] and waited == 1
    first_node.close()
    second_node.close()


def test_totals_stay_exact_with_writers_at_once(db_target: Target) -> None:
    """Threads of several processes (here: of two Database objects) adding and deleting
    snapshots and clips at once, one by one and in bulk as retention does: the running
    totals are the sums of the rows, and no writer fails."""
    dbs = [Database(db_target), Database(db_target)]

    def write(index: int) -> None:
        db = dbs[index % 2]
        for i in range(30):
            snapshot = db.add_snapshot(1, None, float(i), "frame", f"{index}/{i}.jpg", 100 + i)
            event = db.add_event(1, float(i), [], 1.0)
            db.end_event(event, float(i) + 1, 1.0)
            db.start_clip(event, f"{index}/{i}.mp4", float(i))
            db.finish_clip(event, 1000 + index, 1.0)
            if i % 3 == 0:
                db.delete_snapshots([snapshot])
                db.delete_events([event])

    def prune(index: int) -> None:  # Two prune the same rows at once, in bulk.
        db = dbs[index % 2]
        snapshots = [s["id"] for s in db.snapshots(limit=10_000)]
        events = [e["id"] for e in db.events(limit=10_000)]
        for start in range(0, len(snapshots), 40):
            db.delete_snapshots(snapshots[start : start + 40][:: 1 if index % 2 else -1])
            db.delete_events(events[start : start + 40])

    with ThreadPoolExecutor(6) as pool:
        list(pool.map(write, range(6)))
    with ThreadPoolExecutor(6) as pool:
        done = [pool.submit(write, 10 + i) for i in range(2)]
        done += [pool.submit(prune, i) for i in range(4)]
        for future in done:
            future.result()
    ((snapshots,),) = raw_rows(db_target, "SELECT COALESCE(SUM(size), 0) FROM snapshots")
    ((clips,),) = raw_rows(db_target, "SELECT COALESCE(SUM(clip_bytes), 0) FROM events")
    assert dbs[0].snapshot_bytes() == dbs[1].snapshot_bytes() == snapshots
    assert dbs[0].clip_bytes() == clips
    dbs[0].add_snapshot(1, None, 1.0, "frame", "last.jpg", 7)
    assert dbs[1].snapshot_bytes() == snapshots + 7
    for db in dbs:
        db.close()
