"""The deployment file: PostgreSQL, a one-shot migration, the broker, two API instances behind a proxy, and the
simulated leg as a device through the broker."""

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


def test_compose_runs_postgres_a_migration_the_broker_two_api_instances_a_proxy_and_a_leg_through_the_broker():
    compose = yaml.safe_load((ROOT / "docker-compose.yml").read_text())
    services = compose["services"]
    pg, migrate, broker, identities, api1, api2, proxy, leg = (services[n] for n in (
        "postgres", "migrate", "mosquitto", "identities", "api1", "api2", "proxy", "bridge-sim"))
    assert any(v.endswith(":/var/lib/postgresql/data") and v.split(":")[0] in compose["volumes"] for v in pg["volumes"])
    # the migration runs once, after PostgreSQL is ready, and the instances only after it succeeded
    assert migrate["command"].strip().rstrip('"').endswith("quasitune db upgrade") and migrate["restart"] == "no"
    assert migrate["depends_on"]["postgres"]["condition"] == "service_healthy"
    assert api1["depends_on"]["migrate"]["condition"] == "service_completed_successfully"
    # the broker: Debian's Mosquitto from the deployment's own script (tests/test_deploy_broker.py runs it), its CA
    # made at first start on a volume, the CA certificate shared read-only with the instances and the leg
    assert broker["command"] == ["sh", "/deploy/start.sh"] and "./deploy/broker:/deploy:ro" in broker["volumes"]
    assert "quasitune-broker-ca:/ca" in broker["volumes"] and "QUASITUNE_BROKER_ADMIN_PASSWORD" in broker["environment"]
    assert identities["depends_on"]["mosquitto"]["condition"] == "service_healthy" and identities["restart"] == "no"
    assert "for n in api1 api2" in identities["command"] and "quasitune broker add-server $$n" in identities["command"]
    assert "quasitune broker add-device sim-leg-1" in identities["command"]
    for api, port, name in ((api1, 8001, "api1"), (api2, 8002, "api2")):
        env = api["environment"]
        assert env["QUASITUNE_DATABASE_URL"].startswith("postgresql://quasitune:")
        assert f"quasitune serve --host 127.0.0.1 --port {port}" in api["command"]
        assert (ROOT / env["QUASITUNE_MIGRATIONS_DIR"].removeprefix("/src/")).is_dir()
        # every instance reaches the leg through the broker, with an identity and a client id of its own
        assert env["QUASITUNE_DEVICE"] == "mqtt:sim-leg-1" and env["QUASITUNE_INSTANCE_NAME"] == name
        assert env["QUASITUNE_BROKER_CREDENTIALS"] == f"/identities/{name}.json"
        assert env["QUASITUNE_BROKER_URL"].startswith("mqtts://") and env["QUASITUNE_BROKER_CA_FILE"] == "/broker-ca/ca.crt"
        spec = parse_device_spec(env["QUASITUNE_DEVICE"])
        assert spec is not None and spec.interface == "mqtt" and spec.device_id == "sim-leg-1"
    assert api1["depends_on"]["identities"]["condition"] == "service_completed_successfully"
    # the proxy balances both instances, the live telemetry's WebSockets included
    conf = (ROOT / "deploy" / "nginx.conf").read_text()
    assert "./deploy/nginx.conf:/etc/nginx/nginx.conf:ro" in proxy["volumes"]
    assert "server 127.0.0.1:8001" in conf and "server 127.0.0.1:8002" in conf and "listen 127.0.0.1:8000" in conf
    assert "proxy_set_header Upgrade $http_upgrade" in conf
    # the simulated leg is a device like any other: its bridge connects out with the leg's identity, buffer on a volume
    last = " ".join(leg["command"].split("&&")[-1].split()).strip().rstrip('"')
    args = build_parser().parse_args(shlex.split(last)[1:])
    assert (args.can, args.device_id, args.broker) == ("sim", "sim-leg-1", api1["environment"]["QUASITUNE_BROKER_URL"])
    assert str(args.credentials) == "/identities/sim-leg-1.json" and str(args.buffer).startswith("/state/")
    assert "quasitune-bridge:/state" in leg["volumes"]


@pytest.mark.skipif(shutil.which("docker-compose") is None, reason="docker-compose is not installed here")
def test_docker_compose_config_is_valid_and_needs_the_database_and_broker_passwords():
    env = {k: v for k, v in os.environ.items() if k not in ("QUASITUNE_DB_PASSWORD", "QUASITUNE_BROKER_ADMIN_PASSWORD")}
    r = subprocess.run(["docker-compose", "config", "-q"], cwd=ROOT, capture_output=True, text=True,
                       env={**env, "QUASITUNE_DB_PASSWORD": "a long random password",
                            "QUASITUNE_BROKER_ADMIN_PASSWORD": "another long random password"})
    assert r.returncode == 0, r.stderr
    r = subprocess.run(["docker-compose", "config", "-q"], cwd=ROOT, capture_output=True, text=True, env=env)
    assert r.returncode != 0 and "set QUASITUNE_DB_PASSWORD" in r.stderr
    r = subprocess.run(["docker-compose", "config", "-q"], cwd=ROOT, capture_output=True, text=True,
                       env={**env, "QUASITUNE_DB_PASSWORD": "a long random password"})
    assert r.returncode != 0 and "set QUASITUNE_BROKER_ADMIN_PASSWORD" in r.stderr
