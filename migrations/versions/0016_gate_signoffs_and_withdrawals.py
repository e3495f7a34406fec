"""A hard gate: two prosthetists' sign-offs on a version the bench did not find clean; and withdrawn versions.

* ``gate_signoffs``: one prosthetist's written sign-off on a version's bench findings, for exactly its content
  (``content_sha256``); a version whose bench preview is not clean is approved or pushed only with two, by two
  accounts (``backend.store.signoffs``).
* ``withdrawals``: an approved version taken back, by whom and why; it is never pushed again and a leg running it is
  sent back to the last version it ran that was not withdrawn, or to safe mode (``backend.store.withdrawals``).
* ``pushes.sent_back_reason``: a push the server made because the version the leg ran was withdrawn (which, by whom,
  why), for the monitor.
* ``walking_sessions.simulated``: walked by the simulated patient on the simulated leg (1) or by a person (0); NULL for
  the sessions recorded before (not known). Every report and PDF of a simulated walk says so in its header.

Both are append-only (triggers, as the audit log).

Revision ID: 0016
Revises: 0015
Created: 2026-11-28
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0016"
down_revision = "0015"
branch_labels = None
depends_on = None

_APPEND_ONLY = {"gate_signoffs": "a sign-off is kept as written", "withdrawals": "a withdrawal is kept as written"}


def upgrade() -> None:
    op.create_table(
        "gate_signoffs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("proposal_id", sa.Integer(), nullable=True),
        sa.Column("envelope_id", sa.Integer(), nullable=True),
        sa.Column("content_sha256", sa.Text(), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("reason", sa.Text(), nullable=False),
        sa.Column("signed_at", sa.Text(), nullable=False),
        sa.CheckConstraint("(proposal_id IS NULL) <> (envelope_id IS NULL)"),
        sa.CheckConstraint("length(content_sha256) = 64"),
        sa.ForeignKeyConstraint(["envelope_id"], ["envelopes.id"]),
        sa.ForeignKeyConstraint(["proposal_id"], ["proposals.id"]),
        sa.ForeignKeyConstraint(["user_id"], ["users.id"]),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("envelope_id", "user_id"),
        sa.UniqueConstraint("proposal_id", "user_id"),
    )
    op.create_table(
        "withdrawals",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("proposal_id", sa.Integer(), nullable=True),
        sa.Column("envelope_id", sa.Integer(), nullable=True),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("reason", sa.Text(), nullable=False),
        sa.Column("withdrawn_at", sa.Text(), nullable=False),
        sa.CheckConstraint("(proposal_id IS NULL) <> (envelope_id IS NULL)"),
        sa.ForeignKeyConstraint(["envelope_id"], ["envelopes.id"]),
        sa.ForeignKeyConstraint(["proposal_id"], ["proposals.id"]),
        sa.ForeignKeyConstraint(["user_id"], ["users.id"]),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("envelope_id"),
        sa.UniqueConstraint("proposal_id"),
    )
    op.add_column("pushes", sa.Column("sent_back_reason", sa.Text(), nullable=True))
    op.add_column("walking_sessions", sa.Column("simulated", sa.Integer(), sa.CheckConstraint("simulated IN (0, 1)"),
                                                nullable=True))
    postgres = op.get_bind().dialect.name == "postgresql"
    for table, message in _APPEND_ONLY.items():
        for event in ("UPDATE", "DELETE"):
            name = f"{table}_no_{event.lower()}"
            if postgres:    # quasitune_refuse: revision 0012
                op.execute(f"CREATE TRIGGER {name} BEFORE {event} ON {table} FOR EACH ROW "
                           f"EXECUTE FUNCTION quasitune_refuse('{message}')")
            else:
                op.execute(f"CREATE TRIGGER {name} BEFORE {event} ON {table} BEGIN SELECT RAISE(ABORT, '{message}'); END")


def downgrade() -> None:
    raise NotImplementedError("QuasiTune's schema only moves forward: restore a backup to go back")
