"""The app: validation errors that name the field, methods a path allows, storage prepared before serving."""

from __future__ import annotations

from backend.app import prepare_storage
from backend.db import connect
from backend.migrate import schema_version
from backend.settings import Settings


def test_a_validation_error_names_the_field_and_what_was_wrong(api):
    r = api.client.post("/api/patients", headers=api.as_("prosthetist"),
                        json={"code_name": "P-9", "body_mass_kg": -3.0, "side": "left", "height_m": 1.8, "k_level": 3})
    assert r.status_code == 422
    body = r.json()
    assert "body mass must be at least 20 kg" in body["detail"]                 # in words on the page
    assert [(e["field"], e["type"]) for e in body["errors"]] == [("body_mass_kg", "greater_than_equal")]   # scripts


def test_a_wrong_method_is_405_with_the_methods_allowed(api):
    r = api.client.delete("/api/patients", headers=api.as_("prosthetist"))
    assert r.status_code == 405 and set(r.headers["Allow"].split(", ")) >= {"GET", "POST"}


def test_storage_is_created_and_migrated_before_serving(tmp_path):
    settings = Settings(data_dir=tmp_path / "new")
    prepare_storage(settings)
    conn = connect(settings.db_path)
    try:
        assert schema_version(conn) >= 11
    finally:
        conn.close()


def test_the_openapi_schema_lists_every_router(api):
    paths = api.client.get("/openapi.json").json()["paths"]
    for path in ("/api/patients", "/api/proposals/{proposal_id}", "/api/envelopes/{envelope_id}",
                 "/api/devices", "/api/sessions/{session_id}", "/api/task-range", "/api/audit"):
        assert path in paths
