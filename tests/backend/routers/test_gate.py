"""Withdrawing an approved version: never pushed again, and the leg that runs it goes back to the last version it ran
that was not withdrawn, or to safe mode, with the reason on the monitor. (The two-person sign-off of the bench gate
is tested in test_bench_gate.py.)"""

from __future__ import annotations

from backend.db import write_transaction
from backend.devices import manager as manager_module
from backend.store import versions, withdrawals
from backend.store.users import User
from tests.helpers.api import DEVICE, approve_anyway, approved_proposal, push_body, push_to_leg, wait_for, walk_preview

WHY = "the patient reported the knee giving way on the ramp"


def _device(api) -> dict:
    return api.client.get(f"/api/devices/{DEVICE}", headers=api.as_("prosthetist")).json()


def _running(api, proposal_id: int) -> dict:
    return wait_for(lambda: _device(api), lambda d: d["active_table"] and d["active_table"]["proposal_id"] == proposal_id
                    and d["mode"] == "active", clock=api.clock)


def _withdraw(api, proposal_id: int, role: str = "prosthetist", reason: str = WHY):
    return api.client.post(f"/api/proposals/{proposal_id}/withdraw", headers=api.as_(role), json={"reason": reason})


def test_a_withdrawn_table_is_never_pushed_again_and_its_leg_goes_back_to_the_one_before(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    first = approved_proposal(api)
    assert push_to_leg(api, first).status_code == 201
    _running(api, first["id"])
    second = api.propose(first["patient_id"], speed=1.0)
    walk_preview(api, second["id"])
    assert approve_anyway(api, "proposal", second["id"]).status_code == 200
    r = c.post(f"/api/proposals/{second['id']}/push", headers=pro,
               json={**push_body(api), "override_reason": "test: the withdrawal, not the bench gate"})
    assert r.status_code == 201, r.text
    _running(api, second["id"])

    assert _withdraw(api, second["id"], role="viewer").status_code == 403
    assert _withdraw(api, second["id"], reason="short").status_code == 422
    r = _withdraw(api, second["id"])
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["withdrawal"]["by"] == "prosthetist" and out["withdrawal"]["reason"] == WHY
    [leg] = out["legs"]
    assert leg["device_id"] == DEVICE and leg["action"] == "sent_back" and leg["to_label"] == "P-001 · table v1"
    device = _running(api, first["id"])                    # back on the first table, at its next heel strike
    notice = device["withdrawal_notice"]
    assert notice["state"] == "sent_back" and notice["label"] == "P-001 · table v1"
    assert "P-001 · table v2 was withdrawn by prosthetist" in notice["words"] and WHY in notice["words"]

    shown = c.get(f"/api/proposals/{second['id']}", headers=pro).json()
    assert shown["status"] == "approved" and shown["withdrawal"]["reason"] == WHY   # the decision itself stays
    r = c.post(f"/api/proposals/{second['id']}/push", headers=pro,
               json={**push_body(api), "override_reason": "test: the withdrawal, not the bench gate"})
    assert r.status_code == 409 and "withdrawn by prosthetist" in r.json()["detail"]
    again = _withdraw(api, second["id"])
    assert again.status_code == 409 and "already withdrawn" in again.json()["detail"]
    [back, *_] = c.get(f"/api/proposals/{first['id']}/pushes", headers=pro).json()
    assert back["sent_back_reason"].startswith("P-001 · table v2 was withdrawn") and back["requested_by"] == "prosthetist"
    audit = c.get("/api/audit", headers=api.as_("admin"), params={"entity": "proposal",
                                                                  "entity_id": second["id"]}).json()["items"]
    assert audit[0]["action"] == "proposal.withdraw" and audit[0]["after"] == {"withdrawn": True, "reason": WHY}


def test_a_leg_with_nothing_to_go_back_to_is_put_in_safe_mode_and_stays_there(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    only = approved_proposal(api)
    assert push_to_leg(api, only).status_code == 201
    _running(api, only["id"])
    [leg] = _withdraw(api, only["id"]).json()["legs"]
    assert leg["action"] == "safe_mode" and "no earlier version" in leg["detail"]
    device = wait_for(lambda: _device(api), lambda d: d["safe_mode"], clock=api.clock)
    notice = device["withdrawal_notice"]
    assert notice["state"] == "runs_withdrawn" and WHY in notice["words"] and "safe mode" in notice["words"]
    r = c.post(f"/api/devices/{DEVICE}/commands", headers=pro, json={"command": "leave_safe_mode"})
    assert r.status_code == 409 and "withdrawn" in r.json()["detail"]
    api.clock.advance(1.0)
    assert _device(api)["safe_mode"]


def test_a_leg_found_running_a_version_withdrawn_elsewhere_is_put_in_safe_mode(sim_api, monkeypatch):
    """Withdrawn through another API instance (here: its store, this process not told): the leg's reports are
    checked again every few seconds, and the leg is put in safe mode."""
    monkeypatch.setattr(manager_module, "WITHDRAWAL_RECHECK_S", 0.0)
    api = sim_api
    prop = approved_proposal(api)
    assert push_to_leg(api, prop).status_code == 201
    _running(api, prop["id"])
    with api.db() as conn, write_transaction(conn):
        withdrawals.withdraw(conn, "proposal", versions.get_row(conn, "proposal", prop["id"]),
                             User(1, "prosthetist", "prosthetist"), WHY)
    device = wait_for(lambda: _device(api), lambda d: d["safe_mode"], clock=api.clock)
    assert device["withdrawal_notice"]["state"] == "runs_withdrawn"


def test_only_an_approved_version_is_withdrawn(api):
    p = api.propose(api.new_patient()["id"])
    r = _withdraw(api, p["id"])
    assert r.status_code == 409 and "rejected instead" in r.json()["detail"]
    assert api.client.get(f"/api/proposals/{p['id']}", headers=api.as_("viewer")).json()["withdrawal"] is None
    assert _withdraw(api, 999999).status_code == 404
