"""Signing in, tokens, and what a token lets through."""

from __future__ import annotations

import pytest
from starlette.websockets import WebSocketDisconnect

from backend.db import write_transaction
from tests.helpers.api import PASSWORD, walk_preview
from tests.helpers.sql import sql


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
    actions = [e["action"] for e in api.client.get("/api/audit", headers=api.as_("prosthetist")).json()["items"]]
    assert actions.count("auth.login_failed") == 2


def test_repeated_failed_sign_ins_are_throttled_and_write_a_bounded_audit(api):
    c, admin = api.client, api.as_("admin")       # the admin signed in before the address is throttled
    codes = [c.post("/api/auth/token", data={"username": "viewer", "password": f"guess-{i}"}).status_code
             for i in range(12)]
    assert codes[:5] == [401] * 5 and set(codes[5:]) == {429}
    r = c.post("/api/auth/token", data={"username": "viewer", "password": PASSWORD})    # even the right one waits
    assert r.status_code == 429 and 0 < int(r.headers["retry-after"]) <= 60 and "try again in" in r.json()["detail"]
    assert c.post("/api/auth/token", data={"username": "admin", "password": PASSWORD}).status_code == 200
    for i in range(30):                           # many names from one address: the address is throttled too
        c.post("/api/auth/token", data={"username": f"spray{i}", "password": "whatever-1"})
    assert c.post("/api/auth/token", data={"username": "prosthetist", "password": PASSWORD}).status_code == 429
    failed = [e for e in c.get("/api/audit?limit=500", headers=admin).json()["items"]
              if e["action"] == "auth.login_failed"]
    assert len(failed) == 20                      # 5 for viewer, then the address's 20 in all: bounded
    assert failed[0]["after"]["address"] == "testclient"


def test_a_failed_sign_in_name_is_logged_printable(api):
    c = api.client
    c.post("/api/auth/token", data={"username": "evil\x1b[31m\r\nadmin logged in", "password": "whatever-1"})
    [entry] = [e for e in c.get("/api/audit", headers=api.as_("admin")).json()["items"]
               if e["action"] == "auth.login_failed"]
    assert entry["actor"] == "evil\\x1b[31m\\r\\nadmin logged in"
    assert not any(ch in entry["actor"] for ch in "\x1b\r\n")


def test_a_password_is_kept_exactly_as_typed(api):
    r = api.client.post("/api/users", headers=api.as_("admin"),
                        json={"username": "spacey", "role": "viewer", "password": "  two words  "})
    assert r.status_code == 201, r.text
    ok = api.client.post("/api/auth/token", data={"username": "spacey", "password": "  two words  "})
    assert ok.status_code == 200
    assert api.client.post("/api/auth/token", data={"username": "spacey", "password": "two words"}).status_code == 401


def test_expired_token_is_refused(api):
    viewer = api.as_("viewer")                    # signed in before the tokens expire
    conn = api.db()
    with write_transaction(conn):
        sql(conn, "UPDATE tokens SET expires_at_unix = 0")
    conn.close()
    r = api.client.get("/api/patients", headers=viewer)
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
        walk_preview(api, proposal["id"])   # approval rests on the bench
        r = api.client.post(f"/api/proposals/{proposal['id']}/approve", headers=h, json={"comment": "ok"})
        assert r.status_code == 403 and "prosthetist" in r.json()["detail"]
        # reading is allowed
        assert api.client.get(f"/api/proposals/{proposal['id']}", headers=h).status_code == 200
    for role in ("viewer", "prosthetist"):
        assert api.client.get("/api/users", headers=api.as_(role)).status_code == 403
    assert api.client.get("/api/proposals/1", headers=api.as_("viewer")).json()["status"] == "draft"


def test_sign_out_revokes_the_token(api):
    c = api.client
    token = c.post("/api/auth/token", data={"username": "viewer", "password": PASSWORD}).json()["access_token"]
    h = {"Authorization": f"Bearer {token}"}
    assert c.post("/api/auth/logout", headers=h).status_code == 204
    assert c.get("/api/patients", headers=h).status_code == 401
    assert c.get("/api/patients", headers=api.as_("viewer")).status_code == 200     # other sessions stay


def test_a_disabled_account_loses_its_tokens_and_cannot_sign_in(api):
    c, admin, viewer = api.client, api.as_("admin"), api.as_("viewer")     # the viewer holds a token when disabled
    users = {u["username"]: u for u in c.get("/api/users", headers=admin).json()}
    assert c.patch(f"/api/users/{users['viewer']['id']}", headers=api.as_("prosthetist"),
                   json={"disabled": True}).status_code == 403
    r = c.patch(f"/api/users/{users['viewer']['id']}", headers=admin, json={"disabled": True})
    assert r.status_code == 200 and r.json()["disabled"] is True
    assert c.get("/api/patients", headers=viewer).status_code == 401
    assert c.post("/api/auth/token", data={"username": "viewer", "password": PASSWORD}).status_code == 401
    r = c.patch(f"/api/users/{users['admin']['id']}", headers=admin, json={"disabled": True})
    assert r.status_code == 409 and "another admin" in r.json()["detail"]
    c.patch(f"/api/users/{users['viewer']['id']}", headers=admin, json={"disabled": False})
    assert c.post("/api/auth/token", data={"username": "viewer", "password": PASSWORD}).status_code == 200


def _sign_in(api, name: str, password: str) -> dict[str, str]:
    r = api.client.post("/api/auth/token", data={"username": name, "password": password})
    assert r.status_code == 200, r.text
    return {"Authorization": f"Bearer {r.json()['access_token']}"}


def test_a_one_time_password_must_be_changed_before_anything_else_works(api):
    c = api.client
    assert c.post("/api/users", headers=api.as_("admin"), json={
        "username": "newbie", "role": "viewer", "password": "chosen-by-admin"}).status_code == 201
    h = _sign_in(api, "newbie", "chosen-by-admin")
    assert c.get("/api/auth/me", headers=h).json()["must_change_password"] is True
    refused = c.get("/api/patients", headers=h)
    assert refused.status_code == 403 and "one-time password" in refused.json()["detail"]
    with pytest.raises(WebSocketDisconnect) as closed, \
            c.websocket_connect(f"/api/devices/none/telemetry?token={h['Authorization'].split()[1]}") as ws:
        ws.receive_json()
    assert closed.value.code == 1008 and "one-time" in closed.value.reason   # nor the live telemetry
    # a wrong current password changes nothing and is a failed sign-in; the same password again is refused
    wrong = c.post("/api/auth/password", headers=h, json={"current_password": "guess", "new_password": "x" * 12})
    assert wrong.status_code == 403 and "nothing was changed" in wrong.json()["detail"]
    same = c.post("/api/auth/password", headers=h,
                  json={"current_password": "chosen-by-admin", "new_password": "chosen-by-admin"})
    assert same.status_code == 422 and "differ" in same.json()["detail"]
    for weak, why in (("password1", "most common passwords"), ("newbie-newbie", "user name"), ("newbie12", "user name")):
        r = c.post("/api/auth/password", headers=h, json={"current_password": "chosen-by-admin", "new_password": weak})
        assert r.status_code == 422 and why in r.json()["detail"], (weak, r.text)
    other = _sign_in(api, "newbie", "chosen-by-admin")                    # a second session of the same account
    ok = c.post("/api/auth/password", headers=h,
                json={"current_password": "chosen-by-admin", "new_password": " my own, with spaces "})
    assert ok.status_code == 200 and ok.json()["must_change_password"] is False
    assert c.get("/api/patients", headers=h).status_code == 200           # this session goes on
    assert c.get("/api/patients", headers=other).status_code == 401       # every other one ends
    assert c.post("/api/auth/token", data={"username": "newbie", "password": "chosen-by-admin"}).status_code == 401
    _sign_in(api, "newbie", " my own, with spaces ")
    actions = [e["action"] for e in c.get("/api/audit", headers=api.as_("prosthetist")).json()["items"]]
    assert "user.password" in actions and "auth.login_failed" in actions


def test_an_admin_reset_ends_the_sessions_and_forces_a_change(api):
    c, admin, viewer = api.client, api.as_("admin"), api.as_("viewer")     # the viewer holds a token when reset
    viewer_id = {u["username"]: u["id"] for u in c.get("/api/users", headers=admin).json()}["viewer"]
    assert c.put(f"/api/users/{viewer_id}/password", headers=api.as_("prosthetist"),
                 json={"password": "reset-by-admin"}).status_code == 403
    r = c.put(f"/api/users/{viewer_id}/password", headers=admin, json={"password": "reset-by-admin"})
    assert r.status_code == 200 and r.json()["must_change_password"] and r.json()["password_changed_at"]
    assert c.get("/api/patients", headers=viewer).status_code == 401
    h = _sign_in(api, "viewer", "reset-by-admin")
    assert c.get("/api/patients", headers=h).status_code == 403


def test_the_token_answer_is_never_cached(api):
    r = api.client.post("/api/auth/token", data={"username": "viewer", "password": PASSWORD})
    assert r.status_code == 200 and r.headers["cache-control"] == "no-store"


@pytest.mark.parametrize("path", ["/api/patients", "/api/proposals/1/approve", "/api/envelopes/1/push"])
def test_an_anonymous_malformed_write_is_refused_before_its_body_is_read(api, path):
    r = api.client.post(path, content=b"{not json", headers={"Content-Type": "application/json"})
    assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
    assert r.headers["x-content-type-options"] == "nosniff"          # still inside the security headers
    signed_in = api.client.post(path, content=b"{not json",
                                headers={"Content-Type": "application/json", **api.as_("prosthetist")})
    assert signed_in.status_code == 422                               # a signed-in caller is told what is wrong
