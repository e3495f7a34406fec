"""Stored previews: the first walk of a content wins, and a preview is never shown for other content."""

from __future__ import annotations

import pytest
from sqlalchemy.exc import IntegrityError

from backend.errors import ConflictError
from backend.store import previews
from tests.helpers.sql import sql

A, B = "a" * 64, "b" * 64   # two contents' sha256


def test_the_first_stored_preview_wins_and_is_tied_to_its_table(conn, draft):
    pid = draft()
    assert previews.get_preview(conn, "proposal", pid, A) is None
    first = previews.store_preview(conn, "proposal", pid, A, {"seconds": 10.0, "walk": 1})
    again = previews.store_preview(conn, "proposal", pid, A, {"seconds": 10.0, "walk": 2})
    assert first["walk"] == again["walk"] == 1 and again["seconds"] == 10.0
    with pytest.raises(ConflictError, match="another table"):
        previews.get_preview(conn, "proposal", pid, B)
    with pytest.raises(IntegrityError, match=r"(?i)check"):      # refused, never silently dropped
        previews.store_preview(conn, "proposal", draft(), "not a sha256", {"seconds": 10.0})


def test_an_envelope_preview_is_tied_to_its_envelope(conn, prosthetist, patient):
    eid = sql(conn, "INSERT INTO versions (patient_id, kind, version, source, n_speeds, n_inclines, speed_mps, "
              "incline_deg, body_mass_kg, extrapolation, safety_ok, content_json, content_sha256, created_by, "
              "created_at) VALUES (:patient, 'envelope', 1, 'model', 2, 2, 1.2, 0, 80, false, true, '{}', :sha, :user, "
              "'2026-01-01T00:00:00Z') RETURNING id", patient=patient["id"], sha=A, user=prosthetist.id).scalar_one()
    stored = previews.store_preview(conn, "envelope", eid, A, {"course": {"name": "mixed"}, "n": 1})
    assert stored["n"] == 1 and previews.get_preview(conn, "envelope", eid, A)["course"]["name"] == "mixed"
    with pytest.raises(ConflictError, match="another envelope"):
        previews.get_preview(conn, "envelope", eid, B)
    with pytest.raises(ValueError):
        previews.store_preview(conn, "envelope", 1, A, {"course": {"name": "mixed"}, "x": float("nan")})
