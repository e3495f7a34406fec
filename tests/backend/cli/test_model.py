"""quasitune predict, train and envelope, run in-process (one subprocess checks the installed entry point)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from backend.cli import main


def test_the_entry_point_runs_as_a_module():
    out = subprocess.run([sys.executable, "-m", "backend.cli", "predict", "--speed", "1.25", "--format", "json"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["task"]["speed_mps"] == 1.25


def test_cli_predict_json_is_one_object(capsys):
    assert main(["predict", "--speed", "1.25", "--incline", "0", "--mass", "75", "--format", "json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["task"] == {"speed_mps": 1.25, "incline_deg": 0.0, "mass_kg": 75.0} and d["extrapolation"] is False
    assert len(d["model"]["data_sha256"]) == 64 and d["safety"] == {"ok": True, "violations": []}
    assert [f["name"] for f in d["features"]][:3] == ["knee_heel_strike_angle", "knee_stance_flexion_peak",
                                                       "knee_swing_flexion_peak"]
    swing = next(f for f in d["features"] if f["name"] == "knee_swing_flexion_peak")
    assert swing["unit"] == "deg" and 50.0 < swing["value"] < 75.0 and 0.6 < swing["phase"] < 0.8
    assert len(d["curves"]["knee_angle_deg"]) == 101 and len(d["table"]) == 8
    stance = [r for r in d["table"] if r["subphase"].startswith("stance")]
    assert all(r["k_Nm_per_rad"] < 0 for r in stance)               # stance rows restore, never inject energy


@pytest.mark.parametrize(("args", "names"), [(["--speed", "0"], "speed_mps"), (["--speed", "nan"], "speed_mps"),
                                            (["--speed", "1", "--incline", "30"], "incline_deg"),
                                            (["--speed", "1", "--mass", "500"], "mass_kg"),
                                            (["--speed=-0.5"], "speed_mps")])
def test_cli_bad_input_exits_2_with_one_line(capsys, args, names):
    assert main(["predict", *args]) == 2
    out = capsys.readouterr()
    assert out.out == ""
    assert len(out.err.strip().splitlines()) == 1 and out.err.startswith("quasitune: error:") and names in out.err


def test_cli_readable_table(capsys):
    assert main(["predict", "--speed", "1.4", "--incline", "3"]) == 0
    text = capsys.readouterr().out
    assert "Parameter table" in text and "stance_flexion" in text


def test_cli_train_on_standard_format_then_predict_with_it(capsys, reference, tmp_path):
    from controller_core.phase_table import reference_to_phase_table

    data = tmp_path / "bovi_standard.parquet"
    reference_to_phase_table(reference).to_parquet(data)  # real Bovi rows in the standard format
    assert main(["train", "--data", str(data), "--out", str(tmp_path / "m")]) == 0
    out = capsys.readouterr()
    assert "training on" in out.err and "(5 conditions) saved to" in out.out
    assert main(["predict", "--speed", "1.3", "--model", str(tmp_path / "m"), "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["task"]["speed_mps"] == 1.3
    assert main(["predict", "--speed", "1.3", "--model", str(tmp_path / "nope")]) == 2
    assert "no model" in capsys.readouterr().err



def test_cli_envelope_prints_the_grid_its_checks_and_crc_and_refuses_a_bad_grid(capsys):
    from backend.cli import main
    from controller_core.content import canonical_json, content_sha256
    from controller_core.envelope import Envelope
    from device_bridge.as_run import as_run

    assert main(["envelope", "--speeds", "0.8", "1.4", "--inclines", "-6", "6", "--grid", "3", "3"]) == 0
    text = capsys.readouterr().out
    assert "Envelope 3 × 3" in text and "CRC-32" in text and "all within limits" in text
    assert main(["envelope", "--grid", "3", "2", "--mass", "80", "--format", "json"]) == 0
    body = json.loads(capsys.readouterr().out)
    env = Envelope.from_json({k: v for k, v in body.items() if k not in ("wire_crc32", "envelope_sha256", "safety")})
    assert env.shape == (3, 2) and env.mass_kg == 80.0 and body["safety"]["ok"] and body["wire_crc32"] > 0
    assert body["envelope_sha256"] == content_sha256(canonical_json(as_run(env).item))
    assert main(["envelope", "--grid", "1", "5"]) == 2
    assert "at least 2" in capsys.readouterr().err


def test_cli_predict_for_a_leg_proposes_its_swing_rows_and_refuses_one_it_cannot_read(capsys):
    """``--leg``: the swing rows are proposed for that leg's inertia, as the server does for a patient's leg; a leg
    that is not there exits 2 naming it."""
    def knee_swing_extension(extra: list[str]) -> dict:
        assert main(["predict", "--speed", "1.2", "--format", "json", *extra]) == 0
        table = json.loads(capsys.readouterr().out)["table"]
        return next(r for r in table if (r["joint"], r["subphase"]) == ("knee", "swing_extension"))

    plain, heavy = knee_swing_extension([]), knee_swing_extension(["--leg", "heavy_foot"])
    assert heavy["k_Nm_per_rad"] < plain["k_Nm_per_rad"] - 10.0          # firmer for the heavier foot's inertia
    assert main(["predict", "--speed", "1.2", "--leg", "no_such_leg"]) == 2
    assert "no_such_leg" in capsys.readouterr().err
