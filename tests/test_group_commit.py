"""Group commit (backend/group_commit.py) on a real SQLite file: writes of one loop round share a transaction,
a failing write is rolled back alone, a failing COMMIT stores nothing of the group."""

from __future__ import annotations

import asyncio
import sqlite3
import threading

import pytest

from backend import group_commit
from backend.db import connect, database_path, try_write_lock, write_transaction
from backend.group_commit import GroupCommitter
from backend.pool import ConnectionPool


@pytest.fixture
def pool(tmp_path):
    path = tmp_path / "gc.db"
    conn = connect(path)
    conn.executescript("""
        CREATE TABLE parent (id INTEGER PRIMARY KEY);
        CREATE TABLE item (id INTEGER PRIMARY KEY, label TEXT NOT NULL UNIQUE,
                           parent_id INTEGER REFERENCES parent(id) DEFERRABLE INITIALLY DEFERRED);
        INSERT INTO parent (id) VALUES (1);
    """)
    conn.close()
    p = ConnectionPool(path)
    yield p
    p.close()


def _labels(pool: ConnectionPool) -> list[str]:
    with pool.connection() as conn:
        return [r[0] for r in conn.execute("SELECT label FROM item ORDER BY id")]


def _insert(label: str, parent_id: int = 1):
    def write(conn: sqlite3.Connection) -> int:
        return conn.execute("INSERT INTO item (label, parent_id) VALUES (?, ?)", (label, parent_id)).lastrowid
    return write


def test_writes_of_one_loop_round_share_one_transaction(pool):
    committer = GroupCommitter(pool)

    async def main() -> list[int]:
        return await asyncio.gather(*(committer.run(_insert(f"w{i}")) for i in range(5)))

    ids = asyncio.run(main())
    assert ids == [1, 2, 3, 4, 5]                        # in the order handed in, each its own result
    assert _labels(pool) == [f"w{i}" for i in range(5)]
    assert (committer.stats_.groups, committer.stats_.writes) == (1, 5)


def test_max_group_splits_a_round_into_several_transactions(pool):
    committer = GroupCommitter(pool, max_group=2)

    async def main() -> None:
        await asyncio.gather(*(committer.run(_insert(f"w{i}")) for i in range(5)))

    asyncio.run(main())
    assert _labels(pool) == [f"w{i}" for i in range(5)]
    assert (committer.stats_.groups, committer.stats_.largest_group) == (3, 2)


def test_a_write_that_raises_is_rolled_back_alone(pool):
    committer = GroupCommitter(pool)

    def half_then_fail(conn: sqlite3.Connection) -> None:
        conn.execute("INSERT INTO item (label) VALUES ('half-written')")
        raise LookupError("patient 7 not found")

    async def main() -> list:
        return await asyncio.gather(committer.run(_insert("a")), committer.run(half_then_fail),
                                    committer.run(_insert("b")), return_exceptions=True)

    a, failed, b = asyncio.run(main())
    assert isinstance(failed, LookupError) and "patient 7" in str(failed)
    assert (a, b) == (1, 2)                              # the failed write left no row (nor rowid) behind
    assert _labels(pool) == ["a", "b"]                   # nothing of the failed write, both others
    assert committer.stats_.groups == 1


def test_a_failing_commit_fails_every_write_of_the_group_and_stores_nothing(pool):
    committer = GroupCommitter(pool)

    async def main() -> list:
        # the dangling reference passes its savepoint (the key is deferred) and fails the COMMIT
        return await asyncio.gather(committer.run(_insert("a")), committer.run(_insert("dangling", parent_id=99)),
                                    return_exceptions=True)

    results = asyncio.run(main())
    assert all(isinstance(r, sqlite3.IntegrityError) and "FOREIGN KEY" in str(r) for r in results)
    assert _labels(pool) == []
    with pool.connection() as conn:                      # and the connection is usable again, no open transaction
        assert not conn.in_transaction
        with write_transaction(conn):
            _insert("after")(conn)
    assert _labels(pool) == ["after"]


def test_a_cancelled_request_writes_nothing(pool):
    committer = GroupCommitter(pool)

    async def main() -> None:
        gone = asyncio.ensure_future(committer.run(_insert("gone")))
        kept = asyncio.ensure_future(committer.run(_insert("kept")))
        await asyncio.sleep(0)          # both writes handed in, flush not yet run
        gone.cancel()
        await kept

    asyncio.run(main())
    assert _labels(pool) == ["kept"]


def test_write_transaction_rolls_back_when_the_commit_itself_fails(pool):
    with pool.connection() as conn:
        with pytest.raises(sqlite3.IntegrityError), write_transaction(conn):
            _insert("dangling", parent_id=99)(conn)
        assert not conn.in_transaction
    assert _labels(pool) == []


def test_an_interrupted_group_answers_every_request_and_stores_nothing(pool):
    class Interrupt(BaseException):      # not an Exception: escapes the per-write savepoint handling
        pass

    committer = GroupCommitter(pool)

    def interrupted(conn: sqlite3.Connection) -> None:
        raise Interrupt()

    async def main() -> list:
        # the flush's exception goes to the loop's handler; every request still gets an answer, none hangs
        return await asyncio.wait_for(asyncio.gather(committer.run(_insert("a")), committer.run(interrupted),
                                                     return_exceptions=True), timeout=5)

    results = asyncio.run(main())
    assert all(isinstance(r, RuntimeError) and "nothing of this request was stored" in str(r) for r in results)
    assert _labels(pool) == []


def test_waiting_for_the_write_lock_leaves_the_loop_free_and_gathers_the_writes_that_arrive(pool):
    committer = GroupCommitter(pool)
    with pool.connection() as holder_conn:
        release = try_write_lock(database_path(holder_conn))            # another writer is committing
        assert release is not None
        threading.Timer(0.3, release).start()

        async def main() -> int:
            ticks = 0

            async def ticker() -> None:                   # would stall if the flush blocked the loop
                nonlocal ticks
                while not done.is_set():
                    ticks += 1
                    await asyncio.sleep(0.01)

            done = asyncio.Event()
            tick_task = asyncio.ensure_future(ticker())
            first = asyncio.ensure_future(committer.run(_insert("early")))
            await asyncio.sleep(0.1)
            late = asyncio.ensure_future(committer.run(_insert("late")))   # arrives while the first waits
            await asyncio.gather(first, late)
            done.set()
            await tick_task
            return ticks

        ticks = asyncio.run(main())
    assert ticks >= 15                                   # about 30 in the 0.3 s; the loop was never held
    assert _labels(pool) == ["early", "late"]
    assert (committer.stats_.groups, committer.stats_.writes) == (1, 2)


def test_a_write_lock_held_past_the_busy_timeout_fails_the_waiting_writes_and_stores_nothing(pool, monkeypatch):
    monkeypatch.setattr(group_commit, "BUSY_TIMEOUT_MS", 100)
    committer = GroupCommitter(pool)
    with pool.connection() as holder_conn:
        release = try_write_lock(database_path(holder_conn))
        try:
            async def main() -> list:
                return await asyncio.gather(committer.run(_insert("a")), committer.run(_insert("b")),
                                            return_exceptions=True)
            results = asyncio.run(main())
        finally:
            release()
    assert all(isinstance(r, sqlite3.OperationalError) and "database is locked" in str(r) for r in results)
    assert _labels(pool) == []
    asyncio.run(committer.run(_insert("after")))          # and the committer works again once it is free
    assert _labels(pool) == ["after"]


def test_try_write_lock_refuses_while_another_holds_it_and_takes_it_after(pool):
    with pool.connection() as conn:
        path = database_path(conn)
    release = try_write_lock(path)
    assert release is not None and try_write_lock(path) is None
    release()
    again = try_write_lock(path)
    assert again is not None
    again()
