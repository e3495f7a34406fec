"""The bench's planned hip path and foot placement."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from controller_core.walking_reference import level_walking_reference
from device_bridge.sim.bench_trajectory import (
    hip_height_mismatch_mm,
    plan_bench_trajectory,
    stance_hip_height_m,
    thigh_angle_rad,
)
from device_bridge.sim.leg_model import LegGeometry


def test_bench_puts_the_reference_foot_flat_and_on_the_floor_in_mid_stance():
    ref = level_walking_reference(1.2)
    g = LegGeometry()
    thigh = thigh_angle_rad(ref, 0.0)
    mid = (ref.phase >= 0.15) & (ref.phase <= 0.40)
    pitch = thigh - ref.knee_angle_rad + ref.ankle_angle_rad
    assert abs(np.mean(pitch[mid])) < 1e-9                      # flat on average, by construction
    h = stance_hip_height_m(thigh, ref.knee_angle_rad, ref.ankle_angle_rad, g, 0.0)
    leg = g.thigh_m + g.shank_m + g.ankle_height_m
    assert np.all(h[mid] < leg) and np.all(h[mid] > 0.85 * leg)   # a bent stance leg, never longer than straight
    traj = plan_bench_trajectory(ref, g, 75.0, 2.0)
    assert traj.x_m[-1] - traj.x_m[0] == pytest.approx(1.2 * (2.0 - 0.001), rel=1e-6)   # belt speed
    assert traj.load_N.max() == pytest.approx(ref.vgrf_bw.max() * 75.0 * 9.81, rel=0.05)


def test_hip_height_mismatch_is_zero_when_both_legs_agree_and_measures_the_plan_otherwise():
    # synthetic gait, said so: a leg frozen at one posture touches the floor at one height all cycle long,
    # so the two legs agree in double support and the bench's path meets the touching height everywhere
    ref = level_walking_reference(1.2)
    frozen = dataclasses.replace(ref, hip_angle_rad=np.full_like(ref.phase, 0.2),
                                 knee_angle_rad=np.full_like(ref.phase, 0.1), ankle_angle_rad=np.zeros_like(ref.phase))
    g = LegGeometry()
    agree = hip_height_mismatch_mm(frozen, g)
    assert agree["heel_strike"] == pytest.approx(0.0, abs=1e-6) and agree["pre_swing"] == pytest.approx(0.0, abs=1e-6)
    # the shipped curves: the two legs disagree in double support, so the hip is too high when the foot should
    # land and too low in pre-swing (docs/results.md); the heel-strike figure is the planned path's own
    real = hip_height_mismatch_mm(ref, g)
    assert real["heel_strike"] > 5.0 and real["pre_swing"] < -20.0
    traj = plan_bench_trajectory(ref, g, 75.0, 0.01, start_phase=0.0)
    thigh = thigh_angle_rad(ref, 0.0)
    touch = stance_hip_height_m(thigh, ref.knee_angle_rad, ref.ankle_angle_rad, g, 0.0)
    assert real["heel_strike"] == pytest.approx(1000.0 * (traj.height_m[0] - touch[0]), abs=1e-6)
