"""Task estimation from on-leg signals: scripted strides with known speed and slope, and strides walked on the bench."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.fsm import GaitState, ImpedanceSchedule, SensorSample, StateMachineController
from controller_core.task_estimator import TaskEstimator

THIGH_M, SHANK_M = 0.43, 0.43


def _leg_angles(ax: np.ndarray, az: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Thigh angle from vertical and knee flexion (rad) putting the ankle at (ax, az) from the hip (two-link IK)."""
    d = np.hypot(ax, az)
    beta = np.arctan2(ax, -az)
    a1 = np.arccos((THIGH_M**2 + d**2 - SHANK_M**2) / (2 * THIGH_M * d))
    a2 = np.arccos((SHANK_M**2 + d**2 - THIGH_M**2) / (2 * SHANK_M * d))
    thigh = beta + a1
    return thigh, a1 + a2


def scripted_walk(speed_mps: float, incline_deg: float, strides: int = 5, dt: float = 0.001, slide_mps: float = 0.0,
                  thigh_nan: bool = False, stance_s: float = 0.35, moment_Nm: float = -50.0
                  ) -> list[tuple[SensorSample, bool]]:
    """Synthetic strides (a test of the geometry, not gait data): in stance the foot lies flat on a slope of
    ``incline_deg`` and the hip passes over it at ``speed_mps`` along the slope (the foot sliding back at
    ``slide_mps``), 700 N on it with an ankle moment of ``moment_Nm`` (the centre of pressure −moment / 700 N ahead
    of the ankle); in swing (0.4 s) the foot pitches quickly, as a swinging foot does."""
    g = math.radians(incline_deg)
    out: list[tuple[SensorSample, bool]] = []
    t0 = 0.0
    for _ in range(strides):
        t = np.arange(0.0, stance_s, dt)
        progress = -0.5 * speed_mps * stance_s + (speed_mps + slide_mps) * t   # hip along the slope, from the ankle
        height = 0.80 + 0.01 * np.sin(np.pi * t / stance_s)
        hx = progress * math.cos(g) - height * math.sin(g)
        hz = progress * math.sin(g) + height * math.cos(g)
        thigh, knee = _leg_angles(-hx, -hz)
        ankle = g - (thigh - knee)                       # the foot flat on the slope
        vt, vk, va = (np.gradient(a, dt) for a in (thigh, knee, ankle))
        for k in range(t.size):
            out.append((SensorSample(t0 + t[k], knee[k], vk[k], ankle[k], va[k], 700.0, moment_Nm,
                                     math.nan if thigh_nan else thigh[k], vt[k]), True))
        t0 += stance_s
        for k in range(400):                              # swing: the foot pitches at 3 rad/s
            out.append((SensorSample(t0 + k * dt, 0.6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.3, 3.0), False))
        t0 += 0.4
    out.append((SensorSample(t0, 0.1, 0.0, 0.0, 0.0, 700.0, 0.0, 0.3, 0.0), True))   # the last heel strike
    return out


def run(est: TaskEstimator, samples):
    return [e for x, stance in samples if (e := est.update(x, stance)) is not None]


@pytest.mark.parametrize(("speed", "incline"), [(1.2, 0.0), (0.7, 8.0), (1.6, -9.0), (1.0, 3.5)])
def test_speed_and_incline_of_scripted_strides_are_read_back(speed, incline):
    est = TaskEstimator(THIGH_M, SHANK_M)
    estimates = run(est, scripted_walk(speed, incline))
    assert len(estimates) == 5                          # one per stride, at the heel strike that ends it
    last = estimates[-1]
    assert last.speed_mps == pytest.approx(speed, abs=0.01)
    assert last.incline_deg == pytest.approx(incline, abs=0.05)
    assert last.speed_confident and last.incline_confident and last.confidence > 0.9


def test_a_sliding_foot_spoils_the_speed_reading_but_not_the_slope():
    # the foot slides back at 0.3 m/s with a wobble: the hip's progress is no longer a straight line
    est = TaskEstimator(THIGH_M, SHANK_M)
    samples = scripted_walk(1.0, 8.0, slide_mps=0.3)
    wobbled = [(SensorSample(x.time_s, x.knee_angle_rad + 0.03 * math.sin(40 * x.time_s), x.knee_velocity_rad_s,
                             x.ankle_angle_rad + 0.03 * math.sin(40 * x.time_s), x.ankle_velocity_rad_s, x.load_N,
                             x.ankle_moment_Nm, x.thigh_angle_rad, x.thigh_velocity_rad_s), s) for x, s in samples]
    last = run(est, wobbled)[-1]
    assert last.incline_deg == pytest.approx(8.0, abs=0.2) and last.incline_confident
    assert last.speed_confidence < 0.5 and not last.speed_confident


def test_no_imu_or_too_short_a_flat_foot_gives_no_estimate_and_no_confidence():
    for samples in (scripted_walk(1.2, 0.0, thigh_nan=True), scripted_walk(1.2, 0.0, stance_s=0.05)):
        est = TaskEstimator(THIGH_M, SHANK_M)
        estimates = run(est, samples)
        assert estimates and all(not (e.speed_confident or e.incline_confident) for e in estimates)
        assert all(math.isnan(e.speed_mps) and e.confidence == 0.0 for e in estimates)


def _later(samples, by_s: float):
    return [(SensorSample(x.time_s + by_s, *[getattr(x, f) for f in SensorSample.__slots__[1:]]), s) for x, s in samples]


def test_the_estimate_averages_the_last_strides_and_follows_a_change_at_once():
    """Level, then a ramp walked faster: the first ramp stride's estimate is the ramp's own reading, not a mean across
    the change (which would say 3°, 1.2 m/s: right for neither); strides that agree within the estimate's resolution
    are averaged."""
    est = TaskEstimator(THIGH_M, SHANK_M, smoothing_strides=2)
    level = scripted_walk(1.0, 0.0, strides=3)
    ramp = _later(scripted_walk(1.4, 6.0, strides=3), 3.0)
    estimates = run(est, level[:-1] + ramp)
    first = estimates[3]
    assert first.incline_deg == pytest.approx(6.0, abs=0.05) and first.speed_mps == pytest.approx(1.4, abs=0.01)
    assert estimates[-1].incline_deg == pytest.approx(6.0, abs=0.05)
    close = TaskEstimator(THIGH_M, SHANK_M, smoothing_strides=2)      # 1° apart: within the resolution, averaged
    estimates = run(close, scripted_walk(1.0, 0.0, strides=3)[:-1] + _later(scripted_walk(1.05, 1.0, strides=3), 3.0))
    first = estimates[3]
    assert first.incline_deg == pytest.approx(0.5, abs=0.05) and first.speed_mps == pytest.approx(1.025, abs=0.01)


@pytest.mark.parametrize("bad", [{"thigh_length_m": 0.0}, {"smoothing_strides": 0}, {"confidence_threshold": 1.5},
                                 {"flat_rate_rad_s": math.nan}])
def test_nonsense_settings_are_refused(bad):
    with pytest.raises(ValueError):
        TaskEstimator(**{"thigh_length_m": THIGH_M, "shank_length_m": SHANK_M, **bad})


@pytest.mark.parametrize(("speed", "incline"), [(1.3, 5.0), (1.2, -8.0)])
def test_strides_walked_on_the_bench_are_estimated_within_the_target(model, speed, incline):
    from controller_core.walking_reference import sloped_walking_reference
    from device_bridge.sim.bench_trajectory import plan_bench_trajectory
    from device_bridge.sim.plant import SimulatedLeg

    ref = sloped_walking_reference(speed, incline)
    leg = SimulatedLeg(incline_deg=incline)
    traj = plan_bench_trajectory(ref, leg.geometry, 75.0, 10.0, leg.timestep_s)
    s0 = traj.phase[0]
    x = leg.reset(traj, float(np.interp(s0, ref.phase, ref.knee_angle_rad)),
                  float(np.interp(s0, ref.phase, ref.ankle_angle_rad)))
    ctrl = StateMachineController(ImpedanceSchedule.from_table(model.propose(speed, incline, 75.0).table))
    est = TaskEstimator(leg.geometry.thigh_m, leg.geometry.shank_m)
    estimates = []
    for _ in range(traj.time_s.shape[0]):
        cmd = ctrl.step(x)
        if (e := est.update(x, cmd.state in (GaitState.STANCE_FLEXION, GaitState.STANCE_EXTENSION))) is not None:
            estimates.append(e)
        x = leg.step(cmd.knee_torque_Nm, cmd.ankle_torque_Nm)
    settled = estimates[3:]   # the first strides are the bench settling from its start
    assert len(settled) >= 4
    assert all(abs(e.speed_mps - speed) <= 0.1 and abs(e.incline_deg - incline) <= 1.5 for e in settled)
    # confident on most strides: downhill the body's weight makes some flat-foot windows short or the hip's progress
    # over the foot uneven, and the estimator says so rather than claim what it did not see
    assert sum(e.speed_confident and e.incline_confident for e in settled) >= len(settled) / 2


def test_a_still_foot_on_its_toe_is_not_read_as_the_slope():
    """Synthetic strides: the same still foot, its centre of pressure at the forefoot throughout (the heel up), gives
    no reading when the forefoot's distance is known, and is read as foot-flat without it (the earlier behaviour)."""
    on_toe = scripted_walk(1.2, -3.0, moment_Nm=-0.125 * 700.0)            # 0.125 m ahead: past 0.8 × 0.13 m
    knowing = run(TaskEstimator(THIGH_M, SHANK_M, forefoot_m=0.13), on_toe)
    assert knowing and all(not e.stride.valid and not e.incline_confident for e in knowing)
    blind = run(TaskEstimator(THIGH_M, SHANK_M), on_toe)
    assert blind[-1].incline_deg == pytest.approx(-3.0, abs=0.1) and blind[-1].incline_confident
    flat = run(TaskEstimator(THIGH_M, SHANK_M, forefoot_m=0.13), scripted_walk(1.2, -3.0))    # 0.07 m: heel down
    assert flat[-1].incline_deg == pytest.approx(-3.0, abs=0.1) and flat[-1].incline_confident
    with pytest.raises(ValueError, match="heel_off_fraction"):
        TaskEstimator(THIGH_M, SHANK_M, forefoot_m=0.13, heel_off_fraction=1.5)
