"""Devices through the API: push, telemetry, sessions, safe mode."""

from __future__ import annotations

import time

import pytest
from starlette.websockets import WebSocketDisconnect

from backend.routers.devices import RECHECK_TOKEN_S
from device_bridge.envelope_wire import table_wire
from tests.helpers.api import (
    DEVICE,
    FIXTURE_OVERRIDE,
    approved_proposal,
    assign,
    cosign,
    push_body,
    push_to_leg,
    wait_for,
    wait_recorded,
    walk_preview,
)


@pytest.mark.parametrize("sim_api", ["stepped", pytest.param("wall", marks=[pytest.mark.wallclock, pytest.mark.live])],
                         indirect=True)      # the whole loop once as `quasitune serve` runs it: the leg's own threads
def test_approve_push_active_telemetry_and_a_session_summary(sim_api, model):
    api = sim_api
    c, viewer = api.client, api.as_("viewer")
    device = wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=viewer).json(), lambda d: d["online"], clock=api.clock)
    assert device["mode"] == "no_table" and device["active_crc32"] is None

    prop = approved_proposal(api)
    r = push_to_leg(api, prop)
    assert r.status_code == 201, r.text
    push = r.json()
    table = model.propose(1.2, 0.0, 80.0).table
    assert push["crc32"] == f"{table_wire(table).crc32():08x}"
    assert push["status"] in ("acknowledged", "active") and push["table_version"] == 1   # the device's counter
    assert push["table_label"] == f"P-001 · table v{prop['version']}"

    device = wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=viewer).json(),
                      lambda d: d["active_crc32"] == push["crc32"], clock=api.clock)
    assert device["mode"] == "active" and device["active_version"] == 1
    assert device["active_table"]["table_label"] == push["table_label"]
    assert device["patient"]["patient_code"] == "P-001"
    got = wait_for(lambda: c.get(f"/api/proposals/{prop['id']}", headers=viewer).json(),
                   lambda p: p["deployment"] == "active_on_device", clock=api.clock)
    assert got["status"] == "approved"   # the approved proposal itself never changes
    [record] = c.get(f"/api/proposals/{prop['id']}/pushes", headers=viewer).json()
    assert record["status"] == "active" and record["active_at"] is not None

    # a session at the active table's task: the simulated patient walks, telemetry streams
    r = c.post(f"/api/patients/{prop['patient_id']}/sessions", headers=api.as_("prosthetist"), json={"device_id": DEVICE})
    assert r.status_code == 201, r.text
    session = r.json()
    assert session["task"]["speed_mps"] == 1.2 and session["proposal_id"] == prop["id"]
    token = viewer["Authorization"].split()[1]
    samples = []
    with c.websocket_connect(f"/api/devices/{DEVICE}/telemetry?token={token}") as ws:
        first = ws.receive_json()
        assert first["type"] == "status" and first["active_crc32"] == push["crc32"]
        if api.clock is not None:
            api.clock.advance(3.5)      # the patient walks 3.5 s: the stream's queue holds its samples
        while len(samples) < 300:
            msg = ws.receive_json()
            if msg["type"] == "telemetry":
                samples.append(msg)
    seqs = [s["seq"] for s in samples]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    device = c.get(f"/api/devices/{DEVICE}", headers=viewer).json()     # the instance's count of the live stream
    assert device["telemetry_samples_received"] >= 300 and device["telemetry_samples_missing"] == 0
    assert max(s["knee_angle_deg"] for s in samples) - min(s["knee_angle_deg"] for s in samples) > 10
    # the 300 seen, and more: the patient stands a second and takes the first steps, then two strides or more
    wait_recorded(api, session["id"], 5.0)
    refused = c.post(f"/api/sessions/{session['id']}/stop", headers=viewer)   # the prosthetist's recording
    assert refused.status_code == 403, refused.text
    assert c.get(f"/api/sessions/{session['id']}", headers=viewer).json()["status"] == "recording"
    r = c.post(f"/api/sessions/{session['id']}/stop", headers=api.as_("prosthetist"))
    assert r.status_code == 200, r.text
    summary = r.json()["summary"]
    again = c.post(f"/api/sessions/{session['id']}/stop", headers=api.as_("prosthetist"))
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
    body = push_body(api)
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=pro, json=body)
    assert r.status_code == 409 and "only approved proposals" in r.json()["detail"]
    walk_preview(api, draft["id"])   # approval rests on the bench
    c.post(f"/api/proposals/{draft['id']}/approve", headers=pro, json={"comment": "ok"})
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=api.as_("viewer"), json=body)
    assert r.status_code == 403
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=pro, json={**body, "device_id": "no-such-leg"})
    assert r.status_code == 404 and "no-such-leg" in r.json()["detail"]
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=pro, json={**body, "device_id": "bad id!"})
    assert r.status_code == 422
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=pro, json=body)
    assert r.status_code == 409 and "not assigned to a patient" in r.json()["detail"]
    assign(api, patient["id"])
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=pro, json={**body, "patient_ready": False})
    assert r.status_code == 422 and "patient_ready" in r.text                      # the precondition is confirmed
    r = c.post(f"/api/proposals/{draft['id']}/push", headers=pro, json={k: v for k, v in body.items()
                                                                         if k != "replaces_proposal_id"})
    assert r.status_code == 422 and "replaces_proposal_id" in r.text               # what it replaces, too
    assert c.get(f"/api/proposals/{draft['id']}/pushes", headers=pro).json() == []   # nothing recorded
    r = c.post(f"/api/patients/{patient['id']}/sessions", headers=pro, json={"device_id": DEVICE})
    assert r.status_code == 422 and "push a table" in r.json()["detail"]


def test_a_table_goes_only_to_the_leg_of_its_patient_and_a_session_records_that_patient(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    heavy, light = api.new_patient("P-190", 190.0), api.new_patient("P-045", 45.0)
    heavy_table = api.propose(heavy["id"])
    walk_preview(api, heavy_table["id"])   # approval rests on the bench (a 190 kg body sinks on it: overridden here)
    cosign(api, "proposal", heavy_table["id"])
    r = c.post(f"/api/proposals/{heavy_table['id']}/approve", headers=pro,
               json={"comment": "ok", "override_reason": FIXTURE_OVERRIDE})
    assert r.status_code == 200, r.text
    assign(api, light["id"])
    r = c.post(f"/api/proposals/{heavy_table['id']}/push", headers=pro, json=push_body(api))
    assert r.status_code == 409
    assert "assigned to P-045 (45 kg), not to P-190 (190 kg)" in r.json()["detail"]
    assert c.get(f"/api/proposals/{heavy_table['id']}/pushes", headers=pro).json() == []    # nothing sent
    r = c.post(f"/api/patients/{heavy['id']}/sessions", headers=pro, json={"device_id": DEVICE, "speed_mps": 1.0})
    assert r.status_code == 409 and "assigned to P-045" in r.json()["detail"]
    # the heavy patient's table on the leg, then the device handed to the light one: no session until theirs
    assert push_to_leg(api, heavy_table, override_reason=FIXTURE_OVERRIDE).status_code == 201
    assign(api, light["id"])
    r = c.post(f"/api/patients/{light['id']}/sessions", headers=pro, json={"device_id": DEVICE, "speed_mps": 1.0})
    assert r.status_code == 409 and "P-190 · table v1, another patient's table" in r.json()["detail"]
    audit = c.get("/api/audit", headers=api.as_("admin")).json()["items"]
    assert [e["after"]["patient_id"] for e in audit if e["action"] == "device.assign"][:2] == [light["id"], heavy["id"]]


def test_assignment_cannot_change_under_a_recording_session(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    prop = approved_proposal(api)
    assert push_to_leg(api, prop).status_code == 201
    other = api.new_patient("P-002")
    session = c.post(f"/api/patients/{prop['patient_id']}/sessions", headers=pro, json={"device_id": DEVICE}).json()
    r = c.put(f"/api/devices/{DEVICE}/assignment", headers=pro, json={"patient_id": other["id"]})
    assert r.status_code == 409 and f"recording session {session['id']}" in r.json()["detail"]
    assert c.delete(f"/api/devices/{DEVICE}/assignment", headers=pro).status_code == 409
    assert c.put(f"/api/devices/{DEVICE}/assignment", headers=api.as_("viewer"),
                 json={"patient_id": other["id"]}).status_code == 403
    c.post(f"/api/sessions/{session['id']}/stop", headers=pro)
    assert c.delete(f"/api/devices/{DEVICE}/assignment", headers=pro).json()["patient"] is None
    r = c.put(f"/api/devices/{DEVICE}/assignment", headers=pro, json={"patient_id": 999})
    assert r.status_code == 404 and "patient 999" in r.json()["detail"]


def test_a_push_names_what_it_replaces_and_is_refused_when_the_leg_changed_meanwhile(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    first = approved_proposal(api)
    assert push_to_leg(api, first).status_code == 201
    second = api.propose(first["patient_id"], speed=1.4)
    walk_preview(api, second["id"])   # approval rests on the bench
    c.post(f"/api/proposals/{second['id']}/approve", headers=pro, json={"comment": "faster"})
    stale = {"device_id": DEVICE, "replaces_proposal_id": None, "patient_ready": True}   # looked before the first
    r = c.post(f"/api/proposals/{second['id']}/push", headers=pro, json=stale)
    assert r.status_code == 409 and "now runs P-001 · table v1 (1.2 m/s, 0°)" in r.json()["detail"]
    r = c.post(f"/api/proposals/{second['id']}/push", headers=pro,
               json={**stale, "replaces_proposal_id": first["id"]})
    assert r.status_code == 201 and r.json()["table_label"] == "P-001 · table v2"


def test_a_table_built_for_another_body_mass_is_pushed_only_with_a_written_reason(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    prop = approved_proposal(api)                                   # built for 80 kg
    c.patch(f"/api/patients/{prop['patient_id']}", headers=pro, json={"body_mass_kg": 95.0})
    r = push_to_leg(api, prop)
    assert r.status_code == 409 and "built for 80 kg and P-001 now weighs 95 kg" in r.json()["detail"]
    assert "override_reason" in r.json()["detail"] and c.get(f"/api/proposals/{prop['id']}/pushes",
                                                               headers=pro).json() == []
    reason = "weighed in shoes today; the table is being re-proposed"
    r = c.post(f"/api/proposals/{prop['id']}/push", headers=pro, json={**push_body(api), "override_reason": reason})
    assert r.status_code == 201 and r.json()["override_reason"] == reason
    c.patch(f"/api/patients/{prop['patient_id']}", headers=pro, json={"body_mass_kg": 83.0})   # within 5 %
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["active_table"], clock=api.clock)
    r = c.post(f"/api/proposals/{prop['id']}/push", headers=pro, json=push_body(api))      # no reason needed
    assert r.status_code == 201 and r.json()["override_reason"] is None


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
    assert push_to_leg(api, prop).status_code == 201
    r = c.post(f"/api/devices/{DEVICE}/commands", headers=api.as_("viewer"), json={"command": "enter_safe_mode"})
    assert r.status_code == 403
    r = c.post(f"/api/devices/{DEVICE}/commands", headers=pro, json={"command": "enter_safe_mode"})
    assert r.status_code == 202
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["safe_mode"], clock=api.clock)
    c.post(f"/api/devices/{DEVICE}/commands", headers=pro, json={"command": "leave_safe_mode"})
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(), lambda d: d["mode"] == "active", clock=api.clock)


def test_an_open_telemetry_stream_closes_when_its_user_is_disabled(sim_api):
    api = sim_api
    c, admin = api.client, api.as_("admin")
    viewer_id = next(u["id"] for u in c.get("/api/users", headers=admin).json() if u["username"] == "viewer")
    token = api.as_("viewer")["Authorization"].split()[1]
    with c.websocket_connect(f"/api/devices/{DEVICE}/telemetry?token={token}") as ws:
        assert ws.receive_json()["type"] == "status"
        c.patch(f"/api/users/{viewer_id}", headers=admin, json={"disabled": True})
        deadline = time.monotonic() + 20 * RECHECK_TOKEN_S
        with pytest.raises(WebSocketDisconnect) as closed:
            while time.monotonic() < deadline:   # the token is checked again every RECHECK_TOKEN_S of real time
                api.clock.advance(0.1)           # the unworn leg reports on: a status every 0.1 s
                ws.receive_json()
        assert closed.value.code == 1008 and "disabled" in closed.value.reason


def test_a_table_built_for_another_body_mass_is_flagged_on_the_device(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    prop = approved_proposal(api)                                  # built for 80 kg
    assert push_to_leg(api, prop).status_code == 201
    device = wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(),
                      lambda d: d["active_table"] is not None, clock=api.clock)
    assert device["active_table"]["body_mass_kg"] == 80.0 and device["body_mass_mismatch"] is None
    assert c.patch(f"/api/patients/{prop['patient_id']}", headers=pro, json={"body_mass_kg": 83.0}).status_code == 200
    assert c.get(f"/api/devices/{DEVICE}", headers=pro).json()["body_mass_mismatch"] is None      # within 5 %
    assert c.patch(f"/api/patients/{prop['patient_id']}", headers=pro, json={"body_mass_kg": 95.0}).status_code == 200
    flag = c.get(f"/api/devices/{DEVICE}", headers=pro).json()["body_mass_mismatch"]
    assert flag["built_for_kg"] == 80.0 and flag["patient_now_kg"] == 95.0 and flag["difference_percent"] == 18.8
    assert "P-001 · table v1 was built for 80 kg" in flag["message"] and "95 kg" in flag["message"]


def test_the_assigned_patient_stands_on_the_simulated_leg_between_walks_with_live_signals(sim_api):
    """Live signals while the patient stands, not only during a recorded walk; nobody wearing the leg: none."""
    api = sim_api
    c, viewer = api.client, api.as_("viewer")
    patient = api.new_patient("P-STAND", 80.0)
    device = assign(api, patient["id"])
    assert device["bench_state"] == "standing" and device["walking"] is False
    samples = []
    with c.websocket_connect(f"/api/devices/{DEVICE}/telemetry?token={viewer['Authorization'].split()[1]}") as ws:
        assert ws.receive_json()["type"] == "status"
        api.clock.advance(0.6)
        while len(samples) < 50:
            msg = ws.receive_json()
            if msg["type"] == "telemetry":
                samples.append(msg)
    assert all(0.4 * 80 * 9.81 < s["load_N"] < 0.6 * 80 * 9.81 for s in samples)   # half the body weight
    assert max(s["knee_angle_deg"] for s in samples) < 10.0                      # the knee near extension
    r = c.delete(f"/api/devices/{DEVICE}/assignment", headers=api.as_("prosthetist"))
    assert r.status_code == 200 and r.json()["bench_state"] == "not_worn"


def test_the_lost_link_mode_is_the_prosthetists_choice_audited_sent_to_the_leg_and_obeyed(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    device = lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json()   # noqa: E731
    prop = approved_proposal(api)
    assert push_to_leg(api, prop).status_code == 201
    wait_for(device, lambda d: d["mode"] == "active" and d["link_mode_on_device"] == "supervised", clock=api.clock)
    assert device()["link_mode"] == "supervised"
    body = {"link_mode": "autonomous", "reason": "home trial: the patient walks far from the clinic's server"}
    assert c.put(f"/api/devices/{DEVICE}/link-mode", headers=api.as_("viewer"), json=body).status_code == 403
    for bad in ({**body, "link_mode": "sometimes"}, {**body, "reason": "home"}, {"link_mode": "autonomous"}):
        r = c.put(f"/api/devices/{DEVICE}/link-mode", headers=pro, json=bad)
        assert r.status_code == 422, r.text
    r = c.put(f"/api/devices/{DEVICE}/link-mode", headers=pro, json=body)
    assert r.status_code == 200 and r.json()["link_mode"] == "autonomous"
    wait_for(device, lambda d: d["link_mode_on_device"] == "autonomous", clock=api.clock)
    [entry] = [e for e in c.get("/api/audit", headers=api.as_("admin"), params={"entity": "device"}).json()["items"]
               if e["action"] == "device.link_mode"]
    assert entry["before"]["link_mode"] == "supervised" and entry["after"]["reason"] == body["reason"]

    link = api.client.app.state.devices.get(DEVICE).link
    link.pause_heartbeat()                 # the link to the server is lost: the autonomous leg runs on
    wait_for(device, lambda d: "heartbeat_lost" in d["faults"], clock=api.clock)
    assert device()["mode"] == "active"
    link.pause_heartbeat(False)
    wait_for(device, lambda d: "heartbeat_lost" not in d["faults"] and d["mode"] == "active", clock=api.clock)

    r = c.put(f"/api/devices/{DEVICE}/link-mode", headers=pro,
              json={"link_mode": "supervised", "reason": "back in the clinic for tuning"})
    wait_for(device, lambda d: d["link_mode_on_device"] == "supervised", clock=api.clock)
    link.pause_heartbeat()                 # supervised: the lost link means safe mode
    wait_for(device, lambda d: d["safe_mode"] and "heartbeat_lost" in d["faults"], clock=api.clock)
    link.pause_heartbeat(False)


def test_a_restarted_leg_is_sent_the_stored_lost_link_mode_again(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    r = c.put(f"/api/devices/{DEVICE}/link-mode", headers=pro,
              json={"link_mode": "autonomous", "reason": "home trial with the patient's own phone link"})
    assert r.status_code == 200
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(),
             lambda d: d["link_mode_on_device"] == "autonomous", clock=api.clock)
    firmware = api.client.app.state.devices.get(DEVICE).node.firmware
    firmware.link_mode_ = type(firmware.link_mode_).SUPERVISED   # as after a restart: the device starts supervised
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(),
             lambda d: d["link_mode_on_device"] == "autonomous", clock=api.clock)


def test_the_simulated_leg_has_nothing_to_calibrate_and_a_calibration_request_is_checked(sim_api):
    """The simulated bench reads itself exactly: the leg itself answers ``no_sensors`` (audited); the request is the
    prosthetist's, a step goes with ``measure`` only, an unknown device is a 404."""
    api = sim_api
    c = api.client
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=api.as_("viewer")).json(), lambda d: d["online"],
             clock=api.clock)
    url = f"/api/devices/{DEVICE}/calibration"
    r = c.post(url, headers=api.as_("prosthetist"), json={"action": "start"})
    assert r.status_code == 200, r.text
    answer = r.json()
    assert answer["outcome"] == "refused" and answer["refused_reason"] == "no_sensors"
    assert "simulated bench reads itself exactly" in answer["refused_words"]
    assert c.post(url, headers=api.as_("viewer"), json={"action": "start"}).status_code == 403
    bad = c.post(url, headers=api.as_("prosthetist"), json={"action": "measure"})
    assert bad.status_code == 422 and "a step is named with action 'measure'" in bad.text
    assert c.post(url, headers=api.as_("prosthetist"), json={"action": "start", "step": "direction"}).status_code == 422
    assert c.post(url, headers=api.as_("prosthetist"), json={"action": "explode"}).status_code == 422
    assert c.post("/api/devices/nope/calibration", headers=api.as_("prosthetist"),
                  json={"action": "start"}).status_code == 404
    audit = c.get("/api/audit", headers=api.as_("admin"), params={"limit": 20}).json()
    items = audit["items"] if isinstance(audit, dict) else audit
    assert [e["action"] for e in items].count("device.calibration.start") == 1


def test_the_simulated_leg_walks_the_leg_its_patient_describes(sim_api):
    """Assigned to a patient whose record describes their leg, the simulated device is fitted to it (and says so);
    handed to a patient without a description, it walks the server's bench leg again."""
    from device_bridge.sim.leg_file import load_leg_file

    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    short, plain = api.new_patient("P-SHORT"), api.new_patient("P-PLAIN")
    c.patch(f"/api/patients/{short['id']}", headers=pro, json={"leg": load_leg_file("short_person").description()})
    assign(api, short["id"])
    assert c.get(f"/api/devices/{DEVICE}", headers=pro).json()["bench_leg"] == "short person (1.58 m)"
    assign(api, plain["id"])
    assert c.get(f"/api/devices/{DEVICE}", headers=pro).json()["bench_leg"] == "nominal"
