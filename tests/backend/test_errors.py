"""Domain errors carry the status the API answers with and what goes into the body."""

from __future__ import annotations

from backend.errors import (
    ConflictError,
    DeviceError,
    DomainError,
    InvalidError,
    NotFoundError,
    ServiceUnavailableError,
)


def test_each_error_has_its_status_and_keeps_its_message_and_extra():
    assert [e.status for e in (DomainError, NotFoundError, ConflictError, InvalidError, ServiceUnavailableError,
                               DeviceError)] == [400, 404, 409, 422, 503, 502]
    e = ConflictError("already decided", violations=[1, 2])
    assert str(e) == e.message == "already decided" and e.extra == {"violations": [1, 2]}


def test_the_api_answers_a_domain_error_with_its_status_and_body(api):
    r = api.client.get("/api/patients/999", headers=api.as_("prosthetist"))
    assert r.status_code == 404 and "patient 999 not found" in r.json()["detail"]
