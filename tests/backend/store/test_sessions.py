"""Walking sessions in storage: one recording per device, samples written once, stopped once."""

from __future__ import annotations

import pytest

from backend.errors import ConflictError, NotFoundError
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
    s = sessions.get_session(conn, session_id)
    assert s["status"] == "recording" and s["table_label"] is None and s["table_crc32"] is None
    assert s["task_words"].startswith("'mixed' course: ") and s["task"] == TASK
    assert [x["id"] for x in sessions.sessions_of_patient(conn, patient["id"])] == [session_id]


def test_a_retried_batch_never_duplicates_a_sample_and_samples_read_in_order(conn, session_id):
    sessions.add_samples(conn, session_id, [_sample(i) for i in (2, 0, 1)])
    sessions.add_samples(conn, session_id, [_sample(i) for i in (1, 2, 3)])       # 1 and 2 again: a retry
    got = sessions.samples(conn, session_id)
    assert got["seq"] == [0, 1, 2, 3] and got["t_s"] == [0.0, 0.01, 0.02, 0.03]
    assert set(got) == set(sessions.SAMPLE_COLUMNS)


def test_a_session_stops_once_with_its_summary(conn, prosthetist, session_id):
    with pytest.raises(ValueError):                       # a summary that is not JSON: nothing written
        sessions.stop_session(conn, session_id, {"x": float("nan")}, prosthetist)
    assert sessions.get_session(conn, session_id)["status"] == "recording"
    sessions.stop_session(conn, session_id, {"samples": 4, "strides": 0}, prosthetist)
    s = sessions.get_session(conn, session_id)
    assert s["status"] == "stopped" and s["summary"] == {"samples": 4, "strides": 0} and s["stopped_by"] == "pat"
    with pytest.raises(ConflictError, match="already stopped"):
        sessions.stop_session(conn, session_id, {}, prosthetist)
    with pytest.raises(NotFoundError):
        sessions.stop_session(conn, 999, {}, prosthetist)


def test_task_words_name_a_course_by_its_range_and_a_fixed_task_by_its_values():
    assert sessions.task_words(None, 1.234, -3.0) == "1.23 m/s, incline -3.0°"
    assert sessions.task_words("unknown", 1.0, 0.0) == "1.00 m/s, incline +0.0°"
    words = sessions.task_words("mixed", 1.0, 0.0)
    assert "0.85–1.60 m/s" in words and "incline -8° to +8°" in words


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
