"""The measured able-bodied walking conditions behind the model."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field


class ReferenceCondition(BaseModel):
    """One measured able-bodied walking condition the model was trained on (mean curves, display units)."""

    name: str
    dataset: str
    citation: str
    speed_mps: float | None
    incline_deg: float | None
    subjects_or_strides: int | None
    phase: list[float]
    knee_angle_deg: list[float]
    knee_moment_Nm_per_kg: list[float]
    ankle_angle_deg: list[float]
    ankle_moment_Nm_per_kg: list[float]


class TaskReference(BaseModel):
    """The reference at one task, and what it really is: measured level walking, or level walking plus the change
    measured on a ramp (one participant), scaled to the incline. None where nothing was measured that steep."""

    kind: Literal["measured", "measured_ramp_trend"]
    label: str = Field(description="what the curve is, in a sentence for the chart's legend")
    source: str
    citations: list[str]
    speed_mps: float
    incline_deg: float
    phase: list[float]
    knee_angle_deg: list[float]
    knee_moment_Nm_per_kg: list[float]
    ankle_angle_deg: list[float]
    ankle_moment_Nm_per_kg: list[float]


class RampCondition(BaseModel):
    """A measured ramp condition the incline change is learned from (one participant; curves not repeated here)."""

    name: str
    dataset: str
    citation: str
    speed_mps: float
    incline_deg: float
    strides: int


class ReferenceOut(BaseModel):
    model_version: str
    data_sha256: str
    conditions: list[ReferenceCondition]
    ramp_conditions: list[RampCondition] = Field(
        default_factory=list, description="the measured ramp walking (±10°, one participant) behind the model's incline "
                                          "change, with the same participant's level walking")
    at_task: TaskReference | None = Field(
        default=None, description="with speed_mps and incline_deg: the reference at that task, or null where no "
                                  "curves were measured that steep (the proposal is then the model's prediction)")


class KnownRangeOut(BaseModel):
    data_speed_mps: list[float] = Field(description="the level walking data's speeds, lowest and highest (m/s)")
    data_incline_deg: list[float] = Field(description="the measured ramps' inclines, lowest and highest (deg)")
    speed_margin_mps: float = Field(description="how far beyond the data's speeds the model predicts unasked (m/s)")
    incline_margin_deg: float = Field(description="how far beyond the data's inclines the model predicts unasked (deg)")
    speed_mps: list[float] = Field(description="speeds a request may name without extrapolate (m/s)")
    incline_deg: list[float] = Field(description="inclines a request may name without extrapolate (deg)")


class TaskRangeOut(BaseModel):
    """What a request may name: any walking task within the limits, and without ``extrapolate`` only what the model
    knows."""

    speed_mps: list[float] = Field(description="any request's speed limits (m/s)")
    incline_deg: list[float] = Field(description="any request's incline limits (deg)")
    body_mass_kg: list[float] = Field(description="a patient's body mass limits (kg)")
    envelope_nodes_per_axis: list[int] = Field(description="an envelope's nodes along each axis, fewest and most")
    envelope_max_nodes: int = Field(description="an envelope's nodes in all, at most (what one transfer carries)")
    known: KnownRangeOut
    extrapolation_reason_min_chars: int = 20
