"""User accounts (admin)."""

from __future__ import annotations

from tests.conftest import TEST_HASH_COST
from tests.helpers.sql import sql


def test_admin_adds_users_and_passwords_are_scrypt_hashes(api):
    r = api.client.post("/api/users", headers=api.as_("admin"),
                        json={"username": "dana", "role": "prosthetist", "password": "a-long-password"})
    assert r.status_code == 201 and r.json()["role"] == "prosthetist" and "a-long-password" not in r.text
    assert r.json()["must_change_password"]          # an admin chose it: the user must choose their own
    assert api.client.post("/api/users", headers=api.as_("admin"), json={
        "username": "dana", "role": "viewer", "password": "a-long-password"}).status_code == 409
    short = api.client.post("/api/users", headers=api.as_("admin"),
                            json={"username": "eve", "role": "viewer", "password": "short"})
    assert short.status_code == 422 and "password" in short.json()["detail"]
    conn = api.db()
    stored = sql(conn, "SELECT password_hash FROM users WHERE username = 'dana'").scalar_one()
    conn.close()
    assert stored.startswith(f"scrypt${TEST_HASH_COST}$8$1$") and "a-long-password" not in stored   # the run's cost
    assert api.client.post("/api/auth/token", data={"username": "dana", "password": "a-long-password"}).status_code == 200
