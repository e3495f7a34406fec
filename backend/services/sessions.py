"""A walking session as the clinic reads it: its task in words (a bench course by its name and range), the version the
leg ran by its name and by what the API calls it, and its summary; from the rows :mod:`backend.store.sessions` stores.
"""

from __future__ import annotations

import json

from sqlalchemy import Connection, RowMapping

from backend.store import sessions as store
from backend.store.versions import api_ids, version_label
from device_bridge.sim.course import COURSES


def _label(row: RowMapping) -> str | None:
    return None if row["version_id"] is None else version_label(row["kind"], row["table_patient_code"], row["version"])


def task_words(course: str | None, speed_mps: float, incline_deg: float) -> str:
    """A session's task as people read it: a bench course by its name and range, else the speed and incline."""
    walked = COURSES.get(course) if course else None
    if walked is None:
        return f"{speed_mps:.2f} m/s, incline {incline_deg:+.1f}°"
    speeds = [seg.speed_mps for seg in walked.segments]
    inclines = [seg.incline_deg for seg in walked.segments]
    slope = (f"incline {min(inclines):+.0f}° to {max(inclines):+.0f}°" if min(inclines) != max(inclines)
             else f"incline {inclines[0]:+.0f}°")
    pace = (f"{min(speeds):.2f}–{max(speeds):.2f} m/s" if min(speeds) != max(speeds)   # never "1.00–1.00 m/s"
            else f"{speeds[0]:.2f} m/s")
    return f"'{course}' course: {pace}, {slope}"


def view(row: RowMapping) -> dict:
    """The API's view of a session row (:func:`backend.store.sessions.session_row`)."""
    return {"id": row["id"], "patient_id": row["patient_id"], "patient_code": row["patient_code"],
            "device_id": row["device_id"], **api_ids(row["kind"], row["version_id"]),
            "table_label": _label(row), "course": row["course"],
            "simulated": None if row["simulated"] is None else bool(row["simulated"]),
            "task_words": task_words(row["course"], row["speed_mps"], row["incline_deg"]),
            "approval_override": row["approval_override"],
            "extrapolation_reason": row["extrapolation_reason"], "table_version": row["table_version"],
            "table_crc32": None if row["table_crc32"] is None else f"{row['table_crc32']:08x}",
            "task": {"speed_mps": row["speed_mps"], "incline_deg": row["incline_deg"],
                     "body_mass_kg": row["body_mass_kg"]},
            "status": row["status"], "started_by": row["started_by_name"], "started_at": row["started_at"],
            "stopped_by": row["stopped_by_name"], "stopped_at": row["stopped_at"],
            "summary": None if row["summary_json"] is None else json.loads(row["summary_json"])}


def get_session(conn: Connection, session_id: int) -> dict:
    return view(store.session_row(conn, session_id))


def sessions_of_patient(conn: Connection, patient_id: int) -> list[dict]:
    return [view(r) for r in store.rows_of_patient(conn, patient_id)]
