"""Audit log entries."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel


class AuditEntry(BaseModel):
    id: int
    at: str
    actor: str
    action: str
    entity: str
    entity_id: int | None
    before: Any
    after: Any


class AuditPage(BaseModel):
    items: list[AuditEntry]
    next_before_id: int | None
