"""Refinements from walking through the API.

The sessions here are recorded offline (tests/helpers/sessions.py): the bench walks the approved table and its samples
are stored as a leg's telemetry. Where a test needs a leg whose swing knee flexes consistently short, the recorded knee
angle is scaled down after toe-off (``swing_scale``): a synthetic change.
"""

from __future__ import annotations

import math

import pytest

from device_bridge.protocol import Mode
from tests.helpers.api import approve_anyway, walk_preview
from tests.helpers.sessions import BENCH_DEVICE as DEVICE
from tests.helpers.sessions import record_offline


def recorded_session(api, model, patient: dict, table: dict, seconds: float = 25.0, **walk) -> int:
    """A stopped session of the patient on the approved table, its samples from the bench walked offline."""
    sid = record_offline(api.database, model, patient, table["id"], seconds, **walk)
    r = api.client.post(f"/api/sessions/{sid}/stop", headers=api.as_("prosthetist"))
    assert r.status_code == 200, r.text
    return sid


def approved(api, patient: dict, speed: float = 1.2) -> dict:
    prop = api.propose(patient["id"], speed=speed)
    walk_preview(api, prop["id"])
    r = approve_anyway(api, "proposal", prop["id"], reason="test: the refinement, not the bench gate")
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
    assert ref["bench_leg"] == "the nominal bench leg"   # the leg the table was made for, and it says so
    assert all("spread" in q for q in node["quantities"].values())   # beside each bias, what no row moves
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
    assert c.get(f"/api/proposals/{table['id']}/refinement", headers=pro).json() is None   # not made by one
    assert c.get("/api/proposals/987654/refinement", headers=pro).status_code == 404
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


def test_the_refinement_names_the_leg_its_bench_walked():
    from backend.services.legs import words
    from device_bridge.sim.leg_file import LegFile, load_leg_file

    assert words(load_leg_file("heavy_foot")) == "the leg described as 'heavy powered ankle and foot'"
    assert words(LegFile()) == words(LegFile(name="anything")) == "the nominal bench leg"
    assert words(LegFile(body_height_m=1.7)) == "a leg described without a name"
