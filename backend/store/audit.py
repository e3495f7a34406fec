"""The append-only audit log: who did what, when, to which entity, with the values before and after.

SQLite triggers refuse any UPDATE or DELETE of ``audit_log`` (migration 0001).
"""

from __future__ import annotations

import json
import sqlite3
from typing import Any

from backend.db import utc_now


def record(conn: sqlite3.Connection, actor_id: int | None, actor_name: str, action: str, entity: str,
           entity_id: int | None, before: Any = None, after: Any = None) -> int:
    """Append one entry (call inside the transaction that makes the change); returns its id."""
    cur = conn.execute(
        "INSERT INTO audit_log (at, actor_id, actor_name, action, entity, entity_id, before_json, after_json) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
        (utc_now(), actor_id, actor_name, action, entity, entity_id,
         None if before is None else json.dumps(before, sort_keys=True),
         None if after is None else json.dumps(after, sort_keys=True)))
    return int(cur.lastrowid)


def _entry(row: sqlite3.Row) -> dict:
    return {"id": row["id"], "at": row["at"], "actor": row["actor_name"], "action": row["action"],
            "entity": row["entity"], "entity_id": row["entity_id"],
            "before": None if row["before_json"] is None else json.loads(row["before_json"]),
            "after": None if row["after_json"] is None else json.loads(row["after_json"])}


def list_entries(conn: sqlite3.Connection, entity: str | None = None, entity_id: int | None = None,
                 actor: str | None = None, before_id: int | None = None, limit: int = 100) -> list[dict]:
    """Newest first; ``before_id`` pages back through older entries."""
    where, args = [], []
    for clause, value in (("entity = ?", entity), ("entity_id = ?", entity_id), ("actor_name = ?", actor),
                          ("id < ?", before_id)):
        if value is not None:
            where.append(clause)
            args.append(value)
    sql = "SELECT * FROM audit_log" + (" WHERE " + " AND ".join(where) if where else "")
    rows = conn.execute(sql + " ORDER BY id DESC LIMIT ?", (*args, limit)).fetchall()
    return [_entry(r) for r in rows]
