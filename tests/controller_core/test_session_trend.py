"""A patient's sessions per day (scripted session summaries)."""

from __future__ import annotations

import pytest

from controller_core.session_trend import session_trend


def _session(day: str, strides: int, knee: float, speed: float = 1.2, incline: float = 0.0, adaptive=None) -> dict:
    summary = {"strides": strides, "strides_scored": strides, "duration_s": strides * 1.1,
               "cadence_steps_per_min": 100.0 + strides, "knee_angle_rmse_deg": knee, "ankle_angle_rmse_deg": 5.0}
    if adaptive is not None:
        summary["adaptive"] = {"task_class_time_s": adaptive}
    return {"started_at": f"{day}T10:00:00Z", "task": {"speed_mps": speed, "incline_deg": incline}, "summary": summary}


def test_days_weigh_sessions_by_strides_and_sum_time_per_task_class():
    uphill_fast = [[0, 0, 0], [0, 0, 0], [0, 3.0, 7.0]]
    sessions = [_session("2026-11-23", 10, 4.0), _session("2026-11-23", 30, 8.0, speed=0.8, incline=-6.0),
                _session("2026-11-24", 20, 6.0, adaptive=uphill_fast),
                {"started_at": "2026-11-24T11:00:00Z", "task": {"speed_mps": 1.0, "incline_deg": 0.0}, "summary": None}]
    first, second = session_trend(sessions)
    assert (first["day"], first["sessions"], first["strides"]) == ("2026-11-23", 2, 40)
    assert first["knee_angle_rmse_deg"] == pytest.approx((10 * 4.0 + 30 * 8.0) / 40)
    assert first["time_by_task_class_s"]["moderate_level"] == pytest.approx(11.0)
    assert first["time_by_task_class_s"]["slow_downhill"] == pytest.approx(33.0)
    assert second["sessions"] == 1                                     # a session still recording is not counted
    assert second["time_by_task_class_s"]["fast_uphill"] == 7.0 and second["time_by_task_class_s"]["fast_level"] == 3.0


def test_a_day_reads_each_sessions_headline_errors_where_it_has_them():
    """A course session's stride-mean error at its first task (12°) is not what the day shows: its headline, each
    stride at its own task (3°), weighted by the strides that headline scored."""
    course = _session("2026-11-25", 20, 12.0)
    course["summary"]["headline"] = {"knee_angle_rmse_deg": 3.0, "ankle_angle_rmse_deg": 4.0, "strides_scored": 18,
                                     "enough_strides": True, "min_strides": 5, "against": "each stride's own task"}
    [day] = session_trend([course, _session("2026-11-25", 6, 9.0)])
    assert day["knee_angle_rmse_deg"] == pytest.approx((18 * 3.0 + 6 * 9.0) / 24)
