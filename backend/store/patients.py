"""Patients: pseudonymous code name, body mass (kg), height (m), amputated side, K-level, notes, and a description of
their leg (a leg file's fields, ``device_bridge/sim/leg_file.py``; None: none given)."""

from __future__ import annotations

import json

from sqlalchemy import Connection, RowMapping, bindparam, func, insert, select, update

from backend.db import utc_now, write_transaction
from backend.errors import ConflictError, NotFoundError
from backend.store import audit
from backend.store.tables import patients
from backend.store.users import User
from controller_core.content import canonical_text

FIELDS = ("code_name", "body_mass_kg", "height_m", "side", "k_level", "notes", "leg")
_COLUMNS = {f: f for f in FIELDS} | {"leg": "leg_json"}


def _public(row: RowMapping) -> dict:
    leg = row["leg_json"]
    return {"id": row["id"], **{f: row[f] for f in FIELDS if f != "leg"},
            "leg": None if leg is None else json.loads(leg), "created_at": row["created_at"],
            "updated_at": row["updated_at"]}


def _stored(data: dict) -> dict:
    """Fields as columns: the leg's description as canonical JSON."""
    out = {_COLUMNS[f]: v for f, v in data.items()}
    if out.get("leg_json") is not None:
        out["leg_json"] = canonical_text(out["leg_json"])
    return out


# on most requests: built once (see backend/store/__init__.py)
_BY_ID = select(patients).where(patients.c.id == bindparam("patient_id"))
_LOCK = select(patients.c.id).where(patients.c.id == bindparam("patient_id")).with_for_update()


def get_patient(conn: Connection, patient_id: int) -> dict:
    row = conn.execute(_BY_ID, {"patient_id": patient_id}).mappings().first()
    if row is None:
        raise NotFoundError(f"patient {patient_id} not found")
    return _public(row)


def lock_patient(conn: Connection, patient_id: int) -> None:
    """Inside a write transaction: hold the patient's row until it ends (NotFoundError when there is none), so two
    instances numbering the patient's next version do it one after the other (a row lock on PostgreSQL; SQLite's
    ``BEGIN IMMEDIATE`` already serialises every writer)."""
    found = conn.execute(_LOCK, {"patient_id": patient_id}).first()
    if found is None:
        raise NotFoundError(f"patient {patient_id} not found")


def list_patients(conn: Connection) -> list[dict]:
    query = select(patients).order_by(func.lower(patients.c.code_name), patients.c.id)
    return [_public(r) for r in conn.execute(query).mappings()]


def _unique_code_name(conn: Connection, code_name: str, patient_id: int | None = None) -> None:
    row = conn.execute(select(patients.c.id).where(patients.c.code_name == code_name)).first()
    if row is not None and row.id != patient_id:
        raise ConflictError(f"code_name {code_name!r} is already used by patient {row.id}")


def create_patient(conn: Connection, data: dict, actor: User) -> dict:
    """Insert a validated patient (``data`` holds exactly :data:`FIELDS`). The unique code name is checked first for
    a clear message; the table's unique constraint decides between two instances creating the same name at once."""
    now = utc_now()
    with write_transaction(conn):
        _unique_code_name(conn, data["code_name"])
        new_id = conn.execute(insert(patients).values(**_stored({f: data.get(f) for f in FIELDS}), created_by=actor.id,
                                                      created_at=now, updated_at=now)).inserted_primary_key[0]
        created = get_patient(conn, int(new_id))
        audit.record(conn, actor.id, actor.username, "patient.create", "patient", created["id"], after=created)
    return created


def update_patient(conn: Connection, patient_id: int, changes: dict, actor: User) -> dict:
    """Apply a validated partial update; the audit entry holds only the fields that changed."""
    unknown = set(changes) - set(FIELDS)
    if unknown:
        raise ValueError(f"unknown patient fields {sorted(unknown)}")
    with write_transaction(conn):
        lock_patient(conn, patient_id)
        before = get_patient(conn, patient_id)
        changed = {k: v for k, v in changes.items() if before[k] != v}
        if not changed:
            return before
        if "code_name" in changed:
            _unique_code_name(conn, changed["code_name"], patient_id)
        conn.execute(update(patients).where(patients.c.id == patient_id).values(**_stored(changed),
                                                                                updated_at=utc_now()))
        after = get_patient(conn, patient_id)
        audit.record(conn, actor.id, actor.username, "patient.update", "patient", patient_id,
                     before={k: before[k] for k in changed}, after={k: after[k] for k in changed})
    return after
