"""Approving or rejecting a draft once: the rule every version follows, a table or an envelope (the triggers enforce
"once" too)."""

from __future__ import annotations

from collections.abc import Callable

from sqlalchemy import Connection, RowMapping

from backend.errors import ConflictError
from backend.services import legs
from backend.services.bench_verdict import require_bench
from backend.store import audit
from backend.store.decisions import record_decision
from backend.store.users import User
from controller_core.table import LimitViolation


def decide_once(conn: Connection, entity: str, row: RowMapping, status: str, comment: str, actor: User,
                recheck: Callable[[], list[LimitViolation]], checked_against: str, audit_after: dict,
                override_reason: str | None = None) -> None:
    """Record the decision on draft ``row`` (inside the caller's write transaction) and audit it.

    Taken once even when two servers decide the same version at the same moment: the update changes the row only
    while it is still a draft, and the database lets one such update through at a time (SQLite's write lock; on
    PostgreSQL the row lock the first update holds until its commit, after which the second finds no draft and
    changes nothing). An update that changed nothing is refused here, so the loser writes no decision and no audit.

    Args:
        entity: ``proposal`` or ``envelope``.
        recheck: the check of the stored content an approval must pass (run only to approve).
        checked_against: what ``recheck`` checks, for the refusal (e.g. "the safety limits").
        override_reason: an approval without a clean bench preview goes ahead only when two prosthetists signed off
            its findings; this reason is the approver's own sign-off when theirs is the second
            (:mod:`backend.services.bench_verdict`). Who signed off and why is kept with the decision and audited.

    Raises:
        ConflictError: already decided, an approval whose content fails ``recheck``, or one the bench's verdict
            does not allow without an override (nothing written).
    """
    if status not in ("approved", "rejected"):
        raise ValueError(f"status must be 'approved' or 'rejected', got {status!r}")
    if row["status"] != "draft":
        raise ConflictError(f"{entity} {row['id']} was already {row['status']} by {row['decided_by_name']} at "
                            f"{row['decided_at']}; derive a new version to change it")
    bench, override = None, None
    if status == "approved":
        violations = recheck()
        if violations:
            raise ConflictError(f"{entity} {row['id']} cannot be approved: {len(violations)} value(s) outside "
                                f"{checked_against}: " + "; ".join(v.message for v in violations),
                                violations=[v.model_dump() for v in violations])
        verdict, override = require_bench(conn, entity, row, override_reason, "approved",   # type: ignore[arg-type]
                                          actor)
        bench = verdict["status"]
    if not record_decision(conn, row["id"], status, comment, actor, override):
        raise ConflictError(f"{entity} {row['id']} was decided by someone else a moment ago; reload it to see the "
                            "decision")
    audit.record(conn, actor.id, actor.username, f"{entity}.{'approve' if status == 'approved' else 'reject'}",
                 entity, row["id"], before={"status": "draft"}, after={
                     "status": status, "comment": comment, **audit_after,
                     **({"bench": bench} if bench else {}), **({"override_reason": override} if override else {})})


def version_meta(row: RowMapping) -> dict:
    """What every version's view says of it, whichever kind: who made it from what, and its decision (None while a
    draft), from a row of :func:`backend.store.decisions.version_select`."""
    return {
        "id": row["id"], "patient_id": row["patient_id"], "version": row["version"], "parent_id": row["parent_id"],
        "parent_version": row["parent_version"], "source": row["source"], "status": row["status"],
        "created_by": row["created_by_name"], "created_at": row["created_at"], "edit_comment": row["edit_comment"],
        "decision": None if row["status"] == "draft" else {
            "status": row["status"], "by": row["decided_by_name"], "at": row["decided_at"],
            "comment": row["decision_comment"], "override_reason": row["decision_override"]},
        "extrapolation": bool(row["extrapolation"]), "extrapolation_reason": row["extrapolation_reason"],
        "leg": legs.view(legs.version_leg(row)),
    }
