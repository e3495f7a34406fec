"""The bench against the people it imitates: the reference's own joint angles keep the hip on its path."""

from __future__ import annotations

import pytest

from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.calibration import (
    DEFICIT_MEAN_TOLERANCE_BW,
    DEFICIT_TOLERANCE_BW,
    HIP_TOLERANCE_MM,
    calibration_walk,
)


@pytest.mark.parametrize(("speed", "incline"), [(1.2, 0.0), (1.95, 5.0)])
def test_the_reference_angles_keep_the_hip_on_its_path_with_little_help(speed, incline):
    r = calibration_walk(task_reference(speed, incline, None, 75.0), seconds=6.0)
    assert -HIP_TOLERANCE_MM <= r["hip_error_stance_min_mm"] <= r["hip_error_stance_max_mm"] <= HIP_TOLERANCE_MM
    assert r["support_deficit_max_bw"] <= DEFICIT_TOLERANCE_BW
    assert r["support_deficit_mean_bw"] <= DEFICIT_MEAN_TOLERANCE_BW
    assert r["hip_error_rms_mm"] < 25.0
