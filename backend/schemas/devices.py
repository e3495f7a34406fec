"""Devices, pushes and walking sessions."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import Path
from pydantic import BaseModel, Field

from backend.schemas.common import StrictIn

DEVICE_ID_PATTERN = r"^[A-Za-z0-9._-]{1,64}$"
DeviceId = Annotated[str, Field(pattern=DEVICE_ID_PATTERN, description="device id, as GET /api/devices lists it")]
DeviceIdPath = Annotated[str, Path(pattern=DEVICE_ID_PATTERN, description="device id")]


class DeviceOut(BaseModel):
    id: str
    kind: Literal["simulated", "can"]
    interface: str
    channel: str
    online: bool = Field(description="a status arrived within the last second")
    mode: Literal["no_table", "active", "safe"] | None
    safe_mode: bool
    fsm_state: int | None = Field(description="0 stance flexion, 1 stance extension, 2 swing flexion, 3 swing extension")
    active_version: int | None = Field(description="version of the table running (the proposal id)")
    active_crc32: str | None = Field(description="CRC-32 (hex) of the table running, read back from the device")
    pending_version: int | None = Field(description="a verified table waiting for the next heel strike")
    faults: list[str]
    temperature_degC: float | None
    rx_errors: int | None
    last_heartbeat_unix_s: float | None = Field(description="when the device's last status arrived (Unix s)")
    last_heartbeat_age_s: float | None
    walking: bool | None = Field(description="simulated leg only: the bench is walking")
    recording_session_id: int | None


class ViewerOut(BaseModel):
    device_id: str
    host: str = Field(description="always loopback")
    port: int = Field(description="the port viser bound, read back from it")
    url: str
    frames_drawn: int = Field(description="leg poses drawn from telemetry so far (30 per second while it streams)")


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


class CommandRequest(StrictIn):
    command: Literal["enter_safe_mode", "leave_safe_mode"]


class SessionRequest(StrictIn):
    device_id: DeviceId
    speed_mps: float | None = Field(default=None, gt=0, le=3,
                                    description="walking speed (m/s); default: the task of the table active on the device")
    incline_deg: float | None = Field(default=None, ge=-20, le=20, description="incline (deg); default as speed")


class SessionTask(BaseModel):
    speed_mps: float
    incline_deg: float
    body_mass_kg: float


class SessionOut(BaseModel):
    id: int
    patient_id: int
    device_id: str
    proposal_id: int | None
    table_version: int | None
    table_crc32: str | None
    task: SessionTask
    status: Literal["recording", "stopped"]
    started_by: str
    started_at: str
    stopped_by: str | None
    stopped_at: str | None
    summary: dict | None = Field(description="strides, cadence_steps_per_min, *_rmse_deg, *_rmse_Nm_per_kg, "
                                             "mean and reference curves on phase_grid (deg, N·m/kg)")


class SamplesOut(BaseModel):
    session_id: int
    count: int
    every: int
    columns: dict[str, list[float | int | None]] = Field(
        description="t_s, mode, fsm_state, knee/ankle angle (deg), velocity (deg/s), torque (N·m), load_N, "
                    "ankle_moment_Nm")
