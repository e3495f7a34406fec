"""The bench's hip path, thigh angle and the other leg's push at a task."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.walking_reference import level_walking_reference, sloped_walking_reference
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.bench_trajectory import (
    SWING_CLEARANCE_M,
    hip_path_m,
    other_leg_share_bw,
    plan_bench_trajectory,
    thigh_angle_rad,
    touching_hip_height_m,
)
from device_bridge.sim.leg_model import LegGeometry


def test_bench_puts_the_reference_foot_flat_and_on_the_floor_in_mid_stance():
    ref = level_walking_reference(1.2)
    g = LegGeometry()
    thigh = thigh_angle_rad(ref, 0.0)
    mid = (ref.phase >= 0.15) & (ref.phase <= 0.40)
    pitch = thigh - ref.knee_angle_rad + ref.ankle_angle_rad
    assert abs(np.mean(pitch[mid])) < 1e-9                      # flat on average, by construction
    h = touching_hip_height_m(thigh, ref.knee_angle_rad, ref.ankle_angle_rad, g, 0.0)
    leg = g.thigh_m + g.shank_m + g.ankle_height_m
    assert np.all(h[mid] < leg) and np.all(h[mid] > 0.85 * leg)   # a bent stance leg, never longer than straight


@pytest.mark.parametrize(("speed", "incline"), [(0.84, 0.0), (1.2, 0.0), (1.95, 0.0), (1.2, 10.0), (1.2, -10.0)])
def test_the_path_is_the_reference_legs_own_in_stance_and_clears_its_foot_in_swing(speed, incline):
    ref = task_reference(speed, incline, None, 75.0)
    g = LegGeometry()
    thigh, height = hip_path_m(ref, g)
    touch = touching_hip_height_m(thigh, ref.knee_angle_rad, ref.ankle_angle_rad, g, incline)
    stance = ref.phase <= ref.toe_off_phase
    np.testing.assert_allclose(height[stance], touch[stance], atol=1e-12)   # the reference leg carries the hip
    mid_swing = (ref.phase > ref.toe_off_phase + 0.06) & (ref.phase < 0.94)
    assert np.all(height[mid_swing] - touch[mid_swing] >= SWING_CLEARANCE_M - 1e-9)   # and its foot clears
    assert abs(height[-1] - height[0]) < 1e-12                                   # one stride joins the next


def test_the_hip_moves_at_belt_speed_along_the_floor():
    ref = level_walking_reference(1.2)
    traj = plan_bench_trajectory(ref, LegGeometry(), 75.0, 3 * ref.stride_time_s, timestep_s=0.001, start_phase=0.0)
    np.testing.assert_allclose(traj.xd_m_s, 1.2, atol=1e-9)


def test_the_other_leg_carries_half_the_weight_and_the_body_over_the_swing():
    ref = level_walking_reference(1.2)
    share = other_leg_share_bw(ref)
    assert float(np.mean(share[:-1])) == pytest.approx(0.5, abs=1e-12)
    mass = 75.0
    traj = plan_bench_trajectory(ref, LegGeometry(), mass, ref.stride_time_s, start_phase=0.0)
    w = mass * 9.81
    stance = traj.stance
    np.testing.assert_allclose(traj.other_leg_N[stance], np.interp(traj.phase[stance], ref.phase, share) * w,
                               rtol=1e-9)
    # over the swing the other leg keeps the body on its path: the push is the weight plus mass × the path's
    # vertical acceleration, which over the swing averages to the change of the path's vertical speed
    swing = ~stance
    dt = 0.001
    mean_push = float(np.mean(traj.other_leg_N[swing])) - w
    dv = (traj.zd_m_s[swing][-1] - traj.zd_m_s[swing][0]) / (np.count_nonzero(swing) * dt)
    assert mean_push == pytest.approx(mass * dv, abs=0.02 * w)
    assert np.all(traj.other_leg_N >= 0.0) and traj.other_foot_down[swing].all()


def test_on_a_slope_the_path_follows_the_floor():
    ref = task_reference(1.2, 10.0, None, 75.0)
    traj = plan_bench_trajectory(ref, LegGeometry(), 75.0, 2.0, start_phase=0.0)
    climb = (traj.z_m[-1] - traj.z_m[0]) / (traj.x_m[-1] - traj.x_m[0])
    assert math.degrees(math.atan(climb)) == pytest.approx(10.0, abs=1.0)


def test_a_start_from_standing_stands_still_then_becomes_the_walk_itself():
    """Quiet standing (the hip still, the other leg pushing half the weight), then gait initiation that is done before
    the other leg's first landing (so the prosthesis's unloading is the walk's), after which it is exactly the walk
    from the prosthesis's heel strike: the same positions, thigh and push at the same times, at belt speed."""
    from controller_core.units import G_MPS2
    from device_bridge.sim.bench_trajectory import INITIATION_STRIDES, plan_standing_start

    ref, g, mass = sloped_walking_reference(1.2, -6.0), LegGeometry(), 75.0
    traj = plan_standing_start(ref, g, mass, 6.0, stand_s=1.0)
    still = traj.time_s < 1.0
    assert np.ptp(traj.x_m[still]) == 0 and np.ptp(traj.hip_rad[still]) == 0 and traj.stance[still].all()
    assert traj.other_leg_N[still] == pytest.approx(0.5 * mass * G_MPS2)
    assert np.all(traj.xd_m_s[still] == 0) and np.all(traj.zd_m_s[still] == 0)
    ramp_end = 1.0 + INITIATION_STRIDES * ref.stride_time_s
    assert traj.phase[np.argmax(traj.time_s >= ramp_end)] < 0.5          # done before the other leg lands (phase 0.5)
    for name in ("x_m", "z_m"):                                           # the velocities are the positions' rates
        rate = np.gradient(getattr(traj, name), traj.time_s)
        assert np.allclose(rate[5:-5], getattr(traj, name.replace("_m", "d_m_s"))[5:-5], atol=2e-3), name
    walk = plan_bench_trajectory(ref, g, mass, 5.0, start_phase=0.0)
    after = traj.time_s >= ramp_end
    for name in ("x_m", "z_m", "hip_rad", "xd_m_s", "other_leg_N", "phase"):
        assert np.allclose(getattr(traj, name)[after], getattr(walk, name)[after[1000:]]), name


def test_from_standing_the_learned_table_walks_downhill_where_the_swing_start_made_it_fall(model):
    """The bench's first start (late swing at belt speed, joints still) landed the foot early on a knee bent 30°:
    downhill every controller fell, once per bench stride (now fewer times: the stumble support recovers it). From
    quiet standing through gait initiation the same tables at the same tasks walk without falling."""
    from controller_core.fsm import ImpedanceSchedule, StateMachineController
    from controller_core.walking_reference import sloped_walking_reference
    from device_bridge.sim.simulate import run_walk, score_walk

    for speed in (0.85, 1.0):
        ref = sloped_walking_reference(speed, -10.0)
        table = model.propose(speed, -10.0, 75.0).table
        falls = {start: score_walk(run_walk(StateMachineController(ImpedanceSchedule.from_table(table)), ref, 75.0,
                                            15.0, start=start), ref).summary["falls"] for start in ("swing", "standing")}
        assert falls["swing"] >= 1 and falls["standing"] == 0, (speed, falls)


def test_each_fall_says_when_in_which_state_and_why(model):
    """A walk that falls (downhill from the old late-swing start) lists each fall it counts: its time, the leg's
    state, the bench's phase, the knee and the load then, and which of the two rules it broke."""
    from controller_core.fsm import ImpedanceSchedule, StateMachineController
    from controller_core.walking_reference import sloped_walking_reference
    from device_bridge.sim.simulate import run_walk, score_walk

    ref = sloped_walking_reference(1.0, -10.0)
    summary = score_walk(run_walk(StateMachineController(ImpedanceSchedule.from_table(
        model.propose(1.0, -10.0, 75.0).table)), ref, 75.0, 8.0, start="swing"), ref).summary
    events = summary["fall_events"]
    assert summary["falls"] == len(events) > 0
    assert [e["time_s"] for e in events] == sorted(e["time_s"] for e in events)
    assert all(e["why"] in ("the hip sank", "the knee buckled under load") and 0 <= e["bench_phase"] < 1 and
               e["state"] in ("stance_flexion", "stance_extension", "swing_flexion", "swing_extension")
               for e in events)
    assert any(e["why"] == "the knee buckled under load" and e["knee_angle_deg"] >= 60 and e["load_bw"] > 0.5
               for e in events) or any(e["why"] == "the hip sank" for e in events)
