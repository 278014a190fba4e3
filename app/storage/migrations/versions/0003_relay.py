"""Any node serves the whole site (issue 31, app/nodes/relay.py):

- ``nodes.relay_token``: a secret each node makes at every start and says in its row.
  Another node asking it for what it holds (a camera's pictures, a file) shows that token
  (``X-Vigil-Relay``); whoever reads the database is trusted with the site already.
  ``GET /api/nodes`` never shows it.
- ``file_deletions``: the files of rows deleted on one node (by hand or by retention)
  that another node holds, for that node to delete at its next renewal.
- ``analyses.node``: the node an analysis runs on, whose disk holds its files.

Revision ID: 0003
Revises: 0002
Create Date: 2026-12-05
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None

INT64: sa.types.TypeEngine[int] = sa.BigInteger().with_variant(sa.Integer(), "sqlite")


def upgrade() -> None:
    op.add_column("nodes", sa.Column("relay_token", sa.Text, nullable=False, server_default=""))
    op.create_table(
        "file_deletions",
        sa.Column("id", INT64, primary_key=True),
        sa.Column("node", sa.Text, nullable=False),
        sa.Column("kind", sa.Text, nullable=False),
        sa.Column("path", sa.Text, nullable=False),
    )
    op.create_index("file_deletions_node", "file_deletions", ["node"])
    op.add_column("analyses", sa.Column("node", sa.Text))


def downgrade() -> None:
    raise NotImplementedError("Vigil's migrations only go forward")
