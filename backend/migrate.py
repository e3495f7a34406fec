"""Apply the numbered SQL files in ``migrations/`` once each, in order, recording them in ``schema_version``.

Safe when two processes start at once: each migration runs in a ``BEGIN IMMEDIATE`` transaction that first
re-reads ``schema_version``, so the second process waits for the first and then finds the work done. A
recorded migration whose file changed since it was applied is refused (its sha256 no longer matches).
"""

from __future__ import annotations

import hashlib
import re
import sqlite3
from dataclasses import dataclass
from pathlib import Path

from backend.db import connect, utc_now, write_transaction
from backend.settings import default_migrations_dir

# the repository's migrations/ (Settings.migrations_dir, QUASITUNE_MIGRATIONS_DIR, names another copy)
MIGRATIONS_DIR = default_migrations_dir()
_NAME = re.compile(r"^(\d{4})_[a-z0-9_]+\.sql$")


class MigrationError(RuntimeError):
    """The migrations on disk and those recorded in the database disagree."""


@dataclass(frozen=True)
class Migration:
    version: int
    name: str
    sql: str

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.sql.encode()).hexdigest()


def discover(directory: Path = MIGRATIONS_DIR) -> list[Migration]:
    """Migrations in ``directory`` sorted by number; numbers must be unique and start at 1 without gaps."""
    found = []
    for path in sorted(directory.glob("*.sql")):
        m = _NAME.match(path.name)
        if not m:
            raise MigrationError(f"migration file name {path.name!r} is not NNNN_name.sql")
        found.append(Migration(int(m.group(1)), path.name, path.read_text(encoding="utf-8")))
    numbers = [m.version for m in found]
    if numbers != list(range(1, len(found) + 1)):
        raise MigrationError(f"migration numbers must run 1, 2, 3 … without gaps; found {numbers}")
    return found


def statements(sql: str) -> list[str]:
    """Split a script into complete statements (trigger bodies with inner ``;`` stay whole)."""
    out, buf = [], ""
    for line in sql.splitlines(keepends=True):
        stripped = line.strip()
        if not buf and (not stripped or stripped.startswith("--")):
            continue
        buf += line
        if sqlite3.complete_statement(buf):
            out.append(buf.strip())
            buf = ""
    if buf.strip():
        raise MigrationError(f"incomplete SQL statement at the end of a migration: {buf.strip()[:80]!r}")
    return out


def _applied(conn: sqlite3.Connection) -> dict[int, str]:
    return {r["version"]: r["sha256"] for r in conn.execute("SELECT version, sha256 FROM schema_version")}


def migrate(db_path: str | Path, directory: Path = MIGRATIONS_DIR) -> list[int]:
    """Bring the database at ``db_path`` up to date; returns the versions applied by this call."""
    if not directory.is_dir():
        raise MigrationError(f"migrations folder {directory} not found; set QUASITUNE_MIGRATIONS_DIR")
    migrations = discover(directory)
    conn = connect(db_path)
    try:
        conn.execute("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER PRIMARY KEY, name TEXT NOT NULL, "
                     "sha256 TEXT NOT NULL, applied_at TEXT NOT NULL)")
        done: list[int] = []
        for mig in migrations:
            with write_transaction(conn):
                applied = _applied(conn)
                if mig.version in applied:
                    if applied[mig.version] != mig.sha256:
                        raise MigrationError(f"migration {mig.name} changed after it was applied; add a new "
                                             "migration instead of editing a shipped one")
                    continue
                for stmt in statements(mig.sql):
                    conn.execute(stmt)
                conn.execute("INSERT INTO schema_version (version, name, sha256, applied_at) VALUES (?, ?, ?, ?)",
                             (mig.version, mig.name, mig.sha256, utc_now()))
                done.append(mig.version)
        unknown = sorted(set(_applied(conn)) - {m.version for m in migrations})
        if unknown:
            raise MigrationError(f"the database has schema versions {unknown} that this QuasiTune does not know; "
                                 "it was written by a newer version")
        return done
    finally:
        conn.close()


def schema_version(conn: sqlite3.Connection) -> int:
    """Highest applied migration number (0 for an empty database)."""
    row = conn.execute("SELECT max(version) AS v FROM schema_version").fetchone()
    return int(row["v"] or 0)
