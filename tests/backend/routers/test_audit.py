"""The append-only audit log."""

from __future__ import annotations


def test_audit_pages_newest_first(api):
    patient = api.new_patient()
    for _ in range(3):
        api.propose(patient["id"])
    h = api.as_("prosthetist")
    first = api.client.get("/api/audit", headers=h, params={"entity": "proposal", "limit": 2}).json()
    assert len(first["items"]) == 2 and first["items"][0]["id"] > first["items"][1]["id"]
    rest = api.client.get("/api/audit", headers=h, params={"entity": "proposal", "limit": 2,
                                                           "before_id": first["next_before_id"]}).json()
    assert len(rest["items"]) == 1 and rest["next_before_id"] is None
    assert api.client.get("/api/audit", headers=h, params={"limit": 0}).status_code == 422


def test_the_audit_log_is_for_prosthetists_and_admins(api):
    r = api.client.get("/api/audit", headers=api.as_("viewer"))
    assert r.status_code == 403 and "prosthetist or admin" in r.json()["detail"]
    for role in ("prosthetist", "admin"):
        assert api.client.get("/api/audit", headers=api.as_(role)).status_code == 200
