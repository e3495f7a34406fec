"""A throwaway PostgreSQL server for the tests: Debian's ``postgresql`` binaries, a cluster in a temporary folder,
listening on loopback only, run as ``nobody`` when the tests run as root (PostgreSQL refuses root), stopped and
removed afterwards. Each test gets a database of its own (``CREATE DATABASE``), dropped after it."""

from __future__ import annotations

import glob
import os
import shutil
import socket
import subprocess
import tempfile
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import psycopg

SUPERUSER = "quasitune"


def bin_dir() -> Path:
    """The newest installed server's binaries (``/usr/lib/postgresql/N/bin``)."""
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/postgres"), key=lambda p: int(Path(p).parts[-3]))
    if not found:
        raise RuntimeError("PostgreSQL's server is not installed (Debian package 'postgresql'): "
                           "bash scripts/test.sh installs it")
    return Path(found[-1]).parent


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PostgresServer:
    """One cluster: :meth:`start`, :meth:`new_database` per test, :meth:`stop`."""

    def __init__(self) -> None:
        self.root = Path(tempfile.mkdtemp(prefix="quasitune-pg-"))
        self.data = self.root / "data"
        self.port = _free_port()
        self._as_nobody = os.geteuid() == 0

    def _run(self, *args: str) -> list[str]:
        return ["runuser", "-u", "nobody", "--", *args] if self._as_nobody else list(args)

    def start(self) -> None:
        if self._as_nobody:
            shutil.chown(self.root, "nobody", "nogroup")
        bins = bin_dir()
        subprocess.run(self._run(str(bins / "initdb"), "-D", str(self.data), "-U", SUPERUSER, "--auth=trust",
                                 "--encoding=UTF8", "--locale=C.UTF-8", "--no-sync"),
                       check=True, capture_output=True)
        # durability off: a test server only (fsync, full pages); the app's guarantees come from transactions
        subprocess.run(self._run(str(bins / "pg_ctl"), "-D", str(self.data), "-l", str(self.root / "log"), "-w",
                                 "-o", f"-p {self.port} -c listen_addresses=127.0.0.1 -k {self.root} -c fsync=off "
                                       "-c full_page_writes=off -c synchronous_commit=off -c max_connections=200",
                                 "start"), check=True, capture_output=True)
        deadline = time.monotonic() + 30
        while True:
            try:
                psycopg.connect(self.dsn("postgres"), connect_timeout=2).close()
                return
            except psycopg.OperationalError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)

    def dsn(self, database: str) -> str:
        return f"host=127.0.0.1 port={self.port} user={SUPERUSER} dbname={database}"

    def url(self, database: str) -> str:
        """SQLAlchemy's URL for ``database`` (psycopg 3)."""
        return f"postgresql+psycopg://{SUPERUSER}@127.0.0.1:{self.port}/{database}"

    def create_database(self, name: str, template: str | None = None) -> str:
        """A database ``name`` (a copy of ``template`` when given: PostgreSQL copies its files, far faster than
        migrating again); returns its name."""
        with psycopg.connect(self.dsn("postgres"), autocommit=True) as admin:
            admin.execute(f'CREATE DATABASE "{name}"' + (f' TEMPLATE "{template}"' if template else ""))
        return name

    @contextmanager
    def new_database(self, template: str | None = None) -> Iterator[str]:
        """A database for one test (its URL; empty, or a copy of ``template``), dropped afterwards with any connection
        still open to it."""
        name = self.create_database("t_" + uuid.uuid4().hex[:12], template)
        try:
            yield self.url(name)
        finally:
            with psycopg.connect(self.dsn("postgres"), autocommit=True) as admin:
                admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')

    def stop(self) -> None:
        if self.data.exists():
            subprocess.run(self._run(str(bin_dir() / "pg_ctl"), "-D", str(self.data), "-m", "immediate", "-w", "stop"),
                           capture_output=True)
        shutil.rmtree(self.root, ignore_errors=True)
