"""A stated bound on every request body, enforced before the body is read: a Content-Length beyond it is answered 413
at once; a body without one is read only up to the bound. (uvicorn and Starlette have no body limit; this ASGI
middleware is the few lines they leave to the application.) Three concurrent 150 MB bodies to ``POST /api/patients``
were read whole before the 403 (server memory 0.55 → 1.7 GB)."""

from __future__ import annotations

from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

MAX_BODY_BYTES = 1024 * 1024   # every API request of QuasiTune is JSON far below this (an envelope edit: a few kB)


def _too_large(limit: int) -> JSONResponse:
    return JSONResponse({"detail": f"Not accepted: the request body is larger than this server takes "
                                   f"({limit // 1024} KiB); nothing was read or stored."}, status_code=413,
                        headers={"Connection": "close"})


class LimitBodies:
    """Bodies of at most ``limit`` bytes (see the module)."""

    def __init__(self, app: ASGIApp, limit: int = MAX_BODY_BYTES) -> None:
        self.app, self.limit = app, limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] in ("GET", "HEAD", "OPTIONS"):
            await self.app(scope, receive, send)
            return
        length = next((v for k, v in scope["headers"] if k == b"content-length"), None)
        if length is not None:
            if not length.isdigit() or int(length) > self.limit:
                await _too_large(self.limit)(scope, receive, send)
                return
            await self.app(scope, receive, send)
            return
        # no length given (chunked): read up to the limit here, then hand the app what was read
        chunks, size, more = [], 0, True
        while more:
            message = await receive()
            if message["type"] != "http.request":
                await self.app(scope, _replay([message]), send)
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.limit:
                await _too_large(self.limit)(scope, receive, send)
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
