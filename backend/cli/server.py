"""Server commands: ``serve``, ``users add|list|disable|enable|passwd``, ``bridge``."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from sqlalchemy import Connection

from backend.settings import Settings

SIGNAL_POLL_S = 0.2   # how often the bridge's main thread wakes to run a signal's handler

DATA_DIR_HELP = "data directory holding quasitune.sqlite (default: $QUASITUNE_DATA_DIR or ~/.local/share/quasitune)"


def _settings(args: argparse.Namespace, **flags: object) -> Settings:
    """The one Settings: the environment's values, the command line's flags (those given) over them."""
    given = {"data_dir": args.data_dir, "model_dir": getattr(args, "model", None), **flags}
    return Settings(**{name: value for name, value in given.items() if value is not None})


@contextmanager
def _database(args: argparse.Namespace) -> Iterator[tuple[Settings, Connection]]:
    """The settings and a connection to their database: the SQLite file migrated first (created if missing), a server
    database checked to be at this QuasiTune's revision."""
    from backend.db import connect
    from backend.migrate import migrate, require_current
    from backend.security import set_hash_cost

    settings = _settings(args)
    set_hash_cost(settings.password_hash_cost)
    if settings.database_url is None:
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        migrate(settings.db_path, settings.migrations_dir)
    else:       # a server database is migrated once, by 'quasitune db upgrade', never on the side
        require_current(settings.database_url, settings.migrations_dir)
    conn = connect(settings.database)
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


def _bench_leg(leg: str | None) -> Path | None:
    """``--leg`` (a path or a repository leg's name, as ``load_leg`` reads it), checked before the server starts."""
    if leg is None:
        return None
    from device_bridge.sim.leg_file import load_leg

    load_leg(leg)   # ValueError names the file, the field and the reason
    return Path(leg)


def cmd_serve(args: argparse.Namespace) -> int:
    from backend.devices import parse_device_specs
    from backend.serve import serve

    settings = _settings(args, device=args.device, viewer3d=args.viewer3d or None, bench_leg=_bench_leg(args.leg),
                         trusted_proxies=tuple(args.trusted_proxy) if args.trusted_proxy else None)
    if not settings.given("device"):
        settings = settings.model_copy(update={"device": "sim"})   # serve's own default: the simulated leg
    parse_device_specs(settings.device)   # refuse a bad spec before anything starts
    return serve(settings, host=args.host, port=args.port, bootstrap=not args.no_bootstrap_user)


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
            user = create_user(conn, body.username, body.role, body.password,
                               must_change_password=args.one_time)
        except ConflictError as exc:
            raise ValueError(exc.message) from None
    print(f"user {user['username']} ({user['role']}) added to {settings.database_shown}"
          + (": the password must be changed at the first sign-in" if args.one_time else ""))
    return 0


def _user_id(conn: Connection, name: str) -> int:
    from backend.errors import NotFoundError
    from backend.store.users import id_of

    try:
        return id_of(conn, name)
    except NotFoundError as exc:
        raise ValueError(exc.message) from None


def cmd_users_disable(args: argparse.Namespace) -> int:
    from backend.errors import ConflictError
    from backend.store.users import set_disabled

    disabled = args.users_command == "disable"
    with _database(args) as (_, conn):
        try:
            set_disabled(conn, _user_id(conn, args.name), disabled, actor=None)
        except ConflictError as exc:
            raise ValueError(exc.message) from None
    print(f"user {args.name} {'disabled: its sessions ended' if disabled else 'enabled'}")
    return 0


def cmd_users_passwd(args: argparse.Namespace) -> int:
    from pydantic import TypeAdapter, ValidationError

    from backend.schemas.common import Password
    from backend.store.users import set_password

    try:
        password = TypeAdapter(Password).validate_python(_read_password())
    except ValidationError as exc:
        raise ValueError(f"password: {exc.errors()[0]['msg']}") from None
    with _database(args) as (_, conn):
        set_password(conn, _user_id(conn, args.name), password, must_change_password=args.one_time)
    print(f"password of {args.name} set; its sessions ended"
          + (", and it must be changed at the next sign-in" if args.one_time else ""))
    return 0


def cmd_users_list(args: argparse.Namespace) -> int:
    from backend.store.users import list_users

    with _database(args) as (_, conn):
        for u in list_users(conn):
            notes = ["disabled"] * u["disabled"] + ["must change password"] * u["must_change_password"]
            print(f"{u['id']:4d}  {u['username']:24s} {u['role']:12s} {', '.join(notes)}")
    return 0


def cmd_db_upgrade(args: argparse.Namespace) -> int:
    """Run the migrations once, before any API instance starts (``serve`` on the embedded SQLite file also does)."""
    from backend.migrate import head, migrate

    settings = _settings(args)
    if settings.database_url is None:
        settings.data_dir.mkdir(parents=True, exist_ok=True)
    applied = migrate(settings.database, settings.migrations_dir)
    done = ", ".join(applied) if applied else "nothing to apply"
    print(f"{settings.database_shown}: {done}; at revision {head(settings.migrations_dir)}")
    return 0


def _credentials(path: Path) -> dict:
    """The bridge's identity at the broker: a JSON file ``{"username": ..., "password": ..., "ca_file": ...}`` as
    ``POST /api/devices/{id}/credentials`` (admin) answered it (ValueError naming what is missing)."""
    import json

    try:
        found = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"--credentials {path}: not a readable JSON file ({exc})") from None
    missing = [k for k in ("username", "password") if not isinstance(found.get(k), str) or not found[k]]
    if missing:
        raise ValueError(f"--credentials {path}: {', '.join(missing)} missing")
    return found


def _state_dir() -> Path:
    """Where a bridge keeps what waits for its link: ``$XDG_STATE_HOME/quasitune`` (``~/.local/state/quasitune``)."""
    return Path(os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state") / "quasitune"


def cmd_bridge(args: argparse.Namespace) -> int:
    from device_bridge.buses import open_bus
    from device_bridge.gateway import Gateway

    if args.broker:
        from device_bridge.late_buffer import LateBuffer
        from device_bridge.mqtt_bus import MqttBus

        if args.device_id is None or args.credentials is None:
            raise ValueError("--broker needs --device-id and --credentials")
        if not (isinstance(args.buffer_mb, int) and 1 <= args.buffer_mb <= 65536):
            raise ValueError(f"--buffer-mb must be a whole number of MiB in [1, 65536], got {args.buffer_mb!r}")
        who = _credentials(args.credentials)
        path = args.buffer or _state_dir() / f"bridge-{args.device_id}-late.sqlite"
        path.parent.mkdir(parents=True, exist_ok=True)
        buffer = LateBuffer(path, max_bytes=args.buffer_mb * 1024 * 1024)
        if len(buffer):
            print(f"QuasiTune bridge: {len(buffer)} message(s) kept from before, delivered once connected", flush=True)
        far = MqttBus(args.device_id, args.broker, who["username"], who["password"], role="device",
                      ca_file=who.get("ca_file"), late_buffer=buffer)
        to = f"{args.broker} as {args.device_id} (buffer {path}, at most {args.buffer_mb} MiB)"
    else:
        far, to = open_bus(args.to), args.to
        if args.to.startswith("udp_multicast"):
            print("WARNING: udp_multicast has no identity and no encryption: an isolated bench network only; "
                  "use --broker for a leg anywhere else", file=sys.stderr, flush=True)
    node = None
    leg_bus = args.can
    if args.can == "sim":   # the simulated leg as a device of its own, its patient standing on it (demos, benches)
        import can

        from device_bridge.device_node import DeviceNode
        from device_bridge.sim.walker import SimWalker

        leg_bus = f"virtual:quasitune-bridge-sim-{os.getpid()}"
        walker = SimWalker()
        walker.stand(args.mass)
        node = DeviceNode(can.Bus(interface="virtual", channel=leg_bus.split(":", 1)[1]), leg=walker,
                          config=walker.firmware_config()).start()
    gateway = (Gateway.to_broker(open_bus(leg_bus), far) if args.broker else Gateway(open_bus(leg_bus), far)).start()
    # Ctrl-C or SIGTERM (docker stop) end it cleanly, from the moment it says it runs. The main thread waits in short
    # rounds: a signal the kernel hands to another of the bridge's threads only runs its Python handler when the main
    # thread next runs, and a wait without a timeout never returns for it (a loaded CI machine saw a bridge ignore
    # Ctrl-C for good so).
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    print(f"QuasiTune bridge: {args.can} <-> {to}", flush=True)
    try:
        while not stop.is_set() and not gateway.wait(SIGNAL_POLL_S):
            pass
    finally:
        gateway.close()
        if node is not None:
            node.close()
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
                        "INTERFACE:CHANNEL for a real leg on a python-can bus (e.g. socketcan:can0, or mqtt:LEG_ID "
                        "through the broker); several comma-separated; default $QUASITUNE_DEVICE or sim")
    p.add_argument("--trusted-proxy", action="append", default=None, metavar="ADDRESS",
                   help="a reverse proxy whose X-Forwarded-For is believed (repeatable; default "
                        "$QUASITUNE_TRUSTED_PROXIES, comma-separated, else none)")
    p.add_argument("--leg", default=None,
                   help="the simulated leg and person for the simulated device and the bench previews: a leg file "
                        "(device_bridge/sim/leg_file.py) or a repository leg's name; default the nominal bench")
    p.add_argument("--viewer3d", action="store_true",
                   help="also serve viser's 3D view of the leg on a loopback port; viser has no login, so anyone on "
                        "this machine can watch it: only for an engineer's single-user bench")
    p.set_defaults(func=cmd_serve)
    p = sub.add_parser("bridge", help="forward frames between the leg's CAN bus and the servers: through an MQTT "
                                      "broker over TLS (--broker), or another python-can bus (--to)")
    p.add_argument("--can", required=True, help="the leg's bus, INTERFACE:CHANNEL (e.g. socketcan:can0), or 'sim': the "
                                                 "simulated leg in this process, its patient standing on it")
    p.add_argument("--mass", type=float, default=75.0, help="with --can sim: the standing patient's body mass (kg)")
    p.add_argument("--broker", default=None, help="mqtts://HOST:PORT: connect out to the broker as this leg")
    p.add_argument("--device-id", default=None, help="the leg's id at the broker (with --broker)")
    p.add_argument("--credentials", type=Path, default=None,
                   help="JSON file with the leg's username, password and ca_file (with --broker)")
    p.add_argument("--to", default="udp_multicast:239.74.163.2",
                   help="without --broker: the bus 'quasitune serve --device' uses (udp_multicast: an isolated "
                        "bench network only, it has no identity and no encryption)")
    p.add_argument("--buffer", type=Path, default=None,
                   help="with --broker: the file where the leg's messages wait while the broker is out of reach "
                        "(default $XDG_STATE_HOME/quasitune/bridge-ID-late.sqlite); delivered late on reconnection")
    p.add_argument("--buffer-mb", type=int, default=64,
                   help="with --broker: the most the buffer holds (MiB, default 64: about four hours of walking); "
                        "past it the oldest messages go first")
    p.set_defaults(func=cmd_bridge)
    p = sub.add_parser("db", help="the database's schema")
    db_sub = p.add_subparsers(dest="db_command", required=True)
    p = db_sub.add_parser("upgrade", help="bring the database to the newest schema (Alembic), once, before the API "
                                          "instances start; a database of QuasiTune 0.1 is taken over in place")
    p.add_argument("--data-dir", type=Path, default=None, help=DATA_DIR_HELP)
    p.set_defaults(func=cmd_db_upgrade)
    p = sub.add_parser("users", help="manage users")
    users_sub = p.add_subparsers(dest="users_command", required=True)
    p = users_sub.add_parser("add", help="add a user (password from a prompt, or one line of stdin)")
    p.add_argument("name")
    p.add_argument("--role", required=True, choices=ROLES)
    p.add_argument("--one-time", action="store_true",
                   help="a password chosen for someone else: they must change it at their first sign-in")
    p.add_argument("--data-dir", type=Path, default=None, help=DATA_DIR_HELP)
    p.set_defaults(func=cmd_users_add)
    p = users_sub.add_parser("list", help="list users")
    p.add_argument("--data-dir", type=Path, default=None, help=DATA_DIR_HELP)
    p.set_defaults(func=cmd_users_list)
    for name, text in (("disable", "disable an account: it cannot sign in and its open sessions end at once"),
                       ("enable", "enable a disabled account again")):
        p = users_sub.add_parser(name, help=text)
        p.add_argument("name")
        p.add_argument("--data-dir", type=Path, default=None, help=DATA_DIR_HELP)
        p.set_defaults(func=cmd_users_disable)
    p = users_sub.add_parser("passwd", help="set a user's password (from a prompt, or one line of stdin); "
                                            "their sessions end")
    p.add_argument("name")
    p.add_argument("--one-time", action="store_true", help="the user must change it at the next sign-in")
    p.add_argument("--data-dir", type=Path, default=None, help=DATA_DIR_HELP)
    p.set_defaults(func=cmd_users_passwd)
