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

The committer belongs to one event loop and is used only from it (it is not thread-safe); its writes run on
the loop, like the proposal computation that precedes them.
"""

from __future__ import annotations

import asyncio
import sqlite3
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from backend.db import write_transaction
from backend.pool import ConnectionPool

T = TypeVar("T")
MAX_GROUP = 64      # writes per transaction at most: bounds how long one flush holds the loop and the lock


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
        group, self._pending = self._pending[:self.max_group], self._pending[self.max_group:]
        if self._pending:
            asyncio.get_running_loop().call_soon(self._flush)
        else:
            self._scheduled = False
        group = [(write, future) for write, future in group if not future.cancelled()]   # requests gone
        if not group:
            return
        outcomes: list[tuple[asyncio.Future, bool, Any]] = []
        try:
            with self.pool.connection() as conn, write_transaction(conn):
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
