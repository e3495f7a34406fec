"""Every write route has a stated bound on its body, enforced before the body is read: a stated length beyond it, or a
chunked body that grows beyond it, is answered 413 and nothing is stored; a caller whose role may not do the operation
is refused before a byte of the body is read."""

from __future__ import annotations

import asyncio

from backend.body_limit import BODY_BYTES, SIGN_IN_BODY_BYTES

PATIENT = b'{"code_name": "P-BIG", "body_mass_kg": 70, "side": "left", "notes": "'


def test_a_body_beyond_its_routes_bound_is_refused_before_it_is_read(api):
    h = {**api.as_("prosthetist"), "content-type": "application/json"}
    r = api.client.post("/api/patients", headers=h, content=PATIENT + b"x" * BODY_BYTES + b'"}')
    assert r.status_code == 413 and "larger than this operation takes (64 KiB)" in r.json()["detail"]
    assert r.headers["x-content-type-options"] == "nosniff"                 # inside the security headers

    def chunks():                                                          # no Content-Length: chunked
        yield PATIENT
        for _ in range(20):
            yield b"x" * (BODY_BYTES // 10)
        yield b'"}'

    r = api.client.post("/api/patients", headers=h, content=chunks())
    assert r.status_code == 413
    assert r.headers.get("content-length") is not None and api.count("patients") == 0

    def small():
        yield b'{"code_name": "P-SMALL", "body_mass_kg": 70, "side": "left"}'

    assert api.client.post("/api/patients", headers=h, content=small()).status_code == 201   # chunked, within it
    assert api.client.post("/api/patients", headers={**h, "content-length": "nope"}, content=b"{}").status_code in (
        400, 413)
    assert api.count("patients") == 1
    r = api.client.post("/api/auth/token", data={"username": "x" * SIGN_IN_BODY_BYTES, "password": "y"})
    assert r.status_code == 413 and "(16 KiB)" in r.json()["detail"]      # the sign-in's own, smaller bound


def test_each_write_states_its_bound_in_the_api_schema(api):
    paths = api.client.get("/openapi.json").json()["paths"]
    assert paths["/api/patients"]["post"]["x-max-body-bytes"] == BODY_BYTES
    assert paths["/api/auth/token"]["post"]["x-max-body-bytes"] == SIGN_IN_BODY_BYTES
    writes = [op for ops in paths.values() for method, op in ops.items() if method in ("post", "put", "patch",
                                                                                         "delete")]
    assert writes and all("x-max-body-bytes" in op for op in writes)


def _call_unread(app, path: str, headers: dict[str, str]) -> tuple[int, int]:
    """POST ``path`` straight to the ASGI app with a body that never ends (chunked, no length); the status and how
    many times the body was read."""
    read, sent = [], []

    async def receive():
        read.append(1)
        return {"type": "http.request", "body": b"{}", "more_body": True}

    async def send(message):
        sent.append(message)

    scope = {"type": "http", "method": "POST", "path": path, "raw_path": path.encode(), "root_path": "",
             "query_string": b"", "http_version": "1.1", "scheme": "http", "server": ("testserver", 80),
             "client": ("127.0.0.1", 1), "headers": [(k.lower().encode(), v.encode()) for k, v in headers.items()]}
    asyncio.run(app(scope, receive, send))
    return next(m["status"] for m in sent if m["type"] == "http.response.start"), len(read)


def test_a_role_that_may_not_write_is_refused_before_its_body_is_read(api):
    """The viewer's and the admin's 403 on a prosthetist's operation, a prosthetist's on an admin's, an unknown
    token's 401: from the token alone, the body never read; the prosthetist's own request reads it (here, to the
    bound)."""
    app, json_ = api.client.app, {"content-type": "application/json"}
    for who, path in (("viewer", "/api/patients"), ("admin", "/api/patients"), ("prosthetist", "/api/users")):
        assert _call_unread(app, path, {**api.as_(who), **json_}) == (403, 0), (who, path)
    assert _call_unread(app, "/api/patients", {"Authorization": "Bearer not-a-token", **json_}) == (401, 0)
    status, read = _call_unread(app, "/api/patients", {**api.as_("prosthetist"), **json_})
    assert status == 413 and read > 0
    assert api.count("patients") == 0


def test_a_writes_token_is_looked_up_once(api, monkeypatch):
    """The gate finds the token's holder before the body is read and leaves it for the route's dependency: one
    look-up a write, not two (a read, which the gate does not see, still looks it up in its dependency)."""
    import backend.body_limit
    import backend.deps

    calls: list[str] = []
    for module in (backend.body_limit, backend.deps):
        real = module.user_for_token
        monkeypatch.setattr(module, "user_for_token", lambda conn, token, real=real: calls.append(token) or
                            real(conn, token))
    h = api.as_("prosthetist")
    r = api.client.post("/api/patients", headers=h, json={"code_name": "P-ONCE", "body_mass_kg": 70, "side": "left"})
    assert r.status_code == 201 and len(calls) == 1
    assert api.client.get(f"/api/patients/{r.json()['id']}", headers=h).status_code == 200 and len(calls) == 2
