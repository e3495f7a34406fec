"""Statements the tests run behind the store's back (to tamper with a row, or to read one), on either database."""

from __future__ import annotations

from sqlalchemy import Connection, text


def sql(conn: Connection, statement: str, **params):
    """One statement with named parameters (``:name``), as SQLite and PostgreSQL both take it."""
    return conn.execute(text(statement), params)


def drop_trigger(conn: Connection, name: str, table: str) -> None:
    """What a tampered database could be: one of the baseline's guarding triggers removed."""
    conn.exec_driver_sql(f"DROP TRIGGER {name}" + ("" if conn.dialect.name == "sqlite" else f" ON {table}"))
