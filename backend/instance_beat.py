"""This API instance's heartbeat in the database, so the other instances know it is alive (``instance_beats``): a push
it left ``sending`` when it died stops blocking theirs within seconds (``backend.store.pushes``). One thread, one row
written every two seconds."""

from __future__ import annotations

import logging
import threading

from sqlalchemy import Engine

from backend.db import pooled
from backend.store.instance_beats import BEAT_PERIOD_S, beat

log = logging.getLogger(__name__)


class InstanceBeat:
    """Beats for instance ``name`` from :meth:`start` (which writes the first beat before it returns) to :meth:`close`.
    A failed write is logged and tried again on the next beat: the database is the one place the others look."""

    def __init__(self, db: Engine, name: str, period_s: float = BEAT_PERIOD_S) -> None:
        self.db, self.name, self.period_s = db, name, period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"instance-beat-{name}", daemon=True)

    def beat(self) -> None:
        with pooled(self.db) as conn:
            beat(conn, self.name)

    def start(self) -> InstanceBeat:
        self.beat()
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.wait(self.period_s):
            try:
                self.beat()
            except Exception:      # the next beat tries again; the others see this instance alive meanwhile
                log.exception("instance %s: heartbeat not written", self.name)

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
