"""Security headers on every response; anonymous writes refused before their body is read."""

from __future__ import annotations

from backend.headers import CSP, HEADERS


def test_every_response_carries_the_security_headers(api):
    viewer = api.as_("viewer")
    answers = {path: api.client.get(path) for path in ("/api/health", "/", "/openapi.json", "/api/no-such-thing",
                                                        "/api/patients")}
    answers["422"] = api.client.get("/api/reference", params={"speed_mps": "fast"}, headers=viewer)
    assert [r.status_code for r in answers.values()] == [200, 200, 200, 404, 401, 422]
    for what, r in answers.items():
        assert r.headers["Content-Security-Policy"] == CSP, what
        for name, value in HEADERS.items():
            assert r.headers[name] == value, (what, name)
        assert len(r.headers.get_list("X-Frame-Options")) == 1, what      # set once, never doubled


def test_an_anonymous_write_is_refused_without_reading_its_body(api):
    r = api.client.post("/api/patients", content=b"{not json", headers={"Content-Type": "application/json"})
    assert r.status_code == 401 and r.headers["WWW-Authenticate"] == "Bearer" and r.json() == {"detail": "not signed in"}
    signing_in = api.client.post("/api/auth/token", data={"username": "nobody", "password": "a wrong password"})
    assert signing_in.json()["detail"] != "not signed in"            # signing in is the one open write


def test_the_docs_page_allows_only_its_own_inline_script(api):
    r = api.client.get("/docs")
    assert r.status_code == 200 and "script-src 'self' 'sha256-" in r.headers["Content-Security-Policy"]
    assert "/vendor/swagger-ui/swagger-ui-bundle.js" in r.text
