"""Approving or rejecting a draft once: the rule proposals and envelopes share (their triggers enforce it too)."""

from __future__ import annotations

import sqlite3
from collections.abc import Callable

from backend.db import utc_now
from backend.errors import ConflictError
from backend.store import audit
from backend.store.users import User
from controller_core.table import LimitViolation

_TABLES = {"proposal": "proposals", "envelope": "envelopes"}


def decide_once(conn: sqlite3.Connection, entity: str, row: sqlite3.Row, status: str, comment: str, actor: User,
                recheck: Callable[[], list[LimitViolation]], checked_against: str, audit_after: dict) -> None:
    """Record the decision on draft ``row`` (inside the caller's write transaction) and audit it.

    Args:
        entity: ``proposal`` or ``envelope``.
        recheck: the check of the stored content an approval must pass (run only to approve).
        checked_against: what ``recheck`` checks, for the refusal (e.g. "the safety limits").

    Raises:
        ConflictError: already decided, or an approval whose content fails ``recheck`` (nothing written).
    """
    if status not in ("approved", "rejected"):
        raise ValueError(f"status must be 'approved' or 'rejected', got {status!r}")
    if row["status"] != "draft":
        raise ConflictError(f"{entity} {row['id']} was already {row['status']} by {row['decided_by_name']} at "
                            f"{row['decided_at']}; derive a new version to change it")
    if status == "approved":
        violations = recheck()
        if violations:
            raise ConflictError(f"{entity} {row['id']} cannot be approved: {len(violations)} value(s) outside "
                                f"{checked_against}: " + "; ".join(v.message for v in violations),
                                violations=[v.model_dump() for v in violations])
    conn.execute(f"UPDATE {_TABLES[entity]} SET status = ?, decided_by = ?, decided_at = ?, decision_comment = ? "
                 "WHERE id = ? AND status = 'draft'", (status, actor.id, utc_now(), comment, row["id"]))
    audit.record(conn, actor.id, actor.username, f"{entity}.{'approve' if status == 'approved' else 'reject'}",
                 entity, row["id"], before={"status": "draft"}, after={"status": status, "comment": comment,
                                                                      **audit_after})
