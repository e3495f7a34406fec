"""Alembic migrations: a fresh database gets the baseline once, a database of the hand-written migrations is stamped
with every row kept, a failing revision leaves nothing behind, processes starting at once upgrade once."""

from __future__ import annotations

import hashlib
import shutil
import sqlite3
from pathlib import Path

import pytest

from backend.db import sqlite_pragmas
from backend.migrate import BASELINE, LEGACY_DIR_NAME, MIGRATIONS_DIR, MigrationError, head, migrate
from backend.store.sample_pack import pack, unpack
from tests.helpers.migrators import migrate_at_once

LEGACY = sorted((MIGRATIONS_DIR / LEGACY_DIR_NAME).glob("*.sql"))
NOW = "2026-11-24T00:00:00Z"
DATA = Path(__file__).parents[1] / "leg" / "data"          # a table and an envelope as QuasiTune stored them
TABLE_JSON = (DATA / "table_1.2mps_level_75kg.json").read_text()
ENVELOPE_JSON = (DATA / "envelope_default_75kg.json").read_text()


def connect(path: Path) -> sqlite3.Connection:
    """The file opened with the app's own connection settings (WAL, foreign keys, busy timeout, autocommit), as
    SQLite's own connection: these tests read SQLite's catalogue and the driver's errors."""
    conn = sqlite3.connect(path, isolation_level=None)
    sqlite_pragmas(conn, None)
    return conn


def schema_version(conn: sqlite3.Connection) -> int:
    row = conn.execute("SELECT version_num FROM alembic_version").fetchone()
    return int(row[0]) if row else 0


def _legacy_database(path: Path, files: list[Path] = LEGACY) -> sqlite3.Connection:
    """A database as QuasiTune 0.1 made it: the hand-written files applied in order, each recorded with its sha256."""
    conn = sqlite3.connect(path, isolation_level=None)
    conn.execute("CREATE TABLE schema_version (version INTEGER PRIMARY KEY, name TEXT NOT NULL, sha256 TEXT NOT NULL, "
                 "applied_at TEXT NOT NULL)")
    for f in files:
        sql = f.read_text(encoding="utf-8")
        conn.executescript(sql)
        conn.execute("INSERT INTO schema_version VALUES (?, ?, ?, ?)",
                     (int(f.name[:4]), f.name, hashlib.sha256(sql.encode()).hexdigest(), NOW))
    return conn


SAMPLE = (0, 0.01, 1, 2, 0.1, 0.2, 3.0, -0.1, 0.0, 5.0, 700.0, 1.0, 1.2, 0.5, 1.2, 0.0, "adaptive")


def _fill(conn: sqlite3.Connection) -> None:
    """A row in every table, through the columns the later migrations added too (a database of the hand-written
    migrations: samples a row each, as they were stored then; a newer one: a second of samples packed)."""
    x = conn.execute
    x("INSERT INTO users (id, username, role, password_hash, created_at, must_change_password) VALUES "
      "(1, 'Dana', 'prosthetist', 'h', ?, 1)", (NOW,))
    x("INSERT INTO tokens VALUES ('t' || hex(randomblob(8)), 1, ?, 1.5e9)", (NOW,))
    x("INSERT INTO patients (id, code_name, body_mass_kg, height_m, side, k_level, created_by, created_at, updated_at) "
      "VALUES (1, 'P-1', 80, 1.8, 'left', 3, 1, ?, ?)", (NOW, NOW))
    x("INSERT INTO proposals (id, patient_id, version, source, speed_mps, incline_deg, body_mass_kg, extrapolation, "
      "safety_ok, model_json, table_json, table_sha256, created_by, created_at, extrapolation_reason) VALUES "
      "(1, 1, 1, 'model', 1.2, 0, 80, 0, 1, '{}', ?, 's', 1, ?, NULL)", (TABLE_JSON, NOW))
    x("INSERT INTO envelopes (id, patient_id, version, source, body_mass_kg, n_speeds, n_inclines, extrapolation, "
      "safety_ok, envelope_json, envelope_sha256, wire_crc32, created_by, created_at) VALUES "
      "(1, 1, 1, 'model', 80, 5, 5, 0, 1, ?, 'e', 4294967295, 1, ?)", (ENVELOPE_JSON, NOW))
    x("INSERT INTO devices (id, kind, interface, channel, registered_at, patient_id, last_wire_version) VALUES "
      "('leg', 'simulated', 'virtual', 'c', ?, 1, 7)", (NOW,))
    x("INSERT INTO pushes (proposal_id, device_id, table_version, crc32, status, requested_by, requested_at, "
      "override_reason) VALUES (1, 'leg', 3, 4294967295, 'active', 1, ?, 'a reason written out in full')", (NOW,))
    x("INSERT INTO walking_sessions (id, patient_id, device_id, envelope_id, speed_mps, incline_deg, body_mass_kg, "
      "status, started_by, started_at, course) VALUES (1, 1, 'leg', 1, 1.2, 0, 80, 'recording', 1, ?, 'mixed')", (NOW,))
    if x("SELECT 1 FROM sqlite_master WHERE name = 'session_samples'").fetchone():
        x(f"INSERT INTO session_samples VALUES (1, {', '.join('?' * len(SAMPLE))})", SAMPLE)
    else:
        x("INSERT INTO session_sample_seconds VALUES (1, 0, 1, ?)", (pack([SAMPLE]),))
    x("INSERT INTO proposal_previews VALUES (1, ?, 10, ?, '{\"a\": 1}')", ("0" * 64, NOW))
    x("INSERT INTO envelope_previews VALUES (1, ?, 'mixed', ?, '{}')", ("0" * 64, NOW))
    x("INSERT INTO audit_log (at, actor_id, actor_name, action, entity, entity_id) VALUES (?, 1, 'Dana', 'a', 'b', 1)",
      (NOW,))
    x("INSERT INTO envelopes (id, patient_id, version, parent_id, source, body_mass_kg, n_speeds, n_inclines, "
      "extrapolation, safety_ok, envelope_json, envelope_sha256, created_by, created_at) VALUES "
      "(2, 1, 2, 1, 'edit', 80, 5, 5, 0, 1, ?, 'f', 1, ?)", (ENVELOPE_JSON, NOW))
    x("INSERT INTO refinements (envelope_id, parent_id, session_ids_json, evidence_json, created_by, created_at) "
      "VALUES (2, 1, '[1]', '{}', 1, ?)", (NOW,))


def _fill_now(conn: sqlite3.Connection) -> None:
    """A row in each table the rules below touch, at the newest revision."""
    x = conn.execute
    x("INSERT INTO users (id, username, role, password_hash, created_at) VALUES (1, 'Dana', 'prosthetist', 'h', ?)",
      (NOW,))
    x("INSERT INTO patients (id, code_name, body_mass_kg, side, created_by, created_at, updated_at) "
      "VALUES (1, 'P-1', 80, 'left', 1, ?, ?)", (NOW, NOW))
    x("INSERT INTO versions (id, patient_id, kind, version, source, n_speeds, n_inclines, speed_mps, incline_deg, "
      "body_mass_kg, extrapolation, safety_ok, content_json, content_sha256, created_by, created_at) VALUES "
      "(1, 1, 'table', 1, 'model', 1, 1, 1.2, 0, 80, 0, 1, '{}', ?, 1, ?)", ("0" * 64, NOW))
    x("INSERT INTO devices (id, kind, interface, channel, registered_at) VALUES ('leg', 'simulated', 'virtual', 'c', ?)",
      (NOW,))
    x("INSERT INTO walking_sessions (id, patient_id, device_id, version_id, speed_mps, incline_deg, body_mass_kg, "
      "status, started_by, started_at) VALUES (1, 1, 'leg', 1, 1.2, 0, 80, 'recording', 1, ?)", (NOW,))
    x("INSERT INTO refinements (version_id, parent_id, session_ids_json, evidence_json, created_by, created_at) "
      "VALUES (1, 1, '[1]', '{}', 1, ?)", (NOW,))


def _everything(conn: sqlite3.Connection) -> dict[str, list[tuple]]:
    tables = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT IN "
                                         "('schema_version', 'alembic_version') ORDER BY name")]
    return {t: [tuple(r) for r in conn.execute(f"SELECT * FROM {t} ORDER BY 1, 2")] for t in tables}


LATER = ["0013", "0014", "0015", "0016", "0017", "0018", "0019", "0020", "0021"]   # the revisions after the baseline
LATER_TABLES = {"login_failures", "session_sample_seconds", "gate_signoffs", "withdrawals",   # the tables they added
                "instance_beats"}
LATER_TRIGGERS = {"gate_signoffs_no_update", "gate_signoffs_no_delete", "withdrawals_no_update", "withdrawals_no_delete",
                  "proposals_leg_kept", "envelopes_leg_kept"}          # through 0020
# the rules at the newest revision: those of tables and envelopes became the versions' (0021)
NOW_TRIGGERS = {"audit_no_delete", "audit_no_update", "gate_signoffs_no_delete", "gate_signoffs_no_update",
                "legacy_ids_kept", "pushes_never_deleted", "pushes_override_kept", "refinements_never_change",
                "refinements_never_deleted", "sessions_stopped_once", "versions_content_immutable",
                "versions_decided_once", "versions_extrapolation_reason_kept", "versions_leg_kept",
                "versions_never_deleted", "withdrawals_no_delete", "withdrawals_no_update"}


def _triggers(conn: sqlite3.Connection) -> set[str]:
    return {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'trigger'")}


def test_a_fresh_database_gets_the_baseline_once_in_wal_mode(tmp_path):
    db = tmp_path / "q.sqlite"
    applied = migrate(db)
    assert applied[0] == BASELINE and applied[-1] == head()
    assert migrate(db) == []
    conn = connect(db)
    assert schema_version(conn) == int(head())
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert conn.execute("PRAGMA foreign_keys").fetchone()[0] == 1
    conn.close()


def test_a_database_of_the_hand_written_migrations_is_stamped_with_every_row_kept(tmp_path):
    db = tmp_path / "q.sqlite"
    old = _legacy_database(db)
    _fill(old)
    rows, triggers = _everything(old), _triggers(old)
    old.close()
    assert all(rows.values()) and len(rows) == 13 and len(triggers) == 18
    assert migrate(db, to="0020") == LATER[:-1]     # stamped at the baseline, then the later revisions applied
    conn = connect(db)
    now = _everything(conn)
    # every row kept; the samples now a row per second (revision 0014), read back the same; every device supervised
    # when its link is lost, as it was before anyone could choose (revision 0015)
    rows["devices"] = [(*r, "supervised") for r in rows["devices"]]
    rows["pushes"] = [(*r, None, None) for r in rows["pushes"]]   # none sent back from a withdrawn version (0016);
    # which instance sent each is not known (0017)
    rows["walking_sessions"] = [(*r, None) for r in rows["walking_sessions"]]   # who walked them is not known (0016)
    assert rows["envelope_previews"]        # walked before nodes were walked alone: walked again on request (0018)
    rows["envelope_previews"] = [r for r in rows["envelope_previews"] if '"nodes":' in r[-1]]
    rows["patients"] = [(*r, None) for r in rows["patients"]]         # no leg described (0019): the bench's stands in
    for t in ("proposals", "envelopes"):                              # made on the nominal bench leg (0019)
        rows[t] = [(*r, "{}") for r in rows[t]]
    assert {t: v for t, v in now.items() if t not in LATER_TABLES} == {t: v for t, v in rows.items()
                                                                       if t != "session_samples"}
    assert [r for (blob,) in conn.execute("SELECT samples FROM session_sample_seconds") for r in unpack(blob)] == \
        [tuple(r[1:]) for r in rows["session_samples"]]
    assert _triggers(conn) == (triggers - {"session_samples_append_only"}) | LATER_TRIGGERS
    assert schema_version(conn) == 20
    assert conn.execute("SELECT 1 FROM sqlite_master WHERE name = 'schema_version'").fetchone() is None
    with pytest.raises(sqlite3.IntegrityError, match="append-only"):   # its rules still hold
        conn.execute("DELETE FROM audit_log")
    with pytest.raises(sqlite3.IntegrityError, match="CHECK"):
        conn.execute("INSERT INTO pushes (device_id, table_version, crc32, status, requested_by, requested_at) "
                     "VALUES ('leg', 4, 1, 'sending', 1, ?)", (NOW,))
    conn.close()
    assert migrate(db) == ["0021"]                  # and on to one version (tests/backend/test_migrate_one_version.py)
    conn = connect(db)
    assert [tuple(r) for r in conn.execute("SELECT id, kind, version FROM versions ORDER BY id")] == [
        (1, "table", 1), (3, "envelope", 1), (4, "envelope", 2)]   # envelopes past the largest id of either kind
    assert _triggers(conn) == NOW_TRIGGERS
    conn.close()


def test_the_fresh_and_the_stamped_database_hold_the_same_rules(tmp_path):
    fresh, stamped = tmp_path / "fresh.sqlite", tmp_path / "stamped.sqlite"
    migrate(fresh)
    _legacy_database(stamped).close()
    migrate(stamped)
    a, b = connect(fresh), connect(stamped)
    assert _triggers(a) == _triggers(b) == NOW_TRIGGERS
    for conn in (a, b):
        _fill_now(conn)
        for sql, match in [("UPDATE versions SET content_json = '[]'", "immutable"),
                           ("UPDATE walking_sessions SET status = 'stopped'", None),
                           ("UPDATE walking_sessions SET course = 'x'", "final"),
                           ("DELETE FROM refinements", "never deleted"),
                           ("UPDATE versions SET extrapolation_reason = 'x'", "kept as written"),
                           ("UPDATE versions SET leg_json = '{\"name\": \"x\"}'", "made for is kept as written"),
                           ("INSERT INTO users (username, role, password_hash, created_at) "
                            "VALUES ('dana', 'viewer', 'h', 'now')", "UNIQUE"),   # names are case-insensitive
                           ("INSERT INTO previews VALUES (1, ?, 1, NULL, 'now', 'not json')", "CHECK"),
                           ("INSERT INTO versions (patient_id, kind, version, source, n_speeds, n_inclines, speed_mps, "
                            "incline_deg, body_mass_kg, extrapolation, safety_ok, content_json, content_sha256, "
                            "created_by, created_at) VALUES (1, 'table', 9, 'model', 2, 2, 1.2, 0, 80, 0, 1, '{}', ?, 1, "
                            "'now')", "CHECK")]:      # a table is one node
            params = ("0" * 64,) if "?" in sql else ()
            if match is None:
                conn.execute(sql, params)
            else:
                with pytest.raises(sqlite3.IntegrityError, match=match):
                    conn.execute(sql, params)
    a.close()
    b.close()


def test_an_older_or_altered_hand_written_database_is_refused(tmp_path):
    older = tmp_path / "older.sqlite"
    _legacy_database(older, LEGACY[:-1]).close()
    with pytest.raises(MigrationError, match=r"QuasiTune 0\.1"):
        migrate(older)
    altered = tmp_path / "altered.sqlite"
    _legacy_database(altered).execute("UPDATE schema_version SET sha256 = 'x' WHERE version = 3")
    with pytest.raises(MigrationError, match=r"\[3\] differ"):
        migrate(altered)
    conn = connect(altered)      # refused, and left as it was
    assert conn.execute("SELECT count(*) FROM schema_version").fetchone()[0] == len(LEGACY)
    conn.close()


def test_a_failing_revision_leaves_nothing_behind(tmp_path):
    mig = tmp_path / "migrations"
    shutil.copytree(MIGRATIONS_DIR, mig)
    (mig / "versions" / "9999_broken.py").write_text(
        f"import sqlalchemy as sa\nfrom alembic import op\nrevision = '9999'\ndown_revision = '{head()}'\n"
        "branch_labels = None\ndepends_on = None\n\n\ndef upgrade():\n"
        "    op.create_table('half_done', sa.Column('a', sa.Integer))\n"
        "    op.execute('INSERT INTO no_such_table VALUES (1)')\n")
    db = tmp_path / "q.sqlite"
    with pytest.raises(Exception, match="no_such_table"):
        migrate(db, mig)
    conn = connect(db)
    assert conn.execute("SELECT 1 FROM sqlite_master WHERE name IN ('half_done', 'users')").fetchone() is None
    conn.close()
    assert migrate(db) == [BASELINE, *LATER]      # and the good revisions still apply


def test_a_database_from_a_newer_quasitune_is_refused(tmp_path):
    db = tmp_path / "q.sqlite"
    migrate(db)
    conn = connect(db)
    conn.execute("UPDATE alembic_version SET version_num = '0099'")
    conn.close()
    with pytest.raises(Exception, match="0099"):
        migrate(db)


def test_two_processes_starting_at_once_upgrade_once(tmp_path):
    db = str(tmp_path / "q.sqlite")
    assert migrate_at_once(db) == [0, 0, 0]
    conn = connect(db)
    assert [r[0] for r in conn.execute("SELECT version_num FROM alembic_version")] == [head()]
    assert _triggers(conn) == NOW_TRIGGERS
    conn.close()
