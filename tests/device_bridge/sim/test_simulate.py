"""Walks on the MuJoCo bench: both controllers walk, the load cell reads what a leg feels."""

from __future__ import annotations

import math

import numpy as np

from controller_core.gait_metrics import (
    heel_strikes,
)


def test_fsmic_walks_strides_on_the_bench_without_falling(fsmic_walk):
    s = fsmic_walk[1].summary
    assert s["strides"] >= 3
    assert s["falls"] == 0
    assert abs(s["stride_time_s"] - s["reference_stride_time_s"]) < 0.1   # the leg keeps the bench's cadence
    for key in ("knee_angle_rmse_deg", "ankle_angle_rmse_deg", "knee_moment_rmse_Nm_per_kg", "ankle_moment_rmse_Nm_per_kg"):
        assert math.isfinite(s[key]) and s[key] > 0
    assert all(v > 0 for v in s["time_in_state_s"].values())           # every state visited
    assert s["guard_transitions"] == 0
    # the leg carries the body, and the walk says how well: the hip's sink in stance, the person's compensation, the
    # stance knee beside the reference's (a walk that falls at none of them still sinks: docs/results.md)
    assert 0.0 <= s["hip_sink_max_mm"] < 150.0 and s["support_deficit_max_bw"] >= 0.0
    assert s["stance_knee_flexion_peak_deg"] <= s["stance_knee_flexion_peak_max_deg"] < 60.0
    assert 15.0 < s["reference_stance_knee_flexion_peak_deg"] < 25.0
    lo, hi = s["knee_angle_rmse_ci95_deg"]                              # how sure: an interval over the strides
    assert 0 < lo <= s["knee_angle_rmse_deg"] <= hi                      # (the FSMIC's strides scatter: it is wide)
    assert s["ankle_moment_rmse_ci95_Nm_per_kg"][0] <= s["ankle_moment_rmse_ci95_Nm_per_kg"][1]
    for channel in ("knee_angle", "ankle_angle"):   # an average curve is never further off than its strides
        assert s[f"{channel}_per_stride_rmse_deg"] >= s[f"{channel}_rmse_deg"]
    # heel strike reaches stance on every stride, never sooner than its 5 ms load hold allows, and no stride keeps
    # a leg with more than half the body weight on it in swing for more than 20 ms
    assert s["heel_strikes_without_stance"] == 0
    assert 5.0 <= s["heel_strike_to_stance_ms_median"] <= s["heel_strike_to_stance_ms_max"] < 500.0
    assert s["loaded_swing_ms_per_stride"] <= s["loaded_swing_ms_max_stride"] <= 20.0


def test_learned_table_walks_strides_on_the_bench_without_falling(quasi_stiffness_walk):
    s = quasi_stiffness_walk[1].summary
    assert s["strides"] >= 3
    assert s["falls"] == 0 and s["toe_catches"] == 0
    assert abs(s["stride_time_s"] - s["reference_stride_time_s"]) < 0.1
    assert all(v > 0 for v in s["time_in_state_s"].values())
    assert s["guard_transitions"] == 0
    # the swing targets carry the knee back towards extension before every heel strike (on alternate strides it
    # still lands flexed about 25°: the walk alternates, docs/results.md)
    log = quasi_stiffness_walk[0].channels
    strikes = heel_strikes(log["contact_N"], 0.02 * 75.0 * 9.81, 150)
    late = [s for s in strikes if log["time_s"][s] > 2.0]
    assert late and max(math.degrees(log["knee_angle_rad"][s]) for s in late) < 35.0


def test_load_cell_reads_compression_in_stance_and_a_plantarflexor_moment_at_push_off(fsmic_walk):
    log, _ = fsmic_walk
    c = log.channels
    weight = 75.0 * 9.81
    stance = c["contact_N"] > 0.5 * weight
    assert np.median(c["load_N"][stance]) > 0.4 * weight                # compression +
    push_off = (c["state"] == 1) & stance
    assert np.median(c["ankle_moment_Nm"][push_off]) < -10.0             # plantarflexor − (QuasiTune signs)
    swing = c["contact_N"] == 0
    assert np.median(np.abs(c["load_N"][swing])) < 0.1 * weight          # only the foot's own weight in swing
