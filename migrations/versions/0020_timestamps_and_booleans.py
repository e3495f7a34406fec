"""Times as timestamps and flags as booleans (PostgreSQL); SQLite, which has neither type, is left as it is.

On PostgreSQL every time column becomes ``timestamp with time zone`` (the ISO-8601 UTC text it held, cast) and every
flag ``boolean`` (0/1 → false/true; a flag's default ``false``), its ``IN (0, 1)`` check dropped (the type says it).
PostgreSQL refuses to change the type of a column a trigger names (the immutability triggers' ``UPDATE OF`` lists), so
the triggers on these tables are read back as the database wrote them, dropped, and made again after the change,
word for word. On SQLite times stay ISO-8601 text and flags checked 0/1 integers, as SQLAlchemy's own ``DateTime``
and ``Boolean`` keep them there; the application reads both alike (``backend.store.column_types``).

Revision ID: 0020
Revises: 0019
Created: 2026-11-29
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0020"
down_revision = "0019"
branch_labels = None
depends_on = None

TIMES = {"users": ("created_at", "password_changed_at"), "audit_log": ("at",),
         "patients": ("created_at", "updated_at"), "tokens": ("issued_at",),
         "devices": ("registered_at", "assigned_at"), "proposals": ("created_at", "decided_at"),
         "envelopes": ("created_at", "decided_at"), "proposal_previews": ("created_at",),
         "envelope_previews": ("created_at",), "gate_signoffs": ("signed_at",),
         "pushes": ("requested_at", "acknowledged_at", "active_at", "ended_at"), "refinements": ("created_at",),
         "walking_sessions": ("started_at", "stopped_at"), "withdrawals": ("withdrawn_at",)}
FLAGS = {"users": ("disabled", "must_change_password"), "proposals": ("extrapolation", "safety_ok"),
         "envelopes": ("extrapolation", "safety_ok"), "walking_sessions": ("simulated",)}
DEFAULT_FALSE = {("users", "disabled"), ("users", "must_change_password")}


def upgrade() -> None:
    if op.get_bind().dialect.name != "postgresql":
        return
    conn = op.get_bind()
    tables = sorted(set(TIMES) | set(FLAGS))
    triggers = conn.execute(sa.text(
        "SELECT t.tgname, c.relname, pg_get_triggerdef(t.oid) FROM pg_trigger t JOIN pg_class c ON c.oid = t.tgrelid "
        "WHERE NOT t.tgisinternal AND c.relname = ANY(:tables) ORDER BY c.relname, t.tgname"),
        {"tables": tables}).all()
    for name, table, _ in triggers:
        op.execute(f'DROP TRIGGER "{name}" ON "{table}"')
    checks = conn.execute(sa.text(
        "SELECT con.conname, c.relname FROM pg_constraint con JOIN pg_class c ON c.oid = con.conrelid "
        "WHERE con.contype = 'c' AND c.relname = ANY(:tables) "
        "AND pg_get_constraintdef(con.oid) ~ 'ARRAY\\[0, 1\\]'"), {"tables": tables}).all()
    for name, table in checks:
        op.execute(f'ALTER TABLE "{table}" DROP CONSTRAINT "{name}"')
    for table, columns in TIMES.items():
        for column in columns:
            op.execute(f'ALTER TABLE "{table}" ALTER COLUMN "{column}" TYPE timestamp with time zone '
                       f'USING "{column}"::timestamp with time zone')
    for table, columns in FLAGS.items():
        for column in columns:
            op.execute(f'ALTER TABLE "{table}" ALTER COLUMN "{column}" DROP DEFAULT')
            op.execute(f'ALTER TABLE "{table}" ALTER COLUMN "{column}" TYPE boolean USING "{column}" <> 0')
            if (table, column) in DEFAULT_FALSE:
                op.execute(f'ALTER TABLE "{table}" ALTER COLUMN "{column}" SET DEFAULT false')
    for _, _, definition in triggers:
        op.execute(definition)


def downgrade() -> None:
    raise NotImplementedError("QuasiTune's schema only moves forward: restore a backup to go back")
