"""Every request body has a stated bound, enforced before it is read: a stated length beyond it, or a chunked body that
grows beyond it, is answered 413 and nothing is stored."""

from __future__ import annotations

from backend.body_limit import MAX_BODY_BYTES


def test_a_body_beyond_the_bound_is_refused_before_it_is_read(api):
    h = {**api.as_("prosthetist"), "content-type": "application/json"}
    big = b'{"code_name": "P-BIG", "body_mass_kg": 70, "side": "left", "notes": "' + b"x" * MAX_BODY_BYTES + b'"}'
    r = api.client.post("/api/patients", headers=h, content=big)
    assert r.status_code == 413 and "larger than this server takes (1024 KiB)" in r.json()["detail"]
    assert r.headers["x-content-type-options"] == "nosniff"                 # inside the security headers

    def chunks():                                                          # no Content-Length: chunked
        yield b'{"code_name": "P-BIG", "body_mass_kg": 70, "side": "left", "notes": "'
        for _ in range(20):
            yield b"x" * (MAX_BODY_BYTES // 10)
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
