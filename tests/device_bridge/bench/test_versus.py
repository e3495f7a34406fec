"""The one comparison of two walks, at one task and over a course."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from controller_core.gait_metrics import GAIT_CHANNELS, PHASE_GRID
from device_bridge.bench.versus import against_fsmic, mean_difference, versus
from device_bridge.sim.course_walk import CourseScore
from device_bridge.sim.simulate import WalkScore


def _synthetic_walk(offset: float, noise: float, seed: int) -> WalkScore:
    """Synthetic strides (for this test only): a sine reference and 30 strides offset from it, with noise."""
    rng = np.random.default_rng(seed)
    ref = {c: 10.0 * np.sin(2 * np.pi * PHASE_GRID) for c in GAIT_CHANNELS}
    strides = {c: ref[c][None] + offset + noise * rng.standard_normal((30, PHASE_GRID.size)) for c in GAIT_CHANNELS}
    return WalkScore(summary={}, mean_curves={c: s.mean(axis=0) for c, s in strides.items()}, reference_curves=ref,
                     stride_curves=strides)


def test_a_clearly_closer_walk_is_lower_and_an_equal_one_is_not_resolved():
    close, far = _synthetic_walk(0.5, 0.3, 1), _synthetic_walk(3.0, 0.3, 2)
    rows = versus(close, far, "close", "far")
    for channel in GAIT_CHANNELS:
        d = rows[channel]
        assert d["rmse_difference"] == pytest.approx(-2.5, abs=0.1)
        assert d["ci95"][0] < d["rmse_difference"] < d["ci95"][1] < 0.0 and d["verdict"] == "close lower"
    assert versus(far, close, "far", "close")["knee_angle_deg"]["verdict"] == "close lower"
    same = versus(close, _synthetic_walk(0.5, 0.3, 3), "a", "b")["knee_angle_deg"]
    assert same["ci95"][0] < 0.0 < same["ci95"][1] and same["verdict"] == "not resolved"


def test_a_channel_with_fewer_than_two_strides_is_not_judged():
    close, far = _synthetic_walk(0.5, 0.3, 1), _synthetic_walk(3.0, 0.3, 2)
    one = dataclasses.replace(far, stride_curves={c: s[:1] for c, s in far.stride_curves.items()})
    assert versus(close, one, "a", "b")["knee_angle_deg"] == {"rmse_difference": None, "ci95": None, "verdict": None}


def test_course_walks_compare_their_per_stride_errors():
    rng = np.random.default_rng(0)
    low = CourseScore(summary={}, stride_rmse={c: 2.0 + 0.2 * rng.standard_normal(40) for c in GAIT_CHANNELS})
    high = CourseScore(summary={}, stride_rmse={c: 4.0 + 0.2 * rng.standard_normal(40) for c in GAIT_CHANNELS})
    d = versus(low, high, "adaptive", "fsmic")["ankle_angle_deg"]
    assert d["rmse_difference"] == pytest.approx(low.stride_rmse["ankle_angle_deg"].mean()
                                                 - high.stride_rmse["ankle_angle_deg"].mean())
    assert d["verdict"] == "adaptive lower" and d["ci95"][1] < 0.0
    assert mean_difference(np.array([1.0]), np.array([2.0, 3.0]))["verdict"] is None
    with pytest.raises(TypeError, match="same kind"):
        versus(low, _synthetic_walk(0.0, 0.1, 0), "a", "b")


def test_learned_against_fsmic_on_the_bench_names_each_difference_in_flat_keys(quasi_stiffness_walk, fsmic_walk):
    learned, fsmic = quasi_stiffness_walk[1], fsmic_walk[1]
    v = against_fsmic(learned, fsmic)
    d = v["ankle_angle_rmse_difference_deg"]
    assert d == pytest.approx(learned.summary["ankle_angle_rmse_deg"] - fsmic.summary["ankle_angle_rmse_deg"])
    lo, hi = v["ankle_angle_rmse_difference_ci95_deg"]
    expected = "learned lower" if hi < 0 else "FSMIC lower" if lo > 0 else "not resolved"
    assert lo <= d <= hi and v["ankle_angle_verdict"] == expected
    assert set(v) >= {"knee_angle_verdict", "knee_moment_rmse_difference_Nm_per_kg",
                      "ankle_moment_rmse_difference_ci95_Nm_per_kg"}
    assert against_fsmic(learned, dataclasses.replace(fsmic, stride_curves={}))["knee_angle_verdict"] is None
