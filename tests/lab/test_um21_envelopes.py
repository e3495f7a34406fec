"""The model's incline change against UM21's ten people (LocoHub range midpoints), data it was never trained on."""

from __future__ import annotations

import math

import pytest

from controller_core.model_io import train
from lab.um21_envelopes import format_um21_report, load_um21_ranges, um21_change_check


def test_the_shipped_ranges_load_in_our_convention():
    ranges = load_um21_ranges()
    assert len(ranges) == 40            # knee and ankle angles of 3 tasks, moments of 2 (incline moments are nan)
    assert not any(task == "incline_walking" and channel.endswith("moment") for task, channel, _ in ranges)
    lo, hi = ranges[("level_walking", "ankle_angle", 50)]
    assert math.radians(8.0) < lo < hi < math.radians(20.0)     # late-stance dorsiflexion, positive here
    lo, hi = ranges[("level_walking", "ankle_moment", 50)]
    assert -2.0 < lo < hi < 0.0                                 # plantarflexor moment, negative here
    lo, hi = ranges[("incline_walking", "knee_angle", 0)]
    assert hi > math.radians(40.0)                              # people land with the knee flexed uphill


def test_a_row_whose_unit_contradicts_its_name_is_refused(tmp_path):
    bad = tmp_path / "ranges.csv"
    bad.write_text("task,phase_pct,variable_as_in_source,lo_as_in_source,hi_as_in_source,unit_as_in_source\n"
                   "level_walking,0,knee_flexion_angle_ipsi_rad,-5,14,deg\n")
    with pytest.raises(ValueError, match="unit 'deg'"):
        load_um21_ranges(bad)


def test_the_model_changes_with_slope_the_way_ten_other_people_do(model):
    report = um21_change_check(model)
    for side in ("incline_walking", "decline_walking"):
        assert report["sides"][side]["channels"]["knee_angle_deg"]["ratio_to_ignore_incline"] < 0.6
    assert report["sides"]["decline_walking"]["channels"]["knee_moment_Nm_per_kg"]["ratio_to_ignore_incline"] < 0.6
    assert report["mean_ratio_to_ignore_incline"] < 0.6
    assert "Mean ratio to ignoring incline" in format_um21_report(report)


def test_a_model_that_learned_no_slope_scores_as_ignoring_incline(reference):
    """The check can fail: trained on level walking alone, the model's change is nothing, ratio 1."""
    level_only = train(reference, use_published=False)
    report = um21_change_check(level_only)
    assert report["mean_ratio_to_ignore_incline"] == pytest.approx(1.0, abs=0.05)
