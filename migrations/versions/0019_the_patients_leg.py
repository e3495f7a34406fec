"""The patient's leg: a description of it on the patient, and on every version the leg it was made for.

* ``patients.leg_json``: the patient's leg as a leg file describes it (``device_bridge/sim/leg_file.py``: height,
  segment and unit masses, drive friction, reflected inertia), or NULL: none given, and the server's bench leg stands
  in for it (the nominal one unless the server was started with ``--leg``), as the pages say.
* ``proposals.leg_json`` and ``envelopes.leg_json``: the leg a version was made for (its swing rows are proposed for
  that leg's inertia) and that its bench preview, its refinements and so its bench verdict walk, fixed when the
  version is made (an edit or a refinement keeps its parent's). The versions stored before were made and previewed on
  the server's bench leg, the nominal one unless the server ran with ``--leg``: they are given the nominal leg
  (``'{}'``, a description with no fields). Kept as written (a trigger, like the content).

Revision ID: 0019
Revises: 0018
Created: 2026-11-29
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0019"
down_revision = "0018"
branch_labels = None
depends_on = None

_KEPT = "the leg a version was made for is kept as written"


def upgrade() -> None:
    sqlite = op.get_bind().dialect.name == "sqlite"
    def json_check(condition: str) -> list[sa.CheckConstraint]:     # PostgreSQL: the application writes it
        return [sa.CheckConstraint(condition)] if sqlite else []

    op.add_column("patients", sa.Column("leg_json", sa.Text(), *json_check("leg_json IS NULL OR json_valid(leg_json)"),
                                        nullable=True))
    for table in ("proposals", "envelopes"):
        op.add_column(table, sa.Column("leg_json", sa.Text(), *json_check("json_valid(leg_json)"), nullable=False,
                                       server_default="{}"))
        name = f"{table}_leg_kept"
        if sqlite:
            op.execute(f"CREATE TRIGGER {name} BEFORE UPDATE OF leg_json ON {table} "
                       f"BEGIN SELECT RAISE(ABORT, '{_KEPT}'); END")
        else:               # quasitune_refuse: revision 0012
            op.execute(f"CREATE TRIGGER {name} BEFORE UPDATE OF leg_json ON {table} FOR EACH ROW "
                       f"EXECUTE FUNCTION quasitune_refuse('{_KEPT}')")


def downgrade() -> None:
    raise NotImplementedError("QuasiTune's schema only moves forward: restore a backup to go back")
