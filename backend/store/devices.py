"""Devices in SQLite (migration 0002): their registration and the commands sent to them."""

from __future__ import annotations

import sqlite3

from backend.db import utc_now, write_transaction
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
