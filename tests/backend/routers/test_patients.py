"""Patients: create, read, update, with audit; bad fields named."""

from __future__ import annotations

import pytest


# -------------------------------------------------------------- patients
def test_patient_create_read_update_with_audit(api):
    p = api.new_patient("P-007", 82.5)
    assert p["body_mass_kg"] == 82.5 and p["side"] == "left" and p["k_level"] == 3
    got = api.client.get(f"/api/patients/{p['id']}", headers=api.as_("viewer")).json()
    assert got == p
    r = api.client.patch(f"/api/patients/{p['id']}", headers=api.as_("prosthetist"),
                         json={"body_mass_kg": 84.0, "k_level": None})
    assert r.status_code == 200 and r.json()["body_mass_kg"] == 84.0 and r.json()["k_level"] is None
    entries = api.client.get("/api/audit", headers=api.as_("prosthetist"),
                             params={"entity": "patient", "entity_id": p["id"]}).json()["items"]
    update = entries[0]
    assert update["action"] == "patient.update" and update["actor"] == "prosthetist"
    assert update["before"] == {"body_mass_kg": 82.5, "k_level": 3}
    assert update["after"] == {"body_mass_kg": 84.0, "k_level": None}
    assert entries[1]["action"] == "patient.create"
    assert [x["code_name"] for x in api.client.get("/api/patients", headers=api.as_("viewer")).json()] == ["P-007"]


@pytest.mark.parametrize(("body", "field", "words"), [
    ({"code_name": "A", "body_mass_kg": 19.9, "side": "left"}, "body_mass_kg", "body mass must be at least 20 kg"),
    ({"code_name": "A", "body_mass_kg": 70, "side": "up"}, "side", "'left' or 'right'"),
    ({"code_name": "", "body_mass_kg": 70, "side": "left"}, "code_name", "pattern"),
    ({"code_name": "A", "body_mass_kg": 70, "side": "left", "height_m": 3.1}, "height_m", "height must be at most 2.5 m"),
    ({"code_name": "A", "body_mass_kg": 70, "side": "left", "shoe": 42}, "shoe", "shoe is not part of this request"),
    ({"code_name": "A", "body_mass_kg": 70, "side": "left", "notes": "bad\x00byte"}, "notes", "control characters"),
])
def test_bad_patient_fields_are_named_in_the_422(api, body, field, words):
    r = api.client.post("/api/patients", headers=api.as_("prosthetist"), json=body)
    assert r.status_code == 422
    detail = r.json()["detail"]
    assert words in detail and field in [e["field"] for e in r.json()["errors"]], detail
    assert api.count("patients") == 0


def test_nan_and_unparsable_json_are_refused(api):
    h = {**api.as_("prosthetist"), "content-type": "application/json"}
    r = api.client.post("/api/patients", headers=h, content='{"code_name": "A", "body_mass_kg": NaN, "side": "left"}')
    assert r.status_code == 422 and "body mass must be a finite number" in r.json()["detail"]
    r = api.client.post("/api/patients", headers=h, content='{"code_name": "A", "body_mass_')
    assert r.status_code == 422 and "JSON" in r.json()["detail"]
    assert api.count("patients") == 0


def test_duplicate_code_name_is_a_409_and_missing_ids_404(api):
    api.new_patient("P-1")
    r = api.client.post("/api/patients", headers=api.as_("prosthetist"),
                        json={"code_name": "P-1", "body_mass_kg": 70, "side": "left"})
    assert r.status_code == 409 and "P-1" in r.json()["detail"]
    assert api.client.get("/api/patients/99", headers=api.as_("viewer")).status_code == 404
    r = api.client.get(f"/api/patients/{2**60}", headers=api.as_("viewer"))
    assert r.status_code == 422 and "patient id must be at most" in r.json()["detail"]
    assert api.client.get("/api/proposals/5", headers=api.as_("viewer")).json()["detail"] == "proposal 5 not found"
