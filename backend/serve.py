"""Run the API with uvicorn on a socket bound here, so port 0 works and the real port is printed.

The first line on stdout is ``QuasiTune listening on http://HOST:PORT`` (scripts and tests read it).
"""

from __future__ import annotations

import secrets
import socket
import sys

from backend.app import create_app
from backend.db import connect
from backend.errors import ConflictError
from backend.settings import Settings
from backend.store.users import create_user, list_users

# the first start's accounts: an admin who manages users in the dashboard, and a prosthetist for the clinical work
BOOTSTRAP_USERS = (("admin", "admin", "adds, disables and resets accounts in the dashboard's Users page"),
                   ("prosthetist", "prosthetist", "patients, versions, approvals, pushes and sessions"))


def bootstrap_users(settings: Settings) -> list[tuple[str, str, str, str]]:
    """On a database with no users, create :data:`BOOTSTRAP_USERS`, each with a random one-time password (changed at
    the first sign-in, like an initial admin password); return (name, role, what it does, password) to print once.
    Empty when users exist (or another process starting at the same moment created them)."""
    conn = connect(settings.database)
    try:
        if list_users(conn):
            return []
        made = []
        for name, role, what in BOOTSTRAP_USERS:
            password = secrets.token_urlsafe(12)
            try:
                create_user(conn, name, role, password, must_change_password=True)
            except ConflictError:   # another process starting at the same moment created it first
                continue
            made.append((name, role, what, password))
        return made
    finally:
        conn.close()


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket (ValueError with the reason when the address cannot be used)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        raise ValueError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    sock.listen(2048)
    sock.set_inheritable(True)
    return sock


def one_blas_thread() -> None:
    """Requests run in parallel; BLAS threads inside each tiny solve only spin against them."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


def serve(settings: Settings, host: str = "127.0.0.1", port: int = 8000, bootstrap: bool = True,
          log_level: str = "warning") -> int:
    """Migrate, (maybe) create the first user, bind, print the URL, serve until interrupted; the exit status.

    One process. Several, if ever needed, are uvicorn's own workers behind a reverse proxy (README, deployment).
    """
    import uvicorn

    one_blas_thread()
    app = create_app(settings)
    made = bootstrap_users(settings) if bootstrap else []
    sock = bind(host, port)
    real_host, real_port = sock.getsockname()[:2]
    shown = f"[{real_host}]" if ":" in real_host else real_host
    print(f"QuasiTune listening on http://{shown}:{real_port}", flush=True)
    print(f"  dashboard: http://{shown}:{real_port}/   API docs: http://{shown}:{real_port}/docs", flush=True)
    print(f"  database: {settings.database_shown}", flush=True)
    if made:
        print("  first start: created these accounts, each with a one-time password shown only now (sign in and "
              "choose your own before anything else):", flush=True)
        for name, role, what, password in made:
            print(f"    user '{name}' (role {role}: {what}) password {password}", flush=True)
    if host not in ("127.0.0.1", "::1", "localhost"):
        print("  WARNING: listening beyond loopback; put TLS in front of it", file=sys.stderr, flush=True)
    try:
        # forwarded headers only from the proxies named in the settings (uvicorn trusts 127.0.0.1 by default)
        proxies = list(settings.trusted_proxies)
        uvicorn.Server(uvicorn.Config(app, log_level=log_level, access_log=False, lifespan="on",
                                      proxy_headers=bool(proxies), forwarded_allow_ips=proxies)).run(sockets=[sock])
    finally:
        sock.close()
    return 0
