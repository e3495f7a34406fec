"""GPR, GMR, KMP and the quasi-stiffness fit. Inputs marked synthetic are test-only curves."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.gmr import GaussianMixtureRegression
from controller_core.gpr import FeatureGPR, FeatureGPRBank
from controller_core.hull import TaskHull
from controller_core.kmp import KMP, ViaPoint
from controller_core.quasi_stiffness import fit_line, fit_quasi_stiffness


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
    _, std_in = g.predict_one(np.array([1.3, 0.0]))
    _, std_out = g.predict_one(np.array([1.3, 10.0]))
    _, std_far = g.predict_one(np.array([2.9, 0.0]))
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
    means, stds, out = bank.predict_one(x)
    for i, g in enumerate(gs):
        m, s = g.predict_one(x)
        assert abs(m - means[i]) < 1e-10 and abs(s - stds[i]) < 1e-10
        assert out[i] == g.extrapolates(x)


def test_hull_handles_degenerate_and_full_rank_sets():
    line = TaskHull().fit(np.array([[0.8, 0.0], [1.2, 0.0], [1.9, 0.0]]))
    assert line.contains(np.array([1.0, 0.0])) and line.contains(np.array([1.0, 0.3]))
    assert not line.contains(np.array([1.0, 2.0])) and not line.contains(np.array([2.2, 0.0]))
    tri = TaskHull().fit(np.array([[0.8, 0.0], [1.9, 0.0], [1.2, 5.0]]))
    assert tri.contains(np.array([1.2, 2.0])) and not tri.contains(np.array([1.9, 4.0]))


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


# ---------------------------------------------------------------- KMP on a real reference
@pytest.fixture(scope="module")
def knee_kmp(reference):
    s = np.arange(50) / 50
    nat = next(r for r in reference.records if "Natural" in r.name)
    mu = np.column_stack([np.interp(s, nat.phase, nat.mean["knee_angle"]),
                          np.interp(s, nat.phase, nat.mean["knee_moment"])])
    sd = np.column_stack([np.interp(s, nat.phase, nat.sd["knee_angle"]),
                          np.interp(s, nat.phase, nat.sd["knee_moment"])])
    sigma = np.array([np.diag(v**2) for v in sd])
    return KMP(length_scale=0.05, lam=1.0, lam_c=1.0, via_tolerance=0.005).fit(s, mu, sigma), nat


def test_kmp_reproduces_reference_without_via_points(knee_kmp):
    kmp, nat = knee_kmp
    mean, _ = kmp.predict([])
    assert np.sqrt(np.mean((mean[:, 0] - nat.mean["knee_angle"]) ** 2)) < np.radians(1.0)
    assert np.sqrt(np.mean((mean[:, 1] - nat.mean["knee_moment"]) ** 2)) < 0.03


def test_kmp_passes_through_via_points_and_shrinks_covariance(knee_kmp):
    kmp, _nat = knee_kmp
    target = np.radians(27.0)  # a 7-8 deg deeper stance flexion, as at a faster speed
    via = ViaPoint(0.13, np.array([target, -0.6]), np.diag([np.radians(0.2) ** 2, 0.005**2]))
    mean, cov = kmp.predict([via])
    i = int(np.argmin(np.abs(kmp.s_query_ - 0.13)))
    assert abs(mean[i, 0] - target) < np.radians(1.0)
    assert abs(mean[i, 1] + 0.6) < 0.03
    _, cov0 = kmp.predict([])
    assert cov[i, 0, 0] < 0.5 * cov0[i, 0, 0]
    far = int(np.argmin(np.abs(kmp.s_query_ - 0.6)))
    assert abs(mean[far, 0] - kmp.predict([])[0][far, 0]) < np.radians(0.5)  # local deformation only


def test_kmp_cached_equals_uncached_with_replace_and_insert(knee_kmp):
    kmp, _ = knee_kmp
    vias = [ViaPoint(0.20, np.array([0.3, -0.5]), np.diag([1e-4, 1e-2])),      # on a grid point: replaces
            ViaPoint(0.731, np.array([1.1, 0.0]), np.diag([1e-4, 1.0]))]       # between points: inserts
    assert kmp._replaced(np.array([v.phase for v in vias])).tolist() == [10]
    m0, c0 = kmp.predict(vias)
    m1, c1 = kmp.predict_uncached(vias)
    assert np.allclose(m0, m1, atol=1e-10) and np.allclose(c0, c1, atol=1e-10)
    mu2 = kmp.mu_ref_ * 1.1
    assert np.allclose(kmp.predict(vias, mu=mu2)[0], kmp.predict_uncached(vias, mu=mu2)[0], atol=1e-10)


def test_kmp_pickled_with_the_dense_query_kernel_still_predicts_the_same(knee_kmp):
    import pickle

    from controller_core.kmp import _kron_eye

    kmp, _ = knee_kmp
    vias = [ViaPoint(0.20, np.array([0.3, -0.5]), np.diag([1e-4, 1e-2]))]
    state = dict(kmp.__dict__)                    # how a KMP saved before the factored kernel looked
    state["_Kq"] = _kron_eye(state.pop("_kq"), kmp.n_outputs_)
    old = KMP.__new__(KMP)
    old.__dict__.update(state)
    restored = pickle.loads(pickle.dumps(old))
    assert not hasattr(restored, "_Kq")
    for a, b in zip(restored.predict_std(vias), kmp.predict_std(vias), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


@pytest.mark.parametrize("lam_c, via_mean_scale", [(1.0, 0.1), (3.0, 1.0), (3.0, 0.1)])
def test_kmp_split_mean_and_covariance_systems_match_uncached(knee_kmp, lam_c, via_mean_scale):
    base, _ = knee_kmp
    kmp = KMP(length_scale=0.05, lam=1.0, lam_c=lam_c, via_tolerance=0.005,
              via_mean_scale=via_mean_scale).fit(base.s_ref_, base.mu_ref_, base.sigma_ref_)
    vias = [ViaPoint(0.20, np.array([0.3, -0.5]), np.diag([1e-4, 1e-2])),
            ViaPoint(0.731, np.array([1.1, 0.0]), np.diag([1e-4, 1.0])),
            ViaPoint(0.9, np.array([0.2, 0.1]), np.diag([1e-3, 1e-2]))]
    mu2 = kmp.mu_ref_ * 0.9
    m0, c0 = kmp.predict(vias, mu=mu2)
    m1, c1 = kmp.predict_uncached(vias, mu=mu2)
    assert np.allclose(m0, m1, atol=1e-9) and np.allclose(c0, c1, atol=1e-9)
    m2, sd = kmp.predict_std(vias, mu=mu2)
    np.testing.assert_allclose(m2, m0, atol=1e-12)
    np.testing.assert_allclose(sd, np.sqrt(np.diagonal(c0, axis1=1, axis2=2)), atol=1e-9)


# ---------------------------------------------------------------- quasi-stiffness
def test_line_fit_recovers_k_and_theta_e():
    theta = np.linspace(0.1, 0.4, 20)  # synthetic exact line (test only)
    k, te, r2, guarded = fit_line(theta, -150.0 * (theta - 0.05), (0.0, 2.0))
    assert abs(k + 150.0) < 1e-9 and abs(te - 0.05) < 1e-12 and r2 > 0.999999 and not guarded


def test_line_fit_guards_flat_torque():
    theta = np.linspace(0.1, 0.4, 20)  # synthetic: constant torque, k ≈ 0
    k, te, _, guarded = fit_line(theta, np.full(20, 3.0) + 1e-9 * theta, (0.0, 2.0))
    assert guarded and 0.0 <= te <= 2.0 and np.isfinite(k)


def test_subphase_fit_on_real_knee_curve(reference):
    nat = next(r for r in reference.records if "Natural" in r.name)
    fits = fit_quasi_stiffness(nat.phase, nat.mean["knee_angle"], nat.mean["knee_moment"] * 75.0,
                               (0.12, nat.toe_off_phase, 0.72), (0.0, np.radians(120)))
    sf = fits[0]
    assert sf.subphase == "stance_flexion" and sf.k_Nm_per_rad < 0 and sf.r2 > 0.9  # spring-like loading
    assert 0.0 <= sf.theta_e_rad < np.radians(15)
    with pytest.raises(ValueError, match="boundaries"):
        fit_quasi_stiffness(nat.phase, nat.mean["knee_angle"], nat.mean["knee_moment"], (0.5, 0.3, 0.7),
                            (0.0, 2.0))


def test_vectorised_subphase_fit_equals_line_by_line(model):
    from controller_core.quasi_stiffness import subphase_masks

    for speed, incline in [(0.9, 0.0), (1.9, 0.0), (1.2, -10.0), (2.8, 0.0)]:
        p = model.propose(speed, incline, 75.0)
        for joint, rng in (("knee", (0.0, np.radians(120))), ("ankle", (np.radians(-30), np.radians(30)))):
            th, tau = p.means[f"{joint}_angle"], p.means[f"{joint}_moment"] * 75.0
            fits = fit_quasi_stiffness(p.phase, th, tau, p.boundaries, rng)
            for f, mask in zip(fits, subphase_masks(p.phase, p.boundaries), strict=True):
                k, te, r2, guarded = fit_line(th[mask], tau[mask], rng)
                assert guarded == f.guarded
                assert abs(k - f.k_Nm_per_rad) <= 1e-9 * max(1.0, abs(k))
                assert abs(te - f.theta_e_rad) < 1e-9 and abs(r2 - f.r2) < 1e-9


def test_joint_batched_fit_equals_one_joint_at_a_time(model):
    from controller_core.model import JOINT_RANGE_RAD
    from controller_core.quasi_stiffness import fit_quasi_stiffness_joints

    p = model.propose(1.6, 4.0, 80.0)
    ranges = [JOINT_RANGE_RAD[j] for j in ("knee", "ankle")]
    th = np.array([p.means["knee_angle"], p.means["ankle_angle"]])
    tau = np.array([p.means["knee_moment"], p.means["ankle_moment"]]) * 80.0
    both = fit_quasi_stiffness_joints(p.phase, th, tau, p.boundaries, ranges, -20.0)
    singles = [fit_quasi_stiffness(p.phase, th[j], tau[j], p.boundaries, ranges[j], -20.0) for j in range(2)]
    # propose() fits the stance rows with the passivity ceiling 0.25 N·m/rad/kg × 80 kg = −20 N·m/rad (its swing
    # rows are swing targets: tests/test_swing_targets.py)
    for fits in (singles, [p.fits["knee"][:2] + both[0][2:], p.fits["ankle"][:2] + both[1][2:]]):
        for a, b in zip(both[0] + both[1], fits[0] + fits[1], strict=True):
            assert (a.subphase, a.method, a.n_points, a.phase_start, a.phase_end) == \
                (b.subphase, b.method, b.n_points, b.phase_start, b.phase_end)
            np.testing.assert_allclose([a.k_Nm_per_rad, a.theta_e_rad, a.r2], [b.k_Nm_per_rad, b.theta_e_rad, b.r2],
                                       rtol=1e-10, atol=1e-12)


def test_kmp_replaced_points_fast_path_matches_brute_force(model):
    kmp = model.joints_["knee"].kmp
    n, rng = kmp.s_ref_.size, np.random.default_rng(1)
    for _ in range(2000):
        sv = rng.uniform(0.0, 1.0, rng.integers(1, 6))
        sv[0] = np.mod(rng.integers(0, n) / n + rng.choice([-1, 1]) * rng.choice([0.4999, 0.5001]) / n, 1.0)
        gap = np.abs(sv[:, None] - kmp.s_ref_[None])
        gap = np.minimum(gap, 1.0 - gap)
        assert kmp._replaced(sv).tolist() == np.flatnonzero((gap <= kmp.via_tolerance).any(axis=0)).tolist()
