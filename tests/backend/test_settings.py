"""The one Settings: every knob from the environment, the command line over it."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from pydantic import ValidationError

from backend import __version__
from backend.settings import DB_FILE, Settings, default_data_dir, default_frontend_dir


@pytest.fixture(autouse=True)
def _clean_environment(monkeypatch):
    import os

    for name in [n for n in os.environ if n.startswith("QUASITUNE_")]:
        monkeypatch.delenv(name)


def test_the_data_directory_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("QUASITUNE_DATA_DIR", str(tmp_path / "q"))
    assert Settings().data_dir == tmp_path / "q"
    monkeypatch.delenv("QUASITUNE_DATA_DIR")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert Settings().data_dir == default_data_dir() == tmp_path / "xdg" / "quasitune"
    monkeypatch.delenv("XDG_DATA_HOME")
    assert Settings().data_dir == Path.home() / ".local" / "share" / "quasitune"


def test_the_dashboard_is_the_repositorys_unless_named(monkeypatch, tmp_path):
    assert (Settings().frontend_dir / "index.html").exists() and Settings().frontend_dir == default_frontend_dir()
    monkeypatch.setenv("QUASITUNE_FRONTEND_DIR", str(tmp_path))
    assert Settings().frontend_dir == tmp_path


def test_defaults_are_the_embedded_ones():
    s = Settings(data_dir=Path("/tmp/x"))
    assert s.db_path == Path("/tmp/x") / DB_FILE and s.device == "none" and not s.viewer3d
    assert s.token_ttl_s == 8 * 3600 and s.request_threads == 2 and s.trusted_proxies == ()
    assert 1 <= s.bench_processes <= 8 and s.bench_processes < max(os.cpu_count() or 1, 2)   # a core left to serve
    assert Settings.model_fields["password_hash_cost"].default == 2**14     # the run's own is lowered (conftest)
    assert (s.migrations_dir / "env.py").exists() and not s.given("device")


def test_every_knob_comes_from_the_environment_and_the_command_line_wins(monkeypatch, tmp_path):
    env = {"DATA_DIR": str(tmp_path), "TOKEN_TTL_S": "60", "MODEL_DIR": str(tmp_path / "m"), "MODEL_WAIT_S": "5",
           "DEVICE": "socketcan:can0", "FRONTEND_DIR": str(tmp_path / "f"), "MIGRATIONS_DIR": str(tmp_path / "mig"),
           "BENCH_LEG": "heavy_foot", "VIEWER3D": "true", "TRUSTED_PROXIES": "10.0.0.2, 10.0.0.3",
           "REQUEST_THREADS": "4", "LOGIN_PER_USER_PER_MINUTE": "3", "LOGIN_PER_ADDRESS_PER_MINUTE": "9",
           "LOGIN_PER_USER_ANYWHERE_PER_MINUTE": "50", "PASSWORD_HASH_COST": "1024",
           "DATABASE_URL": "postgresql://qt:secret@db.example:5432/quasitune",
           "BROKER_URL": "mqtts://broker.example:8883", "BROKER_USERNAME": "server-a", "BROKER_PASSWORD": "pw",
           "BROKER_CA_FILE": str(tmp_path / "ca.crt"), "BROKER_ADMIN_USERNAME": "admin",
           "BROKER_ADMIN_PASSWORD": "admin pw", "INSTANCE_NAME": "api-a",
           "BROKER_CREDENTIALS": str(tmp_path / "identity.json"), "BENCH_PROCESSES": "3"}
    (tmp_path / "identity.json").write_text('{"username": "from-file", "password": "file pw"}')
    for name, value in env.items():
        monkeypatch.setenv(f"QUASITUNE_{name}", value)
    s = Settings()
    assert set(env) == {name.upper() for name in Settings.model_fields}   # no knob outside the class
    assert (s.token_ttl_s, s.model_wait_s, s.device, s.viewer3d, s.request_threads) == (60, 5.0, "socketcan:can0",
                                                                                           True, 4)
    assert s.trusted_proxies == ("10.0.0.2", "10.0.0.3") and s.bench_leg == Path("heavy_foot")
    assert s.bench_processes == 3
    assert (s.login_per_user_per_minute, s.login_per_address_per_minute,
            s.login_per_user_anywhere_per_minute, s.password_hash_cost) == (3, 9, 50, 1024)
    assert s.database_url == "postgresql+psycopg://qt:secret@db.example:5432/quasitune"   # psycopg 3 always
    assert s.database_shown == "postgresql+psycopg://qt:***@db.example:5432/quasitune"      # never the password
    assert s.broker_password.get_secret_value() == "pw" and "pw" not in repr(s) and s.instance_name == "api-a"
    assert s.broker_username == "server-a"                 # what is given outright wins over the credentials file
    assert s.given("device")
    flags = Settings(device="none", token_ttl_s=120)
    assert flags.device == "none" and flags.token_ttl_s == 120 and flags.request_threads == 4


@pytest.mark.parametrize(("name", "value"), [("TOKEN_TTL_S", "-1"), ("REQUEST_THREADS", "0"), ("BENCH_PROCESSES", "0"),
                                             ("MODEL_WAIT_S", "soon"), ("VIEWER3D", "perhaps"),
                                             ("DATABASE_URL", "mysql://db/quasitune"), ("DATABASE_URL", "/a/file"),
                                             ("INSTANCE_NAME", "two words")])
def test_a_bad_value_is_refused_naming_the_knob(monkeypatch, name, value):
    monkeypatch.setenv(f"QUASITUNE_{name}", value)
    with pytest.raises(ValidationError, match=name.lower()):
        Settings()


def test_one_version_string_the_packages():
    from importlib.metadata import version

    assert __version__ == version("quasitune") and __version__ != "unknown"


def test_the_brokers_identity_from_a_credentials_file_and_a_bad_file_refused(tmp_path):
    good = tmp_path / "api1.json"
    good.write_text('{"username": "api1", "password": "a long one", "ca_file": "/broker-ca/ca.crt"}')
    s = Settings(broker_credentials=good)
    assert (s.broker_username, s.broker_password.get_secret_value(), s.broker_ca_file) == \
        ("api1", "a long one", Path("/broker-ca/ca.crt"))
    for text, why in (("not json", "not a readable JSON file"), ('{"username": "api1"}', "password are needed")):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(ValueError, match=why):
            Settings(broker_credentials=bad)
    with pytest.raises(ValueError, match="not a readable"):
        Settings(broker_credentials=tmp_path / "missing.json")
