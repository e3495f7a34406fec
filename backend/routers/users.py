"""User accounts (admin only)."""

from __future__ import annotations

from fastapi import APIRouter, status

from backend.deps import Admin, Conn
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, UNAUTHORIZED
from backend.schemas.users import PasswordReset, UserCreate, UserOut, UserPatch
from backend.store import users

router = APIRouter(prefix="/api", tags=["users"])


@router.get("/users", response_model=list[UserOut], responses={**UNAUTHORIZED, **FORBIDDEN})
def list_users(conn: Conn, _admin: Admin) -> list[dict]:
    """All users (admin only)."""
    return users.list_users(conn)


@router.post("/users", response_model=UserOut, status_code=status.HTTP_201_CREATED,
             responses={**UNAUTHORIZED, **FORBIDDEN, **CONFLICT})
def create_user(body: UserCreate, conn: Conn, admin: Admin) -> dict:
    """Add a user with a role (admin only). The password is one-time: the user must change it at first sign-in."""
    return users.create_user(conn, body.username, body.role, body.password, actor=admin, must_change_password=True)


@router.patch("/users/{user_id}", response_model=UserOut,
              responses={**UNAUTHORIZED, **FORBIDDEN, **NOT_FOUND, **CONFLICT})
def patch_user(user_id: IdPath, body: UserPatch, conn: Conn, admin: Admin) -> dict:
    """Disable or re-enable an account (admin only). Disabling revokes its tokens at once: requests fail and an
    open telemetry stream closes within a second."""
    return users.set_disabled(conn, user_id, body.disabled, admin)


@router.put("/users/{user_id}/password", response_model=UserOut, responses={**UNAUTHORIZED, **FORBIDDEN, **NOT_FOUND})
def reset_password(user_id: IdPath, body: PasswordReset, conn: Conn, admin: Admin) -> dict:
    """Give a user a new one-time password (admin only; e.g. a forgotten one): their sessions end at once and they
    must choose their own password at the next sign-in."""
    return users.set_password(conn, user_id, body.password, True, actor=admin)
