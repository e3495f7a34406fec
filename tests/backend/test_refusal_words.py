"""Refusals speak clinical words: what was wrong, with its unit, never pydantic's or the JSON's own phrasing."""

from __future__ import annotations

import pytest

from backend.refusal_words import field_name, sentence

JARGON = ("Input should", "Value error", '"extrapolate"', "got [", "greater than or equal", "less than or equal",
          "invalid request")


def _refused(api, path: str, body: dict) -> str:
    r = api.client.post(path, headers=api.as_("prosthetist"), json=body)
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert not [j for j in JARGON if j in detail], detail
    return detail


def test_requests_beyond_the_limits_are_refused_in_words_with_their_units(api):
    pid = api.new_patient()["id"]
    envelopes = f"/api/patients/{pid}/envelopes"
    detail = _refused(api, envelopes, {"speed_range_mps": [1.6, 0.6], "incline_range_deg": [-6, 6]})
    assert "speed range must go from a slower to a faster speed within 0.1–3 m/s (asked from 1.6 to 0.6 m/s)" in detail
    detail = _refused(api, envelopes, {"speed_range_mps": [0.8, 1.4], "incline_range_deg": [-6, 6], "grid": [9, 9]})
    assert "at most 64 in all (asked 9 × 9)" in detail
    detail = _refused(api, envelopes, {"speed_range_mps": [0.8, 1.4], "incline_range_deg": [-6, 6], "extrapolate": True})
    assert "a task beyond what the model knows needs a written reason of at least 20 characters" in detail
    detail = _refused(api, f"/api/patients/{pid}/proposals", {"speed_mps": -1.0, "incline_deg": 0.0})
    assert "speed must be at least" in detail and "m/s" in detail
    detail = _refused(api, f"/api/patients/{pid}/proposals", {"speed_mps": "fast", "incline_deg": 0.0})
    assert "speed must be a number" in detail
    assert api.count("envelopes") == 0 and api.count("proposals") == 0          # nothing half-written


def test_an_edit_names_the_row_and_the_setting_in_words(api):
    pid = api.new_patient()["id"]
    prop = api.propose(pid)
    detail = _refused(api, f"/api/proposals/{prop['id']}/edits", {
        "rows": [{"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": 1e9}], "comment": "too much"})
    assert "stiffness k (row 1) must be at most" in detail and "N·m/rad" in detail


@pytest.mark.parametrize(("error", "words"), [
    ({"loc": ("body", "body_mass_kg"), "type": "greater_than_equal", "ctx": {"ge": 20}}, "body mass must be at least 20 kg"),
    ({"loc": ("body", "incline_deg"), "type": "less_than_equal", "ctx": {"le": 20.0}}, "incline must be at most 20°"),
    ({"loc": ("body", "rows", 2, "theta_e_deg"), "type": "finite_number"},
     "equilibrium angle θe (row 3) must be a finite number (not NaN or infinity)"),
    ({"loc": ("body", "grid", 1), "type": "int_parsing"}, "grid (value 2) must be a whole number"),
    ({"loc": ("body", "comment"), "type": "string_too_short", "ctx": {"min_length": 1}},
     "reason must not be empty"),
    ({"loc": ("body", "override_reason"), "type": "string_too_short", "ctx": {"min_length": 20}},
     "sign-off reason must have at least 20 characters"),
    ({"loc": ("body", "side"), "type": "literal_error", "ctx": {"expected": "'left' or 'right'"}},
     "side must be 'left' or 'right'"),
    ({"loc": ("body",), "type": "value_error", "msg": "Value error, the grid must have 2–15 nodes"},
     "the grid must have 2–15 nodes"),
    ({"loc": ("body",), "type": "json_invalid", "msg": "JSON decode error"}, "the request body is not valid JSON"),
])
def test_each_kind_of_error_reads_as_a_sentence(error, words):
    assert sentence({"msg": "pydantic's own words", **error}) == words


def test_a_field_is_named_without_its_unit_suffix():
    assert field_name(("body", "speed_range_mps")) == ("speed range", "m/s")
    assert field_name(("query", "before_version")) == ("before version", "")
    assert field_name(()) == ("the request", "")
