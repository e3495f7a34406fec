"""A throwaway Mosquitto broker for the tests: Debian's ``mosquitto``, TLS on a loopback port with a certificate from a
CA made for the run (openssl), the dynamic security plugin with an admin identity, in a temporary folder, run as the
``mosquitto`` user when the tests run as root (Mosquitto drops to it), stopped and removed afterwards."""

from __future__ import annotations

import os
import secrets
import shutil
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from device_bridge.broker_admin import BrokerAdmin

DYNSEC_PLUGIN = next(iter(sorted(Path("/usr/lib").glob("*/mosquitto_dynamic_security.so"))),
                     Path("/usr/lib/x86_64-linux-gnu/mosquitto_dynamic_security.so"))   # Debian's multiarch folder
ADMIN = "quasitune-admin"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def make_certificates(folder: Path) -> None:
    """``ca.crt`` (a CA of this run only) and ``server.crt``/``server.key`` for 127.0.0.1, signed by it."""
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    _openssl("req", "-x509", *ec, "-keyout", "ca.key", "-out", "ca.crt", "-days", "2", "-subj",
             "/CN=QuasiTune test CA", cwd=folder)
    _openssl("req", *ec, "-keyout", "server.key", "-out", "server.csr", "-subj", "/CN=127.0.0.1", cwd=folder)
    (folder / "san.ext").write_text("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
    _openssl("x509", "-req", "-in", "server.csr", "-CA", "ca.crt", "-CAkey", "ca.key", "-CAcreateserial", "-out",
             "server.crt", "-days", "2", "-extfile", "san.ext", cwd=folder)


class MosquittoBroker:
    """:meth:`start`, then :attr:`url` (``mqtts://127.0.0.1:PORT``), :attr:`ca_file` and the admin's password;
    :meth:`stop` and :meth:`start` again keep the port and the identities (a broker restart)."""

    def __init__(self) -> None:
        if shutil.which("mosquitto") is None and not Path("/usr/sbin/mosquitto").exists():
            raise RuntimeError("Mosquitto is not installed (Debian package 'mosquitto'): bash scripts/test.sh installs it")
        self.root = Path(tempfile.mkdtemp(prefix="quasitune-mqtt-"))
        self.port = _free_port()
        self.admin_password = secrets.token_urlsafe(16)
        self.proc: subprocess.Popen | None = None
        make_certificates(self.root)
        subprocess.run(["mosquitto_ctrl", "dynsec", "init", str(self.root / "dynsec.json"), ADMIN,
                        self.admin_password], check=True, capture_output=True)
        user = "user mosquitto\n" if os.geteuid() == 0 else ""
        (self.root / "mosquitto.conf").write_text(
            f"per_listener_settings false\nallow_anonymous false\n{user}"
            f"persistence true\npersistence_location {self.root}/\nlog_dest file {self.root}/mosquitto.log\n"
            "max_queued_messages 100000\nmax_packet_size 65536\n"
            f"listener {self.port} 127.0.0.1\ncafile {self.root}/ca.crt\ncertfile {self.root}/server.crt\n"
            f"keyfile {self.root}/server.key\nplugin {DYNSEC_PLUGIN}\n"
            f"plugin_opt_config_file {self.root}/dynsec.json\n")
        if os.geteuid() == 0:
            for path in [self.root, *self.root.iterdir()]:
                shutil.chown(path, "mosquitto", "mosquitto")

    @property
    def url(self) -> str:
        return f"mqtts://127.0.0.1:{self.port}"

    @property
    def ca_file(self) -> str:
        return str(self.root / "ca.crt")

    def start(self) -> None:
        self.proc = subprocess.Popen(["/usr/sbin/mosquitto", "-c", str(self.root / "mosquitto.conf")],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        deadline = time.monotonic() + 10
        while True:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.5).close()
                return
            except OSError:
                if self.proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"mosquitto did not start: {self.proc.stderr.read().decode()[-500:]}") from None
                time.sleep(0.05)

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(10)
        self.proc = None

    def remove(self) -> None:
        self.stop()
        shutil.rmtree(self.root, ignore_errors=True)


@contextmanager
def running_broker() -> Iterator[MosquittoBroker]:
    """A broker started for the ``with`` block, removed after it."""
    server = MosquittoBroker()
    try:
        server.start()
        yield server
    finally:
        server.remove()


@contextmanager
def admin_of(server: MosquittoBroker) -> Iterator[BrokerAdmin]:
    """The broker's admin (identities), connected for the ``with`` block."""
    admin = BrokerAdmin(server.url, ADMIN, server.admin_password, server.ca_file)
    try:
        yield admin
    finally:
        admin.close()


def connect_as(broker: MosquittoBroker, username: str, password: str, client_id: str, clean_session: bool = False):
    """(whether the broker accepts this identity under ``client_id``, the paho client, connected or not, for the
    caller to stop). By default a persistent session is asked for, as an attacker taking over a session would."""
    import ssl
    import threading

    import paho.mqtt.client as mqtt
    from paho.mqtt.enums import CallbackAPIVersion

    answered, accepted = threading.Event(), []
    c = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=clean_session)
    c.username_pw_set(username, password)
    c.tls_set(ca_certs=broker.ca_file, cert_reqs=ssl.CERT_REQUIRED, tls_version=ssl.PROTOCOL_TLS_CLIENT)
    c.on_connect = lambda _c, _u, _f, code, _p: (accepted.append(not code.is_failure), answered.set())
    c.connect("127.0.0.1", broker.port)
    c.loop_start()
    assert answered.wait(5), "the broker did not answer the connection"
    return accepted[0], c
