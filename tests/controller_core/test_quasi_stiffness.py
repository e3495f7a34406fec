"""Quasi-stiffness lines per sub-phase: known lines, guards, windows, the batched fits."""

# ---------------------------------------------------------------- GPR on real features
from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.quasi_stiffness import fit_line, fit_quasi_stiffness, fit_quasi_stiffness_joints

RANGE = (0.0, math.radians(120.0))


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
    from controller_core.quasi_stiffness import fit_quasi_stiffness_joints
    from controller_core.table_rules import JOINT_RANGE_RAD

    p = model.propose(1.6, 4.0, 80.0)
    ranges = [JOINT_RANGE_RAD[j] for j in ("knee", "ankle")]
    th = np.array([p.means["knee_angle"], p.means["ankle_angle"]])
    tau = np.array([p.means["knee_moment"], p.means["ankle_moment"]]) * 80.0
    both = fit_quasi_stiffness_joints(p.phase, th, tau, p.boundaries, ranges, -20.0)
    singles = [fit_quasi_stiffness(p.phase, th[j], tau[j], p.boundaries, ranges[j], -20.0) for j in range(2)]
    # propose() fits the stance rows with the passivity ceiling 0.25 N·m/rad/kg × 80 kg = −20 N·m/rad (its swing
    # rows are swing targets: tests/controller_core/test_model.py)
    for fits in (singles, [p.fits["knee"][:2] + both[0][2:], p.fits["ankle"][:2] + both[1][2:]]):
        for a, b in zip(both[0] + both[1], fits[0] + fits[1], strict=True):
            assert (a.subphase, a.method, a.n_points, a.phase_start, a.phase_end) == \
                (b.subphase, b.method, b.n_points, b.phase_start, b.phase_end)
            np.testing.assert_allclose([a.k_Nm_per_rad, a.theta_e_rad, a.r2], [b.k_Nm_per_rad, b.theta_e_rad, b.r2],
                                       rtol=1e-10, atol=1e-12)


def test_passivity_guard_replaces_an_unstable_swing_line_and_every_energy_injecting_stance_line():
    # synthetic line (test-only data): τ = +20(θ − 0.56) over θ in [0.3, 0.7]; only swing flexion
    # (θ from 0.5 to 0.62) sweeps across θe
    phase = np.linspace(0, 1, 101)
    theta = 0.3 + 0.4 * phase
    tau = 20.0 * (theta - 0.56)
    free = fit_quasi_stiffness(phase, theta, tau, (0.2, 0.5, 0.8), (0.0, 2.0))
    assert free[2].k_Nm_per_rad == pytest.approx(20.0) and free[2].method == "least_squares"
    guarded = fit_quasi_stiffness(phase, theta, tau, (0.2, 0.5, 0.8), (0.0, 2.0), max_k_Nm_per_rad=-10.0)
    by_name = {f.subphase: f for f in guarded}
    assert by_name["swing_flexion"].k_Nm_per_rad == -10.0 and by_name["swing_flexion"].method == "passivity_guard"
    # in swing extension θe lies outside the angles swept: the line only brakes, and is kept
    assert by_name["swing_extension"].k_Nm_per_rad == pytest.approx(20.0) and not by_name["swing_extension"].guarded
    # in stance the patient's weight is on it: never kept. Stance flexion (θ 0.30–0.38 rad, τ < 0) is, about the
    # range end θ = 0, a restoring spring that still carries its moment; stance extension's moment changes sign
    # across θe, so no line through either end restores, and the floor is used
    sf, se = by_name["stance_flexion"], by_name["stance_extension"]
    mask = phase <= 0.2
    k_end = float(theta[mask] @ tau[mask]) / float(theta[mask] @ theta[mask])
    assert sf.method == "passivity_guard" and sf.theta_e_rad == 0.0 and sf.k_Nm_per_rad == pytest.approx(k_end)
    assert sf.k_Nm_per_rad < -10.0
    assert se.method == "passivity_guard" and se.k_Nm_per_rad == -10.0
    with pytest.raises(ValueError, match="negative"):
        fit_quasi_stiffness(phase, theta, tau, (0.2, 0.5, 0.8), (0.0, 2.0), max_k_Nm_per_rad=5.0)


def test_a_fit_window_fits_its_part_of_the_sub_phase_only():
    # synthetic: stance extension over phase [0.2, 0.6]; an exact spring k = −200 N·m/rad, θe = 0.15 rad up to
    # phase 0.4, then the joint flexes with a small moment that no line through the spring part explains
    phase = np.linspace(0.0, 1.0, 101)
    theta = np.where(phase <= 0.4, 0.35 - 0.5 * (phase - 0.2), 0.25 + 2.0 * (phase - 0.4))
    tau = np.where(phase <= 0.4, -200.0 * (theta - 0.15), -5.0 * np.sin(8 * phase))
    bounds = (0.2, 0.6, 0.8)
    plain = fit_quasi_stiffness_joints(phase, theta[None], tau[None], bounds, [RANGE])[0]
    windowed = fit_quasi_stiffness_joints(phase, theta[None], tau[None], bounds, [RANGE],
                                          fit_windows=[{"stance_extension": (0.2, 0.4)}])[0]
    se_plain, se = plain[1], windowed[1]
    assert se.method == "extension_window" and not se.guarded
    assert se.k_Nm_per_rad == pytest.approx(-200.0, rel=1e-9)
    assert se.theta_e_rad == pytest.approx(0.15, abs=1e-9)
    assert se.r2 == pytest.approx(1.0, abs=1e-9)
    assert (se.phase_start, se.phase_end, se.n_points) == (pytest.approx(0.2), pytest.approx(0.4), 21)
    assert se_plain.r2 < 0.9 and se_plain.method != "extension_window"       # the whole sub-phase is no line
    assert [f for i, f in enumerate(windowed) if i != 1] == [f for i, f in enumerate(plain) if i != 1]
    with pytest.raises(ValueError, match="at least 3 samples"):
        fit_quasi_stiffness_joints(phase, theta[None], tau[None], bounds, [RANGE],
                                   fit_windows=[{"stance_extension": (0.2, 0.205)}])
