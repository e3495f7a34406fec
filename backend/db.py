"""SQLite connections and transactions.

Every connection: WAL journal, ``synchronous=FULL`` (an acknowledged write is on disk), foreign keys on,
a busy timeout, and Python's implicit transactions off — writes go through :func:`write_transaction`,
which takes the write lock up front with ``BEGIN IMMEDIATE`` so two writers never deadlock half-way.

Writers in one process also queue on a per-file ``threading.Lock`` before ``BEGIN IMMEDIATE``: SQLite's busy
handler sleeps with back-off (up to 100 ms a try), which under many concurrent request threads turns into
second-long tails; a lock hands over in microseconds. Other processes still meet the busy timeout.
"""

from __future__ import annotations

import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

BUSY_TIMEOUT_MS = 10_000

_write_locks: dict[str, threading.Lock] = {}
_registry_lock = threading.Lock()


def _write_lock(conn: sqlite3.Connection) -> threading.Lock:
    path = conn.execute("PRAGMA database_list").fetchone()[2]
    with _registry_lock:
        return _write_locks.setdefault(path, threading.Lock())


def connect(path: str | Path) -> sqlite3.Connection:
    """Open the database with the project's pragmas (rows behave like mappings)."""
    conn = sqlite3.connect(str(path), timeout=BUSY_TIMEOUT_MS / 1000, isolation_level=None,
                           check_same_thread=False)
    conn.row_factory = sqlite3.Row
    conn.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
    _enable_wal(conn)
    conn.execute("PRAGMA synchronous = FULL")
    conn.execute("PRAGMA foreign_keys = ON")
    return conn


def _enable_wal(conn: sqlite3.Connection) -> None:
    """Switch to WAL once per file. Switching takes an exclusive lock and, on a brand-new file, SQLite does
    not run the busy handler for it, so processes starting together retry here until the busy timeout."""
    deadline = time.monotonic() + BUSY_TIMEOUT_MS / 1000
    while True:
        try:
            if conn.execute("PRAGMA journal_mode").fetchone()[0].lower() != "wal":
                conn.execute("PRAGMA journal_mode = WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.005)


@contextmanager
def write_transaction(conn: sqlite3.Connection) -> Iterator[sqlite3.Connection]:
    """``BEGIN IMMEDIATE`` … ``COMMIT``; any exception rolls everything back and propagates."""
    with _write_lock(conn):
        conn.execute("BEGIN IMMEDIATE")
        try:
            yield conn
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        conn.execute("COMMIT")


def utc_now() -> str:
    """Current UTC time as ISO-8601 text with a ``Z`` suffix (millisecond resolution)."""
    return datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")
