"""A proposal as people and scripts read it: display units with the unit in every name."""

from __future__ import annotations

import math

import pytest


@pytest.fixture(scope="module")
def proposal(model):
    return model.propose(1.3, 4.0, 70.0)


def test_features_are_shown_in_degrees_and_their_units_are_named(proposal):
    body = proposal.to_dict()
    knee = next(f for f in body["features"] if f["name"] == "knee_swing_flexion_peak")
    raw = next(f for f in proposal.features if f.spec.name == "knee_swing_flexion_peak")
    assert knee["unit"] == "deg" and knee["value"] == pytest.approx(math.degrees(raw.value), abs=1e-4)
    toe = next(f for f in body["features"] if f["name"] == "toe_off")
    assert toe["unit"] == "fraction of gait cycle" and 0.5 < toe["value"] < 0.75


def test_curves_and_via_points_carry_their_units_in_their_names(proposal):
    body = proposal.to_dict()
    curves = body["curves"]
    assert len(curves["phase"]) == 101 and set(curves) == {
        "phase", *(f"{j}_{q}{s}" for j in ("knee", "ankle") for q in ("angle_deg", "moment_Nm_per_kg")
                   for s in ("", "_std"))}
    assert max(curves["knee_angle_deg"]) == pytest.approx(math.degrees(proposal.means["knee_angle"].max()), abs=1e-3)
    assert all({"joint", "phase", "angle_deg", "moment_Nm_per_kg"} == set(v) for v in body["via_points"])
    b = body["subphase_boundaries_phase"]
    assert 0 < b["stance_flexion_to_stance_extension"] < b["stance_extension_to_swing_flexion"] < \
        b["swing_flexion_to_swing_extension"] < 1


def test_the_task_model_and_safety_are_stated(proposal):
    body = proposal.to_dict()
    assert body["task"] == {"speed_mps": 1.3, "incline_deg": 4.0, "mass_kg": 70.0}
    assert body["model"]["data_sha256"] == proposal.data_sha256 and body["safety"]["ok"] is True
    assert len(body["table"]) == 8 and {"k_Nm_per_rad", "theta_e_deg", "b_Nm_s_per_rad"} <= set(body["table"][0])
