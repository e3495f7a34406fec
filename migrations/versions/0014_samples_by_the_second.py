"""Session telemetry stored one row per second of walking: ``session_sample_seconds`` replaces ``session_samples``.

A row holds one second's samples (up to 100) packed into one value (``backend.store.sample_pack``, format 1: shuffled
float64 columns under zlib). Every stored sample is carried over exactly, grouped by ``seq // 100``, in the same
transaction that drops the old table (and its append-only trigger: a second's row is now merged by the store, which
keeps every stored sample as it was). Format 1 is read by every later QuasiTune.

Revision ID: 0014
Revises: 0013
Created: 2026-11-27
"""

from __future__ import annotations

import itertools

import sqlalchemy as sa
from alembic import op

from backend.store.sample_pack import COLUMNS, pack, second_of

revision = "0014"
down_revision = "0013"
branch_labels = None
depends_on = None


def upgrade() -> None:
    new = op.create_table(
        "session_sample_seconds",
        sa.Column("session_id", sa.Integer(), nullable=False),
        sa.Column("second", sa.Integer(), nullable=False),
        sa.Column("n", sa.Integer(), nullable=False),
        sa.Column("samples", sa.LargeBinary(), nullable=False),
        sa.CheckConstraint("second >= 0"),
        sa.CheckConstraint("n BETWEEN 1 AND 100"),
        sa.ForeignKeyConstraint(["session_id"], ["walking_sessions.id"]),
        sa.PrimaryKeyConstraint("session_id", "second"),
    )
    bind = op.get_bind()
    old = sa.table("session_samples", *(sa.column(c) for c in ("session_id", *COLUMNS)))
    rows = bind.execute(sa.select(old).order_by(old.c.session_id, old.c.seq))
    batch: list[dict] = []
    for (session_id, second), group in itertools.groupby(rows, key=lambda r: (r[0], second_of(r[1]))):
        samples = [tuple(r[1:]) for r in group]
        batch.append({"session_id": session_id, "second": second, "n": len(samples), "samples": pack(samples)})
        if len(batch) >= 500:
            bind.execute(sa.insert(new), batch)
            batch = []
    if batch:
        bind.execute(sa.insert(new), batch)
    op.drop_table("session_samples")


def downgrade() -> None:
    raise NotImplementedError("QuasiTune's schema only moves forward: restore a backup to go back")
