"""Shared field types: strict models, text that SQLite can store, database ids."""

from __future__ import annotations

import re
from typing import Annotated

from fastapi import Path, Query, Response
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, StringConstraints

from backend.security import MAX_PASSWORD_LENGTH, MIN_PASSWORD_LENGTH

MAX_ID = 2**53  # ids beyond what JSON numbers carry exactly are refused before they reach SQLite

_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


def is_utf8_encodable(text: str) -> bool:
    """False for strings SQLite cannot store: unpaired surrogates (which JSON and form decoding let through)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _storable_text(value: str) -> str:
    if not is_utf8_encodable(value):
        raise ValueError("text must be valid Unicode (no unpaired surrogates)")
    if _CONTROL.search(value):
        raise ValueError("text must not contain control characters")
    return value


# the pattern is documented in the schema (so clients and fuzzers know); the validator gives the readable message
Text = Annotated[str, AfterValidator(_storable_text),
                 Field(json_schema_extra={"pattern": "^[^\\x00-\\x08\\x0b\\x0c\\x0e-\\x1f\\x7f]*$"})]


# a value typed into a table or envelope edit: finite and far beyond every limit and wire field (the limits then
# refuse it with their own words), so that no number overflows fixed-point rounding (1e306 / 0.001 is inf)
EDIT_BOUND = 10_000.0
EditValue = Annotated[float | None, Field(default=None, ge=-EDIT_BOUND, le=EDIT_BOUND)]


# a password is taken exactly as typed: never stripped (the strict models strip other text)
# (its length is the password policy's, backend.security: the rest of the policy needs the username, so the store
# checks it: backend.store.users)
Password = Annotated[str, StringConstraints(strip_whitespace=False, min_length=MIN_PASSWORD_LENGTH,
                                            max_length=MAX_PASSWORD_LENGTH),
                     AfterValidator(_storable_text),
                     Field(description=f"{MIN_PASSWORD_LENGTH}-{MAX_PASSWORD_LENGTH} characters, kept exactly as typed "
                                       "(spaces included)")]


def json_integer(value: object) -> object:
    """Use as a ``field_validator(mode="before")``: JSON Schema counts 1.0 as an integer, strict validation
    would not. Booleans stay refused. (A validator on the type itself would hide ge/le from the schema.)"""
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value
IdPath = Annotated[int, Path(ge=1, le=MAX_ID, description="database id")]


class StrictIn(BaseModel):
    """Base of request bodies: unknown fields, NaN, ±inf and type coercion ("1.5" or true for a number) are
    refused; strings are stripped."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, str_strip_whitespace=True, strict=True)


class Message(BaseModel):
    """Error body: ``detail`` is a sentence for a person; other keys (``errors``, ``violations``) for scripts."""

    detail: str


# one page of a list of versions: newest first, at most ``limit``, older than ``before_version``; the response's
# X-Total-Count header says how many there are in all, X-Next-Before-Version the cursor of the next page (if any)
PageLimit = Annotated[int, Query(ge=1, le=200, description="at most this many (default 50)")]
BeforeVersion = Annotated[int | None, Query(ge=1, le=MAX_ID, description="only versions older than this one (the "
                                                                       "previous page's X-Next-Before-Version)")]


def page_headers(response: Response, items: list[dict], total: int, limit: int) -> list[dict]:
    """Set the paging headers of a list response; returns ``items``."""
    response.headers["X-Total-Count"] = str(total)
    if len(items) == limit and items[-1]["version"] > 1:
        response.headers["X-Next-Before-Version"] = str(items[-1]["version"])
    return items


# a prosthetist going ahead without a clean bench preview (or past a body-mass mismatch): why, in words that a reader of
# the audit, the version and the device page can weigh
OverrideReason = Annotated[Text | None, Field(
    default=None, min_length=20, max_length=2000,
    description="go ahead although the bench preview of this version is not walked or shows an unsafe figure: why "
                "(at least 20 characters; audited, and shown wherever the version is shown)")]


# a request beyond the tasks the model knows (controller_core.known_range): why the prosthetist extrapolates anyway
ExtrapolationReason = Annotated[Text | None, Field(
    default=None, min_length=20, max_length=2000,
    description="with extrapolate: why a task beyond what the model knows is requested (at least 20 characters; "
                "audited, and shown with the version everywhere)")]


def require_reason_to_extrapolate(extrapolate: bool, reason: str | None) -> None:
    """``extrapolate`` needs its written reason (raised as a validation error naming both fields)."""
    if extrapolate and reason is None:
        raise ValueError("a task beyond what the model knows needs a written reason of at least 20 characters: why "
                         "it is requested")
