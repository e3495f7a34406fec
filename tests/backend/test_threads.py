"""The bench's queue: walks one at a time, at most BENCH_QUEUE waiting or walking, BENCH_PER_USER per user; beyond,
refused at once with a Retry-After (503 for everyone, 429 for one user's share), never left to pile up."""

from __future__ import annotations

import threading

import anyio
import pytest

from backend import threads
from backend.errors import ServiceUnavailableError, TooManyError


def test_walks_go_one_at_a_time_and_the_queue_is_bounded_per_user_and_in_all(monkeypatch):
    monkeypatch.setattr(threads, "BENCH_QUEUE", 4)
    release = threading.Event()
    walking: list[int] = []
    most = [0]
    lock = threading.Lock()

    def walk(i: int) -> int:
        with lock:
            walking.append(i)
            most[0] = max(most[0], len(walking))
        release.wait(10)
        with lock:
            walking.remove(i)
        return i

    async def main() -> None:
        done: list[int] = []

        async def one(user: str, i: int) -> None:
            done.append(await threads.run_bench(user, walk, i))

        async with anyio.create_task_group() as tg:
            for i, user in enumerate(["ann", "ann", "bob", "cal"]):
                tg.start_soon(one, user, i)
            with anyio.fail_after(5):                              # all four queued (one walking, three waiting)
                while sum(threads.bench_queue().values()) < 4 or not walking:
                    await anyio.sleep(0.01)
            assert threads.bench_queue() == {"ann": 2, "bob": 1, "cal": 1}
            with pytest.raises(TooManyError, match="ann has 2 bench walks queued"):
                await threads.run_bench("ann", walk, 9)
            with pytest.raises(ServiceUnavailableError, match="the bench is busy: 4 walks are queued") as busy:
                await threads.run_bench("dee", walk, 9)
            assert busy.value.extra["retry_after_s"] == threads.BENCH_RETRY_S
            release.set()
        assert sorted(done) == [0, 1, 2, 3] and threads.bench_queue() == {}

    failed: list[BaseException] = []     # on a thread of its own: a test before may have left an event loop here

    def run() -> None:
        try:
            anyio.run(main)
        except BaseException as exc:   # handed back to the test's thread
            failed.append(exc)

    runner = threading.Thread(target=run)
    runner.start()
    runner.join(30)
    if failed:
        raise failed[0]
    assert most[0] == threads.BENCH_WALKS == 1                      # never two walks at once
