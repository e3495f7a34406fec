"""Walking a course: the adaptive leg on the course's floor, each stride scored against its own task."""

from __future__ import annotations

import numpy as np
import pytest

from device_bridge.sim.course import Course, Segment
from device_bridge.sim.course_walk import mean_interval
from device_bridge.sim.leg_model import LegGeometry

SHORT = Course("short-ramp", (Segment(6.0, 1.0, 0.0), Segment(12.0, 1.1, 6.0)), transition_s=2.0)


def test_a_mean_interval_needs_two_strides_and_contains_the_mean():
    rng = np.random.default_rng(0)
    values = np.array([1.0, 2.0, 3.0, 4.0])
    lo, hi = mean_interval(values, rng)
    assert lo < values.mean() < hi and lo >= 1.0 and hi <= 4.0
    assert mean_interval(np.array([1.0]), rng) is None


@pytest.fixture(scope="module")
def adaptive_walk(model):
    from device_bridge.bench.controllers import make_controller
    from device_bridge.sim.course_walk import run_course, score_course

    env = model.propose_envelope([0.8, 1.1, 1.4], [-8.0, 0.0, 8.0], 75.0, nominal=(1.1, 0.0))
    ctrl = make_controller("adaptive", 75.0, model, envelope=env, geometry=LegGeometry())
    changes: list[tuple[int, int]] = []
    step = ctrl.step

    def recording_step(x):   # which state the machine was in, and entered, whenever its rows changed
        before, schedule = ctrl.machine_.state_, ctrl.machine_.schedule
        cmd = step(x)
        if ctrl.machine_.schedule is not schedule:
            changes.append((int(before), int(cmd.state)))
        return cmd

    ctrl.step = recording_step
    log, traj = run_course(ctrl, SHORT, 75.0, start="standing")   # a person stands, then walks the course
    return ctrl, changes, score_course(log, traj, SHORT, ctrl.decisions_)


def test_the_adaptive_leg_follows_the_ramp_changing_rows_at_heel_strike_and_within_the_stride(adaptive_walk):
    """Rows change at heel strike (swing → stance flexion) and, on the ramp, within a stance once its own foot-flat
    slope is read (the state going on: its own row is left as it is, controller_core/adaptive.py)."""
    ctrl, changes, score = adaptive_walk
    s = score.summary
    assert s["falls"] == 0 and s["toe_catches"] == 0 and s["loaded_swing_ms_max_stride"] <= 20.0
    at_heel_strike = [(b, a) for b, a in changes if a == 0 and b in (2, 3)]
    within = [(b, a) for b, a in changes if (b, a) not in at_heel_strike]
    assert at_heel_strike and within and all(b == a and a in (0, 1) for b, a in within)
    last = ctrl.decisions_[-1]
    assert last.mode == "adaptive" and last.incline_deg == pytest.approx(6.0, abs=1.5)
    assert last.speed_mps == pytest.approx(1.1, abs=0.1)
    e = s["estimation"]
    assert e["strides_counted"] >= 8 and e["incline_within_1_5_deg_fraction"] >= 0.9
    assert e["speed_within_0_1_mps_fraction"] >= 0.8


def test_the_first_strides_after_the_change_are_scored_apart_from_the_rest(adaptive_walk):
    """The ramp's first three strides (the leg crossing the change) and the rest: every stride in one of the two,
    each part's mean the mean of its strides' RMSEs, and a part of the walk keeps only its strides."""
    _, _, score = adaptive_walk
    s, seg, after = score.summary, score.stride_segments, score.stride_after_change
    assert after.sum() == 3 and np.all(seg[after] == 1) and np.all(np.flatnonzero(after) == np.flatnonzero(seg == 1)[:3])
    assert s["after_change"]["strides"] + s["between_changes"]["strides"] == s["strides"]
    knee = score.stride_rmse["knee_angle_deg"]
    assert s["after_change"]["knee_angle_rmse_deg"] == pytest.approx(knee[after].mean())
    assert s["between_changes"]["knee_angle_rmse_deg"] == pytest.approx(knee[~after].mean())
    part = score.only(after)
    assert part.stride_rmse["knee_angle_deg"].tolist() == knee[after].tolist() and part.stride_after_change.all()


def test_a_course_walked_from_standing_stands_first_and_needs_a_first_segment_to_start_in():
    """The course's first second is quiet standing on its first floor (the hip still, the foot loaded); a course whose
    first segment is too short to stand and take the first steps in is refused, saying why."""
    from device_bridge.sim.course_walk import course_leg

    traj, _, (knee0, _) = course_leg(SHORT, 75.0, start="standing")
    still = traj.bench.time_s < 1.0
    assert np.ptp(traj.bench.x_m[still]) == 0 and traj.bench.stance[still].all() and knee0 == pytest.approx(
        np.radians(3.0))
    assert np.mean(traj.bench.xd_m_s[traj.bench.time_s > 3.0]) > 0.9          # walking by then
    brief = Course("brief", (Segment(1.2, 1.0, 0.0), Segment(6.0, 1.0, 0.0)))
    with pytest.raises(ValueError, match=r"first segment lasts 1\.2 s"):
        course_leg(brief, 75.0, start="standing")
    with pytest.raises(ValueError, match="start must be"):
        course_leg(SHORT, 75.0, start="running")


def test_a_course_fall_says_its_segment_and_what_the_leg_was_running():
    """Synthetic channels (said so): the hip sinks past the fall line at 7 s, in the course's second segment, after a
    heel strike at which the adaptive leg ran 1.1 m/s +6° on an estimate of 1.08 m/s +5.5°."""
    from controller_core.adaptive import StrideDecision
    from controller_core.task_estimator import TaskEstimate
    from device_bridge.sim.course_walk import course_fall_events

    n, dt = 10_000, 0.001
    c = {"time_s": np.arange(n) * dt, "hip_height_error_m": np.zeros(n), "knee_angle_rad": np.zeros(n),
         "load_N": np.zeros(n), "state": np.zeros(n), "bench_phase": np.zeros(n)}
    c["hip_height_error_m"][7000:7300] = -0.2
    est = TaskEstimate(time_s=6.8, speed_mps=1.08, incline_deg=5.5, speed_confidence=0.9, incline_confidence=0.9,
                       speed_confident=True, incline_confident=True, stride=None)
    decisions = [StrideDecision(6.8, est, 1.08, 5.5, 1.1, 6.0, "adaptive")]
    (event,) = course_fall_events(c, 735.0, 200, SHORT, decisions)
    assert event["time_s"] == pytest.approx(7.0) and event["segment"] == 1 and event["why"] == "the hip sank"
    assert (event["running_speed_mps"], event["running_incline_deg"], event["mode"]) == (1.1, 6.0, "adaptive")
    assert (event["estimate_speed_mps"], event["estimate_incline_deg"]) == (1.08, 5.5)


def test_each_stride_is_scored_against_its_own_task(adaptive_walk):
    _, _, score = adaptive_walk
    tasks, segments = score.stride_tasks, score.stride_segments
    assert tasks.shape[0] == score.summary["strides"] == score.stride_rmse["knee_angle_deg"].shape[0]
    assert np.allclose(tasks[0], [1.0, 0.0]) and np.all(tasks[-3:, 1] == pytest.approx(6.0))
    assert np.all(np.diff(tasks[:, 1]) >= -1e-9)     # a stride across the change gets the mean of what it walked
    assert np.any((tasks[:, 1] > 0.05) & (tasks[:, 1] < 5.95))
    by_segment = score.summary["by_segment"]
    assert [b["strides"] for b in by_segment] == [int(np.sum(segments == k)) for k in range(2)]
    lo, hi = score.summary["knee_angle_rmse_ci95_deg"]
    assert lo <= score.summary["knee_angle_rmse_deg"] <= hi


def test_a_one_task_course_walks_exactly_as_the_fixed_task_bench(model):
    """The course's floor and socket path change nothing where the task does not change (a height field once did).

    The paths are the same to rounding; the walks then agree until rounding differences, which a body carried by a
    leg amplifies (a late heel strike one stride, an early one the next), have grown: compared over the first 2 s
    (standing, the first steps and a stride)."""
    from controller_core.fsm import ImpedanceSchedule, StateMachineController
    from device_bridge.sim.bench_trajectory import plan_standing_start
    from device_bridge.sim.course import task_pattern
    from device_bridge.sim.course_walk import run_course
    from device_bridge.sim.leg_model import LegGeometry
    from device_bridge.sim.simulate import run_walk

    table = model.propose(1.2, 5.0, 75.0).table
    course = Course("one-task", (Segment(6.0, 1.2, 5.0),))
    log_course, traj = run_course(StateMachineController(ImpedanceSchedule.from_table(table)), course, 75.0)
    fixed = plan_standing_start(task_pattern(1.2, 5.0), LegGeometry(), 75.0, 6.0)     # both start from standing
    for name in ("x_m", "z_m", "hip_rad", "xd_m_s", "zd_m_s", "hipd_rad_s"):
        np.testing.assert_allclose(getattr(traj.bench, name), getattr(fixed, name), atol=1e-9)
    np.testing.assert_allclose(traj.bench.other_leg_N, fixed.other_leg_N, atol=1e-6)
    log_fixed = run_walk(StateMachineController(ImpedanceSchedule.from_table(table)), task_pattern(1.2, 5.0), 75.0, 6.0)
    first = slice(0, 2000)
    for channel in ("knee_angle_rad", "ankle_angle_rad"):
        np.testing.assert_allclose(log_course.channels[channel][first], log_fixed.channels[channel][first], atol=1e-4)
    settled = slice(100, 2000)   # the standing foot's first contacts settle differently on a height field and a plane
    np.testing.assert_allclose(log_course.channels["contact_N"][settled], log_fixed.channels["contact_N"][settled],
                               rtol=1e-3, atol=0.5)
    np.testing.assert_array_equal(log_course.channels["state"][first], log_fixed.channels["state"][first])
