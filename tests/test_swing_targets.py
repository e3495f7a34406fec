"""Swing rows of the learned table: θe at the predicted swing targets, k the model's swing stiffness.

Real model, real data: the targets are read back from the proposal's own features and curves and the R² is
recomputed here from the predicted loop, so a row built from the wrong target, sign or sub-phase fails.
"""

from __future__ import annotations

import copy
import math

import pytest

from controller_core.model import QuasiStiffnessModel
from controller_core.quasi_stiffness import subphase_masks

TASKS = [(0.84, 0.0, 60.0), (1.25, 0.0, 75.0), (1.6, 5.0, 90.0), (2.2, -8.0, 75.0)]


@pytest.mark.parametrize(("speed", "incline", "mass"), TASKS)
def test_swing_rows_aim_at_the_predicted_swing_targets(model, speed, incline, mass):
    p = model.propose(speed, incline, mass)
    rows = {(r.joint, r.subphase): r for r in p.table.rows}
    feature = {f.spec.name: f for f in p.features}
    knee_wf_stiffness, knee_we_stiffness = model.swing_knee_stiffness_Nm_per_rad_per_kg
    ankle_after_toe_off = p.means["ankle_angle"][p.phase >= p.boundaries[1]]
    expected = {
        ("knee", "swing_flexion"): (-knee_wf_stiffness * mass, math.degrees(feature["knee_swing_flexion_peak"].value)),
        ("knee", "swing_extension"): (-knee_we_stiffness * mass, math.degrees(p.means["knee_angle"][0])),
        ("ankle", "swing_flexion"): (-model.swing_ankle_stiffness_Nm_per_rad_per_kg * mass,
                                     math.degrees(ankle_after_toe_off.max()) + model.swing_ankle_clearance_deg),
    }
    expected[("ankle", "swing_extension")] = expected[("ankle", "swing_flexion")]
    masks = dict(zip(("stance_flexion", "stance_extension", "swing_flexion", "swing_extension"),
                     subphase_masks(p.phase, p.boundaries), strict=True))
    for (joint, sub), (k, theta_e_deg) in expected.items():
        row = rows[(joint, sub)]
        assert row.fit_method == "swing_target" and row.guarded
        assert row.k_Nm_per_rad == pytest.approx(k, rel=1e-12) and row.k_Nm_per_rad < 0
        assert row.theta_e_deg == pytest.approx(theta_e_deg, abs=1e-9)
        th = p.means[f"{joint}_angle"][masks[sub]]
        tau = p.means[f"{joint}_moment"][masks[sub]] * mass
        resid = tau - k * (th - math.radians(theta_e_deg))
        r2 = 1.0 - float(resid @ resid) / float(((tau - tau.mean()) ** 2).sum())
        assert row.r2 == pytest.approx(r2, rel=1e-9)
    # stance rows are still least-squares fits (or their guards), never swing targets
    assert all(rows[(j, s)].fit_method != "swing_target" for j in ("knee", "ankle")
               for s in ("stance_flexion", "stance_extension"))
    # the knee's swing flexion target lies above its swing-extension target, and the WF→WE threshold below it
    assert rows[("knee", "swing_flexion")].theta_e_deg > p.table.thresholds.wf_to_we_knee_angle_deg \
        > rows[("knee", "swing_extension")].theta_e_deg
    assert p.violations == []


def test_least_squares_swing_rule_gives_back_the_plain_fits(model):
    literal = copy.copy(model)
    literal.swing_rule = "least_squares"
    p, q = model.propose(1.2, 0.0, 75.0), literal.propose(1.2, 0.0, 75.0)
    for a, b in zip(p.table.rows, q.table.rows, strict=True):
        if a.subphase.startswith("stance"):
            assert a == b
        else:
            assert a.fit_method == "swing_target" and b.fit_method != "swing_target"
    # the literal knee swing-flexion line is energy-injecting (k > 0): the reason the target rule exists
    assert next(r for r in q.table.rows if (r.joint, r.subphase) == ("knee", "swing_flexion")).k_Nm_per_rad > 0


@pytest.mark.parametrize(("params", "message"), [
    ({"swing_rule": "pendulum"}, "swing_rule"),
    ({"swing_knee_stiffness_Nm_per_rad_per_kg": (0.66, -0.25)}, "swing stiffnesses"),
    ({"swing_ankle_stiffness_Nm_per_rad_per_kg": float("nan")}, "swing stiffnesses"),
    ({"swing_ankle_clearance_deg": 40.0}, "swing_ankle_clearance_deg"),
])
def test_bad_swing_settings_are_refused_before_fitting(params, message):
    with pytest.raises(ValueError, match=message):
        QuasiStiffnessModel(**params).fit(reference=None)   # refused before the data is touched


def test_a_saved_model_from_before_the_swing_settings_is_refused_with_a_reason(model, tmp_path):
    from controller_core.model_io import load_model, save_model

    old = copy.copy(model)
    del old.swing_rule                      # what a model pickled by an older QuasiTune looks like
    save_model(old, tmp_path / "old")
    with pytest.raises(ValueError, match=r"older QuasiTune.*swing_rule.*quasitune train"):
        load_model(tmp_path / "old")
    save_model(model, tmp_path / "new")
    assert load_model(tmp_path / "new").propose(1.2, 0.0, 75.0).table == model.propose(1.2, 0.0, 75.0).table
