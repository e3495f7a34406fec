"""Stored simulated previews of versions (computed once: a version never changes): a table's walk at its task, an
envelope's course and node walks."""

from __future__ import annotations

import json

from sqlalchemy import Connection, bindparam, select

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError
from backend.store.dialect import insert_or_ignore
from backend.store.tables import previews
from backend.store.versions import Item

# read with every version shown (its bench verdict): built once (see backend/store/__init__.py)
_PREVIEW = select(previews).where(previews.c.version_id == bindparam("version_id"))


def get_preview(conn: Connection, item: Item, version_id: int, content_sha256: str) -> dict | None:
    """The stored preview of a version (when it was walked, and what it found), or ``None``; refuses one made from
    different content."""
    row = conn.execute(_PREVIEW, {"version_id": version_id}).mappings().first()
    if row is None:
        return None
    if row["content_sha256"] != content_sha256:
        raise ConflictError(f"the stored preview of {item} {version_id} was simulated from another "
                            f"{'table' if item == 'proposal' else 'envelope'}; refusing to show it")
    return {"created_at": row["created_at"], **json.loads(row["result_json"])}


def store_preview(conn: Connection, item: Item, version_id: int, content_sha256: str, result: dict) -> dict:
    """Keep a freshly simulated preview (the first one wins if two requests raced) and return the stored one: a
    table's with its walk's length, an envelope's with its course."""
    table = item == "proposal"
    with write_transaction(conn):
        conn.execute(insert_or_ignore(conn, previews, ["version_id"]).values(
            version_id=version_id, content_sha256=content_sha256,
            seconds=float(result["seconds"]) if table else None, course=None if table else result["course"]["name"],
            created_at=utc_now(), result_json=json.dumps(result, allow_nan=False)))
    stored = get_preview(conn, item, version_id, content_sha256)
    assert stored is not None
    return stored
