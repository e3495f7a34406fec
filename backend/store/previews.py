"""Stored simulated previews of proposals and envelopes (computed once: neither ever changes)."""

from __future__ import annotations

import json

from sqlalchemy import Connection, bindparam, select

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError
from backend.store.dialect import insert_or_ignore
from backend.store.tables import envelope_previews, proposal_previews

# read with every version shown (its bench verdict): built once (see backend/store/__init__.py)
_PROPOSAL_PREVIEW = select(proposal_previews).where(proposal_previews.c.proposal_id == bindparam("proposal_id"))
_ENVELOPE_PREVIEW = select(envelope_previews).where(envelope_previews.c.envelope_id == bindparam("envelope_id"))


def get_preview(conn: Connection, proposal_id: int, table_sha256: str) -> dict | None:
    """The stored preview of a proposal, or ``None``; refuses one made from a different table."""
    row = conn.execute(_PROPOSAL_PREVIEW, {"proposal_id": proposal_id}).mappings().first()
    if row is None:
        return None
    if row["table_sha256"] != table_sha256:
        raise ConflictError(f"the stored preview of proposal {proposal_id} was simulated from another table; "
                            "refusing to show it")
    return {"proposal_id": proposal_id, "table_sha256": table_sha256, "created_at": row["created_at"],
            **json.loads(row["result_json"])}


def store_preview(conn: Connection, proposal_id: int, table_sha256: str, result: dict) -> dict:
    """Keep a freshly simulated preview (the first one wins if two requests raced) and return the stored one."""
    with write_transaction(conn):
        conn.execute(insert_or_ignore(conn, proposal_previews, ["proposal_id"]).values(
            proposal_id=proposal_id, table_sha256=table_sha256, seconds=float(result["seconds"]), created_at=utc_now(),
            result_json=json.dumps(result)))
    stored = get_preview(conn, proposal_id, table_sha256)
    assert stored is not None
    return stored


def get_envelope_preview(conn: Connection, envelope_id: int, envelope_sha256: str) -> dict | None:
    """The stored preview of an envelope, or ``None``; refuses one made from a different envelope."""
    row = conn.execute(_ENVELOPE_PREVIEW, {"envelope_id": envelope_id}).mappings().first()
    if row is None:
        return None
    if row["envelope_sha256"] != envelope_sha256:
        raise ConflictError(f"the stored preview of envelope {envelope_id} was simulated from another envelope; "
                            "refusing to show it")
    return {"envelope_id": envelope_id, "created_at": row["created_at"], **json.loads(row["result_json"])}


def store_envelope_preview(conn: Connection, envelope_id: int, envelope_sha256: str, result: dict) -> dict:
    """Keep a freshly simulated envelope preview (the first one wins a race) and return the stored one."""
    with write_transaction(conn):
        conn.execute(insert_or_ignore(conn, envelope_previews, ["envelope_id"]).values(
            envelope_id=envelope_id, envelope_sha256=envelope_sha256, course=result["course"]["name"],
            created_at=utc_now(), result_json=json.dumps(result, allow_nan=False)))
    stored = get_envelope_preview(conn, envelope_id, envelope_sha256)
    assert stored is not None
    return stored
