"""Devices, table pushes and walking sessions in SQLite (migration 0002).

A push row is written before anything goes on the bus (status ``sending``) and finished afterwards
(``acknowledged`` with the CRC the device read back, or ``failed`` with the reason); ``active`` is set only when
the device's own status reports that version and CRC running. Sessions store the telemetry samples as they arrive
and their summary when stopped.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError, NotFoundError
from backend.store import audit
from backend.store.users import User

_PUSH_SELECT = ("SELECT pu.*, u.username AS requested_by_name FROM pushes pu JOIN users u ON u.id = pu.requested_by")


def register_device(conn: sqlite3.Connection, device_id: str, kind: str, interface: str, channel: str) -> None:
    """Record a configured device (once; later starts keep the first registration)."""
    with write_transaction(conn):
        conn.execute("INSERT OR IGNORE INTO devices (id, kind, interface, channel, registered_at) VALUES (?, ?, ?, ?, ?)",
                     (device_id, kind, interface, channel, utc_now()))


def _push(row: sqlite3.Row) -> dict:
    return {"id": row["id"], "proposal_id": row["proposal_id"], "device_id": row["device_id"],
            "table_version": row["table_version"], "crc32": f"{row['crc32']:08x}", "status": row["status"],
            "requested_by": row["requested_by_name"], "requested_at": row["requested_at"],
            "acknowledged_at": row["acknowledged_at"], "active_at": row["active_at"], "ended_at": row["ended_at"],
            "attempts": row["attempts"], "elapsed_ms": row["elapsed_ms"], "error": row["error"]}


def get_push(conn: sqlite3.Connection, push_id: int) -> dict:
    row = conn.execute(_PUSH_SELECT + " WHERE pu.id = ?", (push_id,)).fetchone()
    if row is None:
        raise NotFoundError(f"push {push_id} not found")
    return _push(row)


def pushes_of_proposal(conn: sqlite3.Connection, proposal_id: int) -> list[dict]:
    rows = conn.execute(_PUSH_SELECT + " WHERE pu.proposal_id = ? ORDER BY pu.id DESC", (proposal_id,)).fetchall()
    return [_push(r) for r in rows]


def begin_push(conn: sqlite3.Connection, proposal_id: int, device_id: str, version: int, crc32: int,
               actor: User) -> int:
    """Record a push about to be sent (``sending``) and audit it; returns the push id."""
    with write_transaction(conn):
        cur = conn.execute(
            "INSERT INTO pushes (proposal_id, device_id, table_version, crc32, status, requested_by, requested_at) "
            "VALUES (?, ?, ?, ?, 'sending', ?, ?)", (proposal_id, device_id, version, crc32, actor.id, utc_now()))
        push_id = int(cur.lastrowid)
        audit.record(conn, actor.id, actor.username, "proposal.push", "proposal", proposal_id,
                     after={"push_id": push_id, "device_id": device_id, "table_version": version,
                            "crc32": f"{crc32:08x}"})
    return push_id


def finish_push(conn: sqlite3.Connection, push_id: int, ok: bool, attempts: int | None, elapsed_ms: float,
                error: str | None) -> None:
    """``acknowledged`` or ``failed`` (a push already marked active by the device's status stays active)."""
    now = utc_now()
    with write_transaction(conn):
        if ok:
            conn.execute("UPDATE pushes SET status = CASE status WHEN 'sending' THEN 'acknowledged' ELSE status END, "
                         "acknowledged_at = ?, attempts = ?, elapsed_ms = ? WHERE id = ?",
                         (now, attempts, elapsed_ms, push_id))
        else:
            conn.execute("UPDATE pushes SET status = CASE status WHEN 'sending' THEN 'failed' ELSE status END, "
                         "ended_at = ?, elapsed_ms = ?, error = ? WHERE id = ?", (now, elapsed_ms, error, push_id))


def mark_active(conn: sqlite3.Connection, device_id: str, version: int, crc32: int) -> list[int]:
    """The device reports ``version``/``crc32`` running: the newest push of exactly that table becomes ``active``
    and any other active push on the device ``superseded``. Returns the proposal ids that changed."""
    now = utc_now()
    with write_transaction(conn):
        row = conn.execute("SELECT id, proposal_id, status FROM pushes WHERE device_id = ? AND table_version = ? AND "
                           "crc32 = ? ORDER BY id DESC LIMIT 1", (device_id, version, crc32)).fetchone()
        old = conn.execute("SELECT id, proposal_id FROM pushes WHERE device_id = ? AND status = 'active'",
                           (device_id,)).fetchall()
        changed = []
        for o in old:
            if row is None or o["id"] != row["id"]:
                conn.execute("UPDATE pushes SET status = 'superseded', ended_at = ? WHERE id = ?", (now, o["id"]))
                changed.append(o["proposal_id"])
        if row is not None and row["status"] != "active":
            conn.execute("UPDATE pushes SET status = 'active', active_at = ? WHERE id = ?", (now, row["id"]))
            changed.append(row["proposal_id"])
    return changed


def active_push(conn: sqlite3.Connection, device_id: str) -> dict | None:
    row = conn.execute(_PUSH_SELECT + " WHERE pu.device_id = ? AND pu.status = 'active' ORDER BY pu.id DESC LIMIT 1",
                       (device_id,)).fetchone()
    return None if row is None else _push(row)


def deployment_state(conn: sqlite3.Connection, proposal_id: int) -> str | None:
    """``active_on_device`` / ``pushed`` / ``push_failed`` / None (never pushed) from the proposal's pushes."""
    statuses = {r[0] for r in conn.execute("SELECT status FROM pushes WHERE proposal_id = ?", (proposal_id,))}
    if "active" in statuses:
        return "active_on_device"
    if statuses & {"acknowledged", "sending", "superseded"}:
        return "pushed"
    return "push_failed" if statuses else None


def record_command(conn: sqlite3.Connection, device_id: str, command: str, actor: User) -> None:
    """Audit a command sent to a device (the device's status tells whether it took effect)."""
    with write_transaction(conn):
        audit.record(conn, actor.id, actor.username, f"device.{command}", "device", None, after={"device_id": device_id})


# --------------------------------------------------------------------------------------------- sessions

_SESSION_SELECT = ("SELECT s.*, su.username AS started_by_name, pu.username AS stopped_by_name FROM walking_sessions s "
                   "JOIN users su ON su.id = s.started_by LEFT JOIN users pu ON pu.id = s.stopped_by")


def _session(row: sqlite3.Row) -> dict:
    return {"id": row["id"], "patient_id": row["patient_id"], "device_id": row["device_id"],
            "proposal_id": row["proposal_id"], "table_version": row["table_version"],
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


def start_session(conn: sqlite3.Connection, patient_id: int, device_id: str, task: dict, active: dict | None,
                  actor: User) -> int:
    """Open a recording session (409 when the device already records one)."""
    with write_transaction(conn):
        if conn.execute("SELECT 1 FROM walking_sessions WHERE device_id = ? AND status = 'recording'",
                        (device_id,)).fetchone():
            raise ConflictError(f"device {device_id} is already recording a session; stop it first")
        cur = conn.execute(
            "INSERT INTO walking_sessions (patient_id, device_id, proposal_id, table_version, table_crc32, speed_mps, "
            "incline_deg, body_mass_kg, status, started_by, started_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, 'recording', ?, ?)",
            (patient_id, device_id, active["proposal_id"] if active else None,
             active["table_version"] if active else None, int(active["crc32"], 16) if active else None,
             task["speed_mps"], task["incline_deg"], task["body_mass_kg"], actor.id, utc_now()))
        session_id = int(cur.lastrowid)
        audit.record(conn, actor.id, actor.username, "session.start", "session", session_id,
                     after={"patient_id": patient_id, "device_id": device_id, "task": task,
                            "proposal_id": active["proposal_id"] if active else None})
    return session_id


SAMPLE_COLUMNS = ("seq", "t_s", "mode", "fsm_state", "knee_angle_rad", "knee_velocity_rad_s", "knee_torque_Nm",
                  "ankle_angle_rad", "ankle_velocity_rad_s", "ankle_torque_Nm", "load_N", "ankle_moment_Nm")


def add_samples(conn: sqlite3.Connection, session_id: int, rows: Iterable[tuple]) -> None:
    """Append samples (tuples in :data:`SAMPLE_COLUMNS` order) to a recording session."""
    sql = (f"INSERT OR IGNORE INTO session_samples (session_id, {', '.join(SAMPLE_COLUMNS)}) "
           f"VALUES (?, {', '.join('?' * len(SAMPLE_COLUMNS))})")
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
