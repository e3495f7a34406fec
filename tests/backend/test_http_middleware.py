"""The middlewares' base: HTTP requests to the subclass's ``http``, every other scope to the wrapped app unchanged."""

from __future__ import annotations

import asyncio

from backend.http_middleware import HttpMiddleware


class _Marks(HttpMiddleware):
    async def http(self, scope, receive, send) -> None:
        scope["marked"] = True
        await self.app(scope, receive, send)


def test_only_http_requests_reach_the_subclass_and_the_rest_pass_through_as_they_came():
    seen = []

    async def app(scope, receive, send) -> None:
        seen.append(dict(scope))

    middleware = _Marks(app)
    for kind in ("http", "websocket", "lifespan"):
        asyncio.run(middleware({"type": kind}, None, None))
    assert seen == [{"type": "http", "marked": True}, {"type": "websocket"}, {"type": "lifespan"}]
    plain = []
    asyncio.run(HttpMiddleware(lambda scope, receive, send: _record(plain, scope))({"type": "http"}, None, None))
    assert plain == [{"type": "http"}]                 # the base alone passes HTTP on too


async def _record(into: list, scope) -> None:
    into.append(scope)
