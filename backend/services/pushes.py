"""A push as the clinic reads it: its version by the name people use ("P-001 · table v3"), what the API calls the
version (a table's ``proposal_id``, an envelope's ``envelope_id``), its task, its fate and any withdrawal of its
version; from the rows :mod:`backend.store.pushes` stores."""

from __future__ import annotations

from sqlalchemy import Connection, RowMapping

from backend.store import pushes as store
from backend.store.pushes import Pushed
from backend.store.versions import api_ids, version_label


def view(row: RowMapping) -> dict:
    """The API's view of a push row (:func:`backend.store.pushes.push_row`)."""
    table = row["kind"] == "table"
    label = version_label(row["kind"], row["patient_code"], row["version"])
    return {"id": row["id"], "kind": row["kind"], **api_ids(row["kind"], row["version_id"]),
            "device_id": row["device_id"],
            "patient_id": row["patient_id"], "patient_code": row["patient_code"],
            "proposal_version": row["version"] if table else None,
            "envelope_version": None if table else row["version"],
            "label": label, "table_label": label if table else None,
            "task": {"speed_mps": row["speed_mps"], "incline_deg": row["incline_deg"]},
            "body_mass_kg": row["built_for_mass_kg"], "override_reason": row["override_reason"],
            "approval_override": row["approval_override"], "extrapolation_reason": row["extrapolation_reason"],
            "table_version": row["table_version"], "crc32": f"{row['crc32']:08x}", "status": row["status"],
            "requested_by": row["requested_by_name"], "requested_at": row["requested_at"],
            "acknowledged_at": row["acknowledged_at"], "active_at": row["active_at"], "ended_at": row["ended_at"],
            "attempts": row["attempts"], "elapsed_ms": row["elapsed_ms"], "error": row["error"],
            "withdrawal": None if row["withdrawn_at"] is None else {
                "by": row["withdrawn_by_name"], "at": row["withdrawn_at"], "reason": row["withdrawn_reason"]},
            "sent_back_reason": row["sent_back_reason"]}


def _maybe(row: RowMapping | None) -> dict | None:
    return None if row is None else view(row)


def get_push(conn: Connection, push_id: int) -> dict:
    return view(store.push_row(conn, push_id))


def pushes_of(conn: Connection, item: Pushed) -> list[dict]:
    """Every push of this proposal or envelope, newest first."""
    return [view(r) for r in store.rows_of(conn, item)]


def push_of_version(conn: Connection, device_id: str, version: int | None, crc32: int | None = None) -> dict | None:
    """The newest push of this table version (and CRC) to the device (:func:`backend.store.pushes.row_of_version`)."""
    return _maybe(store.row_of_version(conn, device_id, version, crc32))


def last_run_not_withdrawn(conn: Connection, device_id: str, besides: Pushed) -> dict | None:
    """Where a withdrawal sends the leg back (:func:`backend.store.pushes.last_run_not_withdrawn`)."""
    return _maybe(store.last_run_not_withdrawn(conn, device_id, besides))
