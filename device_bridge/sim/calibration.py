"""Calibrate the bench against the people it imitates: walk the reference's own joint angles and see whether the body
rides where people's does.

A position-controlled knee and ankle follow the reference at the task (the reference's joint moment × body mass fed
forward, and a PD servo on the reference's angle and velocity for the rest: a stiff servo alone chatters against the
floor under the body's weight), so the prosthesis does what the able-bodied leg did. If the bench's body, other leg
and hip path are right, the hip then stays on its path and the person adds nothing beyond their other leg's reference
share.
:func:`calibration_walk` measures both; :data:`HIP_TOLERANCE_MM` and :data:`DEFICIT_TOLERANCE_BW` are the bounds the
tests and the results hold it to.
"""

from __future__ import annotations

import math

import numpy as np

from controller_core.units import G_MPS2
from controller_core.walking_reference import WalkingReference
from device_bridge.sim.bench_trajectory import plan_bench_trajectory
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.person import Person
from device_bridge.sim.plant import SimulatedLeg
from device_bridge.sim.simulate import windowed_support_N

HIP_TOLERANCE_MM = 60.0          # the hip within this of its path over the stance, at every task of the compare grid
DEFICIT_TOLERANCE_BW = 1.0       # the person's largest compensation (a 50 ms mean, as walks read it) within this
DEFICIT_MEAN_TOLERANCE_BW = 0.2   # and its mean over the stance within this
JOINT_STIFFNESS_NM_PER_RAD = 600.0
JOINT_DAMPING_NM_S_PER_RAD = 15.0


def calibration_walk(reference: WalkingReference, mass_kg: float = 75.0, seconds: float = 8.0, settle_s: float = 2.0,
                     geometry: LegGeometry | None = None) -> dict[str, float]:
    """Walk the reference's knee and ankle angles, position-controlled, at the reference's task; returns the hip's
    error from its path over the prosthesis's stance (mm, lowest and highest, actual − path) and over the whole
    stride (RMS, mm), and the person's compensation (body weights): its largest 50 ms mean and its mean over the
    prosthesis's stance."""
    leg = SimulatedLeg(geometry, reference.incline_deg, person=Person(mass_kg))
    traj = plan_bench_trajectory(reference, leg.geometry, mass_kg, seconds, leg.timestep_s)
    s_grid, T = reference.phase, reference.stride_time_s
    knee = np.interp(traj.phase, s_grid, reference.knee_angle_rad)
    ankle = np.interp(traj.phase, s_grid, reference.ankle_angle_rad)
    knee_rate = np.interp(traj.phase, s_grid, np.gradient(reference.knee_angle_rad, s_grid)) / T
    ankle_rate = np.interp(traj.phase, s_grid, np.gradient(reference.ankle_angle_rad, s_grid)) / T
    knee_ff = np.interp(traj.phase, s_grid, reference.knee_moment_Nm_per_kg) * mass_kg
    ankle_ff = np.interp(traj.phase, s_grid, reference.ankle_moment_Nm_per_kg) * mass_kg
    x = leg.reset(traj, float(knee[0]), float(ankle[0]))
    n = traj.time_s.shape[0]
    error, support = np.empty(n), np.empty(n)
    kp, kd = JOINT_STIFFNESS_NM_PER_RAD, JOINT_DAMPING_NM_S_PER_RAD
    for i in range(n):
        error[i] = leg.hip_position_m()[1] - traj.z_m[i]
        support[i] = leg.support_N
        x = leg.step(knee_ff[i] + kp * (knee[i] - x.knee_angle_rad) + kd * (knee_rate[i] - x.knee_velocity_rad_s),
                     ankle_ff[i] + kp * (ankle[i] - x.ankle_angle_rad) + kd * (ankle_rate[i] - x.ankle_velocity_rad_s))
    after = traj.time_s >= settle_s
    stance = after & traj.stance
    error *= math.cos(math.radians(reference.incline_deg))   # along the floor's normal
    smooth = windowed_support_N(support, leg.timestep_s)[after]
    return {"speed_mps": reference.speed_mps, "incline_deg": reference.incline_deg,
            "hip_error_stance_min_mm": 1000.0 * float(error[stance].min()),
            "hip_error_stance_max_mm": 1000.0 * float(error[stance].max()),
            "hip_error_rms_mm": 1000.0 * float(np.sqrt(np.mean(error[after] ** 2))),
            "support_deficit_max_bw": float(max(0.0, smooth.max())) / (mass_kg * G_MPS2),
            "support_deficit_mean_bw": float(np.mean(np.maximum(support[stance], 0.0))) / (mass_kg * G_MPS2)}
