"""The simulated bench: real reference data in, physics out, metrics that can fail."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from backend.cli import main
from controller_core.gait_metrics import (
    bootstrap_rmse,
    heel_strikes,
    percentile_interval,
    rmse,
    rmse_difference,
    state_entry_delays,
    stride_curves,
    strided_errors,
)
from controller_core.quasi_stiffness import fit_quasi_stiffness
from controller_core.reference import load_shipped_reference
from controller_core.walking_reference import level_walking_reference
from device_bridge.sim.bench_trajectory import (
    hip_height_mismatch_mm,
    plan_bench_trajectory,
    stance_hip_height_m,
    thigh_angle_rad,
)
from device_bridge.sim.experiments import against_fsmic, make_controller
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import run_walk, score_walk


def test_walking_reference_reproduces_a_record_and_interpolates_between_two():
    ref_set = load_shipped_reference()
    rec = min(ref_set.records, key=lambda r: abs(r.task["speed_mps"] - 1.49))
    at = level_walking_reference(rec.task["speed_mps"])
    np.testing.assert_allclose(at.knee_angle_rad, rec.mean["knee_angle"], atol=1e-6)
    np.testing.assert_allclose(at.ankle_angle_rad, rec.mean["ankle_angle"], atol=1e-6)
    mid = level_walking_reference(1.7)
    fast = level_walking_reference(1.95)
    assert not mid.extrapolation and level_walking_reference(2.5).extrapolation
    assert at.stride_time_s > mid.stride_time_s > fast.stride_time_s     # faster walking, shorter strides
    with pytest.raises(ValueError, match="speed_mps"):
        level_walking_reference(float("nan"))


def test_bench_puts_the_reference_foot_flat_and_on_the_floor_in_mid_stance():
    ref = level_walking_reference(1.2)
    g = LegGeometry()
    thigh = thigh_angle_rad(ref, 0.0)
    mid = (ref.phase >= 0.15) & (ref.phase <= 0.40)
    pitch = thigh - ref.knee_angle_rad + ref.ankle_angle_rad
    assert abs(np.mean(pitch[mid])) < 1e-9                      # flat on average, by construction
    h = stance_hip_height_m(thigh, ref.knee_angle_rad, ref.ankle_angle_rad, g, 0.0)
    leg = g.thigh_m + g.shank_m + g.ankle_height_m
    assert np.all(h[mid] < leg) and np.all(h[mid] > 0.85 * leg)   # a bent stance leg, never longer than straight
    traj = plan_bench_trajectory(ref, g, 75.0, 2.0)
    assert traj.x_m[-1] - traj.x_m[0] == pytest.approx(1.2 * (2.0 - 0.001), rel=1e-6)   # belt speed
    assert traj.load_N.max() == pytest.approx(ref.vgrf_bw.max() * 75.0 * 9.81, rel=0.05)


def test_gait_metrics_on_a_known_signal():
    contact = np.zeros(1000)
    for start in (100, 400, 700):
        contact[start:start + 150] = 500.0
    strikes = heel_strikes(contact, 20.0, 50)
    assert strikes.tolist() == [100, 400, 700]
    curves = stride_curves(np.arange(1000.0), strikes)
    assert curves.shape == (2, 101)
    assert curves[0, 0] == 100 and curves[0, -1] == 400
    assert rmse(np.ones(5), np.zeros(5)) == 1.0


def test_state_entry_delays_on_a_scripted_machine():
    # synthetic, labelled: a machine that enters state 0 five samples after the first event, two samples before
    # the second, and never within the third event's stride (it enters only after the fourth event)
    states = np.full(100, 3)
    states[15:30] = 0
    states[48:60] = 0
    states[95:] = 0
    events = np.array([10, 50, 70, 90])
    delays = state_entry_delays(states, 0, events, lead_samples=3)
    assert delays[:2].tolist() == [5.0, -2.0]
    assert np.isnan(delays[2])               # the entry at 95 belongs to the event at 90, not to 70
    assert delays[3] == 5.0
    # without the lead, an entry before the event is not this event's: the next one is after the next event
    assert np.isnan(state_entry_delays(states, 0, events, lead_samples=0)[1])
    with pytest.raises(ValueError, match="lead_samples"):
        state_entry_delays(states, 0, events, lead_samples=-1)


def test_per_stride_rmse_counts_errors_that_cancel_in_the_stride_average():
    # synthetic, labelled: strides alternately 2 deg above and below the reference
    ref = np.sin(np.linspace(0, 2 * np.pi, 101))
    strides = np.array([ref + 2.0, ref - 2.0, ref + 2.0, ref - 2.0])
    _, errors = strided_errors({"knee_angle_deg": strides}, ["knee_angle_deg"], {"knee_angle_deg": ref},
                               per_stride=True)
    assert errors["knee_angle_rmse_deg"] == pytest.approx(0.0, abs=1e-12)
    assert errors["knee_angle_per_stride_rmse_deg"] == pytest.approx(2.0)
    _, plain = strided_errors({"knee_angle_deg": strides}, ["knee_angle_deg"], {"knee_angle_deg": ref})
    assert "knee_angle_per_stride_rmse_deg" not in plain


def test_stride_bootstrap_brackets_the_rmse_and_tells_a_real_difference_from_stride_noise():
    # synthetic strides (a sine "reference" plus offsets and noise), only to check the statistics
    rng = np.random.default_rng(7)
    grid = np.linspace(0.0, 1.0, 101)
    ref = 10.0 * np.sin(2 * np.pi * grid)
    same = np.tile(ref + 2.0, (12, 1))                  # every stride identical: no stride-to-stride spread
    boots = bootstrap_rmse(same, ref)
    assert np.allclose(boots, 2.0)
    noisy = ref + 2.0 + rng.normal(0.0, 1.5, (12, 101)) + rng.normal(0.0, 1.0, (12, 1))
    lo, hi = percentile_interval(bootstrap_rmse(noisy, ref))
    assert lo < rmse(noisy.mean(axis=0), ref) < hi and hi - lo > 0.1
    wider = ref + 2.0 + rng.normal(0.0, 1.5, (12, 101)) + rng.normal(0.0, 4.0, (12, 1))
    lo_w, hi_w = percentile_interval(bootstrap_rmse(wider, ref))
    assert hi_w - lo_w > hi - lo                        # more stride-to-stride variation, a wider interval

    better = ref + 0.5 + rng.normal(0.0, 0.5, (12, 101))
    d = rmse_difference(better, noisy, ref)
    assert d["verdict"] == "A lower" and d["difference"] < 0 and d["interval"][1] < 0
    assert rmse_difference(noisy, better, ref)["verdict"] == "B lower"
    twin = ref + 2.0 + rng.normal(0.0, 1.5, (12, 101)) + rng.normal(0.0, 1.0, (12, 1))
    assert rmse_difference(twin, noisy, ref)["verdict"] == "not resolved"   # same process, different strides
    with pytest.raises(ValueError, match="two strides"):
        bootstrap_rmse(same[:1], ref)
    with pytest.raises(ValueError, match="grid points"):
        bootstrap_rmse(same[:, :50], ref)
    with pytest.raises(ValueError, match="level"):
        percentile_interval(boots, 1.5)


def test_passivity_guard_replaces_an_unstable_swing_line():
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
    for name in ("stance_flexion", "stance_extension", "swing_extension"):   # θe outside their spans: kept
        assert by_name[name].k_Nm_per_rad == pytest.approx(20.0) and not by_name[name].guarded
    with pytest.raises(ValueError, match="negative"):
        fit_quasi_stiffness(phase, theta, tau, (0.2, 0.5, 0.8), (0.0, 2.0), max_k_Nm_per_rad=5.0)


def test_hip_height_mismatch_is_zero_when_both_legs_agree_and_measures_the_plan_otherwise():
    # synthetic gait, said so: a leg frozen at one posture touches the floor at one height all cycle long,
    # so the two legs agree in double support and the bench's path meets the touching height everywhere
    ref = level_walking_reference(1.2)
    frozen = dataclasses.replace(ref, hip_angle_rad=np.full_like(ref.phase, 0.2),
                                 knee_angle_rad=np.full_like(ref.phase, 0.1), ankle_angle_rad=np.zeros_like(ref.phase))
    g = LegGeometry()
    agree = hip_height_mismatch_mm(frozen, g)
    assert agree["heel_strike"] == pytest.approx(0.0, abs=1e-6) and agree["pre_swing"] == pytest.approx(0.0, abs=1e-6)
    # the shipped curves: the two legs disagree in double support, so the hip is too high when the foot should
    # land and too low in pre-swing (docs/results.md); the heel-strike figure is the planned path's own
    real = hip_height_mismatch_mm(ref, g)
    assert real["heel_strike"] > 5.0 and real["pre_swing"] < -20.0
    traj = plan_bench_trajectory(ref, g, 75.0, 0.01, start_phase=0.0)
    thigh = thigh_angle_rad(ref, 0.0)
    touch = stance_hip_height_m(thigh, ref.knee_angle_rad, ref.ankle_angle_rad, g, 0.0)
    assert real["heel_strike"] == pytest.approx(1000.0 * (traj.height_m[0] - touch[0]), abs=1e-6)


@pytest.fixture(scope="module")
def fsmic_walk():
    ref = level_walking_reference(1.2)
    log = run_walk(make_controller("fsmic", 1.2, 0.0, 75.0), ref, 75.0, seconds=7.0)
    return log, score_walk(log, ref)


def test_fsmic_walks_strides_on_the_bench_without_falling(fsmic_walk):
    s = fsmic_walk[1].summary
    assert s["strides"] >= 3
    assert s["falls"] == 0
    assert abs(s["stride_time_s"] - s["reference_stride_time_s"]) < 0.1   # the leg keeps the bench's cadence
    for key in ("knee_angle_rmse_deg", "ankle_angle_rmse_deg", "knee_moment_rmse_Nm_per_kg", "ankle_moment_rmse_Nm_per_kg"):
        assert math.isfinite(s[key]) and s[key] > 0
    assert all(v > 0 for v in s["time_in_state_s"].values())           # every state visited
    assert s["guard_transitions"] == 0
    assert s["bench_hip_height_mismatch_mm"] == hip_height_mismatch_mm(level_walking_reference(1.2), LegGeometry())
    lo, hi = s["knee_angle_rmse_ci95_deg"]                              # how sure: an interval over the strides
    assert 0 < lo <= hi and hi - lo < s["knee_angle_rmse_deg"]
    assert s["ankle_moment_rmse_ci95_Nm_per_kg"][0] <= s["ankle_moment_rmse_ci95_Nm_per_kg"][1]
    for channel in ("knee_angle", "ankle_angle"):   # an average curve is never further off than its strides
        assert s[f"{channel}_per_stride_rmse_deg"] >= s[f"{channel}_rmse_deg"]
    # heel strike reaches stance on every stride, and never sooner than the 20 ms event hold allows
    assert s["heel_strikes_without_stance"] == 0
    assert 20.0 <= s["heel_strike_to_stance_ms_median"] <= s["heel_strike_to_stance_ms_max"] < 500.0
    assert s["loaded_swing_ms_per_stride"] >= 0.0


@pytest.fixture(scope="module")
def quasi_stiffness_walk(model):
    ref = level_walking_reference(1.2)
    log = run_walk(make_controller("quasi-stiffness", 1.2, 0.0, 75.0, model), ref, 75.0, seconds=7.0)
    return log, score_walk(log, ref)


def test_learned_table_walks_strides_on_the_bench_without_falling(quasi_stiffness_walk):
    s = quasi_stiffness_walk[1].summary
    assert s["strides"] >= 3
    assert s["falls"] == 0 and s["toe_catches"] == 0
    assert abs(s["stride_time_s"] - s["reference_stride_time_s"]) < 0.1
    assert all(v > 0 for v in s["time_in_state_s"].values())
    assert s["guard_transitions"] == 0
    # the swing targets carry the knee through swing: it is nearly straight again before heel strike
    log = quasi_stiffness_walk[0].channels
    strikes = heel_strikes(log["contact_N"], 0.02 * 75.0 * 9.81, 150)
    late = [s for s in strikes if log["time_s"][s] > 2.0]
    assert late and max(math.degrees(log["knee_angle_rad"][s]) for s in late) < 25.0


def test_learned_against_fsmic_reports_each_difference_with_an_interval_and_a_verdict(quasi_stiffness_walk, fsmic_walk):
    learned, fsmic = quasi_stiffness_walk[1], fsmic_walk[1]
    v = against_fsmic(learned, fsmic)
    d = v["ankle_angle_rmse_difference_deg"]
    assert d == pytest.approx(learned.summary["ankle_angle_rmse_deg"] - fsmic.summary["ankle_angle_rmse_deg"])
    lo, hi = v["ankle_angle_rmse_difference_ci95_deg"]
    assert lo <= hi
    expected = "learned lower" if hi < 0 else "FSMIC lower" if lo > 0 else "not resolved"
    assert v["ankle_angle_verdict"] == expected
    assert set(v) >= {"knee_angle_verdict", "knee_moment_rmse_difference_Nm_per_kg",
                      "ankle_moment_rmse_difference_ci95_Nm_per_kg"}
    assert against_fsmic(learned, dataclasses.replace(fsmic, stride_curves={}))["knee_angle_verdict"] is None


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


def test_cli_simulate_prints_json_and_refuses_bad_input(capsys, tmp_path):
    rec = tmp_path / "walk.csv"
    assert main(["simulate", "--speed", "1.2", "--controller", "quasi-stiffness", "--seconds", "3",
                 "--format", "json", "--record", str(rec)]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("strides", "falls", "toe_catches", "knee_angle_rmse_deg", "ankle_angle_rmse_deg",
                "knee_moment_rmse_Nm_per_kg", "ankle_moment_rmse_Nm_per_kg", "time_in_state_s", "real_time_factor"):
        assert key in out
    assert out["controller"] == "quasi-stiffness" and out["real_time_factor"] > 1.0
    header = rec.read_text().splitlines()[0].split(",")
    assert "knee_angle_deg" in header and "ankle_torque_Nm" in header and len(rec.read_text().splitlines()) == 3001
    assert main(["simulate", "--speed", "0", "--controller", "fsmic"]) == 2
    assert "speed" in capsys.readouterr().err
    assert main(["simulate", "--speed", "1.2", "--controller", "fsmic", "--seconds", "nan"]) == 2
    assert "seconds" in capsys.readouterr().err


def test_cli_compare_prints_the_table_and_the_verdicts_and_writes_them(capsys, tmp_path):
    out = tmp_path / "compare.json"
    assert main(["compare", "--speeds", "1.2", "--seconds", "5", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "| 1.20 | 0.00 | quasi-stiffness |" in text and "| 1.20 | 0.00 | fsmic |" in text
    assert "95 % interval over strides" in text
    rows = json.loads(out.read_text())
    learned = next(r for r in rows if r["controller"] == "quasi-stiffness")
    verdict = learned["vs_fsmic"]["knee_angle_verdict"]
    assert verdict in ("learned lower", "FSMIC lower", "not resolved") and verdict in text
    assert "vs_fsmic" not in next(r for r in rows if r["controller"] == "fsmic")
