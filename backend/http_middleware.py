"""The base of QuasiTune's own ASGI middlewares: each acts on HTTP requests only and passes every other scope
(WebSockets, the lifespan) to the app it wraps unchanged. Plain ASGI, as Starlette's documentation advises where
speed matters; no maintained package offers a base this small."""

from __future__ import annotations

from starlette.types import ASGIApp, Receive, Scope, Send


class HttpMiddleware:
    """Wraps ``app``; :meth:`http` handles an HTTP request, anything else goes to ``app`` as it came."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        await self.http(scope, receive, send)

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Handle one HTTP request (a subclass's work); by default pass it on."""
        await self.app(scope, receive, send)
