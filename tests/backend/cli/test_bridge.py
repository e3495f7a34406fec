"""``quasitune bridge --can sim --broker …``: the simulated leg behind a bridge process of its own, reached through the
broker as a real leg is (the command the deployment's ``bridge-sim`` service runs)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest

from controller_core.fsmic import fsmic_table
from device_bridge.host import DeviceLink
from device_bridge.mqtt_bus import MqttBus
from device_bridge.protocol import Mode
from tests.helpers.device import until

pytestmark = [pytest.mark.broker, pytest.mark.wallclock, pytest.mark.live]


def test_a_bridge_process_puts_the_simulated_leg_on_the_broker_and_a_server_pushes_to_it(broker, broker_admin,
                                                                                          tmp_path):
    credentials = tmp_path / "leg.json"
    username, password = broker_admin.add_device("cli-bridge-leg")
    credentials.write_text(json.dumps({"username": username, "password": password, "ca_file": broker.ca_file}))
    err = (tmp_path / "stderr.txt").open("w")      # a file, not a pipe: a full pipe would stop the bridge
    proc = subprocess.Popen([sys.executable, "-m", "backend.cli", "bridge", "--can", "sim", "--broker", broker.url,
                             "--device-id", "cli-bridge-leg", "--credentials", str(credentials),
                             "--buffer", str(tmp_path / "late.sqlite"), "--buffer-mb", "4"],
                            stdout=subprocess.PIPE, stderr=err, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONFAULTHANDLER": "1"})
    link = None
    try:
        line = proc.stdout.readline()
        assert "QuasiTune bridge: sim <->" in line and "at most 4 MiB" in line, (tmp_path / "stderr.txt").read_text()
        link = DeviceLink(MqttBus("cli-bridge-leg", broker.url, *broker_admin.add_server("cli-bridge-server"), role="server",
                                  ca_file=broker.ca_file)).start()
        result = link.push(fsmic_table(75.0), version=3)
        until(lambda: link.status and link.status.mode == Mode.ACTIVE and link.status.active_crc32 == result.crc32,
              10.0, poll_s=0.05)          # the bridged leg reports the table running
    finally:
        if link is not None:
            link.close()
        _interrupt(proc, tmp_path / "stderr.txt")
        err.close()
    assert (tmp_path / "late.sqlite").exists()


def _interrupt(proc: subprocess.Popen, stderr, stop: int = signal.SIGINT) -> None:
    """Ctrl-C (or ``stop``), and the bridge stops cleanly; one that does not is aborted and its threads' stacks are the
    failure."""
    proc.send_signal(stop)
    try:
        proc.wait(30)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)          # PYTHONFAULTHANDLER: every thread's stack to stderr
        proc.wait(10)
        stacks = [line for line in stderr.read_text().splitlines() if not line.startswith("Extension modules")]
        raise AssertionError("the bridge did not stop after Ctrl-C:\n" + "\n".join(stacks)[-8000:]) from None
    assert proc.returncode == 0, stderr.read_text()[-3000:]


def test_a_bridge_refuses_a_buffer_bound_that_is_not_a_size(tmp_path):
    r = subprocess.run([sys.executable, "-m", "backend.cli", "bridge", "--can", "sim", "--broker",
                        "mqtts://127.0.0.1:1", "--device-id", "x", "--credentials", str(tmp_path / "none.json"),
                        "--buffer-mb", "0"], capture_output=True, text=True)
    assert r.returncode == 2 and "--buffer-mb" in r.stderr


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT])
def test_a_bridge_stops_cleanly_on_sigterm_as_on_ctrl_c(tmp_path, stop):
    """``docker stop`` sends SIGTERM: the bridge closes its buses and exits 0, as on Ctrl-C."""
    with (tmp_path / "stderr.txt").open("w") as err:
        proc = subprocess.Popen([sys.executable, "-m", "backend.cli", "bridge", "--can", "sim", "--to",
                                 f"virtual:test-bridge-stop-{os.getpid()}"], stdout=subprocess.PIPE, stderr=err,
                                text=True, env={**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONFAULTHANDLER": "1"})
        assert "QuasiTune bridge: sim <->" in proc.stdout.readline(), (tmp_path / "stderr.txt").read_text()
        _interrupt(proc, tmp_path / "stderr.txt", stop)
