"""What a lost link does to each leg: ``devices.link_mode``, the prosthetist's choice per device.

``supervised`` (every device until someone chooses otherwise, and what the leg itself starts in): a lost host
heartbeat puts the leg in safe mode. ``autonomous``: the leg runs on with the approved table or envelope it holds.
The server sends the stored choice to the device whenever the device reports another (``backend.devices.manager``).

Revision ID: 0015
Revises: 0014
Created: 2026-11-27
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0015"
down_revision = "0014"
branch_labels = None
depends_on = None


def upgrade() -> None:
    # one ALTER on both databases (a column check is allowed in SQLite's ADD COLUMN; no table rebuild)
    op.add_column("devices", sa.Column("link_mode", sa.Text(), sa.CheckConstraint(
        "link_mode IN ('supervised', 'autonomous')"), nullable=False, server_default="supervised"))


def downgrade() -> None:
    raise NotImplementedError("QuasiTune's schema only moves forward: restore a backup to go back")
