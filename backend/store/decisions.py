"""Approving or rejecting a draft once: the rule proposals and envelopes share (their triggers enforce it too)."""

from __future__ import annotations

import sqlite3
from collections.abc import Callable

from backend.db import utc_now
from backend.errors import ConflictError
from backend.store import audit
from backend.store.bench_verdict import require_bench
from backend.store.users import User
from controller_core.table import LimitViolation

_TABLES = {"proposal": "proposals", "envelope": "envelopes"}


def decide_once(conn: sqlite3.Connection, entity: str, row: sqlite3.Row, status: str, comment: str, actor: User,
                recheck: Callable[[], list[LimitViolation]], checked_against: str, audit_after: dict,
                override_reason: str | None = None) -> None:
    """Record the decision on draft ``row`` (inside the caller's write transaction) and audit it.

    Args:
        entity: ``proposal`` or ``envelope``.
        recheck: the check of the stored content an approval must pass (run only to approve).
        checked_against: what ``recheck`` checks, for the refusal (e.g. "the safety limits").
        override_reason: an approval without a clean bench preview goes ahead only with this written reason
            (:mod:`backend.store.bench_verdict`); kept with the decision and audited.

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
        verdict, override = require_bench(conn, entity, row, override_reason, "approved")   # type: ignore[arg-type]
        bench = verdict["status"]
    conn.execute(f"UPDATE {_TABLES[entity]} SET status = ?, decided_by = ?, decided_at = ?, decision_comment = ?, "
                 "decision_override = ? WHERE id = ? AND status = 'draft'",
                 (status, actor.id, utc_now(), comment, override, row["id"]))
    audit.record(conn, actor.id, actor.username, f"{entity}.{'approve' if status == 'approved' else 'reject'}",
                 entity, row["id"], before={"status": "draft"}, after={
                     "status": status, "comment": comment, **audit_after,
                     **({"bench": bench} if bench else {}), **({"override_reason": override} if override else {})})


# what every decided-once version's summary reads, besides its own columns
VERSION_COLUMNS = ("id", "patient_id", "version", "parent_id", "source", "status", "created_at", "edit_comment",
                   "decided_at", "decision_comment", "decision_override", "safety_ok")


def summary_select(select: str, alias: str, columns: str) -> str:
    """``select`` (``SELECT {alias}.*, …``) reading only the shared version columns and ``columns``, not the
    stored bodies."""
    shared = ", ".join(f"{alias}.{c}" for c in VERSION_COLUMNS)
    return select.replace(f"SELECT {alias}.*,", f"SELECT {shared}, {columns},", 1)


def version_page(conn: sqlite3.Connection, entity: str, select: str, alias: str, patient_id: int, limit: int,
                 before_version: int | None) -> tuple[list[sqlite3.Row], int]:
    """One page of a patient's versions, newest first (older than ``before_version``), and how many in all."""
    table = _TABLES[entity]
    total = conn.execute(f"SELECT count(*) FROM {table} WHERE patient_id = ?", (patient_id,)).fetchone()[0]
    rows = conn.execute(select + f" WHERE {alias}.patient_id = ? AND {alias}.version < ? ORDER BY {alias}.version "
                        "DESC LIMIT ?", (patient_id, before_version or 2**62, limit)).fetchall()
    return rows, total
