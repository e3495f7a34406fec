"""KMP: the reference without via-points, via-points passed, the cached solve against the plain one."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.kmp import KMP, ViaPoint

# ---------------------------------------------------------------- GPR on real features


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


def assert_cached_paths_match_the_plain_solve(kmp: KMP, vias: list[ViaPoint], mu: np.ndarray, atol: float) -> None:
    """predict, predict_std and predict_mean against predict_uncached (the whole system factorised)."""
    m1, c1 = kmp.predict_uncached(vias, mu=mu)
    m0, c0 = kmp.predict(vias, mu=mu)
    np.testing.assert_allclose(m0, m1, atol=atol)
    np.testing.assert_allclose(c0, c1, atol=atol)
    m2, sd = kmp.predict_std(vias, mu=mu)
    np.testing.assert_allclose(m2, m1, atol=atol)
    np.testing.assert_allclose(sd, np.sqrt(np.diagonal(c1, axis1=1, axis2=2)), atol=atol)
    np.testing.assert_allclose(kmp.predict_mean(vias, mu=mu), m1, atol=atol)


def test_kmp_cached_equals_uncached_when_via_points_only_insert(knee_kmp):
    """Via-points between grid points remove nothing: the bordered update has no removed-row block."""
    kmp, _ = knee_kmp
    vias = [ViaPoint(0.131, np.array([0.45, -0.6]), np.diag([1e-4, 1e-2])),
            ViaPoint(0.731, np.array([1.1, 0.0]), np.diag([1e-4, 1.0]))]
    assert kmp._replaced(np.array([v.phase for v in vias])).size == 0
    assert_cached_paths_match_the_plain_solve(kmp, vias, kmp.mu_ref_ * 1.05, atol=1e-10)


def test_kmp_pickled_with_the_dense_query_kernel_still_predicts_the_same(knee_kmp):
    import pickle

    from controller_core.kmp import _kron_eye

    kmp, _ = knee_kmp
    vias = [ViaPoint(0.20, np.array([0.3, -0.5]), np.diag([1e-4, 1e-2]))]
    state = dict(kmp.__dict__)                    # how a KMP saved before the factored kernel looked
    state["_Kq"] = _kron_eye(state.pop("_kq"), kmp.n_outputs_)
    state["_G"] = state["_G_c"] = state["_Zc"].T   # products older saves kept and nothing reads now
    old = KMP.__new__(KMP)
    old.__dict__.update(state)
    restored = pickle.loads(pickle.dumps(old))
    assert not hasattr(restored, "_Kq") and not hasattr(restored, "_G") and not hasattr(restored, "_G_c")
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
    assert_cached_paths_match_the_plain_solve(kmp, vias, mu2, atol=1e-9)
    np.testing.assert_allclose(kmp.predict_mean([], mu=mu2), kmp.predict_uncached([], mu=mu2)[0], atol=1e-9)


def test_kmp_replaced_points_fast_path_matches_brute_force(model):
    kmp = model.joint_reference_.joints_["knee"].kmp
    n, rng = kmp.s_ref_.size, np.random.default_rng(1)
    for _ in range(2000):
        sv = rng.uniform(0.0, 1.0, rng.integers(1, 6))
        sv[0] = np.mod(rng.integers(0, n) / n + rng.choice([-1, 1]) * rng.choice([0.4999, 0.5001]) / n, 1.0)
        gap = np.abs(sv[:, None] - kmp.s_ref_[None])
        gap = np.minimum(gap, 1.0 - gap)
        assert kmp._replaced(sv).tolist() == np.flatnonzero((gap <= kmp.via_tolerance).any(axis=0)).tolist()


@pytest.mark.parametrize(("lam", "gap", "var"), [(1e-3, 1e-5, 1e-10), (1e-2, 1e-7, 1e-10), (0.1, 1e-5, 1e-10)])
def test_an_ill_conditioned_update_falls_back_to_the_plain_solve(model, lam, gap, var):
    ref = model.joint_reference_.joints_["knee"].kmp
    kmp = KMP(length_scale=ref.length_scale, lam=lam, lam_c=lam, via_tolerance=ref.via_tolerance).fit(
        ref.s_ref_, ref.mu_ref_, ref.sigma_ref_, ref.s_query_)
    twins = [ViaPoint(0.3, np.array([0.5, -0.4]), np.eye(2) * var),          # two nearly coincident,
             ViaPoint(0.3 + gap, np.array([0.5, -0.4]), np.eye(2) * var)]    # very confident via-points
    mean, cov = kmp.predict(twins)
    oracle_mean, oracle_cov = kmp.predict_uncached(twins)
    assert np.allclose(mean, oracle_mean, atol=1e-12) and np.allclose(cov, oracle_cov, atol=1e-12)
    mean_s, sd = kmp.predict_std(twins)
    assert np.allclose(mean_s, oracle_mean, atol=1e-12)
    assert np.allclose(sd, np.sqrt(np.diagonal(oracle_cov, axis1=1, axis2=2).clip(0)), atol=1e-12)
    assert kmp.fallbacks_ == 2
    assert np.allclose(kmp.predict_mean(twins), oracle_mean, atol=1e-12)
    assert kmp.fallbacks_ == 3


def test_the_model_s_own_via_points_take_the_cached_path(model):
    kmp = model.joint_reference_.joints_["knee"].kmp
    before = kmp.fallbacks_
    for speed in (0.8, 1.2, 1.9):
        model.propose(speed, 0.0, 75.0)
    assert kmp.fallbacks_ == before


def test_many_means_in_stacked_solves_are_the_single_solves_means(model):
    """Random via-points (a test of the algebra, not data): groups by via count and replaced points, none, and an
    ill-conditioned pair that must take the single solve's fallback."""
    kmp = model.joint_reference_.joints_["knee"].kmp
    rng = np.random.default_rng(3)
    n = kmp.s_ref_.size
    sets: list[list[ViaPoint]] = [[]]
    for _ in range(30):
        m = int(rng.integers(1, 5))
        phases = rng.uniform(0.0, 1.0, m)
        phases[: m // 2] = np.round(phases[: m // 2] * n) / n             # some exactly on the grid: replaced points
        sets.append([ViaPoint(float(p), rng.normal([0.3, -0.2], [0.2, 0.1]), np.diag(rng.uniform(1e-4, 1e-2, 2)))
                     for p in phases])
    sets.append([ViaPoint(0.3, np.array([0.5, -0.4]), np.eye(2) * 1e-10),
                 ViaPoint(0.3 + 1e-7, np.array([0.5, -0.4]), np.eye(2) * 1e-10)])
    mus = [None if k % 2 else kmp.mu_ref_ + rng.normal(0.0, 0.02, kmp.mu_ref_.shape) for k in range(len(sets))]
    many = kmp.predict_mean_many(sets, mus)
    for v, mu, mean in zip(sets, mus, many, strict=True):
        np.testing.assert_allclose(mean, kmp.predict_mean(v, mu), atol=1e-9)
    with pytest.raises(ValueError, match="same length"):
        kmp.predict_mean_many(sets, mus[:-1])
