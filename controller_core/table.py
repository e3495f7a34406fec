"""The parameter table pushed to the leg, and the safety limits checked on it.

Field names carry their units. Stiffness and damping are SI (N·m/rad, N·m·s/rad); equilibrium angles and
angle thresholds are in degrees because this table is what a prosthetist reads, edits and approves.

Safety is layered: :func:`check_table` is run when a table is built (the proposal carries its result),
again at approval (backend), and again by the device before use (device bridge); every violation names
the offending field, its value and the allowed range.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal, Protocol

from pydantic import BaseModel, ConfigDict, Field, field_validator

from controller_core.quasi_stiffness import SUBPHASES

Joint = Literal["knee", "ankle"]
Subphase = Literal["stance_flexion", "stance_extension", "swing_flexion", "swing_extension"]


class _Strict(BaseModel):
    """Base of every table model: unknown fields, NaN and ±inf are refused; instances are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class ParameterRow(_Strict):
    """Impedance of one joint in one sub-phase: τ = k(θ − θe) − bθ̇."""

    joint: Joint
    subphase: Subphase
    k_Nm_per_rad: float = Field(description="quasi-stiffness (N·m/rad); negative = restoring")
    theta_e_deg: float = Field(description="equilibrium angle (deg; knee flexion +, ankle dorsiflexion +)")
    b_Nm_s_per_rad: float = Field(description="damping (N·m·s/rad), >= 0")
    r2: float | None = Field(default=None, description="R² of the linear fit (None when edited by hand)")
    guarded: bool = Field(default=False, description="the plain least-squares line was not used (see fit_method)")
    fit_method: Literal["least_squares", "extension_window", "range_guard", "passivity_guard", "swing_target",
                        "manual", "literature", "neighbour_guard", "support_floor", "refined"] = Field(
        default="least_squares",
        description="least_squares: τ = kθ + c; extension_window: the same line fitted over the knee's stance "
                    "extension only (stance-flexion peak to the knee's late-stance minimum), leaving out the "
                    "pre-swing flexion that no line fits; range_guard: θe clamped to the joint range, k re-fitted; "
                    "passivity_guard: an energy-injecting line with θe inside the swept angles, replaced by the "
                    "restoring floor and a re-fitted θe; swing_target: a swing sub-phase whose θe is the model's "
                    "predicted swing target and whose k is the model's swing stiffness; manual: edited; "
                    "literature: a published table; neighbour_guard: moved into the envelope's step from its neighbours "
                    "(see controller_core.envelope); support_floor: the knee's stance-flexion line was softer than the "
                    "stance support floor (the person does positive work here, which a spring cannot), so the row "
                    "holds the floor and θe is re-fitted; refined: moved by a refinement from the leg's own strides "
                    "(the version's evidence says from what and why)")


class Thresholds(_Strict):
    """Transition thresholds and state-time guards of the four-state machine."""

    sf_to_se_ankle_moment_Nm: float = Field(
        description="SF→SE when the ankle (sagittal) moment falls below this (N·m; plantarflexor negative)")
    se_to_wf_load_N: float = Field(description="SE→WF (toe-off) when the vertical load falls below this (N)")
    wf_to_we_knee_angle_deg: float = Field(
        description="WF→WE when the knee is flexed beyond this (deg) and slowing")
    we_to_sf_load_N: float = Field(description="WE→SF (heel strike) when the vertical load rises above this (N)")
    min_state_time_s: float = Field(description="minimum time in any state (s)")
    max_state_time_s: float = Field(description="maximum time in any state before the guard moves on (s)")
    sf_to_se_knee_extension_deg_per_s: float = Field(
        default=0.0, description="SF→SE also when the loaded knee extends faster than this (deg/s; 0 = off): the "
                                 "stance-flexion peak itself, for gaits whose ankle moment is late to cross")
    # the stumble support (controller_core.fsm, "Stumbles"): what triggers it and how long it holds
    stumble_knee_margin_deg: float = Field(
        default=15.0, description="stumble: a swing-extension knee this far above its equilibrium that has stopped "
                                  "extending is held by the floor (a caught toe, an early landing) and gets stance "
                                  "support at once; the support holds until the knee is back within this of the "
                                  "stance-flexion equilibrium (deg)")
    stumble_knee_rate_deg_per_s: float = Field(
        default=30.0, description="stumble: 'stopped extending' is slower than this (deg/s; a free knee extends at "
                                  "115–230 deg/s in late swing)")
    fold_knee_rate_deg_per_s: float = Field(
        default=90.0, description="fold: a loaded stance-extension knee flexing faster than this early in stance is "
                                  "giving way and gets stance support (deg/s; a downhill knee yields at up to about "
                                  "60 deg/s, a folding one at 115–300)")
    fold_window_of_stance_pct: float = Field(
        default=50.0, description="fold: 'early in stance' is within this share of the last stance's length (%; "
                                  "pre-swing's flexion begins at about 80 %)")
    # an early landing on the forefoot (controller_core.fsm, "An early landing on the forefoot"): its trigger; its
    # support is the stance-flexion ankle row without plantarflexion torque while the weight stays on the toe
    early_landing_swing_pct: float = Field(
        default=80.0, description="early landing: a swing shorter than this share of the last ordinary swing ended "
                                  "early (%; ordinary swings vary by about 5 % from stride to stride)")
    forefoot_landing_pct: float = Field(
        default=50.0, description="early landing: the foot landed on its toe when, in the landing's first 30 ms, the "
                                  "centre of pressure lay beyond this share of the forefoot's length ahead of the "
                                  "ankle (%; a heel landing puts it behind the ankle)")


STUMBLE_THRESHOLDS = {"stumble_knee_margin_deg": "deg", "stumble_knee_rate_deg_per_s": "deg/s",
                      "fold_knee_rate_deg_per_s": "deg/s", "fold_window_of_stance_pct": "%",
                      "early_landing_swing_pct": "%", "forefoot_landing_pct": "%"}   # and their units


class Provenance(_Strict):
    """Where a table came from."""

    model_version: str
    data_sha256: str
    speed_mps: float
    incline_deg: float
    patient_mass_kg: float
    extrapolation: bool
    source: Literal["model", "edit", "literature", "refinement"] = "model"
    swing_inertia_ratio: tuple[float, float] = Field(
        default=(1.0, 1.0), description="the leg's swing inertia about the knee and the ankle over the reference leg's, "
                                        "as the swing rows were scaled for it (controller_core.table_rules.swing_scale)")

    @field_validator("swing_inertia_ratio")
    @classmethod
    def _positive(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not all(x > 0.0 for x in v):
            raise ValueError(f"swing inertia ratios must be positive, got {v!r}")
        return v


class ParameterTable(_Strict):
    """Per joint × sub-phase impedance, FSM thresholds and provenance."""

    rows: list[ParameterRow]
    thresholds: Thresholds
    provenance: Provenance

    @property
    def body_mass_kg(self) -> float:
        """The body mass (kg) the table was built for: the stance support floor scales with it."""
        return self.provenance.patient_mass_kg

    @field_validator("rows")
    @classmethod
    def _complete(cls, rows: list[ParameterRow]) -> list[ParameterRow]:
        keys = [(r.joint, r.subphase) for r in rows]
        expected = {(j, s) for j in ("knee", "ankle") for s in SUBPHASES}
        if len(keys) != len(set(keys)) or set(keys) != expected:
            raise ValueError("a table needs exactly one row per joint (knee, ankle) and sub-phase (4)")
        return rows

    def row(self, joint: str, subphase: str) -> ParameterRow:
        """The row of one joint and sub-phase."""
        for r in self.rows:
            if r.joint == joint and r.subphase == subphase:
                return r
        raise KeyError((joint, subphase))


class ImpedanceRow(Protocol):
    """What the limit check reads from a row: a :class:`ParameterRow`, or the device's decoded row."""

    @property
    def joint(self) -> str: ...
    @property
    def subphase(self) -> str: ...
    @property
    def k_Nm_per_rad(self) -> float: ...
    @property
    def theta_e_deg(self) -> float: ...
    @property
    def b_Nm_s_per_rad(self) -> float: ...


class ImpedanceTable(Protocol):
    """What the limit check and the controller read from a table: a :class:`ParameterTable`, or the table the
    device decoded from the wire (which carries no provenance)."""

    @property
    def rows(self) -> Sequence[ImpedanceRow]: ...
    @property
    def thresholds(self) -> Thresholds: ...
    @property
    def body_mass_kg(self) -> float: ...
    def row(self, joint: str, subphase: str) -> ImpedanceRow: ...


class Range(_Strict):
    """Closed interval [low, high] in the unit of the field it guards."""

    low: float
    high: float


class SafetyLimits(_Strict):
    """Limits enforced on every table.

    Defaults: joint ranges of the simulated/Open Source Leg-class device (knee 0–120°, ankle ±30°);
    |k| up to 1200 N·m/rad restoring (above the quasi-stiffness of a 200 kg patient's able-bodied reference,
    about 3 N·m/kg/rad) and, in swing only, up to 200 N·m/rad energy-injecting (a small positive swing k only
    brakes the swinging shank while θe lies beyond the angles it sweeps). Stance rows must be passive, k ≤ 0 with
    no tolerance: with k > 0 the row is a negative spring, which under the patient's weight drives the joint
    away from θe (a knee that gives way into flexion); b ≥ 0 keeps the damping passive too. Damping 0–30
    N·m·s/rad; loads 0–3000 N; state times 0.01–3 s; the SF→SE knee-extension speed 0–200 deg/s (0 = off).

    **Stumble support** (it cannot be switched off): the margin 5–30° (above 30° a toe caught on a 50° knee is never
    seen stalled); "stopped extending" 10–90 deg/s (above it a knee still swinging freely would be taken for a
    planted one); the fold rate 60–300 deg/s (at or below a downhill knee's yielding every downhill stance would be
    held stiff; above it a folding knee is caught too late); the fold window 20–70 % of stance (beyond it pre-swing's
    flexion would be held stiff through toe-off). An early landing on the forefoot: a swing under 50–95 % of the last
    ordinary one (below 50 % a foot put down on an obstacle's top in late swing is not seen; above 95 % ordinary
    stride-to-stride variation would trip it), the centre of pressure beyond 20–90 % of the forefoot (below 20 % a
    foot landing flat would count; above 90 % only a landing on the very tip would).

    **Stance support floor**: the knee's stance-flexion row must be at least as firm as
    ``knee_stance_support_Nm_per_rad_per_kg`` × the body mass the table was built for (k ≤ −floor), or the knee
    buckles under load. 1.2 N·m/rad/kg is the Open Source Leg's published early-stance knee stiffness, 99.4
    N·m/rad (OSL example walking controller, Neurobionics Lab, University of Michigan; Azocar et al., Nat Biomed Eng
    4:941-953, 2020), for an 82 kg user; the example states 60 kg (1.66 N·m/rad/kg), so the floor sits below the
    benchmark's own stance stiffness at every mass. The body mass itself must lie in ``body_mass_kg``.
    """

    k_Nm_per_rad: Range = Range(low=-1200.0, high=200.0)
    stance_k_Nm_per_rad: Range = Range(low=-1200.0, high=0.0)
    knee_theta_e_deg: Range = Range(low=0.0, high=120.0)
    ankle_theta_e_deg: Range = Range(low=-30.0, high=30.0)
    b_Nm_s_per_rad: Range = Range(low=0.0, high=30.0)
    load_N: Range = Range(low=0.0, high=3000.0)
    ankle_moment_Nm: Range = Range(low=-300.0, high=0.0)
    state_time_s: Range = Range(low=0.01, high=3.0)
    knee_extension_deg_per_s: Range = Range(low=0.0, high=200.0)
    stumble_knee_margin_deg: Range = Range(low=5.0, high=30.0)
    stumble_knee_rate_deg_per_s: Range = Range(low=10.0, high=90.0)
    fold_knee_rate_deg_per_s: Range = Range(low=60.0, high=300.0)
    fold_window_of_stance_pct: Range = Range(low=20.0, high=70.0)
    early_landing_swing_pct: Range = Range(low=50.0, high=95.0)
    forefoot_landing_pct: Range = Range(low=20.0, high=90.0)
    knee_stance_support_Nm_per_rad_per_kg: float = Field(default=1.2, ge=0.0)
    body_mass_kg: Range = Range(low=20.0, high=200.0)


class LimitViolation(_Strict):
    """One value outside its allowed range."""

    field: str
    value: float
    low: float
    high: float
    message: str


class SafetyLimitError(ValueError):
    """A table violates the safety limits; ``violations`` lists every offending field."""

    def __init__(self, violations: list[LimitViolation]) -> None:
        self.violations = violations
        super().__init__("; ".join(v.message for v in violations))


def _check(field: str, value: float, rng: Range, unit: str, out: list[LimitViolation]) -> None:
    if not (math.isfinite(value) and rng.low <= value <= rng.high):
        out.append(LimitViolation(field=field, value=value, low=rng.low, high=rng.high,
                                  message=f"{field} = {value:.4g} {unit} is outside [{rng.low:g}, {rng.high:g}] {unit}"))


def _check_stance_k(row: ImpedanceRow, rng: Range, out: list[LimitViolation]) -> None:
    """Stance rows carry the patient's weight: a positive k would push the joint away from θe under load."""
    field = f"{row.joint}.{row.subphase}.k_Nm_per_rad"
    k = row.k_Nm_per_rad
    if not math.isfinite(k) or k < rng.low:
        _check(field, k, rng, "N·m/rad", out)
    elif k > rng.high:
        where = row.subphase.replace("_", " ")
        effect = "the knee gives way into flexion under load" if row.joint == "knee" else \
            "the ankle is pushed away from its equilibrium under load"
        out.append(LimitViolation(
            field=field, value=k, low=rng.low, high=rng.high,
            message=f"{row.joint} {where}: k = {k:+.4g} N·m/rad pushes the joint instead of resisting it "
                    f"({effect}); a stance row must resist or be neutral, k ≤ {rng.high:g} N·m/rad"))


def _check_support_floor(table: ImpedanceTable, lim: SafetyLimits, out: list[LimitViolation]) -> None:
    """The knee's stance-flexion row at least as firm as the stance support floor for the table's body mass."""
    mass = table.body_mass_kg
    _check("body_mass_kg", mass, lim.body_mass_kg, "kg", out)
    if not (math.isfinite(mass) and lim.body_mass_kg.low <= mass <= lim.body_mass_kg.high):
        return
    k = table.row("knee", "stance_flexion").k_Nm_per_rad
    ceiling = -lim.knee_stance_support_Nm_per_rad_per_kg * mass
    if math.isfinite(k) and ceiling < k <= lim.stance_k_Nm_per_rad.high:
        out.append(LimitViolation(
            field="knee.stance_flexion.k_Nm_per_rad", value=k, low=lim.stance_k_Nm_per_rad.low, high=ceiling,
            message=f"knee stance flexion: k = {k:+.4g} N·m/rad is softer than the stance support floor "
                    f"({ceiling:+.4g} N·m/rad = {lim.knee_stance_support_Nm_per_rad_per_kg:g} N·m/rad per kg × "
                    f"{mass:g} kg): the knee could buckle under the patient's weight; k ≤ {ceiling:+.4g} N·m/rad"))


def support_floor_Nm_per_rad(mass_kg: float, limits: SafetyLimits | None = None) -> float:
    """The knee's stance-flexion stiffness ceiling (N·m/rad, negative) for a body mass (kg): k must not exceed it."""
    return -(limits or DEFAULT_LIMITS).knee_stance_support_Nm_per_rad_per_kg * mass_kg


DEFAULT_LIMITS = SafetyLimits()   # frozen: the defaults, built once


def check_table(table: ImpedanceTable, limits: SafetyLimits | None = None) -> list[LimitViolation]:
    """All limit violations of a table (empty list = safe)."""
    lim = limits or DEFAULT_LIMITS
    out: list[LimitViolation] = []
    for r in table.rows:
        key = f"{r.joint}.{r.subphase}"
        if r.subphase.startswith("stance"):
            _check_stance_k(r, lim.stance_k_Nm_per_rad, out)
        else:
            _check(f"{key}.k_Nm_per_rad", r.k_Nm_per_rad, lim.k_Nm_per_rad, "N·m/rad", out)
        theta_rng = lim.knee_theta_e_deg if r.joint == "knee" else lim.ankle_theta_e_deg
        _check(f"{key}.theta_e_deg", r.theta_e_deg, theta_rng, "deg", out)
        _check(f"{key}.b_Nm_s_per_rad", r.b_Nm_s_per_rad, lim.b_Nm_s_per_rad, "N·m·s/rad", out)
    _check_support_floor(table, lim, out)
    t = table.thresholds
    _check("thresholds.sf_to_se_ankle_moment_Nm", t.sf_to_se_ankle_moment_Nm, lim.ankle_moment_Nm, "N·m", out)
    _check("thresholds.se_to_wf_load_N", t.se_to_wf_load_N, lim.load_N, "N", out)
    _check("thresholds.we_to_sf_load_N", t.we_to_sf_load_N, lim.load_N, "N", out)
    _check("thresholds.wf_to_we_knee_angle_deg", t.wf_to_we_knee_angle_deg, lim.knee_theta_e_deg, "deg", out)
    _check("thresholds.min_state_time_s", t.min_state_time_s, lim.state_time_s, "s", out)
    _check("thresholds.max_state_time_s", t.max_state_time_s, lim.state_time_s, "s", out)
    _check("thresholds.sf_to_se_knee_extension_deg_per_s", t.sf_to_se_knee_extension_deg_per_s,
           lim.knee_extension_deg_per_s, "deg/s", out)
    for name, unit in STUMBLE_THRESHOLDS.items():
        _check(f"thresholds.{name}", getattr(t, name), getattr(lim, name), unit, out)
    if t.min_state_time_s >= t.max_state_time_s:
        out.append(LimitViolation(field="thresholds.min_state_time_s", value=t.min_state_time_s,
                                  low=lim.state_time_s.low, high=t.max_state_time_s,
                                  message="thresholds.min_state_time_s must be below max_state_time_s"))
    if t.se_to_wf_load_N >= t.we_to_sf_load_N:
        out.append(LimitViolation(field="thresholds.se_to_wf_load_N", value=t.se_to_wf_load_N,
                                  low=lim.load_N.low, high=t.we_to_sf_load_N,
                                  message="thresholds.se_to_wf_load_N (toe-off) must be below we_to_sf_load_N "
                                          "(heel strike), or the machine chatters"))
    return out


def assert_safe(table: ImpedanceTable, limits: SafetyLimits | None = None) -> None:
    """Raise :class:`SafetyLimitError` naming every offending field, if any."""
    violations = check_table(table, limits)
    if violations:
        raise SafetyLimitError(violations)


# A fitted line that explains less than half of the moment's variance in its sub-phase is a weak fit: marked on the
# table and the maps, so that a prosthetist reads its k and θe as a rough summary rather than a measurement.
WEAK_FIT_R2 = 0.5
FITTED_METHODS = ("least_squares", "extension_window", "range_guard", "passivity_guard", "support_floor")
# rows whose k (and θe) were moved from the plain fit to a limit, a floor or a neighbour's step
HELD_METHODS = ("range_guard", "passivity_guard", "support_floor", "neighbour_guard")


def weak_fit(row: ParameterRow) -> bool:
    """The row is a line fit whose R² is below :data:`WEAK_FIT_R2`."""
    return row.r2 is not None and row.fit_method in FITTED_METHODS and row.r2 < WEAK_FIT_R2


def display_rows(table: ParameterTable) -> list[dict]:
    """The table's rows for people and JSON: k in N·m/rad and N·m/deg, θe in deg, b in N·m·s/rad; whether the row is
    a weak fit, held at a limit, floor or neighbour's step, and that damping is a default per kg, never fitted."""
    return [{
        "joint": r.joint, "subphase": r.subphase, "k_Nm_per_rad": round(r.k_Nm_per_rad, 3),
        "k_Nm_per_deg": round(r.k_Nm_per_rad * math.pi / 180.0, 4), "theta_e_deg": round(r.theta_e_deg, 3),
        "b_Nm_s_per_rad": round(r.b_Nm_s_per_rad, 4), "r2": None if r.r2 is None else round(r.r2, 4),
        "guarded": r.guarded, "fit_method": r.fit_method, "weak_fit": weak_fit(r),
        "held": r.fit_method in HELD_METHODS, "damping_source": "default",
    } for r in table.rows]
