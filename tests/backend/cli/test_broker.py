"""``quasitune broker add-server|add-device``: a deployment's identities at the broker, written to a file only its
owner can read, never twice."""

from __future__ import annotations

import json
import stat

import pytest

from backend.cli import main
from device_bridge.mqtt_bus import MqttBus
from tests.helpers.mosquitto import ADMIN


@pytest.fixture
def admin_env(broker, monkeypatch):
    monkeypatch.setenv("QUASITUNE_BROKER_URL", broker.url)
    monkeypatch.setenv("QUASITUNE_BROKER_CA_FILE", broker.ca_file)
    monkeypatch.setenv("QUASITUNE_BROKER_ADMIN_USERNAME", ADMIN)
    monkeypatch.setenv("QUASITUNE_BROKER_ADMIN_PASSWORD", broker.admin_password)
    return broker


def test_a_legs_identity_is_written_for_its_owner_only_and_lets_the_leg_in(admin_env, tmp_path, capsys):
    out = tmp_path / "legs" / "cli-leg-1.json"
    assert main(["broker", "add-device", "cli-leg-1", "--out", str(out)]) == 0
    assert stat.S_IMODE(out.stat().st_mode) == 0o600
    written = json.loads(out.read_text())
    assert written["password"] not in capsys.readouterr().out
    MqttBus("cli-leg-1", admin_env.url, written["username"], written["password"], role="device",
            ca_file=written["ca_file"]).shutdown()
    assert main(["broker", "add-device", "cli-leg-1", "--out", str(out)]) == 2          # the file is in use
    assert main(["broker", "add-device", "cli-leg-1", "--out", str(tmp_path / "again.json")]) == 2   # so is the name
    assert "already exists" in capsys.readouterr().err and not (tmp_path / "again.json").exists()


def test_without_the_brokers_admin_settings_nothing_is_done(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("QUASITUNE_BROKER_URL", raising=False)
    assert main(["broker", "add-server", "api1", "--out", str(tmp_path / "api1.json")]) == 2
    assert "QUASITUNE_BROKER_URL" in capsys.readouterr().err and not (tmp_path / "api1.json").exists()
