"""Safe mode that holds a person: what the leg does without a table it may run (safe mode, no table yet).

A damper alone let a loaded knee fold (the simulated knee sat at 40–65° under 58 % of body weight stride after
stride). Like a microprocessor knee's safety mode, this one is passive and asymmetric:

* **knee, loaded** (the load cell above :attr:`SafeModeParameters.loaded_on_N`, off again below
  :attr:`~SafeModeParameters.loaded_off_N`): the angle where the load found the knee is held against flexion by a
  stiff spring and a strong flexion damper, and follows the knee down as it extends (a ratchet: extension is free,
  only lightly damped). The spring's rest angle never moves toward flexion while loaded, so it only gives back what
  the person put in: it injects no energy;
* **knee, unloaded** (swing, or the leg lifted): a soft spring toward near-full extension with light damping, a
  passive knee's extension assist: the shank swings and is extended for the next landing (without it the foot landed
  on a knee still bent 30–40°, which the hold then kept);
* **ankle**: a spring to neutral with damping, so the foot lands flat-ish and the person can roll over it.

Values are absolute (N, N·m/rad), sized for the leg's rated 100 kg: a lighter person gets a firmer knee, which is
the safe side. Every torque is clipped to the actuator and range limits like the table's. The controller is pure
(no clock, no I/O): the firmware runs it in safe mode and without a table, and the bench walks it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from controller_core.fsm import ActuatorLimits, GaitState, Impedance, SensorSample, TorqueCommand, clip_torque


@dataclass(frozen=True)
class SafeModeParameters:
    """What safe mode does (SI; see the module).

    Attributes:
        loaded_on_N, loaded_off_N: the leg counts as loaded above the first and unloaded again below the second (N;
            hysteresis, so a load near one threshold does not chatter).
        knee_hold_k_Nm_per_rad: the spring holding the loaded knee against flexion beyond where the load found it.
        knee_flexion_b_Nm_s_per_rad: damping of loaded knee flexion.
        knee_extension_b_Nm_s_per_rad: damping of loaded knee extension (light: extension is free).
        knee_swing_k_Nm_per_rad, knee_swing_theta_rad: the unloaded knee's extension assist: a spring toward this
            angle (a fixed rest angle: it stores and gives back, it injects nothing).
        knee_swing_b_Nm_s_per_rad: damping of the unloaded knee (light: the shank swings).
        ankle_k_Nm_per_rad, ankle_b_Nm_s_per_rad: the ankle's spring to neutral and its damping.
    """

    loaded_on_N: float = 150.0
    loaded_off_N: float = 60.0
    knee_hold_k_Nm_per_rad: float = 600.0
    knee_flexion_b_Nm_s_per_rad: float = 60.0
    knee_extension_b_Nm_s_per_rad: float = 3.0
    knee_swing_k_Nm_per_rad: float = 80.0
    knee_swing_theta_rad: float = math.radians(3.0)
    knee_swing_b_Nm_s_per_rad: float = 5.0
    ankle_k_Nm_per_rad: float = 250.0
    ankle_b_Nm_s_per_rad: float = 4.0

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"safe mode's {name} must be a finite value ≥ 0, got {value!r}")
        if not self.loaded_off_N < self.loaded_on_N:
            raise ValueError(f"safe mode's loaded_off_N ({self.loaded_off_N:g} N) must be below loaded_on_N "
                             f"({self.loaded_on_N:g} N): the hysteresis between them keeps it from chattering")


@dataclass
class SafeModeController:
    """Safe mode's torques (see the module); :meth:`reset` when it is entered.

    Attributes:
        loaded_: whether the leg counts as loaded now.
        knee_hold_rad_: the loaded knee's hold angle (rad; None while unloaded).
        transitions_, guard_transitions_: loaded/unloaded changes (for the bench's bookkeeping; no guard here).
    """

    params: SafeModeParameters = field(default_factory=SafeModeParameters)
    limits: ActuatorLimits = field(default_factory=ActuatorLimits)
    loaded_: bool = field(init=False, default=False)
    knee_hold_rad_: float | None = field(init=False, default=None)
    transitions_: int = field(init=False, default=0)
    guard_transitions_: int = field(init=False, default=0)

    def reset(self) -> None:
        self.loaded_, self.knee_hold_rad_ = False, None
        self.transitions_ = 0

    def impedance(self) -> Impedance:
        """Safe mode as a spring and damper per joint (k, θe rad, b): the loaded knee held where the load found it
        (both ways, and with the flexion damping: an actuator's impedance is symmetric), the unloaded knee's extension
        assist, the ankle to neutral."""
        p = self.params
        if self.loaded_ and self.knee_hold_rad_ is not None:
            knee = (-p.knee_hold_k_Nm_per_rad, self.knee_hold_rad_, p.knee_flexion_b_Nm_s_per_rad)
        else:
            knee = (-p.knee_swing_k_Nm_per_rad, p.knee_swing_theta_rad, p.knee_swing_b_Nm_s_per_rad)
        return knee, (-p.ankle_k_Nm_per_rad, 0.0, p.ankle_b_Nm_s_per_rad)

    def step(self, x: SensorSample) -> TorqueCommand:
        p, lim = self.params, self.limits
        loaded = x.load_N > (p.loaded_off_N if self.loaded_ else p.loaded_on_N)
        if loaded != self.loaded_:
            self.transitions_ += 1
            self.loaded_ = loaded
        if loaded:
            hold = x.knee_angle_rad if self.knee_hold_rad_ is None else min(self.knee_hold_rad_, x.knee_angle_rad)
            self.knee_hold_rad_ = hold
            v = x.knee_velocity_rad_s
            knee = -p.knee_hold_k_Nm_per_rad * (x.knee_angle_rad - hold) - (
                p.knee_flexion_b_Nm_s_per_rad if v > 0 else p.knee_extension_b_Nm_s_per_rad) * v
        else:
            self.knee_hold_rad_ = None
            knee = -p.knee_swing_k_Nm_per_rad * (x.knee_angle_rad - p.knee_swing_theta_rad) - \
                p.knee_swing_b_Nm_s_per_rad * x.knee_velocity_rad_s
        ankle = -p.ankle_k_Nm_per_rad * x.ankle_angle_rad - p.ankle_b_Nm_s_per_rad * x.ankle_velocity_rad_s
        tk, sat_k = clip_torque(knee, x.knee_angle_rad, lim.knee_torque_Nm, *lim.knee_range_rad)
        ta, sat_a = clip_torque(ankle, x.ankle_angle_rad, lim.ankle_torque_Nm, *lim.ankle_range_rad)
        state = GaitState.STANCE_FLEXION if loaded else GaitState.SWING_EXTENSION
        return TorqueCommand(state, tk, ta, sat_k or sat_a)
