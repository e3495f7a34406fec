"""Numbered migrations applied once, whole, in order."""

from __future__ import annotations

import multiprocessing
import shutil

import pytest

from backend.db import connect
from backend.migrate import MIGRATIONS_DIR, MigrationError, discover, migrate, schema_version, statements


def _migrate_in_child(db: str, barrier) -> None:
    barrier.wait()
    migrate(db)


def test_fresh_database_gets_every_migration_once(tmp_path):
    db = tmp_path / "q.sqlite"
    applied = migrate(db)
    assert applied == [m.version for m in discover()] and applied[0] == 1
    assert migrate(db) == []
    conn = connect(db)
    rows = conn.execute("SELECT version, name, sha256 FROM schema_version ORDER BY version").fetchall()
    assert [r["version"] for r in rows] == applied
    assert schema_version(conn) == applied[-1]
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert conn.execute("PRAGMA foreign_keys").fetchone()[0] == 1
    conn.close()


def test_trigger_bodies_stay_whole_when_split():
    sql = "CREATE TABLE t (a);\n-- note\nCREATE TRIGGER x BEFORE DELETE ON t\nBEGIN\n  SELECT 1;\n  SELECT 2;\nEND;\n"
    parts = statements(sql)
    assert len(parts) == 2 and parts[1].startswith("CREATE TRIGGER") and parts[1].endswith("END;")
    with pytest.raises(MigrationError, match="incomplete"):
        statements("CREATE TABLE t (a")


def test_a_changed_shipped_migration_is_refused(tmp_path):
    mig = tmp_path / "migrations"
    shutil.copytree(MIGRATIONS_DIR, mig)
    db = tmp_path / "q.sqlite"
    migrate(db, mig)
    first = sorted(mig.glob("0001_*.sql"))[0]
    first.write_text(first.read_text() + "\n-- edited later\n")
    with pytest.raises(MigrationError, match="changed after it was applied"):
        migrate(db, mig)


def test_a_failing_migration_leaves_nothing_behind(tmp_path):
    mig = tmp_path / "migrations"
    shutil.copytree(MIGRATIONS_DIR, mig)
    n = len(discover(mig)) + 1
    (mig / f"{n:04d}_broken.sql").write_text("CREATE TABLE half_done (a);\nINSERT INTO no_such_table VALUES (1);\n")
    db = tmp_path / "q.sqlite"
    with pytest.raises(Exception, match="no_such_table"):
        migrate(db, mig)
    conn = connect(db)
    assert schema_version(conn) == n - 1
    assert conn.execute("SELECT 1 FROM sqlite_master WHERE name = 'half_done'").fetchone() is None
    conn.close()


def test_gaps_in_numbering_are_refused(tmp_path):
    (tmp_path / "0001_a.sql").write_text("CREATE TABLE a (x);")
    (tmp_path / "0003_c.sql").write_text("CREATE TABLE c (x);")
    with pytest.raises(MigrationError, match="without gaps"):
        discover(tmp_path)


def test_two_processes_starting_at_once(tmp_path):
    db = str(tmp_path / "q.sqlite")
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(3)
    procs = [ctx.Process(target=_migrate_in_child, args=(db, barrier)) for _ in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0, 0]
    conn = connect(db)
    versions = [r[0] for r in conn.execute("SELECT version FROM schema_version ORDER BY version")]
    conn.close()
    assert versions == [m.version for m in discover()]
