"""The person around the prosthesis on the bench: their hip, their other leg, and nothing more.

The bench's body rides on the socket's vertical slide and the prosthesis carries what it can; the person supplies the
rest the way a person can:

* **The hip** drives the thigh along the reference thigh angle (a PD servo, the person placing their leg). In swing
  the leg is light and the servo is unlimited; while the foot touches the floor the hip can add only its strength,
  :attr:`Person.hip_strength_Nm_per_kg` × body mass. A stiff servo there would hold the body up through a locked
  thigh and hide a knee that gives way (with the thigh angle and the hip's forward position both fixed and the foot
  flat, the knee cannot flex at all).
* **The other leg** pushes the reference's contralateral vertical force (the ipsilateral one half a cycle on, each
  leg's share scaled to half the body weight over a stride); while its foot is down it is also a leg, pushing harder
  the lower the hip is below its path (a spring and damper, never pulling), which is how a person takes weight onto
  their sound leg when the prosthesis gives way. Over the prosthesis's swing it carries the body along its path
  (:mod:`device_bridge.sim.bench_trajectory`).
* **The walk's progression**: the body moves forward at belt speed, driven by a servo that yields (critically damped
  for the body's mass, about 3 Hz): the person's momentum, not a rail. A rail would let a knee flex only as far as the
  geometry of a planted foot under a hip on the rail allows, and hide a soft stance row.
* **A weak stabiliser** (0.1 body weight per 0.1 m from the path, damping ratio 0.5) keeps a long walk from drifting.
* **A recovery step**, only where a walk asks for it (``recovery_steps``: the stumble walks of
  :mod:`device_bridge.sim.stumble`): once the hip is ``recovery_step_sink_m`` below its path while the other foot is in
  the air, that foot comes down at once and stays down to the end of its next planned stance, as a person who has
  tripped puts their sound foot down early (the lowering strategy's quick step). 50 mm is the gate's bound on a hip
  sinking in stance (beyond what walking does) and a third of the way to a fall; the sink itself takes 0.3–0.5 s
  to build after a trip, longer than a person's 150–250 ms to react. Steady walks and the gate keep a person who
  never steps to save themselves: there a hip sinking 150 mm is a fall, which is the stricter test of a table.

What the other leg's spring and the stabiliser add beyond the reference share is the person's **compensation**
(``support_N``): the figure ``support_deficit_max_bw`` reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

from controller_core.units import G_MPS2, require_positive


@dataclass(frozen=True)
class Person:
    """The person's side of the bench (see the module docstring).

    Args:
        mass_kg: body mass (kg), the weight the socket carries.
        hip_strength_Nm_per_kg: the most hip torque per kg of body mass while the foot is on the floor (N·m/kg):
            1.0 is about the peak hip moment of level walking.
        hip_stiffness_Nm_per_rad, hip_damping_Nm_s_per_rad: the hip's servo on the reference thigh angle.
        other_leg_stiffness_N_per_m, other_leg_damping_N_s_per_m: the other leg's spring while its foot is down:
            about a walking leg's vertical stiffness, damped critically for the body's mass.
        stabiliser_bw_per_0_1m, stabiliser_damping_ratio: the weak spring to the path that stops drift.
        progression_stiffness_N_per_m, progression_damping_N_s_per_m: the forward drive at belt speed.
        recovery_steps, recovery_step_sink_m: whether the person steps to save themselves, and how far their hip
            sinks below its path (m) before they do (module docstring).
    """

    mass_kg: float
    hip_strength_Nm_per_kg: float = 1.0
    hip_stiffness_Nm_per_rad: float = 3000.0
    hip_damping_Nm_s_per_rad: float = 100.0
    other_leg_stiffness_N_per_m: float = 20000.0
    other_leg_damping_N_s_per_m: float = 2300.0
    stabiliser_bw_per_0_1m: float = 0.1
    stabiliser_damping_ratio: float = 0.5
    progression_stiffness_N_per_m: float = 20000.0
    progression_damping_N_s_per_m: float = 2300.0
    recovery_steps: bool = False
    recovery_step_sink_m: float = 0.05

    def __post_init__(self) -> None:
        require_positive(self, tuple(n for n in vars(self) if n != "recovery_steps"))

    @property
    def weight_N(self) -> float:
        return self.mass_kg * G_MPS2

    @cached_property
    def hip_limit_Nm(self) -> float:
        """The hip's strength with the foot down (N·m)."""
        return self.hip_strength_Nm_per_kg * self.mass_kg

    @cached_property
    def _stabiliser_gains(self) -> tuple[float, float]:
        """The stabiliser's stiffness (N/m) and damping (N·s/m), worked out once: the bench asks every tick."""
        k = self.stabiliser_bw_per_0_1m * self.weight_N / 0.1
        return k, 2.0 * self.stabiliser_damping_ratio * math.sqrt(k * self.mass_kg)

    def hip_torque_Nm(self, angle_error_rad: float, rate_error_rad_s: float, foot_down: bool) -> float:
        """The hip's torque on the thigh (N·m, flexion +) for the error from the reference thigh angle and rate."""
        tau = self.hip_stiffness_Nm_per_rad * angle_error_rad + self.hip_damping_Nm_s_per_rad * rate_error_rad_s
        if foot_down:
            lim = self.hip_limit_Nm
            tau = max(-lim, min(lim, tau))
        return tau

    def compensation_N(self, height_error_m: float, rate_error_m_s: float, other_foot_down: bool,
                       other_share_N: float) -> float:
        """Vertical push (N, up +) beyond the other leg's reference share, for the hip's error from its path
        (path − actual: positive when the hip is low) and its rate."""
        k, c = self._stabiliser_gains
        push = k * height_error_m + c * rate_error_m_s
        if other_foot_down:   # the other leg is a leg: it pushes harder when the hip is low, and never pulls
            leg = self.other_leg_stiffness_N_per_m * height_error_m + self.other_leg_damping_N_s_per_m * rate_error_m_s
            push += max(-other_share_N, leg)
        return push
