"""Pushes in SQLite (migrations 0002, 0004, 0007): an approved proposal's table or an approved envelope.

A push row is written before anything goes on the bus (status ``sending``) and finished afterwards
(``acknowledged`` with the CRC the device read back, or ``failed`` with the reason); ``active`` is set only when
the device's own status reports that version and CRC running. The version is the device's own counter
(:func:`backend.store.devices.next_wire_version`); a table is named to people as "patient code · table vN",
N being the proposal's version for that patient (:func:`backend.store.proposals.table_label`), an envelope as
"patient code · envelope vN". Exactly one of ``proposal_id`` and ``envelope_id`` is set (``kind`` says which).
"""

from __future__ import annotations

import sqlite3
from typing import Literal

from backend.db import utc_now, write_transaction
from backend.errors import NotFoundError
from backend.store import audit, devices
from backend.store.envelopes import envelope_label
from backend.store.proposals import table_label
from backend.store.users import User

_PUSH_SELECT = ("SELECT pu.*, u.username AS requested_by_name, pr.version AS proposal_version, "
                "en.version AS envelope_version, coalesce(pr.patient_id, en.patient_id) AS patient_id, "
                "pa.code_name AS patient_code, "
                "coalesce(pr.speed_mps, json_extract(en.envelope_json, '$.nominal_speed_mps')) AS speed_mps, "
                "coalesce(pr.incline_deg, json_extract(en.envelope_json, '$.nominal_incline_deg')) AS incline_deg "
                "FROM pushes pu "
                "JOIN users u ON u.id = pu.requested_by LEFT JOIN proposals pr ON pr.id = pu.proposal_id "
                "LEFT JOIN envelopes en ON en.id = pu.envelope_id "
                "JOIN patients pa ON pa.id = coalesce(pr.patient_id, en.patient_id)")


def _push(row: sqlite3.Row) -> dict:
    table = row["proposal_id"] is not None
    label = (table_label(row["patient_code"], row["proposal_version"]) if table
             else envelope_label(row["patient_code"], row["envelope_version"]))
    return {"id": row["id"], "kind": "table" if table else "envelope", "proposal_id": row["proposal_id"],
            "envelope_id": row["envelope_id"], "device_id": row["device_id"],
            "patient_id": row["patient_id"], "patient_code": row["patient_code"],
            "proposal_version": row["proposal_version"], "envelope_version": row["envelope_version"],
            "label": label, "table_label": label if table else None,
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


PushedKind = Literal["proposal", "envelope"]
Pushed = tuple[PushedKind, int]      # ("proposal", id): its table; ("envelope", id): the whole envelope


def pushes_of(conn: sqlite3.Connection, item: Pushed) -> list[dict]:
    """Every push of this proposal or envelope, newest first."""
    kind, item_id = item
    rows = conn.execute(_PUSH_SELECT + f" WHERE pu.{kind}_id = ? ORDER BY pu.id DESC", (item_id,)).fetchall()
    return [_push(r) for r in rows]


def begin_push(conn: sqlite3.Connection, item: Pushed, device_id: str, crc32: int, actor: User) -> tuple[int, int]:
    """Record a push about to be sent (``sending``) under the device's next table version, and audit it;
    returns (push id, version)."""
    kind, item_id = item
    with write_transaction(conn):
        version = devices.next_wire_version(conn, device_id)
        cur = conn.execute(
            f"INSERT INTO pushes ({kind}_id, device_id, table_version, crc32, status, requested_by, requested_at) "
            "VALUES (?, ?, ?, ?, 'sending', ?, ?)", (item_id, device_id, version, crc32, actor.id, utc_now()))
        push_id = int(cur.lastrowid)
        audit.record(conn, actor.id, actor.username, f"{kind}.push", kind, item_id,
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


def _item(row: sqlite3.Row) -> Pushed:
    return ("proposal", row["proposal_id"]) if row["proposal_id"] is not None else ("envelope", row["envelope_id"])


def mark_active(conn: sqlite3.Connection, device_id: str, version: int, crc32: int) -> list[Pushed]:
    """The device reports ``version``/``crc32`` running: the newest push of exactly that table becomes ``active``
    and any other active push on the device ``superseded``. Returns what changed (``("proposal", id)`` or
    ``("envelope", id)``)."""
    now = utc_now()
    with write_transaction(conn):
        row = conn.execute("SELECT id, proposal_id, envelope_id, status FROM pushes WHERE device_id = ? AND "
                           "table_version = ? AND "
                           "crc32 = ? ORDER BY id DESC LIMIT 1", (device_id, version, crc32)).fetchone()
        old = conn.execute("SELECT id, proposal_id, envelope_id FROM pushes WHERE device_id = ? AND status = 'active'",
                           (device_id,)).fetchall()
        changed = []
        for o in old:
            if row is None or o["id"] != row["id"]:
                conn.execute("UPDATE pushes SET status = 'superseded', ended_at = ? WHERE id = ?", (now, o["id"]))
                changed.append(_item(o))
        if row is not None and row["status"] != "active":
            conn.execute("UPDATE pushes SET status = 'active', active_at = ? WHERE id = ?", (now, row["id"]))
            changed.append(_item(row))
        if row is not None:     # older pushes the device acknowledged but never ran were overwritten by this one
            stale = conn.execute("SELECT id, proposal_id, envelope_id FROM pushes WHERE device_id = ? AND "
                                 "status = 'acknowledged' "
                                 "AND id < ?", (device_id, row["id"])).fetchall()
            for o in stale:
                conn.execute("UPDATE pushes SET status = 'superseded', ended_at = ? WHERE id = ?", (now, o["id"]))
                changed.append(_item(o))
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


def deployment_state(conn: sqlite3.Connection, item: Pushed) -> str | None:
    """``active_on_device`` / ``pushed`` (on its way: sent or read back, not yet running) / ``replaced`` (ran or
    was sent, then another table took its place) / ``push_failed`` / None (never pushed), from its pushes."""
    kind, item_id = item
    statuses = {r[0] for r in conn.execute(f"SELECT status FROM pushes WHERE {kind}_id = ?", (item_id,))}
    if "active" in statuses:
        return "active_on_device"
    if statuses & {"acknowledged", "sending"}:
        return "pushed"
    if "superseded" in statuses:
        return "replaced"
    return "push_failed" if statuses else None
