"""A stated bound on every route's request body, and its role, checked before the body is read.

Three concurrent 150 MB bodies to ``POST /api/patients`` from a viewer were read whole before the 403 (server memory
0.55 → 1.7 GB): FastAPI reads a body before it solves the dependencies that check the role. Here each write route
has its bound (:func:`body_rules`, also in the OpenAPI schema as ``x-max-body-bytes``): a Content-Length beyond it is
answered 413 at once, a body without one is read only up to it. A route that needs a role is refused (401/403) from
the bearer token alone, before a byte of its body is read. The dependencies check the role again (they are the
authority; this is the door). uvicorn and Starlette have no body limit: this ASGI middleware is the few lines they
leave to the application.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from fastapi import FastAPI
from fastapi.routing import APIRoute
from sqlalchemy import Engine
from starlette.concurrency import run_in_threadpool
from starlette.responses import JSONResponse
from starlette.routing import Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from backend.db import pooled
from backend.http_middleware import HttpMiddleware
from backend.store.users import User, user_for_token

# every body of QuasiTune's API is a few kB of JSON: at most 40 cell edits, texts of at most 4000 characters
BODY_BYTES = 64 * 1024
SIGN_IN_BODY_BYTES = 16 * 1024      # a user name and a password or two (each at most 1024 characters)
_SIGN_IN = ("/api/auth/token", "/api/auth/password", "/api/auth/logout")
_WRITES = {"POST", "PUT", "PATCH", "DELETE"}
TOKEN_HOLDER = "token_holder"     # request.state's name for the user the gate found holding the request's token


@dataclass(frozen=True)
class BodyRule:
    """One write route: its bound on the body (bytes) and the roles that may call it (None: any signed-in user, or
    no one signed in for the sign-in itself)."""

    route: APIRoute
    max_bytes: int
    roles: tuple[str, ...] | None


def _roles(dependant) -> tuple[str, ...] | None:
    """The roles a route's dependencies require (``backend.deps.require_role`` marks its check with them)."""
    for dep in dependant.dependencies:
        found = getattr(dep.call, "roles", None) or _roles(dep)
        if found:
            return found
    return None


def _api_routes(app: FastAPI) -> list[APIRoute]:
    out: list[APIRoute] = []
    for route in app.routes:
        inner = getattr(route, "original_router", None)      # a router included whole
        out.extend(r for r in (inner.routes if inner is not None else [route]) if isinstance(r, APIRoute))
    return out


def body_rules(app: FastAPI) -> list[BodyRule]:
    """Each write route's rule, also stated in its OpenAPI operation (``x-max-body-bytes``). Call once the routers are
    included."""
    rules = []
    for route in _api_routes(app):
        if not route.methods & _WRITES:
            continue
        limit = SIGN_IN_BODY_BYTES if route.path in _SIGN_IN else BODY_BYTES
        route.openapi_extra = {**(route.openapi_extra or {}), "x-max-body-bytes": limit}
        rules.append(BodyRule(route, limit, _roles(route.dependant)))
    return rules


def _answer(status: int, detail: str, **headers: str) -> JSONResponse:
    return JSONResponse({"detail": detail}, status_code=status, headers=headers)


def _too_large(limit: int) -> JSONResponse:
    return _answer(413, f"Not accepted: the request body is larger than this operation takes ({limit // 1024} KiB); "
                        "nothing was read or stored.", Connection="close")


def _bearer(scope: Scope) -> str | None:
    value = next((v for k, v in scope["headers"] if k == b"authorization"), b"").decode("latin-1")
    scheme, _, token = value.partition(" ")
    return token.strip() or None if scheme.lower() == "bearer" else None


class GateBodies(HttpMiddleware):
    """Bodies within their route's bound, from a user whose role may call the route (see the module).

    Args:
        app: the inner application.
        rules: the write routes' rules (:func:`body_rules`), given once the app's routers are included.
        db: the app's database engine, when asked (the token's holder is looked up there).
        default_bytes: the bound of a write no rule covers (a path that is not an operation: answered 404/405 later).
    """

    def __init__(self, app: ASGIApp, rules: list[BodyRule], db: Callable[[], Engine],
                 default_bytes: int = BODY_BYTES) -> None:
        super().__init__(app)
        self.rules, self.db, self.default_bytes = rules, db, default_bytes

    def _rule(self, scope: Scope) -> BodyRule | None:
        for rule in self.rules:
            if rule.route.matches(scope)[0] == Match.FULL:
                return rule
        return None

    async def _refusal(self, scope: Scope, rule: BodyRule) -> JSONResponse | None:
        """401/403 for a caller whose token does not hold one of the route's roles; None: let the request in."""
        token = _bearer(scope)
        if token is None:
            return _answer(401, "not signed in: send 'Authorization: Bearer <token>' from POST /api/auth/token",
                           **{"WWW-Authenticate": "Bearer"})

        def holder() -> User | None:
            with pooled(self.db()) as conn:
                return user_for_token(conn, token)

        user = await run_in_threadpool(holder)
        if user is None:
            return _answer(401, "the bearer token is unknown or has expired; sign in again",
                           **{"WWW-Authenticate": "Bearer"})
        if user.must_change_password:
            return _answer(403, f"{user.username} must change the one-time password first (POST /api/auth/password)")
        if user.role not in rule.roles:
            return _answer(403, f"this action needs the role {' or '.join(rule.roles)}; {user.username} is "
                                f"{user.role}")
        scope.setdefault("state", {})[TOKEN_HOLDER] = user     # the route's dependency takes it: one look-up a request
        return None

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["method"] not in _WRITES:
            await self.app(scope, receive, send)
            return
        rule = self._rule(scope)
        limit = rule.max_bytes if rule is not None else self.default_bytes
        length = next((v for k, v in scope["headers"] if k == b"content-length"), None)
        if length is not None and (not length.isdigit() or int(length) > limit):
            await _too_large(limit)(scope, receive, send)
            return
        if rule is not None and rule.roles and (length is None or int(length) > 0):
            if not any(k == b"authorization" for k, _ in scope["headers"]):
                await self.app(scope, receive, send)     # backend.headers.RefuseAnonymousWrites answers, unread
                return
            refusal = await self._refusal(scope, rule)
            if refusal is not None:
                await refusal(scope, receive, send)
                return
        if length is not None:
            await self.app(scope, receive, send)
            return
        # no length given (chunked): read up to the bound here, then hand the app what was read
        chunks, size, more = [], 0, True
        while more:
            message = await receive()
            if message["type"] != "http.request":
                await self.app(scope, _replay([message]), send)
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > limit:
                await _too_large(limit)(scope, receive, send)
                return
            chunks.append(chunk)
            more = message.get("more_body", False)
        await self.app(scope, _replay([{"type": "http.request", "body": b"".join(chunks), "more_body": False}],
                                      receive), send)


def _replay(messages: list[Message], then: Receive | None = None) -> Receive:
    """A receive that gives ``messages`` first, then what ``then`` gives (a disconnect, later)."""
    pending = list(messages)

    async def receive() -> Message:
        if pending:
            return pending.pop(0)
        if then is None:
            return {"type": "http.disconnect"}
        return await then()

    return receive
