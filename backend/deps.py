"""FastAPI dependencies: the database connection, the signed-in user, role checks, the model.

They are ``async`` on purpose: each is microseconds of work (a pool checkout, one indexed SQLite lookup), and a
sync dependency costs a thread-pool hop apiece — seven per request before this, most of a proposal's overhead
under load. Most endpoints are sync and run in the thread pool; the proposal request runs on the loop
(``backend/routers/proposals.py`` says why).
"""

from __future__ import annotations

import sqlite3
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Annotated

import anyio.to_thread
from fastapi import Depends, HTTPException, Request, status
from fastapi.security import OAuth2PasswordBearer

from backend.group_commit import GroupCommitter
from backend.model_service import ModelService
from backend.settings import Settings
from backend.store.users import User, user_for_token
from controller_core import QuasiStiffnessModel

oauth2 = OAuth2PasswordBearer(tokenUrl="/api/auth/token", auto_error=False)


async def get_settings(request: Request) -> Settings:
    return request.app.state.settings


async def get_conn(request: Request) -> AsyncIterator[sqlite3.Connection]:
    with request.app.state.pool.connection() as conn:
        yield conn


Conn = Annotated[sqlite3.Connection, Depends(get_conn)]


async def get_committer(request: Request) -> GroupCommitter:
    return request.app.state.committer


Committer = Annotated[GroupCommitter, Depends(get_committer)]


def _unauthorized(message: str) -> HTTPException:
    return HTTPException(status.HTTP_401_UNAUTHORIZED, message, headers={"WWW-Authenticate": "Bearer"})


async def current_user(conn: Conn, token: Annotated[str | None, Depends(oauth2)]) -> User:
    """The user holding the request's bearer token (401 when missing, unknown or expired)."""
    if not token:
        raise _unauthorized("not signed in: send 'Authorization: Bearer <token>' from POST /api/auth/token")
    user = user_for_token(conn, token)
    if user is None:
        raise _unauthorized("the bearer token is unknown or has expired; sign in again")
    return user


CurrentUser = Annotated[User, Depends(current_user)]


def require_role(*roles: str) -> Callable[[User], Awaitable[User]]:
    """Dependency refusing (403) users whose role is not in ``roles``."""
    async def check(user: CurrentUser) -> User:
        if user.role not in roles:
            raise HTTPException(status.HTTP_403_FORBIDDEN,
                                f"this action needs the role {' or '.join(roles)}; {user.username} is {user.role}")
        return user
    return check


Prosthetist = Annotated[User, Depends(require_role("prosthetist"))]
Admin = Annotated[User, Depends(require_role("admin"))]
# clinicians monitoring remotely (viewer) may record walking sessions: recording changes nothing on the leg
Monitor = Annotated[User, Depends(require_role("prosthetist", "viewer"))]


async def get_model(request: Request) -> QuasiStiffnessModel:
    service: ModelService = request.app.state.model
    if service.status == "loading":   # wait off the event loop
        return await anyio.to_thread.run_sync(service.get, request.app.state.settings.model_wait_s)
    return service.get(0.0)


Model = Annotated[QuasiStiffnessModel, Depends(get_model)]

