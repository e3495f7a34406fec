"""Table pushes in SQLite (migrations 0002, 0004).

A push row is written before anything goes on the bus (status ``sending``) and finished afterwards
(``acknowledged`` with the CRC the device read back, or ``failed`` with the reason); ``active`` is set only when
the device's own status reports that version and CRC running. The version is the device's own counter
(:func:`backend.store.devices.next_wire_version`); a table is named to people as "patient code · table vN",
N being the proposal's version for that patient (:func:`backend.store.proposals.table_label`).
"""

from __future__ import annotations

import sqlite3

from backend.db import utc_now, write_transaction
from backend.errors import NotFoundError
from backend.store import audit, devices
from backend.store.proposals import table_label
from backend.store.users import User

_PUSH_SELECT = ("SELECT pu.*, u.username AS requested_by_name, pr.version AS proposal_version, pr.patient_id, "
                "pa.code_name AS patient_code, pr.speed_mps, pr.incline_deg FROM pushes pu "
                "JOIN users u ON u.id = pu.requested_by JOIN proposals pr ON pr.id = pu.proposal_id "
                "JOIN patients pa ON pa.id = pr.patient_id")


def _push(row: sqlite3.Row) -> dict:
    return {"id": row["id"], "proposal_id": row["proposal_id"], "device_id": row["device_id"],
            "patient_id": row["patient_id"], "patient_code": row["patient_code"],
            "proposal_version": row["proposal_version"],
            "table_label": table_label(row["patient_code"], row["proposal_version"]),
            "task": {"speed_mps": row["speed_mps"], "incline_deg": row["incline_deg"]},
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


def begin_push(conn: sqlite3.Connection, proposal_id: int, device_id: str, crc32: int,
               actor: User) -> tuple[int, int]:
    """Record a push about to be sent (``sending``) under the device's next table version, and audit it;
    returns (push id, version)."""
    with write_transaction(conn):
        version = devices.next_wire_version(conn, device_id)
        cur = conn.execute(
            "INSERT INTO pushes (proposal_id, device_id, table_version, crc32, status, requested_by, requested_at) "
            "VALUES (?, ?, ?, ?, 'sending', ?, ?)", (proposal_id, device_id, version, crc32, actor.id, utc_now()))
        push_id = int(cur.lastrowid)
        audit.record(conn, actor.id, actor.username, "proposal.push", "proposal", proposal_id,
                     after={"push_id": push_id, "device_id": device_id, "table_version": version,
                            "crc32": f"{crc32:08x}"})
    return push_id, version


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
        if row is not None:     # older pushes the device acknowledged but never ran were overwritten by this one
            stale = conn.execute("SELECT id, proposal_id FROM pushes WHERE device_id = ? AND status = 'acknowledged' "
                                 "AND id < ?", (device_id, row["id"])).fetchall()
            for o in stale:
                conn.execute("UPDATE pushes SET status = 'superseded', ended_at = ? WHERE id = ?", (now, o["id"]))
                changed.append(o["proposal_id"])
    return changed


def push_of_version(conn: sqlite3.Connection, device_id: str, version: int | None,
                    crc32: int | None = None) -> dict | None:
    """The newest push of this table version (and CRC, when given) to the device: what its status reports
    running or waiting for heel strike. None for no version, or a table this server never sent."""
    if version is None:
        return None
    sql, args = " WHERE pu.device_id = ? AND pu.table_version = ?", [device_id, version]
    if crc32 is not None:
        sql, args = sql + " AND pu.crc32 = ?", [*args, crc32]
    row = conn.execute(_PUSH_SELECT + sql + " ORDER BY pu.id DESC LIMIT 1", args).fetchone()
    return None if row is None else _push(row)


def current_push(conn: sqlite3.Connection, device_id: str) -> dict | None:
    """The table the device runs or will run from its next heel strike: its newest push that is ``active`` or
    ``acknowledged`` (a CRC read back but no status frame reporting it yet)."""
    row = conn.execute(_PUSH_SELECT + " WHERE pu.device_id = ? AND pu.status IN ('active', 'acknowledged') "
                       "ORDER BY pu.id DESC LIMIT 1", (device_id,)).fetchone()
    return None if row is None else _push(row)


def deployment_state(conn: sqlite3.Connection, proposal_id: int) -> str | None:
    """``active_on_device`` / ``pushed`` (on its way: sent or read back, not yet running) / ``replaced`` (ran or
    was sent, then another table took its place) / ``push_failed`` / None (never pushed), from its pushes."""
    statuses = {r[0] for r in conn.execute("SELECT status FROM pushes WHERE proposal_id = ?", (proposal_id,))}
    if "active" in statuses:
        return "active_on_device"
    if statuses & {"acknowledged", "sending"}:
        return "pushed"
    if "superseded" in statuses:
        return "replaced"
    return "push_failed" if statuses else None
