"""Devices: their status, commands and the 3D view."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import Path
from pydantic import BaseModel, Field

from backend.schemas.common import StrictIn

DEVICE_ID_PATTERN = r"^[A-Za-z0-9._-]{1,64}$"
DeviceId = Annotated[str, Field(pattern=DEVICE_ID_PATTERN, description="device id, as GET /api/devices lists it")]
DeviceIdPath = Annotated[str, Path(pattern=DEVICE_ID_PATTERN, description="device id")]
LinkModeName = Literal["supervised", "autonomous"]


class DeviceAssignment(BaseModel):
    patient_id: int
    patient_code: str
    body_mass_kg: float
    assigned_by: str | None
    assigned_at: str | None


class TableOnDevice(BaseModel):
    kind: Literal["table", "envelope"] = Field(description="a proposal's table, or an envelope the leg adapts in")
    proposal_id: int | None
    proposal_version: int | None = Field(description="the proposal's version for its patient (the N of 'table vN')")
    envelope_id: int | None
    envelope_version: int | None = Field(description="the envelope's version for its patient")
    patient_id: int
    patient_code: str
    label: str = Field(description="its one name everywhere: 'patient code · table vN' or '… · envelope vN'")
    table_label: str | None = Field(description="the same, for a table (null for an envelope)")
    task: dict[str, float] = Field(description="speed_mps and incline_deg the table was proposed for (an "
                                               "envelope: its nominal task)")
    body_mass_kg: float = Field(description="the body mass the table or envelope was built for (kg)")
    approval_override: str | None = Field(
        default=None, description="approved without a clean bench preview: the prosthetist's reason")
    extrapolation_reason: str | None = Field(
        default=None, description="requested beyond the tasks the model knows: the prosthetist's written reason")
    override_reason: str | None = Field(default=None, description="pushed without a clean bench preview: why")


class MassMismatch(BaseModel):
    """The table on the leg was built for another body mass than the patient's now (torques and load thresholds scale
    with body mass)."""

    built_for_kg: float
    patient_now_kg: float
    difference_percent: float
    message: str


class WithdrawalNotice(BaseModel):
    """A withdrawal that concerns what this leg runs (``backend/routers/gate.py``)."""

    state: Literal["runs_withdrawn", "sent_back"] = Field(
        description="runs_withdrawn: the leg reports a withdrawn version running (it is put in safe mode); sent_back: "
                    "what it runs or will run was sent because the version before it was withdrawn")
    label: str = Field(description="runs_withdrawn: the withdrawn version; sent_back: the version sent back to")
    by: str
    at: str
    reason: str
    words: str = Field(description="the monitor's line")


class LegStateOut(BaseModel):
    """What a real leg says of itself (DEVICE_LEG)."""

    knee_calibrated: bool
    ankle_calibrated: bool
    loadcell_calibrated: bool
    torque_mode: Literal["current", "torque", "actuator_impedance", "unknown"]
    derating_pct: int | None = Field(description="the torque its thermal model allows (%); null: not measured")


class BenchTask(BaseModel):
    speed_mps: float
    incline_deg: float
    course: str | None = Field(description="the course being walked, if any")


class DeviceOut(BaseModel):
    id: str
    patient: DeviceAssignment | None = Field(description="the patient the device is assigned to (pushes and "
                                                         "sessions are for this patient only)")
    active_table: TableOnDevice | None = Field(description="the table the device reports running")
    pending_table: TableOnDevice | None = Field(description="a verified table waiting for the next heel strike")
    body_mass_mismatch: MassMismatch | None = Field(
        default=None, description="set when the table running was built for a body mass more than 5 % away from "
                                  "the assigned patient's current mass")
    kind: Literal["simulated", "can"]
    interface: str
    channel: str
    online: bool = Field(description="a status arrived within the last second")
    mode: Literal["no_table", "active", "safe", "calibrating"] | None = Field(
        description="what the leg does: runs no table (passive), its table, safe mode (passive, holds a loaded knee), "
                    "or a guided calibration from this page (no torque at all)")
    safe_mode: bool
    fsm_state: int | None = Field(description="0 stance flexion, 1 stance extension, 2 swing flexion, 3 swing extension")
    active_version: int | None = Field(description="the device's own version number of the table running (a "
                                                   "16-bit counter per device; see active_table for which it is)")
    active_crc32: str | None = Field(description="CRC-32 (hex) of the table running, read back from the device")
    pending_version: int | None = Field(description="a verified table waiting for the next heel strike")
    faults: list[str]
    temperature_degC: float | None
    leg: LegStateOut | None = Field(default=None, description="a real leg's word on itself (an Open Source Leg: "
                                                              "DEVICE_LEG); null for the simulated bench")
    rx_errors: int | None
    last_heartbeat_unix_s: float | None = Field(description="when the device's last status arrived (Unix s)")
    last_heartbeat_age_s: float | None
    walking: bool | None = Field(description="simulated leg only: the bench is walking")
    bench_state: Literal["walking", "standing", "not_worn"] | None = Field(
        default=None, description="simulated leg only: its patient walks, stands on it between walks (live quiet-stance "
                                  "readings), or nobody wears it (no readings)")
    bench_task: BenchTask | None = Field(description="simulated leg only: the true task the bench walks now "
                                                     "(ground truth for the leg's own estimate)")
    bench_leg: str | None = Field(default=None, description="simulated leg only: the leg it walks, fitted to its "
                                                             "patient's described leg (else the server's bench leg)")
    recording_session_id: int | None
    link_mode: LinkModeName = Field(description="the prosthetist's choice of what a lost link does to this leg")
    withdrawal_notice: WithdrawalNotice | None = Field(
        default=None, description="a withdrawal that concerns what the leg runs, for the monitor")
    link_mode_on_device: LinkModeName | None = Field(
        description="what the device reports it does (null before its first status); the server sends the choice "
                    "whenever the two differ")
    telemetry_samples_received: int = Field(
        description="live telemetry samples this API instance received from the leg since it connected")
    telemetry_samples_missing: int = Field(
        description="live samples this instance did not receive, by the leg's sequence numbers (a broker link's late "
                    "delivery fills them in the session record afterwards)")


class ViewerOut(BaseModel):
    device_id: str
    host: str = Field(description="always loopback")
    port: int = Field(description="the port viser bound, read back from it")
    url: str
    frames_drawn: int = Field(description="leg poses drawn from telemetry so far (30 per second while it streams)")


class AssignmentRequest(StrictIn):
    patient_id: int = Field(ge=1, le=2**53, description="the patient who will wear the device")


class CommandRequest(StrictIn):
    command: Literal["enter_safe_mode", "leave_safe_mode"]


class LinkModeRequest(StrictIn):
    link_mode: LinkModeName = Field(description="what a lost link does to the leg: 'supervised' (tuning in the "
                                                "clinic): it goes to safe mode; 'autonomous' (daily life, no server "
                                                "near): it runs on with the approved table or envelope it holds")
    reason: str = Field(min_length=10, max_length=500, description="why, in the prosthetist's words (audited)")


CalibrationStepName = Literal["joint_zero", "direction", "loadcell_zero", "loadcell_sign"]


class CalibrationRequest(StrictIn):
    action: Literal["start", "measure", "keep", "cancel"] = Field(
        description="start (only from safe mode or with no table: the leg then gives no torque), measure a step, "
                    "keep the four steps' result on the leg, or cancel (the leg keeps its calibration)")
    step: CalibrationStepName | None = Field(default=None, description="the step to measure (action measure only)")


class CalibrationMeasured(BaseModel):
    subject: Literal["knee", "ankle", "loadcell", "leg"]
    values: dict[str, float] = Field(description="what the leg measured, the unit in each name (reading_deg, "
                                                 "spread_deg, moved_deg, sign, torque_sign, force_N, moment_Nm, "
                                                 "change_N, body_weight_N …)")
    words: str


class CalibrationOut(BaseModel):
    """The leg's answer to one calibration command, in its words and numbers."""

    device_id: str
    step: CalibrationStepName | None = Field(description="the step answered (null: the calibration as a whole)")
    outcome: Literal["started", "accepted", "refused", "kept", "cancelled"]
    measured: list[CalibrationMeasured]
    refused_reason: str | None = Field(description="why the leg refused (a code: not_still, too_little_move, "
                                                   "beyond_range, load_offset, not_loaded, leg_busy, no_sensors …)")
    refused_subject: str | None
    refused_words: str | None = Field(description="what was wrong and what to do, in the leg's words")
    prompt: str | None = Field(description="what the prosthetist does before measuring this step again")
    next_step: CalibrationStepName | None = Field(description="the step to measure next (null: none, keep or cancel)")
    next_prompt: str | None = Field(description="what to do before measuring the next step")
    body_mass_kg: float | None = Field(description="the assigned patient's mass the load cell's sign was read "
                                                   "against (kg)")
