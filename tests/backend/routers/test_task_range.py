"""Requests far outside the data: a task beyond the model's known range (its data plus the stated margin) is refused
unless the prosthetist asks to extrapolate and writes why; the reason is audited and shown with the version."""

from __future__ import annotations

import pytest

from tests.backend.routers.test_envelopes import request_envelope

REASON = "the patient walks very slowly at home; we want to see what the model says"


def _count(api, patient_id: int, kind: str) -> int:
    r = api.client.get(f"/api/patients/{patient_id}/{kind}", headers=api.as_("viewer"))
    return int(r.headers["X-Total-Count"])


def test_the_task_range_states_the_data_and_the_margin(api):
    r = api.client.get("/api/task-range", headers=api.as_("viewer"))
    assert r.status_code == 200
    body = r.json()
    assert body["speed_mps"] == [0.1, 3.0] and body["incline_deg"] == [-20.0, 20.0]
    assert body["envelope_nodes_per_axis"] == [2, 15] and body["envelope_max_nodes"] == 64
    known = body["known"]
    lo, hi = known["data_speed_mps"]
    assert 0.8 < lo < 0.9 and 1.9 < hi < 2.0 and known["data_incline_deg"] == [-10.0, 10.0]
    assert known["speed_mps"] == [pytest.approx(lo - 0.35, abs=0.01), pytest.approx(hi + 0.35, abs=0.01)]
    assert known["incline_deg"] == [-15.0, 15.0]


@pytest.mark.parametrize(("speed", "incline"), [(0.15, -19.0), (0.3, 0.0), (2.9, 0.0), (1.2, 17.0), (1.2, -16.0)])
def test_a_proposal_beyond_the_known_range_is_refused_and_nothing_is_stored(api, speed, incline):
    patient = api.new_patient()
    r = api.client.post(f"/api/patients/{patient['id']}/proposals", headers=api.as_("prosthetist"),
                        json={"speed_mps": speed, "incline_deg": incline})
    assert r.status_code == 422
    body = r.json()
    assert "beyond what the model knows" in body["detail"] and "0.84–1.95 m/s" in body["detail"]
    assert '"extrapolate": true' in body["detail"] and body["known_range"]["incline_deg"] == [-15.0, 15.0]
    assert _count(api, patient["id"], "proposals") == 0


def test_extrapolating_needs_a_written_reason_which_is_kept_audited_and_inherited(api):
    patient = api.new_patient()
    c, pro = api.client, api.as_("prosthetist")
    url = f"/api/patients/{patient['id']}/proposals"
    assert c.post(url, headers=pro, json={"speed_mps": 0.3, "extrapolate": True}).status_code == 422
    assert c.post(url, headers=pro, json={"speed_mps": 0.3, "extrapolate": True, "reason": "slow"}).status_code == 422
    assert _count(api, patient["id"], "proposals") == 0
    p = api.propose(patient["id"], speed=0.3, extrapolate=True, reason=REASON)
    assert p["extrapolation"] is True and p["extrapolation_reason"] == REASON
    listed = c.get(url, headers=pro).json()[0]
    assert listed["extrapolation_reason"] == REASON
    audit = c.get("/api/audit", headers=pro, params={"entity": "proposal", "entity_id": p["id"]}).json()["items"]
    assert next(e for e in audit if e["action"] == "proposal.create")["after"]["extrapolation_reason"] == REASON
    edited = c.post(f"/api/proposals/{p['id']}/edits", headers=pro, json={
        "rows": [{"joint": "ankle", "subphase": "swing_flexion", "b_Nm_s_per_rad": 0.5}], "comment": "a little damping"})
    assert edited.status_code == 201, edited.text
    assert edited.json()["extrapolation_reason"] == REASON
    # inside the known range a reason is not stored: the version is not extrapolated on purpose
    q = api.propose(patient["id"], speed=1.2, extrapolate=True, reason=REASON)
    assert q["extrapolation_reason"] is None and q["extrapolation"] is False


def test_the_default_envelope_stays_requestable_and_one_beyond_needs_a_reason(api):
    patient = api.new_patient()
    default = api.client.post(f"/api/patients/{patient['id']}/envelopes", headers=api.as_("prosthetist"), json={})
    assert default.status_code == 201, default.text
    assert default.json()["extrapolation_reason"] is None
    r = api.client.post(f"/api/patients/{patient['id']}/envelopes", headers=api.as_("prosthetist"),
                        json={"speed_range_mps": [0.3, 1.6], "incline_range_deg": [-10, 10], "grid": [3, 3]})
    assert r.status_code == 422 and "0.3 m/s" in r.json()["detail"]
    assert _count(api, patient["id"], "envelopes") == 1
    e = request_envelope(api, patient["id"], speed_range_mps=[0.3, 1.6], incline_range_deg=[-18, 10], grid=[3, 3],
                         extrapolate=True, reason=REASON)
    assert e["extrapolation_reason"] == REASON and e["extrapolation"] is True
