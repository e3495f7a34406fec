"""The bench's calibration over a grid: one row per task, each judged on the stated tolerances."""

from __future__ import annotations

from lab.bench_calibration import calibrate, format_calibration


def test_each_task_of_the_grid_is_walked_and_judged_on_the_tolerances():
    rows = calibrate((1.2,), (0.0, 5.0), seconds=5.0)
    assert [(r["speed_mps"], r["incline_deg"]) for r in rows] == [(1.2, 0.0), (1.2, 5.0)]
    assert all(r["within"] for r in rows)
    worse = [{**rows[0], "hip_error_stance_max_mm": 75.0, "within": False}]
    assert "| NO |" in format_calibration(worse) and "| yes |" in format_calibration(rows)
