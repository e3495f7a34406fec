"""How command results are printed."""

from __future__ import annotations

import json

from backend.cli.formatting import emit, print_proposal


def test_a_proposal_prints_as_tables_with_units(model, capsys):
    print_proposal(model.propose(1.2, 0.0, 75.0).to_dict())
    out = capsys.readouterr().out
    assert out.startswith("Task: 1.20 m/s, incline +0.0 deg, patient 75.0 kg")
    assert "k N·m/rad" in out and "θe deg" in out and "Safety limits: all within limits" in out
    assert out.count("knee   stance_flexion") == 1 and "swing target: not a fit" in out


def test_flat_results_print_as_json_or_aligned_lines(capsys):
    emit({"falls": 0, "knee_angle_rmse_deg": 6.0}, "json")
    assert json.loads(capsys.readouterr().out) == {"falls": 0, "knee_angle_rmse_deg": 6.0}
    emit({"falls": 0}, "text")
    assert capsys.readouterr().out == f"{'falls':40s} 0\n"
