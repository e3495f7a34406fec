"""The deployment's broker (deploy/broker/start.sh, the docker-compose service ``mosquitto``), run here on Debian's
Mosquitto: its own CA and certificate made on first start and kept on the next, the admin identity from the
environment, legs admitted only with identities issued through it."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import can
import pytest

from device_bridge.broker_admin import BrokerAdmin
from device_bridge.mqtt_bus import MqttBus

pytestmark = [pytest.mark.broker, pytest.mark.wallclock]

ROOT = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(env: dict, port: int) -> subprocess.Popen:
    proc = subprocess.Popen(["sh", str(ROOT / "deploy" / "broker" / "start.sh")], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 30
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            return proc
        except OSError:
            if proc.poll() is not None or time.monotonic() > deadline:
                proc.kill()
                raise AssertionError(f"the broker did not start: {proc.stderr.read().decode()[-800:]}") from None
            time.sleep(0.1)


def _stop(proc: subprocess.Popen) -> None:
    proc.terminate()
    proc.wait(10)


@pytest.fixture
def deployment():
    root = Path(tempfile.mkdtemp(prefix="quasitune-deploy-broker-"))
    root.chmod(0o755)                      # Mosquitto drops root for its own user, who must reach its data
    port = _free_port()
    env = {**os.environ, "QUASITUNE_BROKER_DATA": str(root / "data"), "QUASITUNE_BROKER_CA_OUT": str(root / "ca"),
           "QUASITUNE_BROKER_PORT": str(port), "QUASITUNE_BROKER_ADDRESS": "127.0.0.1",
           "QUASITUNE_BROKER_HOST": "broker.example", "QUASITUNE_BROKER_ADMIN_USERNAME": "quasitune-admin",
           "QUASITUNE_BROKER_ADMIN_PASSWORD": "a long admin password for the test"}
    try:
        yield env, port, root
    finally:
        shutil.rmtree(root, ignore_errors=True)


def test_first_start_makes_its_own_ca_and_a_restart_keeps_it_and_every_identity(deployment):
    env, port, root = deployment
    url, ca = f"mqtts://127.0.0.1:{port}", str(root / "ca" / "ca.crt")
    proc = _start(env, port)
    try:
        first_ca = Path(ca).read_bytes()
        assert b"BEGIN CERTIFICATE" in first_ca and not (root / "ca" / "ca.key").exists()
        admin = BrokerAdmin(url, env["QUASITUNE_BROKER_ADMIN_USERNAME"], env["QUASITUNE_BROKER_ADMIN_PASSWORD"], ca)
        identity = admin.add_device("deploy-leg")
        admin.close()
        MqttBus("deploy-leg", url, *identity, role="device", ca_file=ca).shutdown()
    finally:
        _stop(proc)
    proc = _start(env, port)                 # a restart: nothing made again, nothing forgotten
    try:
        assert Path(ca).read_bytes() == first_ca
        MqttBus("deploy-leg", url, *identity, role="device", ca_file=ca).shutdown()
        with pytest.raises(can.CanInitializationError):   # anyone else is refused
            MqttBus("deploy-leg", url, identity.username, "not the password", role="device", ca_file=ca,
                    connect_timeout_s=2).shutdown()
    finally:
        _stop(proc)
