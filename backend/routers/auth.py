"""Sign-in (OAuth2 password form → bearer token) and the signed-in user."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, status
from fastapi.security import OAuth2PasswordRequestForm

from backend.deps import Conn, CurrentUser, get_settings
from backend.schemas.auth import Me, TokenOut
from backend.schemas.common import is_utf8_encodable
from backend.schemas.errors import UNAUTHORIZED
from backend.security import burn_password_check, verify_password
from backend.settings import Settings
from backend.store import users

router = APIRouter(prefix="/api", tags=["auth"])


@router.post("/auth/token", response_model=TokenOut, responses=UNAUTHORIZED)
def login(form: Annotated[OAuth2PasswordRequestForm, Depends()], conn: Conn,
          settings: Annotated[Settings, Depends(get_settings)]) -> TokenOut:
    """Exchange a user name and password (form fields) for a bearer token that expires."""
    found = users.credentials(conn, form.username) if is_utf8_encodable(form.username) and len(form.username) <= 64 else None
    if found is None:
        burn_password_check(form.password)
        ok = False
    else:
        ok = verify_password(form.password, found[1])
    if not ok:
        if is_utf8_encodable(form.username):
            users.record_failed_login(conn, form.username)
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "incorrect user name or password",
                            headers={"WWW-Authenticate": "Bearer"})
    token = users.issue_token(conn, found[0], settings.token_ttl_s)
    return TokenOut(access_token=token, expires_in=settings.token_ttl_s)


@router.get("/auth/me", response_model=Me, responses=UNAUTHORIZED)
def me(user: CurrentUser) -> Me:
    """Who the token belongs to, and their role."""
    return Me(id=user.id, username=user.username, role=user.role)
