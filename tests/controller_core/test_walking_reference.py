"""The walking reference at a speed, from the shipped records."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.reference import load_shipped_reference
from controller_core.walking_reference import level_walking_reference, sloped_walking_reference


def test_walking_reference_reproduces_a_record_and_interpolates_between_two():
    ref_set = load_shipped_reference()
    rec = min(ref_set.records, key=lambda r: abs(r.task["speed_mps"] - 1.49))
    at = level_walking_reference(rec.task["speed_mps"])
    np.testing.assert_allclose(at.knee_angle_rad, rec.mean["knee_angle"], atol=1e-6)
    np.testing.assert_allclose(at.ankle_angle_rad, rec.mean["ankle_angle"], atol=1e-6)
    mid = level_walking_reference(1.7)
    fast = level_walking_reference(1.95)
    assert not mid.extrapolation and level_walking_reference(2.5).extrapolation
    assert at.stride_time_s > mid.stride_time_s > fast.stride_time_s     # faster walking, shorter strides
    with pytest.raises(ValueError, match="speed_mps"):
        level_walking_reference(float("nan"))


def test_on_a_slope_the_reference_is_the_measured_ramp_trend_where_the_ramps_reach():
    level = level_walking_reference(1.2)
    up = sloped_walking_reference(1.2, 8.0)
    assert up.kind == "measured_ramp_trend" and "scaled to +8°" in up.source and "Vielemeyer 2025" in up.source
    assert np.degrees(up.knee_angle_rad[0] - level.knee_angle_rad[0]) > 15    # lands flexed
    assert np.degrees(up.hip_angle_rad[0] - level.hip_angle_rad[0]) > 5       # the hip too: the socket follows it
    np.testing.assert_allclose(up.vgrf_bw, level.vgrf_bw)                      # no ground forces on the ramps
    assert sloped_walking_reference(1.2, 0.0).kind == "measured"
    assert sloped_walking_reference(1.2, -12.0) is None                        # steeper than any measured ramp
