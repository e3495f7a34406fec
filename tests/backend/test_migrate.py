"""Numbered migrations applied once, whole, in order."""

from __future__ import annotations

import multiprocessing
import shutil
import sqlite3

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


def _database_before(tmp_path, n: int):
    """A database migrated to version ``n`` with a user, a patient, a proposal and a device; (db, migrations dir)."""
    mig = tmp_path / "migrations"
    mig.mkdir()
    for m in discover()[:n]:
        (mig / m.name).write_text(m.sql)
    db = tmp_path / "q.sqlite"
    migrate(db, mig)
    conn = connect(db)
    conn.execute("INSERT INTO users (id, username, role, password_hash, created_at) VALUES (1, 'p', 'prosthetist', "
                 "'x', ?)", (NOW,))
    conn.execute("INSERT INTO patients (id, code_name, body_mass_kg, side, created_by, created_at, updated_at) "
                 "VALUES (1, 'P-1', 80, 'left', 1, ?, ?)", (NOW, NOW))
    conn.execute("INSERT INTO proposals (id, patient_id, version, source, speed_mps, incline_deg, body_mass_kg, "
                 "extrapolation, safety_ok, model_json, table_json, table_sha256, created_by, created_at) "
                 "VALUES (1, 1, 1, 'model', 1.2, 0, 80, 0, 1, '{}', '{}', 'x', 1, ?)", (NOW,))
    conn.execute("INSERT INTO devices (id, kind, interface, channel, registered_at) VALUES ('leg', 'simulated', "
                 "'virtual', 'x', ?)", (NOW,))
    conn.commit()
    return db, mig, conn


NOW = "2026-11-24T00:00:00Z"


def test_envelope_pushes_migration_keeps_every_table_push(tmp_path):
    """0007 rebuilds ``pushes`` (proposal_id may now be NULL for an envelope): old rows, the trigger and the
    one-of rule survive."""
    db, mig, conn = _database_before(tmp_path, 6)
    now = NOW
    conn.execute("INSERT INTO pushes (id, proposal_id, device_id, table_version, crc32, status, requested_by, "
                 "requested_at, attempts) VALUES (7, 1, 'leg', 3, 4660, 'active', 1, ?, 2)", (now,))
    conn.commit()
    conn.close()
    shutil.copy(MIGRATIONS_DIR / discover()[6].name, mig)
    assert migrate(db, mig) == [7]
    conn = connect(db)
    row = conn.execute("SELECT * FROM pushes").fetchone()
    assert (row["id"], row["proposal_id"], row["envelope_id"], row["crc32"], row["status"], row["attempts"]) == (
        7, 1, None, 4660, "active", 2)
    with pytest.raises(sqlite3.IntegrityError, match="CHECK"):      # neither a table nor an envelope
        conn.execute("INSERT INTO pushes (device_id, table_version, crc32, status, requested_by, requested_at) "
                     "VALUES ('leg', 4, 1, 'sending', 1, ?)", (now,))
    with pytest.raises(sqlite3.IntegrityError, match="never deleted"):
        conn.execute("DELETE FROM pushes")
    assert conn.execute("PRAGMA foreign_key_check").fetchall() == []
    conn.close()


def test_push_reconciliation_migration_keeps_every_push_and_admits_the_two_new_states(tmp_path):
    """0008 rebuilds ``pushes`` for 'unconfirmed' and 'lost': table and envelope pushes of every old state survive."""
    db, mig, conn = _database_before(tmp_path, 7)
    now = NOW
    conn.execute("INSERT INTO envelopes (id, patient_id, version, source, body_mass_kg, n_speeds, n_inclines, "
                 "extrapolation, safety_ok, envelope_json, envelope_sha256, crc32, created_by, created_at) "
                 "VALUES (1, 1, 1, 'model', 80, 2, 2, 0, 1, '{}', 'x', 5, 1, ?)", (now,))
    old = ["sending", "acknowledged", "active", "failed", "superseded"]
    for i, status in enumerate(old):
        item = "proposal_id, envelope_id" if i % 2 else "envelope_id, proposal_id"
        conn.execute(f"INSERT INTO pushes (id, {item}, device_id, table_version, crc32, status, requested_by, "
                     "requested_at, error) VALUES (?, 1, NULL, 'leg', ?, 77, ?, 1, ?, ?)",
                     (i + 1, i + 1, status, now, f"e{i}"))
    conn.commit()
    before = [tuple(r) for r in conn.execute("SELECT * FROM pushes ORDER BY id")]
    conn.close()
    shutil.copy(MIGRATIONS_DIR / discover()[7].name, mig)
    assert migrate(db, mig) == [8]
    conn = connect(db)
    assert [tuple(r) for r in conn.execute("SELECT * FROM pushes ORDER BY id")] == before
    for status in ("unconfirmed", "lost"):
        conn.execute("INSERT INTO pushes (proposal_id, device_id, table_version, crc32, status, requested_by, "
                     "requested_at) VALUES (1, 'leg', 9, 1, ?, 1, ?)", (status, now))
    with pytest.raises(sqlite3.IntegrityError, match="CHECK"):
        conn.execute("INSERT INTO pushes (proposal_id, device_id, table_version, crc32, status, requested_by, "
                     "requested_at) VALUES (1, 'leg', 9, 1, 'maybe', 1, ?)", (now,))
    with pytest.raises(sqlite3.IntegrityError, match="never deleted"):
        conn.execute("DELETE FROM pushes")
    assert conn.execute("PRAGMA foreign_key_check").fetchall() == []
    conn.close()


def test_one_envelope_checksum_migration_drops_the_json_crc_and_keeps_every_envelope(tmp_path):
    """0011 drops ``envelopes.crc32``: every envelope keeps every other column, content stays immutable."""
    db, mig, conn = _database_before(tmp_path, 10)
    for version in (1, 2):
        conn.execute("INSERT INTO envelopes (id, patient_id, version, source, body_mass_kg, n_speeds, n_inclines, "
                     "extrapolation, safety_ok, envelope_json, envelope_sha256, crc32, wire_crc32, created_by, "
                     "created_at) VALUES (?, 1, ?, 'model', 80, 2, 2, 0, 1, '{}', ?, 5, ?, 1, ?)",
                     (version, version, f"sha{version}", 1000 + version, NOW))
    conn.commit()
    kept = "id, patient_id, version, envelope_sha256, wire_crc32, status"
    before = [tuple(r) for r in conn.execute(f"SELECT {kept} FROM envelopes ORDER BY id")]
    conn.close()
    shutil.copy(MIGRATIONS_DIR / discover()[10].name, mig)
    assert migrate(db, mig) == [11]
    conn = connect(db)
    assert [tuple(r) for r in conn.execute(f"SELECT {kept} FROM envelopes ORDER BY id")] == before
    assert "crc32" not in [r["name"] for r in conn.execute("PRAGMA table_info(envelopes)")]
    with pytest.raises(sqlite3.IntegrityError, match="immutable"):
        conn.execute("UPDATE envelopes SET wire_crc32 = 1 WHERE id = 1")
    with pytest.raises(sqlite3.IntegrityError, match="never deleted"):
        conn.execute("DELETE FROM envelopes")
    conn.close()
