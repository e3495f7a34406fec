"""The bridge's store-and-forward buffer: what the leg sends while the broker is out of reach, kept on disk in order.

While the link is down the bridge appends each message (its frames, as :mod:`device_bridge.mqtt_bus` packs them) with
the time it left the leg's bus; once the link is back it hands them over oldest first, in chunks, and forgets each chunk
only once the broker has acknowledged it (QoS 1). A bridge that restarts mid-outage finds what it held.

* **Bound**: ``max_bytes`` of payload (default 64 MiB: about four hours of a walking leg, whose telemetry is some
  4.4 kB/s). Past it the oldest messages go first and are counted in :attr:`LateBuffer.dropped`: the newest walking is
  what a clinician is likeliest to look at, and a leg's session is never held up by a full disk.
* **Storage**: one SQLite file (the standard library's; WAL, ``synchronous=NORMAL``). Appends are kept in memory and
  written every :data:`WRITE_PERIOD_S` by :meth:`write_pending` (the bridge's drain thread), so a 100 Hz stream costs a
  few transactions a second; a crash of the bridge loses at most that fraction of a second.
"""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path

DEFAULT_MAX_BYTES = 64 * 1024 * 1024
WRITE_PERIOD_S = 0.2


class LateBuffer:
    """A bounded FIFO of (time the message left the leg's bus in Unix s, payload) on disk.

    Attributes:
        dropped: messages dropped, oldest first, to keep within ``max_bytes`` (since this process opened it).
    """

    def __init__(self, path: Path | str, max_bytes: int = DEFAULT_MAX_BYTES) -> None:
        if not isinstance(max_bytes, int) or max_bytes < 1024:
            raise ValueError(f"max_bytes must be a whole number of bytes, at least 1024, got {max_bytes!r}")
        self.path, self.max_bytes = Path(path), max_bytes
        self.dropped = 0
        self._pending: list[tuple[float, bytes]] = []
        self._lock = threading.Lock()
        self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
        self._db.execute("PRAGMA journal_mode = WAL")
        self._db.execute("PRAGMA synchronous = NORMAL")
        self._db.execute("CREATE TABLE IF NOT EXISTS late (id INTEGER PRIMARY KEY, at_unix REAL NOT NULL, "
                         "payload BLOB NOT NULL)")
        self._held = int(self._db.execute("SELECT coalesce(sum(length(payload)), 0) FROM late").fetchone()[0])

    def append(self, at_unix_s: float, payload: bytes) -> None:
        """Keep one message (written to disk at the next :meth:`write_pending`)."""
        with self._lock:
            self._pending.append((at_unix_s, bytes(payload)))

    @property
    def held_bytes(self) -> int:
        """Payload bytes held, on disk and waiting to be written."""
        with self._lock:
            return self._held + sum(len(p) for _, p in self._pending)

    def __len__(self) -> int:
        with self._lock:
            return int(self._db.execute("SELECT count(*) FROM late").fetchone()[0]) + len(self._pending)

    def write_pending(self) -> None:
        """Write what :meth:`append` kept, then drop the oldest messages beyond the bound, in one transaction."""
        with self._lock:
            if not self._pending:
                return
            rows, self._pending = self._pending, []
            self._db.execute("BEGIN IMMEDIATE")
            try:
                self._db.executemany("INSERT INTO late (at_unix, payload) VALUES (?, ?)", rows)
                self._held += sum(len(p) for _, p in rows)
                while self._held > self.max_bytes:
                    oldest = self._db.execute("SELECT id, length(payload) FROM late ORDER BY id LIMIT 256").fetchall()
                    cut, freed = 0, 0
                    for row_id, size in oldest:
                        cut, freed = row_id, freed + size
                        self.dropped += 1
                        if self._held - freed <= self.max_bytes:
                            break
                    self._db.execute("DELETE FROM late WHERE id <= ?", (cut,))
                    self._held -= freed
                self._db.execute("COMMIT")
            except BaseException:
                self._db.execute("ROLLBACK")
                raise

    def oldest(self, max_payload_bytes: int) -> list[tuple[int, float, bytes]]:
        """The oldest messages on disk, (id, time, payload), up to ``max_payload_bytes`` together (at least one)."""
        with self._lock:
            out, total = [], 0
            for row_id, at, payload in self._db.execute("SELECT id, at_unix, payload FROM late ORDER BY id LIMIT 4096"):
                if out and total + len(payload) > max_payload_bytes:
                    break
                out.append((int(row_id), float(at), bytes(payload)))
                total += len(payload)
            return out

    def forget_through(self, row_id: int) -> None:
        """The messages up to ``row_id`` were delivered: remove them."""
        with self._lock:
            freed = self._db.execute("SELECT coalesce(sum(length(payload)), 0) FROM late WHERE id <= ?",
                                     (row_id,)).fetchone()[0]
            self._db.execute("DELETE FROM late WHERE id <= ?", (row_id,))
            self._held -= int(freed)

    def close(self) -> None:
        self.write_pending()
        with self._lock:
            self._db.close()
