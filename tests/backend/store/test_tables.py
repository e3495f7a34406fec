"""The tables defined once (``backend.store.tables``) are the schema the migrations build."""

from __future__ import annotations

from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import CheckConstraint, create_engine, inspect

from backend.db import database_url
from backend.migrate import migrate
from backend.store.tables import metadata


def _checks(table, dialect: str = "sqlite") -> list[str]:
    """The table's checks on ``dialect`` and its columns' own (a column check is how a later revision adds a checked
    column); a check made on SQLite only (JSON's, a flag's 0/1) is not PostgreSQL's."""
    constraints = [*table.constraints, *(c for column in table.columns for c in column.constraints)]
    return sorted(" ".join(str(c.sqltext).split()) for c in constraints if isinstance(c, CheckConstraint)
                  and (c._ddl_if is None or c._ddl_if.dialect in (None, dialect)))


def test_the_migrated_database_is_the_metadata_column_for_column(database):
    """On both databases: Alembic's own comparison finds nothing, and every check is there (word for word on SQLite,
    which keeps the text; by count on PostgreSQL, which rewrites it into its own form)."""
    engine = create_engine(database_url(database))
    with engine.connect() as conn:
        context = MigrationContext.configure(conn, opts={"compare_type": True, "compare_server_default": True})
        diffs = [d for d in compare_metadata(context, metadata)
                 if not (d[0] == "remove_table" and d[1].name == "alembic_version")]
        assert diffs == []
        reflected = inspect(conn)
        assert set(reflected.get_table_names()) == set(metadata.tables) | {"alembic_version"}
        for table in metadata.sorted_tables:   # Alembic does not compare checks: reflect them
            got = sorted(" ".join(c["sqltext"].split()) for c in reflected.get_check_constraints(table.name))
            if conn.dialect.name == "sqlite":
                assert got == _checks(table), table.name
            else:
                assert len(got) == len(_checks(table, "postgresql")), (table.name, got)
    engine.dispose()


def test_a_change_to_the_metadata_would_be_seen(tmp_path):
    from sqlalchemy import Column, Integer, MetaData

    db = tmp_path / "q.sqlite"
    migrate(db)
    changed = MetaData()
    for table in metadata.sorted_tables:
        table.to_metadata(changed)
    changed.tables["patients"].append_column(Column("shoe_size", Integer))
    engine = create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        diffs = compare_metadata(MigrationContext.configure(conn), changed)
    engine.dispose()
    assert any(d[0] == "add_column" and d[3].name == "shoe_size" for d in diffs)
