"""FastAPI dependencies: the database connection, the signed-in user, role checks, the model.

They are ``async``: each is microseconds of work (opening a connection, one indexed lookup), which a thread-pool
hop per dependency would only add to.
"""

from __future__ import annotations

from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Annotated

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import OAuth2PasswordBearer
from sqlalchemy import Connection

from backend.body_limit import TOKEN_HOLDER
from backend.db import pooled
from backend.model_service import ModelService
from backend.settings import Settings
from backend.store.users import User, user_for_token
from backend.threads import run_waiting
from controller_core import QuasiStiffnessModel

oauth2 = OAuth2PasswordBearer(tokenUrl="/api/auth/token", auto_error=False)


async def get_settings(request: Request) -> Settings:
    return request.app.state.settings


async def get_conn(request: Request) -> AsyncIterator[Connection]:
    """A connection for this request alone, back in the pool once the answer has been sent."""
    with pooled(request.app.state.db) as conn:
        yield conn


Conn = Annotated[Connection, Depends(get_conn)]


def _unauthorized(message: str) -> HTTPException:
    return HTTPException(status.HTTP_401_UNAUTHORIZED, message, headers={"WWW-Authenticate": "Bearer"})


async def signed_in(request: Request, conn: Conn, token: Annotated[str | None, Depends(oauth2)]) -> User:
    """The user holding the request's bearer token (401 when missing, unknown or expired), also one who must
    still change a password someone else chose (only /api/auth/me, /password and /logout accept that). A write's
    token was looked up moments ago by the body gate (:mod:`backend.body_limit`), which left its holder here."""
    if not token:
        raise _unauthorized("not signed in: send 'Authorization: Bearer <token>' from POST /api/auth/token")
    user = getattr(request.state, TOKEN_HOLDER, None) or user_for_token(conn, token)
    if user is None:
        raise _unauthorized("the bearer token is unknown or has expired; sign in again")
    return user


SignedIn = Annotated[User, Depends(signed_in)]


async def current_user(user: SignedIn) -> User:
    """The signed-in user, refused (403) until they have changed a password someone else chose for them."""
    if user.must_change_password:
        raise HTTPException(status.HTTP_403_FORBIDDEN, f"{user.username} must change the one-time password first "
                            "(POST /api/auth/password)")
    return user


CurrentUser = Annotated[User, Depends(current_user)]


def require_role(*roles: str) -> Callable[[User], Awaitable[User]]:
    """Dependency refusing (403) users whose role is not in ``roles``."""
    async def check(user: CurrentUser) -> User:
        if user.role not in roles:
            raise HTTPException(status.HTTP_403_FORBIDDEN,
                                f"this action needs the role {' or '.join(roles)}; {user.username} is {user.role}")
        return user
    check.roles = roles      # read by backend.body_limit: the role is checked before a body is read
    return check


Prosthetist = Annotated[User, Depends(require_role("prosthetist"))]
Admin = Annotated[User, Depends(require_role("admin"))]
# the audit log names patients, people and every clinical decision: the prosthetists' and the admins' to read
Auditor = Annotated[User, Depends(require_role("prosthetist", "admin"))]


async def get_model(request: Request) -> QuasiStiffnessModel:
    service: ModelService = request.app.state.model
    if service.status == "loading":   # wait off the event loop
        return await run_waiting(service.get, request.app.state.settings.model_wait_s)
    return service.get(0.0)


Model = Annotated[QuasiStiffnessModel, Depends(get_model)]

