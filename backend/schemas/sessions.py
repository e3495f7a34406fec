"""Walking sessions: recording a device's telemetry for a patient, the summary and the samples."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from backend.schemas.common import StrictIn
from backend.schemas.devices import DeviceId
from controller_core.task import SPEED_RANGE_MPS


class SessionRequest(StrictIn):
    device_id: DeviceId
    speed_mps: float | None = Field(default=None, ge=SPEED_RANGE_MPS[0], le=SPEED_RANGE_MPS[1],
                                    description="walking speed (m/s); default: the task of the table active on the device")
    incline_deg: float | None = Field(default=None, ge=-20, le=20, description="incline (deg); default as speed")
    course: Literal["speed", "terrain", "mixed"] | None = Field(
        default=None, description="walk one of the bench's varying-task courses instead of one task (a simulated "
                                  "leg only): speed changes, ramps up and down (±8°), or both; it stops at the end")


class SessionTask(BaseModel):
    speed_mps: float
    incline_deg: float
    body_mass_kg: float


class SessionOut(BaseModel):
    id: int
    patient_id: int
    patient_code: str
    device_id: str
    proposal_id: int | None
    envelope_id: int | None
    table_label: str | None = Field(description="what the leg ran: 'patient code · table vN' or '… · envelope vN'")
    simulated: bool | None = Field(default=None, description="walked by the simulated patient on the simulated leg "
                                                             "(true), by a person (false); null: recorded before this "
                                                             "was kept")
    approval_override: str | None = Field(
        default=None, description="that version was approved without a clean bench preview: the two prosthetists' "
                                  "sign-offs, 'name: reason; name: reason'")
    extrapolation_reason: str | None = Field(
        default=None, description="requested beyond the tasks the model knows: the prosthetist's written reason")
    table_version: int | None = Field(description="the device's own version number of that table or envelope")
    table_crc32: str | None = Field(description="CRC-32 (hex) of the table or envelope as the device runs it")
    course: str | None = Field(description="the bench course walked, if any")
    task: SessionTask = Field(description="the task the session started at: the table's, the envelope's nominal, or "
                                          "the course's first (each stride's errors are scored at its own task)")
    task_words: str = Field(description="the task in words: its speed and incline, or a course by its name and range")
    status: Literal["recording", "stopped"]
    started_by: str
    started_at: str
    stopped_by: str | None
    stopped_at: str | None
    summary: dict | None = Field(description="headline (each stride's knee and ankle angle RMSE against the reference at "
                                             "its own task, averaged; enough_strides false below 5), strides, "
                                             "cadence_steps_per_min, stride-mean *_rmse_deg and *_rmse_Nm_per_kg at the "
                                             "session's task, mean and reference curves on phase_grid (deg, N·m/kg)")


class SamplesOut(BaseModel):
    session_id: int
    count: int
    every: int
    columns: dict[str, list[float | int | str | None]] = Field(
        description="t_s, mode (active / safe / no_table), fsm_state, knee/ankle angle (deg), velocity (deg/s), "
                    "torque (N·m), load_N, ankle_moment_Nm; with an envelope: estimated_speed_mps, "
                    "estimated_incline_deg (null before an estimate), running_speed_mps, running_incline_deg, "
                    "adaptive_mode (nominal / partial / adaptive / clamped)")


class TrendDay(BaseModel):
    day: str = Field(description="calendar day (UTC), YYYY-MM-DD")
    sessions: int
    strides: int
    walking_s: float
    cadence_steps_per_min: float | None = Field(description="stride-weighted mean of the day's sessions")
    knee_angle_rmse_deg: float | None = Field(description="each stride against its own task, weighted by the strides "
                                                          "scored")
    ankle_angle_rmse_deg: float | None
    time_by_task_class_s: dict[str, float] = Field(
        description="seconds per speed class (slow < 0.9 m/s ≤ moderate < 1.3 m/s ≤ fast) × incline class (downhill "
                    "< −4° ≤ level ≤ +4° < uphill), keyed speed_incline")
