"""Stance rows of the learned table: the knee stance-extension fit window and the event thresholds.

The first test runs on a synthetic loop, built here and labelled so: a sub-phase whose first part is an exact
spring and whose rest is not. The others use the real model on the shipped data.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from controller_core.fsmic import fsmic_table
from controller_core.model import G
from controller_core.quasi_stiffness import fit_quasi_stiffness_joints

RANGE = (0.0, math.radians(120.0))


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


@pytest.mark.parametrize("speed", [0.84, 1.2, 1.6])
def test_knee_extension_window_fits_the_stance_extension_up_to_the_knee_minimum(model, speed):
    windowed = copy.copy(model)
    windowed.knee_extension_window = True
    p, q = model.propose(speed, 0.0, 75.0), windowed.propose(speed, 0.0, 75.0)
    row = {(r.joint, r.subphase): r for r in q.table.rows}[("knee", "stance_extension")]
    fit = next(f for f in q.fits["knee"] if f.subphase == "stance_extension")
    knee = q.means["knee_angle"]
    in_se = (q.phase >= q.boundaries[0]) & (q.phase <= q.boundaries[1])
    assert fit.phase_end == pytest.approx(q.phase[in_se][np.argmin(knee[in_se])])    # the late-stance minimum
    assert fit.phase_start == pytest.approx(q.phase[in_se][0])
    assert row.fit_method == "extension_window" and row.r2 > 0.75
    assert row.k_Nm_per_rad < -100.0 and 5.0 < row.theta_e_deg < 12.0            # a restoring spring near 8°
    plain = {(r.joint, r.subphase): r for r in p.table.rows}[("knee", "stance_extension")]
    assert plain.fit_method != "extension_window" and plain.r2 < row.r2            # the default: whole sub-phase
    others = [(a, b) for a, b in zip(p.table.rows, q.table.rows, strict=True)
              if (a.joint, a.subphase) != ("knee", "stance_extension")]
    assert all(a == b for a, b in others)


def test_event_load_thresholds_are_the_published_pair_the_fsmic_uses(model):
    for mass in (60.0, 90.0):
        learned, benchmark = model.propose(1.2, 0.0, mass).table.thresholds, fsmic_table(mass).thresholds
        assert learned.se_to_wf_load_N == pytest.approx(0.15 * mass * G) == benchmark.se_to_wf_load_N
        assert learned.we_to_sf_load_N == pytest.approx(0.40 * mass * G) == benchmark.we_to_sf_load_N


def test_knee_extension_window_setting_is_checked(model):
    from controller_core.model import QuasiStiffnessModel

    with pytest.raises(ValueError, match="knee_extension_window"):
        QuasiStiffnessModel(knee_extension_window="yes").fit(reference=None)
