"""Column types that are what they hold on each database: a time is a timestamp, a flag a boolean.

PostgreSQL stores a :class:`Timestamp` as ``timestamp with time zone`` and a :class:`Flag` as ``boolean``; SQLite has
neither type, so there a time stays ISO-8601 text (UTC, ``Z``, milliseconds: ordered as the times are) and a flag a
0/1 integer with its check, as SQLAlchemy's own ``DateTime`` and ``Boolean`` keep them there. On both, the
application reads a time as that text (:func:`backend.db.utc_text`, what the API has always answered) and a flag as a
``bool``, and writes either form; so nothing above the tables changes with the database.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import Boolean, Dialect, Integer, Text, TypeDecorator
from sqlalchemy.dialects.postgresql import TIMESTAMP
from sqlalchemy.types import TypeEngine

from backend.db import utc_text


def _postgres(dialect: Dialect) -> bool:
    return dialect.name == "postgresql"


class Timestamp(TypeDecorator[str]):
    """An instant: ``timestamp with time zone`` on PostgreSQL, ISO-8601 text on SQLite; read as that text."""

    impl = Text
    cache_ok = True

    def load_dialect_impl(self, dialect: Dialect) -> TypeEngine:
        return dialect.type_descriptor(TIMESTAMP(timezone=True) if _postgres(dialect) else Text())

    def process_bind_param(self, value: str | datetime | None, dialect: Dialect) -> object:
        if value is None or not _postgres(dialect):
            return value if not isinstance(value, datetime) else utc_text(value)
        return value if isinstance(value, datetime) else datetime.fromisoformat(value.replace("Z", "+00:00"))

    def process_result_value(self, value: object, dialect: Dialect) -> str | None:
        return utc_text(value) if isinstance(value, datetime) else value  # type: ignore[return-value]


class Flag(TypeDecorator[bool]):
    """Yes or no: ``boolean`` on PostgreSQL, a 0/1 integer on SQLite (the table keeps its ``IN (0, 1)`` check there);
    read as a ``bool``."""

    impl = Integer
    cache_ok = True

    def load_dialect_impl(self, dialect: Dialect) -> TypeEngine:
        return dialect.type_descriptor(Boolean(create_constraint=False) if _postgres(dialect) else Integer())

    def process_bind_param(self, value: bool | int | None, dialect: Dialect) -> object:
        if value is None:
            return None
        if value not in (0, 1):                  # True, False, 0 and 1 only: anything else is a bug, never stored
            raise ValueError(f"a flag is 0/1 or False/True, got {value!r}")
        return bool(value) if _postgres(dialect) else int(value)

    def process_result_value(self, value: object, dialect: Dialect) -> bool | None:
        return None if value is None else bool(value)
