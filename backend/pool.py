"""A small pool of SQLite connections shared by the request threads."""

from __future__ import annotations

import queue
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from backend.db import connect


class ConnectionPool:
    """Connections are created on demand and reused; one is never used by two requests at once.

    Up to ``max_idle`` are kept. A proposal request holds its connection while it waits for its group commit,
    so one process with 20 clients has 21 in use; with 16 kept, the rest were opened (pragmas, WAL check) and
    closed again on every request.
    """

    def __init__(self, path: str | Path, max_idle: int = 64) -> None:
        self.path = Path(path)
        self._idle: queue.LifoQueue[sqlite3.Connection] = queue.LifoQueue(maxsize=max_idle)

    @contextmanager
    def connection(self) -> Iterator[sqlite3.Connection]:
        try:
            conn = self._idle.get_nowait()
        except queue.Empty:
            conn = connect(self.path)
        try:
            yield conn
        finally:
            if conn.in_transaction:   # never hand on a connection with an open transaction
                conn.execute("ROLLBACK")
            try:
                self._idle.put_nowait(conn)
            except queue.Full:
                conn.close()

    def close(self) -> None:
        while True:
            try:
                self._idle.get_nowait().close()
            except queue.Empty:
                return
