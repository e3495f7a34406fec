"""The deployment file: PostgreSQL, a one-shot migration, two API instances behind a proxy, the CAN bridge."""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from backend.cli import build_parser
from backend.devices import parse_device_spec

ROOT = Path(__file__).resolve().parents[1]


def test_compose_runs_postgres_a_migration_once_two_api_instances_a_proxy_and_the_bridge():
    compose = yaml.safe_load((ROOT / "docker-compose.yml").read_text())
    services = compose["services"]
    pg, migrate, api1, api2, proxy, bridge = (services[n] for n in ("postgres", "migrate", "api1", "api2", "proxy",
                                                                      "bridge"))
    assert any(v.endswith(":/var/lib/postgresql/data") and v.split(":")[0] in compose["volumes"] for v in pg["volumes"])
    # the migration runs once, after PostgreSQL is ready, and the instances only after it succeeded
    assert migrate["command"].strip().rstrip('"').endswith("quasitune db upgrade") and migrate["restart"] == "no"
    assert migrate["depends_on"]["postgres"]["condition"] == "service_healthy"
    assert api1["depends_on"]["migrate"]["condition"] == "service_completed_successfully"
    for api, port in ((api1, 8001), (api2, 8002)):
        assert api["environment"]["QUASITUNE_DATABASE_URL"].startswith("postgresql://quasitune:")
        assert f"quasitune serve --host 127.0.0.1 --port {port}" in api["command"]
        assert (ROOT / api["environment"]["QUASITUNE_MIGRATIONS_DIR"].removeprefix("/src/")).is_dir()
    # the proxy balances both instances and sends what talks to the leg to the one holding its bus
    conf = (ROOT / "deploy" / "nginx.conf").read_text()
    assert "./deploy/nginx.conf:/etc/nginx/nginx.conf:ro" in proxy["volumes"]
    assert "server 127.0.0.1:8001" in conf and "server 127.0.0.1:8002" in conf and "listen 127.0.0.1:8000" in conf
    assert api2["environment"]["QUASITUNE_DEVICE"] == "none"
    # the bridge gets the CAN interface (host network namespace) and forwards to the bus api1 uses
    assert bridge["network_mode"] == "host" and "QUASITUNE_CAN" in bridge["environment"]
    last = bridge["command"].split("&&")[-1].strip().rstrip('"')
    bridge_cmd = shlex.split(last.replace("$$QUASITUNE_CAN", "socketcan:can0"))
    args = build_parser().parse_args(bridge_cmd[1:])
    assert args.can == "socketcan:can0" and args.to == api1["environment"]["QUASITUNE_DEVICE"]
    spec = parse_device_spec(api1["environment"]["QUASITUNE_DEVICE"])
    assert spec is not None and spec.interface == "udp_multicast"


@pytest.mark.skipif(shutil.which("docker-compose") is None, reason="docker-compose is not installed here")
def test_docker_compose_config_is_valid_and_needs_the_database_password():
    env = {k: v for k, v in os.environ.items() if k != "QUASITUNE_DB_PASSWORD"}
    r = subprocess.run(["docker-compose", "config", "-q"], cwd=ROOT, capture_output=True, text=True,
                       env={**env, "QUASITUNE_DB_PASSWORD": "a long random password"})
    assert r.returncode == 0, r.stderr
    r = subprocess.run(["docker-compose", "config", "-q"], cwd=ROOT, capture_output=True, text=True, env=env)
    assert r.returncode != 0 and "set QUASITUNE_DB_PASSWORD" in r.stderr
