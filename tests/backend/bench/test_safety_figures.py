"""Safety figures are flagged on their own bounds, whatever the tracking errors say.

The summaries here are hand-written (not walks): each test sets the one figure it is about.
"""

from __future__ import annotations

from backend.bench.safety_figures import safety_flags

SAFE = {"strides": 8, "falls": 0, "toe_catches": 0, "heel_strikes_without_stance": 0,
        "heel_strike_to_stance_ms_median": 24.0, "heel_strike_to_stance_ms_max": 30.0,
        "loaded_swing_ms_per_stride": 4.0, "loaded_swing_ms_max_stride": 9.0, "knee_angle_rmse_deg": 3.0}


def figures(flags: list[dict]) -> dict[str, str]:
    return {f["figure"]: f["severity"] for f in flags}


def test_a_safe_walk_has_no_flags():
    assert safety_flags(SAFE, SAFE) == []


def test_toe_catches_are_bad_even_when_the_table_tracks_better():
    table = {**SAFE, "toe_catches": 7, "knee_angle_rmse_deg": 1.0}
    flags = safety_flags(table, SAFE)
    assert figures(flags) == {"toe_catches": "bad"}
    assert "7" in flags[0]["message"] and "trip" in flags[0]["message"] and flags[0]["fsmic_value"] == 0


def test_a_late_stance_entry_is_flagged_against_its_bound_and_against_the_fsmic():
    # the example: 101 ms from foot contact to stance against the FSMIC's 28 ms
    flags = safety_flags({**SAFE, "heel_strike_to_stance_ms_max": 101.0}, {**SAFE, "heel_strike_to_stance_ms_max": 28.0})
    assert figures(flags) == {"heel_strike_to_stance_ms_max": "bad"}       # beyond its bound: it gates, as a fall
    assert "101 ms" in flags[0]["message"] and "FSMIC 28 ms" in flags[0]["message"] and "bound 50 ms" in flags[0]["message"]
    # within 50 ms but 20 ms behind the benchmark: still flagged
    late = {**SAFE, "heel_strike_to_stance_ms_max": 45.0}
    assert figures(safety_flags(late, {**SAFE, "heel_strike_to_stance_ms_max": 20.0}))
    assert not safety_flags(late, {**SAFE, "heel_strike_to_stance_ms_max": 40.0})


def test_loaded_swing_time_is_judged_on_the_longest_stride_against_its_one_bound():
    assert figures(safety_flags({**SAFE, "loaded_swing_ms_max_stride": 19.0}, SAFE)) == {}
    assert figures(safety_flags({**SAFE, "loaded_swing_ms_max_stride": 30.0}, SAFE)) == {
        "loaded_swing_ms_max_stride": "bad"}
    # a stored preview from before the longest stride was measured: the mean per stride, and it says so
    old = {k: v for k, v in SAFE.items() if k != "loaded_swing_ms_max_stride"}
    [flag] = safety_flags({**old, "loaded_swing_ms_per_stride": 30.0}, old)
    assert flag["figure"] == "loaded_swing_ms_per_stride" and "on average" in flag["message"]


def test_every_figure_beyond_its_bound_is_flagged_and_a_walk_without_strides_is_not_called_safe():
    flags = safety_flags({**SAFE, "heel_strike_to_stance_ms_max": 90.0, "falls": 2}, SAFE)
    assert figures(flags) == {"falls": "bad", "heel_strike_to_stance_ms_max": "bad"}
    none = {**SAFE, "strides": 0, "heel_strikes_without_stance": None, "heel_strike_to_stance_ms_max": None}
    assert figures(safety_flags(none, SAFE)) == {"strides": "bad"}


def test_a_leg_that_does_not_carry_the_body_is_flagged_in_a_prosthetists_words():
    carried = {**SAFE, "hip_sink_max_mm": 30.0, "support_deficit_max_bw": 0.8, "stance_knee_flexion_peak_max_deg": 22.0,
               "reference_stance_knee_flexion_peak_deg": 19.0}
    assert safety_flags(carried, SAFE) == []
    sinking = {**carried, "hip_sink_max_mm": 92.0, "support_deficit_max_bw": 2.3, "stance_knee_flexion_peak_max_deg": 46.0}
    flags = safety_flags(sinking, carried)
    assert figures(flags) == {"hip_sink_max_mm": "bad", "support_deficit_max_bw": "bad",
                              "stance_knee_flexion_peak_max_deg": "bad"}     # each gates approval and push
    words = {f["figure"]: f["message"] for f in flags}
    assert "92 mm" in words["hip_sink_max_mm"] and "2.30 body weights" in words["support_deficit_max_bw"]
    assert "46°" in words["stance_knee_flexion_peak_max_deg"] and "people: 19°" in words["stance_knee_flexion_peak_max_deg"]
    assert next(f for f in flags if f["figure"] == "hip_sink_max_mm")["fsmic_value"] == 30.0
