"""Group commit: the writes of requests that are ready together share one SQLite transaction and one fsync.

Why: with ``synchronous=FULL`` every COMMIT waits for an fsync of the write-ahead log before the request is
answered. Under the load benchmark that wait and its bookkeeping were about an eighth of a proposal's cost
(the same server with ``synchronous=NORMAL``, which skips the fsync and is not durable against power loss, did
12 % more proposals per second). Group commit keeps every acknowledged write on disk and pays the fsync once
per group instead of once per request.

How: a request hands its write (a function of a connection, run inside the transaction) to
:meth:`GroupCommitter.run` and awaits the result. The first write to arrive schedules a flush at the end of
the event loop's current round (``call_soon``), so the requests that are ready in the same round add their
writes before it runs. The flush runs them in one ``BEGIN IMMEDIATE`` transaction (:func:`write_transaction`,
so writers in other threads and processes still queue on the same locks), each inside its own SAVEPOINT: a
write that raises is rolled back alone and its request gets the exception, the others go on. Every request is
answered only after the COMMIT has returned; if the COMMIT fails, every write of the group fails and nothing
of any of them is stored.

The flush takes the write locks (this process's, then the cross-process ``flock``: ``backend/db.py``) without
waiting. When another writer holds them it looks again every :data:`LOCK_POLL_S` and leaves the loop free
meanwhile, to compute the next proposals, whose writes join the waiting group; after the busy timeout the
waiting writes fail with "database is locked" and nothing of them is stored. Blocking on the lock instead
left a worker idle for about 8 % of a load-benchmark run while the other process committed.

The committer belongs to one event loop and is used only from it (it is not thread-safe); its writes run on
the loop, like the proposal computation that precedes them.
"""

from __future__ import annotations

import asyncio
import sqlite3
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from backend.db import BUSY_TIMEOUT_MS, database_path, try_write_lock, write_transaction
from backend.pool import ConnectionPool

T = TypeVar("T")
MAX_GROUP = 64      # writes per transaction at most: bounds how long one flush holds the loop and the lock
LOCK_POLL_S = 0.0002   # how often a flush that found the write lock taken looks again


@dataclass
class GroupStats:
    """What the committer has done: transactions run (committed or failed) and the writes in them."""

    groups: int = 0
    writes: int = 0
    largest_group: int = 0

    def add(self, size: int) -> None:
        self.groups += 1
        self.writes += size
        self.largest_group = max(self.largest_group, size)


class GroupCommitter:
    """Runs writes handed to :meth:`run` in shared transactions, one savepoint per write."""

    def __init__(self, pool: ConnectionPool, max_group: int = MAX_GROUP) -> None:
        if max_group < 1:
            raise ValueError(f"max_group must be at least 1, got {max_group}")
        self.pool = pool
        self.max_group = max_group
        self.stats_ = GroupStats()
        self._pending: list[tuple[Callable[[sqlite3.Connection], Any], asyncio.Future]] = []
        self._scheduled = False
        self._lock_wait_started: float | None = None
        self._path: str | None = None            # the database file as the write locks know it, read once

    async def run(self, write: Callable[[sqlite3.Connection], T]) -> T:
        """Run ``write(conn)`` inside a write transaction shared with the other writes of this loop round;
        returns its result once the transaction has committed (raises what it raised, or the commit's error)."""
        loop = asyncio.get_running_loop()
        future: asyncio.Future = loop.create_future()
        self._pending.append((write, future))
        if not self._scheduled:
            self._scheduled = True
            loop.call_soon(self._flush)
        return await future

    def _flush(self) -> None:
        loop = asyncio.get_running_loop()
        if self._path is None:
            with self.pool.connection() as conn:
                self._path = database_path(conn)
        release = try_write_lock(self._path)
        if release is None:                      # another writer (thread or process) is committing
            self._wait_for_lock(loop)
            return
        self._lock_wait_started = None
        try:
            with self.pool.connection() as conn:
                self._commit_group(conn, loop)
        finally:
            release()

    def _wait_for_lock(self, loop: asyncio.AbstractEventLoop) -> None:
        """Look again shortly, leaving the loop free meanwhile (writes that arrive join the group); after
        the busy timeout, fail every waiting write as SQLite would."""
        now = loop.time()
        if self._lock_wait_started is None:
            self._lock_wait_started = now
        if now - self._lock_wait_started <= BUSY_TIMEOUT_MS / 1000:
            loop.call_later(LOCK_POLL_S, self._flush)
            return
        self._lock_wait_started = None
        self._scheduled = False
        waiting, self._pending = self._pending, []
        failure = sqlite3.OperationalError(f"database is locked: another writer has held it for more than "
                                           f"{BUSY_TIMEOUT_MS / 1000:g} s; nothing of this request was stored")
        for _write, future in waiting:
            if not future.done():
                future.set_exception(failure)

    def _commit_group(self, conn: sqlite3.Connection, loop: asyncio.AbstractEventLoop) -> None:
        group, self._pending = self._pending[:self.max_group], self._pending[self.max_group:]
        if self._pending:
            loop.call_soon(self._flush)
        else:
            self._scheduled = False
        group = [(write, future) for write, future in group if not future.cancelled()]   # requests gone
        if not group:
            return
        outcomes: list[tuple[asyncio.Future, bool, Any]] = []
        try:
            with write_transaction(conn, locked=True):
                for write, future in group:
                    conn.execute("SAVEPOINT request")
                    try:
                        result = write(conn)
                    except Exception as exc:
                        conn.execute("ROLLBACK TO request")
                        conn.execute("RELEASE request")
                        outcomes.append((future, False, exc))
                    else:
                        conn.execute("RELEASE request")
                        outcomes.append((future, True, result))
        except BaseException as exc:      # BEGIN or COMMIT failed, or a write was interrupted: nothing stored
            failure = exc if isinstance(exc, Exception) else RuntimeError(
                f"the group commit was interrupted ({exc!r}); nothing of this request was stored")
            for _write, future in group:
                if not future.done():
                    future.set_exception(failure)
            if failure is not exc:
                raise                      # SystemExit, KeyboardInterrupt …: after every request has its answer
            return
        finally:
            self.stats_.add(len(group))
        for future, ok, value in outcomes:
            if future.done():
                continue
            if ok:
                future.set_result(value)
            else:
                future.set_exception(value)
