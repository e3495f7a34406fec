"""Features measured on recorded strides. The strides here are synthetic curves (raised-cosine bumps), made up to
have a known peak where the test says."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.gait_metrics import PHASE_GRID
from controller_core.stride_features import measure_stride, measure_strides, toe_off_phases


def _bump(centre: float, width: float, height: float) -> np.ndarray:
    x = np.clip((PHASE_GRID - centre) / width, -1.0, 1.0)
    return height * 0.5 * (1.0 + np.cos(math.pi * x))


def _stride(stance_peak_deg: float = 18.0, swing_peak_deg: float = 62.0, swing: bool = True) -> dict[str, np.ndarray]:
    knee = 3.0 + _bump(0.15, 0.12, stance_peak_deg - 3.0)
    if swing:
        knee = knee + _bump(0.72, 0.2, swing_peak_deg - 3.0)
    else:   # a knee that keeps flexing through the swing window: no interior peak there
        knee = knee + np.where(PHASE_GRID > 0.5, 100.0 * (PHASE_GRID - 0.5), 0.0)
    ankle = 2.0 + _bump(0.45, 0.12, 8.0) - _bump(0.64, 0.07, 20.0)
    return {"knee_angle_deg": knee, "ankle_angle_deg": ankle,
            "knee_moment_Nm_per_kg": -_bump(0.12, 0.1, 0.6) + _bump(0.9, 0.08, 0.3),
            "ankle_moment_Nm_per_kg": _bump(0.05, 0.05, 0.2) - _bump(0.5, 0.15, 1.5)}


def test_a_stride_with_a_known_peak_gives_it_back():
    found, missing = measure_stride(_stride(stance_peak_deg=21.0, swing_peak_deg=64.0))
    phase, value = found["knee_stance_flexion_peak"]
    assert phase == pytest.approx(0.15, abs=0.01) and math.degrees(value) == pytest.approx(21.0, abs=0.1)
    phase, value = found["knee_swing_flexion_peak"]
    assert phase == pytest.approx(0.72, abs=0.01) and math.degrees(value) == pytest.approx(64.0, abs=0.3)
    phase, value = found["ankle_plantarflexion_peak"]
    assert phase == pytest.approx(0.64, abs=0.01) and math.degrees(value) == pytest.approx(-18.0, abs=0.5)
    assert "knee_swing_flexion_peak" not in missing


def test_a_stride_without_a_peak_is_counted_not_guessed():
    found, missing = measure_stride(_stride(swing=False))
    assert "knee_swing_flexion_peak" not in found
    assert "monotonic" in missing["knee_swing_flexion_peak"]
    strides, not_found = measure_strides({k: np.stack([v, _stride()[k]]) for k, v in _stride(swing=False).items()},
                                         [(1.2, 0.0), (1.2, 0.0)])
    assert not_found["knee_swing_flexion_peak"] == 1
    assert "knee_swing_flexion_peak" not in strides[0].features and "knee_swing_flexion_peak" in strides[1].features


def test_a_stride_without_a_task_or_off_the_table_is_left_out():
    curves = {k: np.stack([v, v, v]) for k, v in _stride().items()}
    strides, _ = measure_strides(curves, [(1.0, 0.0), None, (1.4, 5.0)], use=[True, True, False])
    assert [(s.speed_mps, s.incline_deg) for s in strides] == [(1.0, 0.0)]


def test_a_missing_channel_or_a_broken_curve_says_why():
    curves = _stride()
    curves.pop("ankle_moment_Nm_per_kg")
    curves["knee_angle_deg"] = curves["knee_angle_deg"].copy()
    curves["knee_angle_deg"][40] = np.nan
    found, missing = measure_stride(curves)
    assert "no ankle_moment_Nm_per_kg channel" in missing["ankle_plantarflexor_moment_peak"]
    assert "not a finite curve" in missing["knee_stance_flexion_peak"]
    assert "ankle_plantarflexion_peak" in found


def test_toe_off_is_where_the_load_first_falls_after_the_loading_response():
    t = np.arange(0, 3.0, 0.01)
    load = np.where((t % 1.0) < 0.62, 700.0, 0.0)
    load[(t % 1.0 > 0.05) & (t % 1.0 < 0.07)] = 50.0       # a ring at contact: not a toe-off
    strikes = np.array([0, 100, 200])
    assert toe_off_phases(load, strikes, 75.0) == pytest.approx([0.62, 0.62], abs=0.011)
