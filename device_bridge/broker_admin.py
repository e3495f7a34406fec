"""Device identities at the broker: Mosquitto's dynamic security plugin, driven over its own control topic.

Each leg gets a user name (``device-{id}``) and a random password, and a role that lets it publish only its own frames
(``…/{id}/up``, and ``…/{id}/late`` for what it buffered while away) and subscribe only to its own commands
(``…/{id}/down``); API server instances get a role that publishes commands to any leg and reads every leg's frames.
Nothing else may publish or subscribe (the plugin's defaults deny both; QuasiTune's roles are the only grants). Names
are namespaced (:func:`~device_bridge.mqtt_bus.identity_name`): issuing or revoking a leg's identity can only ever touch
a ``device-`` name, never a server's or the admin's. Each identity has its one client id bound (its user name): a leg's
credentials cannot connect as the server's client id and inherit its persistent session, nor as another leg's and
knock it off. A change of several commands goes to the plugin in one message, checked first, so a refusal leaves the
broker as it was.

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
from typing import NamedTuple

from device_bridge.mqtt_bus import TOPIC_PREFIX, broker_client, identity_name, topic

CONTROL = "$CONTROL/dynamic-security/v1"
SERVER_ROLE = "quasitune-server"


class BrokerAdminError(RuntimeError):
    """The broker refused or did not answer a command (the message says which and why)."""


def device_role(device_id: str) -> str:
    return f"quasitune-device-{device_id}"


class Identity(NamedTuple):
    """An identity just made at the broker: its user name (also its client id) and its password, shown once."""

    username: str
    password: str


class BrokerAdmin:
    """Commands to the dynamic security plugin, answered one at a time (used from the server, as the broker's admin).

    Args:
        broker: ``mqtts://HOST:PORT``; username, password: the broker's admin identity; ca_file: the broker's CA.
    """

    def __init__(self, broker: str, username: str, password: str, ca_file: str | None = None,
                 timeout_s: float = 10.0, insecure: bool = False) -> None:
        if username.startswith(("device-", "server-")):
            raise BrokerAdminError(f"the broker's admin identity {username!r} is named like a leg's or a server's "
                                   "(device-…, server-…): rename it so no leg's credentials can ever collide with it")
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

    def _commands(self, *commands: dict) -> list[dict]:
        """Send ``commands`` in one message (the plugin runs them in order) and return their answers; BrokerAdminError
        names the first one refused."""
        keyed = [{**c, "correlationData": uuid.uuid4().hex} for c in commands]
        self._client.publish(CONTROL, json.dumps({"commands": keyed}), qos=1)
        answers = []
        with self._arrived:
            for c in keyed:
                if not self._arrived.wait_for(lambda k=c["correlationData"]: k in self._answers, self.timeout_s):
                    raise BrokerAdminError(f"the broker did not answer {c['command']}")
                answers.append(self._answers.pop(c["correlationData"]))
        for c, answer in zip(keyed, answers, strict=True):
            if answer.get("error"):
                raise BrokerAdminError(f"the broker refused {c['command']}: {answer['error']}")
        return answers

    def _command(self, command: str, **fields: object) -> dict:
        return self._commands({"command": command, **fields})[0]

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

    def _client_with(self, username: str, role: str) -> Identity:
        """A new identity with its role and its one client id (its user name) bound: it may connect under no other,
        and no other identity under it. Its random password, returned once."""
        password = secrets.token_urlsafe(24)
        self._command("createClient", username=username, password=password, clientid=username,
                      roles=[{"rolename": role}])
        return Identity(username, password)

    def add_server(self, name: str) -> Identity:
        """An identity for one API instance (``server-{name}``, its password shown once): commands to every leg, every
        leg's frames."""
        self._role(SERVER_ROLE, [("publishClientSend", f"{TOPIC_PREFIX}/+/down"),
                                 ("subscribePattern", f"{TOPIC_PREFIX}/+/up"),
                                 ("subscribePattern", f"{TOPIC_PREFIX}/+/late")])
        return self._client_with(identity_name("server", name), SERVER_ROLE)

    def add_device(self, device_id: str) -> Identity:
        """The leg's identity (``device-{id}``, its password shown once): its own frames out, its own commands in,
        nothing else. BrokerAdminError if it exists (:meth:`replace_device` gives it a new password); a refusal leaves
        no role behind."""
        role = device_role(device_id)
        try:
            self._command("getRole", rolename=role)
            had_role = True
        except BrokerAdminError:
            had_role = False
        self._role(role, [("publishClientSend", topic(device_id, "up")),
                          ("publishClientSend", topic(device_id, "late")),
                          ("subscribeLiteral", topic(device_id, "down"))])
        try:
            return self._client_with(identity_name("device", device_id), role)
        except BrokerAdminError:
            if not had_role:
                self._command("deleteRole", rolename=role)
            raise

    def require_device(self, device_id: str) -> None:
        """Refuse (BrokerAdminError) unless the leg's identity ``device-{id}`` exists with exactly its own role."""
        username = identity_name("device", device_id)
        client = self._command("getClient", username=username).get("data", {}).get("client", {})
        roles = [r.get("rolename") for r in client.get("roles", [])]
        if roles != [device_role(device_id)]:
            raise BrokerAdminError(f"{username} is not a leg's identity at the broker (made by add_device with its "
                                   "own role only): it is not replaced nor revoked as one")

    def replace_device(self, device_id: str) -> Identity:
        """A new password for the leg; the old one stops working and a bridge connected with it is disconnected (the
        three commands in one message: a refusal of the first leaves the broker as it was). Only a leg's identity
        (:meth:`require_device`)."""
        self.require_device(device_id)
        username, password = identity_name("device", device_id), secrets.token_urlsafe(24)
        self._commands({"command": "setClientPassword", "username": username, "password": password},
                       {"command": "disableClient", "username": username},     # drops a connection on the old one
                       {"command": "enableClient", "username": username})
        return Identity(username, password)

    def revoke_device(self, device_id: str) -> None:
        """The leg's identity removed: refused from now on, disconnected now if connected. Only a leg's identity."""
        self.require_device(device_id)
        self._command("deleteClient", username=identity_name("device", device_id))

    def close(self) -> None:
        self._client.disconnect()
        self._client.loop_stop()
