"""A fault in a request answers 500 and leaves the connection open. Starlette's outermost error middleware answers 500
and re-raises for the server to log, and uvicorn then drops the keep-alive connection: the client's next request on it
met "connection reset". Here, inside it, the fault is logged with an id and answered once; nothing is re-raised."""

from __future__ import annotations

import logging
import uuid

from starlette.responses import JSONResponse
from starlette.types import Message, Receive, Scope, Send

from backend.http_middleware import HttpMiddleware

log = logging.getLogger(__name__)


class AnswerFaults(HttpMiddleware):
    """See the module. A fault after the response began cannot be answered; it is logged and the connection ends."""

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        started = False

        async def tracked(message: Message) -> None:
            nonlocal started
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, receive, tracked)
        except Exception:
            fault = uuid.uuid4().hex[:12]
            log.exception("fault %s in %s %s", fault, scope.get("method"), scope.get("path"))
            if started:
                raise
            await JSONResponse({"detail": f"the server met a fault handling this request (logged as "
                                          f"{fault})", "fault": fault}, status_code=500)(scope, receive, send)
