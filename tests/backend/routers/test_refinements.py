"""Refinements from walking through the API.

The sessions here are recorded offline: the bench walks the approved table (faster than real time) and its samples are
stored as a leg's telemetry at the device's 100 Hz. Where a test needs a leg whose swing knee flexes consistently
short, the recorded knee angle is scaled down after toe-off: a synthetic change, said where it is made.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from backend.store import devices as devices_store
from backend.store import proposals as proposals_store
from backend.store import sessions as sessions_store
from backend.store.users import User
from controller_core.fsm import ImpedanceSchedule, StateMachineController
from controller_core.table import ParameterTable
from device_bridge.bench.task_reference import task_reference
from device_bridge.protocol import Mode
from device_bridge.sim.simulate import run_walk
from tests.helpers.api import walk_preview

DEVICE = "bench-leg"


def _samples(t: ParameterTable, table: dict, model, mass: float, seconds: float, swing_scale: float = 1.0,
             mode: Mode = Mode.ACTIVE) -> list[tuple]:
    task = table["task"]
    ref = task_reference(task["speed_mps"], task["incline_deg"], model, mass)
    log = run_walk(StateMachineController(ImpedanceSchedule.from_table(t)), ref, mass, seconds)
    c = log.channels
    idx = np.arange(0, c["time_s"].size, 10)             # the device's 10 ms telemetry period
    knee = c["knee_angle_rad"][idx].copy()
    if swing_scale != 1.0:   # synthetic: the knee flexes less once the foot is off the ground
        swing = c["load_N"][idx] < 0.1 * mass * 9.81
        knee[swing] *= swing_scale
    return [(k, float(c["time_s"][i]), int(mode), int(c["state"][i]), float(knee[k]),
             float(c["knee_velocity_rad_s"][i]), float(c["knee_torque_Nm"][i]), float(c["ankle_angle_rad"][i]),
             float(c["ankle_velocity_rad_s"][i]), float(c["ankle_torque_Nm"][i]), float(c["load_N"][i]),
             float(c["ankle_moment_Nm"][i]), None, None, None, None, None) for k, i in enumerate(idx)]


def recorded_session(api, model, patient: dict, table: dict, seconds: float = 25.0, **walk) -> int:
    """A stopped session of the patient on the approved table, its samples from the bench walked offline."""
    conn = api.db()
    try:
        if conn.execute("SELECT 1 FROM devices WHERE id = ?", (DEVICE,)).fetchone() is None:
            devices_store.register_device(conn, DEVICE, "can", "virtual", "bench")
        user = User(id=1, username="prosthetist", role="prosthetist")
        task = {**{k: table["task"][k] for k in ("speed_mps", "incline_deg")}, "body_mass_kg": patient["body_mass_kg"]}
        sid = sessions_store.start_session(conn, patient["id"], DEVICE, task,
                                           {"proposal_id": table["id"], "envelope_id": None, "table_version": 1,
                                            "crc32": 1}, user)
        stored = proposals_store.stored_table(proposals_store.get_row(conn, table["id"]))
        sessions_store.add_samples(conn, sid, _samples(stored, table, model, patient["body_mass_kg"], seconds, **walk))
    finally:
        conn.close()
    r = api.client.post(f"/api/sessions/{sid}/stop", headers=api.as_("prosthetist"))
    assert r.status_code == 200, r.text
    return sid


def approved(api, patient: dict, speed: float = 1.2) -> dict:
    prop = api.propose(patient["id"], speed=speed)
    walk_preview(api, prop["id"])
    r = api.client.post(f"/api/proposals/{prop['id']}/approve", headers=api.as_("prosthetist"),
                        json={"comment": "ok", "override_reason": "test: the refinement, not the bench gate"})
    assert r.status_code == 200, r.text
    return api.client.get(f"/api/proposals/{prop['id']}", headers=api.as_("viewer")).json()


@pytest.fixture
def walked(api, model):
    patient = api.new_patient(mass=80.0)
    table = approved(api, patient)
    sid = recorded_session(api, model, patient, table, swing_scale=0.85)
    return patient, table, sid


def test_a_refinement_is_a_draft_with_its_evidence_that_moves_the_short_swing_up(api, walked):
    _, table, sid = walked
    c, pro = api.client, api.as_("prosthetist")
    versions = api.count("proposals")
    r = c.post(f"/api/proposals/{table['id']}/refinements", headers=pro,
               json={"session_ids": [sid], "comment": "the knee swings short"})
    assert r.status_code == 201, r.text
    ref = r.json()
    assert api.count("proposals") == versions + 1 and ref["parent_id"] == table["id"] and ref["session_ids"] == [sid]
    node = ref["nodes"][0]
    swing = node["quantities"]["knee_swing_flexion_peak_deg"]
    assert swing["act"] and swing["error"] < -2.0 and swing["ci95"][1] < 0.0 and swing["expected_error"] > swing["error"]
    bench = node["bench"]   # the bench walked the old and the new rows at the node's task, same feature definitions
    assert bench["walked"] and set(bench["after"]) == set(node["quantities"]) and bench["falls_after"] >= 0
    theta = [ch for ch in ref["changes"] if ch["field"] == "knee.swing_flexion.theta_e_deg"]
    assert theta and theta[0]["after"] > theta[0]["before"] and "swing knee flexion" in theta[0]["why"]
    assert "short" in theta[0]["why"]
    new = c.get(f"/api/proposals/{ref['proposal_id']}", headers=pro).json()
    assert new["status"] == "draft"
    row = next(x for x in new["table"] if x["joint"] == "knee" and x["subphase"] == "swing_flexion")
    assert row["fit_method"] == "refined" and row["theta_e_deg"] == pytest.approx(theta[0]["after"], abs=1e-3)
    assert new["safety"]["ok"]
    # the diff shows old, new and change per cell; the record reads back; the audit says it was a refinement
    diff = c.get(f"/api/proposals/{table['id']}/diff/{new['id']}", headers=pro).json()
    assert any(d["field"] == "knee.swing_flexion.theta_e_deg" for d in diff["changes"])
    assert c.get(f"/api/proposals/{new['id']}/refinement", headers=pro).json()["id"] == ref["id"]
    assert c.get(f"/api/proposals/{table['id']}/refinement", headers=pro).status_code == 404
    entries = c.get("/api/audit", headers=api.as_("admin"), params={"entity": "proposal"}).json()["items"]
    refine = [e for e in entries if e["action"] == "proposal.refine"]
    assert len(refine) == 1 and refine[0]["entity_id"] == new["id"]


def test_a_refined_draft_cannot_reach_the_leg_without_approval(api, walked):
    _, table, sid = walked
    c, pro = api.client, api.as_("prosthetist")
    ref = c.post(f"/api/proposals/{table['id']}/refinements", headers=pro,
                 json={"session_ids": [sid], "comment": "refine"}).json()
    pushes = api.count("pushes")
    r = c.post(f"/api/proposals/{ref['proposal_id']}/push", headers=pro,
               json={"device_id": DEVICE, "replaces_proposal_id": None, "replaces_envelope_id": None,
                     "patient_ready": True})
    assert r.status_code in (404, 409, 422) and api.count("pushes") == pushes
    assert "approved" in r.text or "draft" in r.text


def test_sessions_of_another_patient_or_another_version_are_refused_and_nothing_is_stored(api, model, walked):
    patient, table, sid = walked
    c, pro = api.client, api.as_("prosthetist")
    other = api.new_patient(code="P-002", mass=80.0)
    other_table = approved(api, other)
    other_sid = recorded_session(api, model, other, other_table, seconds=6.0)
    second = approved(api, patient, speed=1.0)
    before = (api.count("proposals"), api.count("refinements"))
    r = c.post(f"/api/proposals/{table['id']}/refinements", headers=pro,
               json={"session_ids": [sid, other_sid], "comment": "x"})
    assert r.status_code == 422 and "not the patient" in r.json()["detail"]
    r = c.post(f"/api/proposals/{second['id']}/refinements", headers=pro, json={"session_ids": [sid], "comment": "x"})
    assert r.status_code == 422 and "not this table" in r.json()["detail"]
    r = c.post(f"/api/proposals/{table['id']}/refinements", headers=api.as_("viewer"),
               json={"session_ids": [sid], "comment": "x"})
    assert r.status_code == 403
    assert c.post(f"/api/proposals/{table['id']}/refinements", headers=pro,
                  json={"session_ids": [], "comment": "x"}).status_code == 422
    assert c.post(f"/api/proposals/{table['id']}/refinements", headers=pro,
                  json={"session_ids": [987654], "comment": "x"}).status_code == 404
    assert (api.count("proposals"), api.count("refinements")) == before


def test_a_session_in_safe_mode_all_along_is_refused(api, model):
    patient = api.new_patient(mass=80.0)
    table = approved(api, patient)
    sid = recorded_session(api, model, patient, table, seconds=6.0, mode=Mode.SAFE)
    r = api.client.post(f"/api/proposals/{table['id']}/refinements", headers=api.as_("prosthetist"),
                        json={"session_ids": [sid], "comment": "x"})
    assert r.status_code == 422 and "safe mode" in r.json()["detail"] and api.count("refinements") == 0


def test_a_leg_on_target_gives_nothing_to_refine_and_says_why(api, model):
    patient = api.new_patient(mass=80.0)
    table = approved(api, patient)
    sid = recorded_session(api, model, patient, table, seconds=8.0)
    r = api.client.post(f"/api/proposals/{table['id']}/refinements", headers=api.as_("prosthetist"),
                        json={"session_ids": [sid], "comment": "x"})
    assert r.status_code == 422 and r.json()["detail"].startswith("nothing to refine")
    assert "too few strides" in r.json()["detail"] or "disagree" in r.json()["detail"]
    assert math.isfinite(len(r.json()["nodes"])) and api.count("refinements") == 0
