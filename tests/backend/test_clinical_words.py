"""Settings and limits in the words a prosthetist uses."""

from __future__ import annotations

from backend.clinical_words import field_words, unit_of, violation_words
from controller_core.table import LimitViolation


def test_every_field_key_has_words_and_a_unit():
    assert field_words("knee.stance_flexion.k_Nm_per_rad") == \
        "knee stance flexion resistance (loading response): stiffness"
    assert field_words("thresholds.we_to_sf_load_N") == "heel strike: load above"
    assert field_words("not.a.field") == "not.a.field"
    assert [unit_of(f) for f in ("knee.swing_flexion.b_Nm_s_per_rad", "ankle.stance_extension.theta_e_deg",
                                 "thresholds.sf_to_se_ankle_moment_Nm", "thresholds.min_state_time_s",
                                 "thresholds.sf_to_se_knee_extension_deg_per_s")] == ["N·m·s/rad", "°", "N·m", "s",
                                                                                     "deg/s"]


def test_a_violation_reads_without_field_keys():
    v = LimitViolation(field="knee.stance_flexion.k_Nm_per_rad", value=12.0, low=-1200.0, high=0.0,
                       message="knee.stance_flexion.k_Nm_per_rad = 12 is outside [-1200, 0]")
    words = violation_words(v)
    assert "knee stance flexion resistance" in words and "12" in words and "k_Nm_per_rad" not in words
    rule = LimitViolation(field="neighbours[1.2 m/s, 0 deg | 1.2 m/s, 5 deg].knee.stance_flexion.k_Nm_per_rad",
                          value=350.0, low=0.0, high=300.0, message="too far apart")
    words = violation_words(rule)
    assert "between the neighbouring tasks 1.2 m/s, 0° and 1.2 m/s, 5°" in words and "at most 300 N·m/rad" in words
