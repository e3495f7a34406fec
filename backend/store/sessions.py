"""Walking sessions in SQLite (migration 0002): the telemetry samples as they arrive and the summary when stopped."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError, NotFoundError
from backend.store import audit
from backend.store.envelopes import envelope_label
from backend.store.proposals import table_label
from backend.store.users import User
from device_bridge.sim.course import COURSES

_SESSION_SELECT = ("SELECT s.*, su.username AS started_by_name, pu.username AS stopped_by_name, "
                   "pa.code_name AS patient_code, pr.version AS proposal_version, en.version AS envelope_version, "
                   "pp.code_name AS table_patient_code, "
                   "coalesce(pr.decision_override, en.decision_override) AS approval_override, "
                   "coalesce(pr.extrapolation_reason, en.extrapolation_reason) AS extrapolation_reason "
                   "FROM walking_sessions s JOIN users su ON su.id = s.started_by "
                   "LEFT JOIN users pu ON pu.id = s.stopped_by JOIN patients pa ON pa.id = s.patient_id "
                   "LEFT JOIN proposals pr ON pr.id = s.proposal_id LEFT JOIN envelopes en ON en.id = s.envelope_id "
                   "LEFT JOIN patients pp ON pp.id = coalesce(pr.patient_id, en.patient_id)")


def _label(row: sqlite3.Row) -> str | None:
    if row["proposal_id"] is not None:
        return table_label(row["table_patient_code"], row["proposal_version"])
    if row["envelope_id"] is not None:
        return envelope_label(row["table_patient_code"], row["envelope_version"])
    return None


def task_words(course: str | None, speed_mps: float, incline_deg: float) -> str:
    """A session's task as people read it: a bench course by its name and range, else the speed and incline."""
    walked = COURSES.get(course) if course else None
    if walked is None:
        return f"{speed_mps:.2f} m/s, incline {incline_deg:+.1f}°"
    speeds = [seg.speed_mps for seg in walked.segments]
    inclines = [seg.incline_deg for seg in walked.segments]
    slope = (f"incline {min(inclines):+.0f}° to {max(inclines):+.0f}°" if min(inclines) != max(inclines)
             else f"incline {inclines[0]:+.0f}°")
    return f"'{course}' course: {min(speeds):.2f}–{max(speeds):.2f} m/s, {slope}"


def _session(row: sqlite3.Row) -> dict:
    return {"id": row["id"], "patient_id": row["patient_id"], "patient_code": row["patient_code"],
            "device_id": row["device_id"], "proposal_id": row["proposal_id"], "envelope_id": row["envelope_id"],
            "table_label": _label(row), "course": row["course"],
            "task_words": task_words(row["course"], row["speed_mps"], row["incline_deg"]),
            "approval_override": row["approval_override"],
            "extrapolation_reason": row["extrapolation_reason"], "table_version": row["table_version"],
            "table_crc32": None if row["table_crc32"] is None else f"{row['table_crc32']:08x}",
            "task": {"speed_mps": row["speed_mps"], "incline_deg": row["incline_deg"],
                     "body_mass_kg": row["body_mass_kg"]},
            "status": row["status"], "started_by": row["started_by_name"], "started_at": row["started_at"],
            "stopped_by": row["stopped_by_name"], "stopped_at": row["stopped_at"],
            "summary": None if row["summary_json"] is None else json.loads(row["summary_json"])}


def get_session(conn: sqlite3.Connection, session_id: int) -> dict:
    row = conn.execute(_SESSION_SELECT + " WHERE s.id = ?", (session_id,)).fetchone()
    if row is None:
        raise NotFoundError(f"session {session_id} not found")
    return _session(row)


def sessions_of_patient(conn: sqlite3.Connection, patient_id: int) -> list[dict]:
    rows = conn.execute(_SESSION_SELECT + " WHERE s.patient_id = ? ORDER BY s.id DESC", (patient_id,)).fetchall()
    return [_session(r) for r in rows]


def start_session(conn: sqlite3.Connection, patient_id: int, device_id: str, task: dict, ran: dict,
                  actor: User, course: str | None = None) -> int:
    """Open a recording session (409 when the device already records one). ``ran``: what the device reports running
    (``table_version`` and ``crc32`` as reported, None for no table; ``proposal_id`` or ``envelope_id`` when this
    server sent it)."""
    with write_transaction(conn):
        if conn.execute("SELECT 1 FROM walking_sessions WHERE device_id = ? AND status = 'recording'",
                        (device_id,)).fetchone():
            raise ConflictError(f"device {device_id} is already recording a session; stop it first")
        cur = conn.execute(
            "INSERT INTO walking_sessions (patient_id, device_id, proposal_id, envelope_id, table_version, table_crc32, "
            "speed_mps, incline_deg, body_mass_kg, course, status, started_by, started_at) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, 'recording', ?, ?)",
            (patient_id, device_id, ran["proposal_id"], ran["envelope_id"], ran["table_version"], ran["crc32"],
             task["speed_mps"], task["incline_deg"], task["body_mass_kg"], course, actor.id, utc_now()))
        session_id = int(cur.lastrowid)
        audit.record(conn, actor.id, actor.username, "session.start", "session", session_id,
                     after={"patient_id": patient_id, "device_id": device_id, "task": task, "course": course,
                            "proposal_id": ran["proposal_id"], "envelope_id": ran["envelope_id"],
                            "device_reported": {"table_version": ran["table_version"],
                                                "crc32": None if ran["crc32"] is None else f"{ran['crc32']:08x}"}})
    return session_id


SAMPLE_COLUMNS = ("seq", "t_s", "mode", "fsm_state", "knee_angle_rad", "knee_velocity_rad_s", "knee_torque_Nm",
                  "ankle_angle_rad", "ankle_velocity_rad_s", "ankle_torque_Nm", "load_N", "ankle_moment_Nm",
                  # the adaptive leg's task (migration 0007; NULL while a single table runs)
                  "estimated_speed_mps", "estimated_incline_deg", "running_speed_mps", "running_incline_deg",
                  "adaptive_mode")


def add_samples(conn: sqlite3.Connection, session_id: int, rows: Iterable[tuple]) -> None:
    """Append samples (tuples in :data:`SAMPLE_COLUMNS` order) to a recording session; a sample already stored
    (the same sequence number, a retried batch) is kept as it was, anything else malformed is refused."""
    sql = (f"INSERT INTO session_samples (session_id, {', '.join(SAMPLE_COLUMNS)}) "
           f"VALUES (?, {', '.join('?' * len(SAMPLE_COLUMNS))}) ON CONFLICT (session_id, seq) DO NOTHING")
    with write_transaction(conn):
        conn.executemany(sql, ((session_id, *r) for r in rows))


def samples(conn: sqlite3.Connection, session_id: int) -> dict[str, list]:
    """The session's samples by column (SI), in sequence order."""
    rows = conn.execute(f"SELECT {', '.join(SAMPLE_COLUMNS)} FROM session_samples WHERE session_id = ? ORDER BY seq",
                        (session_id,)).fetchall()
    return {c: [r[i] for r in rows] for i, c in enumerate(SAMPLE_COLUMNS)}


def stop_session(conn: sqlite3.Connection, session_id: int, summary: dict, actor: User) -> None:
    with write_transaction(conn):
        row = conn.execute("SELECT status FROM walking_sessions WHERE id = ?", (session_id,)).fetchone()
        if row is None:
            raise NotFoundError(f"session {session_id} not found")
        if row["status"] != "recording":
            raise ConflictError(f"session {session_id} is already stopped")
        conn.execute("UPDATE walking_sessions SET status = 'stopped', stopped_by = ?, stopped_at = ?, summary_json = ? "
                     "WHERE id = ?", (actor.id, utc_now(), json.dumps(summary, allow_nan=False), session_id))
        audit.record(conn, actor.id, actor.username, "session.stop", "session", session_id,
                     after={k: summary.get(k) for k in ("samples", "strides", "cadence_steps_per_min",
                                                        "knee_angle_rmse_deg", "ankle_angle_rmse_deg")})
