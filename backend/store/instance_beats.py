"""Each API instance's heartbeat (``instance_beats``, revision 0017): written every :data:`BEAT_PERIOD_S` while the
instance serves; one silent for :data:`DEAD_AFTER_S` is dead to the others (its unfinished pushes no longer block
theirs, ``backend.store.pushes``)."""

from __future__ import annotations

import time

from sqlalchemy import Connection, and_, exists, not_, select
from sqlalchemy.sql.elements import ColumnElement

from backend.db import write_transaction
from backend.store.dialect import dialect_insert
from backend.store.tables import instance_beats

BEAT_PERIOD_S = 2.0
DEAD_AFTER_S = 10.0     # five beats missed: an instance starved that long has failed its legs' heartbeats long since


def beat(conn: Connection, name: str, at_unix: float | None = None) -> None:
    """Instance ``name`` is alive now (or at ``at_unix``)."""
    at = time.time() if at_unix is None else at_unix
    with write_transaction(conn):
        conn.execute(dialect_insert(conn, instance_beats).values(name=name, beat_at_unix=at).on_conflict_do_update(
            index_elements=["name"], set_={"beat_at_unix": at}))


def is_dead(name_column: ColumnElement, now_unix: float | None = None) -> ColumnElement:
    """SQL: the instance named in ``name_column`` has not beaten within :data:`DEAD_AFTER_S` (or never has)."""
    now = time.time() if now_unix is None else now_unix
    return not_(exists(select(instance_beats.c.name).where(and_(
        instance_beats.c.name == name_column, instance_beats.c.beat_at_unix >= now - DEAD_AFTER_S))))
