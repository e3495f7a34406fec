"""The learned-against-FSMIC comparison and its verdicts."""

from __future__ import annotations

import dataclasses

import pytest

from backend.experiments.comparison import against_fsmic


def test_learned_against_fsmic_reports_each_difference_with_an_interval_and_a_verdict(quasi_stiffness_walk, fsmic_walk):
    learned, fsmic = quasi_stiffness_walk[1], fsmic_walk[1]
    v = against_fsmic(learned, fsmic)
    d = v["ankle_angle_rmse_difference_deg"]
    assert d == pytest.approx(learned.summary["ankle_angle_rmse_deg"] - fsmic.summary["ankle_angle_rmse_deg"])
    lo, hi = v["ankle_angle_rmse_difference_ci95_deg"]
    assert lo <= hi
    expected = "learned lower" if hi < 0 else "FSMIC lower" if lo > 0 else "not resolved"
    assert v["ankle_angle_verdict"] == expected
    assert set(v) >= {"knee_angle_verdict", "knee_moment_rmse_difference_Nm_per_kg",
                      "ankle_moment_rmse_difference_ci95_Nm_per_kg"}
    assert against_fsmic(learned, dataclasses.replace(fsmic, stride_curves={}))["knee_angle_verdict"] is None
