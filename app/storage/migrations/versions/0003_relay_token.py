"""Relaying between nodes (issue 31): each node's ``relay_token``, a secret it makes at every
start and says in its ``nodes`` row. Another node asking it for a camera's pictures or a
file it holds shows that token (``X-Vigil-Relay``); whoever reads the database is trusted
with the site already. ``GET /api/nodes`` never shows it.

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


def upgrade() -> None:
    op.add_column("nodes", sa.Column("relay_token", sa.Text, nullable=False, server_default=""))


def downgrade() -> None:
    raise NotImplementedError("Vigil's migrations only go forward")
