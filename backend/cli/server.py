"""Server commands: ``serve``, ``users add|list``, ``bridge``."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sqlite3
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from backend.settings import Settings, default_data_dir

DATA_DIR_HELP = "data directory holding quasitune.sqlite (default: $QUASITUNE_DATA_DIR or ~/.local/share/quasitune)"


def _settings(args: argparse.Namespace) -> Settings:
    return Settings(data_dir=args.data_dir or default_data_dir(), model_dir=getattr(args, "model", None))


@contextmanager
def _database(args: argparse.Namespace) -> Iterator[tuple[Settings, sqlite3.Connection]]:
    """The settings and a connection to their database, migrated first (created if missing)."""
    from backend.db import connect
    from backend.migrate import migrate

    settings = _settings(args)
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    migrate(settings.db_path)
    conn = connect(settings.db_path)
    try:
        yield settings, conn
    finally:
        conn.close()


def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"port must be a whole number 0-65535, got {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"port must be 0-65535 (0 = any free port), got {port}")
    return port


def cmd_serve(args: argparse.Namespace) -> int:
    from backend.devices import parse_device_spec
    from backend.serve import serve

    device = args.device or os.environ.get("QUASITUNE_DEVICE") or "sim"
    parse_device_spec(device)   # refuse a bad spec before anything starts
    return serve(dataclasses.replace(_settings(args), device=device), host=args.host, port=args.port,
                 bootstrap=not args.no_bootstrap_user)


def _read_password() -> str:
    import getpass

    if sys.stdin.isatty():
        first = getpass.getpass("password: ")
        if getpass.getpass("again: ") != first:
            raise ValueError("the two passwords differ")
        return first
    return sys.stdin.readline().rstrip("\r\n")


def cmd_users_add(args: argparse.Namespace) -> int:
    from pydantic import ValidationError

    from backend.errors import ConflictError
    from backend.schemas.users import UserCreate
    from backend.store.users import create_user

    try:
        body = UserCreate(username=args.name, role=args.role, password=_read_password())
    except ValidationError as exc:
        err = exc.errors()[0]
        raise ValueError(f"{'.'.join(map(str, err['loc']))}: {err['msg']}") from None
    with _database(args) as (settings, conn):
        try:
            user = create_user(conn, body.username, body.role, body.password)
        except ConflictError as exc:
            raise ValueError(exc.message) from None
    print(f"user {user['username']} ({user['role']}) added to {settings.db_path}")
    return 0


def cmd_users_list(args: argparse.Namespace) -> int:
    from backend.store.users import list_users

    with _database(args) as (_, conn):
        for u in list_users(conn):
            print(f"{u['id']:4d}  {u['username']:24s} {u['role']:12s} {'disabled' if u['disabled'] else ''}")
    return 0


def cmd_bridge(args: argparse.Namespace) -> int:
    from device_bridge.buses import open_bus
    from device_bridge.gateway import Gateway

    gateway = Gateway(open_bus(args.can), open_bus(args.to)).start()
    print(f"QuasiTune bridge: {args.can} <-> {args.to}", flush=True)
    try:
        gateway.wait()
    except KeyboardInterrupt:
        pass
    finally:
        gateway.close()
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    from backend.store.users import ROLES

    p = sub.add_parser("serve", help="run the API server (loopback by default)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default loopback only)")
    p.add_argument("--port", type=_port, default=8000, help="port (0 = any free port; the real one is printed)")
    p.add_argument("--data-dir", type=Path, default=None, help=DATA_DIR_HELP)
    p.add_argument("--model", type=Path, default=None, help="model directory from 'quasitune train'")
    p.add_argument("--no-bootstrap-user", action="store_true",
                   help="do not create the first user on an empty database")
    p.add_argument("--device", default=None,
                   help="'sim' (default: the simulated leg on an in-process virtual CAN bus), 'none', or "
                        "INTERFACE:CHANNEL for a real leg on a python-can bus (e.g. socketcan:can0); "
                        "default $QUASITUNE_DEVICE or sim")
    p.set_defaults(func=cmd_serve)
    p = sub.add_parser("bridge", help="forward frames between the leg's CAN bus and the API server's bus")
    p.add_argument("--can", required=True, help="the leg's bus, INTERFACE:CHANNEL (e.g. socketcan:can0)")
    p.add_argument("--to", default="udp_multicast:239.74.163.2",
                   help="the bus 'quasitune serve --device' uses (default udp_multicast:239.74.163.2)")
    p.set_defaults(func=cmd_bridge)
    p = sub.add_parser("users", help="manage users")
    users_sub = p.add_subparsers(dest="users_command", required=True)
    p = users_sub.add_parser("add", help="add a user (password from a prompt, or one line of stdin)")
    p.add_argument("name")
    p.add_argument("--role", required=True, choices=ROLES)
    p.add_argument("--data-dir", type=Path, default=None, help=DATA_DIR_HELP)
    p.set_defaults(func=cmd_users_add)
    p = users_sub.add_parser("list", help="list users")
    p.add_argument("--data-dir", type=Path, default=None, help=DATA_DIR_HELP)
    p.set_defaults(func=cmd_users_list)
