"""Pushes of an approved table or envelope to a device."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from backend.schemas.common import OverrideReason, StrictIn
from backend.schemas.devices import DeviceId
from backend.schemas.gate import Withdrawal


class PushRequest(StrictIn):
    device_id: DeviceId
    replaces_proposal_id: int | None = Field(
        description="the proposal whose table you saw on the leg and are replacing (null: none from this server, or "
                    "an envelope); the push is refused if the leg runs anything else now")
    replaces_envelope_id: int | None = Field(
        default=None, description="the envelope you saw on the leg and are replacing (null: not an envelope)")
    patient_ready: Literal[True] = Field(description="you confirm the patient is seated or in the parallel bars: "
                                                     "the leg changes its behaviour at the next heel strike")
    override_reason: OverrideReason = None


class PushOut(BaseModel):
    id: int
    kind: Literal["table", "envelope"] = Field(description="a proposal's table, or a whole envelope")
    proposal_id: int | None
    envelope_id: int | None
    device_id: str
    patient_id: int
    patient_code: str
    proposal_version: int | None
    envelope_version: int | None
    label: str = Field(description="its one name everywhere: 'patient code · table vN' or '… · envelope vN'")
    table_label: str | None = Field(description="the same name, for a table push (null for an envelope)")
    task: dict[str, float] = Field(description="the table's task, or the envelope's nominal task")
    body_mass_kg: float = Field(description="the body mass the table or envelope was built for (kg)")
    override_reason: str | None = Field(default=None, description="pushed without a clean bench preview: why")
    approval_override: str | None = Field(
        default=None, description="the version was approved without a clean bench preview: the two prosthetists' "
                                  "sign-offs, 'name: reason; name: reason'")
    withdrawal: Withdrawal | None = Field(default=None, description="the version was withdrawn: by whom, when, why")
    sent_back_reason: str | None = Field(
        default=None, description="sent by the server because the version the leg ran before was withdrawn")
    extrapolation_reason: str | None = Field(
        default=None, description="requested beyond the tasks the model knows: the prosthetist's written reason")
    table_version: int = Field(description="the device's own version number for this push (16-bit, per device)")
    crc32: str = Field(description="CRC-32 (hex) of the table or envelope as sent, in the wire's fixed-point")
    status: Literal["sending", "unconfirmed", "acknowledged", "active", "failed", "superseded", "lost"] = Field(
        description="as the device last reported it: unconfirmed (no acknowledgement yet: the device's next status "
                    "decides), lost (the device reported it no longer holds it: restarted or lost)")
    requested_by: str
    requested_at: str
    acknowledged_at: str | None
    active_at: str | None
    ended_at: str | None
    attempts: int | None
    elapsed_ms: float | None
    error: str | None
