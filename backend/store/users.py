"""Users, roles and bearer tokens."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal, get_args

from sqlalchemy import Connection, RowMapping, bindparam, delete, false, func, insert, select, update

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError, InvalidError, NotFoundError
from backend.security import check_password_policy, hash_password, new_token, token_digest
from backend.store import audit
from backend.store.tables import tokens, users

Role = Literal["prosthetist", "viewer", "admin"]
ROLES: tuple[str, ...] = get_args(Role)


@dataclass(frozen=True)
class User:
    id: int
    username: str
    role: str
    must_change_password: bool = False   # a password someone else chose: nothing but changing it works


def _public(row: RowMapping) -> dict:
    return {"id": row["id"], "username": row["username"], "role": row["role"], "created_at": row["created_at"],
            "disabled": bool(row["disabled"]), "must_change_password": bool(row["must_change_password"]),
            "password_changed_at": row["password_changed_at"]}


def _user(row: RowMapping) -> User:
    return User(row["id"], row["username"], row["role"], bool(row["must_change_password"]))


def _named(username: str):
    """The user-name match, ignoring case on every database (SQLite's column collates NOCASE; PostgreSQL's does not)."""
    return func.lower(users.c.username) == func.lower(username)


def _row(conn: Connection, user_id: int) -> dict:
    return _public(conn.execute(select(users).where(users.c.id == user_id)).mappings().one())


def _actor(actor: User | None) -> tuple[int | None, str]:
    return (actor.id, actor.username) if actor else (None, "command line")


def create_user(conn: Connection, username: str, role: str, password: str,
                actor: User | None = None, must_change_password: bool = False) -> dict:
    """Add a user (password hashed with scrypt). ``actor`` None means the command line; ``must_change_password``
    for a password someone other than the user chose (nothing else works until the user changes it)."""
    if role not in ROLES:
        raise ValueError(f"role must be one of {', '.join(ROLES)}, got {role!r}")
    _policy(password, username)
    password_hash = hash_password(password)   # slow on purpose: outside the write lock
    with write_transaction(conn):
        if conn.execute(select(users.c.id).where(_named(username))).first():
            raise ConflictError(f"a user named {username!r} already exists")
        uid = int(conn.execute(insert(users).values(
            username=username, role=role, password_hash=password_hash, created_at=utc_now(),
            must_change_password=int(must_change_password))).inserted_primary_key[0])
        audit.record(conn, *_actor(actor), "user.create", "user", uid,
                     after={"username": username, "role": role, "must_change_password": must_change_password})
        return _row(conn, uid)


def id_of(conn: Connection, username: str) -> int:
    """The id of the user named ``username`` (NotFoundError when there is none)."""
    row = conn.execute(select(users.c.id).where(_named(username))).first()
    if row is None:
        raise NotFoundError(f"no user named {username!r}")
    return int(row.id)


def password_hash_of(conn: Connection, user: User) -> str:
    return conn.execute(select(users.c.password_hash).where(users.c.id == user.id)).scalar_one()


def set_password(conn: Connection, target_id: int, password: str, must_change_password: bool,
                 actor: User | None = None, keep_token: str | None = None) -> dict:
    """Set a user's password and end every session it holds (except ``keep_token``: the one changing it).

    A user changing their own password clears ``must_change_password``; an admin or the command line setting
    someone's password usually sets it (the user must then choose their own)."""
    named = conn.execute(select(users.c.username).where(users.c.id == target_id)).scalar()
    if named is None:
        raise NotFoundError(f"user {target_id} not found")
    _policy(password, named)
    password_hash = hash_password(password)   # slow on purpose: outside the write lock
    with write_transaction(conn):
        changed = conn.execute(update(users).where(users.c.id == target_id).values(
            password_hash=password_hash, must_change_password=int(must_change_password),
            password_changed_at=utc_now()))
        if changed.rowcount == 0:
            raise NotFoundError(f"user {target_id} not found")
        conn.execute(delete(tokens).where(tokens.c.user_id == target_id,
                                          tokens.c.token_sha256 != (token_digest(keep_token) if keep_token else "")))
        audit.record(conn, *_actor(actor), "user.password", "user", target_id,
                     after={"must_change_password": must_change_password})
        return _row(conn, target_id)


def _policy(password: str, username: str) -> None:
    try:
        check_password_policy(password, username)
    except ValueError as exc:
        raise InvalidError(str(exc), field="password") from None


def list_users(conn: Connection) -> list[dict]:
    return [_public(r) for r in conn.execute(select(users).order_by(users.c.id)).mappings()]


def credentials(conn: Connection, username: str) -> tuple[User, str] | None:
    """(user, stored password hash) of an enabled user, or None."""
    row = conn.execute(select(users).where(_named(username), users.c.disabled == false())).mappings().first()
    return None if row is None else (_user(row), row["password_hash"])


def issue_token(conn: Connection, user: User, ttl_s: float) -> str:
    """A new bearer token for ``user`` valid ``ttl_s`` seconds (expired tokens are purged on the way)."""
    token = new_token()
    now = time.time()
    with write_transaction(conn):
        conn.execute(delete(tokens).where(tokens.c.expires_at_unix < now))
        conn.execute(insert(tokens).values(token_sha256=token_digest(token), user_id=user.id, issued_at=utc_now(),
                                           expires_at_unix=now + ttl_s))
        audit.record(conn, user.id, user.username, "auth.login", "user", user.id)
    return token


def printable(text: str, limit: int = 64) -> str:
    """``text`` safe to show and log: control and other non-printing characters escaped (``\\x1b``), at most
    ``limit`` characters of the original."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text[:limit])


def record_failed_login(conn: Connection, username: str, address: str) -> None:
    """Count a failed sign-in for the throttle (:mod:`backend.throttle`) and audit it under the name as typed, made
    printable (a name is attacker-controlled text), in one transaction."""
    from backend.throttle import record_failure

    with write_transaction(conn):
        record_failure(conn, username, address)
        audit.record(conn, None, printable(username), "auth.login_failed", "user", None,
                     after={"address": printable(address)})


# every request runs it: built once (see backend/store/__init__.py)
_BY_TOKEN = (select(users.c.id, users.c.username, users.c.role, users.c.must_change_password)
             .join(tokens, tokens.c.user_id == users.c.id)
             .where(tokens.c.token_sha256 == bindparam("digest"), tokens.c.expires_at_unix > bindparam("now_unix"),
                    users.c.disabled == false()))


def user_for_token(conn: Connection, token: str) -> User | None:
    """The enabled user holding an unexpired ``token``, or None."""
    row = conn.execute(_BY_TOKEN, {"digest": token_digest(token), "now_unix": time.time()}).mappings().first()
    return None if row is None else _user(row)


def revoke_token(conn: Connection, token: str, user: User) -> None:
    """Sign out: the token stops working at once (audited)."""
    with write_transaction(conn):
        conn.execute(delete(tokens).where(tokens.c.token_sha256 == token_digest(token)))
        audit.record(conn, user.id, user.username, "auth.logout", "user", user.id)


def set_disabled(conn: Connection, user_id: int, disabled: bool, actor: User | None) -> dict:
    """Disable (or re-enable) an account; disabling also revokes every token it holds, so open sessions end."""
    with write_transaction(conn):
        row = conn.execute(select(users).where(users.c.id == user_id).with_for_update()).mappings().first()
        if row is None:
            raise NotFoundError(f"user {user_id} not found")
        if disabled and actor is not None and user_id == actor.id:
            raise ConflictError("you cannot disable your own account; another admin must")
        conn.execute(update(users).where(users.c.id == user_id).values(disabled=int(disabled)))
        if disabled:
            conn.execute(delete(tokens).where(tokens.c.user_id == user_id))
        audit.record(conn, *_actor(actor), "user.disable" if disabled else "user.enable", "user", user_id,
                     before={"disabled": bool(row["disabled"])}, after={"disabled": disabled})
        return _row(conn, user_id)
