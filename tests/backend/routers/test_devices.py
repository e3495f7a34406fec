"""Devices through the API: push, telemetry, sessions, safe mode."""

from __future__ import annotations

import time

import pytest
from starlette.websockets import WebSocketDisconnect

from device_bridge.protocol import WireTable
from tests.helpers.api import DEVICE, approved_proposal, wait_for


def test_approve_push_active_telemetry_and_a_session_summary(sim_api, model):
    api = sim_api
    c, pro, viewer = api.client, api.as_("prosthetist"), api.as_("viewer")
    device = wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=viewer).json(), lambda d: d["online"])
    assert device["mode"] == "no_table" and device["active_crc32"] is None

    prop = approved_proposal(api)
    r = c.post(f"/api/proposals/{prop['id']}/push", headers=pro, json={"device_id": DEVICE})
    assert r.status_code == 201, r.text
    push = r.json()
    table = model.propose(1.2, 0.0, 80.0).table
    assert push["crc32"] == f"{WireTable.from_table(table).crc32():08x}"
    assert push["status"] in ("acknowledged", "active") and push["table_version"] == prop["id"]

    device = wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=viewer).json(),
                      lambda d: d["active_crc32"] == push["crc32"])
    assert device["mode"] == "active" and device["active_version"] == prop["id"]
    got = wait_for(lambda: c.get(f"/api/proposals/{prop['id']}", headers=viewer).json(),
                   lambda p: p["deployment"] == "active_on_device")
    assert got["status"] == "approved"   # the approved proposal itself never changes
    [record] = c.get(f"/api/proposals/{prop['id']}/pushes", headers=viewer).json()
    assert record["status"] == "active" and record["active_at"] is not None

    # a session at the active table's task: the simulated patient walks, telemetry streams
    r = c.post(f"/api/patients/{prop['patient_id']}/sessions", headers=viewer, json={"device_id": DEVICE})
    assert r.status_code == 201, r.text
    session = r.json()
    assert session["task"]["speed_mps"] == 1.2 and session["proposal_id"] == prop["id"]
    token = viewer["Authorization"].split()[1]
    samples = []
    with c.websocket_connect(f"/api/devices/{DEVICE}/telemetry?token={token}") as ws:
        first = ws.receive_json()
        assert first["type"] == "status" and first["active_crc32"] == push["crc32"]
        while len(samples) < 300:
            msg = ws.receive_json()
            if msg["type"] == "telemetry":
                samples.append(msg)
    seqs = [s["seq"] for s in samples]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    assert max(s["knee_angle_deg"] for s in samples) - min(s["knee_angle_deg"] for s in samples) > 10
    time.sleep(1.0)
    r = c.post(f"/api/sessions/{session['id']}/stop", headers=viewer)
    assert r.status_code == 200, r.text
    summary = r.json()["summary"]
    again = c.post(f"/api/sessions/{session['id']}/stop", headers=viewer)
    assert again.status_code == 409 and "already stopped" in again.json()["detail"]
    assert summary["samples"] >= 350 and summary["missing_samples"] == 0
    assert summary["strides"] >= 2 and 60 < summary["cadence_steps_per_min"] < 160
    assert 0 < summary["knee_angle_rmse_deg"] < 60
    stored = c.get(f"/api/patients/{prop['patient_id']}/sessions", headers=viewer).json()
    assert stored[0]["id"] == session["id"] and stored[0]["status"] == "stopped"
    cols = c.get(f"/api/sessions/{session['id']}/samples?every=10", headers=viewer).json()
    assert cols["count"] == len(cols["columns"]["knee_angle_deg"]) >= 35
    actions = [e["action"] for e in c.get("/api/audit", headers=api.as_("admin")).json()["items"]]
    assert {"proposal.push", "session.start", "session.stop"} <= set(actions)


def test_push_refusals(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    patient = api.new_patient()
    draft = api.propose(patient["id"])
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=pro, json={"device_id": DEVICE})
    assert r.status_code == 409 and "only approved proposals" in r.json()["detail"]
    c.post(f"/api/proposals/{draft['id']}/approve", headers=pro, json={"comment": ""})
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=api.as_("viewer"), json={"device_id": DEVICE})
    assert r.status_code == 403
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=pro, json={"device_id": "no-such-leg"})
    assert r.status_code == 404 and "no-such-leg" in r.json()["detail"]
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=pro, json={"device_id": "bad id!"})
    assert r.status_code == 422
    assert c.get(f"/api/proposals/{draft['id']}/pushes", headers=pro).json() == []   # nothing recorded
    r = c.post(f"/api/patients/{patient['id']}/sessions", headers=pro, json={"device_id": DEVICE})
    assert r.status_code == 422 and "push a table" in r.json()["detail"]


def test_telemetry_websocket_needs_a_token(sim_api):
    c = sim_api.client
    for url in (f"/api/devices/{DEVICE}/telemetry", f"/api/devices/{DEVICE}/telemetry?token=forged"):
        with pytest.raises(WebSocketDisconnect) as exc, c.websocket_connect(url) as ws:
            ws.receive_json()
        assert exc.value.code == 1008


def test_safe_mode_command_round_trip(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    prop = approved_proposal(api)
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["online"])
    assert c.post(f"/api/proposals/{prop['id']}/push", headers=pro, json={"device_id": DEVICE}).status_code == 201
    r = c.post(f"/api/devices/{DEVICE}/commands", headers=api.as_("viewer"), json={"command": "enter_safe_mode"})
    assert r.status_code == 403
    r = c.post(f"/api/devices/{DEVICE}/commands", headers=pro, json={"command": "enter_safe_mode"})
    assert r.status_code == 202
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["safe_mode"])
    c.post(f"/api/devices/{DEVICE}/commands", headers=pro, json={"command": "leave_safe_mode"})
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["mode"] == "active")
