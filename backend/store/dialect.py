"""The few Core constructs that differ per database: an insert that knows ``ON CONFLICT`` (one that leaves an existing
row alone), and a field of a JSON text column.

``INSERT … ON CONFLICT (…) DO NOTHING`` is the same SQL on SQLite and PostgreSQL, but SQLAlchemy builds it from each
dialect's own ``insert``; :func:`insert_or_ignore` picks the one of the connection's database.
"""

from __future__ import annotations

from sqlalchemy import JSON, Connection, Table
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.exc import IntegrityError
from sqlalchemy.ext.compiler import compiles
from sqlalchemy.sql.functions import FunctionElement


def dialect_insert(conn: Connection, table: Table):
    """The connection's database's own ``INSERT`` on ``table``, which knows ``ON CONFLICT`` (add ``.values(...)``)."""
    return (postgresql if conn.dialect.name == "postgresql" else sqlite).insert(table)


def insert_or_ignore(conn: Connection, table: Table, key: list[str]):
    """``INSERT INTO table … ON CONFLICT (key) DO NOTHING`` for the connection's database (add ``.values(...)``)."""
    return dialect_insert(conn, table).on_conflict_do_nothing(index_elements=key)


class json_of(FunctionElement):   # noqa: N801 (a SQL function, named as SQL names them)
    """A JSON text column read as JSON, so ``json_of(column)["key"]`` reads one field in the database (SQLite's
    ``json_extract`` on the text itself; PostgreSQL's ``->`` on the text cast to ``json``). SQLite has no JSON type: a
    ``CAST(… AS JSON)`` there is a numeric cast that turns the text into 0, so SQLAlchemy's plain ``cast`` cannot be
    used on both."""

    type = JSON()
    name = "json_of"
    inherit_cache = True


@compiles(json_of, "sqlite")
def _json_of_sqlite(element: json_of, compiler, **kw) -> str:
    return compiler.process(element.clauses, **kw)


@compiles(json_of, "postgresql")
def _json_of_postgresql(element: json_of, compiler, **kw) -> str:
    return f"CAST({compiler.process(element.clauses, **kw)} AS JSON)"


def unique_violation(exc: IntegrityError, index: str, sqlite_columns: str) -> bool:
    """Whether ``exc`` is the unique index ``index`` refusing a row (PostgreSQL names the index; SQLite names its
    columns, e.g. ``pushes.device_id``)."""
    text = str(exc.orig)
    return f'"{index}"' in text if "duplicate key" in text else text == f"UNIQUE constraint failed: {sqlite_columns}"
