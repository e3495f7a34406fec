"""Refinements from walking (migration 0012): the record that a draft version came from the leg's own strides."""

from __future__ import annotations

import json
from collections.abc import Callable

from sqlalchemy import Connection, RowMapping, insert, select

from backend.db import utc_now
from backend.errors import NotFoundError
from backend.store.tables import refinements, users, versions
from backend.store.users import User


def recorder(parent_id: int, session_ids: list[int], evidence: dict, actor: User) -> Callable[[Connection, dict], dict]:
    """What the version store runs inside its transaction once the refined version is inserted: the refinement row
    (of the new version, derived from ``parent_id``); returns what the audit entry adds."""

    def record(conn: Connection, meta: dict) -> dict:
        new_id = conn.execute(insert(refinements).values(
            {"version_id": meta["id"], "parent_id": parent_id, "session_ids_json": json.dumps(session_ids),
             "evidence_json": json.dumps(evidence, allow_nan=False), "created_by": actor.id,
             "created_at": utc_now()})).inserted_primary_key[0]
        return {"refinement_id": int(new_id), "session_ids": session_ids,
                "nodes_changed": evidence.get("nodes_changed", []), "strides_used": evidence.get("strides_used")}

    return record


_SELECT = (select(refinements, users.c.username.label("created_by_name"), versions.c.kind)
           .join(users, users.c.id == refinements.c.created_by).join(versions, versions.c.id == refinements.c.version_id))


def refinement_row(conn: Connection, refinement_id: int) -> RowMapping:
    """A refinement with who made it and the kind of version it made."""
    row = conn.execute(_SELECT.where(refinements.c.id == refinement_id)).mappings().first()
    if row is None:
        raise NotFoundError(f"refinement {refinement_id} not found")
    return row


def row_of_version(conn: Connection, version_id: int) -> RowMapping | None:
    """The refinement that made this version (a table or an envelope), if one did."""
    return conn.execute(_SELECT.where(refinements.c.version_id == version_id)).mappings().first()
