"""The four-state impedance machine that runs on the leg: τ = k(θ − θe) − bθ̇ per joint and state.

States follow the quasi-stiffness sub-phases: stance flexion (SF) → stance extension (SE) when the sagittal
(ankle) moment falls below its threshold, or (where the table sets a speed) the knee extends faster than it,
while the leg is loaded (load at or above the heel-strike threshold)
→ swing flexion (WF) at toe-off, when the vertical load falls below
its threshold → swing extension (WE) when the knee is flexed past its swing threshold and has stopped
flexing → SF at heel strike, when the load rises above its threshold. Every state has a minimum time (no
transition before it) and a maximum time (the guard moves on to the next state, so a missed event cannot
hold the leg in one state). An event counts only once its condition has held for ``event_hold_s``
(20 ms by default): a load cell rings at heel strike and when a straight knee meets its end stop, and on the
simulated bench a single low sample in mid-stance is enough to fire a false toe-off and put a loaded leg
into swing flexion.

Heel strike is recognised sooner, because a loaded leg on the weak swing impedance is the hazard (the 20 ms hold
plus swing extension's minimum time kept a loaded leg in swing for 50–120 ms per stride): from either swing
state, a load above the heel-strike threshold for ``heel_strike_hold_s`` (5 ms) goes straight to stance flexion,
without waiting for the state's minimum time. That includes a leg loaded again just after a toe-off (a false
one, when the load dipped in mid-stance): it returns to stance in 5 ms. The short hold is safe in this direction
only: a false heel strike puts the leg in its stiffer stance settings, where a false toe-off would put a loaded
leg in swing; and the toe-off threshold lies below the heel-strike threshold (the safety limits require it), so
the two cannot chatter. A foot that lands on a knee near swing extension's equilibrium is stance too once the load
has stayed above the toe-off threshold for ``heel_contact_hold_s``: the heel's impact can bounce the load back below
the heel-strike threshold, which left the leg on its swing settings for the first 100–270 ms of a slow stance.

**Standing.** A person standing still on the leg is neither walking nor in any one sub-phase: run as walking, the
maximum-time guard cycled the states every 1.5 s, put a leg carrying half the body weight into swing flexion and
stepped the knee torque by tens of N·m at each change. So a stance state whose knee and ankle have both been still
(slower than ``standing_still_rad_s``) for ``standing_enter_s`` while the leg carries at least the toe-off load becomes
*standing*: no event and no guard moves the state; the knee is held where standing found it (its stance-flexion
stiffness against further flexion, the hold following it as it extends: it may straighten, it cannot fold), the
ankle is held about where standing found it with its stance-flexion stiffness. Standing ends when the knee moves
faster than ``standing_leave_rad_s`` (the person walks on from it: on in the stance state it stood in, its dwell
restarted; a knee flexing into pre-swing from stance extension put back in stance flexion was held stiff through
its toe-off and swing) or when the load falls below about a third of the toe-off threshold for ``event_hold_s``
(the leg is lifted: swing flexion if the knee bends, else swing extension: a leg lifted straight waited 0.8 s in
swing flexion for a flexion that never came, and missed its heel strikes). Separately, the maximum-time guard never
moves a leg that carries at least the heel-strike load into swing flexion: only its toe-off does.

**Stumbles.** A toe caught in swing, or a foot that lands early on a bent knee, left the leg with no support: the
swing-extension row pressed a planted toe down while the pylon's axial load (the force mostly across the tilted shank)
never reached the heel-strike threshold, and stance extension's weak row let a knee that was still flexing under the
body fold. So a swing-extension knee still well flexed that has stopped extending (``stumble_knee_margin_rad`` above
the row's equilibrium, slower than ``stumble_knee_rate_rad_s``, for ``event_hold_s`` after the state's minimum time:
the foot is held by the floor) goes to stance flexion; so does a loaded stance-extension knee that flexes faster than
``fold_knee_rate_rad_s`` early in stance (before ``fold_window_of_stance`` of the last stance's length: later, the
flexion is pre-swing's), a stance that was already supported included. That stance flexion is *recovering*: it does
not leave on the ankle moment (which already says "late stance" in a fold) but when the knee is back within the margin
of the stance-flexion equilibrium, or on an unloading that lasts ``RECOVERY_LIFT_S`` (a lift: a foot bouncing on an
obstacle's edge unloads for about 20 ms, and ending the support then put the landing's load on stance extension's
weak row); the next heel strike returns the leg to the table's usual rows and events.

**An early landing on the forefoot** (a foot put down on an obstacle's top or a raised floor before its swing is over,
on the toe): stance flexion's ankle row, made for a heel landing, then pushes the toe down with the shank held back,
and the body's weight comes onto a knee far behind its foot. So where the swing that ended lasted less than
the table's ``early_landing_swing_pct`` of the last ordinary one (80 %), and in its first ``FOREFOOT_LANDING_WINDOW_S``
the centre of pressure (−ankle moment / load, from the pylon's load cell) lay beyond its ``forefoot_landing_pct`` of
the forefoot rocker's distance ahead of the ankle (50 %), the ankle gives no more plantarflexion torque than a centre
of pressure at that threshold needs (the threshold × the forefoot × the load) while the weight stays on the toe: the
heel comes down and the foot gets flat, with the shank still supported; once the centre of pressure has been back
for the event hold, the row is the row again (released on each sample, the torque moved the centre of pressure and
the release beat against it at half the control rate). That stance flexion is recovering (above): a foot on its toe
gives the ankle moment of late stance from its first sample. A capped torque injects nothing the row would not;
dorsiflexion torque (the row resisting a plantarflexed foot) is kept. **Except after a toe caught in swing while the
knee gives way**: where the stance began with the swing's stall (``caught_``), the knee's row asks at least its
drive's limit and the knee still flexes, the ankle runs its row uncapped, since pushing on the forefoot turns the
shank back under the knee, the one thing left that extends it (on the bench's toe catch at 1.0 m/s −6° a knee 50°
flexed under half the body's weight folded past 60° at 120 N·m with the cap). Not after an ordinary early landing on
the toe: tall legs' fast steep descents land so, and uncapped there the grid of a 1.85 m person fell at 1.6 m/s −10°
(0 → 2) and of a 1.95 m one more (3 → 4). Needs the foot's forefoot distance
(:meth:`StateMachineController.use_forefoot`; the firmware's ``forefoot_m``); without it the rule is off, and an
actuator running the impedance itself (:meth:`StateMachineController.impedance`) runs the row without it. On the
bench's grid the learned table's walks are unchanged on every repository leg (no ordinary landing
is that early and on the toe); the sixteen stumble walks recover in 14 (``docs/results.md``: a 1.45 m person's
grid 14 falls → 0).

**Drive friction.** The swing rows of the ankle are soft (a few N·m of spring torque clear the toe), and a drive's
Coulomb friction of the same size stops the foot short of the row's equilibrium: on the bench a leg with 3 N·m of
ankle friction left the foot plantarflexed after push-off and caught its toe at 0.85 m/s in 13 of 15 strides (and fell
12 times with 2.5 N·m at the knee as well). Given the ankle drive's friction (``ActuatorLimits.ankle_friction_Nm``,
from the leg's description), the swing states add to the ankle's spring torque s = k(θ − θe) the torque
½f·tanh(s / ``FRICTION_SHAPE_NM``): at most half the friction, in the spring's own direction, nothing at the
equilibrium. It depends on the angle alone, so the row stays a spring (stiffer near its equilibrium) plus its damper:
it stores and returns energy and cannot inject any, whatever the friction's estimate. Half
(``FRICTION_COMPENSATED_FRACTION``): on the bench's grid half was enough for no fall on every friction leg tried (2 to
6 N·m at the ankle; no toe catch left at 3 N·m), and the ankle followed the reference 0.4 to 1.3° closer than with all
of it: the rest of the friction is damping the soft swing rows lack (and a drive's friction varies with temperature
and wear). Not in stance (friction there only adds to the rows' damping) and not at the knee, whose swing rows work
at tens of N·m (compensating 1.5 N·m there changed the swing's timing and fell at 1.6 m/s −10° on the bench). An
actuator running the impedance itself (:meth:`StateMachineController.impedance`) runs the rows without it.

The controller is pure: :meth:`StateMachineController.step` takes one :class:`SensorSample` and returns one
:class:`TorqueCommand`; it does no I/O and keeps only the state and its entry time. It is written with
plain floats (no numpy in the loop) because it runs at 1 kHz or faster.

Units are SI: rad, rad/s, N, N·m, N·m/rad, N·m·s/rad, s. Signs as everywhere in QuasiTune: knee flexion
and ankle dorsiflexion +, torques + in the + angle direction, so k < 0 is a restoring stiffness.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import IntEnum

from controller_core.quasi_stiffness import SUBPHASES
from controller_core.table import ImpedanceTable, SafetyLimits, assert_safe

Impedance = tuple[tuple[float, float, float], tuple[float, float, float]]   # knee, ankle: (k, θe rad, b)


class GaitState(IntEnum):
    """The four states, numbered in walking order (the same order as the table's sub-phases)."""

    STANCE_FLEXION = 0
    STANCE_EXTENSION = 1
    SWING_FLEXION = 2
    SWING_EXTENSION = 3

    @property
    def subphase(self) -> str:
        """The table sub-phase name of this state (``stance_flexion`` …)."""
        return SUBPHASES[int(self)]


_SWING_FLEXION = int(GaitState.SWING_FLEXION)   # the swing states are this and the next


@dataclass(frozen=True, slots=True)
class SensorSample:
    """What the controller reads once per tick (SI).

    Attributes:
        time_s: time stamp (s), monotonic.
        knee_angle_rad, ankle_angle_rad: joint angles (rad; knee flexion +, ankle dorsiflexion +).
        knee_velocity_rad_s, ankle_velocity_rad_s: joint velocities (rad/s).
        load_N: vertical (axial) load through the pylon load cell (N, compression +).
        ankle_moment_Nm: sagittal moment at the load cell (N·m, + in the dorsiflexion direction).
        thigh_angle_rad, thigh_velocity_rad_s: the socket's (thigh's) sagittal angle from the vertical and its rate
            (rad, rad/s; flexion +), from an IMU on the socket; NaN on a leg without one. The state machine does not
            read them; the task estimator does (:mod:`controller_core.task_estimator`).
    """

    time_s: float
    knee_angle_rad: float
    knee_velocity_rad_s: float
    ankle_angle_rad: float
    ankle_velocity_rad_s: float
    load_N: float
    ankle_moment_Nm: float
    thigh_angle_rad: float = math.nan
    thigh_velocity_rad_s: float = math.nan


@dataclass(frozen=True, slots=True)
class TorqueCommand:
    """What the controller asks of the actuators for one tick.

    Attributes:
        state: the state the torques were computed in.
        knee_torque_Nm, ankle_torque_Nm: commanded joint torques (N·m), already clipped.
        saturated: True when either torque was clipped by the actuator limit or the range guard.
    """

    state: GaitState
    knee_torque_Nm: float
    ankle_torque_Nm: float
    saturated: bool


FRICTION_SHAPE_NM = 1.0        # spring torque at which the swing ankle's friction compensation reaches 76 % of it
FRICTION_COMPENSATED_FRACTION = 0.5   # of the ankle drive's stated friction (module docstring, "Drive friction")
MAX_DRIVE_FRICTION_NM = 15.0   # a harmonic or ball-screw drive with its seals (the leg files' and leg config's bound)
FOREFOOT_LANDING_WINDOW_S = 0.03  # the landing's first samples, read for where the foot landed (s)
RECOVERY_LIFT_S = 0.05         # a recovering stance ends on an unloading this long: a lift, not a bounce (docstring)
FOREFOOT_MIN_LOAD_N = 50.0     # below this the centre of pressure is too uncertain to say where the foot rests
MAX_WALKING_SWING_S = 1.0      # a longer "swing" was a guard's or a lifted leg's wait, no measure of a walking one


@dataclass(frozen=True)
class ActuatorLimits:
    """Torque and range limits of the device (SI).

    The defaults are for an Open Source Leg-class knee-ankle prosthesis and a patient up to about 100 kg:
    peak torques above the able-bodied peaks at brisk walking (knee ≈ 1 N·m/kg, ankle ≈ 1.6 N·m/kg) and the
    mechanical ranges the safety limits also use (knee 0–120°, ankle ±30°). Set them to the rating of the
    device actually driven.
    """

    knee_torque_Nm: float = 120.0
    ankle_torque_Nm: float = 160.0
    knee_range_rad: tuple[float, float] = (0.0, math.radians(120.0))
    ankle_range_rad: tuple[float, float] = (math.radians(-30.0), math.radians(30.0))
    ankle_friction_Nm: float = 0.0       # the ankle drive's Coulomb friction, compensated in swing (module docstring)

    def __post_init__(self) -> None:
        for name in ("knee_torque_Nm", "ankle_torque_Nm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite torque (N·m), got {value!r}")
        if not (math.isfinite(self.ankle_friction_Nm) and 0.0 <= self.ankle_friction_Nm <= MAX_DRIVE_FRICTION_NM):
            raise ValueError(f"ankle_friction_Nm must be a friction torque in [0, {MAX_DRIVE_FRICTION_NM:g}] N·m, got "
                             f"{self.ankle_friction_Nm!r}")
        for name in ("knee_range_rad", "ankle_range_rad"):
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError(f"{name} must be a finite (low, high) pair with low < high (rad), got {(lo, hi)!r}")


@dataclass(frozen=True)
class ImpedanceSchedule:
    """A parameter table in the controller's SI form: per state (0–3) stiffness, equilibrium and damping.

    Attributes:
        knee_k, ankle_k: stiffness per state (N·m/rad).
        knee_theta_e, ankle_theta_e: equilibrium angle per state (rad).
        knee_b, ankle_b: damping per state (N·m·s/rad).
        sf_to_se_ankle_moment_Nm, se_to_wf_load_N, wf_to_we_knee_angle_rad, we_to_sf_load_N: thresholds.
        sf_to_se_knee_extension_rad_s: SF→SE also fires when the loaded knee extends faster than this (rad/s;
            0 = off), i.e. at the stance-flexion peak that defines the sub-phase boundary.
        min_state_time_s, max_state_time_s: state-time guards (s).
        swing_slowing_rad_s: WF→WE also needs the knee flexion velocity at or below this (rad/s).
        event_hold_s: a transition's condition must hold this long, uninterrupted, before it fires (s).
        heel_strike_hold_s: heel strike (load above its threshold in either swing state) needs only this long
            (s) and no minimum time in the state: see the module docstring.
        heel_contact_hold_s: a landing below the heel-strike load (see the module docstring): swing extension's
            knee near its equilibrium and the load above the toe-off threshold this long (s).
        standing_still_rad_s, standing_enter_s, standing_leave_rad_s: standing (see the module docstring): entered
            from a loaded stance state once knee and ankle have both moved slower than the first (rad/s) for the
            second (s); left when the knee moves faster than the third (rad/s) for ``event_hold_s``, or the leg is
            unloaded (a step: see ``standing_lift_of_toe_off``).
        standing_blend_s: the torques go over from the row's to standing's in this long (s), so entering standing
            is no step in torque (a step jolted the knee out of standing at once).
        standing_lift_of_toe_off: standing ends on a lift when the load falls below this share of the toe-off
            threshold (a real lift unloads the leg fully within tens of milliseconds; a person shifting their weight to
            the other leg leaves some: at the toe-off threshold itself, standing on a bent uphill knee or a heavy foot
            downhill flickered into swing with every shift).
        stumble_knee_margin_rad, stumble_knee_rate_rad_s, fold_knee_rate_rad_s, fold_window_of_stance: stumbles
            (see the module docstring): a swing-extension knee more than the margin (rad) above its equilibrium that
            extends slower than the stumble rate (rad/s; a free knee extends at 2–4 rad/s there) is held by the
            floor; a loaded stance-extension knee flexing faster than the fold rate (rad/s; a downhill knee yields at
            up to about 1 rad/s, a folding one at 2–5) within this fraction of the last stance (pre-swing's flexion
            begins at about 80 % of it) is giving way; the support holds until the knee is back within the margin of
            the stance-flexion equilibrium. From the table's thresholds (``stumble_knee_margin_deg`` …), so the
            prosthetist sees them with their limits and the device checks and runs what was approved.
        early_landing_fraction, forefoot_landing_fraction: an early landing on the forefoot (module docstring): a
            swing shorter than the first share of the last ordinary one ended early; a centre of pressure beyond the
            second share of the forefoot's length ahead of the ankle is a landing on the toe. From the table's
            ``early_landing_swing_pct`` and ``forefoot_landing_pct``, likewise.
    """

    knee_k: tuple[float, float, float, float]
    knee_theta_e: tuple[float, float, float, float]
    knee_b: tuple[float, float, float, float]
    ankle_k: tuple[float, float, float, float]
    ankle_theta_e: tuple[float, float, float, float]
    ankle_b: tuple[float, float, float, float]
    sf_to_se_ankle_moment_Nm: float
    se_to_wf_load_N: float
    wf_to_we_knee_angle_rad: float
    we_to_sf_load_N: float
    min_state_time_s: float
    max_state_time_s: float
    sf_to_se_knee_extension_rad_s: float = 0.0
    swing_slowing_rad_s: float = 0.05
    event_hold_s: float = 0.02
    heel_strike_hold_s: float = 0.005
    heel_contact_hold_s: float = 0.010
    standing_still_rad_s: float = 0.2
    standing_enter_s: float = 0.5
    standing_leave_rad_s: float = 0.6
    standing_blend_s: float = 0.2
    standing_lift_of_toe_off: float = 0.35
    stumble_knee_margin_rad: float = math.radians(15.0)      # the table's defaults (Thresholds)
    stumble_knee_rate_rad_s: float = math.radians(30.0)
    fold_knee_rate_rad_s: float = math.radians(90.0)
    fold_window_of_stance: float = 0.5
    early_landing_fraction: float = 0.8
    forefoot_landing_fraction: float = 0.5

    @classmethod
    def from_table(cls, table: ImpedanceTable, limits: SafetyLimits | None = None) -> ImpedanceSchedule:
        """Convert a parameter table, re-checking every safety limit first (the device's own check).

        Raises:
            SafetyLimitError: the table violates ``limits``; nothing is converted.
        """
        assert_safe(table, limits)
        return cls._convert(table)

    @classmethod
    def from_table_unchecked(cls, table: ImpedanceTable) -> ImpedanceSchedule:
        """Convert a table without the limit check: for bench studies of unsafe tables only (``quasitune simulate
        --skip-limits``). The device and every product path use :meth:`from_table`."""
        return cls._convert(table)

    @classmethod
    def _convert(cls, table: ImpedanceTable) -> ImpedanceSchedule:
        def per_state(joint: str, attr: str, scale: float = 1.0) -> tuple[float, float, float, float]:
            v = [float(getattr(table.row(joint, s), attr)) * scale for s in SUBPHASES]
            return (v[0], v[1], v[2], v[3])

        deg = math.pi / 180.0
        t = table.thresholds
        return cls(
            knee_k=per_state("knee", "k_Nm_per_rad"), knee_theta_e=per_state("knee", "theta_e_deg", deg),
            knee_b=per_state("knee", "b_Nm_s_per_rad"),
            ankle_k=per_state("ankle", "k_Nm_per_rad"), ankle_theta_e=per_state("ankle", "theta_e_deg", deg),
            ankle_b=per_state("ankle", "b_Nm_s_per_rad"),
            sf_to_se_ankle_moment_Nm=t.sf_to_se_ankle_moment_Nm, se_to_wf_load_N=t.se_to_wf_load_N,
            wf_to_we_knee_angle_rad=t.wf_to_we_knee_angle_deg * deg, we_to_sf_load_N=t.we_to_sf_load_N,
            min_state_time_s=t.min_state_time_s, max_state_time_s=t.max_state_time_s,
            sf_to_se_knee_extension_rad_s=t.sf_to_se_knee_extension_deg_per_s * deg,
            stumble_knee_margin_rad=t.stumble_knee_margin_deg * deg,
            stumble_knee_rate_rad_s=t.stumble_knee_rate_deg_per_s * deg,
            fold_knee_rate_rad_s=t.fold_knee_rate_deg_per_s * deg, fold_window_of_stance=t.fold_window_of_stance_pct / 100.0,
            early_landing_fraction=t.early_landing_swing_pct / 100.0,
            forefoot_landing_fraction=t.forefoot_landing_pct / 100.0)


def held_since(since_s: float | None, holds: bool, now_s: float) -> float | None:
    """Since when a condition has held without a break (s): ``now_s`` when it starts holding, None while it does not."""
    if not holds:
        return None
    return now_s if since_s is None else since_s


def held_for(since_s: float | None, now_s: float, hold_s: float) -> bool:
    """The condition held since ``since_s`` (:func:`held_since`) has lasted ``hold_s`` by ``now_s``."""
    return since_s is not None and now_s - since_s >= hold_s - 1e-9


def clip_torque(tau: float, theta: float, limit: float, lo: float, hi: float) -> tuple[float, bool]:
    """Clip a torque to ±limit, and refuse any torque that drives the joint further past a range end."""
    out = tau
    if out > limit:
        out = limit
    elif out < -limit:
        out = -limit
    if (theta >= hi and out > 0.0) or (theta <= lo and out < 0.0):
        out = 0.0
    return out, out != tau


@dataclass
class StateMachineController:
    """The four-state impedance machine (one instance per leg and walking session).

    Args:
        schedule: impedance per state and the transition thresholds.
        limits: actuator torque limits and joint ranges.
        initial_state: the state to start in (swing extension: the leg is about to touch down).

    Attributes:
        state_: the current state.
        state_entry_time_s_: when the current state was entered (s); None before the first sample.
        event_since_s_: since when the current state's exit condition has held (s); None while it does not.
        heel_load_since_s_: since when a swing state has seen heel-strike load (s); None while it has not.
        contact_since_s_: since when swing extension has seen a landing below the heel-strike load (s), or None.
        transitions_: number of transitions taken.
        guard_transitions_: how many of them the maximum-time guard forced.
        standing_: whether the leg is standing (see the module docstring); the state stays the stance state it was.
        still_since_s_: since when knee and ankle have been still in a loaded stance state (s); None while not.
        standing_knee_rad_, standing_ankle_rad_: where standing holds the knee (against flexion) and the ankle (rad).
        standing_since_s_: when standing was entered (s; the blend from the row's torques runs from it).
        stand_next_: :meth:`stand` was called: standing from the next sample.
        standing_loaded_: standing has seen the toe-off load (only then does unloading end it).
        recovering_: the stance flexion now is a stumble's support (see the module docstring).
        stance_entry_s_, last_stance_s_: when this stance began at heel strike, and how long the last one lasted (s).
        folding_since_s_: since when a loaded stance-extension knee has been flexing early in stance (s).
        forefoot_m: the foot's forefoot rocker ahead of the ankle (m), for an early landing on the toe; None: unknown
            (that rule off).
        swing_entry_s_, last_swing_s_: when this swing began, and how long the last ordinary (not early) one lasted (s).
        early_landing_, toe_landing_: this stance began with an early landing; and on the forefoot (docstring).
        caught_: this stance began with a toe caught in swing (swing extension's stall, not a heel strike).
    """

    schedule: ImpedanceSchedule
    limits: ActuatorLimits = field(default_factory=ActuatorLimits)
    initial_state: GaitState = GaitState.SWING_EXTENSION
    state_: GaitState = field(init=False)
    state_entry_time_s_: float | None = field(init=False, default=None)
    event_since_s_: float | None = field(init=False, default=None)
    heel_load_since_s_: float | None = field(init=False, default=None)
    contact_since_s_: float | None = field(init=False, default=None)
    transitions_: int = field(init=False, default=0)
    guard_transitions_: int = field(init=False, default=0)
    standing_: bool = field(init=False, default=False)
    still_since_s_: float | None = field(init=False, default=None)
    standing_knee_rad_: float = field(init=False, default=0.0)
    standing_ankle_rad_: float = field(init=False, default=0.0)
    standing_since_s_: float = field(init=False, default=0.0)
    stand_next_: bool = field(init=False, default=False)
    standing_loaded_: bool = field(init=False, default=False)
    recovering_: bool = field(init=False, default=False)
    stance_entry_s_: float | None = field(init=False, default=None)
    last_stance_s_: float = field(init=False, default=0.6)
    folding_since_s_: float | None = field(init=False, default=None)
    forefoot_m: float | None = None
    swing_entry_s_: float | None = field(init=False, default=None)
    last_swing_s_: float | None = field(init=False, default=None)
    early_landing_: bool = field(init=False, default=False)
    toe_landing_: bool = field(init=False, default=False)
    caught_: bool = field(init=False, default=False)
    toe_back_since_s_: float | None = field(init=False, default=None)
    lifted_since_s_: float | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        self.state_ = GaitState(self.initial_state)
        self.use_forefoot(self.forefoot_m)            # checked as when it is set later

    def reset(self, state: GaitState | None = None) -> None:
        """Forget the history: back to ``state`` (or the initial state), entry time taken at the next sample."""
        self.state_ = GaitState(self.initial_state if state is None else state)
        self.state_entry_time_s_ = None
        self.event_since_s_ = None
        self.heel_load_since_s_ = None
        self.contact_since_s_ = None
        self.transitions_ = 0
        self.guard_transitions_ = 0
        self.standing_ = False
        self.still_since_s_ = None
        self.stand_next_ = False
        self.recovering_ = False
        self.stance_entry_s_ = None
        self.folding_since_s_ = None
        self.swing_entry_s_, self.last_swing_s_ = None, None
        self.early_landing_, self.toe_landing_, self.caught_ = False, False, False
        self.toe_back_since_s_ = None
        self.lifted_since_s_ = None

    def stand(self) -> None:
        """A person stands on the leg now (a leg switched on or given a table under them, the bench's standing start):
        from the next sample the machine stands (in stance extension, whose exit is the toe-off the first step ends
        with), holding the joints where it finds them, instead of starting on the walking rows (which bent an uphill
        standing knee to 23° and unloaded the leg in the half second standing takes to notice). An unloaded leg is
        not taken for lifted until the person's weight has come onto it."""
        self.stand_next_ = True

    def load(self, schedule: ImpedanceSchedule) -> None:
        """Swap the impedance schedule (the caller decides when: the device does it at heel strike)."""
        self.schedule = schedule

    def _event(self, x: SensorSample) -> bool:
        sch, st = self.schedule, self.state_
        if st == GaitState.STANCE_FLEXION:  # gated on load: a swinging foot's inertia also makes a moment
            ext = sch.sf_to_se_knee_extension_rad_s
            if self.recovering_:            # held in stance flexion until the knee is back near its equilibrium
                back = x.knee_angle_rad <= sch.knee_theta_e[0] + sch.stumble_knee_margin_rad
                self.lifted_since_s_ = held_since(self.lifted_since_s_, x.load_N < sch.se_to_wf_load_N, x.time_s)
                return back or held_for(self.lifted_since_s_, x.time_s, RECOVERY_LIFT_S - sch.event_hold_s)
            return x.load_N >= sch.we_to_sf_load_N and (
                x.ankle_moment_Nm <= sch.sf_to_se_ankle_moment_Nm or (ext > 0.0 and x.knee_velocity_rad_s <= -ext))
        if st == GaitState.STANCE_EXTENSION:
            return x.load_N < sch.se_to_wf_load_N
        if st == GaitState.SWING_FLEXION:
            return x.knee_angle_rad >= sch.wf_to_we_knee_angle_rad and x.knee_velocity_rad_s <= sch.swing_slowing_rad_s
        return x.load_N > sch.we_to_sf_load_N or self._stalled(x)

    def _folding(self, x: SensorSample) -> bool:
        """Stance extension early in stance, loaded, the knee flexing: the knee is giving way under the body."""
        sch = self.schedule
        early = self.stance_entry_s_ is not None and \
            x.time_s - self.stance_entry_s_ < sch.fold_window_of_stance * self.last_stance_s_
        folding = self.state_ == GaitState.STANCE_EXTENSION and early and \
            x.load_N >= sch.we_to_sf_load_N and x.knee_velocity_rad_s > sch.fold_knee_rate_rad_s
        self.folding_since_s_ = held_since(self.folding_since_s_, folding, x.time_s)
        return held_for(self.folding_since_s_, x.time_s, sch.event_hold_s)

    def _stalled(self, x: SensorSample) -> bool:
        """Swing extension's knee, still well flexed, has stopped extending: the foot is held (planted or caught)."""
        sch = self.schedule
        return x.knee_angle_rad > sch.knee_theta_e[3] + sch.stumble_knee_margin_rad and \
            x.knee_velocity_rad_s > -sch.stumble_knee_rate_rad_s

    def _heel_strike(self, x: SensorSample) -> bool:
        """The foot has been loaded in a swing state for ``heel_strike_hold_s``, or has landed on an extended knee
        in swing extension above the toe-off load for ``heel_contact_hold_s`` (no minimum time: see the module)."""
        sch, st = self.schedule, self.state_
        loaded = st in (GaitState.SWING_FLEXION, GaitState.SWING_EXTENSION) and x.load_N > sch.we_to_sf_load_N
        landed = st == GaitState.SWING_EXTENSION and x.load_N > sch.se_to_wf_load_N and \
            x.knee_angle_rad <= sch.knee_theta_e[3] + sch.stumble_knee_margin_rad
        self.heel_load_since_s_ = held_since(self.heel_load_since_s_, loaded, x.time_s)
        self.contact_since_s_ = held_since(self.contact_since_s_, landed, x.time_s)
        return held_for(self.heel_load_since_s_, x.time_s, sch.heel_strike_hold_s) or \
            held_for(self.contact_since_s_, x.time_s, sch.heel_contact_hold_s)

    def _standing(self, x: SensorSample) -> bool:
        """Update standing (see the module docstring) with this sample; whether the leg stands now."""
        sch = self.schedule
        if self.standing_:
            self.standing_loaded_ = self.standing_loaded_ or x.load_N >= sch.se_to_wf_load_N
            moving = abs(x.knee_velocity_rad_s) > sch.standing_leave_rad_s
            lifted = self.standing_loaded_ and x.load_N < sch.standing_lift_of_toe_off * sch.se_to_wf_load_N
            self.event_since_s_ = held_since(self.event_since_s_, moving or lifted, x.time_s)
            if held_for(self.event_since_s_, x.time_s, sch.event_hold_s):
                self.standing_ = False              # lifted: a step; moving: on in the stance state it stood in
                swing = GaitState.SWING_FLEXION if x.knee_velocity_rad_s > sch.standing_still_rad_s else \
                    GaitState.SWING_EXTENSION         # lifted on a knee that does not bend: nothing to flex first
                self._enter(swing if lifted else self.state_, x.time_s, guard=False)
            return self.standing_
        still = self.state_ in (GaitState.STANCE_FLEXION, GaitState.STANCE_EXTENSION) and \
            x.load_N >= sch.se_to_wf_load_N and abs(x.knee_velocity_rad_s) < sch.standing_still_rad_s and \
            abs(x.ankle_velocity_rad_s) < sch.standing_still_rad_s
        self.still_since_s_ = held_since(self.still_since_s_, still, x.time_s)
        if held_for(self.still_since_s_, x.time_s, sch.standing_enter_s):
            self._begin_standing(x, loaded=True, blend=True)
        return self.standing_

    def _begin_standing(self, x: SensorSample, loaded: bool, blend: bool) -> None:
        """Stand from sample ``x``: the joints held where they are; ``loaded``: the person's weight is already on
        the leg; ``blend``: the row's torques go over to standing's over ``standing_blend_s``."""
        self.standing_, self.event_since_s_, self.standing_loaded_ = True, None, loaded
        self.stance_entry_s_ = None        # a stance that stood is no measure of a walking one
        self.standing_since_s_ = x.time_s - (0.0 if blend else self.schedule.standing_blend_s)
        self.standing_knee_rad_, self.standing_ankle_rad_ = x.knee_angle_rad, x.ankle_angle_rad

    def _row_torques(self, x: SensorSample) -> tuple[float, float]:
        sch, i = self.schedule, int(self.state_)
        tk = sch.knee_k[i] * (x.knee_angle_rad - sch.knee_theta_e[i]) - sch.knee_b[i] * x.knee_velocity_rad_s
        spring = sch.ankle_k[i] * (x.ankle_angle_rad - sch.ankle_theta_e[i])
        ta = spring - sch.ankle_b[i] * x.ankle_velocity_rad_s
        friction = self.limits.ankle_friction_Nm
        if friction and i >= _SWING_FLEXION:          # the drive's friction, in the spring's direction (docstring)
            ta += FRICTION_COMPENSATED_FRACTION * friction * math.tanh(spring / FRICTION_SHAPE_NM)
        return tk, ta

    def use_drive_friction(self, ankle_Nm: float) -> None:
        """The ankle drive's Coulomb friction (N·m) of the leg this machine runs on, compensated in swing."""
        self.limits = replace(self.limits, ankle_friction_Nm=ankle_Nm)

    def use_forefoot(self, forefoot_m: float | None) -> None:
        """The foot's forefoot rocker ahead of the ankle (m) of the leg this machine runs on (an early landing on the
        toe, module docstring); None turns that rule off."""
        if forefoot_m is not None and not (math.isfinite(forefoot_m) and 0.0 < forefoot_m <= 0.5):
            raise ValueError(f"forefoot_m must be in (0, 0.5] m, got {forefoot_m!r}")
        self.forefoot_m = forefoot_m

    def _landed_on_the_toe(self, x: SensorSample) -> bool:
        """In stance flexion after an early landing: whether the foot still bears weight on its forefoot, as it landed.
        Released once the centre of pressure has been back behind the threshold (or the load gone) for the machine's
        event hold, not on one sample: the capped torque moves the centre of pressure, and a release on each sample
        beat against it at half the control rate (the load alternating 0.66 / 0.13 of body weight every millisecond
        on the bench, the ankle's torque with it, and no stance extension ever held)."""
        if self.forefoot_m is None:          # the caller has checked the early landing (the cheap flag first)
            return False
        measured = x.load_N > FOREFOOT_MIN_LOAD_N and math.isfinite(x.ankle_moment_Nm)
        forward = measured and -x.ankle_moment_Nm / x.load_N > \
            self.schedule.forefoot_landing_fraction * self.forefoot_m
        if forward and x.time_s - self.state_entry_time_s_ < FOREFOOT_LANDING_WINDOW_S and not self.toe_landing_:
            self.toe_landing_ = True
            self.recovering_ = True     # the ankle moment of a foot on its toe says "late stance": not its exit
        if not self.toe_landing_:
            return False
        self.toe_back_since_s_ = held_since(self.toe_back_since_s_, not forward, x.time_s)
        if held_for(self.toe_back_since_s_, x.time_s, self.schedule.event_hold_s):
            self.toe_landing_ = False                                      # the heel is down: the row again
        return self.toe_landing_

    def _standing_torques(self, x: SensorSample) -> tuple[float, float]:
        """The knee held against flexion where standing found it (the hold follows it as it extends), the ankle about
        where it was: the stance-flexion row's stiffness and damping, both joints; blended in from the row's torques
        over ``standing_blend_s``."""
        sch = self.schedule
        self.standing_knee_rad_ = min(self.standing_knee_rad_, x.knee_angle_rad)
        tk = sch.knee_k[0] * (x.knee_angle_rad - self.standing_knee_rad_) - sch.knee_b[0] * x.knee_velocity_rad_s
        ta = sch.ankle_k[0] * (x.ankle_angle_rad - self.standing_ankle_rad_) - sch.ankle_b[0] * x.ankle_velocity_rad_s
        w = (x.time_s - self.standing_since_s_) / sch.standing_blend_s if sch.standing_blend_s > 0 else 1.0
        if w < 1.0:
            rk, ra = self._row_torques(x)
            tk, ta = w * tk + (1.0 - w) * rk, w * ta + (1.0 - w) * ra
        return tk, ta

    def _enter(self, state: GaitState, now_s: float, guard: bool) -> None:
        if state == GaitState.STANCE_FLEXION and self.state_ in (GaitState.SWING_FLEXION, GaitState.SWING_EXTENSION):
            self.stance_entry_s_ = now_s
            swing = None if self.swing_entry_s_ is None else now_s - self.swing_entry_s_
            walked = swing is not None and swing <= MAX_WALKING_SWING_S   # not a guard's or a lifted leg's wait
            self.early_landing_ = walked and self.last_swing_s_ is not None and \
                swing < self.schedule.early_landing_fraction * self.last_swing_s_
            if walked and not self.early_landing_:
                self.last_swing_s_ = max(swing, 0.2)
            self.toe_landing_, self.toe_back_since_s_ = False, None
        elif state in (GaitState.SWING_FLEXION, GaitState.SWING_EXTENSION) and \
                self.state_ not in (GaitState.SWING_FLEXION, GaitState.SWING_EXTENSION):
            self.swing_entry_s_ = now_s                                        # a swing begins (toe-off, a lift)
        if state == GaitState.SWING_FLEXION and self.stance_entry_s_ is not None and \
                self.state_ not in (GaitState.SWING_FLEXION, GaitState.SWING_EXTENSION):
            self.last_stance_s_ = min(max(now_s - self.stance_entry_s_, 0.3), 1.5)   # a stance's plausible length
        self.folding_since_s_ = None
        self.state_ = state
        self.state_entry_time_s_ = now_s
        self.event_since_s_ = None
        self.heel_load_since_s_ = None
        self.contact_since_s_ = None
        self.lifted_since_s_ = None
        self.transitions_ += 1
        self.guard_transitions_ += int(guard)

    def impedance(self) -> Impedance:
        """The spring and damper each joint runs now, as (k N·m/rad, θe rad, b N·m·s/rad) for the knee and the ankle:
        the row of the current state, or standing's hold about where standing found the joints (run as a spring both
        ways: an actuator's impedance cannot be one-sided). For an actuator that runs the impedance itself."""
        sch = self.schedule
        if self.standing_:
            return ((sch.knee_k[0], self.standing_knee_rad_, sch.knee_b[0]),
                    (sch.ankle_k[0], self.standing_ankle_rad_, sch.ankle_b[0]))
        i = int(self.state_)
        return ((sch.knee_k[i], sch.knee_theta_e[i], sch.knee_b[i]), (sch.ankle_k[i], sch.ankle_theta_e[i], sch.ankle_b[i]))

    def step(self, x: SensorSample) -> TorqueCommand:
        """Advance the machine with one sample and return the joint torques for it."""
        if self.state_entry_time_s_ is None:
            self.state_entry_time_s_ = x.time_s
        sch = self.schedule
        if self.stand_next_:
            self.stand_next_ = False
            self.state_, self.state_entry_time_s_ = GaitState.STANCE_EXTENSION, x.time_s
            self._begin_standing(x, loaded=False, blend=False)                  # nothing walked to blend from
        dwell = x.time_s - self.state_entry_time_s_
        was_standing = self.standing_
        if self._standing(x) or was_standing:
            pass                                     # standing (no event, no guard), or it ended on this sample
        elif self._heel_strike(x):
            self.recovering_ = self.caught_ = False
            self._enter(GaitState.STANCE_FLEXION, x.time_s, guard=False)
        elif self._folding(x):
            self.recovering_, self.caught_ = True, False
            self._enter(GaitState.STANCE_FLEXION, x.time_s, guard=False)
        elif dwell >= sch.min_state_time_s:
            guard = dwell >= sch.max_state_time_s
            if guard and self.state_ == GaitState.STANCE_EXTENSION and x.load_N >= sch.we_to_sf_load_N:
                guard = False                        # never into swing carrying the heel-strike load: only toe-off
            self.event_since_s_ = held_since(self.event_since_s_, self._event(x), x.time_s)
            held = held_for(self.event_since_s_, x.time_s, sch.event_hold_s)
            if guard or held:
                if self.state_ == GaitState.SWING_EXTENSION:     # stance again: caught by a stall, or a heel strike
                    self.recovering_ = self.caught_ = not guard and x.load_N <= sch.we_to_sf_load_N
                self._enter(GaitState((int(self.state_) + 1) % 4), x.time_s, guard)
        lim = self.limits
        tk, ta = self._standing_torques(x) if self.standing_ else self._row_torques(x)
        if self.early_landing_ and self.state_ == GaitState.STANCE_FLEXION and not self.standing_ \
                and self._landed_on_the_toe(x) \
                and not (self.caught_ and tk <= -lim.knee_torque_Nm and x.knee_velocity_rad_s > 0.0):
            # no more plantarflexion torque than a centre of pressure at the threshold needs: the heel comes down
            # (not after a catch while the knee, at its drive's limit, still flexes: the ankle's row helps extend it)
            ta = max(ta, -self.schedule.forefoot_landing_fraction * self.forefoot_m * max(x.load_N, 0.0))
        tk, sk = clip_torque(tk, x.knee_angle_rad, lim.knee_torque_Nm, lim.knee_range_rad[0], lim.knee_range_rad[1])
        ta, sa = clip_torque(ta, x.ankle_angle_rad, lim.ankle_torque_Nm, lim.ankle_range_rad[0], lim.ankle_range_rad[1])
        return TorqueCommand(self.state_, tk, ta, sk or sa)
