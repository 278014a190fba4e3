"""The tables, defined once for SQLite and PostgreSQL: every query in ``app.storage.db`` is
built from them with SQLAlchemy Core, and the migrations (``app/storage/migrations``) make
the same tables in either database (tests/storage/test_migrations.py compares them).

Integers are 64-bit on both: SQLite's are, and PostgreSQL's ``BIGINT``. A row id is
SQLite's ``INTEGER PRIMARY KEY`` (the rowid) and PostgreSQL's identity column. Times are
seconds since the epoch as double precision (SQLite ``REAL``); JSON lists are text.
"""

from __future__ import annotations

from sqlalchemy import REAL, BigInteger, Column, Double, Index, Integer, MetaData, Table, Text, text
from sqlalchemy.types import TypeEngine

INT64: TypeEngine[int] = BigInteger().with_variant(Integer(), "sqlite")
"""A 64-bit integer: ``INTEGER`` in SQLite (the rowid's own type), ``BIGINT`` elsewhere."""
FLOAT64: TypeEngine[float] = Double().with_variant(REAL(), "sqlite")
"""A double-precision number: ``REAL`` in SQLite (as its tables have always said),
``DOUBLE PRECISION`` elsewhere."""

USAGE_SLOTS = 16
"""PostgreSQL keeps each running total (``snapshot_usage``, ``clip_usage``) in this many rows,
a row's size counting in the slot ``id % USAGE_SLOTS``: writers on many nodes rarely wait for
one another's row lock. SQLite keeps one row (``id`` 1): one writer at a time anyway. The
total is the sum of the rows in both."""

metadata = MetaData()

cameras = Table(
    "cameras",
    metadata,
    Column("id", INT64, primary_key=True),
    Column("name", Text, nullable=False),
    Column("source", Text, nullable=False),
    Column("sensitivity", FLOAT64),
    Column("min_area", FLOAT64, nullable=False, server_default="100"),
    Column("method", Text, nullable=False),
    Column("show_mask", Integer, nullable=False, server_default="0"),
    Column("active", Integer, nullable=False, server_default="0"),
    Column("created_at", FLOAT64, nullable=False),
    Column("mask", Text, nullable=False, server_default="[]"),
    # Its lease (app/nodes/leases.py): the node running it, until when unless renewed.
    Column("node", Text),
    Column("lease_until", FLOAT64),
    Column("pinned_to", Text),  # The only node that may run it (a USB camera's), or null.
    sqlite_autoincrement=True,
)

events = Table(
    "events",
    metadata,
    Column("id", INT64, primary_key=True),
    Column("camera_id", INT64, nullable=False),
    Column("started_at", FLOAT64, nullable=False),
    Column("ended_at", FLOAT64),
    Column("max_area", FLOAT64, nullable=False, server_default="0"),
    Column("boxes", Text, nullable=False, server_default="[]"),
    Column("track_ids", Text, nullable=False, server_default="[]"),
    # Its clip (app/recording/): the file under the clips folder, null when it has none
    # (not recorded, refused by the disk, deleted by retention: clip_error says why).
    Column("clip_path", Text),
    Column("clip_bytes", INT64, nullable=False, server_default="0"),
    Column("clip_s", FLOAT64),  # Null while the clip is being recorded.
    Column("clip_started_at", FLOAT64),  # The wall time of its first frame.
    Column("clip_error", Text),
    Column("node", Text),  # The node that made it and holds its clip; null: from before nodes.
    Index("events_camera_time", "camera_id", "started_at"),
    Index("events_time", "started_at"),
    Index(
        "events_open",
        "camera_id",
        sqlite_where=text("ended_at IS NULL"),
        postgresql_where=text("ended_at IS NULL"),
    ),
    Index(
        "events_clips",
        "started_at",
        sqlite_where=text("clip_path IS NOT NULL"),
        postgresql_where=text("clip_path IS NOT NULL"),
    ),
    sqlite_autoincrement=True,
)

snapshots = Table(
    "snapshots",
    metadata,
    Column("id", INT64, primary_key=True),
    Column("camera_id", INT64, nullable=False),
    Column("event_id", INT64),
    Column("ts", FLOAT64, nullable=False),
    Column("kind", Text, nullable=False, server_default="frame"),
    Column("path", Text, nullable=False),
    Column("size", INT64, nullable=False, server_default="0"),
    Column("node", Text),  # The node whose disk holds the file; null: from before nodes.
    Index("snapshots_camera_time", "camera_id", "ts"),
    Index("snapshots_time", "ts"),
    Index("snapshots_event", "event_id"),
    sqlite_autoincrement=True,
)

# The running totals of the snapshots' sizes and of the clips' (events.clip_bytes), kept by
# triggers in both databases, so a size cap is checked without a scan.
snapshot_usage = Table(
    "snapshot_usage",
    metadata,
    Column("id", INT64, primary_key=True, autoincrement=False),
    Column("bytes", INT64, nullable=False),
)
clip_usage = Table(
    "clip_usage",
    metadata,
    Column("id", INT64, primary_key=True, autoincrement=False),
    Column("bytes", INT64, nullable=False),
)

analyses = Table(
    "analyses",
    metadata,
    Column("id", Text, primary_key=True),
    Column("filename", Text, nullable=False),
    Column("status", Text, nullable=False),
    Column("progress", FLOAT64, nullable=False, server_default="0"),
    Column("error", Text),
    Column("options", Text, nullable=False, server_default="{}"),
    Column("created_at", FLOAT64, nullable=False),
    Column("finished_at", FLOAT64),
    Column("node", Text),  # The node it runs on, whose disk holds its files.
)

# Where notifications go: Apprise URLs (app/notify). cameras: a JSON list of camera ids,
# NULL for every camera. origin: 'api' (the API or the page) or 'env' (VIGIL_NOTIFY_URLS).
notification_targets = Table(
    "notification_targets",
    metadata,
    Column("id", INT64, primary_key=True),
    Column("url", Text, nullable=False),
    Column("cameras", Text),
    Column("origin", Text, nullable=False, server_default="api"),
    Column("created_at", FLOAT64, nullable=False),
    Index("notification_targets_url", "url", unique=True),
    sqlite_autoincrement=True,
)

# A camera's motion while activated: the largest moving share (0..1) of each second.
activity = Table(
    "activity",
    metadata,
    Column("camera_id", INT64, primary_key=True, autoincrement=False),
    Column("ts", INT64, primary_key=True, autoincrement=False),
    Column("motion", FLOAT64, nullable=False),
    sqlite_with_rowid=False,
)

# The nodes of a site (app/nodes/): each renews its row with its leases; one whose
# renewed_at is older than VIGIL_LEASE_S is gone. load: its cameras over its capacity.
# relay_token: what another node shows it to be relayed its pictures and files.
nodes = Table(
    "nodes",
    metadata,
    Column("name", Text, primary_key=True),
    Column("url", Text, nullable=False, server_default=""),
    Column("capacity", INT64, nullable=False),
    Column("load", FLOAT64, nullable=False, server_default="0"),
    Column("renewed_at", FLOAT64, nullable=False),
    Column("relay_token", Text, nullable=False, server_default=""),
)

# Files another node holds whose rows were deleted here (by hand or by retention): that
# node deletes them at its next renewal (app/nodes/keeper.py). kind: snapshot or clip.
file_deletions = Table(
    "file_deletions",
    metadata,
    Column("id", INT64, primary_key=True),
    Column("node", Text, nullable=False),
    Column("kind", Text, nullable=False),
    Column("path", Text, nullable=False),
    Index("file_deletions_node", "node"),
)
