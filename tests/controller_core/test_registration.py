"""Phase registration and the task trend of the registered reference."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.feature_model import FeatureModel
from controller_core.features import record_features
from controller_core.joint_reference import JointReference
from controller_core.registration import TaskTrend, UniformUnwarp, canonical_phase, ordered_landmarks, register, unwarp

LANDMARK_NAMES = ("ankle_plantarflexor_moment_peak", "ankle_plantarflexion_peak")


def _landmarks(record) -> np.ndarray:
    f = record_features(record)
    return np.array([f[n][0] for n in LANDMARK_NAMES])


def test_registration_moves_a_real_push_off_peak_to_its_canonical_phase(reference):
    fast = reference.records[-1]                       # 1.95 m/s: push-off earliest in the cycle
    canonical = np.mean([_landmarks(r) for r in reference.records], axis=0)
    own = _landmarks(fast)
    assert own[0] < canonical[0] - 0.01                 # the fast peak really is early
    grid = np.linspace(0.0, 1.0, 1001)
    registered = register(reference.phase, fast.mean["ankle_moment"], own, canonical, grid)
    assert abs(grid[np.argmin(registered)] - canonical[0]) < 0.011   # the peak now sits at the canonical phase
    assert np.min(registered) == pytest.approx(np.min(fast.mean["ankle_moment"]), abs=0.02)


def test_unwarp_undoes_register_on_a_real_curve(reference):
    rec = reference.records[0]
    own, canonical = _landmarks(rec), np.array([0.45, 0.62])
    s = np.arange(200) / 200
    registered = register(reference.phase, rec.mean["knee_angle"], own, canonical, s)
    back = unwarp(s, registered, own, canonical, reference.phase[:-1])
    assert np.max(np.abs(back - rec.mean["knee_angle"][:-1])) < np.radians(1.0)


def test_uniform_unwarp_equals_unwarp(reference):
    rec = reference.records[2]
    grid = np.arange(50) / 50
    curves = np.column_stack([np.interp(grid, reference.phase, rec.mean[c]) for c in ("knee_angle", "knee_moment")])
    canonical, landmarks = np.array([0.45, 0.62]), np.array([0.43, 0.60])
    fast = UniformUnwarp(50, canonical)
    np.testing.assert_allclose(fast.apply(fast.at(landmarks), curves),
                               unwarp(grid, curves, landmarks, canonical, grid), atol=1e-12)


def test_canonical_phase_keeps_heel_strike_and_maps_landmarks():
    lm, canon = np.array([0.40, 0.60]), np.array([0.45, 0.62])
    out = canonical_phase(np.array([0.0, 0.40, 0.60, 1.0]), lm, canon)
    np.testing.assert_allclose(out, [0.0, 0.45, 0.62, 1.0])


def test_landmarks_are_pushed_apart_or_refused():
    np.testing.assert_allclose(ordered_landmarks(np.array([0.5, 0.49])), [0.5, 0.52])
    np.testing.assert_allclose(ordered_landmarks(np.array([-0.3, 0.6])), [0.02, 0.6])
    with pytest.raises(ValueError, match="do not fit"):
        ordered_landmarks(np.linspace(0.5, 0.99, 30))


def test_task_trend_recovers_slopes_and_is_zero_at_the_mean_task():
    # synthetic: residual curves exactly linear in speed, slope known
    speeds = np.array([[0.8], [1.2], [1.5], [1.9]])
    slope = np.sin(np.linspace(0, 2 * np.pi, 50))
    residuals = (speeds - speeds.mean()) * slope[None]
    trend = TaskTrend(ridge=0.0).fit(speeds, residuals)
    np.testing.assert_allclose(trend.predict(np.array([speeds.mean() + 1.0])), slope, atol=1e-9)
    np.testing.assert_allclose(trend.predict(speeds.mean(axis=0)), 0.0, atol=1e-12)


def test_task_trend_refuses_bad_training_data():
    with pytest.raises(ValueError, match="at least two"):
        TaskTrend().fit(np.array([[1.0]]), np.zeros((1, 5)))
    with pytest.raises(ValueError, match="NaN"):
        TaskTrend().fit(np.array([[1.0], [np.nan]]), np.zeros((2, 5)))


def test_registered_reference_follows_speed_inside_the_data_and_holds_amplitude_outside(model):
    knee = {v: model.joint_reference_.at_task(np.array([v, 0.0])).means["knee"][:, 0] for v in (0.9, 1.2, 1.9, 2.6)}
    # knee swing flexion grows with speed between the shipped conditions (Bovi 2011: 57° → 64°)
    assert knee[1.9].max() > knee[0.9].max() + np.radians(2.0)
    # beyond the fastest condition (1.95 m/s) the amplitudes are held, only the timing moves on
    assert knee[2.6].max() == pytest.approx(knee[1.9].max(), abs=np.radians(1.0))
    assert np.argmax(knee[2.6]) <= np.argmax(knee[1.9])


def test_pooled_reference_is_the_same_for_every_task(reference):
    from controller_core.model_io import train

    pooled = train(reference, use_published=False, joint_reference=JointReference(reference_mode="pooled"),
                   feature_model=FeatureModel(n_restarts=0))       # the reference is the subject: a quick feature fit
    a = pooled.joint_reference_.at_task(np.array([0.9, 0.0])).means["ankle"]
    b = pooled.joint_reference_.at_task(np.array([1.9, 0.0])).means["ankle"]
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="reference_mode"):
        train(reference, use_published=False, joint_reference=JointReference(reference_mode="task"))
