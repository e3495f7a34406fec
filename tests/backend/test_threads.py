"""The bench's queue: walks one at a time, at most BENCH_QUEUE waiting or walking, BENCH_PER_USER per user; beyond,
refused at once with a Retry-After (503 for everyone, 429 for one user's share), never left to pile up."""

from __future__ import annotations

import threading

import anyio
import pytest

from backend import threads
from backend.errors import ConflictError, ServiceUnavailableError, TooManyError
from backend.jobs import BOARD
from device_bridge.sim import progress

JOB = ("table preview", "table 1", "/api/proposals/1")


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
            done.append(await threads.run_bench(user, JOB, walk, i))

        async with anyio.create_task_group() as tg:
            for i, user in enumerate(["ann", "ann", "bob", "cal"]):
                tg.start_soon(one, user, i)
            with anyio.fail_after(5):                              # all four queued (one walking, three waiting)
                while sum(threads.bench_queue().values()) < 4 or not walking:
                    await anyio.sleep(0.01)
            assert threads.bench_queue() == {"ann": 2, "bob": 1, "cal": 1}
            with pytest.raises(TooManyError, match="ann has 2 bench walks queued"):
                await threads.run_bench("ann", JOB, walk, 9)
            with pytest.raises(ServiceUnavailableError, match="the bench is busy: 4 walks are queued") as busy:
                await threads.run_bench("dee", JOB, walk, 9)
            assert busy.value.extra["retry_after_s"] == threads.BENCH_RETRY_S
            release.set()
        assert sorted(done) == [0, 1, 2, 3] and threads.bench_queue() == {}

    _on_a_thread_of_its_own(main)
    assert most[0] == threads.BENCH_WALKS == 1                      # never two walks at once


def _on_a_thread_of_its_own(main) -> None:
    """``anyio.run(main)`` on a thread of its own (a test before may have left an event loop here); its failure
    raised here."""
    failed: list[BaseException] = []

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


def test_a_job_reports_its_progress_and_stops_where_it_is_when_cancelled():
    """A walk reports each simulated second; its job's fraction and time left follow. Cancelled while walking, the walk
    stops at its next report and the request answers 409 saying who cancelled it; cancelled while queued, it leaves
    the queue at once and the walk never starts. The next job of the kind expects what the last one walked."""
    go_on = threading.Event()
    reports: list[tuple[float, float]] = []
    started: list[str] = []

    def walk(name: str, seconds: int) -> str:
        started.append(name)
        for _ in range(seconds):
            progress.walked(1.0)
            job = next(j for j in BOARD.jobs() if j.state == "walking")
            reports.append((job.fraction(), job.seconds_left()))
            go_on.wait(0.01)
        return name

    async def main() -> None:
        kind = ("table preview", "table 7", "/api/proposals/7")
        assert await threads.run_bench("ann", kind, walk, "first", 40) == "first"
        fractions = [f for f, _ in reports]
        assert fractions == sorted(fractions) and 0 < fractions[0] < fractions[-1] <= 0.99
        assert reports[-1][1] < reports[0][1]                            # less time left as it walks
        assert BOARD.expectation("table preview")[::2] == (40.0, "the last table preview on this server")
        outcome: dict[str, object] = {}

        async def one(name: str, seconds: int) -> None:
            try:
                outcome[name] = await threads.run_bench("bob", kind, walk, name, seconds)
            except ConflictError as exc:
                outcome[name] = exc.message

        async with anyio.create_task_group() as tg:
            tg.start_soon(one, "long", 100_000)
            with anyio.fail_after(5):
                while "long" not in started:
                    await anyio.sleep(0.01)
            tg.start_soon(one, "queued", 1)
            with anyio.fail_after(5):
                while len([j for j in BOARD.jobs() if j.state == "queued" and j.user == "bob"]) < 1:
                    await anyio.sleep(0.01)
            queued = next(j for j in BOARD.jobs() if j.state == "queued" and j.user == "bob")
            BOARD.cancel(queued, "bob")
            with anyio.fail_after(5):
                while "queued" not in outcome:
                    await anyio.sleep(0.01)
            assert "long" not in outcome                                 # left the queue while the other walks
            walking = next(j for j in BOARD.jobs() if j.state == "walking")
            BOARD.cancel(walking, "an admin")
        assert outcome == {"queued": "the table preview of table 7 was cancelled by bob; nothing was stored",
                           "long": "the table preview of table 7 was cancelled by an admin; nothing was stored"}
        assert started == ["first", "long"]                              # the queued walk never started
        assert [j.state for j in BOARD.jobs()][:2] == ["cancelled", "cancelled"] and threads.bench_queue() == {}

    _on_a_thread_of_its_own(main)
