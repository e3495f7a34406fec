"""The append-only audit log: who did what, when, to which entity, with the values before and after.

Triggers refuse any UPDATE or DELETE of ``audit_log`` (the baseline revision, on SQLite and PostgreSQL).
"""

from __future__ import annotations

import json
from typing import Any

from sqlalchemy import Connection, RowMapping, insert, select

from backend.db import utc_now
from backend.store.tables import audit_log

_INSERT = insert(audit_log)   # every write appends: built once (see backend/store/__init__.py)


def record(conn: Connection, actor_id: int | None, actor_name: str, action: str, entity: str,
           entity_id: int | None, before: Any = None, after: Any = None) -> int:
    """Append one entry (call inside the transaction that makes the change); returns its id."""
    return int(conn.execute(_INSERT, dict(
        at=utc_now(), actor_id=actor_id, actor_name=actor_name, action=action, entity=entity, entity_id=entity_id,
        before_json=None if before is None else json.dumps(before, sort_keys=True),
        after_json=None if after is None else json.dumps(after, sort_keys=True))).inserted_primary_key[0])


def _entry(row: RowMapping) -> dict:
    return {"id": row["id"], "at": row["at"], "actor": row["actor_name"], "action": row["action"],
            "entity": row["entity"], "entity_id": row["entity_id"],
            "before": None if row["before_json"] is None else json.loads(row["before_json"]),
            "after": None if row["after_json"] is None else json.loads(row["after_json"])}


def list_entries(conn: Connection, entity: str | None = None, entity_id: int | None = None,
                 actor: str | None = None, before_id: int | None = None, limit: int = 100) -> list[dict]:
    """Newest first; ``before_id`` pages back through older entries."""
    c = audit_log.c
    query = select(audit_log)
    for column, value in ((c.entity, entity), (c.entity_id, entity_id), (c.actor_name, actor)):
        if value is not None:
            query = query.where(column == value)
    if before_id is not None:
        query = query.where(c.id < before_id)
    return [_entry(r) for r in conn.execute(query.order_by(c.id.desc()).limit(limit)).mappings()]
