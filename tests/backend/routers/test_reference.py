"""The measured conditions behind the model."""

from __future__ import annotations

import numpy as np
import pytest


def test_reference_lists_the_measured_conditions_with_citations(api, reference):
    r = api.client.get("/api/reference", headers=api.as_("viewer"))
    assert r.status_code == 200, r.text
    body = r.json()
    assert len(body["conditions"]) == len(reference.records)
    first = body["conditions"][0]
    assert "Bovi" in first["citation"] and first["speed_mps"] > 0
    rec = reference.records[0]
    assert first["knee_angle_deg"][50] == pytest.approx(np.degrees(rec.mean["knee_angle"][50]), abs=1e-3)
    assert api.client.get("/api/reference").status_code == 401


def test_the_ramp_conditions_are_the_ones_the_model_learned_the_slope_from(api, model):
    ramps = api.client.get("/api/reference", headers=api.as_("viewer")).json()["ramp_conditions"]
    assert [(c["name"], c["incline_deg"], c["strides"]) for c in ramps] == [
        (rec.name, float(rec.task["incline_deg"]), rec.n) for rec in model.ramps_.records]
    assert {c["incline_deg"] for c in ramps} >= {-10.0, 0.0, 10.0} and all("Vielemeyer" in c["citation"] for c in ramps)


def test_the_reference_at_a_task_says_what_it_really_is(api):
    def at(speed: float, incline: float):
        r = api.client.get("/api/reference", headers=api.as_("viewer"),
                           params={"speed_mps": speed, "incline_deg": incline})
        assert r.status_code == 200, r.text
        return r.json()["at_task"]

    level, ramp = at(1.2, 0.0), at(1.2, 8.0)
    assert level["kind"] == "measured" and level["label"] == "measured able-bodied level walking"
    assert ramp["kind"] == "measured_ramp_trend" and "one participant" in ramp["label"]
    assert any("Vielemeyer" in c for c in ramp["citations"])
    assert ramp["knee_angle_deg"][0] > level["knee_angle_deg"][0] + 15
    assert at(1.2, 15.0) is None                       # nothing measured that steep: no curve passes for data
    assert api.client.get("/api/reference", headers=api.as_("viewer"),
                          params={"speed_mps": 1.2, "incline_deg": 25}).status_code == 422
