"""Sign-in (OAuth2 password form → bearer token) and the signed-in user."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Request, Response, status
from fastapi.security import OAuth2PasswordRequestForm
from sqlalchemy import Connection

from backend.deps import Conn, SignedIn, get_settings, oauth2
from backend.errors import InvalidError
from backend.schemas.auth import Me, PasswordChange, TokenOut
from backend.schemas.common import is_utf8_encodable
from backend.schemas.errors import FORBIDDEN, INVALID, TOO_MANY, UNAUTHORIZED
from backend.security import burn_password_check, verify_password
from backend.settings import Settings
from backend.store import users
from backend.throttle import LoginThrottle

router = APIRouter(prefix="/api", tags=["auth"])


def _throttled(request: Request, conn: Connection, name: str) -> str:
    """The caller's address; 429 with Retry-After while ``name`` or the address has had too many failed attempts,
    counted in the database by every instance (then nothing is checked or written)."""
    throttle: LoginThrottle = request.app.state.login_throttle
    address = request.client.host if request.client else "unknown"
    wait = throttle.retry_after_s(conn, name, address)
    if wait:
        raise HTTPException(status.HTTP_429_TOO_MANY_REQUESTS, f"too many failed sign-ins; try again in {wait} s",
                            headers={"Retry-After": str(wait)})
    return address


@router.post("/auth/token", response_model=TokenOut, responses={**UNAUTHORIZED, **TOO_MANY})
def login(form: Annotated[OAuth2PasswordRequestForm, Depends()], request: Request, response: Response, conn: Conn,
          settings: Annotated[Settings, Depends(get_settings)]) -> TokenOut:
    """Exchange a user name and password (form fields) for a bearer token that expires. After too many failed
    sign-ins for one name from one address, from one address for any names, or for one name from everywhere, within
    a minute: 429 with Retry-After, and nothing is checked or written until then (so failed sign-ins write a bounded
    number of audit rows). The address is the TCP peer's, or the one a trusted proxy (settings) forwards."""
    name = form.username[:64] if is_utf8_encodable(form.username) else "<not UTF-8>"
    address = _throttled(request, conn, name)
    found = users.credentials(conn, form.username) if is_utf8_encodable(form.username) and len(form.username) <= 64 else None
    if found is None:
        burn_password_check(form.password)
        ok = False
    else:
        ok = verify_password(form.password, found[1])
    if not ok:
        users.record_failed_login(conn, name, address)
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "incorrect user name or password",
                            headers={"WWW-Authenticate": "Bearer"})
    token = users.issue_token(conn, found[0], settings.token_ttl_s)
    response.headers["Cache-Control"] = "no-store"   # a bearer token is never kept by a cache (RFC 6749 §5.1)
    response.headers["Pragma"] = "no-cache"
    return TokenOut(access_token=token, expires_in=settings.token_ttl_s)


@router.post("/auth/logout", status_code=status.HTTP_204_NO_CONTENT, responses=UNAUTHORIZED)
def logout(user: SignedIn, conn: Conn, token: Annotated[str | None, Depends(oauth2)]) -> None:
    """Sign out: this token stops working at once."""
    users.revoke_token(conn, token or "", user)


@router.get("/auth/me", response_model=Me, responses=UNAUTHORIZED)
def me(user: SignedIn) -> Me:
    """Who the token belongs to, their role, and whether they must change a one-time password first."""
    return Me(id=user.id, username=user.username, role=user.role, must_change_password=user.must_change_password)


@router.post("/auth/password", response_model=Me, responses={**UNAUTHORIZED, **FORBIDDEN, **INVALID, **TOO_MANY})
def change_password(body: PasswordChange, request: Request, user: SignedIn, conn: Conn,
                    token: Annotated[str | None, Depends(oauth2)]) -> Me:
    """Change your own password (the current one is asked again). Every other session of the account ends; this
    one goes on. A wrong current password counts as a failed sign-in (throttled the same way)."""
    address = _throttled(request, conn, user.username)
    if not verify_password(body.current_password, users.password_hash_of(conn, user)):
        users.record_failed_login(conn, user.username, address)
        raise HTTPException(status.HTTP_403_FORBIDDEN, "the current password is not correct; nothing was changed")
    if body.new_password == body.current_password:
        raise InvalidError("new_password: must differ from the current password")
    users.set_password(conn, user.id, body.new_password, False, actor=user, keep_token=token)
    return Me(id=user.id, username=user.username, role=user.role, must_change_password=False)
