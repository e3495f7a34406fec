"""GMM/GMR: a known conditional, and real curves."""

from __future__ import annotations

import numpy as np

from controller_core.gmr import GaussianMixtureRegression

# ---------------------------------------------------------------- GPR on real features


# ---------------------------------------------------------------- GMR
def test_gmr_recovers_a_linear_gaussian_conditional():
    rng = np.random.default_rng(1)  # synthetic data with a known answer (test only)
    x = rng.uniform(-1, 1, 4000)
    y = 2.0 * x + 0.5 + rng.normal(0, 0.1, x.size)
    g = GaussianMixtureRegression(n_components=1).fit(np.column_stack([x, y]))
    mean, cov = g.predict(np.array([[0.3]]), in_idx=(0,))
    assert abs(mean[0, 0] - 1.1) < 0.02 and abs(np.sqrt(cov[0, 0, 0]) - 0.1) < 0.01


def test_gmr_on_real_curves_tracks_the_mean(reference):
    phase = reference.phase
    Z = np.vstack([np.column_stack([phase, r.mean["knee_angle"], r.mean["knee_moment"]])
                   for r in reference.records])
    g = GaussianMixtureRegression(n_components=15).fit(Z)
    mean, cov = g.predict(phase[:, None], in_idx=(0,))
    pooled = np.mean([r.mean["knee_angle"] for r in reference.records], axis=0)
    assert np.sqrt(np.mean((mean[:, 0] - pooled) ** 2)) < np.radians(3.0)
    assert np.all(np.linalg.eigvalsh(cov) > 0)
