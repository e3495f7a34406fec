"""Users, roles and bearer tokens in storage."""

from __future__ import annotations

import pytest

from backend.errors import ConflictError, NotFoundError
from backend.security import verify_password
from backend.store import audit, users


def test_a_user_is_created_once_with_a_hashed_password_and_audited(conn, prosthetist):
    assert users.id_of(conn, "pat") == prosthetist.id
    user, stored = users.credentials(conn, "pat")
    assert user == prosthetist and verify_password("a long password", stored)
    with pytest.raises(ConflictError, match="already exists"):
        users.create_user(conn, "pat", "viewer", "another password")
    with pytest.raises(ValueError, match="role must be one of"):
        users.create_user(conn, "x", "surgeon", "another password")
    assert audit.list_entries(conn, entity="user")[-1]["action"] == "user.create"
    with pytest.raises(NotFoundError):
        users.id_of(conn, "nobody")


def test_a_token_works_until_revoked_or_expired(conn, prosthetist):
    token = users.issue_token(conn, prosthetist, ttl_s=60.0)
    assert users.user_for_token(conn, token) == prosthetist
    users.revoke_token(conn, token, prosthetist)
    assert users.user_for_token(conn, token) is None
    expired = users.issue_token(conn, prosthetist, ttl_s=-1.0)
    assert users.user_for_token(conn, expired) is None


def test_a_new_password_ends_every_other_session(conn, prosthetist):
    keep, other = (users.issue_token(conn, prosthetist, 60.0) for _ in range(2))
    out = users.set_password(conn, prosthetist.id, "a new long password", False, prosthetist, keep_token=keep)
    assert out["password_changed_at"] is not None and not out["must_change_password"]
    assert users.user_for_token(conn, keep) == prosthetist and users.user_for_token(conn, other) is None
    assert verify_password("a new long password", users.password_hash_of(conn, prosthetist))


def test_disabling_ends_sessions_and_nobody_disables_themselves(conn, prosthetist):
    admin_row = users.create_user(conn, "root", "admin", "admin password here")
    admin = users.User(admin_row["id"], "root", "admin")
    token = users.issue_token(conn, prosthetist, 60.0)
    assert users.set_disabled(conn, prosthetist.id, True, admin)["disabled"]
    assert users.user_for_token(conn, token) is None and users.credentials(conn, "pat") is None
    with pytest.raises(ConflictError, match="cannot disable your own"):
        users.set_disabled(conn, admin.id, True, admin)
    assert not users.set_disabled(conn, prosthetist.id, False, admin)["disabled"]


def test_a_failed_login_is_audited_under_a_printable_name(conn):
    users.record_failed_login(conn, "eve\x1b[31m", "10.0.0.1")
    [entry] = audit.list_entries(conn, entity="user")
    assert entry["action"] == "auth.login_failed" and entry["actor"] == "eve\\x1b[31m"
    assert users.printable("a" * 100, limit=5) == "aaaaa"
