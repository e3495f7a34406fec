"""The few statements whose Core construct differs per database: an insert that leaves an existing row alone.

``INSERT … ON CONFLICT (…) DO NOTHING`` is the same SQL on SQLite and PostgreSQL, but SQLAlchemy builds it from each
dialect's own ``insert``; this picks the one of the connection's database.
"""

from __future__ import annotations

from sqlalchemy import Connection, Table
from sqlalchemy.dialects import postgresql, sqlite


def insert_or_ignore(conn: Connection, table: Table, key: list[str]):
    """``INSERT INTO table … ON CONFLICT (key) DO NOTHING`` for the connection's database (add ``.values(...)``)."""
    dialect = postgresql if conn.dialect.name == "postgresql" else sqlite
    return dialect.insert(table).on_conflict_do_nothing(index_elements=key)
