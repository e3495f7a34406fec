"""Database engines, connections and write transactions: SQLite (the embedded default) or PostgreSQL, one code path.

The store speaks SQLAlchemy Core to a :class:`sqlalchemy.Connection`. Connections run in the driver's autocommit mode:
a read is one statement and holds nothing afterwards; every write goes through :func:`write_transaction`, which opens
the transaction itself and commits or rolls back as a whole.

* **SQLite**: WAL journal, ``synchronous=NORMAL``, foreign keys on, a busy timeout. ``BEGIN IMMEDIATE`` takes the
  write lock up front, so two writers never deadlock half-way and a read made inside the transaction is still true at
  its commit (writers are serialised); SQLite's busy timeout queues them. In WAL mode NORMAL keeps every committed
  transaction across a crash of the process (SIGKILL included); only a power loss can undo the last commits.
* **PostgreSQL** (psycopg 3): ``BEGIN`` at READ COMMITTED. Where a decision rests on a row read first (a version's
  status, a device's counter, the next version number) the store locks that row (``SELECT … FOR UPDATE``, rendered
  only where the database has it) or makes the write conditional and checks its row count.

Transaction control is the one place with statements written out (``BEGIN IMMEDIATE`` is SQLite's): SQLAlchemy's
pysqlite recipe for a real ``BEGIN`` does the same, and its own ``begin()`` cannot say IMMEDIATE.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

from sqlalchemy import Connection, Engine, create_engine, event
from sqlalchemy.engine import make_url
from sqlalchemy.pool import NullPool

BUSY_TIMEOUT_MS = 10_000


def database_url(target: str | Path) -> str:
    """SQLAlchemy's URL for ``target``: a URL as given (``postgresql+psycopg://…``, ``sqlite:///…``), or a file path
    for SQLite."""
    text = str(target)
    if "://" in text:
        url = make_url(text)
        if url.get_backend_name() not in ("sqlite", "postgresql"):
            raise ValueError(f"QuasiTune stores its data in SQLite or PostgreSQL, not {url.get_backend_name()!r} "
                             f"({url.render_as_string(hide_password=True)})")
        if url.get_backend_name() == "postgresql" and url.drivername != "postgresql+psycopg":
            url = url.set(drivername="postgresql+psycopg")   # psycopg 3, whatever driver the URL named
        return url.render_as_string(hide_password=False)
    return f"sqlite:///{Path(text)}"


def sqlite_file(target: str | Path) -> Path | None:
    """The SQLite file ``target`` names (a path or a ``sqlite:///`` URL), or None for a server database."""
    url = make_url(database_url(target))
    return Path(url.database) if url.get_backend_name() == "sqlite" else None


def open_engine(target: str | Path, keep: int = 16, pooled: bool = True) -> Engine:
    """An engine on ``target`` (:func:`database_url`) in autocommit mode, its connections with the project's settings.

    ``keep``: idle connections kept in the pool (more are opened on demand on SQLite; on PostgreSQL up to ``keep`` more,
    then requests wait). Why a pool: when the last connection to a WAL database closes, SQLite checkpoints the log and
    deletes it with an fsync, and a PostgreSQL connection costs a process fork; per request that was most of a
    request's time (``python -m benchmarks api``). ``pooled=False``: a connection per :meth:`Engine.connect`
    (command-line tools, tests).
    """
    url = database_url(target)
    pool_args: dict = {} if pooled else {"poolclass": NullPool}
    if url.startswith("sqlite"):
        if pooled:
            pool_args = {"pool_size": keep, "max_overflow": -1}
        engine = create_engine(url, isolation_level="AUTOCOMMIT", connect_args={
            "timeout": BUSY_TIMEOUT_MS / 1000, "check_same_thread": False}, **pool_args)
        event.listen(engine, "connect", sqlite_pragmas)
    else:
        if pooled:
            pool_args = {"pool_size": keep, "max_overflow": keep, "pool_pre_ping": True}
        engine = create_engine(url, isolation_level="AUTOCOMMIT", **pool_args)
    return engine


def connect(target: str | Path) -> Connection:
    """One connection of its own on ``target`` (closing it closes the database connection): for the command line,
    start-up work and tests."""
    return open_engine(target, pooled=False).connect()


@contextmanager
def pooled(engine: Engine) -> Iterator[Connection]:
    """A connection from ``engine``'s pool for the ``with`` block, handed back afterwards (anything left open rolled
    back)."""
    with engine.connect() as conn:
        try:
            yield conn
        finally:
            if in_transaction(conn):
                conn.exec_driver_sql("ROLLBACK")


def sqlite_pragmas(dbapi_connection, _record) -> None:
    """The project's settings on a new SQLite connection (SQLAlchemy's ``connect`` event)."""
    cur = dbapi_connection.cursor()
    cur.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
    _enable_wal(cur)
    cur.execute("PRAGMA synchronous = NORMAL")
    cur.execute("PRAGMA foreign_keys = ON")
    cur.close()


def _enable_wal(cur) -> None:
    """Switch to WAL once per file. On a brand-new file SQLite does not run the busy handler for the switch,
    so a second process starting at the same moment retries here until the busy timeout."""
    import sqlite3

    deadline = time.monotonic() + BUSY_TIMEOUT_MS / 1000
    while True:
        try:
            if cur.execute("PRAGMA journal_mode").fetchone()[0].lower() != "wal":
                cur.execute("PRAGMA journal_mode = WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.005)


def in_transaction(conn: Connection) -> bool:
    """Whether the database connection under ``conn`` is inside a transaction opened by :func:`write_transaction`
    (or left open by a failed one)."""
    driver = conn.connection.dbapi_connection
    if conn.dialect.name == "sqlite":
        return bool(driver.in_transaction)
    from psycopg.pq import TransactionStatus

    return driver.info.transaction_status != TransactionStatus.IDLE


@contextmanager
def write_transaction(conn: Connection) -> Iterator[Connection]:
    """``BEGIN`` (``BEGIN IMMEDIATE`` on SQLite) … ``COMMIT``; any exception, the COMMIT's own included (a deferred
    constraint, a full disk, a serialisation failure), rolls everything back and propagates."""
    if in_transaction(conn):
        raise RuntimeError("write_transaction: a transaction is already open on this connection (they do not nest)")
    conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.dialect.name == "sqlite" else "BEGIN")
    try:
        yield conn
        conn.exec_driver_sql("COMMIT")
    except BaseException:
        if in_transaction(conn):
            conn.exec_driver_sql("ROLLBACK")
        raise


def utc_now() -> str:
    """Current UTC time as ISO-8601 text with a ``Z`` suffix (millisecond resolution)."""
    return utc_text(datetime.now(UTC))


def utc_text(at: datetime) -> str:
    """An aware time as the stored ISO-8601 text (UTC, ``Z``, milliseconds): ordered as the times are."""
    return at.astimezone(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")
