"""Alembic's environment for QuasiTune: the tables of ``backend.store.tables``, one transaction per run.

``backend.migrate`` hands over an open connection (``config.attributes["connection"]``); the ``alembic`` command line
(``alembic.ini``) opens ``QUASITUNE_DATABASE_URL`` or the SQLite file of the data directory instead. On SQLite the
whole upgrade runs in one transaction (SQLite's DDL is transactional), so a failing revision leaves nothing behind.
"""

from __future__ import annotations

from alembic import context
from sqlalchemy import create_engine

from backend.store.tables import metadata


def _run(connection) -> None:
    context.configure(connection=connection, target_metadata=metadata, transactional_ddl=True,
                      render_as_batch=connection.dialect.name == "sqlite", compare_type=True)
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    given = context.config.attributes.get("connection")
    if given is not None:
        _run(given)
        return
    from backend.db import database_url
    from backend.settings import Settings

    engine = create_engine(database_url(Settings().database))
    with engine.connect() as connection:
        _run(connection)


if context.is_offline_mode():
    raise SystemExit("QuasiTune's migrations run against a database (no --sql mode)")
run_migrations_online()
