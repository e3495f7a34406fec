"""The leave-one-ramp-condition-out evaluation of the change from level walking."""

from __future__ import annotations

import numpy as np

from controller_core.feature_model import FeatureModel
from controller_core.phase_table import load_shipped_ramps
from lab.evaluation import evaluate_incline, format_incline_report


def test_each_slope_held_out_is_scored_against_ignoring_incline_and_linear_interpolation(reference):
    report = evaluate_incline(reference, load_shipped_ramps(), feature_model=FeatureModel(n_restarts=0))   # quick fits
    assert [f["incline_deg"] for f in report["folds"]] == [-10.0, 10.0]
    for fold in report["folds"]:
        for channel, r in fold["rmse"].items():
            assert set(r) == {"model", "ignore_incline", "linear"} and all(np.isfinite(list(r.values())))
            assert fold["ratio_to_ignore_incline"][channel]["ignore_incline"] == 1.0
    # with one side held out only the published points know it: the uphill knee is far from predicted
    up_knee = report["folds"][1]["rmse"]["knee_angle_deg"]
    assert up_knee["ignore_incline"] > 10.0
    assert "held out" in format_incline_report(report)
