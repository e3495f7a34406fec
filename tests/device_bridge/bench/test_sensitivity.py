"""Measuring the refinement's sensitivity on the bench: the differences and the limits (the walks themselves are the
bench's, tested with it; the shipped grid's content in tests/controller_core/test_refine_sensitivity.py)."""

from __future__ import annotations

import math

import pytest

from controller_core.refine import PARAMETERS
from controller_core.refine_evidence import QUANTITIES
from controller_core.table import check_table
from device_bridge.bench.sensitivity import LOG_STEP, THETA_STEP_DEG, node_sensitivity, perturbed


def test_central_differences_are_per_unit_of_the_stepping_value():
    keys = [q.key for q in QUANTITIES]
    results, values = [], []
    for c, p in enumerate(PARAMETERS):
        h = LOG_STEP if p.relative else THETA_STEP_DEG
        results += [{k: 1.0 + c * h for k in keys}, {k: 1.0 - c * h for k in keys}]   # a made-up gain of c
        values += [h, -h]
    results[2] = None                                                                # a walk that fell
    J = node_sensitivity(results, values)
    assert J[0][0] == pytest.approx(0.0) and J[3][5] == pytest.approx(5.0)
    assert all(row[1] is None for row in J)                                          # unresolved, not guessed


def test_a_step_past_a_limit_is_held_at_the_limit_and_measured_from_there(model):
    table = model.propose(1.1, 0.0, 75.0).table
    p = next(p for p in PARAMETERS if p.field == "ankle.stance_extension.theta_e_deg")
    at_limit = perturbed(table.model_copy(update={"rows": [
        r.model_copy(update={"theta_e_deg": -29.0}) if (r.joint, r.subphase) == ("ankle", "stance_extension") else r
        for r in table.rows]}), p, -1.0)
    assert at_limit[1] == pytest.approx(-30.0) and check_table(at_limit[0]) == []
    k = next(p for p in PARAMETERS if p.field == "knee.swing_extension.b_Nm_s_per_rad")
    up, value = perturbed(table, k, 1.0)
    assert value == pytest.approx(math.log(table.row("knee", "swing_extension").b_Nm_s_per_rad) + LOG_STEP)
    assert up.row("knee", "swing_extension").b_Nm_s_per_rad == pytest.approx(math.exp(value))


def test_a_measured_grid_gives_back_a_known_response(model, monkeypatch):
    """A made-up bench (said here): the stance knee error is 0.5 × the terminal-swing θe + 10 × ln of its damping, the
    rest 0. The measurement over a 2 × 2 grid must give those gains back, in the form the refinement reads."""
    import device_bridge.bench.sensitivity as sensitivity
    from controller_core.refine_sensitivity import BenchSensitivity

    def made_up(table, speed_mps, incline_deg, mass_kg, model, seconds):
        we = table.row("knee", "swing_extension")
        err = {q.key: 0.0 for q in QUANTITIES}
        err["knee_stance_flexion_peak_deg"] = 0.5 * we.theta_e_deg + 10.0 * math.log(we.b_Nm_s_per_rad)
        return {"strides": 10, "falls": 0, "error": err, "seconds": seconds}

    monkeypatch.setattr(sensitivity, "bench_feature_errors", made_up)
    body = sensitivity.measure_sensitivity(model, (1.0, 1.4), (0.0, 5.0), workers=1)
    grid = BenchSensitivity.from_json(body)
    col = {p.field: c for c, p in enumerate(PARAMETERS)}
    J = grid.at(1.2, 2.5)
    assert J[0, col["knee.swing_extension.theta_e_deg"]] == pytest.approx(0.5, abs=1e-3)
    assert J[0, col["knee.swing_extension.b_Nm_s_per_rad"]] == pytest.approx(10.0, abs=1e-3)
    assert abs(J).sum() == pytest.approx(10.5, abs=1e-2)
    assert body["provenance"]["leg"] == "nominal" and body["provenance"]["seconds_per_walk"] == 16.0
