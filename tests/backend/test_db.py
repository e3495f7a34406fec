"""Writers in different processes queue on SQLite's lock and fail loudly after the busy timeout."""

from __future__ import annotations

import subprocess
import sys

import pytest
from sqlalchemy.exc import OperationalError

from backend import db
from backend.app import prepare_storage
from backend.settings import Settings

pytestmark = [pytest.mark.wallclock, pytest.mark.live]   # another process holds the lock for a time

HOLDER = """
import sys, time
from backend.db import connect, write_transaction
conn = connect(sys.argv[1])
with write_transaction(conn):
    conn.exec_driver_sql("INSERT INTO audit_log (at, actor_name, action, entity) VALUES ('t', 'holder', 'x', 'y')")
    print('holding', flush=True)
    time.sleep(float(sys.argv[2]))
print('released', flush=True)
"""


@pytest.fixture
def db_path(tmp_path):
    settings = Settings(data_dir=tmp_path)
    prepare_storage(settings)
    return settings.db_path


def _hold(db_path, seconds: float) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(db_path), str(seconds)], stdout=subprocess.PIPE,
                            text=True)
    assert proc.stdout.readline().strip() == "holding"
    return proc


def _audit_rows(conn) -> list[str]:
    return list(conn.exec_driver_sql("SELECT actor_name FROM audit_log ORDER BY id").scalars())


def test_a_writer_waits_for_another_process_and_then_commits(db_path):
    conn = db.connect(db_path)
    before = _audit_rows(conn)
    holder = _hold(db_path, 0.5)
    with db.write_transaction(conn):
        conn.exec_driver_sql("INSERT INTO audit_log (at, actor_name, action, entity) VALUES ('t', 'me', 'x', 'y')")
    assert holder.wait(timeout=10) == 0
    # it queued behind the other process's open transaction: both committed, the holder's first
    assert _audit_rows(conn) == [*before, "holder", "me"]


def test_a_writer_gives_up_with_a_clear_error_after_the_busy_timeout(db_path, monkeypatch):
    monkeypatch.setattr(db, "BUSY_TIMEOUT_MS", 300)
    conn = db.connect(db_path)
    before = _audit_rows(conn)
    holder = _hold(db_path, 1.5)
    try:
        with pytest.raises(OperationalError, match="database is locked"), \
                db.write_transaction(conn):
            conn.exec_driver_sql("INSERT INTO audit_log (at, actor_name, action, entity) VALUES ('t', 'me', 'x', 'y')")
    finally:
        assert holder.wait(timeout=10) == 0
    assert _audit_rows(conn) == [*before, "holder"]          # nothing of the refused write
    with db.write_transaction(conn):                           # the lock is free again afterwards
        conn.exec_driver_sql("INSERT INTO audit_log (at, actor_name, action, entity) VALUES ('t', 'me', 'x', 'y')")
    assert _audit_rows(conn)[-1] == "me"
