"""Walking sessions and their report."""

from __future__ import annotations

import json
import time

from tests.helpers.api import DEVICE, approved_proposal


def test_session_report_pdf(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    prop = approved_proposal(api)
    assert c.post(f"/api/proposals/{prop['id']}/push", headers=pro, json={"device_id": DEVICE}).status_code == 201
    started = c.post(f"/api/patients/{prop['patient_id']}/sessions", headers=pro, json={"device_id": DEVICE})
    assert started.status_code == 201, started.text
    session = started.json()
    early = c.get(f"/api/sessions/{session['id']}/report.pdf", headers=pro)
    assert early.status_code == 409 and "still recording" in early.json()["detail"]
    time.sleep(2.5)
    assert c.post(f"/api/sessions/{session['id']}/stop", headers=pro).status_code == 200
    r = c.get(f"/api/sessions/{session['id']}/report.pdf", headers=api.as_("viewer"))
    assert r.status_code == 200 and r.headers["content-type"] == "application/pdf"
    assert r.content.startswith(b"%PDF") and len(r.content) > 5000
    assert f"session-{session['id']}.pdf" in r.headers["content-disposition"]
    json.dumps(c.get(f"/api/sessions/{session['id']}", headers=pro).json())
