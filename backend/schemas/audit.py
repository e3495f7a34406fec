"""Audit log entries."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field


class AuditEntry(BaseModel):
    id: int
    at: str
    actor: str
    action: str
    entity: str
    entity_id: int | None
    now_version_id: int | None = Field(
        default=None, description="an envelope named by its id from before one version (revision 0021): its version "
                                  "id now (its pages and links use it; the entry keeps the id it was written with)")
    before: Any
    after: Any


class AuditPage(BaseModel):
    items: list[AuditEntry]
    next_before_id: int | None
