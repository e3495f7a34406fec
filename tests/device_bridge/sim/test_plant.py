"""The simulated leg: placed on its bench path, stepped with torques, read by its sensors."""

from __future__ import annotations

import math

import pytest

from controller_core.walking_reference import level_walking_reference
from device_bridge.sim.bench_trajectory import plan_bench_trajectory
from device_bridge.sim.plant import SimulatedLeg


def test_the_leg_is_placed_on_its_path_and_falls_limp_without_torque():
    leg = SimulatedLeg()
    ref = level_walking_reference(1.2)
    traj = plan_bench_trajectory(ref, leg.geometry, 75.0, 1.0, leg.timestep_s)
    first = leg.reset(traj, math.radians(10.0), 0.0)
    assert first.knee_angle_rad == pytest.approx(math.radians(10.0), abs=1e-6)
    assert leg.hip_position_m() == pytest.approx((traj.x_m[0], traj.z_m[0]), abs=1e-9)
    for _ in range(300):
        last = leg.step(0.0, 0.0)
    assert last.time_s == pytest.approx(0.3, abs=1e-9)
    assert leg.foot_contact_force() >= 0.0 and math.isfinite(last.load_N)


def test_torque_moves_the_joint_it_is_applied_to():
    leg = SimulatedLeg()
    traj = plan_bench_trajectory(level_walking_reference(1.2), leg.geometry, 75.0, 1.0, leg.timestep_s)
    leg.reset(traj, math.radians(30.0), 0.0)
    free = [leg.step(0.0, 0.0).knee_angle_rad for _ in range(50)][-1]
    leg.reset(traj, math.radians(30.0), 0.0)
    flexed = [leg.step(20.0, 0.0).knee_angle_rad for _ in range(50)][-1]
    assert flexed > free                                   # + knee torque flexes the knee


def test_a_leg_is_refused_a_slope_beyond_twenty_degrees_and_stepping_before_placing():
    with pytest.raises(ValueError, match="within ±20 deg"):
        SimulatedLeg(incline_deg=25.0)
    with pytest.raises(RuntimeError, match="reset"):
        SimulatedLeg().step(0.0, 0.0)
