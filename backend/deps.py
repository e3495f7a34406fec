"""FastAPI dependencies: the database connection, the signed-in user, role checks, the model."""

from __future__ import annotations

import sqlite3
from collections.abc import Callable, Iterator
from typing import Annotated

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import OAuth2PasswordBearer

from backend.model_service import ModelService
from backend.settings import Settings
from backend.store.users import User, user_for_token
from controller_core import QuasiStiffnessModel

oauth2 = OAuth2PasswordBearer(tokenUrl="/api/auth/token", auto_error=False)


def get_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_conn(request: Request) -> Iterator[sqlite3.Connection]:
    with request.app.state.pool.connection() as conn:
        yield conn


Conn = Annotated[sqlite3.Connection, Depends(get_conn)]


def _unauthorized(message: str) -> HTTPException:
    return HTTPException(status.HTTP_401_UNAUTHORIZED, message, headers={"WWW-Authenticate": "Bearer"})


def current_user(conn: Conn, token: Annotated[str | None, Depends(oauth2)]) -> User:
    """The user holding the request's bearer token (401 when missing, unknown or expired)."""
    if not token:
        raise _unauthorized("not signed in: send 'Authorization: Bearer <token>' from POST /api/auth/token")
    user = user_for_token(conn, token)
    if user is None:
        raise _unauthorized("the bearer token is unknown or has expired; sign in again")
    return user


CurrentUser = Annotated[User, Depends(current_user)]


def require_role(*roles: str) -> Callable[[User], User]:
    """Dependency refusing (403) users whose role is not in ``roles``."""
    def check(user: CurrentUser) -> User:
        if user.role not in roles:
            raise HTTPException(status.HTTP_403_FORBIDDEN,
                                f"this action needs the role {' or '.join(roles)}; {user.username} is {user.role}")
        return user
    return check


Prosthetist = Annotated[User, Depends(require_role("prosthetist"))]
Admin = Annotated[User, Depends(require_role("admin"))]


def get_model(request: Request) -> QuasiStiffnessModel:
    service: ModelService = request.app.state.model
    return service.get(request.app.state.settings.model_wait_s)


Model = Annotated[QuasiStiffnessModel, Depends(get_model)]
