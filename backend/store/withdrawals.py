"""Withdrawn versions: an approved table or envelope taken back, by whom and why.

The decision itself never changes (an approved version stays approved, as its audit says); a withdrawal is a record of
its own (revision 0016, never changed or deleted). A withdrawn version is never pushed again
(``backend.routers.pushes``), and a leg that runs it is sent back to the last version it ran that was not withdrawn,
or put in safe mode (``backend.routers.withdrawals``, ``backend.devices.manager``).
"""

from __future__ import annotations

from typing import Literal

from sqlalchemy import Connection, bindparam, insert, select

from backend.db import utc_now
from backend.errors import ConflictError
from backend.store import audit
from backend.store.tables import users, withdrawals
from backend.store.users import User

Kind = Literal["proposal", "envelope"]
# read with every version shown and every push: built once (see backend/store/__init__.py)
_OF = (select(withdrawals.c.reason, withdrawals.c.withdrawn_at, users.c.username)
       .select_from(withdrawals.join(users, users.c.id == withdrawals.c.user_id))
       .where(withdrawals.c.version_id == bindparam("item_id")))


def withdrawal(conn: Connection, kind: Kind, item_id: int) -> dict | None:
    """``by``, ``at``, ``reason`` of the version's withdrawal, or None."""
    row = conn.execute(_OF, {"item_id": item_id}).mappings().first()
    return None if row is None else {"by": row["username"], "at": row["withdrawn_at"], "reason": row["reason"]}


def withdraw(conn: Connection, kind: Kind, row, actor: User, reason: str) -> dict:
    """Record the withdrawal of approved version ``row`` (inside the caller's write transaction) and audit it."""
    if row["status"] != "approved":
        raise ConflictError(f"{kind} {row['id']} is {row['status']}: only an approved version is withdrawn (a draft is "
                            "rejected instead)")
    done = withdrawal(conn, kind, row["id"])
    if done is not None:
        raise ConflictError(f"{kind} {row['id']} was already withdrawn by {done['by']} at {done['at']}")
    conn.execute(insert(withdrawals).values(version_id=row["id"], user_id=actor.id, reason=reason,
                                            withdrawn_at=utc_now()))
    audit.record(conn, actor.id, actor.username, f"{kind}.withdraw", kind, row["id"], before={"withdrawn": False},
                 after={"withdrawn": True, "reason": reason})
    out = withdrawal(conn, kind, row["id"])
    assert out is not None
    return out
