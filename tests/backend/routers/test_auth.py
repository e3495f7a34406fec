"""Signing in, tokens, and what a token lets through."""

from __future__ import annotations

from backend.db import write_transaction
from tests.helpers.api import PASSWORD


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
