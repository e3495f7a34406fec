"""Several API instances on one database: failed sign-ins counted in the database, one push on its way per device.

* ``login_failures``: each failed sign-in (time, the name as typed lower-cased, the client address), so the throttle's
  windows are the same for every instance (``backend.throttle``); rows older than the longest window are purged.
* ``one_push_sending_per_device``: a partial unique index on ``pushes(device_id) WHERE status = 'sending'``. A push to a
  device while another is being sent is refused by the database whichever instance records it. A database holding two
  ``sending`` pushes of one device (a server that stopped mid-push twice without a status in between) has the older
  ones marked ``unconfirmed`` first, as a restarted server would (the device's next status decides them).

Revision ID: 0013
Revises: 0012
Created: 2026-11-27
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0013"
down_revision = "0012"
branch_labels = None
depends_on = None

_Float = sa.Double().with_variant(sa.REAL(), "sqlite")


def upgrade() -> None:
    op.create_table(
        "login_failures",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("at_unix", _Float, nullable=False),
        sa.Column("username_key", sa.Text(), nullable=False),
        sa.Column("address", sa.Text(), nullable=False),
        sa.PrimaryKeyConstraint("id"),
    )
    with op.batch_alter_table("login_failures", schema=None) as batch_op:
        batch_op.create_index("login_failures_by_user", ["username_key", "at_unix"], unique=False)
        batch_op.create_index("login_failures_by_address", ["address", "at_unix"], unique=False)
        batch_op.create_index("login_failures_by_time", ["at_unix"], unique=False)
    op.execute("UPDATE pushes SET status = 'unconfirmed', error = 'the server stopped during this push; the "
               "device''s next status tells whether it holds it' WHERE status = 'sending' AND id NOT IN "
               "(SELECT max(id) FROM pushes WHERE status = 'sending' GROUP BY device_id)")
    op.create_index("one_push_sending_per_device", "pushes", ["device_id"], unique=True,
                    sqlite_where=sa.text("status = 'sending'"), postgresql_where=sa.text("status = 'sending'"))


def downgrade() -> None:
    raise NotImplementedError("QuasiTune's schema only moves forward: restore a backup to go back")
