"""``quasitune broker add-server|add-device``: identities at the MQTT broker for a deployment's first start.

The broker's admin identity and address come from the settings (``QUASITUNE_BROKER_URL``, ``…_CA_FILE``,
``…_ADMIN_USERNAME``, ``…_ADMIN_PASSWORD``). The new identity is written to ``--out`` as the credentials file the
bridge and the settings read (``{"username", "password", "ca_file"}``, readable by its owner only), never printed: the
password exists nowhere else (the broker keeps a salted hash). An identity that already exists is refused, so a second
run cannot silently shut out the first one's holder; ``POST /api/devices/{id}/credentials`` replaces a leg's.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path


def _admin():
    from backend.settings import Settings
    from device_bridge.broker_admin import BrokerAdmin

    s = Settings()
    if s.broker_url is None or not s.broker_admin_username or s.broker_admin_password is None:
        raise ValueError("set QUASITUNE_BROKER_URL, QUASITUNE_BROKER_ADMIN_USERNAME and QUASITUNE_BROKER_ADMIN_PASSWORD "
                         "(and QUASITUNE_BROKER_CA_FILE) first")
    ca = None if s.broker_ca_file is None else str(s.broker_ca_file)
    return BrokerAdmin(s.broker_url, s.broker_admin_username, s.broker_admin_password.get_secret_value(), ca), ca


def _write_private(path: Path, body: dict) -> None:
    """The credentials file, created readable by its owner only (refused if it exists: it may be in use)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        json.dump(body, f)


def cmd_broker_add(args: argparse.Namespace) -> int:
    from device_bridge.broker_admin import BrokerAdminError

    if args.out.exists():
        raise ValueError(f"--out {args.out} exists: an identity is already written there")
    admin, ca = _admin()
    try:
        identity = admin.add_server(args.name) if args.broker_command == "add-server" else admin.add_device(args.name)
    except BrokerAdminError as exc:
        raise ValueError(str(exc)) from None
    finally:
        admin.close()
    _write_private(args.out, {"username": identity.username, "password": identity.password, "ca_file": ca})
    print(f"{identity.username}: identity created at the broker; credentials written to {args.out} (owner only)")
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("broker", help="identities at the MQTT broker (first start of a deployment)")
    broker_sub = p.add_subparsers(dest="broker_command", required=True)
    for name, what in (("add-server", "an API instance: commands to every leg, every leg's frames"),
                       ("add-device", "a leg: its own frames out, its own commands in")):
        q = broker_sub.add_parser(name, help=f"create the identity of {what}")
        q.add_argument("name", help="the instance's name (QUASITUNE_INSTANCE_NAME) or the leg's device id")
        q.add_argument("--out", type=Path, required=True, help="the credentials file to write (must not exist)")
        q.set_defaults(func=cmd_broker_add)
