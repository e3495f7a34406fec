"""Envelope previews walk every node alone at its task: the ones stored before are walked again.

An envelope's preview now walks each node from standing and reached from level walking as well as the ``mixed`` course
(``backend.bench.node_previews``), and its bench verdict gates on every node. A preview stored before has no node
walks, so it would gate on part of the envelope: those rows are removed (a preview is a cache of a deterministic
walk of a version that never changes; the next request walks it again, nodes included). Nothing else is touched: the
approvals, sign-offs and pushes made on them stay as they were, with their audit.

Revision ID: 0018
Revises: 0017
Created: 2026-11-28
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0018"
down_revision = "0017"
branch_labels = None
depends_on = None


def upgrade() -> None:
    previews = sa.table("envelope_previews", sa.column("result_json", sa.Text()))
    op.execute(sa.delete(previews).where(sa.not_(previews.c.result_json.contains('"nodes":'))))


def downgrade() -> None:
    raise NotImplementedError("QuasiTune's schema only moves forward: restore a backup to go back")
