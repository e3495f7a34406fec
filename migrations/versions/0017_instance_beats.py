"""Each API instance's heartbeat, and the instance that sends each push.

* ``instance_beats``: one row per instance name, its last beat (Unix s), written every few seconds while it serves
  (``backend.instance_beat``). An instance that stopped beating is dead to the others.
* ``pushes.instance_name``: the instance that sends the push. A push left ``sending`` by an instance that stopped
  beating is resolved by any instance against the leg's own report at once, instead of blocking every other instance
  (a minute before, by age alone). NULL for the pushes recorded before (their age decides, as it did).

Revision ID: 0017
Revises: 0016
Created: 2026-11-28
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0017"
down_revision = "0016"
branch_labels = None
depends_on = None

_Float = sa.Double().with_variant(sa.REAL(), "sqlite")


def upgrade() -> None:
    op.create_table(
        "instance_beats",
        sa.Column("name", sa.Text(), nullable=False),
        sa.Column("beat_at_unix", _Float, nullable=False),
        sa.PrimaryKeyConstraint("name"),
    )
    op.add_column("pushes", sa.Column("instance_name", sa.Text(), nullable=True))


def downgrade() -> None:
    raise NotImplementedError("QuasiTune's schema only moves forward: restore a backup to go back")
