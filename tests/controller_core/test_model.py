"""The learning model end to end: proposals, their units and provenance, the swing and stance rules."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from controller_core import InvalidTaskError
from controller_core.model import QuasiStiffnessModel
from controller_core.quasi_stiffness import subphase_masks
from controller_core.table_rules import TableRules

TASKS = [(0.84, 0.0, 60.0), (1.25, 0.0, 75.0), (1.6, 5.0, 90.0), (2.2, -8.0, 75.0)]


def test_proposal_shape_units_and_provenance(model):
    d = model.propose(speed_mps=1.25, incline_deg=0.0, mass_kg=75.0).to_dict()
    assert d["task"] == {"speed_mps": 1.25, "incline_deg": 0.0, "mass_kg": 75.0}
    assert len(d["model"]["data_sha256"]) == 64 and d["model"]["version"].startswith("quasitune-")
    assert d["extrapolation"] is False
    assert len(d["features"]) >= 6 and all(f["std"] > 0 for f in d["features"])
    c = d["curves"]
    assert len(c["phase"]) == 101 and c["phase"][0] == 0.0 and c["phase"][-1] == 1.0
    for key in ("knee_angle_deg", "knee_moment_Nm_per_kg", "ankle_angle_deg", "ankle_moment_Nm_per_kg"):
        assert len(c[key]) == 101 and len(c[key + "_std"]) == 101
    assert 55 < max(c["knee_angle_deg"]) < 70 and min(c["ankle_moment_Nm_per_kg"]) < -1.0
    assert len(d["table"]) == 8 and d["safety"]["ok"]
    sf = next(r for r in d["table"] if r["joint"] == "knee" and r["subphase"] == "stance_flexion")
    assert sf["k_Nm_per_rad"] < 0 and sf["r2"] > 0.8


def test_faster_walking_predicts_more_stance_knee_flexion(model):
    slow = {f.spec.name: f for f in model.predict_features(0.9, 0.0)}
    fast = {f.spec.name: f for f in model.predict_features(1.9, 0.0)}
    assert fast["knee_stance_flexion_peak"].value > slow["knee_stance_flexion_peak"].value + math.radians(8)


def test_incline_uses_published_features_and_reports_uncertainty(model):
    level = {f.spec.name: f for f in model.predict_features(1.185, 0.0)}
    uphill = {f.spec.name: f for f in model.predict_features(1.185, 5.0)}
    # up a slope the ankle dorsiflexes more in stance and pushes off harder (Rábago 2016 controls at +5°, and the
    # measured ramps at +10°)
    assert uphill["ankle_dorsiflexion_peak"].value > level["ankle_dorsiflexion_peak"].value + math.radians(2)
    assert uphill["ankle_plantarflexor_moment_peak"].value < level["ankle_plantarflexor_moment_peak"].value - 0.1
    steep = model.propose(1.2, 15.0, 75.0)
    assert steep.extrapolation
    flat = model.propose(1.2, 0.0, 75.0)
    assert np.mean(steep.stds["knee_angle"]) > np.mean(flat.stds["knee_angle"])


def _ramp_changes():
    from controller_core.phase_table import load_shipped_ramps

    ramps = load_shipped_ramps().records
    level = [r for r in ramps if r.task["incline_deg"] == 0.0]
    weights = np.array([r.n for r in level], dtype=float) / sum(r.n for r in level)
    base = {c: sum(w * r.mean[c] for w, r in zip(weights, level, strict=True)) for c in level[0].mean}
    speed = float(sum(w * r.task["speed_mps"] for w, r in zip(weights, level, strict=True)))
    return [(r, {c: r.mean[c] - base[c] for c in base}) for r in ramps if r.task["incline_deg"] != 0.0], speed


@pytest.mark.parametrize("channel", ["knee_angle", "ankle_angle", "knee_moment", "ankle_moment"])
def test_the_change_from_level_follows_the_measured_ramps(model, channel):
    changes, level_speed = _ramp_changes()
    base = model.propose(level_speed, 0.0, 75.0)
    for ramp, measured in changes:
        on_slope = model.propose(ramp.task["speed_mps"], ramp.task["incline_deg"], 75.0)
        predicted = on_slope.means[channel] - base.means[channel]
        error = np.sqrt(np.mean((predicted - measured[channel]) ** 2))
        ignored = np.sqrt(np.mean(measured[channel] ** 2))       # a model blind to incline predicts no change
        assert error < 0.5 * ignored, (ramp.name, channel, error, ignored)


def test_a_slope_moves_the_knee_as_people_do_and_says_how_sure_it_is(model):
    level, up, down = (model.propose(1.3, g, 75.0) for g in (0.0, 10.0, -10.0))
    assert np.degrees(up.means["knee_angle"][0] - level.means["knee_angle"][0]) > 20   # lands flexed uphill
    assert down.means["knee_moment"][5:30].min() < level.means["knee_moment"][5:30].min() - 0.3   # brakes downhill
    half = model.propose(1.3, 5.0, 75.0)
    assert 0.2 < (half.means["knee_angle"][0] - level.means["knee_angle"][0]) / (
        up.means["knee_angle"][0] - level.means["knee_angle"][0]) < 0.8                      # in between
    # one participant is a trend, not a population: the band widens with the slope
    spread = [np.mean(model.propose(1.3, g, 75.0).stds["knee_angle"]) for g in (0.0, 5.0, 10.0, 15.0)]
    assert spread == sorted(spread) and spread[2] > 2 * spread[0]


@pytest.mark.parametrize(("speed", "incline", "mass", "msg"), [
    (0.0, 0.0, 75.0, "speed_mps"), (3.5, 0.0, 75.0, "speed_mps"), (float("nan"), 0.0, 75.0, "finite"),
    (1e-320, 0.0, 75.0, r"outside \[0\.1, 3\] m/s"), (0.09, 0.0, 75.0, "speed_mps"), (True, 0.0, 75.0, "number"),
    (1.2, 25.0, 75.0, "incline_deg"), (1.2, 0.0, 10.0, "mass_kg"), (1.2, 0.0, 250.0, "mass_kg"),
])
def test_bad_tasks_are_refused(model, speed, incline, mass, msg):
    with pytest.raises(InvalidTaskError, match=msg):
        model.propose(speed, incline, mass)


@pytest.mark.parametrize("speed", [0.84, 1.2, 1.6])
def test_knee_extension_window_fits_the_stance_extension_up_to_the_knee_minimum(model, speed):
    windowed = copy.copy(model)
    windowed.table_rules_ = copy.copy(model.table_rules_)
    windowed.table_rules_.knee_extension_window = True
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


def test_knee_extension_window_setting_is_checked(model):
    with pytest.raises(ValueError, match="knee_extension_window"):
        QuasiStiffnessModel(table_rules=TableRules(knee_extension_window="yes")).fit(reference=None)


@pytest.mark.parametrize(("speed", "incline", "mass"), TASKS)
def test_swing_rows_aim_at_the_predicted_swing_targets(model, speed, incline, mass):
    p = model.propose(speed, incline, mass)
    rows = {(r.joint, r.subphase): r for r in p.table.rows}
    feature = {f.spec.name: f for f in p.features}
    knee_wf_stiffness, knee_we_stiffness = model.table_rules_.swing_knee_stiffness_Nm_per_rad_per_kg
    ankle_after_toe_off = p.means["ankle_angle"][p.phase >= p.boundaries[1]]
    expected = {
        ("knee", "swing_flexion"): (-knee_wf_stiffness * mass, math.degrees(feature["knee_swing_flexion_peak"].value)),
        ("knee", "swing_extension"): (-knee_we_stiffness * mass, math.degrees(p.means["knee_angle"][0])),
        ("ankle", "swing_flexion"): (-model.table_rules_.swing_ankle_stiffness_Nm_per_rad_per_kg * mass,
                                     math.degrees(ankle_after_toe_off.max()) + model.table_rules_.swing_ankle_clearance_deg),
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
    literal.table_rules_ = copy.copy(model.table_rules_)
    literal.table_rules_.swing_rule = "least_squares"
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
        QuasiStiffnessModel(table_rules=TableRules(**params)).fit(reference=None)   # refused before the data is touched


def test_a_model_with_another_joint_reference_is_the_model_fitted_with_it(reference):
    """The GMR baseline of the evaluation: the same fitted features, the curves from a pooled reference; the same as
    fitting the whole model with that reference, at the cost of the curves' fit alone."""
    from controller_core.feature_model import FeatureModel
    from controller_core.joint_reference import JointReference

    data = reference.subset([0, 2, 4])
    settings = {"feature_model": FeatureModel(n_restarts=0)}
    base = QuasiStiffnessModel(**settings, joint_reference=JointReference(n_components=6)).fit(data)
    pooled = JointReference(n_components=6, reference_mode="pooled")
    swapped = base.with_joint_reference(pooled)
    whole = QuasiStiffnessModel(**settings, joint_reference=pooled).fit(data)
    assert swapped.feature_model_ is base.feature_model_ and swapped.joint_reference_ is not base.joint_reference_
    for a, b in [(swapped.propose(1.3, 0.0, 75.0, with_vias=False), whole.propose(1.3, 0.0, 75.0, with_vias=False))]:
        for c in a.means:
            np.testing.assert_allclose(a.means[c], b.means[c], rtol=1e-9, atol=1e-12)
    assert base.joint_reference_.reference_mode == "registered"        # the original is left as it was
    with pytest.raises(ValueError, match="reference_mode"):
        base.with_joint_reference(JointReference(reference_mode="nope"))
