"""Nodes (issue 31): the ``nodes`` table, where each node says it is alive; per camera the
lease (``node``, ``lease_until``) and a pin (``pinned_to``); and per event (with its clip)
and snapshot the node that made it, whose disk holds the file.

Rows from before name no node (null): they were made by the one machine there was.

Revision ID: 0002
Revises: 0001
Create Date: 2026-12-05
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None

INT64: sa.types.TypeEngine[int] = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
FLOAT64: sa.types.TypeEngine[float] = sa.Double().with_variant(sa.REAL(), "sqlite")


def upgrade() -> None:
    op.create_table(
        "nodes",
        sa.Column("name", sa.Text, primary_key=True),
        sa.Column("url", sa.Text, nullable=False, server_default=""),
        sa.Column("capacity", INT64, nullable=False),
        sa.Column("load", FLOAT64, nullable=False, server_default="0"),
        sa.Column("renewed_at", FLOAT64, nullable=False),
    )
    op.add_column("cameras", sa.Column("node", sa.Text))
    op.add_column("cameras", sa.Column("lease_until", FLOAT64))
    op.add_column("cameras", sa.Column("pinned_to", sa.Text))
    op.add_column("events", sa.Column("node", sa.Text))
    op.add_column("snapshots", sa.Column("node", sa.Text))


def downgrade() -> None:
    raise NotImplementedError("Vigil's migrations only go forward")
