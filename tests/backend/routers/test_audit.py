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


def test_an_envelopes_entries_from_before_one_version_say_its_version_and_are_found_by_it(api):
    """Revision 0021 moved envelopes to version ids; the entries written before keep the old id (append-only), say the
    version it is now, and asking for the envelope by its version id finds them beside the new ones."""
    from backend.db import write_transaction
    from backend.store import audit
    from tests.backend.routers.test_envelopes import request_envelope
    from tests.helpers.sql import sql

    patient = api.new_patient()
    table = api.propose(patient["id"])
    envelope = request_envelope(api, patient["id"], grid=[2, 2])
    old = table["id"]              # its id before 0021: as after a real migration, a table's id now
    assert old < envelope["id"]
    with api.db() as conn, write_transaction(conn):
        sql(conn, "INSERT INTO legacy_ids (kind, old_id, version_id) VALUES ('envelope', :old, :id)",
            old=old, id=envelope["id"])
        audit.record(conn, None, "dana", "envelope.approve", "envelope", old, after={"status": "approved"})
    h = api.as_("prosthetist")
    page = api.client.get("/api/audit", headers=h, params={"entity": "envelope", "entity_id": envelope["id"]}).json()
    found = {(e["action"], e["entity_id"], e["now_version_id"]) for e in page["items"]}
    assert ("envelope.approve", old, envelope["id"]) in found              # the old entry, and what it is now
    assert ("envelope.create", envelope["id"], None) in found             # and the entries written since
    proposals = api.client.get("/api/audit", headers=h, params={"entity": "proposal"}).json()["items"]
    assert all(e["now_version_id"] is None for e in proposals)            # a table's id never moved
