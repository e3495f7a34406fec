"""Bring a database to the newest schema with Alembic (revisions in ``migrations/versions/``).

* Run once before the API starts: ``quasitune db upgrade``; ``quasitune serve`` and ``create_app`` on the embedded
  SQLite file do it themselves. On PostgreSQL the API instances do not migrate: they refuse to start on a database
  that is not at this QuasiTune's revision (:func:`require_current`), so the one-shot migration runs first.
* The whole upgrade is one transaction (``BEGIN IMMEDIATE`` on SQLite; DDL is transactional on both databases): a
  revision that fails leaves nothing behind. Processes migrating at once queue: on SQLite on an exclusive lock of a
  file beside the database (``fcntl``), on PostgreSQL on a transaction-level advisory lock; one upgrades and the others
  find the work done.
* A database made by the hand-written migrations 0001-0012 (``schema_version`` holding all twelve, each file's sha256
  as shipped in ``migrations/before_alembic/``) is the baseline's schema: it is stamped at revision ``0012`` in the
  same transaction that drops ``schema_version``, every row kept. One made by an older release, or whose migrations
  differ from the shipped ones, is refused with what to do.
"""

from __future__ import annotations

import fcntl
import hashlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, Engine, create_engine, event, inspect, text

from backend.db import BUSY_TIMEOUT_MS, connect, database_url, open_engine, sqlite_file
from backend.settings import default_migrations_dir

MIGRATIONS_DIR = default_migrations_dir()
BASELINE = "0012"            # the revision equal to what the hand-written migrations built
ADVISORY_LOCK_KEY = 0x5155_4D49   # "QUMI": PostgreSQL's advisory lock id held by the migrating process
LEGACY_DIR_NAME = "before_alembic"


class MigrationError(RuntimeError):
    """The database's schema history and this QuasiTune's revisions disagree."""


def sqlite_engine(db_path: str | Path) -> Engine:
    """An engine on the SQLite file whose transactions begin with ``BEGIN IMMEDIATE`` (SQLAlchemy's documented recipe:
    the driver's own transaction handling off, SQLAlchemy's ``begin`` emitting the statement)."""
    engine = create_engine(f"sqlite:///{db_path}", connect_args={"timeout": BUSY_TIMEOUT_MS / 1000})

    @event.listens_for(engine, "connect")
    def _no_driver_transactions(dbapi_connection, _record) -> None:
        dbapi_connection.isolation_level = None

    @event.listens_for(engine, "begin")
    def _begin_immediate(conn: Connection) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE")

    return engine


def alembic_config(directory: Path = MIGRATIONS_DIR) -> Config:
    """Alembic's configuration for the revisions in ``directory`` (no ``alembic.ini`` needed)."""
    if not (directory / "env.py").is_file():
        raise MigrationError(f"migrations folder {directory} not found (no env.py); set QUASITUNE_MIGRATIONS_DIR")
    cfg = Config()
    cfg.set_main_option("script_location", str(directory))
    return cfg


def head(directory: Path = MIGRATIONS_DIR) -> str:
    """The newest revision in ``directory``."""
    heads = ScriptDirectory.from_config(alembic_config(directory)).get_heads()
    if len(heads) != 1:
        raise MigrationError(f"the revisions in {directory} have {len(heads)} heads; merge them into one")
    return heads[0]


@contextmanager
def _exclusive(db_path: Path) -> Iterator[None]:
    """One migrating process at a time for this database file."""
    with open(db_path.with_name(db_path.name + ".migrate-lock"), "a+") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _legacy_sha256s(directory: Path) -> dict[int, str]:
    legacy = directory / LEGACY_DIR_NAME
    return {int(p.name[:4]): hashlib.sha256(p.read_text(encoding="utf-8").encode()).hexdigest()
            for p in sorted(legacy.glob("*.sql"))}


def _stamp_legacy(conn: Connection, directory: Path, script: ScriptDirectory) -> None:
    """Stamp a database of the hand-written migrations at the baseline (module docstring); others are left alone."""
    if "schema_version" not in inspect(conn).get_table_names():
        return
    recorded = {int(v): s for v, s in conn.execute(text("SELECT version, sha256 FROM schema_version"))}
    shipped = _legacy_sha256s(directory)
    if set(recorded) != set(shipped):
        missing = sorted(set(shipped) - set(recorded))
        raise MigrationError(f"this database has the hand-written schema versions {sorted(recorded)}, not 1-"
                             f"{max(shipped)}: open it once with QuasiTune 0.1 (which applies {missing}), then here")
    changed = sorted(v for v in shipped if recorded[v] != shipped[v])
    if changed:
        raise MigrationError(f"this database's migrations {changed} differ from the ones QuasiTune shipped; its schema "
                             "is not the baseline's, and it is not upgraded")
    conn.execute(text("DROP TABLE schema_version"))
    MigrationContext.configure(conn).stamp(script, BASELINE)


def migrate(target: str | Path, directory: Path = MIGRATIONS_DIR, to: str = "head") -> list[str]:
    """Bring the database at ``target`` (an SQLite file, created if missing, or a URL) to the newest revision (or to
    revision ``to``: the tests of a revision's data migration); returns the revisions applied by this call, oldest
    first (a stamped baseline is not among them: nothing was applied)."""
    cfg = alembic_config(directory)
    script = ScriptDirectory.from_config(cfg)
    db_path = sqlite_file(target)
    if db_path is not None:
        with _exclusive(db_path):
            connect(db_path).close()          # the file in WAL mode with the project's pragmas, as the app opens it
            engine = sqlite_engine(db_path)
            try:
                before, after = _upgrade(engine, cfg, directory, script, to)
            finally:
                engine.dispose()
    else:
        engine = create_engine(database_url(target))

        @event.listens_for(engine, "begin")
        def _one_migrator(conn: Connection) -> None:   # held to the transaction's end: migrators queue here
            conn.exec_driver_sql(f"SELECT pg_advisory_xact_lock({ADVISORY_LOCK_KEY})")

        try:
            before, after = _upgrade(engine, cfg, directory, script, to)
        finally:
            engine.dispose()
    if after is None or script.get_revision(after) is None:
        raise MigrationError(f"the database is at revision {after!r}, which this QuasiTune does not know: it was "
                             "written by a newer version")
    chain = [rev.revision for rev in script.iterate_revisions(after, before)]
    return list(reversed(chain))


def _upgrade(engine: Engine, cfg: Config, directory: Path, script: ScriptDirectory, to: str
             ) -> tuple[str | None, str | None]:
    """(revision before, revision after) of one upgrade to ``to``, in one transaction."""
    with engine.begin() as conn:
        _stamp_legacy(conn, directory, script)
    with engine.connect() as conn:
        before = MigrationContext.configure(conn).get_current_revision()
        cfg.attributes["connection"] = conn
        command.upgrade(cfg, to)
        conn.commit()
        after = MigrationContext.configure(conn).get_current_revision()
    return before, after


def require_current(target: str | Path, directory: Path = MIGRATIONS_DIR) -> None:
    """Refuse (MigrationError, saying what to run) a database that is not at this QuasiTune's newest revision: an API
    instance on a server database never migrates it itself."""
    engine = open_engine(target, pooled=False)
    try:
        with engine.connect() as conn:
            current = MigrationContext.configure(conn).get_current_revision()
    finally:
        engine.dispose()
    newest = head(directory)
    if current != newest:
        raise MigrationError(f"the database is at revision {current or 'none (empty)'}, this QuasiTune needs {newest}: "
                             "run 'quasitune db upgrade' once (the one-shot migration service in docker-compose.yml) "
                             "before starting the API instances")


def schema_version(conn: Connection) -> int:
    """The database's revision as a number (revisions are numbered ``NNNN``; 0 for an empty database)."""
    current = MigrationContext.configure(conn).get_current_revision()
    return int(current) if current else 0
