"""Security headers on every response, and the API docs served from this server (npm's swagger-ui-dist).

A header table applied by a small ASGI middleware of our own (``backend.http_middleware``): no package adds these
four headers more simply.
The dashboard loads only its own files; the one frame it embeds is the 3D view on a loopback port.
"""

from __future__ import annotations

import base64
import hashlib
import re

from fastapi import FastAPI
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse, JSONResponse
from starlette.datastructures import MutableHeaders
from starlette.types import Message, Receive, Scope, Send

from backend.http_middleware import HttpMiddleware

CSP = ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
       "connect-src 'self'; frame-src http://127.0.0.1:*; frame-ancestors 'none'; base-uri 'none'; "
       "form-action 'self'; object-src 'none'")
HEADERS = {"X-Frame-Options": "DENY", "X-Content-Type-Options": "nosniff", "Referrer-Policy": "no-referrer"}


class SecurityHeaders(HttpMiddleware):
    """Every HTTP response gets the CSP (unless its route set its own) and the three fixed headers, written into the
    response's start message (FastAPI's ``@app.middleware("http")`` hook ran every request through a task group and
    re-streamed its body)."""

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                headers.setdefault("Content-Security-Policy", CSP)
                for name, value in HEADERS.items():
                    headers.setdefault(name, value)
            await send(message)

        await self.app(scope, receive, send_with_headers)


def add_security_headers(app: FastAPI) -> None:
    """Every response gets the CSP (unless a route set its own) and the three fixed headers (:class:`SecurityHeaders`,
    outermost: a refusal or a 500 from the middleware inside it carries them too)."""
    app.add_middleware(SecurityHeaders)


# writes that need a signed-in user: everything under /api except signing in (and the health check, a GET)
_OPEN_WRITES = ("/api/auth/token",)


class RefuseAnonymousWrites(HttpMiddleware):
    """A write under /api without any credentials is answered 401 before its body is read or validated, so an
    anonymous client learns nothing of the schema (a malformed body would otherwise answer 422 first). It looks at
    the method, path and headers only, at no cost to every other request."""

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["method"] in ("POST", "PUT", "PATCH", "DELETE") and \
                scope["path"].startswith("/api/") and scope["path"] not in _OPEN_WRITES and \
                not any(name == b"authorization" for name, _ in scope["headers"]):
            response = JSONResponse({"detail": "not signed in"}, status_code=401, headers={
                "WWW-Authenticate": "Bearer", "Content-Security-Policy": CSP, **HEADERS})
            await response(scope, receive, send)
            return
        await self.app(scope, receive, send)


def mount_docs(app: FastAPI) -> None:
    """``/docs``: Swagger UI from ``/vendor/swagger-ui`` (no CDN). Its page starts the UI with one inline script,
    allowed by that script's hash and nothing else."""
    page = get_swagger_ui_html(openapi_url=app.openapi_url or "/openapi.json", title=f"{app.title} — API",
                               swagger_js_url="/vendor/swagger-ui/swagger-ui-bundle.js",
                               swagger_css_url="/vendor/swagger-ui/swagger-ui.css",
                               swagger_favicon_url="data:,").body.decode()
    scripts = re.findall(r"<script>(.*?)</script>", page, flags=re.S)
    hashes = " ".join("'sha256-" + base64.b64encode(hashlib.sha256(s.encode()).digest()).decode() + "'"
                      for s in scripts)
    csp = CSP.replace("script-src 'self'", f"script-src 'self' {hashes}")

    @app.get("/docs", include_in_schema=False)
    def docs() -> HTMLResponse:
        return HTMLResponse(page, headers={"Content-Security-Policy": csp})
