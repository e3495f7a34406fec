"""Where the server keeps its data, from the environment."""

from __future__ import annotations

from pathlib import Path

from backend.settings import DB_FILE, Settings, default_data_dir, default_frontend_dir


def test_the_data_directory_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("QUASITUNE_DATA_DIR", str(tmp_path / "q"))
    assert default_data_dir() == tmp_path / "q"
    monkeypatch.delenv("QUASITUNE_DATA_DIR")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert default_data_dir() == tmp_path / "xdg" / "quasitune"
    monkeypatch.delenv("XDG_DATA_HOME")
    assert default_data_dir() == Path.home() / ".local" / "share" / "quasitune"


def test_the_dashboard_is_the_repositorys_unless_named(monkeypatch, tmp_path):
    monkeypatch.delenv("QUASITUNE_FRONTEND_DIR", raising=False)
    assert (default_frontend_dir() / "index.html").exists()
    monkeypatch.setenv("QUASITUNE_FRONTEND_DIR", str(tmp_path))
    assert default_frontend_dir() == tmp_path


def test_defaults_are_the_embedded_ones():
    s = Settings(data_dir=Path("/tmp/x"))
    assert s.db_path == Path("/tmp/x") / DB_FILE and s.device == "none" and not s.viewer3d
    assert s.token_ttl_s == 8 * 3600 and s.request_threads == 2 and s.trusted_proxies == ()
