"""Prosthetists' sign-offs on a version's bench findings: the gate's override takes two.

A version whose bench preview is not clean (a figure beyond its bound, or not walked yet) is approved or pushed only
when two prosthetists, with two accounts, each wrote why they go ahead anyway, on exactly its content (the sign-off
keeps the content's SHA-256; a sign-off on other content never counts). Each sign-off is audited; none is ever changed
or deleted (revision 0016's triggers).
"""

from __future__ import annotations

from typing import Literal

from sqlalchemy import Connection, bindparam, insert, select
from sqlalchemy.exc import IntegrityError

from backend.db import utc_now
from backend.errors import ConflictError
from backend.store import audit
from backend.store.dialect import unique_violation
from backend.store.tables import gate_signoffs, users
from backend.store.users import User

Kind = Literal["proposal", "envelope"]
NEEDED = 2      # sign-offs by distinct prosthetists that override the bench's gate
# read with every version shown: built once (see backend/store/__init__.py)
_OF = (select(gate_signoffs.c.content_sha256, gate_signoffs.c.reason, gate_signoffs.c.signed_at,
              gate_signoffs.c.user_id, users.c.username)
       .select_from(gate_signoffs.join(users, users.c.id == gate_signoffs.c.user_id))
       .where(gate_signoffs.c.version_id == bindparam("item_id")).order_by(gate_signoffs.c.id))


def signoffs(conn: Connection, kind: Kind, item_id: int, content_sha256: str) -> list[dict]:
    """The sign-offs on this version's content, oldest first: ``by``, ``reason``, ``at``."""
    return [{"by": r["username"], "user_id": r["user_id"], "reason": r["reason"], "at": r["signed_at"]}
            for r in conn.execute(_OF, {"item_id": item_id}).mappings() if r["content_sha256"] == content_sha256]


def sign(conn: Connection, kind: Kind, item_id: int, content_sha256: str, actor: User, reason: str) -> list[dict]:
    """Record ``actor``'s sign-off (inside the caller's write transaction) and return them all; refused (409) when
    ``actor`` already signed this version off."""
    if any(s["user_id"] == actor.id for s in signoffs(conn, kind, item_id, content_sha256)):
        raise ConflictError(f"you ({actor.username}) already signed off {kind} {item_id}'s bench findings; the "
                            "second sign-off must come from another prosthetist's account")
    try:
        conn.execute(insert(gate_signoffs).values(version_id=item_id, content_sha256=content_sha256,
                                                  user_id=actor.id, reason=reason, signed_at=utc_now()))
    except IntegrityError as exc:   # the same person's other request (another instance) signed a moment ago
        if not unique_violation(exc, "gate_signoffs_version_id_user_id_key", "gate_signoffs.version_id, "
                                "gate_signoffs.user_id"):
            raise
        raise ConflictError(f"your ({actor.username}) sign-off on {kind} {item_id} was recorded a moment ago by another "
                            "request; reload it to see where it stands") from None
    audit.record(conn, actor.id, actor.username, f"{kind}.gate_signoff", kind, item_id, before=None,
                 after={"content_sha256": content_sha256, "reason": reason})
    return signoffs(conn, kind, item_id, content_sha256)


def summary(signed: list[dict]) -> str | None:
    """The override as one line, for the version, its pushes, the monitor and the reports: who signed and why."""
    if not signed:
        return None
    return "; ".join(f"{s['by']}: {s['reason']}" for s in signed)
