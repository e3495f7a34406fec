"""Users, roles and bearer tokens."""

from __future__ import annotations

import sqlite3
import time
from dataclasses import dataclass
from typing import Literal, get_args

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError, NotFoundError
from backend.security import hash_password, new_token, token_digest
from backend.store import audit

Role = Literal["prosthetist", "viewer", "admin"]
ROLES: tuple[str, ...] = get_args(Role)


@dataclass(frozen=True)
class User:
    id: int
    username: str
    role: str
    must_change_password: bool = False   # a password someone else chose: nothing but changing it works


def _public(row: sqlite3.Row) -> dict:
    return {"id": row["id"], "username": row["username"], "role": row["role"], "created_at": row["created_at"],
            "disabled": bool(row["disabled"]), "must_change_password": bool(row["must_change_password"]),
            "password_changed_at": row["password_changed_at"]}


def _user(row: sqlite3.Row) -> User:
    return User(row["id"], row["username"], row["role"], bool(row["must_change_password"]))


def _actor(actor: User | None) -> tuple[int | None, str]:
    return (actor.id, actor.username) if actor else (None, "command line")


def create_user(conn: sqlite3.Connection, username: str, role: str, password: str,
                actor: User | None = None, must_change_password: bool = False) -> dict:
    """Add a user (password hashed with scrypt). ``actor`` None means the command line; ``must_change_password``
    for a password someone other than the user chose (nothing else works until the user changes it)."""
    if role not in ROLES:
        raise ValueError(f"role must be one of {', '.join(ROLES)}, got {role!r}")
    password_hash = hash_password(password)   # slow on purpose: outside the write lock
    with write_transaction(conn):
        if conn.execute("SELECT 1 FROM users WHERE username = ?", (username,)).fetchone():
            raise ConflictError(f"a user named {username!r} already exists")
        cur = conn.execute("INSERT INTO users (username, role, password_hash, created_at, must_change_password) "
                           "VALUES (?, ?, ?, ?, ?)", (username, role, password_hash, utc_now(),
                                                      int(must_change_password)))
        uid = int(cur.lastrowid)
        audit.record(conn, *_actor(actor), "user.create", "user", uid,
                     after={"username": username, "role": role, "must_change_password": must_change_password})
        return _public(conn.execute("SELECT * FROM users WHERE id = ?", (uid,)).fetchone())


def id_of(conn: sqlite3.Connection, username: str) -> int:
    """The id of the user named ``username`` (NotFoundError when there is none)."""
    row = conn.execute("SELECT id FROM users WHERE username = ?", (username,)).fetchone()
    if row is None:
        raise NotFoundError(f"no user named {username!r}")
    return int(row["id"])


def password_hash_of(conn: sqlite3.Connection, user: User) -> str:
    return conn.execute("SELECT password_hash FROM users WHERE id = ?", (user.id,)).fetchone()["password_hash"]


def set_password(conn: sqlite3.Connection, target_id: int, password: str, must_change_password: bool,
                 actor: User | None = None, keep_token: str | None = None) -> dict:
    """Set a user's password and end every session it holds (except ``keep_token``: the one changing it).

    A user changing their own password clears ``must_change_password``; an admin or the command line setting
    someone's password usually sets it (the user must then choose their own)."""
    password_hash = hash_password(password)   # slow on purpose: outside the write lock
    with write_transaction(conn):
        if conn.execute("SELECT 1 FROM users WHERE id = ?", (target_id,)).fetchone() is None:
            raise NotFoundError(f"user {target_id} not found")
        conn.execute("UPDATE users SET password_hash = ?, must_change_password = ?, password_changed_at = ? "
                     "WHERE id = ?", (password_hash, int(must_change_password), utc_now(), target_id))
        conn.execute("DELETE FROM tokens WHERE user_id = ? AND token_sha256 != ?",
                     (target_id, token_digest(keep_token) if keep_token else ""))
        audit.record(conn, *_actor(actor), "user.password", "user", target_id,
                     after={"must_change_password": must_change_password})
        return _public(conn.execute("SELECT * FROM users WHERE id = ?", (target_id,)).fetchone())


def list_users(conn: sqlite3.Connection) -> list[dict]:
    return [_public(r) for r in conn.execute("SELECT * FROM users ORDER BY id")]


def credentials(conn: sqlite3.Connection, username: str) -> tuple[User, str] | None:
    """(user, stored password hash) of an enabled user, or None."""
    row = conn.execute("SELECT * FROM users WHERE username = ? AND disabled = 0", (username,)).fetchone()
    return None if row is None else (_user(row), row["password_hash"])


def issue_token(conn: sqlite3.Connection, user: User, ttl_s: float) -> str:
    """A new bearer token for ``user`` valid ``ttl_s`` seconds (expired tokens are purged on the way)."""
    token = new_token()
    now = time.time()
    with write_transaction(conn):
        conn.execute("DELETE FROM tokens WHERE expires_at_unix < ?", (now,))
        conn.execute("INSERT INTO tokens (token_sha256, user_id, issued_at, expires_at_unix) VALUES (?, ?, ?, ?)",
                     (token_digest(token), user.id, utc_now(), now + ttl_s))
        audit.record(conn, user.id, user.username, "auth.login", "user", user.id)
    return token


def printable(text: str, limit: int = 64) -> str:
    """``text`` safe to show and log: control and other non-printing characters escaped (``\\x1b``), at most
    ``limit`` characters of the original."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text[:limit])


def record_failed_login(conn: sqlite3.Connection, username: str, address: str) -> None:
    """Audit a failed sign-in under the name as typed, made printable (a name is attacker-controlled text)."""
    with write_transaction(conn):
        audit.record(conn, None, printable(username), "auth.login_failed", "user", None,
                     after={"address": printable(address)})


def user_for_token(conn: sqlite3.Connection, token: str) -> User | None:
    """The enabled user holding an unexpired ``token``, or None."""
    row = conn.execute(
        "SELECT u.id, u.username, u.role, u.must_change_password FROM tokens t JOIN users u ON u.id = t.user_id "
        "WHERE t.token_sha256 = ? AND t.expires_at_unix > ? AND u.disabled = 0",
        (token_digest(token), time.time())).fetchone()
    return None if row is None else _user(row)


def revoke_token(conn: sqlite3.Connection, token: str, user: User) -> None:
    """Sign out: the token stops working at once (audited)."""
    with write_transaction(conn):
        conn.execute("DELETE FROM tokens WHERE token_sha256 = ?", (token_digest(token),))
        audit.record(conn, user.id, user.username, "auth.logout", "user", user.id)


def set_disabled(conn: sqlite3.Connection, user_id: int, disabled: bool, actor: User | None) -> dict:
    """Disable (or re-enable) an account; disabling also revokes every token it holds, so open sessions end."""
    with write_transaction(conn):
        row = conn.execute("SELECT * FROM users WHERE id = ?", (user_id,)).fetchone()
        if row is None:
            raise NotFoundError(f"user {user_id} not found")
        if disabled and actor is not None and user_id == actor.id:
            raise ConflictError("you cannot disable your own account; another admin must")
        conn.execute("UPDATE users SET disabled = ? WHERE id = ?", (int(disabled), user_id))
        if disabled:
            conn.execute("DELETE FROM tokens WHERE user_id = ?", (user_id,))
        audit.record(conn, *_actor(actor), "user.disable" if disabled else "user.enable", "user", user_id,
                     before={"disabled": bool(row["disabled"])}, after={"disabled": disabled})
        return _public(conn.execute("SELECT * FROM users WHERE id = ?", (user_id,)).fetchone())
