"""The table rules: curves → lines, guards, thresholds, damping."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.table import Provenance
from controller_core.table_rules import (
    DEFAULT_DAMPING_NMS_PER_RAD_PER_KG,
    SWING_INERTIA_RATIO_RANGE,
    SWING_SCALED,
    TableRules,
    boundaries,
    swing_scale,
)


def _inputs(model, speed=1.2, incline=0.0):
    features = model.predict_features(speed, incline)
    curves = model.joint_reference_.curves(np.array([[speed, incline]]), [features], with_std=False)[0]
    provenance = Provenance(model_version="test", data_sha256="0" * 64, speed_mps=speed, incline_deg=incline,
                            patient_mass_kg=70.0, extrapolation=False)
    return model.s_query_, curves.means, features, provenance


def test_boundaries_are_the_predicted_events(model):
    features = {f.spec.name: f for f in model.predict_features(1.2, 0.0)}
    b = boundaries(features)
    assert b == (features["knee_stance_flexion_peak"].phase, features["toe_off"].value,
                 features["knee_swing_flexion_peak"].phase)
    assert 0.0 < b[0] < b[1] < b[2] < 1.0


@pytest.mark.parametrize("mass", [50.0, 70.0, 120.0])
def test_the_knee_stance_flexion_row_never_goes_below_the_support_floor(model, mass):
    phase, means, features, provenance = _inputs(model, 0.84, 10.0)
    rules = TableRules()
    table, _, _ = rules.table(phase, means, features, mass, provenance)
    row = next(r for r in table.rows if (r.joint, r.subphase) == ("knee", "stance_flexion"))
    assert row.k_Nm_per_rad <= -rules.knee_support_floor_Nm_per_rad_per_kg * mass + 1e-9


def test_a_stricter_support_floor_holds_the_knee_and_says_so(model):
    phase, means, features, provenance = _inputs(model)
    table, _, _ = TableRules(knee_support_floor_Nm_per_rad_per_kg=20.0).table(phase, means, features, 70.0, provenance)
    row = next(r for r in table.rows if (r.joint, r.subphase) == ("knee", "stance_flexion"))
    assert row.k_Nm_per_rad == pytest.approx(-20.0 * 70.0) and row.fit_method == "support_floor" and row.guarded


def test_damping_scales_with_mass_and_can_be_set(model):
    phase, means, features, provenance = _inputs(model)
    table, _, _ = TableRules().table(phase, means, features, 70.0, provenance)
    for r in table.rows:
        assert r.b_Nm_s_per_rad == pytest.approx(DEFAULT_DAMPING_NMS_PER_RAD_PER_KG[r.joint][r.subphase] * 70.0)
    double = {j: {s: 2.0 * v for s, v in d.items()} for j, d in DEFAULT_DAMPING_NMS_PER_RAD_PER_KG.items()}
    stiffer, _, _ = TableRules(damping_Nms_per_rad_per_kg=double).table(phase, means, features, 70.0, provenance)
    for a, b in zip(table.rows, stiffer.rows, strict=True):
        assert b.b_Nm_s_per_rad == pytest.approx(2.0 * a.b_Nm_s_per_rad)
        assert b.k_Nm_per_rad == a.k_Nm_per_rad


def test_a_leg_with_more_swing_inertia_gets_stiffer_and_more_damped_swing_rows_in_proportion(model):
    phase, means, features, provenance = _inputs(model)
    plain, _, _ = TableRules().table(phase, means, features, 75.0, provenance)
    heavy, _, _ = TableRules().table(phase, means, features, 75.0, provenance, swing_inertia_ratio=(1.5, 1.2))
    scaled = 0
    for a, b in zip(plain.rows, heavy.rows, strict=True):
        times = {"knee": 1.5, "ankle": 1.2}[a.joint] if a.subphase in SWING_SCALED[a.joint] else 1.0
        scaled += times != 1.0
        assert b.k_Nm_per_rad == pytest.approx(times * a.k_Nm_per_rad)
        assert b.b_Nm_s_per_rad == pytest.approx(times * a.b_Nm_s_per_rad)
        assert b.theta_e_deg == a.theta_e_deg                   # the targets are the person's, not the leg's
    assert scaled == 3 and heavy.thresholds == plain.thresholds   # knee swing extension, ankle through swing


def test_a_swing_inertia_ratio_is_held_to_its_range_and_a_bad_one_refused():
    lo, hi = SWING_INERTIA_RATIO_RANGE
    assert swing_scale((1.0, 1.0)) == {"knee": 1.0, "ankle": 1.0}
    assert swing_scale((5.0, 0.1)) == {"knee": hi, "ankle": lo}
    for bad in ((math.nan, 1.0), (1.0, -1.0), (0.0, 1.0), (1.0, math.inf)):
        with pytest.raises(ValueError, match="swing inertia ratio"):
            swing_scale(bad)


def test_thresholds_come_from_the_curves_and_body_weight(model):
    phase, means, features, provenance = _inputs(model)
    rules = TableRules(load_fractions=(0.1, 0.3), swing_threshold_fraction=0.8)
    table, bounds, _ = rules.table(phase, means, features, 70.0, provenance)
    t = table.thresholds
    assert t.se_to_wf_load_N == pytest.approx(0.1 * 70.0 * 9.81, rel=1e-3)
    assert t.we_to_sf_load_N == pytest.approx(0.3 * 70.0 * 9.81, rel=1e-3)
    swing_peak = next(f for f in features if f.spec.name == "knee_swing_flexion_peak").value
    assert t.wf_to_we_knee_angle_deg == pytest.approx(0.8 * math.degrees(swing_peak))
    assert t.sf_to_se_ankle_moment_Nm == pytest.approx(np.interp(bounds[0], phase, means["ankle_moment"]) * 70.0)


@pytest.mark.parametrize(("settings", "message"), [
    ({"swing_rule": "pendulum"}, "swing_rule"),
    ({"knee_extension_window": 1}, "knee_extension_window"),
    ({"swing_knee_stiffness_Nm_per_rad_per_kg": (0.66,)}, "swing stiffnesses"),
    ({"swing_ankle_clearance_deg": -1.0}, "swing_ankle_clearance_deg"),
])
def test_unusable_settings_are_refused_by_name(settings, message):
    with pytest.raises(ValueError, match=message):
        TableRules(**settings).check()
