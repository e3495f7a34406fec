"""Security headers on every response; anonymous writes refused before their body is read."""

from __future__ import annotations

from backend.headers import CSP, HEADERS


def test_every_response_carries_the_security_headers(api):
    for path in ("/api/health", "/", "/openapi.json"):
        r = api.client.get(path)
        assert r.headers["Content-Security-Policy"] == CSP, path
        for name, value in HEADERS.items():
            assert r.headers[name] == value


def test_an_anonymous_write_is_refused_without_reading_its_body(api):
    r = api.client.post("/api/patients", content=b"{not json", headers={"Content-Type": "application/json"})
    assert r.status_code == 401 and r.headers["WWW-Authenticate"] == "Bearer" and r.json() == {"detail": "not signed in"}
    signing_in = api.client.post("/api/auth/token", data={"username": "nobody", "password": "a wrong password"})
    assert signing_in.json()["detail"] != "not signed in"            # signing in is the one open write


def test_the_docs_page_allows_only_its_own_inline_script(api):
    r = api.client.get("/docs")
    assert r.status_code == 200 and "script-src 'self' 'sha256-" in r.headers["Content-Security-Policy"]
    assert "/vendor/swagger-ui/swagger-ui-bundle.js" in r.text
