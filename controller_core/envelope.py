"""An envelope: parameter tables over a speed × incline grid, and the rules that make it safe to blend.

The leg adapts by blending the tables of the four grid nodes around the task it estimates (bilinear in speed and
incline). Every node is a whole table that passes :func:`controller_core.table.check_table`; the limits are
intervals (and stance k ≤ 0), so any blend of safe nodes is inside them too. On top of that, the **neighbour rule**:
two nodes one cell apart (in speed or in incline) differ by at most a stated step per value
(:class:`NeighbourSteps`), so one cell of task change never moves the leg's impedance by more than a step,
however the estimate wanders inside the cell.

The pipeline's tables are not smooth everywhere: a sub-phase whose line flips between the plain fit and a guard
(e.g. the knee's stance flexion on steep uphill, where early stance extends instead of flexing) jumps between
neighbours. :func:`build_envelope` applies a **neighbour guard**: sweeping outwards from the node nearest the
nominal task, each value is moved (the least) into the steps of its already-swept neighbours. A guarded value lies
between its fitted value and its neighbours', so it stays within the limits; each node lists what was moved and
from what (``neighbour_guarded``), and a row so moved says ``fit_method = "neighbour_guard"``.

Units as in the table: N·m/rad, deg, N·m·s/rad, N·m, N, s, deg/s; speeds m/s, inclines deg. The JSON carries a
CRC-32 (zlib) over its canonical form, so a stored or transferred envelope is verified whole.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

if TYPE_CHECKING:    # the leg loads envelopes without the model's KMP (SciPy)
    from controller_core.proposal import FeaturePrediction
from controller_core.quasi_stiffness import SUBPHASES
from controller_core.table import (
    ImpedanceTable,
    LimitViolation,
    ParameterRow,
    ParameterTable,
    SafetyLimits,
    Thresholds,
    check_table,
)
from controller_core.task import INCLINE_LIMIT_DEG, SPEED_RANGE_MPS, InvalidTaskError

ENVELOPE_FORMAT = "quasitune.envelope/1"
ROW_KEYS: tuple[tuple[str, str], ...] = tuple((j, s) for j in ("knee", "ankle") for s in SUBPHASES)
ROW_VALUES = ("k_Nm_per_rad", "theta_e_deg", "b_Nm_s_per_rad")
THRESHOLD_VALUES = ("sf_to_se_ankle_moment_Nm", "se_to_wf_load_N", "wf_to_we_knee_angle_deg", "we_to_sf_load_N",
                    "min_state_time_s", "max_state_time_s", "sf_to_se_knee_extension_deg_per_s",
                    "stumble_knee_margin_deg", "stumble_knee_rate_deg_per_s", "fold_knee_rate_deg_per_s",
                    "fold_window_of_stance_pct", "early_landing_swing_pct", "forefoot_landing_pct")
# every value an envelope blends, in one fixed order: eight rows × (k, θe, b), then the thresholds
VALUE_FIELDS: tuple[str, ...] = tuple(f"{j}.{s}.{v}" for j, s in ROW_KEYS for v in ROW_VALUES) + tuple(
    f"thresholds.{t}" for t in THRESHOLD_VALUES)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class NeighbourSteps(_Strict):
    """The most a value may change between two nodes one cell apart (absolute, in each value's unit).

    Our choice, stated and editable; the device enforces its own ceiling on them. A cell of the default 5 × 5
    envelope over 0.6–1.6 m/s × ±10° is 0.25 m/s or 5°. The steps leave room for what people do between two such
    tasks and no more: 5° of slope moves the knee's flexion at heel strike by about 13° in real ramp walking
    (``vielemeyer2025``, +27° at +10°), hence 15° for equilibrium angles and the swing threshold; a knee's stance
    quasi-stiffness is itself of the order of 4 N·m/rad per kg (Shamaei, Sawicki & Dollar, PLoS ONE 2013), hence
    300 N·m/rad (4 × 75 kg): one cell may not add or remove a whole knee's stiffness. Damping, loads and moment
    thresholds scale with body mass and get a step of the same order per 75 kg; state times 0.1 s. The stumble
    support's trigger (the table's ``stumble_…``/``fold_…`` thresholds) is one setting of the leg, not of the task:
    its margin takes the knee angle's step, its rates 30 deg/s (a third of the fold rate), its window 10 % of stance;
    likewise the early landing's two shares (of the last swing, of the forefoot), 10 % each.
    """

    k_Nm_per_rad: float = Field(default=300.0, gt=0)
    theta_e_deg: float = Field(default=15.0, gt=0)
    b_Nm_s_per_rad: float = Field(default=2.0, gt=0)
    ankle_moment_Nm: float = Field(default=20.0, gt=0)
    load_N: float = Field(default=150.0, gt=0)
    knee_angle_deg: float = Field(default=15.0, gt=0)
    state_time_s: float = Field(default=0.1, gt=0)
    knee_extension_deg_per_s: float = Field(default=10.0, gt=0)
    knee_rate_deg_per_s: float = Field(default=30.0, gt=0)
    share_of_stance_pct: float = Field(default=10.0, gt=0)
    landing_share_pct: float = Field(default=10.0, gt=0)

    def for_fields(self) -> tuple[float, ...]:
        """The step of every value of :data:`VALUE_FIELDS`, in that order."""
        per_row = (self.k_Nm_per_rad, self.theta_e_deg, self.b_Nm_s_per_rad)
        return per_row * len(ROW_KEYS) + (
            self.ankle_moment_Nm, self.load_N, self.knee_angle_deg, self.load_N, self.state_time_s,
            self.state_time_s, self.knee_extension_deg_per_s,
            self.knee_angle_deg, self.knee_rate_deg_per_s, self.knee_rate_deg_per_s, self.share_of_stance_pct,
            self.landing_share_pct, self.landing_share_pct)


DEFAULT_STEPS = NeighbourSteps()


class EnvelopeNode(_Strict):
    """One grid node: the table for its task, whether the task lies outside the training data, and how sure the
    model is of the features it came from (std in display units, the unit in each key)."""

    speed_mps: float
    incline_deg: float
    table: ParameterTable
    extrapolation: bool
    feature_std: dict[str, float] = Field(default_factory=dict)
    neighbour_guarded: dict[str, float] = Field(
        default_factory=dict, description="value moved by the neighbour guard → the value the pipeline fitted")


def _axis_problem(name: str, values: Sequence[float], lo: float, hi: float, least: int) -> str | None:
    if len(values) < least:
        return f"{name} needs at least {least} values, got {len(values)}"
    if len(values) > 15:
        return f"{name} has {len(values)} values; at most 15 per axis"
    if any(not math.isfinite(v) for v in values):
        return f"{name} must be finite numbers"
    if any(b <= a for a, b in itertools.pairwise(values)):
        return f"{name} must be strictly increasing, got {list(values)}"
    if values[0] < lo or values[-1] > hi:
        return f"{name} must lie within [{lo:g}, {hi:g}], got {values[0]:g} … {values[-1]:g}"
    return None


def validate_axes(speeds_mps: Sequence[float], inclines_deg: Sequence[float], single_node: bool = False) -> None:
    """Refuse a grid that is not a grid of walking tasks, with the reason. A range of tasks has at least two values
    on each axis; ``single_node`` also takes one task (one value on each axis: a fixed-task table, the 1 × 1 case).

    Raises:
        InvalidTaskError: fewer than 2 (1 × 1 with ``single_node``) or more than 15 values on an axis, not
            increasing, NaN or out of range.
    """
    least = 1 if single_node and len(speeds_mps) == len(inclines_deg) == 1 else 2
    for problem in (_axis_problem("speeds_mps", speeds_mps, *SPEED_RANGE_MPS, least),
                    _axis_problem("inclines_deg", inclines_deg, -INCLINE_LIMIT_DEG, INCLINE_LIMIT_DEG, least)):
        if problem:
            raise InvalidTaskError(problem)


class Envelope(_Strict):
    """Tables over a speed × incline grid (nodes speed-major: node ``i * len(inclines) + j``). A fixed-task table is
    the grid of one node (1 × 1, :func:`envelope_of_table`): what the leg holds is always an envelope."""

    format: Literal["quasitune.envelope/1"] = ENVELOPE_FORMAT
    speeds_mps: list[float]
    inclines_deg: list[float]
    nominal_speed_mps: float = Field(description="the task the leg returns to when its estimate is not confident")
    nominal_incline_deg: float
    mass_kg: float
    model_version: str
    data_sha256: str
    neighbour_steps: NeighbourSteps = DEFAULT_STEPS
    nodes: list[EnvelopeNode]

    @model_validator(mode="after")
    def _grid(self) -> Envelope:
        validate_axes(self.speeds_mps, self.inclines_deg, single_node=True)
        if len(self.nodes) != len(self.speeds_mps) * len(self.inclines_deg):
            raise ValueError(f"an envelope of {len(self.speeds_mps)} × {len(self.inclines_deg)} needs "
                             f"{len(self.speeds_mps) * len(self.inclines_deg)} nodes, got {len(self.nodes)}")
        for idx, node in enumerate(self.nodes):
            i, j = divmod(idx, len(self.inclines_deg))
            if not (math.isclose(node.speed_mps, self.speeds_mps[i], abs_tol=1e-9)
                    and math.isclose(node.incline_deg, self.inclines_deg[j], abs_tol=1e-9)):
                raise ValueError(f"node {idx} is at {node.speed_mps:g} m/s, {node.incline_deg:g} deg; the grid puts "
                                 f"{self.speeds_mps[i]:g} m/s, {self.inclines_deg[j]:g} deg there")
        if not (self.speeds_mps[0] <= self.nominal_speed_mps <= self.speeds_mps[-1]
                and self.inclines_deg[0] <= self.nominal_incline_deg <= self.inclines_deg[-1]):
            raise ValueError("the nominal task must lie inside the envelope")
        return self

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.speeds_mps), len(self.inclines_deg)

    @property
    def single_node(self) -> bool:
        """One node (a fixed-task table): nothing to blend, the leg runs it as it runs a table."""
        return len(self.nodes) == 1

    def node(self, i: int, j: int) -> EnvelopeNode:
        """The node at speed index ``i`` and incline index ``j``."""
        return self.nodes[i * len(self.inclines_deg) + j]

    def tables(self) -> list[ParameterTable]:
        return [n.table for n in self.nodes]

    def to_json(self) -> dict:
        """The envelope as JSON (units in the field names)."""
        return self.model_dump(mode="json")

    @classmethod
    def from_json(cls, body: dict) -> Envelope:
        """Parse and validate. Storage proves the bytes by their sha256 (:mod:`controller_core.content`); the
        ``crc32`` key that older releases wrote into the JSON is read past.

        Raises:
            ValueError: malformed.
        """
        if not isinstance(body, dict):
            raise ValueError("an envelope is a JSON object")
        return cls.model_validate({k: v for k, v in body.items() if k != "crc32"})


def envelope_of_table(table: ParameterTable) -> Envelope:
    """A table as the envelope of its one node, at the task, mass and model its provenance names: the form the leg
    holds (one kind of buffer on the link and on the device)."""
    p = table.provenance
    return Envelope(speeds_mps=[p.speed_mps], inclines_deg=[p.incline_deg], nominal_speed_mps=p.speed_mps,
                    nominal_incline_deg=p.incline_deg, mass_kg=table.body_mass_kg, model_version=p.model_version,
                    data_sha256=p.data_sha256, nodes=[EnvelopeNode(speed_mps=p.speed_mps, incline_deg=p.incline_deg,
                                                                   table=table, extrapolation=p.extrapolation)])


# ---------------------------------------------------------------- values, the neighbour rule
def table_values(table: ImpedanceTable) -> list[float]:
    """Every blended value of a table, in :data:`VALUE_FIELDS` order (the table's units)."""
    out: list[float] = []
    for joint, sub in ROW_KEYS:
        r = table.row(joint, sub)
        out += [float(r.k_Nm_per_rad), float(r.theta_e_deg), float(r.b_Nm_s_per_rad)]
    t = table.thresholds
    return out + [float(getattr(t, name)) for name in THRESHOLD_VALUES]


def _node_label(speed_mps: float, incline_deg: float) -> str:
    return f"{speed_mps:.2f} m/s, {incline_deg:+.1f} deg"


def neighbour_violations(speeds_mps: Sequence[float], inclines_deg: Sequence[float],
                         tables: Sequence[ImpedanceTable], steps: NeighbourSteps = DEFAULT_STEPS
                         ) -> list[LimitViolation]:
    """Every pair of neighbouring nodes whose values differ by more than a step (empty: the rule holds)."""
    n_inc = len(inclines_deg)
    values = [table_values(t) for t in tables]
    limits = steps.for_fields()
    out: list[LimitViolation] = []
    for i in range(len(speeds_mps)):
        for j in range(n_inc):
            for di, dj in ((1, 0), (0, 1)):
                a, b = i + di, j + dj
                if a >= len(speeds_mps) or b >= n_inc:
                    continue
                va, vb = values[i * n_inc + j], values[a * n_inc + b]
                for name, x, y, step in zip(VALUE_FIELDS, va, vb, limits, strict=True):
                    if abs(x - y) > step + 1e-9:
                        here, there = _node_label(speeds_mps[i], inclines_deg[j]), _node_label(speeds_mps[a],
                                                                                             inclines_deg[b])
                        out.append(LimitViolation(
                            field=f"neighbours[{here} | {there}].{name}", value=abs(x - y), low=0.0, high=step,
                            message=f"{name} changes by {abs(x - y):.4g} between neighbouring nodes {here} and "
                                    f"{there}; at most {step:g} per cell"))
    return out


def check_grid(speeds_mps: Sequence[float], inclines_deg: Sequence[float], tables: Sequence[ImpedanceTable],
               steps: NeighbourSteps, limits: SafetyLimits | None = None) -> list[LimitViolation]:
    """Every node's limit violations (field prefixed with the node's task) and the neighbour rule's, for tables in
    speed-major order: an envelope's, or the ones the device decoded from the wire."""
    out: list[LimitViolation] = []
    for idx, table in enumerate(tables):
        i, j = divmod(idx, len(inclines_deg))
        label = _node_label(speeds_mps[i], inclines_deg[j])
        out += [v.model_copy(update={"field": f"node[{label}].{v.field}", "message": f"at {label}: {v.message}"})
                for v in check_table(table, limits)]
    return out + neighbour_violations(speeds_mps, inclines_deg, tables, steps)


def check_envelope(envelope: Envelope, limits: SafetyLimits | None = None,
                   steps: NeighbourSteps | None = None) -> list[LimitViolation]:
    """:func:`check_grid` of an envelope (with its own steps unless others are given)."""
    return check_grid(envelope.speeds_mps, envelope.inclines_deg, envelope.tables(),
                      steps or envelope.neighbour_steps, limits)


# ---------------------------------------------------------------- building
def nearest_node(speeds_mps: Sequence[float], inclines_deg: Sequence[float], speed_mps: float,
                 incline_deg: float) -> tuple[int, int]:
    """Indices of the grid node nearest a task (each axis on its own)."""
    i = min(range(len(speeds_mps)), key=lambda k: abs(speeds_mps[k] - speed_mps))
    j = min(range(len(inclines_deg)), key=lambda k: abs(inclines_deg[k] - incline_deg))
    return i, j


def grid_neighbours(shape: tuple[int, int], i: int, j: int) -> list[tuple[int, int]]:
    """The nodes one cell from node (i, j) of a grid of ``shape`` (speeds × inclines): those the neighbour rule pairs
    it with."""
    return [(a, b) for a, b in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)) if 0 <= a < shape[0] and 0 <= b < shape[1]]


def neighbour_guard(shape: tuple[int, int], values: list[list[float]], start: tuple[int, int],
                    steps: NeighbourSteps) -> list[list[float]]:
    """Values moved the least into the steps of their neighbours, sweeping outwards from ``start`` (see the module).

    Neighbouring nodes lie at grid distances from ``start`` that differ by one, so every pair has one node swept
    before the other; a node's swept neighbours differ by at most two steps, so the allowed interval is never empty.
    """
    n_s, n_i = shape
    limits = np.array(steps.for_fields())
    order = sorted(((i, j) for i in range(n_s) for j in range(n_i)),
                   key=lambda ij: abs(ij[0] - start[0]) + abs(ij[1] - start[1]))
    out = np.array(values, dtype=float)
    done: set[tuple[int, int]] = set()
    for i, j in order:
        swept = [a * n_i + b for a, b in grid_neighbours(shape, i, j) if (a, b) in done]
        if swept:
            near = out[swept]
            out[i * n_i + j] = np.clip(out[i * n_i + j], near.max(axis=0) - limits, near.min(axis=0) + limits)
        done.add((i, j))
    return out.tolist()


def _feature_std(features: list[FeaturePrediction]) -> dict[str, float]:
    suffix = {"angle": "deg", "moment": "Nm_per_kg", "timing": "cycle"}
    out = {}
    for f in features:
        _, std, _ = f.display_value()
        out[f"{f.spec.name}_{suffix[f.spec.quantity]}"] = round(float(std), 5)
    return out


def table_with_values(table: ParameterTable, values: list[float], fitted: list[float]) -> tuple[ParameterTable, dict]:
    """The table with the guard's values; rows whose values moved say so (their R² no longer describes them)."""
    moved = {VALUE_FIELDS[f]: round(fitted[f], 6) for f in range(len(values)) if values[f] != fitted[f]}
    if not moved:
        return table, {}
    rows = []
    for r_idx, (joint, sub) in enumerate(ROW_KEYS):
        r = table.row(joint, sub)
        k, th, b = values[3 * r_idx: 3 * r_idx + 3]
        if (k, th, b) != (r.k_Nm_per_rad, r.theta_e_deg, r.b_Nm_s_per_rad):
            r = ParameterRow(joint=r.joint, subphase=r.subphase, k_Nm_per_rad=k, theta_e_deg=th, b_Nm_s_per_rad=b,
                             r2=None, guarded=True, fit_method="neighbour_guard")
        rows.append(r)
    n_rows = 3 * len(ROW_KEYS)
    thresholds = Thresholds(**dict(zip(THRESHOLD_VALUES, values[n_rows:], strict=True)))
    return ParameterTable(rows=rows, thresholds=thresholds, provenance=table.provenance), moved


def build_envelope(propose_table: Callable[[float, float, float], tuple[ParameterTable, list[FeaturePrediction]]],
                   speeds_mps: Sequence[float], inclines_deg: Sequence[float], mass_kg: float,
                   model_version: str, data_sha256: str, nominal: tuple[float, float] = (1.2, 0.0),
                   steps: NeighbourSteps = DEFAULT_STEPS) -> Envelope:
    """Build every node with ``propose_table`` (the model's), then apply the neighbour guard.

    Args:
        propose_table: (speed m/s, incline deg, mass kg) → (table, features).
        speeds_mps, inclines_deg: the grid axes, increasing.
        nominal: the fallback task (m/s, deg), clamped into the grid.

    Raises:
        InvalidTaskError: a bad axis, mass or task.
    """
    speeds, inclines = [float(v) for v in speeds_mps], [float(v) for v in inclines_deg]
    validate_axes(speeds, inclines)
    built = [propose_table(s, g, mass_kg) for s in speeds for g in inclines]
    nominal_task = (min(max(float(nominal[0]), speeds[0]), speeds[-1]),
                    min(max(float(nominal[1]), inclines[0]), inclines[-1]))
    fitted = [table_values(t) for t, _ in built]
    guarded = neighbour_guard((len(speeds), len(inclines)), fitted,
                              nearest_node(speeds, inclines, *nominal_task), steps)
    nodes = []
    for idx, ((table, features), values, original) in enumerate(zip(built, guarded, fitted, strict=True)):
        i, j = divmod(idx, len(inclines))
        table, moved = table_with_values(table, values, original)
        nodes.append(EnvelopeNode(speed_mps=speeds[i], incline_deg=inclines[j], table=table,
                                  extrapolation=table.provenance.extrapolation, feature_std=_feature_std(features),
                                  neighbour_guarded=moved))
    return Envelope(speeds_mps=speeds, inclines_deg=inclines, nominal_speed_mps=nominal_task[0],
                    nominal_incline_deg=nominal_task[1], mass_kg=mass_kg, model_version=model_version,
                    data_sha256=data_sha256, neighbour_steps=steps, nodes=nodes)

