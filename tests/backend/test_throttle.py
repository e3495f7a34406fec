"""The sign-in throttle's three windows, counted in the database: one attacker cannot lock out a clinic, and every API
instance sees the same counts (on SQLite and on PostgreSQL)."""

from __future__ import annotations

import pytest

from backend.db import connect, write_transaction
from backend.throttle import WINDOW_S, LoginThrottle, record_failure

NOW = 1_800_000_000.0


@pytest.fixture
def conn(database):
    c = connect(database)
    yield c
    c.close()


def _fail(conn, name: str, address: str, at: float = NOW) -> None:
    with write_transaction(conn):
        record_failure(conn, name, address, now=at)


def test_failures_lock_a_name_only_at_the_attackers_address(conn):
    t = LoginThrottle()
    for i in range(5):
        _fail(conn, "alice", "10.9.9.9", NOW + i)
    assert t.retry_after_s(conn, "ALICE", "10.9.9.9", now=NOW + 5) == 55    # the attacker waits, whatever the case
    assert t.retry_after_s(conn, "alice", "192.0.2.10", now=NOW + 5) == 0   # alice at her own workstation does not
    assert t.retry_after_s(conn, "bob", "10.9.9.9", now=NOW + 5) == 0


def test_the_wait_ends_when_the_oldest_counted_failure_leaves_the_window(conn):
    t = LoginThrottle(per_user_per_minute=2)
    _fail(conn, "alice", "10.9.9.9", NOW)
    _fail(conn, "alice", "10.9.9.9", NOW + 30)
    assert t.retry_after_s(conn, "alice", "10.9.9.9", now=NOW + 40) == 20   # NOW + 60 frees one
    assert t.retry_after_s(conn, "alice", "10.9.9.9", now=NOW + WINDOW_S + 0.5) == 0


def test_an_address_spraying_names_is_locked_and_only_that_address(conn):
    t = LoginThrottle()
    for i in range(20):
        _fail(conn, f"user{i}", "10.9.9.9")
    assert t.retry_after_s(conn, "someone-else", "10.9.9.9", now=NOW) > 0
    assert t.retry_after_s(conn, "someone-else", "192.0.2.10", now=NOW) == 0


def test_a_name_attacked_from_many_addresses_is_slowed_past_a_larger_count(conn):
    t = LoginThrottle(per_user_anywhere_per_minute=30)
    for i in range(29):
        _fail(conn, "alice", f"10.0.0.{i}")
    assert t.retry_after_s(conn, "alice", "192.0.2.10", now=NOW) == 0
    _fail(conn, "alice", "10.0.0.99")
    assert t.retry_after_s(conn, "alice", "192.0.2.10", now=NOW) > 0


def test_failures_counted_by_one_instance_lock_out_at_another(database, conn):
    """Two API instances are two connections to one database: the lock-out is the database's, not a process's."""
    other = connect(database)
    try:
        for i in range(5):
            _fail(other, "alice", "10.9.9.9", NOW + i)
        assert LoginThrottle().retry_after_s(conn, "alice", "10.9.9.9", now=NOW + 5) > 0
    finally:
        other.close()


def test_rows_no_window_reads_are_purged(conn):
    from sqlalchemy import func, select

    from backend.store.tables import login_failures

    for i in range(10):
        _fail(conn, "alice", "10.9.9.9", NOW + i)
    _fail(conn, "bob", "10.9.9.8", NOW + 10 * WINDOW_S)
    assert conn.execute(select(func.count()).select_from(login_failures)).scalar_one() == 1
