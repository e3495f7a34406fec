"""The simulated preview of a proposal."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field


class WalkFigures(BaseModel):
    """What every bench walk reports: strides, falls, toe catches, joint-angle RMSE (more figures are allowed)."""

    model_config = {"extra": "allow"}

    strides: int
    falls: int
    toe_catches: int
    knee_angle_rmse_deg: float | None
    ankle_angle_rmse_deg: float | None


class ControllerPreview(WalkFigures):
    """One controller walked on the simulated bench (the metrics of ``quasitune simulate``)."""

    knee_moment_rmse_Nm_per_kg: float | None
    ankle_moment_rmse_Nm_per_kg: float | None
    cadence_steps_per_min: float | None
    mean_curves: dict[str, list[float]] = Field(description="stride-averaged curves on phase_grid (deg, N·m/kg)")


class SafetyFlag(BaseModel):
    """One safety figure of this table's walk outside its bound (backend/bench/safety_figures.py)."""

    figure: str = Field(description="the summary key, e.g. toe_catches, loaded_swing_ms_per_stride")
    severity: Literal["bad"] = Field(description="every figure beyond its bound gates approval and push")
    value: float
    fsmic_value: float | None = Field(description="the FSMIC's figure on the same bench walk")
    unit: str
    message: str
    node_speed_mps: float | None = Field(default=None, description="an envelope node's flag: the node's speed")
    node_incline_deg: float | None = Field(default=None, description="an envelope node's flag: the node's incline")
    start: Literal["standing", "level"] | None = Field(
        default=None, description="an envelope node's flag: the walk it came from (from quiet standing, or reached "
                                  "from level walking)")


class PreviewOut(BaseModel):
    proposal_id: int
    table_sha256: str = Field(description="the table that was simulated")
    created_at: str
    seconds: float = Field(description="simulated walking time per controller (s)")
    leg: str | None = Field(default=None, description="the simulated leg and person walked (a leg file's name, or "
                                                      "'nominal'; None: walked before legs were named)")
    phase_grid: list[float]
    reference_curves: dict[str, list[float]] = Field(description="able-bodied reference at the task (deg, N·m/kg)")
    controllers: dict[Literal["table", "fsmic"], ControllerPreview] = Field(
        description="table: this proposal's table; fsmic: the hand-tuned benchmark (never re-tuned per task)")
    safety: list[SafetyFlag] = Field(description="this table's safety figures outside their bounds, bad first; "
                                                 "empty when all hold")


class CourseControllerPreview(WalkFigures):
    """One controller over the course (``quasitune simulate --course``), each stride scored at its true task."""

    by_segment: list[dict] = Field(description="per course segment: its task, strides and RMSEs with 95 % intervals")


class CourseDifference(BaseModel):
    rmse_difference: float | None = Field(description="envelope minus FSMIC, mean per-stride RMSE (channel's unit)")
    ci95: list[float] | None
    verdict: str | None


class NodeWalk(BaseModel):
    """One walk of one node (``device_bridge.bench.node_walks``): its safety figures (more figures are allowed)."""

    model_config = {"extra": "allow"}

    start: Literal["standing", "level"]
    strides: int
    falls: int
    toe_catches: int


class NodeWalks(BaseModel):
    speed_mps: float
    incline_deg: float
    walks: dict[Literal["standing", "level"], NodeWalk]
    flags: list[SafetyFlag] = Field(description="this node's figures beyond their bounds, each with its walk's start")


class EnvelopePreviewOut(BaseModel):
    envelope_id: int
    created_at: str
    course: dict = Field(description="the course walked: segments of duration_s, speed_mps, incline_deg")
    mass_kg: float
    leg: str | None = Field(default=None, description="the simulated leg and person walked (a leg file's name, or "
                                                      "'nominal'; None: walked before legs were named)")
    controllers: dict[Literal["envelope", "fsmic"], CourseControllerPreview] = Field(
        description="envelope: the leg estimating its task and adapting inside this envelope; fsmic: the benchmark")
    envelope_minus_fsmic: dict[str, CourseDifference]
    nodes: list[NodeWalks] | None = Field(default=None, description="every node walked alone at its own task (speed-"
                                                                   "major, as the envelope's nodes)")
    node_walks: dict | None = Field(default=None, description="what the node walks are: their starts, seconds and "
                                                              "controller, in words")
    safety: list[SafetyFlag] = Field(description="the course walk's safety figures outside their bounds, then each "
                                                 "node's")
