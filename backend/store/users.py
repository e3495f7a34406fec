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


def _public(row: sqlite3.Row) -> dict:
    return {"id": row["id"], "username": row["username"], "role": row["role"], "created_at": row["created_at"],
            "disabled": bool(row["disabled"])}


def create_user(conn: sqlite3.Connection, username: str, role: str, password: str,
                actor: User | None = None) -> dict:
    """Add a user (password hashed with scrypt). ``actor`` None means the command line."""
    if role not in ROLES:
        raise ValueError(f"role must be one of {', '.join(ROLES)}, got {role!r}")
    password_hash = hash_password(password)   # slow on purpose: outside the write lock
    with write_transaction(conn):
        if conn.execute("SELECT 1 FROM users WHERE username = ?", (username,)).fetchone():
            raise ConflictError(f"a user named {username!r} already exists")
        cur = conn.execute("INSERT INTO users (username, role, password_hash, created_at) VALUES (?, ?, ?, ?)",
                           (username, role, password_hash, utc_now()))
        uid = int(cur.lastrowid)
        audit.record(conn, actor.id if actor else None, actor.username if actor else "command line",
                     "user.create", "user", uid, after={"username": username, "role": role})
        return _public(conn.execute("SELECT * FROM users WHERE id = ?", (uid,)).fetchone())


def list_users(conn: sqlite3.Connection) -> list[dict]:
    return [_public(r) for r in conn.execute("SELECT * FROM users ORDER BY id")]


def credentials(conn: sqlite3.Connection, username: str) -> tuple[User, str] | None:
    """(user, stored password hash) of an enabled user, or None."""
    row = conn.execute("SELECT * FROM users WHERE username = ? AND disabled = 0", (username,)).fetchone()
    return None if row is None else (User(row["id"], row["username"], row["role"]), row["password_hash"])


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
        "SELECT u.id, u.username, u.role FROM tokens t JOIN users u ON u.id = t.user_id "
        "WHERE t.token_sha256 = ? AND t.expires_at_unix > ? AND u.disabled = 0",
        (token_digest(token), time.time())).fetchone()
    return None if row is None else User(row["id"], row["username"], row["role"])


def revoke_token(conn: sqlite3.Connection, token: str, user: User) -> None:
    """Sign out: the token stops working at once (audited)."""
    with write_transaction(conn):
        conn.execute("DELETE FROM tokens WHERE token_sha256 = ?", (token_digest(token),))
        audit.record(conn, user.id, user.username, "auth.logout", "user", user.id)


def set_disabled(conn: sqlite3.Connection, user_id: int, disabled: bool, actor: User) -> dict:
    """Disable (or re-enable) an account; disabling also revokes every token it holds, so open sessions end."""
    with write_transaction(conn):
        row = conn.execute("SELECT * FROM users WHERE id = ?", (user_id,)).fetchone()
        if row is None:
            raise NotFoundError(f"user {user_id} not found")
        if disabled and user_id == actor.id:
            raise ConflictError("you cannot disable your own account; another admin must")
        conn.execute("UPDATE users SET disabled = ? WHERE id = ?", (int(disabled), user_id))
        if disabled:
            conn.execute("DELETE FROM tokens WHERE user_id = ?", (user_id,))
        audit.record(conn, actor.id, actor.username, "user.disable" if disabled else "user.enable", "user", user_id,
                     before={"disabled": bool(row["disabled"])}, after={"disabled": disabled})
        return _public(conn.execute("SELECT * FROM users WHERE id = ?", (user_id,)).fetchone())
