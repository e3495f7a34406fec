"""Quiet standing on the bench, with weight shifts: the person stands on both feet, their hip still above the
prosthesis's foot, and leans from one leg to the other.

The same bench as walking (:mod:`device_bridge.sim.plant`, :mod:`device_bridge.sim.person`), with a still trajectory:
the socket's forward position held, the thigh at the angle that puts the foot flat with the knee at
:data:`STANDING_KNEE_DEG` and the ankle at :data:`STANDING_ANKLE_DEG`, the hip's path at the height the leg touches the
floor with those angles, and the other leg pushing what the prosthesis should not carry: the body weight less the
prosthesis's share, which sways between :data:`SHARE_LOW` and :data:`SHARE_HIGH` of body weight at
:data:`SHIFT_HZ` (a person shifting their weight from leg to leg; quiet standing itself sways a few percent). If the
prosthesis gives way the hip sinks below its path and the person's compensation (their other leg's spring) catches
them, counted as when walking. What the knee and the state machine do is the controller's.
"""

from __future__ import annotations

import math

import numpy as np

from controller_core.units import G_MPS2
from device_bridge.sim.bench_trajectory import BenchTrajectory, touching_hip_height_m
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.person import Person
from device_bridge.sim.plant import SimulatedLeg
from device_bridge.sim.simulate import StepController, WalkLog, walk_loop

STANDING_KNEE_DEG = 3.0
STANDING_ANKLE_DEG = 1.0
SHARE_LOW, SHARE_HIGH = 0.3, 0.7     # the prosthesis's share of body weight, leaning away and onto it
SHIFT_HZ = 0.2


def plan_standing(geometry: LegGeometry, mass_kg: float, seconds: float, timestep_s: float = 0.001,
                  share_low: float = SHARE_LOW, share_high: float = SHARE_HIGH,
                  shift_hz: float = SHIFT_HZ) -> BenchTrajectory:
    """The still socket and the other leg's push for ``seconds`` of standing (see the module)."""
    if not (math.isfinite(seconds) and 0.0 < seconds <= 600.0):
        raise ValueError(f"seconds must be in (0, 600], got {seconds!r}")
    if not 0.0 <= share_low <= share_high <= 1.0:
        raise ValueError(f"the prosthesis's share must be 0 ≤ low ≤ high ≤ 1 of body weight, got {share_low}, "
                         f"{share_high}")
    n = round(seconds / timestep_s)
    t = np.arange(n) * timestep_s
    knee, ankle = math.radians(STANDING_KNEE_DEG), math.radians(STANDING_ANKLE_DEG)
    thigh = knee - ankle                                   # the foot flat: thigh − knee + ankle = 0
    height = float(touching_hip_height_m(thigh, knee, ankle, geometry, 0.0))
    mid, half = (share_low + share_high) / 2, (share_high - share_low) / 2
    share = mid + half * np.sin(2 * math.pi * shift_hz * t)
    zeros = np.zeros(n)
    return BenchTrajectory(time_s=t, phase=zeros.copy(), x_m=zeros.copy(), z_m=np.full(n, height),
                           hip_rad=np.full(n, thigh), xd_m_s=zeros.copy(), zd_m_s=zeros.copy(),
                           hipd_rad_s=zeros.copy(), height_m=np.full(n, height),
                           other_leg_N=(1.0 - share) * mass_kg * G_MPS2, other_foot_down=np.ones(n, dtype=bool),
                           stance=np.ones(n, dtype=bool), stride_time_s=1.0)


def run_standing(controller: StepController, mass_kg: float, seconds: float, geometry: LegGeometry | None = None,
                 person: Person | None = None, **shifts: float) -> WalkLog:
    """``controller`` on the bench while the person stands for ``seconds`` (``shifts``: :func:`plan_standing`'s
    share_low, share_high, shift_hz)."""
    leg = SimulatedLeg(geometry, 0.0, person=person or Person(mass_kg))
    traj = plan_standing(leg.geometry, mass_kg, seconds, leg.timestep_s, **shifts)
    n = traj.time_s.shape[0]
    start = (math.radians(STANDING_KNEE_DEG), math.radians(STANDING_ANKLE_DEG))
    return walk_loop(controller, leg, traj, start, (np.zeros(n), np.ones(n)), mass_kg, standing=True)

