"""quasitune simulate and compare."""

from __future__ import annotations

import json

from backend.cli import main


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
    vs = learned["vs_fsmic"]
    lo, hi = vs["knee_angle_rmse_difference_ci95_deg"]
    expected = "learned lower" if hi < 0 else "FSMIC lower" if lo > 0 else "not resolved"
    assert lo <= vs["knee_angle_rmse_difference_deg"] <= hi and vs["knee_angle_verdict"] == expected
    assert f"{vs['knee_angle_rmse_difference_deg']:+.2f} [{lo:+.2f}, {hi:+.2f}] {expected}" in text
    assert "vs_fsmic" not in next(r for r in rows if r["controller"] == "fsmic")


def test_cli_walks_a_course_file_with_the_adaptive_leg_and_refuses_a_bad_course(capsys, tmp_path):
    course = tmp_path / "course.json"
    course.write_text(json.dumps({"name": "tiny", "transition_s": 1.0, "segments": [
        {"duration_s": 4, "speed_mps": 1.0, "incline_deg": 0}, {"duration_s": 4, "speed_mps": 1.2, "incline_deg": 4}]}))
    assert main(["simulate", "--course", str(course), "--controller", "adaptive", "--format", "json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["course"] == "tiny" and out["controller"] == "adaptive" and "estimation" in out
    assert [b["incline_deg"] for b in out["by_segment"]] == [0, 4] and out["falls"] == 0
    assert main(["simulate", "--course", "moon", "--controller", "adaptive"]) == 2
    assert "unknown course" in capsys.readouterr().err
    assert main(["simulate", "--speed", "1.2", "--controller", "adaptive"]) == 2
    assert "course" in capsys.readouterr().err


def test_cli_walks_a_table_from_a_file_and_an_unsafe_one_only_marked_as_a_bench_study(capsys, tmp_path, model):
    body = model.propose(1.2, 0.0, 75.0).to_dict()
    good = tmp_path / "table.json"
    good.write_text(json.dumps(body))
    assert main(["simulate", "--table", str(good), "--seconds", "4", "--format", "json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["controller"] == "table" and out["speed_mps"] == 1.2 and out["mass_kg"] == 75.0
    for key in ("hip_sink_max_mm", "support_deficit_max_bw", "stance_knee_flexion_peak_deg", "falls"):
        assert key in out
    for row in body["table"]:
        if row["joint"] == "knee" and row["subphase"].startswith("stance"):
            row["k_Nm_per_rad"] = -1.0
    soft = tmp_path / "soft.json"
    soft.write_text(json.dumps(body))
    assert main(["simulate", "--table", str(soft), "--seconds", "2"]) == 2       # limits as on the device
    assert "stance support floor" in capsys.readouterr().err
    assert main(["simulate", "--table", str(soft), "--seconds", "2", "--skip-limits"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines and all(line.startswith("[UNCHECKED TABLE, bench study only") for line in lines)
    assert main(["simulate", "--table", str(soft), "--seconds", "2", "--skip-limits", "--format", "json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["limits"].startswith("UNCHECKED") and any("support floor" in v for v in out["limit_violations"])
    assert main(["simulate", "--speed", "1.2", "--skip-limits"]) == 2
    assert "--table" in capsys.readouterr().err


def test_cli_refine_walks_refines_and_evaluates_on_a_leg_and_writes_the_contract(capsys, tmp_path):
    from controller_core.envelope import Envelope
    from device_bridge.as_run import as_run

    train, evaluate, out = tmp_path / "train.json", tmp_path / "eval.json", tmp_path / "refine.json"
    train.write_text(json.dumps({"name": "level", "transition_s": 1.0, "segments": [
        {"duration_s": 30, "speed_mps": 1.2, "incline_deg": 0}]}))
    evaluate.write_text(json.dumps({"name": "short", "transition_s": 1.0, "segments": [
        {"duration_s": 6, "speed_mps": 1.0, "incline_deg": 0}, {"duration_s": 6, "speed_mps": 1.2, "incline_deg": 3}]}))
    settled = tmp_path / "settled.json"
    settled.write_text(json.dumps({"name": "two", "segments": [{"duration_s": 8, "speed_mps": 1.2, "incline_deg": 0},
                                                               {"duration_s": 8, "speed_mps": 1.0, "incline_deg": 5}]}))
    assert main(["refine", "--leg", "heavy_foot", "--train-course", str(train), "--eval-course", str(evaluate),
                 "--settled-course", str(settled), "--rounds", "2", "--seconds-per-round", "20",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Leg: heavy powered ankle and foot" in text and "| refined |" in text and "Refined minus original" in text
    assert "(task, quantity) pairs within tolerance" in text
    result = json.loads(out.read_text())
    assert [r["round"] for r in result["rounds"]] == [1, 2]
    for r in result["rounds"]:
        assert r["strides"] >= r["strides_used"] >= 0 and isinstance(r["nodes_changed"], list)
        assert all(set(c) >= {"node", "field", "before", "after", "why"} for c in r["changes"])
        assert r["bench_walks"] >= 0
        for n in r["nodes"]:      # bias, its interval and the spread no row moves, per node and quantity
            assert all({"error", "ci95", "spread"} <= set(q) for q in n["quantities"].values())
    for name in ("original", "refined"):    # the settled tasks: bias and spread per task and quantity, on this leg
        st = result["evaluation"][name]["settled"]
        assert st["leg"] == "heavy powered ankle and foot" and [t["speed_mps"] for t in st["tasks"]] == [1.2, 1.0]
        assert 0.0 <= st["settled_within_tolerance_fraction"] <= 1.0 and st["pairs"] > 0
        q = st["tasks"][0]["quantities"]["knee_swing_flexion_peak_deg"]
        assert q["within_tolerance"] == (abs(q["bias"]) <= 2.0) and q["ci95"][0] <= q["bias"] <= q["ci95"][1]
    for name in ("original", "refined", "fsmic"):
        e = result["evaluation"][name]
        assert {"falls", "toe_catches", "loaded_swing_ms_max_stride", "knee_angle_rmse_deg", "ankle_angle_rmse_deg",
                "feature_abs_error"} <= set(e)
        assert "knee_swing_flexion_peak_deg" in e["feature_abs_error"]
    for ch in ("knee_angle_deg", "ankle_angle_deg", "knee_moment_Nm_per_kg", "ankle_moment_Nm_per_kg"):
        d = result["refined_minus_original"][ch]
        assert d["verdict"] in ("refined lower", "original lower", "not resolved", None)
    # whatever the rounds did, the refined envelope is one the device would run
    assert as_run(Envelope.from_json(result["refined_envelope"])).violations == []
    assert main(["refine", "--rounds", "0", "--seconds-per-round", "10"]) == 2
    assert "rounds" in capsys.readouterr().err


def test_cli_stance_response_prints_the_study_and_writes_it(capsys, tmp_path):
    out = tmp_path / "stance.json"
    assert main(["stance-response", "--seconds", "3", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "bench study (limits not checked)" in text and "| the bench's person | learned |" in text
    rows = json.loads(out.read_text())
    assert {r["person"] for r in rows} >= {"the bench's person", "soft progression (2 kN/m)"}


def test_cli_stumble_prints_each_stumble_and_writes_them_and_refuses_unpaired_tasks(capsys, tmp_path):
    out = tmp_path / "stumble.json"
    assert main(["stumble", "--speeds", "1.2", "--inclines", "0", "--kinds", "early_landing",
                 "--controllers", "fsmic", "--out", str(out)]) == 0
    assert "early_landing" in capsys.readouterr().out
    (row,) = json.loads(out.read_text())
    assert row["controller"] == "fsmic" and row["disturbed"] and "strides_to_recover" in row and row["clean"]
    assert main(["stumble", "--speeds", "1.2", "1.0", "--inclines", "0"]) == 2
    assert "one --inclines value per --speeds value" in capsys.readouterr().err
