"""The feature model: task → target features with their uncertainty."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.feature_model import FeatureModel, InclinePoint, incline_points, published_se
from controller_core.features import FEATURES
from controller_core.incline import InclineChange
from controller_core.phase_table import load_shipped_ramps
from controller_core.published_features import PublishedPoint
from controller_core.reference import level_curves_at


def test_one_task_and_many_tasks_give_the_same_features(model):
    fm = model.feature_model_
    tasks = np.array([[0.9, -4.0], [1.4, 0.0], [2.2, 7.5]])
    many = fm.predict_many(tasks)
    for task, batch in zip(tasks, many, strict=True):
        one = fm.predict(*task)
        assert [f.spec.name for f in one] == [f.name for f in FEATURES]
        for a, b in zip(one, batch, strict=True):
            assert a.value == pytest.approx(b.value, abs=1e-12) and a.std == pytest.approx(b.std, abs=1e-12)
            assert a.phase == pytest.approx(b.phase, abs=1e-12) and a.extrapolation == b.extrapolation


def test_the_std_grows_away_from_the_training_speeds(model):
    fm = model.feature_model_
    inside = {f.spec.name: f for f in fm.predict(1.3, 0.0)}
    far = {f.spec.name: f for f in fm.predict(2.9, 0.0)}
    assert far["knee_swing_flexion_peak"].std > inside["knee_swing_flexion_peak"].std
    assert far["knee_swing_flexion_peak"].extrapolation and not inside["knee_swing_flexion_peak"].extrapolation


def test_a_slope_follows_the_measured_ramps_trend_on_its_own_side(model, reference):
    fm = model.feature_model_
    ramps = [p for p in fm.incline_points_ if p.feature == "ankle_dorsiflexion_peak"]
    assert ramps, "the shipped ramps give incline points of the ankle dorsiflexion peak"
    up = fm.feature_trends_["ankle_dorsiflexion_peak"]["uphill"]["value"]
    down = fm.feature_trends_["ankle_dorsiflexion_peak"]["downhill"]["value"]
    g = np.array([p.incline_deg for p in ramps if p.incline_deg > 0])
    d = np.array([p.value_change for p in ramps if p.incline_deg > 0])
    assert up == pytest.approx(float(g @ d / (g @ g)))     # least squares through zero, uphill points only
    assert up != down


def test_incline_points_carry_each_ramp_change_onto_the_level_curves(reference):
    ramps = load_shipped_ramps()
    incline = InclineChange().fit(ramps, lambda v: level_curves_at(reference, v)[0])
    points = incline_points(incline, lambda v: level_curves_at(reference, v), reference.phase)
    assert points and all(isinstance(p, InclinePoint) for p in points)
    assert {p.incline_deg for p in points} == {g for g, _, _ in incline.changes_}
    assert not any(p.feature == "toe_off" for p in points)          # stance timing on slopes: published points
    assert all(math.isfinite(p.value) and p.se >= 0.0 for p in points)


def test_a_published_point_counts_its_lab_spread_where_it_was_published():
    with_sd = PublishedPoint(feature="knee_stance_flexion_peak", speed_mps=1.2, incline_deg=10.0, value=0.3,
                             se=0.02, sd=0.05, source="test", detail="a test point")
    without = PublishedPoint(feature="knee_stance_flexion_peak", speed_mps=1.2, incline_deg=10.0, value=0.3,
                             se=0.02, sd=float("nan"), source="test", detail="a test point")
    assert published_se(with_sd) == pytest.approx(math.hypot(0.02, 0.05))
    assert published_se(without) == 0.02


def test_settings_reach_every_gpr(reference):
    tasks = np.array([[r.task["speed_mps"], r.task.get("incline_deg", 0.0)] for r in reference.records])
    fm = FeatureModel(length_scale_bounds=((0.5, 2.0), (20.0, 40.0)), n_restarts=0).fit(reference, tasks, [], [])
    for gpr in [*fm.value_gprs_.values(), *fm.phase_gprs_.values()]:
        assert gpr.length_scale_bounds == ((0.5, 2.0), (20.0, 40.0))
