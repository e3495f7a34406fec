"""The append-only audit log: who did what, when, to which entity, with the values before and after.

Triggers refuse any UPDATE or DELETE of ``audit_log`` (the baseline revision, on SQLite and PostgreSQL).
"""

from __future__ import annotations

import json
from typing import Any

from sqlalchemy import Connection, RowMapping, and_, insert, or_, select

from backend.db import utc_now
from backend.store.tables import audit_log, legacy_ids

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
            "entity": row["entity"], "entity_id": row["entity_id"], "now_version_id": row["now_version_id"],
            "before": None if row["before_json"] is None else json.loads(row["before_json"]),
            "after": None if row["after_json"] is None else json.loads(row["after_json"])}


def list_entries(conn: Connection, entity: str | None = None, entity_id: int | None = None,
                 actor: str | None = None, before_id: int | None = None, limit: int = 100) -> list[dict]:
    """Newest first; ``before_id`` pages back through older entries. An envelope's entries written before one version
    (revision 0021) name it by its old id: they say which version it is now (``now_version_id``), and asking for an
    envelope by its version id finds them too."""
    c, old = audit_log.c, legacy_ids.c
    moved = and_(c.entity == "envelope", old.kind == "envelope", old.old_id == c.entity_id,
                 old.version_id != c.entity_id)
    query = select(audit_log, old.version_id.label("now_version_id")).outerjoin(legacy_ids, moved)
    for column, value in ((c.entity, entity), (c.actor_name, actor)):
        if value is not None:
            query = query.where(column == value)
    if entity_id is not None:
        query = query.where(or_(c.entity_id == entity_id, and_(c.entity == "envelope", old.version_id == entity_id)))
    if before_id is not None:
        query = query.where(c.id < before_id)
    return [_entry(r) for r in conn.execute(query.order_by(c.id.desc()).limit(limit)).mappings()]
