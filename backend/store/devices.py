"""Devices in SQLite (migration 0002): their registration and the commands sent to them."""

from __future__ import annotations

import sqlite3

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError, NotFoundError
from backend.store import audit
from backend.store.users import User


def register_device(conn: sqlite3.Connection, device_id: str, kind: str, interface: str, channel: str) -> None:
    """Record a configured device (once; later starts keep the first registration)."""
    with write_transaction(conn):
        conn.execute("INSERT INTO devices (id, kind, interface, channel, registered_at) VALUES (?, ?, ?, ?, ?) "
                     "ON CONFLICT (id) DO NOTHING",
                     (device_id, kind, interface, channel, utc_now()))


def record_command(conn: sqlite3.Connection, device_id: str, command: str, actor: User) -> None:
    """Audit a command sent to a device (the device's status tells whether it took effect)."""
    with write_transaction(conn):
        audit.record(conn, actor.id, actor.username, f"device.{command}", "device", None, after={"device_id": device_id})


def assignment(conn: sqlite3.Connection, device_id: str) -> dict | None:
    """The patient the device is assigned to (id, code name, body mass, by whom and when), or None."""
    row = conn.execute("SELECT d.patient_id, p.code_name, p.body_mass_kg, u.username, d.assigned_at FROM devices d "
                       "JOIN patients p ON p.id = d.patient_id LEFT JOIN users u ON u.id = d.assigned_by "
                       "WHERE d.id = ?", (device_id,)).fetchone()
    if row is None:
        return None
    return {"patient_id": row[0], "patient_code": row[1], "body_mass_kg": row[2], "assigned_by": row[3],
            "assigned_at": row[4]}


def assign(conn: sqlite3.Connection, device_id: str, patient_id: int | None, actor: User) -> None:
    """Assign the device to a patient (None: to nobody), audited. Refused while the device records a session:
    the session's patient would change under it."""
    with write_transaction(conn):
        recording = conn.execute("SELECT id, patient_id FROM walking_sessions WHERE device_id = ? AND "
                                 "status = 'recording'", (device_id,)).fetchone()
        if recording is not None:
            raise ConflictError(f"device {device_id} is recording session {recording[0]}; stop it before changing "
                                "the patient the device is assigned to")
        before = conn.execute("SELECT patient_id FROM devices WHERE id = ?", (device_id,)).fetchone()
        if before is None:
            raise NotFoundError(f"device {device_id!r} is not registered")
        if patient_id is not None and conn.execute("SELECT 1 FROM patients WHERE id = ?",
                                                   (patient_id,)).fetchone() is None:
            raise NotFoundError(f"patient {patient_id} not found")
        conn.execute("UPDATE devices SET patient_id = ?, assigned_by = ?, assigned_at = ? WHERE id = ?",
                     (patient_id, actor.id, utc_now(), device_id))
        audit.record(conn, actor.id, actor.username, "device.assign", "device", None,
                     before={"device_id": device_id, "patient_id": before[0]},
                     after={"device_id": device_id, "patient_id": patient_id})


def next_wire_version(conn: sqlite3.Connection, device_id: str) -> int:
    """The device's next table version, 1..65535 then 1 again (call inside the push's write transaction)."""
    (last,) = conn.execute("SELECT last_wire_version FROM devices WHERE id = ?", (device_id,)).fetchone()
    version = last % 0xFFFF + 1
    conn.execute("UPDATE devices SET last_wire_version = ? WHERE id = ?", (version, device_id))
    return version
