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
