"""Walking sessions: the telemetry samples as they arrive and the summary when stopped."""

from __future__ import annotations

import json
from collections.abc import Iterable

from sqlalchemy import Connection, RowMapping, insert, select, update
from sqlalchemy.exc import IntegrityError

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError, NotFoundError
from backend.store import audit, sample_pack
from backend.store.dialect import insert_or_ignore, unique_violation
from backend.store.tables import patients, session_sample_seconds, users, versions, walking_sessions
from backend.store.users import User

_s, _su, _pu, _pa, _pp = (walking_sessions, users.alias("su"), users.alias("pu"), patients.alias("pa"),
                          patients.alias("pp"))
_SESSION_SELECT = (
    select(_s, _su.c.username.label("started_by_name"), _pu.c.username.label("stopped_by_name"),
           _pa.c.code_name.label("patient_code"), versions.c.kind, versions.c.version,
           _pp.c.code_name.label("table_patient_code"), versions.c.decision_override.label("approval_override"),
           versions.c.extrapolation_reason)
    .select_from(_s.join(_su, _su.c.id == _s.c.started_by).outerjoin(_pu, _pu.c.id == _s.c.stopped_by)
                 .join(_pa, _pa.c.id == _s.c.patient_id).outerjoin(versions, versions.c.id == _s.c.version_id)
                 .outerjoin(_pp, _pp.c.id == versions.c.patient_id)))


def session_row(conn: Connection, session_id: int) -> RowMapping:
    """A session with who started and stopped it, its patient and the version the leg ran (its kind and number)."""
    row = conn.execute(_SESSION_SELECT.where(_s.c.id == session_id)).mappings().first()
    if row is None:
        raise NotFoundError(f"session {session_id} not found")
    return row


def rows_of_patient(conn: Connection, patient_id: int) -> list[RowMapping]:
    """A patient's sessions, newest first (rows as :func:`session_row` reads them)."""
    return list(conn.execute(_SESSION_SELECT.where(_s.c.patient_id == patient_id).order_by(_s.c.id.desc())).mappings())


def start_session(conn: Connection, patient_id: int, device_id: str, task: dict, ran: dict,
                  actor: User, course: str | None = None, simulated: bool | None = None) -> int:
    """Open a recording session (409 when the device already records one). ``ran``: what the device reports running
    (``table_version`` and ``crc32`` as reported, None for no table; ``proposal_id`` or ``envelope_id`` when this
    server sent it)."""
    with write_transaction(conn):
        busy = ConflictError(f"device {device_id} is already recording a session; stop it first")
        if conn.execute(select(_s.c.id).where(_s.c.device_id == device_id, _s.c.status == "recording")).first():
            raise busy
        try:
            session_id = int(conn.execute(insert(_s).values(
                patient_id=patient_id, device_id=device_id,
                version_id=ran["proposal_id"] if ran["proposal_id"] is not None else ran["envelope_id"],
                table_version=ran["table_version"], table_crc32=ran["crc32"],
                speed_mps=task["speed_mps"], incline_deg=task["incline_deg"], body_mass_kg=task["body_mass_kg"],
                course=course, status="recording", started_by=actor.id, started_at=utc_now(),
                simulated=None if simulated is None else int(simulated))).inserted_primary_key[0])
        except IntegrityError as exc:   # another instance started one a moment ago: the database's one per device
            if not unique_violation(exc, "one_recording_session_per_device", "walking_sessions.device_id"):
                raise
            raise busy from None
        audit.record(conn, actor.id, actor.username, "session.start", "session", session_id,
                     after={"patient_id": patient_id, "device_id": device_id, "task": task, "course": course,
                            "simulated": simulated,
                            "proposal_id": ran["proposal_id"], "envelope_id": ran["envelope_id"],
                            "device_reported": {"table_version": ran["table_version"],
                                                "crc32": None if ran["crc32"] is None else f"{ran['crc32']:08x}"}})
    return session_id


SAMPLE_COLUMNS = sample_pack.COLUMNS   # (the adaptive leg's task columns are None while a single table runs)


def recording_sessions(conn: Connection, device_ids: Iterable[str]) -> dict[str, int]:
    """The session each of ``device_ids`` records now, if any (device id → session id)."""
    ids = list(device_ids)
    if not ids:
        return {}
    rows = conn.execute(select(_s.c.device_id, _s.c.id).where(_s.c.device_id.in_(ids), _s.c.status == "recording"))
    return {device_id: int(session_id) for device_id, session_id in rows}


def add_samples(conn: Connection, session_id: int, rows: Iterable[tuple]) -> None:
    """Append samples (tuples in :data:`SAMPLE_COLUMNS` order) to a recording session, one stored row per second of
    walking. A sample already stored (the same sequence number: a retried batch) is kept as it was; anything malformed
    is refused (ValueError naming the value) and nothing of the batch is written.

    Each second's row is read under a row lock and rewritten merged, so two writers of one session (two instances)
    never lose each other's samples: SQLite's write lock, PostgreSQL's ``FOR UPDATE`` (an empty second is first
    inserted if missing, without replacing one another writer inserted a moment before)."""
    by_second: dict[int, list[tuple]] = {}
    for r in rows:
        by_second.setdefault(sample_pack.second_of(int(r[0])), []).append(tuple(r))
    # each second's batch as it would be stored on its own (validated, and de-duplicated, before anything is written)
    alone = {second: sample_pack.merge([], batch)[0] for second, batch in by_second.items()}
    packed = {second: sample_pack.pack(batch) for second, batch in alone.items()}
    if not packed:
        return
    t = session_sample_seconds.c
    with write_transaction(conn):
        for second, arriving in sorted(by_second.items()):
            fresh = conn.execute(insert_or_ignore(conn, session_sample_seconds, ["session_id", "second"]).values(
                session_id=session_id, second=second, n=len(alone[second]), samples=packed[second]))
            if fresh.rowcount == 1:
                continue
            stored = conn.execute(select(t.samples).where(t.session_id == session_id, t.second == second)
                                  .with_for_update()).scalar_one()
            merged, added = sample_pack.merge(sample_pack.unpack(stored), arriving)
            if added:
                conn.execute(update(session_sample_seconds).where(t.session_id == session_id, t.second == second)
                             .values(n=len(merged), samples=sample_pack.pack(merged)))


def samples(conn: Connection, session_id: int) -> dict[str, list]:
    """The session's samples by column (SI), in sequence order, exactly as they were written."""
    t = session_sample_seconds.c
    rows = [r for blob in conn.execute(select(t.samples).where(t.session_id == session_id).order_by(t.second))
            .scalars() for r in sample_pack.unpack(blob)]
    return {c: [r[i] for r in rows] for i, c in enumerate(SAMPLE_COLUMNS)}


def stop_session(conn: Connection, session_id: int, summary: dict, actor: User) -> None:
    with write_transaction(conn):
        row = conn.execute(select(_s.c.status).where(_s.c.id == session_id).with_for_update()).first()
        if row is None:
            raise NotFoundError(f"session {session_id} not found")
        if row.status != "recording":
            raise ConflictError(f"session {session_id} is already stopped")
        conn.execute(update(_s).where(_s.c.id == session_id).values(
            status="stopped", stopped_by=actor.id, stopped_at=utc_now(),
            summary_json=json.dumps(summary, allow_nan=False)))
        audit.record(conn, actor.id, actor.username, "session.stop", "session", session_id,
                     after={k: summary.get(k) for k in ("samples", "strides", "cadence_steps_per_min",
                                                        "knee_angle_rmse_deg", "ankle_angle_rmse_deg")})
