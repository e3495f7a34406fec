"""quasitune simulate and stumble."""

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




def test_cli_stumble_prints_each_stumble_and_writes_them_and_refuses_unpaired_tasks(capsys, tmp_path):
    out = tmp_path / "stumble.json"
    assert main(["stumble", "--speeds", "1.2", "--inclines", "0", "--kinds", "early_landing",
                 "--controllers", "fsmic", "--out", str(out)]) == 0
    assert "early_landing" in capsys.readouterr().out
    (row,) = json.loads(out.read_text())
    assert row["controller"] == "fsmic" and row["disturbed"] and "strides_to_recover" in row and row["clean"]
    assert main(["stumble", "--speeds", "1.2", "1.0", "--inclines", "0"]) == 2
    assert "one --inclines value per --speeds value" in capsys.readouterr().err
