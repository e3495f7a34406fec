"""Envelopes: request one for a patient over speed and incline ranges, read it, decide it once."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field, model_validator

from backend.schemas.common import (
    EDIT_BOUND,
    ExtrapolationReason,
    StrictIn,
    Text,
    require_reason_to_extrapolate,
)
from backend.schemas.gate import Withdrawal
from backend.schemas.proposals import (
    BenchVerdict,
    Boundaries,
    Curves,
    DecidedVersion,
    FeatureOut,
    ModelInfo,
    Safety,
    SwingInertia,
    TableRowOut,
    Task,
    ViaPointOut,
)
from controller_core.envelope import NeighbourSteps
from controller_core.table import SafetyLimits, Thresholds
from controller_core.task import INCLINE_LIMIT_DEG, SPEED_RANGE_MPS

MAX_NODES = 64   # what one transfer to the leg carries (device_bridge.envelope_wire)


class EnvelopeRequest(StrictIn):
    speed_range_mps: list[float] = Field(default=[0.6, 1.6], min_length=2, max_length=2,
                                         description="lowest and highest walking speed (m/s), within [0.1, 3]")
    incline_range_deg: list[float] = Field(default=[-10.0, 10.0], min_length=2, max_length=2,
                                           description="lowest and highest incline (deg, + uphill), within [-20, 20]")
    grid: list[int] = Field(default=[5, 5], min_length=2, max_length=2,
                            description="nodes along speed and along incline (2-15 each, at most 64 in all: what one "
                                        "transfer to the leg carries)")
    nominal_speed_mps: float = Field(default=1.2, description="the task the leg returns to when unsure (m/s)")
    nominal_incline_deg: float = Field(default=0.0, description="(deg); clamped into the envelope")
    extrapolate: bool = Field(default=False, description="nodes beyond the tasks the model knows (GET /api/task-range): "
                                                         "needs a reason")
    reason: ExtrapolationReason = None

    @model_validator(mode="after")
    def _ranges(self) -> EnvelopeRequest:
        require_reason_to_extrapolate(self.extrapolate, self.reason)
        (s0, s1), (g0, g1), (ns, ni) = self.speed_range_mps, self.incline_range_deg, self.grid
        if not (SPEED_RANGE_MPS[0] <= s0 < s1 <= SPEED_RANGE_MPS[1]):
            raise ValueError(f"the speed range must go from a slower to a faster speed within {SPEED_RANGE_MPS[0]:g}–"
                             f"{SPEED_RANGE_MPS[1]:g} m/s (asked from {s0:g} to {s1:g} m/s)")
        if not (-INCLINE_LIMIT_DEG <= g0 < g1 <= INCLINE_LIMIT_DEG):
            raise ValueError(f"the incline range must go from a lower to a higher incline within −{INCLINE_LIMIT_DEG:g}° "
                             f"and +{INCLINE_LIMIT_DEG:g}° (asked from {g0:g}° to {g1:g}°)")
        if not (2 <= ns <= 15 and 2 <= ni <= 15 and ns * ni <= MAX_NODES):
            raise ValueError(f"the grid must have 2–15 nodes along each axis and at most {MAX_NODES} in all (asked "
                             f"{ns} × {ni}): what one transfer to the leg carries")
        if not (SPEED_RANGE_MPS[0] <= self.nominal_speed_mps <= SPEED_RANGE_MPS[1]
                and abs(self.nominal_incline_deg) <= INCLINE_LIMIT_DEG):
            raise ValueError("the nominal task must be a walking task: a speed within 0.1–3 m/s and an incline within ±20°")
        return self


class Nominal(BaseModel):
    speed_mps: float
    incline_deg: float


class NodeOut(BaseModel):
    speed_mps: float
    incline_deg: float
    extrapolation: bool = Field(description="this node's task lies outside the training data for some feature")
    feature_std: dict[str, float] = Field(description="the GPR's SD of each feature here (unit in the key)")
    neighbour_guarded: dict[str, float] = Field(
        description="values held to the neighbour rule → the value the pipeline fitted")
    table: list[TableRowOut]
    thresholds: Thresholds


class EnvelopeSummary(DecidedVersion):
    envelope_label: str = Field(description="its one name everywhere: 'patient code · envelope vN'")
    body_mass_kg: float
    grid: list[int]
    speeds_mps: list[float]
    inclines_deg: list[float]
    nominal: Nominal
    extrapolation: bool = Field(description="some node lies outside the training data")
    wire_crc32: int | None = Field(description="the CRC-32 the device verifies and reads back once it holds this "
                                               "envelope (null: it cannot be sent)")
    envelope_sha256: str = Field(description="SHA-256 of the stored envelope JSON, checked at every read")
    model: ModelInfo
    neighbour_steps: NeighbourSteps
    safety: Safety
    swing_inertia: SwingInertia = Field(description="the leg the nodes' swing rows were proposed for")


class EnvelopeListItem(DecidedVersion):
    """A version in the patient's list: what tells versions apart (nodes and the live check on its own endpoint)."""

    envelope_label: str = Field(description="its one name everywhere: 'patient code · envelope vN'")
    body_mass_kg: float
    grid: list[int]
    speeds_mps: list[float]
    inclines_deg: list[float]
    extrapolation: bool = Field(description="some node lies outside the training data")
    wire_crc32: int | None = Field(description="the CRC-32 the device verifies and reads back once it holds this "
                                               "envelope (null: it cannot be sent)")
    envelope_sha256: str = Field(description="SHA-256 of the stored envelope JSON, checked at every read")
    safety_ok: bool = Field(description="every node and the neighbour rule within the limits as the device runs "
                                        "them, checked when it was stored")


class EnvelopeOut(EnvelopeSummary):
    bench: BenchVerdict | None = Field(default=None, description="the bench's verdict on exactly this envelope")
    withdrawal: Withdrawal | None = Field(default=None, description="the approved envelope was withdrawn: never "
                                                                    "pushed again; by whom, when, why")
    deployment: Literal["pushed", "active_on_device", "unconfirmed", "replaced", "not_on_device",
                        "push_failed"] | None = Field(
        default=None, description="from its pushes: active_on_device once a device read back its CRC and runs it")
    nodes: list[NodeOut] = Field(description="speed-major: node i × len(inclines_deg) + j")


class EnvelopeCellEdit(StrictIn):
    """One setting changed across the envelope, or at one node: by an offset (in the field's unit), a percentage, or set
    to a value."""

    field: str = Field(min_length=3, max_length=80, description="joint.subphase.(k_Nm_per_rad|theta_e_deg|"
                                                                "b_Nm_s_per_rad) or thresholds.<name>")
    offset: float | None = Field(default=None, ge=-EDIT_BOUND, le=EDIT_BOUND,
                                 description="added to the value, in the field's unit")
    percent: float | None = Field(default=None, gt=-100, le=1000,
                                  description="the value scaled by (1 + percent/100); k < 0 is restoring, so +10 % "
                                              "is 10 % firmer")
    set_to: float | None = Field(default=None, ge=-EDIT_BOUND, le=EDIT_BOUND,
                                 description="the value set to this, in the field's unit (exactly one of offset, "
                                             "percent and set_to)")
    node: list[int] | None = Field(default=None, min_length=2, max_length=2,
                                   description="[speed index, incline index]; omitted: every node")


class EnvelopeEditRequest(StrictIn):
    edits: list[EnvelopeCellEdit] = Field(min_length=1, max_length=40)
    hold_to_neighbour_rule: bool = Field(
        default=False, description="where the edit would put neighbouring nodes more than a step apart, hold those "
                                   "values within a step (the envelope's own guard, from the nominal node outwards) "
                                   "instead of refusing; each held value is listed with what the edit gave")
    comment: Text = Field(min_length=1, max_length=2000, description="why (audited)")


class EnvelopeChange(BaseModel):
    node: list[int]
    speed_mps: float
    incline_deg: float
    field: str
    setting: str = Field(description="the field in words")
    before: float
    after: float
    change: float = Field(description="after − before, in the unit")
    percent: float | None = Field(description="the change as a percentage of before, as an edit's percent reads "
                                              "(after = before × (1 + percent/100); null where before is 0)")
    unit: str
    held_by_neighbour_rule: bool = Field(
        description="the neighbour rule moved this value: it is not what the pipeline fitted or the edit asked for")
    wanted: float | None = Field(description="held values: what the fit or the edit gave before the rule moved it")


class EnvelopeDiffOut(BaseModel):
    from_id: int
    to_id: int
    from_version: int
    to_version: int
    same_patient: bool
    same_grid: bool = Field(description="false: the grids differ and no node-by-node comparison is made")
    changes: list[EnvelopeChange]


class EnvelopeNodeOut(BaseModel):
    """One node shown like a proposal: its table as approved, and the model's prediction at its task."""

    envelope_id: int
    envelope_label: str
    envelope_status: Literal["draft", "approved", "rejected"]
    patient_id: int
    node: list[int] = Field(description="[speed index, incline index]")
    task: Task
    extrapolation: bool
    feature_std: dict[str, float]
    neighbour_guarded: dict[str, float]
    envelope_model: ModelInfo = Field(description="the model that built the envelope's tables")
    model: ModelInfo = Field(description="the model whose curves and features are shown (serving now)")
    table: list[TableRowOut]
    thresholds: Thresholds
    limits: SafetyLimits
    safety: Safety
    swing_inertia: SwingInertia = Field(description="the leg the node's swing rows were proposed for")
    features: list[FeatureOut]
    subphase_boundaries_phase: Boundaries
    curves: Curves
    via_points: list[ViaPointOut]
