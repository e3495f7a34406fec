"""Versions by one id: a table and an envelope share one id space, and any version is found by its id alone."""

from __future__ import annotations

from tests.backend.routers.test_envelopes import request_envelope


def test_a_version_is_found_by_its_id_whichever_kind_it_is(api):
    patient = api.new_patient()
    table = api.propose(patient["id"])
    envelope = request_envelope(api, patient["id"], grid=[2, 2])
    assert envelope["id"] != table["id"]                                      # one id space
    viewer = api.as_("viewer")
    for version, path in ((table, "proposals"), (envelope, "envelopes")):
        found = api.client.get(f"/api/versions/{version['id']}", headers=viewer, follow_redirects=False)
        assert found.status_code == 307 and found.headers["location"] == f"/api/{path}/{version['id']}"
        assert api.client.get(f"/api/versions/{version['id']}", headers=viewer).json()["id"] == version["id"]
    missing = api.client.get(f"/api/versions/{envelope['id'] + 1000}", headers=viewer)
    assert missing.status_code == 404 and "not found" in missing.json()["detail"]
    assert api.client.get(f"/api/versions/{table['id']}").status_code == 401      # signed in, as every read
