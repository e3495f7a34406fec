"""Approval and push rest on the bench's verdict for exactly the version's content; going ahead anyway takes two
prosthetists' written, audited sign-offs. A proposal at 0.15 m/s, −19° walked its preview with 7 falls and was once
approved and pushed as if nothing had happened; later one prosthetist's two short texts still sufficed."""

from __future__ import annotations

from tests.backend.routers.test_envelopes import request_envelope
from tests.helpers.api import DEVICE, SECOND, assign, cosign, push_body, wait_for

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
    assert body["bench"]["status"] == "clean" and body["decision"]["override_reason"] is None
    assert body["bench"]["flags"] == [] and all(f["severity"] is None for f in body["bench"]["figures"])


def test_an_unsafe_preview_stops_approval_and_push_unless_two_prosthetists_sign_off(sim_api):
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
    alone = _approve(api, "proposal", p["id"], override_reason=REASON)     # one prosthetist's reason is not enough
    assert alone.status_code == 409 and "2 prosthetists' sign-offs" in alone.json()["detail"]
    assert c.get(f"/api/proposals/{p['id']}", headers=pro).json()["status"] == "draft"
    assert c.get(f"/api/proposals/{p['id']}", headers=pro).json()["bench"]["signoffs"] == []    # nothing kept
    # a viewer cannot sign off; the second prosthetist does, then the first approves with their own reason
    assert c.post(f"/api/proposals/{p['id']}/signoffs", headers=api.as_("viewer"),
                  json={"reason": REASON}).status_code == 403
    signed = cosign(api, "proposal", p["id"], "reviewed the falls with the patient in the bars")
    assert signed["complete"] is False and [s["by"] for s in signed["signoffs"]] == [SECOND]
    again = c.post(f"/api/proposals/{p['id']}/signoffs", headers=api.as_(SECOND), json={"reason": REASON})
    assert again.status_code == 409 and "another prosthetist" in again.json()["detail"]
    ok = _approve(api, "proposal", p["id"], override_reason=REASON)
    both = f"{SECOND}: reviewed the falls with the patient in the bars; prosthetist: {REASON}"
    assert ok.status_code == 200 and ok.json()["decision"]["override_reason"] == both
    assert [s["by"] for s in ok.json()["bench"]["signoffs"]] == [SECOND, "prosthetist"]
    audit = c.get("/api/audit", headers=api.as_("admin"), params={"entity": "proposal",
                                                                  "entity_id": p["id"]}).json()["items"]
    approve = next(e for e in audit if e["action"] == "proposal.approve")
    assert approve["after"]["override_reason"] == both and approve["after"]["bench"] == "unsafe"
    assert [e["actor"] for e in audit if e["action"] == "proposal.gate_signoff"] == ["prosthetist", SECOND]
    # the push needs its own reason, and the device page shows both
    assign(api, patient["id"])
    body = push_body(api)
    r = c.post(f"/api/proposals/{p['id']}/push", headers=pro, json=body)
    assert r.status_code == 409 and "not pushed" in r.json()["detail"]
    r = c.post(f"/api/proposals/{p['id']}/push", headers=pro, json={**body, "override_reason": REASON + " (push)"})
    assert r.status_code == 201, r.text
    assert r.json()["override_reason"] == REASON + " (push)" and r.json()["approval_override"] == both
    device = wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["active_table"],
                      clock=api.clock)
    assert device["active_table"]["approval_override"] == both
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
    cosign(api, "proposal", p["id"], REASON)
    assert _approve(api, "proposal", p["id"], override_reason=REASON).status_code == 200
    both = f"{SECOND}: {REASON}; prosthetist: {REASON}"
    assign(api, patient["id"])
    assert c.post(f"/api/proposals/{p['id']}/push", headers=pro,
                  json={**push_body(api), "override_reason": REASON}).status_code == 201
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["active_table"], clock=api.clock)
    s = c.post(f"/api/patients/{patient['id']}/sessions", headers=pro, json={"device_id": DEVICE}).json()
    assert s["approval_override"] == both
    wait_for(lambda: c.get(f"/api/sessions/{s['id']}/samples", headers=pro).json()["count"], lambda n: n >= 100,
             clock=api.clock)
    assert c.post(f"/api/sessions/{s['id']}/stop", headers=pro).status_code == 200
    stopped = c.get(f"/api/sessions/{s['id']}", headers=pro).json()
    facts = dict(report_facts(stopped, c.get(f"/api/patients/{patient['id']}", headers=pro).json()))
    assert facts["Bench override"] == f"approved without a clean bench preview: “{both}”"   # the PDF's first block
    assert c.get(f"/api/sessions/{s['id']}/report.pdf", headers=pro).status_code == 200


def test_a_leg_that_does_not_carry_the_body_is_not_approved_without_the_override(api):
    """Once only a warning, approved by one click: at 1.6 m/s the learned table lets the hip sink under the body on
    the bench (no fall, no toe catch); each figure beyond its bound now gates as a fall does."""
    p = api.propose(api.new_patient("P-075", 75.0)["id"], speed=1.6)
    assert api.client.get(f"/api/proposals/{p['id']}/preview", headers=api.as_("viewer")).status_code == 200
    bench = api.client.get(f"/api/proposals/{p['id']}", headers=api.as_("viewer")).json()["bench"]
    figures = {f["figure"] for f in bench["flags"]}
    assert bench["status"] == "unsafe" and not figures & {"falls", "toe_catches"} and figures, bench
    assert all(f["severity"] == "bad" and "bound" in f["message"] for f in bench["flags"])
    r = _approve(api, "proposal", p["id"])
    assert r.status_code == 409 and "its bench preview shows" in r.json()["detail"]
    assert api.client.get(f"/api/proposals/{p['id']}", headers=api.as_("viewer")).json()["status"] == "draft"
