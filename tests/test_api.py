"""The HTTP API in-process (FastAPI TestClient on a temporary SQLite file, the real default model)."""

from __future__ import annotations

import asyncio
import sqlite3
import threading

import httpx
import pytest
from api_helpers import PASSWORD, make_api

from backend.db import write_transaction
from backend.store import proposals as proposal_store
from backend.store.users import User


def _count(api, table: str) -> int:
    conn = api.db()
    try:
        return conn.execute(f"SELECT count(*) FROM {table}").fetchone()[0]
    finally:
        conn.close()


# ------------------------------------------------------------------ auth
def test_login_gives_an_expiring_bearer_token(api):
    r = api.client.post("/api/auth/token", data={"username": "viewer", "password": PASSWORD})
    assert r.status_code == 200
    body = r.json()
    assert body["token_type"] == "bearer" and body["expires_in"] == 8 * 3600 and len(body["access_token"]) >= 40
    me = api.client.get("/api/auth/me", headers={"Authorization": f"Bearer {body['access_token']}"}).json()
    assert me["username"] == "viewer" and me["role"] == "viewer"


def test_wrong_password_and_unknown_user_get_the_same_401(api):
    for user, pw in (("viewer", "wrong-password"), ("nobody", PASSWORD)):
        r = api.client.post("/api/auth/token", data={"username": user, "password": pw})
        assert r.status_code == 401 and r.json()["detail"] == "incorrect user name or password"
    actions = [e["action"] for e in api.client.get("/api/audit", headers=api.as_("viewer")).json()["items"]]
    assert actions.count("auth.login_failed") == 2


def test_expired_token_is_refused(api):
    conn = api.db()
    with write_transaction(conn):
        conn.execute("UPDATE tokens SET expires_at_unix = 0")
    conn.close()
    r = api.client.get("/api/patients", headers=api.as_("viewer"))
    assert r.status_code == 401 and "expired" in r.json()["detail"]
    assert r.headers["www-authenticate"] == "Bearer"


def test_every_endpoint_but_login_and_health_needs_a_token(api):
    open_paths = {"/api/auth/token", "/api/health"}
    checked = 0
    for path, operations in api.client.app.openapi()["paths"].items():
        if path in open_paths:
            continue
        url = path.replace("{patient_id}", "1").replace("{proposal_id}", "1").replace("{other_id}", "1")
        for method in operations:
            r = api.client.request(method.upper(), url, json={})
            assert r.status_code == 401, (method, path, r.status_code)
            checked += 1
    assert checked >= 12
    assert api.client.get("/api/health").status_code == 200


def test_roles_are_enforced_on_the_server(api):
    patient = api.new_patient()
    proposal = api.propose(patient["id"])
    for role in ("viewer", "admin"):
        h = api.as_(role)
        assert api.client.post("/api/patients", headers=h, json={"code_name": "X", "body_mass_kg": 70,
                                                                  "side": "right"}).status_code == 403
        assert api.client.patch(f"/api/patients/{patient['id']}", headers=h, json={"notes": "x"}).status_code == 403
        assert api.client.post(f"/api/patients/{patient['id']}/proposals", headers=h,
                               json={"speed_mps": 1.0}).status_code == 403
        r = api.client.post(f"/api/proposals/{proposal['id']}/approve", headers=h, json={"comment": "ok"})
        assert r.status_code == 403 and "prosthetist" in r.json()["detail"]
        # reading is allowed
        assert api.client.get(f"/api/proposals/{proposal['id']}", headers=h).status_code == 200
    for role in ("viewer", "prosthetist"):
        assert api.client.get("/api/users", headers=api.as_(role)).status_code == 403
    assert api.client.get("/api/proposals/1", headers=api.as_("viewer")).json()["status"] == "draft"


def test_admin_adds_users_and_passwords_are_scrypt_hashes(api):
    r = api.client.post("/api/users", headers=api.as_("admin"),
                        json={"username": "dana", "role": "prosthetist", "password": "a-long-password"})
    assert r.status_code == 201 and r.json()["role"] == "prosthetist" and "password" not in r.text
    assert api.client.post("/api/users", headers=api.as_("admin"), json={
        "username": "dana", "role": "viewer", "password": "a-long-password"}).status_code == 409
    short = api.client.post("/api/users", headers=api.as_("admin"),
                            json={"username": "eve", "role": "viewer", "password": "short"})
    assert short.status_code == 422 and "password" in short.json()["detail"]
    conn = api.db()
    stored = conn.execute("SELECT password_hash FROM users WHERE username = 'dana'").fetchone()[0]
    conn.close()
    assert stored.startswith("scrypt$16384$8$1$") and "a-long-password" not in stored
    assert api.client.post("/api/auth/token", data={"username": "dana", "password": "a-long-password"}).status_code == 200


# -------------------------------------------------------------- patients
def test_patient_create_read_update_with_audit(api):
    p = api.new_patient("P-007", 82.5)
    assert p["body_mass_kg"] == 82.5 and p["side"] == "left" and p["k_level"] == 3
    got = api.client.get(f"/api/patients/{p['id']}", headers=api.as_("viewer")).json()
    assert got == p
    r = api.client.patch(f"/api/patients/{p['id']}", headers=api.as_("prosthetist"),
                         json={"body_mass_kg": 84.0, "k_level": None})
    assert r.status_code == 200 and r.json()["body_mass_kg"] == 84.0 and r.json()["k_level"] is None
    entries = api.client.get("/api/audit", headers=api.as_("viewer"),
                             params={"entity": "patient", "entity_id": p["id"]}).json()["items"]
    update = entries[0]
    assert update["action"] == "patient.update" and update["actor"] == "prosthetist"
    assert update["before"] == {"body_mass_kg": 82.5, "k_level": 3}
    assert update["after"] == {"body_mass_kg": 84.0, "k_level": None}
    assert entries[1]["action"] == "patient.create"
    assert [x["code_name"] for x in api.client.get("/api/patients", headers=api.as_("viewer")).json()] == ["P-007"]


@pytest.mark.parametrize(("body", "field", "words"), [
    ({"code_name": "A", "body_mass_kg": 19.9, "side": "left"}, "body_mass_kg", "greater than or equal to 20"),
    ({"code_name": "A", "body_mass_kg": 70, "side": "up"}, "side", "'left' or 'right'"),
    ({"code_name": "", "body_mass_kg": 70, "side": "left"}, "code_name", "pattern"),
    ({"code_name": "A", "body_mass_kg": 70, "side": "left", "height_m": 3.1}, "height_m", "less than or equal to 2.5"),
    ({"code_name": "A", "body_mass_kg": 70, "side": "left", "shoe": 42}, "shoe", "not permitted"),
    ({"code_name": "A", "body_mass_kg": 70, "side": "left", "notes": "bad\x00byte"}, "notes", "control characters"),
])
def test_bad_patient_fields_are_named_in_the_422(api, body, field, words):
    r = api.client.post("/api/patients", headers=api.as_("prosthetist"), json=body)
    assert r.status_code == 422
    detail = r.json()["detail"]
    assert field in detail and words in detail, detail
    assert _count(api, "patients") == 0


def test_nan_and_unparsable_json_are_refused(api):
    h = {**api.as_("prosthetist"), "content-type": "application/json"}
    r = api.client.post("/api/patients", headers=h, content='{"code_name": "A", "body_mass_kg": NaN, "side": "left"}')
    assert r.status_code == 422 and "body_mass_kg" in r.json()["detail"] and "finite" in r.json()["detail"]
    r = api.client.post("/api/patients", headers=h, content='{"code_name": "A", "body_mass_')
    assert r.status_code == 422 and "JSON" in r.json()["detail"]
    assert _count(api, "patients") == 0


def test_duplicate_code_name_is_a_409_and_missing_ids_404(api):
    api.new_patient("P-1")
    r = api.client.post("/api/patients", headers=api.as_("prosthetist"),
                        json={"code_name": "P-1", "body_mass_kg": 70, "side": "left"})
    assert r.status_code == 409 and "P-1" in r.json()["detail"]
    assert api.client.get("/api/patients/99", headers=api.as_("viewer")).status_code == 404
    r = api.client.get(f"/api/patients/{2**60}", headers=api.as_("viewer"))
    assert r.status_code == 422 and "patient_id" in r.json()["detail"]
    assert api.client.get("/api/proposals/5", headers=api.as_("viewer")).json()["detail"] == "proposal 5 not found"


# ------------------------------------------------------------- proposals
def test_proposal_carries_features_curves_table_units_and_provenance(api, model):
    patient = api.new_patient(mass=80.0)
    p = api.propose(patient["id"], speed=1.3, incline=2.0)
    assert p["status"] == "draft" and p["version"] == 1 and p["source"] == "model" and p["created_by"] == "prosthetist"
    assert p["task"] == {"speed_mps": 1.3, "incline_deg": 2.0, "body_mass_kg": 80.0}
    direct = model.propose(1.3, 2.0, 80.0)
    for row, ref in zip(p["table"], direct.table.rows, strict=True):
        assert row["k_Nm_per_rad"] == pytest.approx(ref.k_Nm_per_rad, abs=1e-3)
        assert row["k_Nm_per_deg"] == pytest.approx(ref.k_Nm_per_rad * 3.141592653589793 / 180, abs=1e-4)
        assert row["theta_e_deg"] == pytest.approx(ref.theta_e_deg, abs=1e-3)
    assert len(p["curves"]["knee_angle_deg"]) == 101 and len(p["curves"]["knee_angle_deg_std"]) == 101
    assert {f["unit"] for f in p["features"]} >= {"deg", "N·m/kg"}
    assert p["safety"] == {"ok": True, "violations": []}
    assert p["model"]["version"] == model.model_version_ and len(p["model"]["data_sha256"]) == 64
    assert p["limits"]["k_Nm_per_rad"] == {"low": -1200.0, "high": 200.0}
    listed = api.client.get(f"/api/patients/{patient['id']}/proposals", headers=api.as_("viewer")).json()
    assert [x["id"] for x in listed] == [p["id"]] and "curves" not in listed[0]


def test_a_new_proposal_answer_is_exactly_its_schema_and_what_is_stored(api):
    from backend.schemas.proposals import ProposalOut

    patient = api.new_patient()
    r = api.client.post(f"/api/patients/{patient['id']}/proposals", headers=api.as_("prosthetist"),
                        json={"speed_mps": 1.1, "incline_deg": 3.0})
    assert r.status_code == 201 and r.headers["content-type"] == "application/json"
    answer = r.json()
    assert answer == ProposalOut.model_validate(answer).model_dump(mode="json")     # no extra, none missing
    stored = api.client.get(f"/api/proposals/{answer['id']}", headers=api.as_("viewer")).json()
    assert answer == stored


def test_concurrent_proposals_go_through_the_group_commit_with_consecutive_versions(api):
    patient = api.new_patient()
    app = api.client.app

    async def main() -> list[httpx.Response]:
        async with httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://test") as client:
            return await asyncio.gather(*(
                client.post(f"/api/patients/{patient['id']}/proposals", headers=api.as_("prosthetist"),
                            json={"speed_mps": 0.8 + 0.1 * i}) for i in range(6)))

    answers = asyncio.run(main())
    assert [r.status_code for r in answers] == [201] * 6
    assert sorted(r.json()["version"] for r in answers) == [1, 2, 3, 4, 5, 6]
    assert app.state.committer.stats_.writes == 6
    stored = {r.json()["id"]: r.json()["task"]["speed_mps"] for r in answers}
    for pid, speed in stored.items():      # each answer is its own stored row
        assert api.client.get(f"/api/proposals/{pid}", headers=api.as_("viewer")).json()["task"]["speed_mps"] == speed
    actions = [e["action"] for e in api.client.get("/api/audit", headers=api.as_("viewer")).json()["items"]]
    assert actions.count("proposal.create") == 6


def test_task_outside_the_data_is_flagged_with_larger_std(api):
    patient = api.new_patient()
    inside = api.propose(patient["id"], speed=1.2)
    outside = api.propose(patient["id"], speed=2.9)
    assert inside["extrapolation"] is False and outside["extrapolation"] is True
    sd_in = {f["name"]: f["std"] for f in inside["features"]}
    sd_out = {f["name"]: f["std"] for f in outside["features"]}
    assert sd_out["knee_swing_flexion_peak"] > sd_in["knee_swing_flexion_peak"]


@pytest.mark.parametrize(("body", "field"), [
    ({"speed_mps": 0}, "speed_mps"), ({"speed_mps": -1.2}, "speed_mps"), ({"speed_mps": 3.5}, "speed_mps"),
    ({"speed_mps": 1.2, "incline_deg": 25}, "incline_deg"), ({"incline_deg": 2}, "speed_mps"),
    ({"speed_mps": "fast"}, "speed_mps"),
])
def test_bad_task_is_refused_and_nothing_stored(api, body, field):
    patient = api.new_patient()
    r = api.client.post(f"/api/patients/{patient['id']}/proposals", headers=api.as_("prosthetist"), json=body)
    assert r.status_code == 422 and field in r.json()["detail"]
    assert _count(api, "proposals") == 0


def test_edit_makes_a_new_version_and_diff_lists_the_cells(api):
    patient = api.new_patient()
    v1 = api.propose(patient["id"])
    r = api.client.post(f"/api/proposals/{v1['id']}/edits", headers=api.as_("prosthetist"), json={
        "rows": [{"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": -250.0},
                 {"joint": "ankle", "subphase": "swing_extension", "b_Nm_s_per_rad": 2.5}],
        "thresholds": {"we_to_sf_load_N": 150.0}, "comment": "patient felt the knee buckle"})
    assert r.status_code == 201, r.text
    v2 = r.json()
    assert v2["version"] == 2 and v2["parent_id"] == v1["id"] and v2["source"] == "edit" and v2["status"] == "draft"
    knee_sf = next(x for x in v2["table"] if x["joint"] == "knee" and x["subphase"] == "stance_flexion")
    assert knee_sf["k_Nm_per_rad"] == -250.0 and knee_sf["fit_method"] == "manual" and knee_sf["r2"] is None
    ankle_we = next(x for x in v2["table"] if x["joint"] == "ankle" and x["subphase"] == "swing_extension")
    assert ankle_we["b_Nm_s_per_rad"] == 2.5 and ankle_we["fit_method"] != "manual"   # damping only: still a fit
    assert v2["curves"] == v1["curves"] and v2["table_sha256"] != v1["table_sha256"]
    diff = api.client.get(f"/api/proposals/{v1['id']}/diff/{v2['id']}", headers=api.as_("viewer")).json()
    fields = {c["field"]: c for c in diff["changes"]}
    assert set(fields) == {"knee.stance_flexion.k_Nm_per_rad", "knee.stance_flexion.fit_method",
                           "ankle.swing_extension.b_Nm_s_per_rad", "thresholds.we_to_sf_load_N"}
    assert fields["knee.stance_flexion.k_Nm_per_rad"]["after"] == -250.0
    assert fields["knee.stance_flexion.k_Nm_per_rad"]["unit"] == "N·m/rad"
    # the parent is untouched
    again = api.client.get(f"/api/proposals/{v1['id']}", headers=api.as_("viewer")).json()
    assert again["table"] == v1["table"] and again["table_sha256"] == v1["table_sha256"]


@pytest.mark.parametrize(("edit", "words"), [
    ({"rows": [{"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": -5000}]},
     "knee.stance_flexion.k_Nm_per_rad = -5000 N·m/rad is outside [-1200, 200]"),
    ({"rows": [{"joint": "ankle", "subphase": "swing_flexion", "theta_e_deg": 45}]}, "is outside [-30, 30] deg"),
    ({"thresholds": {"min_state_time_s": 2.0}}, "must be below max_state_time_s"),
    ({"rows": [{"joint": "knee", "subphase": "stance_flexion", "b_Nm_s_per_rad": -1}]}, "b_Nm_s_per_rad = -1"),
    ({"rows": []}, "changes nothing"),
    ({"rows": [{"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": -100},
               {"joint": "knee", "subphase": "stance_flexion", "theta_e_deg": 5}]}, "edited twice"),
])
def test_unsafe_or_empty_edit_is_refused_and_nothing_stored(api, edit, words):
    patient = api.new_patient()
    v1 = api.propose(patient["id"])
    before = (_count(api, "proposals"), _count(api, "audit_log"))
    r = api.client.post(f"/api/proposals/{v1['id']}/edits", headers=api.as_("prosthetist"),
                        json={**edit, "comment": "try"})
    assert r.status_code == 422 and words in r.json()["detail"], r.json()
    assert (_count(api, "proposals"), _count(api, "audit_log")) == before


def test_approve_once_then_immutable(api):
    patient = api.new_patient()
    p = api.propose(patient["id"])
    r = api.client.post(f"/api/proposals/{p['id']}/approve", headers=api.as_("prosthetist"),
                        json={"comment": "matches the gait lab"})
    assert r.status_code == 200
    d = r.json()["decision"]
    assert d["status"] == "approved" and d["by"] == "prosthetist" and d["comment"] == "matches the gait lab"
    for action in ("approve", "reject"):
        again = api.client.post(f"/api/proposals/{p['id']}/{action}", headers=api.as_("prosthetist"), json={})
        assert again.status_code == 409 and "already approved" in again.json()["detail"]
    conn = api.db()
    with pytest.raises(sqlite3.IntegrityError, match="immutable"):
        conn.execute("UPDATE proposals SET table_json = '{}' WHERE id = ?", (p["id"],))
    with pytest.raises(sqlite3.IntegrityError, match="already been approved"):
        conn.execute("UPDATE proposals SET status = 'draft' WHERE id = ?", (p["id"],))
    with pytest.raises(sqlite3.IntegrityError, match="never deleted"):
        conn.execute("DELETE FROM proposals")
    with pytest.raises(sqlite3.IntegrityError, match="append-only"):
        conn.execute("DELETE FROM audit_log")
    with pytest.raises(sqlite3.IntegrityError, match="append-only"):
        conn.execute("UPDATE audit_log SET actor_name = 'someone else'")
    conn.close()
    # editing an approved proposal derives a new draft; the approved one stays as it was
    v2 = api.client.post(f"/api/proposals/{p['id']}/edits", headers=api.as_("prosthetist"), json={
        "rows": [{"joint": "knee", "subphase": "swing_flexion", "b_Nm_s_per_rad": 1.0}], "comment": "more damping"})
    assert v2.status_code == 201 and v2.json()["status"] == "draft"
    assert api.client.get(f"/api/proposals/{p['id']}", headers=api.as_("viewer")).json()["status"] == "approved"


def test_reject_records_the_comment(api):
    p = api.propose(api.new_patient()["id"])
    r = api.client.post(f"/api/proposals/{p['id']}/reject", headers=api.as_("prosthetist"),
                        json={"comment": "swing too stiff"})
    assert r.status_code == 200 and r.json()["decision"]["status"] == "rejected"
    entry = api.client.get("/api/audit", headers=api.as_("viewer"), params={"entity": "proposal"}).json()["items"][0]
    assert entry["action"] == "proposal.reject" and entry["after"]["comment"] == "swing too stiff"


def test_approval_rechecks_the_limits_of_the_stored_table(api, model):
    """Layered safety: a draft whose table is outside the limits (stored here behind the API's back, as a
    corrupted or legacy row would be) cannot be approved."""
    patient = api.new_patient()
    proposal = model.propose(1.2, 0.0, 80.0)
    row = proposal.table.rows[0]
    bad_row = row.model_copy(update={"k_Nm_per_rad": -3000.0})
    bad_table = proposal.table.model_copy(update={"rows": [bad_row, *proposal.table.rows[1:]]})
    proposal.table = bad_table
    conn = api.db()
    stored = proposal_store.create_from_model(conn, patient["id"], proposal, User(1, "prosthetist", "prosthetist"))
    conn.close()
    assert stored["safety"]["ok"] is False
    r = api.client.post(f"/api/proposals/{stored['id']}/approve", headers=api.as_("prosthetist"), json={})
    assert r.status_code == 409 and "outside the safety limits" in r.json()["detail"]
    assert r.json()["violations"][0]["field"] == "knee.stance_flexion.k_Nm_per_rad"
    assert api.client.get(f"/api/proposals/{stored['id']}", headers=api.as_("viewer")).json()["status"] == "draft"


def test_tampered_table_is_refused_at_approval(api):
    p = api.propose(api.new_patient()["id"])
    conn = api.db()
    with write_transaction(conn):   # simulate on-disk corruption: drop the trigger, change one byte
        conn.execute("DROP TRIGGER proposals_content_immutable")
        conn.execute("UPDATE proposals SET table_json = replace(table_json, '\"knee\"', '\"knee\" ') WHERE id = ?",
                     (p["id"],))
    conn.close()
    r = api.client.post(f"/api/proposals/{p['id']}/approve", headers=api.as_("prosthetist"), json={})
    assert r.status_code == 409 and "sha256" in r.json()["detail"]


def test_audit_pages_newest_first(api):
    patient = api.new_patient()
    for _ in range(3):
        api.propose(patient["id"])
    h = api.as_("viewer")
    first = api.client.get("/api/audit", headers=h, params={"entity": "proposal", "limit": 2}).json()
    assert len(first["items"]) == 2 and first["items"][0]["id"] > first["items"][1]["id"]
    rest = api.client.get("/api/audit", headers=h, params={"entity": "proposal", "limit": 2,
                                                           "before_id": first["next_before_id"]}).json()
    assert len(rest["items"]) == 1 and rest["next_before_id"] is None
    assert api.client.get("/api/audit", headers=h, params={"limit": 0}).status_code == 422


def test_versions_stay_unique_under_concurrent_edits(api):
    p = api.propose(api.new_patient()["id"])
    errors: list[int] = []

    def edit(i: int) -> None:
        r = api.client.post(f"/api/proposals/{p['id']}/edits", headers=api.as_("prosthetist"), json={
            "rows": [{"joint": "knee", "subphase": "swing_flexion", "b_Nm_s_per_rad": 1.0 + i / 10}],
            "comment": f"edit {i}"})
        if r.status_code != 201:
            errors.append(r.status_code)

    threads = [threading.Thread(target=edit, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    versions = [x["version"] for x in api.client.get(f"/api/patients/{p['patient_id']}/proposals",
                                                     headers=api.as_("viewer")).json()]
    assert sorted(versions) == list(range(1, 10))


def test_model_still_loading_gives_503_with_retry_after(tmp_path, model):
    gate = threading.Event()

    def slow_loader():
        gate.wait(10)
        return model

    api, client = make_api(tmp_path, slow_loader, model_wait_s=0.05)
    with client:
        patient = api.new_patient()
        assert client.get("/api/health").json()["model"] == "loading"
        r = client.post(f"/api/patients/{patient['id']}/proposals", headers=api.as_("prosthetist"),
                        json={"speed_mps": 1.0})
        assert r.status_code == 503 and r.headers["retry-after"] == "5" and "loading" in r.json()["detail"]
        gate.set()
        client.app.state.model._thread.join(5)
        assert client.get("/api/health").json()["model"] == "ready"
        assert api.propose(patient["id"])["status"] == "draft"
