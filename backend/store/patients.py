"""Patients: pseudonymous code name, body mass (kg), height (m), amputated side, K-level, notes."""

from __future__ import annotations

import sqlite3

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError, NotFoundError
from backend.store import audit
from backend.store.users import User

FIELDS = ("code_name", "body_mass_kg", "height_m", "side", "k_level", "notes")


def _public(row: sqlite3.Row) -> dict:
    return {"id": row["id"], **{f: row[f] for f in FIELDS}, "created_at": row["created_at"],
            "updated_at": row["updated_at"]}


def get_patient(conn: sqlite3.Connection, patient_id: int) -> dict:
    row = conn.execute("SELECT * FROM patients WHERE id = ?", (patient_id,)).fetchone()
    if row is None:
        raise NotFoundError(f"patient {patient_id} not found")
    return _public(row)


def list_patients(conn: sqlite3.Connection) -> list[dict]:
    return [_public(r) for r in conn.execute("SELECT * FROM patients ORDER BY code_name COLLATE NOCASE, id")]


def _unique_code_name(conn: sqlite3.Connection, code_name: str, patient_id: int | None = None) -> None:
    row = conn.execute("SELECT id FROM patients WHERE code_name = ?", (code_name,)).fetchone()
    if row is not None and row["id"] != patient_id:
        raise ConflictError(f"code_name {code_name!r} is already used by patient {row['id']}")


def create_patient(conn: sqlite3.Connection, data: dict, actor: User) -> dict:
    """Insert a validated patient (``data`` holds exactly :data:`FIELDS`)."""
    now = utc_now()
    with write_transaction(conn):
        _unique_code_name(conn, data["code_name"])
        cur = conn.execute(
            f"INSERT INTO patients ({', '.join(FIELDS)}, created_by, created_at, updated_at) "
            f"VALUES ({', '.join('?' * len(FIELDS))}, ?, ?, ?)",
            (*(data[f] for f in FIELDS), actor.id, now, now))
        created = get_patient(conn, int(cur.lastrowid))
        audit.record(conn, actor.id, actor.username, "patient.create", "patient", created["id"], after=created)
    return created


def update_patient(conn: sqlite3.Connection, patient_id: int, changes: dict, actor: User) -> dict:
    """Apply a validated partial update; the audit entry holds only the fields that changed."""
    unknown = set(changes) - set(FIELDS)
    if unknown:
        raise ValueError(f"unknown patient fields {sorted(unknown)}")
    with write_transaction(conn):
        before = get_patient(conn, patient_id)
        changed = {k: v for k, v in changes.items() if before[k] != v}
        if not changed:
            return before
        if "code_name" in changed:
            _unique_code_name(conn, changed["code_name"], patient_id)
        assignments = ", ".join(f"{k} = ?" for k in changed)
        conn.execute(f"UPDATE patients SET {assignments}, updated_at = ? WHERE id = ?",
                     (*changed.values(), utc_now(), patient_id))
        after = get_patient(conn, patient_id)
        audit.record(conn, actor.id, actor.username, "patient.update", "patient", patient_id,
                     before={k: before[k] for k in changed}, after={k: after[k] for k in changed})
    return after
