"""Device identities at the broker: Mosquitto's dynamic security plugin, driven over its own control topic.

Each leg gets a user name (its device id) and a random password, and a role that lets it publish only its own frames
(``…/{id}/up``, and ``…/{id}/late`` for what it buffered while away) and subscribe only to its own commands
(``…/{id}/down``); API server instances get a role that publishes commands to any leg and reads every leg's frames.
Nothing else may publish or subscribe (the plugin's defaults deny both; QuasiTune's roles are the only grants). Each
identity has its one client id bound (``device-{id}``, ``server-{name}``): a leg's credentials cannot connect as the
server's client id and inherit its persistent session, nor as another leg's and knock it off.

Why passwords and not client certificates: the plugin stores them hashed (salted PBKDF2-SHA512) and revokes one at
once (``deleteClient`` or ``disableClient`` disconnects a connected client the same moment), where a certificate
would need a revocation list the broker re-reads; the link is TLS either way, so a password never crosses in clear.
QuasiTune keeps no copy: a new password is shown once, to be written into the bridge's credentials file.
"""

from __future__ import annotations

import json
import secrets
import threading
import uuid

from device_bridge.mqtt_bus import TOPIC_PREFIX, broker_client, client_id_of, topic

CONTROL = "$CONTROL/dynamic-security/v1"
SERVER_ROLE = "quasitune-server"


class BrokerAdminError(RuntimeError):
    """The broker refused or did not answer a command (the message says which and why)."""


def device_role(device_id: str) -> str:
    return f"quasitune-device-{device_id}"


class BrokerAdmin:
    """Commands to the dynamic security plugin, answered one at a time (used from the server, as the broker's admin).

    Args:
        broker: ``mqtts://HOST:PORT``; username, password: the broker's admin identity; ca_file: the broker's CA.
    """

    def __init__(self, broker: str, username: str, password: str, ca_file: str | None = None,
                 timeout_s: float = 10.0, insecure: bool = False) -> None:
        self._client, address = broker_client(broker, f"quasitune-admin-{uuid.uuid4().hex[:8]}", username, password,
                                              ca_file, insecure)
        self.timeout_s = timeout_s
        self._answers: dict[str, dict] = {}
        self._arrived = threading.Condition()
        self._ready = threading.Event()
        self._client.on_connect = lambda c, *_: (c.subscribe(CONTROL + "/response", qos=1), None)
        self._client.on_subscribe = lambda *_: self._ready.set()
        self._client.on_message = self._on_message
        self._client.connect(address.host, address.port, keepalive=30)
        self._client.loop_start()
        if not self._ready.wait(timeout_s):
            self.close()
            raise BrokerAdminError(f"the broker at {address.host}:{address.port} did not accept the admin identity")

    def _on_message(self, _client, _userdata, message) -> None:
        for answer in json.loads(message.payload).get("responses", []):
            with self._arrived:
                self._answers[answer.get("correlationData", "")] = answer
                self._arrived.notify_all()

    def _command(self, command: str, **fields: object) -> dict:
        key = uuid.uuid4().hex
        body = {"commands": [{"command": command, "correlationData": key, **fields}]}
        self._client.publish(CONTROL, json.dumps(body), qos=1)
        with self._arrived:
            if not self._arrived.wait_for(lambda: key in self._answers, self.timeout_s):
                raise BrokerAdminError(f"the broker did not answer {command}")
            answer = self._answers.pop(key)
        if answer.get("error"):
            raise BrokerAdminError(f"the broker refused {command}: {answer['error']}")
        return answer

    def _role(self, name: str, acls: list[tuple[str, str]]) -> None:
        try:
            self._command("createRole", rolename=name)
        except BrokerAdminError as exc:
            if "already exists" not in str(exc):
                raise
        for acltype, pattern in acls:
            try:
                self._command("addRoleACL", rolename=name, acltype=acltype, topic=pattern, allow=True, priority=0)
            except BrokerAdminError as exc:
                if "already exists" not in str(exc):
                    raise

    def _client_with(self, username: str, role: str, client_id: str) -> str:
        """A new identity with its role and its one client id bound (it may connect under no other, and no other
        identity under it); its random password, returned once."""
        password = secrets.token_urlsafe(24)
        self._command("createClient", username=username, password=password, clientid=client_id,
                      roles=[{"rolename": role}])
        return password

    def bind_client_id(self, username: str, role: str) -> None:
        """Bind an identity made before client ids were bound to its one client id (:func:`client_id_of`)."""
        self._command("setClientId", username=username, clientid=client_id_of(role, username))

    def add_server(self, name: str) -> str:
        """An identity for one API instance (its password, shown once): commands to every leg, every leg's frames."""
        self._role(SERVER_ROLE, [("publishClientSend", f"{TOPIC_PREFIX}/+/down"),
                                 ("subscribePattern", f"{TOPIC_PREFIX}/+/up"),
                                 ("subscribePattern", f"{TOPIC_PREFIX}/+/late")])
        return self._client_with(name, SERVER_ROLE, client_id_of("server", name))

    def add_device(self, device_id: str) -> str:
        """The leg's identity (its password, shown once): its own frames out, its own commands in, nothing else."""
        self._role(device_role(device_id), [("publishClientSend", topic(device_id, "up")),
                                            ("publishClientSend", topic(device_id, "late")),
                                            ("subscribeLiteral", topic(device_id, "down"))])
        return self._client_with(device_id, device_role(device_id), client_id_of("device", device_id))

    def require_device(self, device_id: str) -> None:
        """Refuse (BrokerAdminError) unless ``device_id`` is a leg's identity, made by :meth:`add_device` with exactly
        its own role: a server's identity or the broker's admin is never replaced nor revoked as if it were a leg."""
        client = self._command("getClient", username=device_id).get("data", {}).get("client", {})
        roles = [r.get("rolename") for r in client.get("roles", [])]
        if roles != [device_role(device_id)]:
            raise BrokerAdminError(f"{device_id} is not a leg's identity at the broker (a server's or the admin's "
                                   "identity is never replaced or revoked as a leg)")

    def replace_device(self, device_id: str) -> str:
        """A new password for the leg; the old one stops working and a bridge connected with it is disconnected.
        Only a leg's identity (:meth:`require_device`)."""
        self.require_device(device_id)
        password = secrets.token_urlsafe(24)
        self._command("setClientPassword", username=device_id, password=password)
        self._command("disableClient", username=device_id)      # drops the connection made with the old password
        self._command("enableClient", username=device_id)
        return password

    def revoke_device(self, device_id: str) -> None:
        """The leg's identity removed: refused from now on, disconnected now if connected. Only a leg's identity."""
        self.require_device(device_id)
        self._command("deleteClient", username=device_id)

    def close(self) -> None:
        self._client.disconnect()
        self._client.loop_stop()
