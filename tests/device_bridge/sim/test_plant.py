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


def test_a_model_in_which_more_than_the_foot_and_floor_collide_is_refused(monkeypatch):
    # the foot's contact force sums every contact, so a shank that could touch the floor would be counted as the foot
    from device_bridge.sim import plant

    real = plant.build_mjcf
    monkeypatch.setattr(plant, "build_mjcf", lambda *a, **k: real(*a, **k).replace(
        '<geom name="shank" type="capsule"', '<geom name="shank" contype="1" conaffinity="1" type="capsule"'))
    with pytest.raises(ValueError, match=r"only the foot and the floor may collide.*shank"):
        SimulatedLeg()


def test_the_foot_contact_force_is_the_normal_force_between_the_foot_and_the_floor():
    import mujoco
    import numpy as np

    leg = SimulatedLeg()
    m, d = leg.model, leg.data
    feet = {m.geom("heel").id, m.geom("toe").id}
    floor = {i for i in range(m.ngeom) if m.geom(i).name.startswith("floor")}
    traj = plan_bench_trajectory(level_walking_reference(1.2), leg.geometry, 75.0, 1.5, leg.timestep_s)
    leg.reset(traj, 0.1, 0.0)
    f6, touched = np.zeros(6), 0
    for _ in range(traj.time_s.shape[0] - 1):
        leg.step(0.0, 0.0)
        expected = 0.0
        for j in range(d.ncon):                      # each contact's pair looked up: foot on floor only
            pair = {int(d.contact[j].geom1), int(d.contact[j].geom2)}
            if pair & feet and pair & floor:
                mujoco.mj_contactForce(m, d, j, f6)
                expected += abs(f6[0])
        touched += expected > 100.0
        assert leg.foot_contact_force() == pytest.approx(expected, abs=1e-9)
    assert touched > 100                              # the foot carried the body for a while: the sum was tested


def _folding_walk(person):
    """A prosthesis whose knee is pushed into flexion (30 N·m) walked from late swing for 1.5 s: the knee folds under
    the body and the hip sinks once the other foot lifts."""
    from device_bridge.sim.person import Person

    leg = SimulatedLeg(person=person or Person(75.0))
    traj = plan_bench_trajectory(level_walking_reference(1.2), leg.geometry, 75.0, 1.5, leg.timestep_s)
    leg.reset(traj, math.radians(5.0), 0.0)
    lowest = 0.0
    for i in range(1, len(traj.time_s)):
        leg.step(30.0, 0.0)
        lowest = min(lowest, leg.hip_position_m()[1] - traj.z_m[i])
    return leg, traj, lowest


def test_a_person_who_steps_to_save_themselves_puts_the_other_foot_down_once_the_hip_has_sunk():
    """Person.recovery_steps (stumble walks): the other foot comes down out of its plan once the hip is 50 mm below
    its path, and the hip sinks less than a person's who never steps; the step's time is kept."""
    from device_bridge.sim.person import Person

    still, _, sunk_still = _folding_walk(Person(75.0))
    stepping, traj, sunk_stepping = _folding_walk(Person(75.0, recovery_steps=True))
    assert still.recovery_step_times_s == [] and sunk_still < -0.1
    assert len(stepping.recovery_step_times_s) >= 1
    t = stepping.recovery_step_times_s[0]
    assert not traj.other_foot_down[round(t / stepping.timestep_s)]        # the plan had that foot in the air
    assert sunk_stepping > sunk_still + 0.03
