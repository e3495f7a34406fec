"""Waiting work runs on threads of its own."""

from __future__ import annotations

import threading

import anyio
import pytest

from backend.threads import WAITING_THREADS, run_waiting


def test_waiting_work_runs_off_the_event_loops_thread_and_returns_its_value():
    loop_thread = threading.get_ident()

    async def main() -> tuple[int, int]:
        return await run_waiting(lambda a, b=0: (threading.get_ident(), a + b), 2, b=3)

    ident, total = anyio.run(main)
    assert ident != loop_thread and total == 5


def test_an_error_in_waiting_work_reaches_the_caller():
    def fails() -> None:
        raise ValueError("the device did not answer")

    async def main() -> None:
        await run_waiting(fails)

    with pytest.raises(ValueError, match="did not answer"):
        anyio.run(main)
    assert WAITING_THREADS >= 2
