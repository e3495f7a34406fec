"""Approval and push rest on the bench's verdict for exactly the version's content (a written, audited override
goes ahead anyway). A proposal at 0.15 m/s, −19° walked its preview with 7 falls and was once approved and pushed
as if nothing had happened."""

from __future__ import annotations

from tests.backend.routers.test_envelopes import request_envelope
from tests.helpers.api import DEVICE, assign, push_body, wait_for

REASON = "patient seated on the bench; checking the rows by hand"


def _approve(api, kind: str, item_id: int, **extra):
    return api.client.post(f"/api/{kind}s/{item_id}/approve", headers=api.as_("prosthetist"),
                           json={"comment": "reviewed", **extra})


def test_a_table_is_approved_only_after_its_preview_is_walked_clean(api):
    p = api.propose(api.new_patient()["id"], speed=1.2)
    before = api.client.get(f"/api/proposals/{p['id']}", headers=api.as_("viewer")).json()
    assert before["bench"]["status"] == "not_walked" and before["safety"]["ok"]
    r = _approve(api, "proposal", p["id"])
    assert r.status_code == 409 and "not been walked" in r.json()["detail"] and "override_reason" in r.json()["detail"]
    assert api.client.get(f"/api/proposals/{p['id']}", headers=api.as_("viewer")).json()["status"] == "draft"
    assert api.client.get(f"/api/proposals/{p['id']}/preview", headers=api.as_("viewer")).status_code == 200
    r = _approve(api, "proposal", p["id"])
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["bench"]["status"] in ("clean", "warnings") and body["decision"]["override_reason"] is None


def test_an_unsafe_preview_stops_approval_and_push_unless_a_written_reason_is_given(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    patient = api.new_patient()
    p = api.propose(patient["id"], speed=0.15, incline=-19.0, extrapolate=True,
                    reason="testing what the bench says of a task far outside the data")
    assert c.get(f"/api/proposals/{p['id']}/preview", headers=pro).status_code == 200
    bench = c.get(f"/api/proposals/{p['id']}", headers=pro).json()["bench"]
    assert bench["status"] == "unsafe" and any(f["figure"] == "falls" for f in bench["flags"])
    refused = _approve(api, "proposal", p["id"])
    assert refused.status_code == 409 and "gave way" in refused.json()["detail"]
    assert refused.json()["bench"]["status"] == "unsafe"
    assert _approve(api, "proposal", p["id"], override_reason="too short").status_code == 422
    ok = _approve(api, "proposal", p["id"], override_reason=REASON)
    assert ok.status_code == 200 and ok.json()["decision"]["override_reason"] == REASON
    audit = c.get("/api/audit", headers=pro, params={"entity": "proposal", "entity_id": p["id"]}).json()["items"]
    approve = next(e for e in audit if e["action"] == "proposal.approve")
    assert approve["after"]["override_reason"] == REASON and approve["after"]["bench"] == "unsafe"
    # the push needs its own reason, and the device page shows both
    assign(api, patient["id"])
    body = push_body(api)
    r = c.post(f"/api/proposals/{p['id']}/push", headers=pro, json=body)
    assert r.status_code == 409 and "not pushed" in r.json()["detail"]
    r = c.post(f"/api/proposals/{p['id']}/push", headers=pro, json={**body, "override_reason": REASON + " (push)"})
    assert r.status_code == 201, r.text
    assert r.json()["override_reason"] == REASON + " (push)" and r.json()["approval_override"] == REASON
    device = wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["active_table"],
                      clock=api.clock)
    assert device["active_table"]["approval_override"] == REASON
    assert device["active_table"]["override_reason"] == REASON + " (push)"


def test_an_envelope_is_not_approved_before_its_preview_exists(api):
    e = request_envelope(api, api.new_patient()["id"], grid=[2, 2])
    r = _approve(api, "envelope", e["id"])
    assert r.status_code == 409 and "not been walked" in r.json()["detail"]
    assert api.client.get(f"/api/envelopes/{e['id']}", headers=api.as_("viewer")).json()["status"] == "draft"


def test_a_session_on_a_version_approved_by_override_carries_the_reason_into_its_report(sim_api):
    from backend.report import report_facts

    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    patient = api.new_patient()
    p = api.propose(patient["id"], speed=1.2)                         # approved before its preview was walked
    assert _approve(api, "proposal", p["id"], override_reason=REASON).status_code == 200
    assign(api, patient["id"])
    assert c.post(f"/api/proposals/{p['id']}/push", headers=pro,
                  json={**push_body(api), "override_reason": REASON}).status_code == 201
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["active_table"], clock=api.clock)
    s = c.post(f"/api/patients/{patient['id']}/sessions", headers=pro, json={"device_id": DEVICE}).json()
    assert s["approval_override"] == REASON
    wait_for(lambda: c.get(f"/api/sessions/{s['id']}/samples", headers=pro).json()["count"], lambda n: n >= 100,
             clock=api.clock)
    assert c.post(f"/api/sessions/{s['id']}/stop", headers=pro).status_code == 200
    stopped = c.get(f"/api/sessions/{s['id']}", headers=pro).json()
    facts = dict(report_facts(stopped, c.get(f"/api/patients/{patient['id']}", headers=pro).json()))
    assert facts["Bench override"] == f"approved without a clean bench preview: “{REASON}”"   # the PDF's first block
    assert c.get(f"/api/sessions/{s['id']}/report.pdf", headers=pro).status_code == 200
