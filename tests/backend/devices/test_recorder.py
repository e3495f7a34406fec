"""The session recorder: a device's samples buffered while it records, written in batches, nothing lost at the end."""

from __future__ import annotations

import pytest

from backend.db import open_engine, pooled
from backend.devices.recorder import SessionRecorder
from backend.migrate import migrate
from backend.store import devices, patients, sessions, users
from device_bridge.clock import SteppedClock


def _sample(seq: int) -> tuple:
    return (seq, seq / 100.0, 1, 0, 0.1, 0.0, -5.0, 0.0, 0.0, 1.0, 700.0, -10.0, None, None, None, None, None)


@pytest.fixture
def recording(tmp_path):
    path = tmp_path / "q.sqlite"
    migrate(path)
    pool = open_engine(path)
    with pooled(pool) as conn:
        made = users.create_user(conn, "pat", "prosthetist", "a long password")
        actor = users.User(made["id"], "pat", "prosthetist")
        patient = patients.create_patient(conn, {"code_name": "P-1", "body_mass_kg": 80.0, "height_m": 1.8,
                                                 "side": "left", "k_level": 3, "notes": ""}, actor)
        devices.register_device(conn, "leg", "simulated", "virtual", "a")
        sid = sessions.start_session(conn, patient["id"], "leg", {"speed_mps": 1.2, "incline_deg": 0.0,
                                                                  "body_mass_kg": 80.0},
                                     {"proposal_id": None, "envelope_id": None, "table_version": None, "crc32": None},
                                     actor)
    recorder = SessionRecorder(pool, clock=SteppedClock())     # not started: flushes happen when the test says so
    yield pool, recorder, sid
    recorder.close()
    pool.dispose()


def test_only_a_recording_device_is_kept_and_end_writes_everything(recording):
    pool, recorder, sid = recording
    recorder.add("leg", _sample(0))                         # before begin: not recorded
    recorder.begin("leg", sid)
    assert recorder.session_of("leg") == sid and recorder.session_of("other") is None
    for seq in range(1, 6):
        recorder.add("leg", _sample(seq))
    recorder.add("other", _sample(99))
    recorder.note_status("leg", "active", (3, 0xABC))
    recorder.note_status("leg", "active", (3, 0xABC))
    recorder.note_status("other", "safe", None)
    reports, late = recorder.end("leg")
    assert reports == {("active", (3, 0xABC)): 2} and late == 0 and recorder.session_of("leg") is None
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == [1, 2, 3, 4, 5]
    recorder.add("leg", _sample(6))                         # after end: not recorded
    recorder.flush()
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == [1, 2, 3, 4, 5]


def test_flushes_append_in_batches(recording):
    pool, recorder, sid = recording
    recorder.begin("leg", sid)
    recorder.add("leg", _sample(1))
    recorder.flush()
    recorder.add("leg", _sample(2))
    recorder.flush()
    recorder.flush()                                         # nothing new: nothing written
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == [1, 2]


def test_the_periodic_flush_writes_whole_seconds_and_a_silent_legs_last_second(recording):
    """Each second of walking is written once, complete; the second still filling waits, unless the leg went silent."""
    from backend.devices.recorder import STALE_S

    pool, recorder, sid = recording
    recorder.begin("leg", sid)
    for seq in range(150):
        recorder.add("leg", _sample(seq))
    recorder.flush(whole_seconds=True)
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == list(range(100))        # second 0 only: second 1 is filling
    recorder._clock.advance(STALE_S * 0.9)
    recorder.flush(whole_seconds=True)
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == list(range(100))        # not silent for long enough yet
    recorder._clock.advance(STALE_S * 0.2)                                  # the last sample is now STALE_S old
    recorder.flush(whole_seconds=True)
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == list(range(150))        # a silent leg's last second is written


def test_late_samples_fill_the_seconds_already_written_and_are_counted(recording):
    """A link down for a while: the live stream jumps past the gap, the bridge's buffer fills it afterwards."""
    pool, recorder, sid = recording
    recorder.begin("leg", sid)
    for seq in [*range(0, 250), *range(6250, 6400)]:        # 60 s missing in the live stream
        recorder.add("leg", _sample(seq))
    recorder.flush(whole_seconds=True)
    for seq in range(250, 6250):                             # delivered late, oldest first
        recorder.add("leg", _sample(seq), late=True)
    recorder.add("leg", _sample(6300), late=True)            # one the live stream also brought: kept once
    recorder.flush(whole_seconds=True)
    _reports, late = recorder.end("leg")
    assert late == 6001
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == list(range(6400))


def test_a_session_started_on_another_instance_is_taken_up_and_one_stopped_there_dropped(recording):
    """Two instances, one leg: both record its open session (each sample stored once), and the one that did not stop it
    drops what it still holds (the stopping instance wrote the same samples)."""
    pool, first, sid = recording
    second = SessionRecorder(pool, device_ids=("leg",))
    second.sync()                                            # the session open in the database: taken up
    assert second.session_of("leg") == sid
    first.begin("leg", sid)
    for seq in range(0, 120):                                # both instances receive every sample
        first.add("leg", _sample(seq))
        second.add("leg", _sample(seq))
    second.flush()
    first.end("leg")                                         # stopped on the first instance
    with pooled(pool) as conn:
        sessions.stop_session(conn, sid, {"strides": 0}, users.User(1, "pat", "prosthetist"))
        assert sessions.samples(conn, sid)["seq"] == list(range(120))
    second.add("leg", _sample(120))
    second.sync()
    assert second.session_of("leg") is None
    second.flush()
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == list(range(120))   # nothing after the stop
    first.sync()                                             # the stopping instance does not take it up again
    assert first.session_of("leg") is None


def test_a_failed_write_keeps_its_samples_for_the_next_flush(recording, monkeypatch):
    pool, recorder, sid = recording
    recorder.begin("leg", sid)
    for seq in range(5):
        recorder.add("leg", _sample(seq))
    real = sessions.add_samples
    monkeypatch.setattr(sessions, "add_samples", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("database away")))
    with pytest.raises(RuntimeError, match="away"):
        recorder.flush()
    monkeypatch.setattr(sessions, "add_samples", real)
    recorder.flush()
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == list(range(5))


def test_one_legs_bad_sample_never_stops_another_legs_recording(recording):
    """A sample the store refuses (a NaN time, a missing load: synthetic, as a broken bridge could send) is refused
    and counted; its leg's other samples and every other leg's are written, and nothing raises."""
    pool, recorder, sid = recording
    with pooled(pool) as conn:
        actor = users.User(1, "pat", "prosthetist")
        devices.register_device(conn, "leg-2", "simulated", "virtual", "b")
        other = sessions.start_session(conn, 1, "leg-2", {"speed_mps": 1.0, "incline_deg": 0.0, "body_mass_kg": 80.0},
                                       {"proposal_id": None, "envelope_id": None, "table_version": None,
                                        "crc32": None}, actor)
    recorder.begin("leg", sid)
    recorder.begin("leg-2", other)
    for seq in range(5):
        recorder.add("leg", _sample(seq))
        bad = _sample(seq)
        if seq == 2:
            bad = (*bad[:1], float("nan"), *bad[2:])
        elif seq == 3:
            bad = (*bad[:10], None, *bad[11:])
        recorder.add("leg-2", bad)
    recorder.flush()                                                            # no exception
    with pooled(pool) as conn:
        assert sessions.samples(conn, sid)["seq"] == list(range(5))
        assert sessions.samples(conn, other)["seq"] == [0, 1, 4]
    assert recorder.refused_samples == {"leg-2": 2}
