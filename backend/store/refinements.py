"""Refinements from walking (migration 0012): the record that a draft version came from the leg's own strides."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable

from backend.db import utc_now
from backend.errors import NotFoundError
from backend.store.users import User


def recorder(kind: str, parent_id: int, session_ids: list[int], evidence: dict, actor: User
             ) -> Callable[[sqlite3.Connection, dict], dict]:
    """What the version store runs inside its transaction once the refined version is inserted: the refinement row
    (``kind`` ``envelope`` or ``proposal``); returns what the audit entry adds."""
    column = {"envelope": "envelope_id", "proposal": "proposal_id"}[kind]

    def record(conn: sqlite3.Connection, meta: dict) -> dict:
        cur = conn.execute(
            f"INSERT INTO refinements ({column}, parent_id, session_ids_json, evidence_json, created_by, created_at) "
            "VALUES (?, ?, ?, ?, ?, ?)",
            (meta["id"], parent_id, json.dumps(session_ids), json.dumps(evidence, allow_nan=False), actor.id,
             utc_now()))
        return {"refinement_id": int(cur.lastrowid), "session_ids": session_ids,
                "nodes_changed": evidence.get("nodes_changed", []), "strides_used": evidence.get("strides_used")}

    return record


def _public(row: sqlite3.Row) -> dict:
    return {"id": row["id"], "envelope_id": row["envelope_id"], "proposal_id": row["proposal_id"],
            "parent_id": row["parent_id"], "session_ids": json.loads(row["session_ids_json"]),
            "created_by": row["created_by_name"], "created_at": row["created_at"],
            **json.loads(row["evidence_json"])}


_SELECT = "SELECT r.*, u.username AS created_by_name FROM refinements r JOIN users u ON u.id = r.created_by"


def get_refinement(conn: sqlite3.Connection, refinement_id: int) -> dict:
    row = conn.execute(_SELECT + " WHERE r.id = ?", (refinement_id,)).fetchone()
    if row is None:
        raise NotFoundError(f"refinement {refinement_id} not found")
    return _public(row)


def of_version(conn: sqlite3.Connection, kind: str, version_id: int) -> dict | None:
    """The refinement that made this envelope or proposal, if one did."""
    column = {"envelope": "envelope_id", "proposal": "proposal_id"}[kind]
    row = conn.execute(_SELECT + f" WHERE r.{column} = ?", (version_id,)).fetchone()
    return None if row is None else _public(row)
