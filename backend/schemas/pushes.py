"""Pushes of an approved table to a device."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from backend.schemas.common import StrictIn
from backend.schemas.devices import DeviceId


class PushRequest(StrictIn):
    device_id: DeviceId


class PushOut(BaseModel):
    id: int
    proposal_id: int
    device_id: str
    table_version: int
    crc32: str = Field(description="CRC-32 (hex) of the table as sent, in the wire's fixed-point")
    status: Literal["sending", "acknowledged", "active", "failed", "superseded"]
    requested_by: str
    requested_at: str
    acknowledged_at: str | None
    active_at: str | None
    ended_at: str | None
    attempts: int | None
    elapsed_ms: float | None
    error: str | None
