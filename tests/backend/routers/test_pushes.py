"""Envelope pushes through the API: the same lifecycle and checks as a table push, and sessions on an adaptive leg."""

from __future__ import annotations

import re

import pytest

from tests.backend.routers.test_envelopes import request_envelope
from tests.helpers.api import DEVICE, FIXTURE_OVERRIDE, assign, cosign, push_body, wait_for, wait_recorded
from tests.helpers.sql import sql


def approved_envelope(api, patient_id: int) -> dict:
    e = request_envelope(api, patient_id)
    cosign(api, "envelope", e["id"])
    r = api.client.post(f"/api/envelopes/{e['id']}/approve", headers=api.as_("prosthetist"),
                        json={"comment": "ok", "override_reason": FIXTURE_OVERRIDE})
    assert r.status_code == 200, r.text
    return r.json()


def push_envelope(api, envelope_id: int, **overrides):
    return api.client.post(f"/api/envelopes/{envelope_id}/push", headers=api.as_("prosthetist"),
                           json={**push_body(api), "override_reason": FIXTURE_OVERRIDE, **overrides})


def test_an_approved_envelope_runs_on_its_patients_leg_and_a_table_can_replace_it(sim_api):
    api = sim_api
    c, pro, viewer = api.client, api.as_("prosthetist"), api.as_("viewer")
    patient = api.new_patient()
    draft = request_envelope(api, patient["id"])
    assign(api, patient["id"])
    r = push_envelope(api, draft["id"])
    assert r.status_code == 409 and "only approved envelopes" in r.json()["detail"]
    env = approved_envelope(api, patient["id"])

    r = push_envelope(api, env["id"])
    assert r.status_code == 201, r.text
    push = r.json()
    assert push["kind"] == "envelope" and push["envelope_id"] == env["id"] and push["proposal_id"] is None
    assert push["crc32"] == f"{env['wire_crc32']:08x}" and push["label"] == "P-001 · envelope v2"
    assert push["table_label"] is None and push["task"] == {"speed_mps": 1.2, "incline_deg": 0.0}   # nominal
    device = wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=viewer).json(),
                      lambda d: d["active_crc32"] == push["crc32"], clock=api.clock)
    assert device["active_table"]["kind"] == "envelope" and device["active_table"]["label"] == push["label"]
    got = wait_for(lambda: c.get(f"/api/envelopes/{env['id']}", headers=viewer).json(),
                   lambda e: e["deployment"] == "active_on_device", clock=api.clock)
    assert got["status"] == "approved"
    [record] = c.get(f"/api/envelopes/{env['id']}/pushes", headers=viewer).json()
    assert record["status"] == "active"
    [entry] = [a for a in c.get("/api/audit?entity=envelope", headers=api.as_("prosthetist")).json()["items"]
               if a["action"] == "envelope.push"]
    assert entry["entity_id"] == env["id"] and entry["after"]["crc32"] == push["crc32"]

    # what the caller confirms replacing must be the envelope now on the leg
    prop = api.propose(patient["id"])
    assert c.get(f"/api/proposals/{prop['id']}/preview", headers=viewer).status_code == 200
    assert c.post(f"/api/proposals/{prop['id']}/approve", headers=pro, json={"comment": "ok"}).status_code == 200
    stale = {**push_body(api), "replaces_envelope_id": None}
    r = c.post(f"/api/proposals/{prop['id']}/push", headers=pro, json=stale)
    assert r.status_code == 409 and "now runs P-001 · envelope v2" in r.json()["detail"]
    assert c.get(f"/api/proposals/{prop['id']}/pushes", headers=viewer).json() == []      # nothing sent
    r = c.post(f"/api/proposals/{prop['id']}/push", headers=pro, json=push_body(api))
    assert r.status_code == 201, r.text
    wait_for(lambda: c.get(f"/api/envelopes/{env['id']}", headers=viewer).json(),
             lambda e: e["deployment"] == "replaced", clock=api.clock)


def test_an_envelope_goes_only_to_the_leg_of_its_patient_at_its_body_mass(sim_api):
    api = sim_api
    c = api.client
    owner, other = api.new_patient("P-070", 70.0), api.new_patient("P-090", 90.0)
    env = approved_envelope(api, owner["id"])
    assign(api, other["id"])
    r = push_envelope(api, env["id"])
    assert r.status_code == 409 and "assigned to P-090 (90 kg), not to P-070 (70 kg) whose envelope" in r.json()["detail"]
    assign(api, owner["id"])
    conn = api.db()
    sql(conn, "UPDATE patients SET body_mass_kg = 80 WHERE id = :id", id=owner["id"])
    conn.close()
    r = push_envelope(api, env["id"], override_reason=None)
    assert r.status_code == 409 and "built for 70 kg and P-070 now weighs 80 kg" in r.json()["detail"]
    assert c.get(f"/api/envelopes/{env['id']}/pushes", headers=api.as_("viewer")).json() == []


def test_a_course_session_records_the_legs_own_task_estimate_and_summarises_it_by_region(sim_api):
    api = sim_api
    c, viewer = api.client, api.as_("viewer")
    patient = api.new_patient()
    env = approved_envelope(api, patient["id"])
    assign(api, patient["id"])
    push = push_envelope(api, env["id"]).json()
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=viewer).json(),
             lambda d: d["active_crc32"] == push["crc32"], clock=api.clock)
    r = c.post(f"/api/patients/{patient['id']}/sessions", headers=api.as_("prosthetist"),
               json={"device_id": DEVICE, "course": "mixed"})
    assert r.status_code == 201, r.text
    session = r.json()
    assert session["course"] == "mixed" and session["envelope_id"] == env["id"]
    assert session["table_label"] == "P-001 · envelope v1" and session["task"]["speed_mps"] == 1.0   # first segment
    device = c.get(f"/api/devices/{DEVICE}", headers=viewer).json()
    assert device["bench_task"]["course"] == "mixed"
    wait_recorded(api, session["id"], 7.0)                                   # 7 s of the course, by the device
    summary = c.post(f"/api/sessions/{session['id']}/stop", headers=api.as_("prosthetist")).json()["summary"]
    cols = c.get(f"/api/sessions/{session['id']}/samples", headers=viewer).json()["columns"]
    estimates = [v for v in cols["estimated_speed_mps"] if v is not None]
    assert estimates and all(0.6 < v < 1.4 for v in estimates)          # the first segment is 1.0 m/s, level
    assert set(cols["adaptive_mode"]) <= {"nominal", "partial", "adaptive", "clamped"}
    adaptive = summary["adaptive"]
    assert adaptive["speeds_mps"] == env["speeds_mps"] and adaptive["inclines_deg"] == env["inclines_deg"]
    seen_s = sum(map(sum, adaptive["time_s"]))
    assert seen_s + adaptive["unestimated_s"] == pytest.approx(summary["duration_s"], abs=0.05)
    assert sum(map(sum, adaptive["strides"])) + adaptive["unestimated_strides"] == summary["strides"]
    level = adaptive["inclines_deg"].index(0.0)
    assert sum(row[level] for row in adaptive["strides"]) >= 1           # strides counted on level ground
    scored = adaptive["errors_by_region"]["strides_scored"]
    assert sum(map(sum, scored)) >= 1 and sum(adaptive["adaptive_mode_s"].values()) > 0
    overall = adaptive["errors_by_region"]["overall"]
    assert overall["strides"] == sum(map(sum, scored)) and 0 < overall["knee_angle_per_stride_rmse_deg"] < 30
    # the headline scores each stride at the course's own task there, not at the course's first task
    head = summary["headline"]
    assert head["against"] == "each stride's own task on the 'mixed' course" and head["strides_scored"] >= 1
    assert head["enough_strides"] == (head["strides_scored"] >= 5) and 0 < head["knee_angle_rmse_deg"] < 30
    listed = c.get(f"/api/patients/{patient['id']}/sessions", headers=viewer).json()[0]
    assert listed["task_words"].startswith("'mixed' course: ") and "m/s" in listed["task_words"]
    pdf = c.get(f"/api/sessions/{session['id']}/report.pdf", headers=viewer).content
    assert pdf.startswith(b"%PDF") and len(re.findall(rb"/Type\s*/Page\b", pdf)) == 2   # the envelope's own page


def test_two_pushes_confirming_the_same_envelope_on_the_leg_cannot_both_go(sim_api):
    """The check of what the leg runs and the push are one step per device: of two pushes that both confirm the
    envelope on the leg, one goes and the other is refused naming what the leg now runs."""
    import threading

    api = sim_api
    patient = api.new_patient()
    assign(api, patient["id"])
    current = approved_envelope(api, patient["id"])
    assert push_envelope(api, current["id"]).status_code == 201
    wait_for(lambda: api.client.get(f"/api/envelopes/{current['id']}", headers=api.as_("viewer")).json(),
             lambda e: e["deployment"] == "active_on_device", clock=api.clock)
    rivals = [approved_envelope(api, patient["id"]) for _ in range(2)]
    body = {**push_body(api), "replaces_envelope_id": current["id"], "override_reason": FIXTURE_OVERRIDE}
    answers: dict[int, object] = {}
    gate = threading.Barrier(2)

    def push(env: dict) -> None:
        gate.wait()
        answers[env["id"]] = api.client.post(f"/api/envelopes/{env['id']}/push", headers=api.as_("prosthetist"),
                                             json=body)

    threads = [threading.Thread(target=push, args=(e,)) for e in rivals]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    codes = sorted(r.status_code for r in answers.values())
    assert codes == [201, 409], [r.text for r in answers.values()]
    winner = next(i for i, r in answers.items() if r.status_code == 201)
    loser = next(r for r in answers.values() if r.status_code == 409)
    label = next(e["envelope_label"] for e in rivals if e["id"] == winner)
    assert label in loser.json()["detail"] and loser.json()["on_leg"]["envelope_id"] == winner
