"""The request schemas' shared rules: storable text, integers from JSON, paging, reasons."""

from __future__ import annotations

import pytest
from fastapi import Response
from pydantic import BaseModel, ValidationError

from backend.schemas.common import (
    StrictIn,
    Text,
    is_utf8_encodable,
    json_integer,
    page_headers,
    require_reason_to_extrapolate,
)


class _Body(StrictIn):
    name: Text
    speed_mps: float


def test_text_must_be_storable_and_bodies_are_strict():
    assert _Body(name="  P-1 ", speed_mps=1.2).name == "P-1"
    for bad in ({"name": "a\x00b", "speed_mps": 1.2}, {"name": "\ud800", "speed_mps": 1.2},
                {"name": "x", "speed_mps": "1.2"}, {"name": "x", "speed_mps": float("nan")},
                {"name": "x", "speed_mps": 1.2, "extra": 1}):
        with pytest.raises(ValidationError):
            _Body.model_validate(bad)
    assert not is_utf8_encodable("\udcff") and is_utf8_encodable("Ω")


def test_a_whole_float_counts_as_an_integer_and_booleans_do_not():
    assert json_integer(3.0) == 3 and isinstance(json_integer(3.0), int)
    assert json_integer(3.5) == 3.5 and json_integer(True) is True


def test_paging_headers_point_at_the_next_page_only_when_there_is_one():
    r = Response()
    items = [{"version": 9}, {"version": 8}]
    assert page_headers(r, items, total=9, limit=2) is items
    assert r.headers["X-Total-Count"] == "9" and r.headers["X-Next-Before-Version"] == "8"
    last = Response()
    page_headers(last, [{"version": 2}, {"version": 1}], total=2, limit=2)
    assert "X-Next-Before-Version" not in last.headers


def test_extrapolating_needs_a_reason():
    require_reason_to_extrapolate(False, None)
    require_reason_to_extrapolate(True, "a reason of at least twenty characters")
    with pytest.raises(ValueError, match="beyond what the model knows needs a written reason"):
        require_reason_to_extrapolate(True, None)
    assert issubclass(_Body, BaseModel)
