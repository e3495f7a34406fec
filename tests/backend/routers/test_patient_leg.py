"""The patient's leg: described on the patient, made for by every new version, walked by its bench preview."""

from __future__ import annotations

import json

import pytest

from device_bridge.sim.leg_file import load_leg_file
from device_bridge.sim.swing_inertia import swing_inertia_ratio

SHORT = load_leg_file("short_person")


def test_a_patients_leg_is_described_changed_and_cleared_with_audit(api):
    p = api.new_patient()
    assert p["leg"] is None                                         # none given: the server's bench leg stands in
    r = api.client.patch(f"/api/patients/{p['id']}", headers=api.as_("prosthetist"), json={"leg": SHORT.description()})
    assert r.status_code == 200, r.text
    assert r.json()["leg"] == SHORT.description() == {"name": "short person (1.58 m)", "body_height_m": 1.58,
                                                        "socket_mass_kg": 2.4}
    assert api.client.get(f"/api/patients/{p['id']}", headers=api.as_("viewer")).json()["leg"] == SHORT.description()
    [update, _] = api.client.get("/api/audit", headers=api.as_("prosthetist"),
                                 params={"entity": "patient", "entity_id": p["id"]}).json()["items"]
    assert update["before"] == {"leg": None} and update["after"] == {"leg": SHORT.description()}
    r = api.client.patch(f"/api/patients/{p['id']}", headers=api.as_("prosthetist"), json={"leg": None})
    assert r.status_code == 200 and r.json()["leg"] is None


@pytest.mark.parametrize(("leg", "field"), [
    ({"knee_friction_Nm": 40.0}, "knee_friction_Nm"),          # beyond any drive the bench can represent
    ({"body_height_m": 1.2}, "body_height_m"),                 # Winter's proportions hold for adults
    ({"shoe_size": 42}, "shoe_size"),                          # not a field of a leg file
    ({"foot_mass_kg": float("nan")}, "foot_mass_kg"),
])
def test_a_leg_the_bench_cannot_walk_is_refused_naming_the_field_and_nothing_changes(api, leg, field):
    p = api.new_patient()
    r = api.client.patch(f"/api/patients/{p['id']}", headers={**api.as_("prosthetist"),
                                                                "Content-Type": "application/json"},
                         content=json.dumps({"leg": leg}))          # NaN written as JSON's NaN
    assert r.status_code == 422 and field in r.text, r.text
    assert api.client.get(f"/api/patients/{p['id']}", headers=api.as_("viewer")).json() == p


def test_a_version_is_made_for_the_patients_leg_and_its_preview_walks_it(api):
    p = api.new_patient(mass=75.0)
    before = api.propose(p["id"])
    assert before["leg"]["nominal"] and before["leg"]["words"] == "the nominal bench leg"
    api.client.patch(f"/api/patients/{p['id']}", headers=api.as_("prosthetist"), json={"leg": SHORT.description()})
    made = api.propose(p["id"])
    assert made["leg"] == {"description": SHORT.description(), "leg_sha256": SHORT.sha256(), "nominal": False,
                           "words": "the leg described as 'short person (1.58 m)'"}
    knee, ankle = swing_inertia_ratio(SHORT.geometry())        # its swing rows are proposed for that leg's inertia
    assert made["swing_inertia"]["knee_ratio"] == pytest.approx(knee, abs=1e-4) != 1.0
    assert made["swing_inertia"]["ankle_ratio"] == pytest.approx(ankle, abs=1e-4)
    edit = api.client.post(f"/api/proposals/{made['id']}/edits", headers=api.as_("prosthetist"), json={
        "thresholds": {"forefoot_landing_pct": 55.0}, "comment": "a little later on the toe"})
    assert edit.status_code == 201 and edit.json()["leg"] == made["leg"]     # an edit keeps its parent's leg
    again = api.client.get(f"/api/proposals/{before['id']}", headers=api.as_("viewer")).json()
    assert again["leg"] == before["leg"]                                     # a version keeps the leg it was made for
    preview = api.client.get(f"/api/proposals/{made['id']}/preview", headers=api.as_("viewer"))
    assert preview.status_code == 200, preview.text
    assert preview.json()["leg"] == "short person (1.58 m)"                  # walked on that leg
    listed = api.client.get(f"/api/patients/{p['id']}/proposals", headers=api.as_("viewer")).json()
    assert [v["leg"]["nominal"] for v in listed] == [False, False, True]


def test_an_envelope_is_made_for_the_patients_leg_and_keeps_it(api):
    p = api.new_patient(mass=75.0)
    api.client.patch(f"/api/patients/{p['id']}", headers=api.as_("prosthetist"), json={"leg": SHORT.description()})
    r = api.client.post(f"/api/patients/{p['id']}/envelopes", headers=api.as_("prosthetist"),
                        json={"speed_range_mps": [1.0, 1.4], "incline_range_deg": [-4, 4], "grid": [2, 2]})
    assert r.status_code == 201, r.text
    envelope = r.json()
    assert envelope["leg"]["leg_sha256"] == SHORT.sha256() and not envelope["leg"]["nominal"]
    assert envelope["swing_inertia"]["knee_ratio"] == pytest.approx(swing_inertia_ratio(SHORT.geometry())[0], abs=1e-4)
    listed = api.client.get(f"/api/patients/{p['id']}/envelopes", headers=api.as_("viewer")).json()
    assert listed[0]["leg"] == envelope["leg"]
