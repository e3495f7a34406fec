"""Pushes of an approved table to a device."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from backend.schemas.common import StrictIn
from backend.schemas.devices import DeviceId


class PushRequest(StrictIn):
    device_id: DeviceId
    replaces_proposal_id: int | None = Field(
        description="the proposal whose table you saw on the leg and are replacing (null: none from this server); "
                    "the push is refused if the leg runs another table now")
    patient_ready: Literal[True] = Field(description="you confirm the patient is seated or in the parallel bars: "
                                                     "the leg changes its behaviour at the next heel strike")


class PushOut(BaseModel):
    id: int
    proposal_id: int
    device_id: str
    patient_id: int
    patient_code: str
    proposal_version: int
    table_label: str = Field(description="the table's one name everywhere: 'patient code · table vN'")
    task: dict[str, float]
    table_version: int = Field(description="the device's own version number for this push (16-bit, per device)")
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
