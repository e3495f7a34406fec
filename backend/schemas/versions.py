"""Versions of a patient's parameters: a table for one task (a proposal) and an envelope over a range of tasks,
requested, edited into a new version, decided once, diffed; what both show (the decision, the bench's verdict, the
leg) once."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field, model_validator

from backend.schemas.common import (
    EDIT_BOUND,
    EditValue,
    ExtrapolationReason,
    OverrideReason,
    StrictIn,
    Text,
    require_reason_to_extrapolate,
)
from backend.schemas.gate import Signoff, Withdrawal
from controller_core.envelope import NeighbourSteps
from controller_core.table import LimitViolation, SafetyLimits, Thresholds
from controller_core.task import INCLINE_LIMIT_DEG, SPEED_RANGE_MPS

Joint = Literal["knee", "ankle"]
Subphase = Literal["stance_flexion", "stance_extension", "swing_flexion", "swing_extension"]


class ProposalRequest(StrictIn):
    speed_mps: float = Field(ge=SPEED_RANGE_MPS[0], le=SPEED_RANGE_MPS[1], description="walking speed (m/s), [0.1, 3]")
    incline_deg: float = Field(default=0.0, ge=-20, le=20, description="incline (deg, + uphill), [-20, 20]")
    extrapolate: bool = Field(default=False, description="go beyond the tasks the model knows (GET /api/task-range): "
                                                         "needs a reason")
    reason: ExtrapolationReason = None

    @model_validator(mode="after")
    def _reasoned(self) -> ProposalRequest:
        require_reason_to_extrapolate(self.extrapolate, self.reason)
        return self


class RowEdit(StrictIn):
    """New values for one row; omitted or null fields keep their value."""

    joint: Joint
    subphase: Subphase
    k_Nm_per_rad: float | None = Field(default=None, ge=-EDIT_BOUND, le=EDIT_BOUND,
                                       description="quasi-stiffness k of the paper's τ = k(θ − θe) (N·m/rad): "
                                                   "negative resists (restoring), positive pushes; the dashboard "
                                                   "shows the resistance K = −k, larger = firmer")
    theta_e_deg: float | None = Field(default=None, ge=-EDIT_BOUND, le=EDIT_BOUND,
                                      description="equilibrium angle (deg)")
    b_Nm_s_per_rad: float | None = Field(default=None, ge=-EDIT_BOUND, le=EDIT_BOUND,
                                         description="damping (N·m·s/rad)")


class ThresholdEdit(StrictIn):
    sf_to_se_ankle_moment_Nm: EditValue = None
    se_to_wf_load_N: EditValue = None
    wf_to_we_knee_angle_deg: EditValue = None
    we_to_sf_load_N: EditValue = None
    min_state_time_s: EditValue = None
    max_state_time_s: EditValue = None
    sf_to_se_knee_extension_deg_per_s: EditValue = None
    stumble_knee_margin_deg: EditValue = None
    stumble_knee_rate_deg_per_s: EditValue = None
    fold_knee_rate_deg_per_s: EditValue = None
    fold_window_of_stance_pct: EditValue = None
    early_landing_swing_pct: EditValue = None
    forefoot_landing_pct: EditValue = None


class EditRequest(StrictIn):
    rows: list[RowEdit] = Field(default_factory=list, max_length=8)
    thresholds: ThresholdEdit | None = None
    comment: Text = Field(min_length=1, max_length=2000, description="why the values were changed (audited)")


class DecisionRequest(StrictIn):
    comment: Text = Field(min_length=1, max_length=2000,
                          description="why the table is approved or rejected (required, audited), e.g. what was reviewed")
    override_reason: OverrideReason = None


class BenchFlag(BaseModel):
    figure: str
    severity: Literal["bad"] = Field(description="every figure beyond its bound gates approval and push")
    value: float | int
    fsmic_value: float | int | None
    unit: str
    message: str


class BenchFigure(BaseModel):
    figure: str
    label: str
    unit: str
    value: float | int | None
    fsmic_value: float | int | None
    severity: Literal["bad"] | None = Field(description="'bad': beyond its bound (gates approval and push); null "
                                                        "within it")


class WorseFigure(BaseModel):
    figure: str
    label: str
    unit: str
    parent_value: float | int
    value: float | int


class WorseThanParent(BaseModel):
    """This version's bench walk against its parent's (the version it was edited or refined from), on the same walk."""

    parent_id: int
    parent_version: int
    walked: bool = Field(description="false: the parent's preview has not been walked, nothing compared")
    figures: list[WorseFigure] = Field(description="the safety figures this version makes worse than its parent "
                                                   "(beyond the bench's resolution per unit): said before anything else")


class BenchVerdict(BaseModel):
    """The bench's verdict on exactly this version's content: its stored preview's safety flags."""

    status: Literal["clean", "unsafe", "not_walked"] = Field(
        description="unsafe: a figure beyond its bound; approval and push then need two prosthetists' sign-offs")
    flags: list[BenchFlag]
    figures: list[BenchFigure] = Field(default_factory=list, description="every safety figure of the walk beside the "
                                                                         "FSMIC's (empty before it is walked)")
    words: str = Field(description="for the chip beside 'within parameter limits'")
    signoffs: list[Signoff] = Field(default_factory=list, description="prosthetists' sign-offs on this content's "
                                                                      "findings: approval and push need signoffs_needed")
    signoffs_needed: int = Field(default=2, description="sign-offs by distinct prosthetists that override the gate")
    worse_than_parent: WorseThanParent | None = Field(default=None, description="null: no parent, or this version "
                                                                                "not walked yet")


class Task(BaseModel):
    speed_mps: float
    incline_deg: float
    body_mass_kg: float


class ModelInfo(BaseModel):
    version: str
    data_sha256: str


class SwingInertia(BaseModel):
    """The leg a table's swing rows were proposed for: its swing inertia over the reference leg's."""

    knee_ratio: float = Field(description="swing inertia about the knee over the reference leg's: the knee's "
                                          "swing-extension stiffness and damping were multiplied by it")
    ankle_ratio: float = Field(description="likewise about the ankle, for the ankle's swing rows")
    scaled_rows: list[str] = Field(description="the rows scaled by their joint's ratio ('joint.subphase')")


class Decision(BaseModel):
    status: Literal["approved", "rejected"]
    by: str
    at: str
    comment: str | None
    override_reason: str | None = Field(
        default=None, description="approved without a clean bench preview: the prosthetist's written reason")


class TableRowOut(BaseModel):
    joint: Joint
    subphase: Subphase
    k_Nm_per_rad: float = Field(description="quasi-stiffness k of the paper's τ = k(θ − θe) − b·θ̇ (N·m/rad): negative "
                                          "resists (restoring), positive pushes. The dashboard shows the resistance "
                                          "K = −k (larger = firmer), as τ = −K(θ − θe) − b·θ̇")
    k_Nm_per_deg: float = Field(description="the same k per degree (N·m/deg), signed as k_Nm_per_rad")
    theta_e_deg: float
    b_Nm_s_per_rad: float
    r2: float | None
    guarded: bool
    fit_method: str
    weak_fit: bool = Field(default=False, description="a line fit with R² below 0.5 (controller_core.table.WEAK_FIT_R2): "
                                                      "less than half the moment's variance explained")
    held: bool = Field(default=False, description="k (and θe) held at a limit, the stance support floor or a "
                                                  "neighbour's step instead of the plain fit (see fit_method)")
    damping_source: Literal["default"] = Field(
        default="default", description="damping is never fitted: a default per kg of body mass (or as edited)")


class Safety(BaseModel):
    ok: bool = Field(description="every value within the safety limits (checked now, against the current limits)")
    violations: list[LimitViolation]


class FeatureOut(BaseModel):
    joint: str
    quantity: str
    name: str
    label: str
    phase: float = Field(description="gait phase of the feature, [0, 1]")
    phase_std: float
    value: float = Field(description="in `unit`")
    std: float
    unit: str
    extrapolation: bool


class Boundaries(BaseModel):
    stance_flexion_to_stance_extension: float
    stance_extension_to_swing_flexion: float
    swing_flexion_to_swing_extension: float


class Curves(BaseModel):
    """Predicted curves on 101 phase points, mean and ±1 SD."""

    phase: list[float]
    knee_angle_deg: list[float]
    knee_angle_deg_std: list[float]
    knee_moment_Nm_per_kg: list[float]
    knee_moment_Nm_per_kg_std: list[float]
    ankle_angle_deg: list[float]
    ankle_angle_deg_std: list[float]
    ankle_moment_Nm_per_kg: list[float]
    ankle_moment_Nm_per_kg_std: list[float]


class ViaPointOut(BaseModel):
    """A KMP via-point: the curve is pulled through (angle, moment) at this phase by the GPR features."""

    joint: Joint
    phase: float = Field(description="gait phase, [0, 1]")
    angle_deg: float
    moment_Nm_per_kg: float


class VersionLeg(BaseModel):
    """The leg a version was made for: its swing rows are proposed for it, its bench preview and refinements walk it."""

    description: dict = Field(description="the leg file's fields given (device_bridge/sim/leg_file.py); the rest are "
                                          "the nominal bench leg's; {} is the nominal leg")
    leg_sha256: str = Field(description="what the bench walks, as one key (the description but its name)")
    words: str = Field(description="which leg, in words")
    nominal: bool = Field(description="the nominal bench leg: no description of the patient's leg was given")


class DecidedVersion(BaseModel):
    """What every immutable version decided once has, a table's or an envelope's."""

    id: int
    patient_id: int
    version: int = Field(description="its version for its patient (the N of 'table vN' or 'envelope vN')")
    parent_id: int | None
    parent_version: int | None = Field(description="the version this one was edited from")
    source: Literal["model", "edit"]
    status: Literal["draft", "approved", "rejected"]
    created_by: str
    created_at: str
    edit_comment: str | None
    decision: Decision | None
    extrapolation_reason: str | None = Field(
        description="requested beyond the tasks the model knows: the prosthetist's written reason (else null)")
    leg: VersionLeg


class ProposalSummary(DecidedVersion):
    table_label: str = Field(description="the table's one name everywhere: 'patient code · table vN'")
    task: Task
    extrapolation: bool
    model: ModelInfo
    table: list[TableRowOut]
    thresholds: Thresholds
    table_sha256: str
    safety: Safety
    swing_inertia: SwingInertia = Field(description="the leg the swing rows were proposed for (1 and 1: the reference "
                                                    "leg, or a table proposed before the rows were scaled for a leg)")


class ProposalListItem(DecidedVersion):
    """A version in the patient's list: what tells versions apart (the full version on its own endpoint)."""

    table_label: str = Field(description="the table's one name everywhere: 'patient code · table vN'")
    task: Task
    extrapolation: bool
    table_sha256: str
    safety_ok: bool = Field(description="within every limit as the device runs it, checked when it was stored")


class ProposalOut(ProposalSummary):
    bench: BenchVerdict | None = Field(default=None, description="the bench's verdict on exactly this table")
    withdrawal: Withdrawal | None = Field(default=None, description="the approved table was withdrawn: never pushed "
                                                                    "again; by whom, when, why")
    deployment: Literal["pushed", "active_on_device", "unconfirmed", "replaced", "not_on_device",
                        "push_failed"] | None = Field(
        default=None, description="from its pushes: active_on_device once a device read back its CRC and runs it; "
                                  "replaced once another table took its place")
    features: list[FeatureOut]
    subphase_boundaries_phase: Boundaries
    curves: Curves
    via_points: list[ViaPointOut] = Field(default_factory=list,
                                          description="KMP via-points from the GPR features (empty for old rows)")
    limits: SafetyLimits


class Change(BaseModel):
    field: str
    before: float | str | None
    after: float | str | None
    unit: str | None


class DiffOut(BaseModel):
    from_id: int
    to_id: int
    from_version: int
    to_version: int
    same_patient: bool
    changes: list[Change]


# ---------------------------------------------------------------------------------------- an envelope

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
