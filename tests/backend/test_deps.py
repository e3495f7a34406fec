"""Who may do what: a bearer token, a changed one-time password, a role."""

from __future__ import annotations

from backend.store import users


def test_no_token_or_an_unknown_one_is_401_with_the_way_to_sign_in(api):
    r = api.client.get("/api/patients")
    assert r.status_code == 401 and "POST /api/auth/token" in r.json()["detail"]
    assert r.headers["WWW-Authenticate"] == "Bearer"
    r = api.client.get("/api/patients", headers={"Authorization": "Bearer not-a-token"})
    assert r.status_code == 401 and "unknown or has expired" in r.json()["detail"]


def test_a_role_that_may_not_act_is_403_naming_the_role_needed(api):
    r = api.client.post("/api/patients", headers=api.as_("viewer"),
                        json={"code_name": "P-9", "body_mass_kg": 80.0, "side": "left", "height_m": 1.8, "k_level": 3})
    assert r.status_code == 403 and "needs the role prosthetist; viewer is viewer" in r.json()["detail"]


def test_a_one_time_password_allows_nothing_but_changing_it(api):
    conn = api.db()
    try:
        made = users.create_user(conn, "newbie", "prosthetist", "chosen by the admin", must_change_password=True)
        token = users.issue_token(conn, users.User(made["id"], "newbie", "prosthetist", True), 60.0)
    finally:
        conn.close()
    headers = {"Authorization": f"Bearer {token}"}
    r = api.client.get("/api/patients", headers=headers)
    assert r.status_code == 403 and "must change the one-time password" in r.json()["detail"]
    assert api.client.get("/api/auth/me", headers=headers).status_code == 200
