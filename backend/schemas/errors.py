"""Error bodies as documented in the OpenAPI schema (every 4xx/5xx answer has ``detail``, a sentence)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from controller_core.table import LimitViolation


class FieldError(BaseModel):
    field: str
    message: str
    type: str | None = None


class ErrorBody(BaseModel):
    """``detail`` for people; ``errors`` (request validation) or ``violations`` (safety limits) for scripts."""

    model_config = ConfigDict(extra="allow")

    detail: str
    errors: list[FieldError] | None = None
    violations: list[LimitViolation] | None = None


def _r(description: str) -> dict:
    return {"model": ErrorBody, "description": description}


UNAUTHORIZED = {401: _r("not signed in, or the token is unknown or expired")}
FORBIDDEN = {403: _r("the signed-in user's role may not do this")}
NOT_FOUND = {404: _r("no such resource")}
CONFLICT = {409: _r("clashes with the stored state")}
UNAVAILABLE = {503: _r("the model is still loading, or the bench's queue is full (see Retry-After)")}
TOO_MANY = {429: _r("too many failed sign-ins, or this user's bench walks already queued (see Retry-After)")}
INVALID = {422: _r("a field is missing, malformed or out of range; `detail` names it")}
DEVICE_FAILED = {502: _r("the device refused the push (it keeps its previous table), or did not acknowledge it "
                         "(then the push is unconfirmed until the device's next status decides)")}
