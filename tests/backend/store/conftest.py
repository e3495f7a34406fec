"""A migrated database of its own per test, and the people who act on it."""

from __future__ import annotations

import pytest

from backend.db import connect
from backend.migrate import migrate
from backend.store import patients, users


@pytest.fixture
def conn(tmp_path):
    path = tmp_path / "store.sqlite"
    migrate(path)
    c = connect(path)
    yield c
    c.close()


@pytest.fixture
def prosthetist(conn) -> users.User:
    made = users.create_user(conn, "pat", "prosthetist", "a long password")
    return users.User(made["id"], "pat", "prosthetist")


@pytest.fixture
def patient(conn, prosthetist) -> dict:
    return patients.create_patient(conn, {"code_name": "P-1", "body_mass_kg": 80.0, "height_m": 1.8, "side": "left",
                                          "k_level": 3, "notes": ""}, prosthetist)


@pytest.fixture
def draft(conn, prosthetist, patient):
    """A function making a draft proposal row with a given table text (its sha256 as stored), returning its id."""
    from controller_core.content import content_sha256

    def make(table_json: str = '{"rows": []}', version: int | None = None) -> int:
        v = version or conn.execute("SELECT coalesce(max(version), 0) + 1 FROM proposals").fetchone()[0]
        cur = conn.execute(
            "INSERT INTO proposals (patient_id, version, source, speed_mps, incline_deg, body_mass_kg, extrapolation, "
            "safety_ok, model_json, table_json, table_sha256, created_by, created_at) "
            "VALUES (?, ?, 'model', 1.2, 0, 80, 0, 1, '{}', ?, ?, ?, '2026-01-01T00:00:00Z')",
            (patient["id"], v, table_json, content_sha256(table_json), prosthetist.id))
        conn.commit()
        return int(cur.lastrowid)

    return make


CLEAN_WALK = {"falls": 0, "toe_catches": 0, "strides": 8, "heel_strikes_without_stance": 0,
              "loaded_swing_ms_max_stride": 5.0, "heel_strike_to_stance_ms_max": 5.0}
