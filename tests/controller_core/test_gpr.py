"""Feature GPRs on real features: uncertainty outside the data, physical bounds, the batched bank."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.gpr import FeatureGPR, FeatureGPRBank

# ---------------------------------------------------------------- GPR on real features


# ---------------------------------------------------------------- GPR on real features
def _knee_peak_data(reference):
    from controller_core.features import record_features

    X = np.array([[r.task["speed_mps"], 0.0] for r in reference.records])
    y = np.array([record_features(r)["knee_stance_flexion_peak"][1] for r in reference.records])
    return X, y


def test_gpr_fits_real_features_and_is_less_sure_outside_the_data(reference):
    X, y = _knee_peak_data(reference)
    g = FeatureGPR().fit(X, y)
    mean, _std = g.predict(X)
    assert np.max(np.abs(mean - y)) < np.radians(3.0)
    _, (std_in, std_out, std_far) = g.predict(np.array([[1.3, 0.0], [1.3, 10.0], [2.9, 0.0]]))
    assert std_out > 2 * std_in and std_far > std_in
    assert not g.extrapolates(np.array([1.3, 0.0]))
    assert g.extrapolates(np.array([1.3, 10.0])) and g.extrapolates(np.array([2.5, 0.0]))


def test_gpr_length_scales_stay_in_physical_bounds(reference):
    X, y = _knee_peak_data(reference)
    g = FeatureGPR(length_scale_bounds=((0.3, 3.0), (3.0, 30.0))).fit(X, y)
    assert 0.3 - 1e-9 <= g.length_scale_[0] <= 3.0 + 1e-9
    assert abs(g.length_scale_[1] - 3.0) < 1e-6  # incline never varies: pinned at the lower bound


def test_gpr_refuses_nan(reference):
    X, y = _knee_peak_data(reference)
    y[0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        FeatureGPR().fit(X, y)


def test_bank_matches_individual_gprs(reference):
    X, y = _knee_peak_data(reference)
    gs = [FeatureGPR().fit(X, y), FeatureGPR().fit(np.vstack([X, [[1.185, 5.0]]]), np.append(y, 0.33),
                                                   np.append(np.zeros(5), 0.02))]
    bank = FeatureGPRBank(gs)
    x = np.array([1.6, 3.0])
    means, stds, out = bank.predict(x)
    for i, g in enumerate(gs):
        (m,), (s,) = g.predict(x)
        assert abs(m - means[i]) < 1e-9 and abs(s - stds[i]) < 1e-9
        assert out[i] == g.extrapolates(x)


@pytest.mark.parametrize("additive", [False, True])
def test_a_fitted_gpr_predicts_from_its_kept_factors_as_scikit_learn_does(reference, monkeypatch, additive):
    """The estimator keeps arrays, not scikit-learn's fitted object (a loaded model predicts without it): its means and
    stds, white noise included, are scikit-learn's own for the same fit, inside the data and far outside it."""
    from sklearn.gaussian_process import GaussianProcessRegressor

    fitted = []
    fit = GaussianProcessRegressor.fit
    monkeypatch.setattr(GaussianProcessRegressor, "fit", lambda self, X, y: fitted.append(self) or fit(self, X, y))
    X, y = _knee_peak_data(reference)
    X = np.vstack([X, [[1.185, 5.0]]])
    y = np.append(y, 0.33)
    g = FeatureGPR(additive=additive).fit(X, y, np.append(np.zeros(len(y) - 1), 0.02))
    tasks = np.array([[1.3, 0.0], [1.6, 3.0], [0.7, -8.0], [2.9, 10.0]])
    mean, std = g.predict(tasks)
    sk_mean, sk_std = fitted[-1].predict(tasks / g.input_scale_, return_std=True)
    np.testing.assert_allclose(mean, sk_mean * g.y_std_ + g.y_mean_, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(std, sk_std * g.y_std_, rtol=1e-7, atol=1e-12)


def test_an_additive_gpr_is_a_level_trend_plus_a_change_and_the_bank_agrees(reference):
    # real level features over speed, and test-only points on slopes that move the value by 0.1 rad per 10°
    X, y = _knee_peak_data(reference)
    slopes = np.array([[1.2, 10.0], [1.2, -10.0], [1.5, 10.0]])
    Xa = np.vstack([X, slopes])
    ya = np.concatenate([y, np.interp(slopes[:, 0], X[:, 0], y) + 0.01 * slopes[:, 1]])
    g = FeatureGPR(additive=True, length_scale_bounds=((0.3, 3.0), (8.0, 40.0))).fit(Xa, ya)
    assert g.rbf_amplitudes_.size == 2 and g.rbf_inverse_lengths_[0, 1] == 0.0 == g.rbf_inverse_lengths_[1, 0]
    (up, level), _ = g.predict(np.array([[1.3, 5.0], [1.3, 0.0]]))
    assert abs((up - level) - 0.05) < 0.02                    # the change does not depend on the speed
    bank = FeatureGPRBank([g, FeatureGPR().fit(X, y)])        # an additive and a product GPR side by side
    for x in (np.array([1.3, 5.0]), np.array([0.9, -8.0])):
        means, stds, out = bank.predict(x)
        (m0,), (s0,) = g.predict(x)
        assert abs(means[0] - m0) < 1e-9 and abs(stds[0] - s0) < 1e-9 and out[0] == g.extrapolates(x)
