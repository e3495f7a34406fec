"""For the storage and service tests: a migrated database of its own per test, on SQLite and on PostgreSQL, and the
people who act on it."""

from __future__ import annotations

import pytest
from sqlalchemy import func, insert, select

from backend.db import connect
from backend.store import patients, users
from backend.store.tables import versions


@pytest.fixture
def conn(database):
    c = connect(database)
    yield c
    c.close()


@pytest.fixture
def prosthetist(conn) -> users.User:
    made = users.create_user(conn, "pat", "prosthetist", "a long password")
    return users.User(made["id"], "pat", "prosthetist")


@pytest.fixture
def colleague(conn) -> users.User:
    """A second prosthetist: the bench gate's override takes two."""
    made = users.create_user(conn, "kim", "prosthetist", "another long password")
    return users.User(made["id"], "kim", "prosthetist")


@pytest.fixture
def patient(conn, prosthetist) -> dict:
    return patients.create_patient(conn, {"code_name": "P-1", "body_mass_kg": 80.0, "height_m": 1.8, "side": "left",
                                          "k_level": 3, "notes": ""}, prosthetist)


@pytest.fixture
def draft(conn, prosthetist, patient):
    """A function making a draft table version with a given content text (its sha256 as stored), returning its id."""
    from controller_core.content import content_sha256

    def make(table_json: str = '{"rows": []}', version: int | None = None, parent_id: int | None = None) -> int:
        v = version or conn.execute(select(func.coalesce(func.max(versions.c.version), 0) + 1)
                                    .where(versions.c.kind == "table")).scalar_one()
        return int(conn.execute(insert(versions).values(
            patient_id=patient["id"], kind="table", parent_id=parent_id, version=v,
            source="model" if parent_id is None else "edit", n_speeds=1, n_inclines=1,
            speed_mps=1.2, incline_deg=0, body_mass_kg=80,
            extrapolation=0, safety_ok=1, model_json="{}", content_json=table_json,
            content_sha256=content_sha256(table_json), created_by=prosthetist.id, created_at="2026-01-01T00:00:00Z",
        )).inserted_primary_key[0])

    return make


CLEAN_WALK = {"falls": 0, "toe_catches": 0, "strides": 8, "heel_strikes_without_stance": 0,
              "loaded_swing_ms_max_stride": 5.0, "heel_strike_to_stance_ms_max": 5.0}
