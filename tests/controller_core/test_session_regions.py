"""Time, strides and errors per envelope region from an adaptive leg's task telemetry (scripted telemetry)."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.gait_metrics import PHASE_GRID, reference_curves
from controller_core.session_regions import errors_by_region, region_index, task_regions
from controller_core.walking_reference import level_walking_reference

SPEEDS, INCLINES = [0.8, 1.2, 1.6], [-10.0, 0.0, 10.0]


def test_a_task_belongs_to_its_nearest_node_and_beyond_the_grid_to_the_edge():
    assert region_index(np.array([0.5, 0.99, 1.01, 1.2, 1.41, 2.5, np.nan]), SPEEDS).tolist() == [0, 0, 1, 1, 2, 2, -1]


def test_time_and_strides_per_region_count_only_estimated_samples():
    t = np.arange(600) * 0.01                               # 6 s at 100 Hz, a strike every 1 s
    strikes = np.arange(0, 600, 100)
    speed = np.full(600, np.nan)
    incline = np.full(600, np.nan)
    speed[100:300], incline[100:300] = 1.25, 0.5            # 2 s near 1.2 m/s, level
    speed[300:], incline[300:] = 1.7, 12.0                  # 3 s beyond the grid: the 1.6 m/s, +10° corner
    out = task_regions(t, speed, incline, strikes, SPEEDS, INCLINES)
    assert out["time_s"][1][1] == pytest.approx(2.0) and out["time_s"][2][2] == pytest.approx(3.0)
    assert out["unestimated_s"] == pytest.approx(1.0) and out["outside_s"] == pytest.approx(3.0)
    assert out["strides"][1][1] == 2 and out["strides"][2][2] == 2 and out["unestimated_strides"] == 1
    assert sum(map(sum, out["strides"])) + out["unestimated_strides"] == strikes.size - 1


def test_a_stride_walked_like_the_reference_at_its_task_scores_zero_and_another_does_not():
    ref = level_walking_reference(1.2)
    curves = reference_curves(ref)
    strides = {c: np.stack([curves[c], curves[c] + 3.0]) for c in ("knee_angle_deg", "ankle_angle_deg")}
    per_stride = [{"speed_mps": 1.2, "incline_deg": 0.0, "region": (1, 1)},
                  {"speed_mps": 1.2, "incline_deg": 0.0, "region": (1, 1)}]
    out = errors_by_region(strides, per_stride, (3, 3), lambda v, g: level_walking_reference(v))
    assert out["strides_scored"][1][1] == 2 and out["strides_scored"][0][0] == 0
    assert out["knee_angle_per_stride_rmse_deg"][1][1] == pytest.approx(1.5, abs=1e-3)   # (0 + 3) / 2
    assert out["ankle_angle_per_stride_rmse_deg"][0][0] is None
    assert out["overall"] == {"strides": 2, "knee_angle_per_stride_rmse_deg": pytest.approx(1.5, abs=1e-3),
                              "ankle_angle_per_stride_rmse_deg": pytest.approx(1.5, abs=1e-3)}
    only_first = errors_by_region(strides, per_stride, (3, 3), lambda v, g: level_walking_reference(v),
                                  scored=[True, False])          # the second stride was walked in safe mode
    assert only_first["overall"]["strides"] == 1 and only_first["overall"]["knee_angle_per_stride_rmse_deg"] == 0.0
    assert PHASE_GRID.size == strides["knee_angle_deg"].shape[1]


def test_walking_at_the_edge_within_the_estimates_resolution_is_not_beyond_it():
    t = np.arange(300) * 0.01
    speed, incline = np.full(300, 1.6), np.full(300, 10.0)     # exactly the 1.6 m/s, +10° corner
    speed[150:], incline[150:] = 1.68, 11.2                    # a little beyond, within ±0.1 m/s, ±1.5°
    out = task_regions(t, speed, incline, np.arange(0, 300, 100), SPEEDS, INCLINES)
    assert out["outside_s"] == 0.0 and out["time_s"][2][2] == pytest.approx(3.0)
    incline[250:] = 12.0                                        # 0.5 s clearly beyond the incline edge
    assert task_regions(t, speed, incline, np.arange(0, 300, 100), SPEEDS, INCLINES)["outside_s"] == pytest.approx(0.5)


def test_the_headline_scores_each_stride_at_its_own_task_and_says_when_strides_are_too_few():
    """Scripted telemetry (synthetic: strides drawn exactly as the references at 0.85 and 1.6 m/s): against each
    stride's own task the error is nearly nothing; against the first task's reference alone, the fast strides look
    several degrees wrong, which is what a course's report used to headline."""
    from controller_core.session_regions import own_task_errors

    tasks = [(0.85, 0.0)] * 4 + [(1.6, 0.0)] * 4
    curves = {task: reference_curves(level_walking_reference(task[0])) for task in set(tasks)}
    knee = np.concatenate([np.radians(curves[task]["knee_angle_deg"][:-1]) for task in tasks] + [np.zeros(1)])
    ankle = np.concatenate([np.radians(curves[task]["ankle_angle_deg"][:-1]) for task in tasks] + [np.zeros(1)])
    strikes = np.arange(0, len(tasks) * (PHASE_GRID.size - 1) + 1, PHASE_GRID.size - 1)
    own = own_task_errors(knee, ankle, strikes, tasks, lambda v, g: level_walking_reference(v), "each stride's task")
    first = own_task_errors(knee, ankle, strikes, [tasks[0]] * len(tasks), lambda v, g: level_walking_reference(v),
                            "the first task")
    assert own["strides_scored"] == 8 and own["enough_strides"] and own["against"] == "each stride's task"
    assert own["knee_angle_rmse_deg"] < 1.0 and own["ankle_angle_rmse_deg"] < 1.0
    assert first["knee_angle_rmse_deg"] > own["knee_angle_rmse_deg"] + 1.0
    few = own_task_errors(knee, ankle, strikes, tasks[:3] + [None] * 5, lambda v, g: level_walking_reference(v), "x")
    assert few["strides_scored"] == 3 and not few["enough_strides"] and few["min_strides"] == 5
