"""Migrations on PostgreSQL: run once before the instances start, never beside them: three migrators at once upgrade
once (an advisory lock), an instance refuses a database not at its revision, and the command line does the upgrade."""

from __future__ import annotations

import pytest
from sqlalchemy import create_engine, inspect

from backend.cli import main
from backend.db import database_url
from backend.migrate import MigrationError, head, migrate, require_current
from tests.helpers.migrators import migrate_at_once


@pytest.fixture
def empty(postgres):
    with postgres.new_database() as url:
        yield url


def test_three_migrators_at_once_upgrade_once(empty):
    assert migrate_at_once(empty) == [0, 0, 0]
    require_current(empty)
    engine = create_engine(database_url(empty))
    with engine.connect() as conn:
        assert "session_sample_seconds" in inspect(conn).get_table_names()
    engine.dispose()


def test_an_instance_refuses_a_database_that_is_not_at_its_revision(empty, tmp_path, model):
    from backend.app import create_app
    from backend.settings import Settings

    with pytest.raises(MigrationError, match="run 'quasitune db upgrade' once"):
        create_app(Settings(data_dir=tmp_path, database_url=empty), model_loader=lambda: model)
    migrate(empty, to="0013")
    with pytest.raises(MigrationError, match=f"at revision 0013, this QuasiTune needs {head()}"):
        require_current(empty)


def test_the_command_line_upgrades_the_database_the_environment_names(empty, monkeypatch, capsys):
    monkeypatch.setenv("QUASITUNE_DATABASE_URL", empty.replace("postgresql+psycopg", "postgresql"))
    assert main(["db", "upgrade"]) == 0
    out = capsys.readouterr().out
    assert f"at revision {head()}" in out and "postgresql+psycopg://" in out
    require_current(empty)
    assert main(["db", "upgrade"]) == 0 and "nothing to apply" in capsys.readouterr().out


def test_times_become_timestamps_and_flags_booleans_with_every_row_and_rule_kept(empty):
    """A database at 0019 holding a user, a patient and a version, upgraded: its times are ``timestamp with time
    zone`` and its flags ``boolean`` (the ISO text and the 0/1 it held, cast), the application reads them as it
    always did, and the immutability triggers the change had to drop are back, word for word."""
    from sqlalchemy import MetaData, Table, text

    from backend.db import utc_text
    from backend.store import users

    migrate(empty, to="0019")
    engine = create_engine(database_url(empty))
    at = "2026-11-29T18:01:43.037Z"
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO users (id, username, role, password_hash, created_at, disabled, "
                          "must_change_password) VALUES (1, 'dana', 'prosthetist', 'h', :at, 0, 1)"), {"at": at})
        conn.execute(text("INSERT INTO patients (id, code_name, body_mass_kg, side, created_by, created_at, "
                          "updated_at) VALUES (1, 'P-1', 80, 'left', 1, :at, :at)"), {"at": at})
        conn.execute(text("INSERT INTO proposals (id, patient_id, version, source, speed_mps, incline_deg, body_mass_kg, "
                          "extrapolation, safety_ok, model_json, table_json, table_sha256, created_by, created_at) "
                          "VALUES (1, 1, 1, 'model', 1.2, 0, 80, 0, 1, '{}', '{}', 's', 1, :at)"), {"at": at})
        triggers = set(conn.execute(text("SELECT tgname FROM pg_trigger WHERE NOT tgisinternal")).scalars())
    migrate(empty, to="0020")
    with engine.connect() as conn:
        proposals = Table("proposals", MetaData(), autoload_with=conn)
        types = {(r.table_name, r.column_name): r.data_type for r in conn.execute(text(
            "SELECT table_name, column_name, data_type FROM information_schema.columns WHERE table_schema = 'public'"))}
        assert types["proposals", "created_at"] == types["users", "created_at"] == "timestamp with time zone"
        assert types["proposals", "safety_ok"] == types["users", "disabled"] == "boolean"
        assert set(conn.execute(text("SELECT tgname FROM pg_trigger WHERE NOT tgisinternal")).scalars()) == triggers
        row = conn.execute(proposals.select()).mappings().one()
        assert utc_text(row["created_at"]) == at and row["safety_ok"] is True and row["extrapolation"] is False
        assert users.list_users(conn)[0]["must_change_password"] is True and users.list_users(conn)[0]["disabled"] is False
        with pytest.raises(Exception, match="immutable"):     # the rules are back
            conn.execute(text("UPDATE proposals SET created_at = now()"))
    engine.dispose()
