"""A real ``quasitune serve`` in a subprocess on a free loopback port, and users added to its database.

Used by the tests that need the real server process (restart, SIGKILL, the browser) and by the benchmarks.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from backend.db import connect
from backend.migrate import migrate
from backend.settings import DB_FILE
from backend.store.users import create_user

PASSWORD = "correct-horse-battery"


def add_user(data_dir: Path, name: str, role: str, password: str = PASSWORD) -> None:
    """Create a user in the database under ``data_dir`` (migrated first), as ``quasitune users add`` does."""
    data_dir.mkdir(parents=True, exist_ok=True)
    migrate(data_dir / DB_FILE)
    conn = connect(data_dir / DB_FILE)
    try:
        create_user(conn, name, role, password)
    finally:
        conn.close()


def start_server(data_dir: Path, bootstrap: bool = False, device: str = "none",
                 viewer3d: bool = False, extra_args: tuple[str, ...] = ()) -> tuple[subprocess.Popen, str]:
    """``quasitune serve --port 0`` in a subprocess; returns (process, base URL) once it listens (its further
    stdout lines are left unread in ``process.stdout``)."""
    cmd = [sys.executable, "-m", "backend.cli", "serve", "--port", "0", "--data-dir", str(data_dir), "--device", device]
    if not bootstrap:
        cmd.append("--no-bootstrap-user")
    if viewer3d:
        cmd.append("--viewer3d")
    cmd += extra_args
    err_path = data_dir / "serve.stderr.log"    # a file, not a pipe nobody drains
    with err_path.open("a") as err:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, text=True,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
    line = proc.stdout.readline()
    if "listening on" not in line:
        proc.kill()
        raise RuntimeError(f"server did not start: {line!r} {err_path.read_text()[-2000:]}")
    return proc, line.rsplit(" ", 1)[-1].strip()


@contextmanager
def temporary_server_process(prefix: str, device: str = "none", user: str = "bench", viewer3d: bool = False,
                             colleague: str | None = None) -> Iterator[tuple[subprocess.Popen, str]]:
    """A fresh server on a temporary database with the prosthetist ``user`` (and a second one, ``colleague``, for the
    bench gate's two-person override; password :data:`PASSWORD`); yields its process and base URL and stops it
    afterwards."""
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        data_dir = Path(tmp)
        add_user(data_dir, user, "prosthetist")
        if colleague is not None:
            add_user(data_dir, colleague, "prosthetist")
        proc, base = start_server(data_dir, device=device, viewer3d=viewer3d)
        try:
            yield proc, base
        finally:
            stop_server(proc)


@contextmanager
def temporary_server(prefix: str, device: str = "none", user: str = "bench", viewer3d: bool = False,
                     colleague: str | None = None) -> Iterator[str]:
    """:func:`temporary_server_process`, yielding only the base URL."""
    with temporary_server_process(prefix, device, user, viewer3d, colleague) as (_, base):
        yield base


def stop_server(proc: subprocess.Popen, grace_s: float = 3.0) -> None:
    """SIGTERM, then SIGKILL after ``grace_s``: a bench walk still running for a request nobody waits for any more
    (a preview a closed page asked for) holds the interpreter's exit until it ends, up to ten seconds; the tests
    want none of its result, and a kill loses no acknowledged write (``test_serve``)."""
    proc.terminate()
    try:
        proc.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=10)


def sign_off(base: str, user: str, kind: str, item_id: int, reason: str) -> dict:
    """``user`` (a prosthetist, password :data:`PASSWORD`) signs off a version's bench findings on the server at
    ``base``: the colleague's half of the bench gate's two-person override."""
    import httpx

    with httpx.Client(base_url=base, timeout=60) as c:
        token = c.post("/api/auth/token", data={"username": user, "password": PASSWORD}).json()["access_token"]
        r = c.post(f"/api/{kind}s/{item_id}/signoffs", headers={"Authorization": f"Bearer {token}"},
                   json={"reason": reason})
        r.raise_for_status()
        return r.json()
