"""The varying-task course: its schedule, its terrain, and how it is named or read from a file."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from device_bridge.sim.course import COURSES, Course, Segment, load_course, plan_course_trajectory
from device_bridge.sim.leg_model import LegGeometry

SHORT = Course("short-ramp", (Segment(6.0, 1.0, 0.0), Segment(12.0, 1.1, 6.0)), transition_s=2.0)


def test_the_task_changes_smoothly_from_segment_to_segment():
    t = np.arange(0.0, SHORT.duration_s, 0.01)
    speed, incline = SHORT.task_at(t)
    assert SHORT.change_times_s == (6.0,)
    assert speed[0] == 1.0 and incline[0] == 0.0 and speed[-1] == pytest.approx(1.1) and incline[-1] == 6.0
    assert np.max(np.abs(np.diff(incline))) < 6.0 * 0.01 * math.pi / 2 / 2.0 + 1e-9   # raised cosine: no jump
    assert incline[round(7.0 / 0.01)] == pytest.approx(3.0, abs=0.05)                 # half-way through the change
    assert SHORT.segment_index(5.9) == 0 and SHORT.segment_index(6.5) == 1


def test_the_terrain_has_the_course_s_slope_under_the_socket():
    traj = plan_course_trajectory(SHORT, LegGeometry(), 75.0)
    x = traj.terrain.x0_m + traj.terrain.step_m * np.arange(traj.terrain.z_m.size)
    ramp = (x > traj.bench.x_m[round(10.0 / 0.001)]) & (x < traj.bench.x_m[-1] - 1.0)
    slope = np.degrees(np.arctan(np.gradient(traj.terrain.z_m[ramp], traj.terrain.step_m)))
    assert np.allclose(slope, 6.0, atol=0.05)
    assert abs(traj.incline_deg[round(3.0 / 0.001)]) < 1e-12 and traj.speed_mps[-1] == pytest.approx(1.1)


@pytest.mark.parametrize(("segments", "why"), [
    ((Segment(5.0, 1.0, 0.0), Segment(1.0, 1.0, 5.0)), "shorter"),
    ((Segment(5.0, 1.0, 0.0), Segment(5.0, 1.0, 14.0)), "steeper"),
    ((Segment(5.0, -1.0, 0.0),), "speed"),
    ((Segment(float("nan"), 1.0, 0.0),), "duration"),
])
def test_a_course_that_cannot_be_walked_is_refused(segments, why):
    with pytest.raises(ValueError, match=why):
        Course("bad", segments)


def test_courses_come_by_name_or_from_a_file(tmp_path):
    assert load_course("mixed") is COURSES["mixed"]
    path = tmp_path / "c.json"
    path.write_text(json.dumps(SHORT.to_json()))
    assert load_course(path) == SHORT
    with pytest.raises(ValueError, match="unknown course"):
        load_course("moon")
    path.write_text('{"segments": [{"duration_s": 5}]}')
    with pytest.raises(ValueError, match="course file"):
        load_course(path)


def test_a_course_walked_for_a_given_time_is_cut_short_or_walked_again():
    mixed = load_course("mixed")
    short = mixed.lasting(30.0)
    assert short.duration_s == pytest.approx(30.0) and short.segments[:2] == mixed.segments[:2]
    longer = mixed.lasting(mixed.duration_s + 20.0)
    assert longer.duration_s == pytest.approx(mixed.duration_s + 20.0)
    assert longer.segments[len(mixed.segments)].speed_mps == mixed.segments[0].speed_mps
    assert mixed.lasting(11.0).segments == (mixed.segments[0],)   # a last piece shorter than a transition is dropped
    with pytest.raises(ValueError, match="seconds"):
        mixed.lasting(-1.0)


def test_the_frequent_course_changes_task_every_six_to_eight_seconds():
    """The public course where an adaptive leg is worst (issue 56): a change every 6-8 s, 1.5 s each, speed and
    slope within the data's range, and it plans a walk."""
    c = load_course("frequent")
    assert c.transition_s == 1.5 and len(c.segments) >= 8
    assert all(6.0 <= s.duration_s <= 8.0 for s in c.segments)
    assert {s.incline_deg > 0 for s in c.segments} == {True, False} and min(s.speed_mps for s in c.segments) < 0.8
    tasks = [(s.speed_mps, s.incline_deg) for s in c.segments]
    assert all(a != b for a, b in itertools.pairwise(tasks))           # every boundary changes the task
    traj = plan_course_trajectory(c, LegGeometry(), 75.0)
    assert traj.speed_mps.shape == traj.incline_deg.shape and traj.bench.time_s[-1] >= c.duration_s - 0.01
