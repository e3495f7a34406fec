"""Devices: their registration, the patient each is assigned to, and the commands sent to them."""

from __future__ import annotations

import json

from sqlalchemy import Connection, select, update

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError, NotFoundError
from backend.store import audit
from backend.store.dialect import insert_or_ignore
from backend.store.tables import devices, patients, users, walking_sessions
from backend.store.users import User


def register_device(conn: Connection, device_id: str, kind: str, interface: str, channel: str) -> None:
    """Record a configured device (once; later starts keep the first registration)."""
    with write_transaction(conn):
        conn.execute(insert_or_ignore(conn, devices, ["id"]).values(
            id=device_id, kind=kind, interface=interface, channel=channel, registered_at=utc_now()))


def record_command(conn: Connection, device_id: str, command: str, actor: User) -> None:
    """Audit a command sent to a device (the device's status tells whether it took effect)."""
    with write_transaction(conn):
        audit.record(conn, actor.id, actor.username, f"device.{command}", "device", None, after={"device_id": device_id})


def record_calibration(conn: Connection, device_id: str, action: str, step: str | None, answer: dict,
                       actor: User) -> None:
    """Audit one guided-calibration command with the leg's answer (what it measured, or why it refused)."""
    with write_transaction(conn):
        audit.record(conn, actor.id, actor.username, f"device.calibration.{action}", "device", None,
                     after={"device_id": device_id, "step": step, "outcome": answer["outcome"],
                            "refused_reason": answer["refused_reason"], "measured": answer["measured"]})


def link_mode(conn: Connection, device_id: str) -> str:
    """The prosthetist's choice of what a lost link does to the device: ``supervised`` or ``autonomous``."""
    row = conn.execute(select(devices.c.link_mode).where(devices.c.id == device_id)).first()
    if row is None:
        raise NotFoundError(f"device {device_id!r} is not registered")
    return str(row[0])


def set_link_mode(conn: Connection, device_id: str, mode: str, reason: str, actor: User) -> None:
    """Choose what a lost link does to the device (audited with the reason, the choice before and after)."""
    with write_transaction(conn):
        before = conn.execute(select(devices.c.link_mode).where(devices.c.id == device_id).with_for_update()).first()
        if before is None:
            raise NotFoundError(f"device {device_id!r} is not registered")
        conn.execute(update(devices).where(devices.c.id == device_id).values(link_mode=mode))
        audit.record(conn, actor.id, actor.username, "device.link_mode", "device", None,
                     before={"device_id": device_id, "link_mode": before[0]},
                     after={"device_id": device_id, "link_mode": mode, "reason": reason})


def assignment(conn: Connection, device_id: str) -> dict | None:
    """The patient the device is assigned to (id, code name, body mass, by whom and when, the leg their record
    describes or None), or None."""
    row = conn.execute(
        select(devices.c.patient_id, patients.c.code_name, patients.c.body_mass_kg, users.c.username,
               devices.c.assigned_at, patients.c.leg_json)
        .select_from(devices.join(patients, patients.c.id == devices.c.patient_id)
                     .outerjoin(users, users.c.id == devices.c.assigned_by))
        .where(devices.c.id == device_id)).first()
    if row is None:
        return None
    return {"patient_id": row[0], "patient_code": row[1], "body_mass_kg": row[2], "assigned_by": row[3],
            "assigned_at": row[4], "leg": None if row[5] is None else json.loads(row[5])}


def assign(conn: Connection, device_id: str, patient_id: int | None, actor: User) -> None:
    """Assign the device to a patient (None: to nobody), audited. Refused while the device records a session:
    the session's patient would change under it."""
    with write_transaction(conn):
        before = conn.execute(select(devices.c.patient_id).where(devices.c.id == device_id).with_for_update()).first()
        recording = conn.execute(select(walking_sessions.c.id).where(
            walking_sessions.c.device_id == device_id, walking_sessions.c.status == "recording")).first()
        if recording is not None:
            raise ConflictError(f"device {device_id} is recording session {recording[0]}; stop it before changing "
                                "the patient the device is assigned to")
        if before is None:
            raise NotFoundError(f"device {device_id!r} is not registered")
        if patient_id is not None and conn.execute(select(patients.c.id).where(patients.c.id == patient_id)
                                                   ).first() is None:
            raise NotFoundError(f"patient {patient_id} not found")
        conn.execute(update(devices).where(devices.c.id == device_id).values(
            patient_id=patient_id, assigned_by=actor.id, assigned_at=utc_now()))
        audit.record(conn, actor.id, actor.username, "device.assign", "device", None,
                     before={"device_id": device_id, "patient_id": before[0]},
                     after={"device_id": device_id, "patient_id": patient_id})


def next_wire_version(conn: Connection, device_id: str) -> int:
    """The device's next table version, 1..65535 then 1 again (call inside the push's write transaction; the device's
    row stays locked until it ends, so two servers never hand out the same version)."""
    last = conn.execute(select(devices.c.last_wire_version).where(devices.c.id == device_id).with_for_update()
                        ).scalar_one()
    version = last % 0xFFFF + 1
    conn.execute(update(devices).where(devices.c.id == device_id).values(last_wire_version=version))
    return version
