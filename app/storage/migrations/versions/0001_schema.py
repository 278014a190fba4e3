"""The schema as Vigil had it before migrations: cameras, events with their clips, snapshots,
their running totals, analyses, notification targets and the activity history.

SQLite: the statements Vigil ran at every start until then, all of them idempotent, so a
database of any earlier release (without the clips' columns, the notification targets, the
totals...) is brought up to this schema with its rows, one already there is left as it is,
and a new one is made. PostgreSQL: the same tables, made anew, with the totals kept by
triggers too (in ``USAGE_SLOTS`` rows each; see app/storage/schema.py); they need
PostgreSQL 11 or later.

Revision ID: 0001
Revises:
Create Date: 2026-12-05
"""

from __future__ import annotations

import sqlite3

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

SQLITE_SCHEMA = """
CREATE TABLE IF NOT EXISTS cameras (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    name TEXT NOT NULL,
    source TEXT NOT NULL,
    sensitivity REAL,
    min_area REAL NOT NULL DEFAULT 100,
    method TEXT NOT NULL,
    show_mask INTEGER NOT NULL DEFAULT 0,
    active INTEGER NOT NULL DEFAULT 0,
    created_at REAL NOT NULL,
    mask TEXT NOT NULL DEFAULT '[]'
);
CREATE TABLE IF NOT EXISTS events (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    camera_id INTEGER NOT NULL,
    started_at REAL NOT NULL,
    ended_at REAL,
    max_area REAL NOT NULL DEFAULT 0,
    boxes TEXT NOT NULL DEFAULT '[]',
    track_ids TEXT NOT NULL DEFAULT '[]'
);
CREATE INDEX IF NOT EXISTS events_camera_time ON events (camera_id, started_at);
CREATE TABLE IF NOT EXISTS snapshots (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    camera_id INTEGER NOT NULL,
    event_id INTEGER,
    ts REAL NOT NULL,
    kind TEXT NOT NULL DEFAULT 'frame',
    path TEXT NOT NULL,
    size INTEGER NOT NULL DEFAULT 0
);
CREATE INDEX IF NOT EXISTS snapshots_camera_time ON snapshots (camera_id, ts);
CREATE INDEX IF NOT EXISTS snapshots_time ON snapshots (ts);
CREATE INDEX IF NOT EXISTS snapshots_event ON snapshots (event_id);
CREATE INDEX IF NOT EXISTS events_time ON events (started_at);
CREATE INDEX IF NOT EXISTS events_open ON events (camera_id) WHERE ended_at IS NULL;
-- The snapshots' total size, kept by triggers, so a size cap is checked without a scan.
CREATE TABLE IF NOT EXISTS snapshot_usage (
    id INTEGER PRIMARY KEY CHECK (id = 1),
    bytes INTEGER NOT NULL
);
INSERT OR IGNORE INTO snapshot_usage (id, bytes) SELECT 1, COALESCE(SUM(size), 0) FROM snapshots;
CREATE TRIGGER IF NOT EXISTS snapshot_usage_insert AFTER INSERT ON snapshots BEGIN
    UPDATE snapshot_usage SET bytes = bytes + NEW.size WHERE id = 1;
END;
CREATE TRIGGER IF NOT EXISTS snapshot_usage_delete AFTER DELETE ON snapshots BEGIN
    UPDATE snapshot_usage SET bytes = bytes - OLD.size WHERE id = 1;
END;
CREATE TABLE IF NOT EXISTS analyses (
    id TEXT PRIMARY KEY,
    filename TEXT NOT NULL,
    status TEXT NOT NULL,
    progress REAL NOT NULL DEFAULT 0,
    error TEXT,
    options TEXT NOT NULL DEFAULT '{}',
    created_at REAL NOT NULL,
    finished_at REAL
);
-- Where notifications go: Apprise URLs (app/notify). cameras: a JSON list of camera ids,
-- NULL for every camera. origin: 'api' (the API or the page) or 'env' (VIGIL_NOTIFY_URLS).
CREATE TABLE IF NOT EXISTS notification_targets (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    url TEXT NOT NULL,
    cameras TEXT,
    origin TEXT NOT NULL DEFAULT 'api',
    created_at REAL NOT NULL
);
CREATE UNIQUE INDEX IF NOT EXISTS notification_targets_url ON notification_targets (url);
"""

# Columns added after the first release, with their definitions, for older databases.
SQLITE_CAMERA_COLUMNS = {"mask": "TEXT NOT NULL DEFAULT '[]'"}
SQLITE_EVENT_COLUMNS = {
    "clip_path": "TEXT",
    "clip_bytes": "INTEGER NOT NULL DEFAULT 0",
    "clip_s": "REAL",
    "clip_started_at": "REAL",
    "clip_error": "TEXT",
}

SQLITE_RECORDINGS = """
CREATE INDEX IF NOT EXISTS events_clips ON events (started_at) WHERE clip_path IS NOT NULL;
-- The clips' total size, kept by triggers as snapshot_usage is.
CREATE TABLE IF NOT EXISTS clip_usage (
    id INTEGER PRIMARY KEY CHECK (id = 1),
    bytes INTEGER NOT NULL
);
INSERT OR IGNORE INTO clip_usage (id, bytes) SELECT 1, COALESCE(SUM(clip_bytes), 0) FROM events;
CREATE TRIGGER IF NOT EXISTS clip_usage_insert AFTER INSERT ON events BEGIN
    UPDATE clip_usage SET bytes = bytes + NEW.clip_bytes WHERE id = 1;
END;
CREATE TRIGGER IF NOT EXISTS clip_usage_update AFTER UPDATE OF clip_bytes ON events BEGIN
    UPDATE clip_usage SET bytes = bytes + NEW.clip_bytes - OLD.clip_bytes WHERE id = 1;
END;
CREATE TRIGGER IF NOT EXISTS clip_usage_delete AFTER DELETE ON events BEGIN
    UPDATE clip_usage SET bytes = bytes - OLD.clip_bytes WHERE id = 1;
END;
-- A camera's motion while activated: the largest moving share (0..1) of each second.
CREATE TABLE IF NOT EXISTS activity (
    camera_id INTEGER NOT NULL,
    ts INTEGER NOT NULL,
    motion REAL NOT NULL,
    PRIMARY KEY (camera_id, ts)
) WITHOUT ROWID;
"""

USAGE_SLOTS = 16
"""Rows per running total in PostgreSQL: a row's size counts in row ``id % 16``."""

# Each total follows its rows' inserts and (clips) updates row by row: one row at a time, and
# one of size 0 changes no total and takes no lock on one (every event starts without a
# clip). Deletes come in bulk (retention): once per statement, slot by slot in order, so that
# two deleting at once take the slots' locks in the same order and never wait on each other
# in a circle.
POSTGRES_USAGE = (
    """
CREATE FUNCTION snapshot_usage_add() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    UPDATE snapshot_usage SET bytes = bytes + NEW.size WHERE id = mod(NEW.id, 16);
    RETURN NULL;
END $$""",
    """
CREATE TRIGGER snapshot_usage_insert AFTER INSERT ON snapshots
    FOR EACH ROW WHEN (NEW.size <> 0) EXECUTE FUNCTION snapshot_usage_add()""",
    """
CREATE FUNCTION snapshot_usage_remove() RETURNS trigger LANGUAGE plpgsql AS $$
DECLARE
    slot record;
BEGIN
    FOR slot IN
        SELECT mod(id, 16) AS id, SUM(size) AS bytes FROM gone
        GROUP BY 1 HAVING SUM(size) <> 0 ORDER BY 1
    LOOP
        UPDATE snapshot_usage SET bytes = bytes - slot.bytes WHERE id = slot.id;
    END LOOP;
    RETURN NULL;
END $$""",
    """
CREATE TRIGGER snapshot_usage_delete AFTER DELETE ON snapshots
    REFERENCING OLD TABLE AS gone
    FOR EACH STATEMENT EXECUTE FUNCTION snapshot_usage_remove()""",
    """
CREATE FUNCTION clip_usage_add() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_OP = 'INSERT' THEN
        UPDATE clip_usage SET bytes = bytes + NEW.clip_bytes WHERE id = mod(NEW.id, 16);
    ELSE
        UPDATE clip_usage SET bytes = bytes + NEW.clip_bytes - OLD.clip_bytes
            WHERE id = mod(NEW.id, 16);
    END IF;
    RETURN NULL;
END $$""",
    """
CREATE TRIGGER clip_usage_insert AFTER INSERT ON events
    FOR EACH ROW WHEN (NEW.clip_bytes <> 0) EXECUTE FUNCTION clip_usage_add()""",
    """
CREATE TRIGGER clip_usage_update AFTER UPDATE OF clip_bytes ON events
    FOR EACH ROW WHEN (NEW.clip_bytes <> OLD.clip_bytes) EXECUTE FUNCTION clip_usage_add()""",
    """
CREATE FUNCTION clip_usage_remove() RETURNS trigger LANGUAGE plpgsql AS $$
DECLARE
    slot record;
BEGIN
    FOR slot IN
        SELECT mod(id, 16) AS id, SUM(clip_bytes) AS bytes FROM gone
        GROUP BY 1 HAVING SUM(clip_bytes) <> 0 ORDER BY 1
    LOOP
        UPDATE clip_usage SET bytes = bytes - slot.bytes WHERE id = slot.id;
    END LOOP;
    RETURN NULL;
END $$""",
    """
CREATE TRIGGER clip_usage_delete AFTER DELETE ON events
    REFERENCING OLD TABLE AS gone
    FOR EACH STATEMENT EXECUTE FUNCTION clip_usage_remove()""",
)


def upgrade() -> None:
    if op.get_bind().dialect.name == "sqlite":
        _sqlite()
    else:
        _postgres()


def downgrade() -> None:
    raise NotImplementedError("Vigil's migrations only go forward")


def _sqlite() -> None:
    conn = op.get_bind()
    for statement in _statements(SQLITE_SCHEMA):
        conn.exec_driver_sql(statement)
    for table, columns in (("cameras", SQLITE_CAMERA_COLUMNS), ("events", SQLITE_EVENT_COLUMNS)):
        present = {row[1] for row in conn.exec_driver_sql(f"PRAGMA table_info({table})")}
        for column, definition in columns.items():
            if column not in present:
                conn.exec_driver_sql(f"ALTER TABLE {table} ADD COLUMN {column} {definition}")
    for statement in _statements(SQLITE_RECORDINGS):
        conn.exec_driver_sql(statement)


def _statements(script: str) -> list[str]:
    """The statements of ``script`` (one per ``;`` at a line's end, triggers whole)."""
    statements: list[str] = []
    current: list[str] = []
    for line in script.strip().splitlines():
        if line.startswith("--") and not current:
            continue
        current.append(line)
        text = "\n".join(current)
        if line.rstrip().endswith(";") and sqlite3.complete_statement(text):
            statements.append(text)
            current = []
    return statements


def _postgres() -> None:
    def row_id() -> sa.Column[int]:
        return sa.Column("id", sa.BigInteger, sa.Identity(), primary_key=True)

    op.create_table(
        "cameras",
        row_id(),
        sa.Column("name", sa.Text, nullable=False),
        sa.Column("source", sa.Text, nullable=False),
        sa.Column("sensitivity", sa.Double),
        sa.Column("min_area", sa.Double, nullable=False, server_default="100"),
        sa.Column("method", sa.Text, nullable=False),
        sa.Column("show_mask", sa.Integer, nullable=False, server_default="0"),
        sa.Column("active", sa.Integer, nullable=False, server_default="0"),
        sa.Column("created_at", sa.Double, nullable=False),
        sa.Column("mask", sa.Text, nullable=False, server_default="[]"),
    )
    op.create_table(
        "events",
        row_id(),
        sa.Column("camera_id", sa.BigInteger, nullable=False),
        sa.Column("started_at", sa.Double, nullable=False),
        sa.Column("ended_at", sa.Double),
        sa.Column("max_area", sa.Double, nullable=False, server_default="0"),
        sa.Column("boxes", sa.Text, nullable=False, server_default="[]"),
        sa.Column("track_ids", sa.Text, nullable=False, server_default="[]"),
        sa.Column("clip_path", sa.Text),
        sa.Column("clip_bytes", sa.BigInteger, nullable=False, server_default="0"),
        sa.Column("clip_s", sa.Double),
        sa.Column("clip_started_at", sa.Double),
        sa.Column("clip_error", sa.Text),
    )
    op.create_index("events_camera_time", "events", ["camera_id", "started_at"])
    op.create_index("events_time", "events", ["started_at"])
    op.create_index(
        "events_open", "events", ["camera_id"], postgresql_where=sa.text("ended_at IS NULL")
    )
    op.create_index(
        "events_clips", "events", ["started_at"], postgresql_where=sa.text("clip_path IS NOT NULL")
    )
    op.create_table(
        "snapshots",
        row_id(),
        sa.Column("camera_id", sa.BigInteger, nullable=False),
        sa.Column("event_id", sa.BigInteger),
        sa.Column("ts", sa.Double, nullable=False),
        sa.Column("kind", sa.Text, nullable=False, server_default="frame"),
        sa.Column("path", sa.Text, nullable=False),
        sa.Column("size", sa.BigInteger, nullable=False, server_default="0"),
    )
    op.create_index("snapshots_camera_time", "snapshots", ["camera_id", "ts"])
    op.create_index("snapshots_time", "snapshots", ["ts"])
    op.create_index("snapshots_event", "snapshots", ["event_id"])
    for name in ("snapshot_usage", "clip_usage"):
        usage = op.create_table(
            name,
            sa.Column("id", sa.BigInteger, primary_key=True, autoincrement=False),
            sa.Column("bytes", sa.BigInteger, nullable=False),
            sa.CheckConstraint(f"id >= 0 AND id < {USAGE_SLOTS}", name=f"{name}_slot"),
        )
        op.bulk_insert(usage, [{"id": slot, "bytes": 0} for slot in range(USAGE_SLOTS)])
    for statement in POSTGRES_USAGE:
        op.get_bind().exec_driver_sql(statement)
    op.create_table(
        "analyses",
        sa.Column("id", sa.Text, primary_key=True),
        sa.Column("filename", sa.Text, nullable=False),
        sa.Column("status", sa.Text, nullable=False),
        sa.Column("progress", sa.Double, nullable=False, server_default="0"),
        sa.Column("error", sa.Text),
        sa.Column("options", sa.Text, nullable=False, server_default="{}"),
        sa.Column("created_at", sa.Double, nullable=False),
        sa.Column("finished_at", sa.Double),
    )
    op.create_table(
        "notification_targets",
        row_id(),
        sa.Column("url", sa.Text, nullable=False),
        sa.Column("cameras", sa.Text),
        sa.Column("origin", sa.Text, nullable=False, server_default="api"),
        sa.Column("created_at", sa.Double, nullable=False),
    )
    op.create_index("notification_targets_url", "notification_targets", ["url"], unique=True)
    op.create_table(
        "activity",
        sa.Column("camera_id", sa.BigInteger, primary_key=True, autoincrement=False),
        sa.Column("ts", sa.BigInteger, primary_key=True, autoincrement=False),
        sa.Column("motion", sa.Double, nullable=False),
    )
