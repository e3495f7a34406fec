"""The default model's proposal, the parameter table's safety check, and the CLI as a user runs it."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from controller_core import InvalidTaskError, ParameterTable, SafetyLimitError, assert_safe, check_table
from controller_core.table import ParameterRow

CLI = [sys.executable, "-m", "backend.cli"]


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
    # Rábago 2016 controls at +5°: dorsiflexion peak 16.9° and plantarflexor peak −1.58 N·m/kg
    assert uphill["ankle_dorsiflexion_peak"].value > level["ankle_dorsiflexion_peak"].value + math.radians(3)
    assert uphill["ankle_plantarflexor_moment_peak"].value < level["ankle_plantarflexor_moment_peak"].value - 0.1
    steep = model.propose(1.2, 15.0, 75.0)
    assert steep.extrapolation
    flat = model.propose(1.2, 0.0, 75.0)
    assert np.mean(steep.stds["knee_angle"]) > np.mean(flat.stds["knee_angle"])


@pytest.mark.parametrize(("speed", "incline", "mass", "msg"), [
    (0.0, 0.0, 75.0, "speed_mps"), (3.5, 0.0, 75.0, "speed_mps"), (float("nan"), 0.0, 75.0, "finite"),
    (1.2, 25.0, 75.0, "incline_deg"), (1.2, 0.0, 10.0, "mass_kg"), (1.2, 0.0, 250.0, "mass_kg"),
])
def test_bad_tasks_are_refused(model, speed, incline, mass, msg):
    with pytest.raises(InvalidTaskError, match=msg):
        model.propose(speed, incline, mass)


def test_safety_check_names_the_offending_field(model):
    table = model.propose(1.25, 0.0, 75.0).table
    assert check_table(table) == []
    rows = [r.model_copy(update={"k_Nm_per_rad": -5000.0}) if (r.joint, r.subphase) == ("ankle", "stance_extension")
            else r for r in table.rows]
    bad = ParameterTable(rows=rows, thresholds=table.thresholds, provenance=table.provenance)
    with pytest.raises(SafetyLimitError, match=r"ankle\.stance_extension\.k_Nm_per_rad = -5000"):
        assert_safe(bad)
    with pytest.raises(ValueError, match="finite"):
        ParameterRow.model_validate({**rows[0].model_dump(), "theta_e_deg": float("nan")})
    with pytest.raises(ValueError, match="one row per joint"):
        ParameterTable(rows=rows[:-1], thresholds=table.thresholds, provenance=table.provenance)


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=300)


def test_cli_predict_json_is_one_object():
    out = _run("predict", "--speed", "1.25", "--incline", "0", "--mass", "75", "--format", "json")
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    for key in ("task", "model", "extrapolation", "features", "curves", "table"):
        assert key in d
    f = d["features"][0]
    assert set(f) >= {"joint", "quantity", "name", "phase", "value", "std", "unit"}
    assert set(d["table"][0]) >= {"joint", "subphase", "k_Nm_per_rad", "theta_e_deg", "b_Nm_s_per_rad", "r2"}


@pytest.mark.parametrize("args", [["--speed", "0"], ["--speed", "nan"], ["--speed", "1", "--incline", "30"],
                                  ["--speed", "1", "--mass", "500"], ["--speed=-0.5"]])
def test_cli_bad_input_exits_2_with_one_line(args):
    out = _run("predict", *args)
    assert out.returncode == 2 and out.stdout == ""
    assert len(out.stderr.strip().splitlines()) == 1 and "error" in out.stderr


def test_cli_readable_table_and_plot(tmp_path):
    out = _run("predict", "--speed", "1.4", "--incline", "3")
    assert out.returncode == 0 and "Parameter table" in out.stdout and "stance_flexion" in out.stdout
    png = tmp_path / "fig.png"
    out = _run("plot", "--speed", "1.4", "--out", str(png))
    assert out.returncode == 0 and png.stat().st_size > 50_000


def test_cli_train_on_standard_format_then_predict_with_it(reference, tmp_path):
    from controller_core.phase_table import reference_to_phase_table

    data = tmp_path / "bovi_standard.parquet"
    reference_to_phase_table(reference).to_parquet(data)  # real Bovi rows in the standard format
    out = _run("train", "--data", str(data), "--out", str(tmp_path / "m"))
    assert out.returncode == 0, out.stderr
    assert "training" in out.stderr  # the progress bar
    pred = _run("predict", "--speed", "1.3", "--model", str(tmp_path / "m"), "--format", "json")
    assert pred.returncode == 0, pred.stderr
    assert json.loads(pred.stdout)["task"]["speed_mps"] == 1.3
    missing = _run("predict", "--speed", "1.3", "--model", str(tmp_path / "nope"))
    assert missing.returncode == 2 and "no model" in missing.stderr


def test_cli_evaluate_writes_json(tmp_path):
    out = _run("evaluate", "--out", str(tmp_path / "eval.json"))
    assert out.returncode == 0, out.stderr
    r = json.loads((tmp_path / "eval.json").read_text())
    assert set(r["curve_rmse"]["knee_angle_deg"]) == {"proposal", "reference", "gmr", "linear", "nearest",
                                                          "between_subject_sd"}
    assert len(r["folds"]) == 5
