"""quasitune users and serve's argument checks, run in-process."""

from __future__ import annotations

import io

import pytest

from backend.cli import main
from tests.helpers.sql import sql


def test_users_add_reads_the_password_from_stdin_and_refuses_bad_input(capsys, monkeypatch, tmp_path):
    def users_add(name: str, role: str, password: str) -> int:
        monkeypatch.setattr("sys.stdin", io.StringIO(password + "\n"))
        return main(["users", "add", name, "--role", role, "--data-dir", str(tmp_path)])

    assert users_add("alex", "viewer", "long-enough-pw") == 0
    assert "alex (viewer)" in capsys.readouterr().out
    assert users_add("alex", "viewer", "long-enough-pw") == 2
    assert "already exists" in capsys.readouterr().err
    assert users_add("bo", "viewer", "short") == 2
    assert "at least 8 characters" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        users_add("cy", "surgeon", "long-enough-pw")
    assert exit_.value.code == 2 and "invalid choice" in capsys.readouterr().err
    assert main(["users", "list", "--data-dir", str(tmp_path)]) == 0
    listed = capsys.readouterr().out
    assert "alex" in listed and "bo" not in listed


def test_users_disable_enable_and_passwd_from_the_command_line(capsys, monkeypatch, tmp_path):
    from backend.db import connect
    from backend.security import verify_password

    def run(*argv: str, stdin: str = "") -> int:
        monkeypatch.setattr("sys.stdin", io.StringIO(stdin))
        return main([*argv, "--data-dir", str(tmp_path)])

    assert run("users", "add", "alex", "--role", "viewer", "--one-time", stdin="first-password\n") == 0
    assert "changed at the first sign-in" in capsys.readouterr().out
    assert run("users", "disable", "alex") == 0 and "disabled" in capsys.readouterr().out
    assert run("users", "list") == 0 and "disabled, must change password" in capsys.readouterr().out
    assert run("users", "disable", "nobody") == 2 and "no user named 'nobody'" in capsys.readouterr().err
    assert run("users", "enable", "alex") == 0
    assert run("users", "passwd", "alex", stdin="short\n") == 2 and "8 characters" in capsys.readouterr().err
    assert run("users", "passwd", "alex", stdin=" second password \n") == 0
    conn = connect(tmp_path / "quasitune.sqlite")
    row = sql(conn, "SELECT * FROM users WHERE username = 'alex'").mappings().one()
    conn.close()
    assert verify_password(" second password ", row["password_hash"]) and not row["disabled"]
    assert row["must_change_password"] == 0                              # set by its owner at the console


@pytest.mark.parametrize("port", ["-1", "65536", "nope"])
def test_serve_refuses_a_bad_port(capsys, tmp_path, port):
    with pytest.raises(SystemExit) as exit_:
        main(["serve", "--port", port, "--data-dir", str(tmp_path)])
    assert exit_.value.code == 2 and "port" in capsys.readouterr().err


def test_serve_refuses_a_bad_device_before_starting(capsys, tmp_path):
    assert main(["serve", "--device", "carrier-pigeon:1", "--data-dir", str(tmp_path)]) == 2
    assert "device must be 'sim', 'none' or INTERFACE:CHANNEL" in capsys.readouterr().err
    assert not (tmp_path / "quasitune.sqlite").exists()          # nothing was started or created


def test_db_upgrade_runs_the_migrations_once_and_says_where_the_database_stands(capsys, tmp_path):
    from backend.migrate import head

    assert main(["db", "upgrade", "--data-dir", str(tmp_path)]) == 0
    first = capsys.readouterr().out
    assert "quasitune.sqlite: 0012, " in first and f"{head()}; at revision {head()}" in first
    assert main(["db", "upgrade", "--data-dir", str(tmp_path)]) == 0
    assert "nothing to apply" in capsys.readouterr().out
