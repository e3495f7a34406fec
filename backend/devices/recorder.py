"""Recording walking sessions: telemetry samples arrive at 100 Hz on the CAN receive thread and are written to the
database by a thread of their own, every :data:`FLUSH_PERIOD_S`, each second of walking once it is complete (the store
keeps a row per second: writing a second as a whole writes its row once, where four partial writes rewrote it four
times, which on PostgreSQL leaves dead row versions behind). A second still filling is held until it is complete, or
until no sample has come for :data:`STALE_S` (a leg that stopped sending); stopping a session writes everything.
What a crash of the server can lose is the second being filled (at most about 1.25 s of samples).

Several API instances reach one leg through the broker and any of them may start or stop its session: every instance's
recorder looks, every :data:`SYNC_PERIOD_S`, for the sessions its devices have open in the database and records them
too (the store merges the instances' writes by sequence number, so each sample is stored once). A session stopped
elsewhere is dropped here without writing what is left: the stopping instance received the same samples and wrote them
before it summarised the session.

Samples the leg's bridge kept while its link was down arrive *late* (:meth:`SessionRecorder.add` with ``late=True``):
they belong to seconds long written, so they are kept apart and written at the next flush, merged into those seconds
by sequence number (the store keeps a sample it already has as it was)."""

from __future__ import annotations

import logging
import threading
from collections import Counter

from sqlalchemy import Engine

from backend.db import pooled
from backend.store import sessions as store
from backend.store.sample_pack import second_of
from backend.store.sample_pack import validate_row as pack_one
from device_bridge.clock import WALL_CLOCK, Clock

FLUSH_PERIOD_S = 0.25
SYNC_PERIOD_S = 1.0   # how often the sessions open in the database are looked up (several instances)
log = logging.getLogger(__name__)
STALE_S = 1.0     # a second still filling is written anyway once no sample has come for this long


class RecorderWriteError(RuntimeError):
    """Some sessions' samples could not be written this time (named); they are kept for the next flush."""


class SessionRecorder:
    """Buffers each device's samples for the session it records and writes them in batches."""

    def __init__(self, db: Engine, device_ids: tuple[str, ...] = (), clock: Clock = WALL_CLOCK) -> None:
        self._db = db
        self._clock = clock
        self._device_ids = tuple(device_ids)      # looked up in the database every SYNC_PERIOD_S (none: never)
        self._ended: set[int] = set()             # sessions this instance stopped: never taken up again
        self._recording: dict[str, int] = {}        # device id → session id
        self._reports: dict[str, Counter] = {}      # device id → (mode, (version, crc) or None) → status reports
        self._buffers: dict[str, list[tuple]] = {}
        self._late: dict[str, list[tuple]] = {}     # device id → late samples not yet written
        self._late_counts: dict[str, int] = {}      # device id → late samples received while recorded
        self._last_sample: dict[str, float] = {}    # device id → when its newest sample arrived (monotonic s)
        self._lock = threading.Lock()
        self._write_lock = threading.Lock()
        self.refused_samples: Counter[str] = Counter()   # per device: samples the store refused as malformed
        self._stop = threading.Event()
        self._next_sync = float("-inf")
        self._thread = threading.Thread(target=self._run, name="session-recorder", daemon=True)

    def start(self) -> SessionRecorder:
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self.flush()

    def session_of(self, device_id: str) -> int | None:
        return self._recording.get(device_id)

    def begin(self, device_id: str, session_id: int) -> None:
        with self._lock:
            if self._recording.get(device_id) == session_id:   # already taken up (from the database, or twice)
                return
            self._recording[device_id] = session_id
            self._buffers[device_id] = []
            self._late[device_id] = []
            self._late_counts[device_id] = 0
            self._reports[device_id] = Counter()

    def end(self, device_id: str) -> tuple[Counter, int]:
        """Stop recording ``device_id``; everything received so far is written before this returns. Returns what
        the device's status reports said while it was recorded, (mode, (version, CRC) or None) → how many, and how
        many of its samples arrived late."""
        self.flush()
        with self._lock:
            session_id = self._recording.get(device_id)
            if session_id is not None:
                self._ended.add(session_id)
            return self._release(device_id)

    def _release(self, device_id: str) -> tuple[Counter, int]:
        """Forget everything held for ``device_id`` (under the lock); its status reports and late-sample count."""
        self._recording.pop(device_id, None)
        for held in (self._buffers, self._late, self._last_sample):
            held.pop(device_id, None)
        return self._reports.pop(device_id, Counter()), self._late_counts.pop(device_id, 0)

    def note_status(self, device_id: str, mode: str, active: tuple[int, int] | None) -> None:
        """One status report of a device (counted only while it is recorded)."""
        with self._lock:
            reports = self._reports.get(device_id)
            if reports is not None:
                reports[(mode, active)] += 1

    def add(self, device_id: str, row: tuple, late: bool = False) -> None:
        """One sample (in :data:`backend.store.sessions.SAMPLE_COLUMNS` order), if the device is recording; ``late``:
        one its bridge kept while the link was down."""
        with self._lock:
            if late:
                buffer = self._late.get(device_id)
                if buffer is not None:
                    buffer.append(row)
                    self._late_counts[device_id] += 1
                return
            buffer = self._buffers.get(device_id)
            if buffer is not None:
                buffer.append(row)
                self._last_sample[device_id] = self._clock.monotonic()

    def flush(self, whole_seconds: bool = False) -> None:
        """Write the buffered samples (``whole_seconds``: only the seconds already complete, and a second still filling
        only once its leg has been silent for :data:`STALE_S`); a flush already writing is waited for, so nothing is
        read half-written. A write that fails (the database away for a moment) puts its samples back for the next
        flush, and raises."""
        with self._write_lock:
            with self._lock:
                batches = []
                now = self._clock.monotonic()
                for d, rows in self._buffers.items():
                    keep: list[tuple] = []
                    if whole_seconds and rows and now - self._last_sample.get(d, now) < STALE_S:
                        filling = second_of(int(rows[-1][0]))
                        keep = [r for r in rows if second_of(int(r[0])) >= filling]
                        rows = [r for r in rows if second_of(int(r[0])) < filling]
                    late, self._late[d] = self._late[d], []
                    if rows or late:
                        batches.append((d, self._recording[d], late + rows))
                    self._buffers[d] = keep
            if not batches:
                return
            # each session on its own: one leg's bad sample or failed write never holds back another's recording
            failed: list[tuple[int, BaseException]] = []
            for d, session_id, rows in batches:
                try:
                    self._write(d, session_id, rows)
                except Exception as exc:   # the database away for a moment: back in front of what arrived meanwhile
                    failed.append((session_id, exc))
                    with self._lock:       # (the store merges by sequence number)
                        if self._recording.get(d) == session_id:
                            self._late[d] = rows + self._late[d]
            if failed:
                raise RecorderWriteError(f"writing the samples of session(s) {', '.join(str(i) for i, _ in failed)} "
                                         f"failed ({failed[0][1]!r}); the others were written") from failed[0][1]

    def _write(self, device_id: str, session_id: int, rows: list[tuple]) -> None:
        """One session's batch. Samples the store refuses as malformed (ValueError naming the value: a time no leg can
        have sent) are dropped one by one and counted in :attr:`refused_samples`, so they never block the batch."""
        try:
            with pooled(self._db) as conn:
                store.add_samples(conn, session_id, rows)
            return
        except (ValueError, OverflowError):
            pass
        good = []
        for row in rows:
            try:
                pack_one(row)
                good.append(row)
            except (ValueError, OverflowError, TypeError):
                self.refused_samples[device_id] += 1
        log.warning("session %s: %d malformed sample(s) of %s refused", session_id, len(rows) - len(good), device_id)
        if good:
            with pooled(self._db) as conn:
                store.add_samples(conn, session_id, good)

    def sync(self) -> None:
        """Take up the sessions the database has open for this instance's devices (started on another instance) and
        drop those stopped elsewhere (see the module docstring)."""
        with pooled(self._db) as conn:
            open_now = store.recording_sessions(conn, self._device_ids)
        with self._lock:
            ours = dict(self._recording)
        for device_id, session_id in open_now.items():
            if ours.get(device_id) != session_id and session_id not in self._ended:
                self.begin(device_id, session_id)
        for device_id, session_id in ours.items():
            if open_now.get(device_id) != session_id:
                self._drop(device_id, session_id)

    def _drop(self, device_id: str, session_id: int) -> None:
        """Stop recording a session stopped elsewhere, writing nothing more (its stopping instance wrote it)."""
        with self._write_lock, self._lock:
            if self._recording.get(device_id) == session_id:
                self._release(device_id)

    def periodic(self) -> None:
        """One round of the recorder's thread (every :data:`FLUSH_PERIOD_S`; a stepped rig calls it at that period):
        the open sessions looked up when :data:`SYNC_PERIOD_S` has passed, then the complete seconds written."""
        if self._device_ids and self._clock.monotonic() >= self._next_sync:
            self._next_sync = self._clock.monotonic() + SYNC_PERIOD_S
            try:
                self.sync()
            except Exception:   # the database away for a moment: the next look tries again
                log.exception("session recorder: looking up the open sessions failed")
        try:
            self.flush(whole_seconds=True)
        except Exception:
            log.exception("session recorder: writing samples failed; they are written at the next flush")

    def _run(self) -> None:
        while not self._clock.wait(self._stop, FLUSH_PERIOD_S):
            self.periodic()
