"""The lab's commands (``lab/cli.py``) as people run them: through ``quasitune``, which finds them at the
``quasitune.commands`` entry point, in-process."""

from __future__ import annotations

import functools
import json

from backend.cli import main


def test_cli_plot_writes_the_figure(tmp_path):
    png = tmp_path / "fig.png"
    assert main(["plot", "--speed", "1.4", "--out", str(png)]) == 0
    assert png.stat().st_size > 50_000


def test_cli_evaluate_writes_json(capsys, monkeypatch, reference, tmp_path):
    from controller_core.feature_model import FeatureModel
    from controller_core.joint_reference import JointReference
    from lab import evaluation

    # three real conditions, single-start GPR fits and six mixture components keep the leave-one-out short; the
    # shipped five and the default settings take the same code path
    monkeypatch.setattr(evaluation, "load_shipped_reference", lambda: reference.subset([0, 2, 4]))
    monkeypatch.setattr(evaluation, "train", functools.partial(evaluation.train, feature_model=FeatureModel(n_restarts=0),
                                                               joint_reference=JointReference(n_components=6)))
    assert main(["evaluate", "--out", str(tmp_path / "eval.json")]) == 0
    text = capsys.readouterr().out
    assert "Leave-one-condition-out curve RMSE" in text and "Leave-one-ramp-condition-out" in text
    assert "Change from level walking against UM21" in text
    r = json.loads((tmp_path / "eval.json").read_text())
    assert set(r["curve_rmse"]["knee_angle_deg"]) == {"proposal", "reference", "gmr", "linear", "nearest",
                                                          "between_subject_sd"}
    assert [f["held_out"] for f in r["folds"]] == [reference.records[i].name for i in (0, 2, 4)]
    assert [f["incline_deg"] for f in r["incline"]["folds"]] == [-10.0, 10.0]
    assert set(r["um21_envelopes"]["sides"]) == {"incline_walking", "decline_walking"}


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
