"""The audit log (read only: it is append-only by construction)."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Query

from backend.deps import Auditor, Conn
from backend.schemas.audit import AuditPage
from backend.schemas.common import MAX_ID
from backend.schemas.errors import FORBIDDEN, UNAUTHORIZED
from backend.store import audit

router = APIRouter(prefix="/api", tags=["audit"])


@router.get("/audit", response_model=AuditPage, responses={**UNAUTHORIZED, **FORBIDDEN})
def list_audit(conn: Conn, _user: Auditor,
               entity: Literal["user", "patient", "proposal", "envelope", "device", "session"] | None = None,
               entity_id: Annotated[int | None, Query(ge=1, le=MAX_ID)] = None,
               actor: Annotated[str | None, Query(max_length=64, pattern=r"^[^\x00-\x1f]*$")] = None,
               before_id: Annotated[int | None, Query(ge=1, le=MAX_ID, description="older than this id")] = None,
               limit: Annotated[int, Query(ge=1, le=1000)] = 100) -> dict:
    """Every state change, newest first: who, when, what, and the values before and after (prosthetist or admin)."""
    items = audit.list_entries(conn, entity, entity_id, actor, before_id, limit)
    return {"items": items, "next_before_id": items[-1]["id"] if len(items) == limit else None}
