"""The deployment file: the API with its database on a volume, a bridge holding the CAN interface."""

from __future__ import annotations

import shlex
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from backend.cli import build_parser
from backend.devices import parse_device_spec

ROOT = Path(__file__).resolve().parents[1]


def test_compose_runs_the_api_with_its_database_on_a_volume_and_a_bridge_holding_the_can_interface():
    compose = yaml.safe_load((ROOT / "docker-compose.yml").read_text())
    api, bridge = compose["services"]["api"], compose["services"]["bridge"]
    data_volume = next(v for v in api["volumes"] if v.endswith(":/data"))
    assert data_volume.split(":")[0] in compose["volumes"]
    assert api["environment"]["QUASITUNE_DATA_DIR"] == "/data"
    assert (ROOT / api["environment"]["QUASITUNE_MIGRATIONS_DIR"].removeprefix("/src/")).is_dir()
    assert "quasitune serve --host 127.0.0.1" in api["command"]
    # the bridge gets the CAN interface (host network namespace) and forwards to the bus the API uses
    assert bridge["network_mode"] == "host" and "QUASITUNE_CAN" in bridge["environment"]
    last = bridge["command"].split("&&")[-1].strip().rstrip('"')
    bridge_cmd = shlex.split(last.replace("$$QUASITUNE_CAN", "socketcan:can0"))
    args = build_parser().parse_args(bridge_cmd[1:])
    assert args.can == "socketcan:can0" and args.to == api["environment"]["QUASITUNE_DEVICE"]
    spec = parse_device_spec(api["environment"]["QUASITUNE_DEVICE"])
    assert spec is not None and spec.interface == "udp_multicast"


@pytest.mark.skipif(shutil.which("docker-compose") is None, reason="docker-compose is not installed here")
def test_docker_compose_config_is_valid():
    r = subprocess.run(["docker-compose", "config", "-q"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
