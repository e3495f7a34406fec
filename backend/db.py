"""SQLite connections and write transactions.

Every connection: WAL journal, ``synchronous=NORMAL``, foreign keys on, a busy timeout, and Python's implicit
transactions off. In WAL mode NORMAL keeps every committed transaction across a crash of the process (SIGKILL
included); only a power loss can undo the last commits, and a deployment that must survive that belongs on a
server database. Writes go through :func:`write_transaction`, which takes the write lock up front with
``BEGIN IMMEDIATE`` so two writers never deadlock half-way; SQLite's busy timeout queues them.
"""

from __future__ import annotations

import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

from sqlalchemy.pool import QueuePool

BUSY_TIMEOUT_MS = 10_000


def connect(path: str | Path) -> sqlite3.Connection:
    """Open the database with the project's pragmas (rows behave like mappings)."""
    conn = sqlite3.connect(str(path), timeout=BUSY_TIMEOUT_MS / 1000, isolation_level=None,
                           check_same_thread=False)
    conn.row_factory = sqlite3.Row
    conn.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
    _enable_wal(conn)
    conn.execute("PRAGMA synchronous = NORMAL")
    conn.execute("PRAGMA foreign_keys = ON")
    return conn


def open_pool(path: str | Path, keep: int = 16) -> QueuePool:
    """SQLAlchemy's connection pool over :func:`connect` (up to ``keep`` idle connections, more opened on demand).

    Why a pool: when the last connection to a WAL database closes, SQLite checkpoints the log and deletes it,
    with an fsync; a connection per request paid that and the pragmas on every request, most of a proposal's
    server time (``python -m benchmarks api``).
    """
    return QueuePool(lambda: connect(path), pool_size=keep, max_overflow=-1, reset_on_return="rollback")


@contextmanager
def pooled(pool: QueuePool) -> Iterator[sqlite3.Connection]:
    """A connection from ``pool`` for the ``with`` block, handed back afterwards (any open transaction rolled back)."""
    fairy = pool.connect()
    try:
        yield fairy.driver_connection
    finally:
        fairy.close()


def _enable_wal(conn: sqlite3.Connection) -> None:
    """Switch to WAL once per file. On a brand-new file SQLite does not run the busy handler for the switch,
    so a second process starting at the same moment retries here until the busy timeout."""
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
    """``BEGIN IMMEDIATE`` … ``COMMIT``; any exception, the COMMIT's own included (a deferred constraint, a
    full disk), rolls everything back and propagates."""
    conn.execute("BEGIN IMMEDIATE")
    try:
        yield conn
        conn.execute("COMMIT")
    except BaseException:
        if conn.in_transaction:
            conn.execute("ROLLBACK")
        raise


def utc_now() -> str:
    """Current UTC time as ISO-8601 text with a ``Z`` suffix (millisecond resolution)."""
    return datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")
