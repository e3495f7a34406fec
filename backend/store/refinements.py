"""Refinements from walking (migration 0012): the record that a draft version came from the leg's own strides."""

from __future__ import annotations

import json
from collections.abc import Callable

from sqlalchemy import Connection, RowMapping, insert, select

from backend.db import utc_now
from backend.errors import NotFoundError
from backend.store.tables import refinements, users
from backend.store.users import User


def recorder(kind: str, parent_id: int, session_ids: list[int], evidence: dict, actor: User
             ) -> Callable[[Connection, dict], dict]:
    """What the version store runs inside its transaction once the refined version is inserted: the refinement row
    (``kind`` ``envelope`` or ``proposal``); returns what the audit entry adds."""
    column = {"envelope": "envelope_id", "proposal": "proposal_id"}[kind]

    def record(conn: Connection, meta: dict) -> dict:
        new_id = conn.execute(insert(refinements).values(
            {column: meta["id"], "parent_id": parent_id, "session_ids_json": json.dumps(session_ids),
             "evidence_json": json.dumps(evidence, allow_nan=False), "created_by": actor.id,
             "created_at": utc_now()})).inserted_primary_key[0]
        return {"refinement_id": int(new_id), "session_ids": session_ids,
                "nodes_changed": evidence.get("nodes_changed", []), "strides_used": evidence.get("strides_used")}

    return record


def _public(row: RowMapping) -> dict:
    return {"id": row["id"], "envelope_id": row["envelope_id"], "proposal_id": row["proposal_id"],
            "parent_id": row["parent_id"], "session_ids": json.loads(row["session_ids_json"]),
            "created_by": row["created_by_name"], "created_at": row["created_at"],
            **json.loads(row["evidence_json"])}


_SELECT = select(refinements, users.c.username.label("created_by_name")).join(users, users.c.id == refinements.c.created_by)


def get_refinement(conn: Connection, refinement_id: int) -> dict:
    row = conn.execute(_SELECT.where(refinements.c.id == refinement_id)).mappings().first()
    if row is None:
        raise NotFoundError(f"refinement {refinement_id} not found")
    return _public(row)


def of_version(conn: Connection, kind: str, version_id: int) -> dict | None:
    """The refinement that made this envelope or proposal, if one did."""
    column = {"envelope": "envelope_id", "proposal": "proposal_id"}[kind]
    row = conn.execute(_SELECT.where(refinements.c[column] == version_id)).mappings().first()
    return None if row is None else _public(row)
