"""SQLite connections and transactions.

Every connection: WAL journal, ``synchronous=FULL`` (an acknowledged write is on disk), foreign keys on,
a busy timeout, and Python's implicit transactions off — writes go through :func:`write_transaction`,
which takes the write lock up front with ``BEGIN IMMEDIATE`` so two writers never deadlock half-way.

Writers queue on a lock before ``BEGIN IMMEDIATE``: SQLite's busy handler sleeps with back-off (1, 2, 5, …
up to 100 ms a try), which under concurrent writers turns into idle cores and long tails, while a lock hands
over as soon as it is released. Within a process that is a per-file ``threading.Lock``; across processes
(``quasitune serve --workers N``, a CLI command beside a running server) an exclusive ``flock`` on a sidecar
file ``<database>.writelock``. With two server processes under the load benchmark the busy-handler sleeps
left about 40 % of the two cores idle. A process that does not use this module still meets the busy
timeout, as before: the lock only orders writers that cooperate, SQLite's own locking still guards the file.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import sqlite3
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

BUSY_TIMEOUT_MS = 10_000

_write_locks: dict[str, threading.Lock] = {}
_lock_files: dict[tuple[int, str], int] = {}     # (pid, database path) → open sidecar file descriptor
_registry_lock = threading.Lock()


def database_path(conn: sqlite3.Connection) -> str:
    """The file ``conn`` has open, as SQLite names it (the key of the write locks; "" when in memory)."""
    return conn.execute("PRAGMA database_list").fetchone()[2]


def _write_lock(path: str) -> threading.Lock:
    with _registry_lock:
        return _write_locks.setdefault(path, threading.Lock())


def _lock_file(path: str) -> int | None:
    """This process's descriptor of ``<path>.writelock`` (None for an in-memory database). Keyed by pid: a
    forked child must open its own, because ``flock`` belongs to the open file, which a fork shares."""
    if not path:
        return None
    key = (os.getpid(), path)
    with _registry_lock:
        fd = _lock_files.get(key)
        if fd is None:
            fd = _lock_files[key] = os.open(path + ".writelock", os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
        return fd


def _try_flock(fd: int) -> bool:
    """Take the exclusive ``flock`` on ``fd`` if no other process holds it; False (not taken) otherwise."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


def try_write_lock(path: str) -> Callable[[], None] | None:
    """Take this process's write lock and the cross-process ``flock`` for the database at ``path`` (as
    :func:`database_path` gives it) without waiting.

    Returns the function that releases both, or None (holding nothing) when another writer holds either. For a
    caller that must not block while it waits, such as the event loop (``backend/group_commit.py``); it then
    runs its transaction with ``write_transaction(conn, locked=True)``.
    """
    lock = _write_lock(path)
    if not lock.acquire(blocking=False):
        return None
    fd = _lock_file(path)
    if fd is None:
        return lock.release
    if not _try_flock(fd):
        lock.release()
        return None

    def release() -> None:
        fcntl.flock(fd, fcntl.LOCK_UN)
        lock.release()
    return release


@contextmanager
def _exclusive(conn: sqlite3.Connection) -> Iterator[None]:
    """Hold this process's per-file lock, then the cross-process ``flock``, for one write transaction."""
    path = database_path(conn)
    with _write_lock(path):
        fd = _lock_file(path)
        if fd is None:
            yield
            return
        _flock_within_busy_timeout(fd, path)
        try:
            yield
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)


def _flock_within_busy_timeout(fd: int, path: str) -> None:
    """Take the exclusive ``flock``, polling every 0.2 ms, and fail like SQLite after the busy timeout
    (a blocking ``flock`` has no timeout: a hung writer would hang every other one silently)."""
    deadline = time.monotonic() + BUSY_TIMEOUT_MS / 1000
    while not _try_flock(fd):
        if time.monotonic() > deadline:
            raise sqlite3.OperationalError(
                f"database is locked: another process has been writing to {path} for more than "
                f"{BUSY_TIMEOUT_MS / 1000:g} s")
        time.sleep(0.0002)


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
def write_transaction(conn: sqlite3.Connection, locked: bool = False) -> Iterator[sqlite3.Connection]:
    """``BEGIN IMMEDIATE`` … ``COMMIT``; any exception, the COMMIT's own included (a deferred constraint, a
    full disk), rolls everything back and propagates. ``locked``: the caller already holds the write locks
    (:func:`try_write_lock`)."""
    with contextlib.nullcontext() if locked else _exclusive(conn):
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
