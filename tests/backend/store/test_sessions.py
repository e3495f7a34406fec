"""Walking sessions in storage: one recording per device, samples written once, stopped once."""

from __future__ import annotations

import pytest

from backend.errors import ConflictError, NotFoundError
from backend.services import sessions as session_views
from backend.store import devices, sessions

TASK = {"speed_mps": 1.2, "incline_deg": 0.0, "body_mass_kg": 80.0}
NOTHING_RAN = {"proposal_id": None, "envelope_id": None, "table_version": None, "crc32": None}


def _sample(seq: int) -> tuple:
    return (seq, seq / 100.0, 1, 0, 0.1, 0.0, -5.0, 0.0, 0.0, 1.0, 700.0, -10.0,
            None, None, None, None, None)


@pytest.fixture
def session_id(conn, prosthetist, patient):
    devices.register_device(conn, "leg", "simulated", "virtual", "a")
    return sessions.start_session(conn, patient["id"], "leg", TASK, NOTHING_RAN, prosthetist, course="mixed")


def test_one_recording_per_device_and_what_the_device_ran_is_kept(conn, prosthetist, patient, session_id):
    with pytest.raises(ConflictError, match="already recording"):
        sessions.start_session(conn, patient["id"], "leg", TASK, NOTHING_RAN, prosthetist)
    s = session_views.get_session(conn, session_id)
    assert s["status"] == "recording" and s["table_label"] is None and s["table_crc32"] is None
    assert s["task_words"].startswith("'mixed' course: ") and s["task"] == TASK
    assert [x["id"] for x in session_views.sessions_of_patient(conn, patient["id"])] == [session_id]


def test_a_retried_batch_never_duplicates_a_sample_and_samples_read_in_order(conn, session_id):
    sessions.add_samples(conn, session_id, [_sample(i) for i in (2, 0, 1)])
    sessions.add_samples(conn, session_id, [_sample(i) for i in (1, 2, 3)])       # 1 and 2 again: a retry
    got = sessions.samples(conn, session_id)
    assert got["seq"] == [0, 1, 2, 3] and got["t_s"] == [0.0, 0.01, 0.02, 0.03]
    assert set(got) == set(sessions.SAMPLE_COLUMNS)


def test_a_session_stops_once_with_its_summary(conn, prosthetist, session_id):
    with pytest.raises(ValueError):                       # a summary that is not JSON: nothing written
        sessions.stop_session(conn, session_id, {"x": float("nan")}, prosthetist)
    assert session_views.get_session(conn, session_id)["status"] == "recording"
    sessions.stop_session(conn, session_id, {"samples": 4, "strides": 0}, prosthetist)
    s = session_views.get_session(conn, session_id)
    assert s["status"] == "stopped" and s["summary"] == {"samples": 4, "strides": 0} and s["stopped_by"] == "pat"
    with pytest.raises(ConflictError, match="already stopped"):
        sessions.stop_session(conn, session_id, {}, prosthetist)
    with pytest.raises(NotFoundError):
        sessions.stop_session(conn, 999, {}, prosthetist)


def test_a_second_recording_started_past_the_check_is_refused_by_the_database(conn, prosthetist, patient, session_id,
                                                                             monkeypatch):
    """Two instances starting a session on one leg at once both pass the read; the database's partial unique index
    refuses the second, and it is the same refusal."""
    from backend.store import sessions as module

    real = module.select

    def blind(*cols):   # the first look finds nothing, as it would for an instance racing another
        query = real(*cols)
        return query.where(module._s.c.id < 0) if cols == (module._s.c.id,) else query

    monkeypatch.setattr(module, "select", blind)
    with pytest.raises(ConflictError, match="already recording"):
        sessions.start_session(conn, patient["id"], "leg", TASK, NOTHING_RAN, prosthetist)


def test_samples_stored_a_row_each_before_revision_0014_are_carried_over_exactly(tmp_path):
    """An SQLite database of the release before (one row per sample; that release ran on SQLite only) upgraded in
    place: every sample reads back the same."""
    from backend.db import connect
    from backend.migrate import migrate
    from tests.helpers.sql import sql

    database = tmp_path / "old.sqlite"
    migrate(database, to="0013")
    conn = connect(database)
    try:
        sql(conn, "INSERT INTO users (username, role, password_hash, created_at) VALUES ('pat', 'prosthetist', 'x', 't')")
        sql(conn, "INSERT INTO patients (code_name, body_mass_kg, side, created_by, created_at, updated_at) "
            "VALUES ('P-1', 80, 'left', 1, 't', 't')")
        sql(conn, "INSERT INTO devices (id, kind, interface, channel, registered_at) VALUES ('leg', 'simulated', "
            "'virtual', 'a', 't')")
        sql(conn, "INSERT INTO walking_sessions (patient_id, device_id, speed_mps, incline_deg, body_mass_kg, status, "
            "started_by, started_at) VALUES (1, 'leg', 1.2, 0, 80, 'recording', 1, 't')")
        rows = [(i, i / 100, 1, i % 4, 0.1 * i, 0.0, -5.0, 0.01 * i, 0.0, 1.0, 700.0 - i, -10.0,
                 *((1.2, 0.5, 1.25, 0.0, "adaptive") if i % 3 else (None,) * 5)) for i in range(250) if i != 120]
        columns = ", ".join(("session_id", *sessions.SAMPLE_COLUMNS))
        marks = ", ".join(f":v{k}" for k in range(len(sessions.SAMPLE_COLUMNS) + 1))
        for r in rows:
            sql(conn, f"INSERT INTO session_samples ({columns}) VALUES ({marks})",
                **{f"v{k}": v for k, v in enumerate((1, *r))})
    finally:
        conn.close()
    assert migrate(database)[0] == "0014"
    conn = connect(database)
    try:
        got = sessions.samples(conn, 1)
        assert [tuple(got[c][i] for c in sessions.SAMPLE_COLUMNS) for i in range(len(got["seq"]))] == rows
        assert sql(conn, "SELECT count(*) FROM session_sample_seconds").scalar_one() == 3      # seconds 0, 1, 2
    finally:
        conn.close()
