"""The joint reference: one path from tasks and features to curves, with or without their std."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.feature_model import FeatureModel
from controller_core.joint_reference import JointReference
from controller_core.model import QuasiStiffnessModel
from controller_core.model_io import train
from controller_core.reference import CHANNELS

TASKS = np.array([[0.9, 0.0], [1.3, 6.0], [2.1, -8.0]])


def test_curves_with_and_without_std_have_the_same_means(model):
    jr = model.joint_reference_
    features = model.predict_features_many(TASKS)
    shown = jr.curves(TASKS, features, with_std=True)
    tables = jr.curves(TASKS, features, with_std=False)
    for a, b in zip(shown, tables, strict=True):
        assert b.stds is None and set(a.stds) == set(CHANNELS)
        for c in CHANNELS:
            np.testing.assert_allclose(a.means[c], b.means[c], atol=1e-9)
            assert np.all(a.stds[c] > 0.0)


def test_the_curves_pass_near_their_via_points(model):
    jr = model.joint_reference_
    features = model.predict_features(1.3, 0.0)
    curve = jr.curves(np.array([[1.3, 0.0]]), [features], with_std=False)[0]
    knee = next(f for f in features if f.spec.name == "knee_swing_flexion_peak")
    at = np.interp(knee.phase, jr.s_query_, curve.means["knee_angle"])
    assert abs(at - knee.value) < 2.0 * knee.std + np.radians(1.0)
    bare = jr.curves(np.array([[1.3, 0.0]]), [features], with_std=False, with_vias=False)[0]
    assert bare.vias == {"knee": [], "ankle": []}


def test_a_slope_widens_the_std_by_the_measured_change_uncertainty(model):
    jr = model.joint_reference_
    level, slope = (jr.curves(np.array([[1.2, g]]), [model.predict_features(1.2, g)], with_std=True)[0]
                    for g in (0.0, 9.0))
    assert np.mean(slope.stds["knee_angle"]) > np.mean(level.stds["knee_angle"])


def test_the_kmp_takes_its_cached_solve_only_for_its_own_fitted_means(reference):
    pooled = train(reference, use_published=False, joint_reference=JointReference(reference_mode="pooled"),
                   feature_model=FeatureModel(n_restarts=0))       # the reference is the subject: a quick feature fit
    jr = pooled.joint_reference_
    level = jr.at_task(np.array([1.0, 0.0]))
    assert level.fitted and level.kmp_mean("knee") is None
    assert level.means["knee"] is jr.joints_["knee"].kmp.mu_ref_


def test_the_registered_reference_moves_with_speed_and_is_never_the_fitted_mean(model):
    jr = model.joint_reference_
    slow, fast = jr.at_task(np.array([0.9, 0.0])), jr.at_task(np.array([1.9, 0.0]))
    assert not slow.fitted and slow.kmp_mean("knee") is slow.means["knee"]
    assert not np.allclose(slow.means["ankle"], fast.means["ankle"])


def test_between_subject_sd_is_linear_between_records_and_held_beyond(model):
    jr = model.joint_reference_
    speeds = jr.level_speeds_
    mid = 0.5 * (speeds[0] + speeds[1])
    sd = jr.between_subject_sd(mid)["knee_angle"]
    np.testing.assert_allclose(sd, 0.5 * (jr.level_sd_["knee_angle"][0] + jr.level_sd_["knee_angle"][1]))
    np.testing.assert_array_equal(jr.between_subject_sd(speeds[-1] + 1.0)["knee_angle"], jr.level_sd_["knee_angle"][-1])


def test_unusable_settings_are_refused_before_the_data_is_touched():
    with pytest.raises(ValueError, match="reference_mode must be 'registered' or 'pooled', got 'nearest'"):
        QuasiStiffnessModel(joint_reference=JointReference(reference_mode="nearest")).fit(reference=None)
    with pytest.raises(ValueError, match="n_components"):
        QuasiStiffnessModel(joint_reference=JointReference(n_components=0)).fit(reference=None)
