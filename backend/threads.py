"""Where a request's blocking work runs.

Walks on the simulated bench (previews, refinements) are CPU work, not waiting: they run one at a time on a queue of
their own (:func:`run_bench`: at most :data:`BENCH_QUEUE` waiting, :data:`BENCH_PER_USER` per user, refused beyond
with 503 or 429 and a Retry-After), so ten refinements at once never take the request threads a command to a leg
needs (safe mode took 42 s behind them).

Request handlers run in a small pool of worker threads (``Settings.request_threads``, anyio's default limiter): the
process is bound by one interpreter lock, so more threads add no throughput and make the event loop, which streams
live telemetry, queue behind every one of them. Work that mostly *waits* (a push waiting for the device's
acknowledgement, a walk on the simulated bench, the model still loading) would then hold a request thread for
seconds; it runs on threads of its own instead (:func:`run_waiting`), so it never makes other requests queue.
"""

from __future__ import annotations

import functools
import threading
from collections import Counter
from collections.abc import Callable
from typing import TypeVar

import anyio
import anyio.to_thread

from backend.errors import ServiceUnavailableError, TooManyError

T = TypeVar("T")
WAITING_THREADS = 16
_waiting: anyio.CapacityLimiter | None = None


def _limiter() -> anyio.CapacityLimiter:
    global _waiting
    if _waiting is None:
        _waiting = anyio.CapacityLimiter(WAITING_THREADS)
    return _waiting


async def run_waiting(fn: Callable[..., T], *args: object, **kwargs: object) -> T:
    """``fn(*args, **kwargs)`` on a thread for waiting work, outside the request threads."""
    return await anyio.to_thread.run_sync(functools.partial(fn, *args, **kwargs), limiter=_limiter())


BENCH_WALKS = 1        # walks at once: each is CPU-bound under one interpreter lock, a second only slows both
BENCH_QUEUE = 8        # walks waiting or walking at most, all users together
BENCH_PER_USER = 2     # … of one user
BENCH_RETRY_S = 10     # what a refused request is told to wait (about one preview)
_bench: anyio.CapacityLimiter | None = None
_bench_count: Counter[str] = Counter()
_bench_lock = threading.Lock()


def bench_queue() -> dict[str, int]:
    """Walks waiting or walking now, per user (for the API's status and the tests)."""
    with _bench_lock:
        return dict(_bench_count)


async def run_bench(user: str, fn: Callable[..., T], *args: object, **kwargs: object) -> T:
    """``fn(*args, **kwargs)`` (a walk on the bench, or work that starts one) on the bench's queue, for ``user``."""
    global _bench
    with _bench_lock:
        if _bench_count[user] >= BENCH_PER_USER:
            raise TooManyError(f"{user} has {_bench_count[user]} bench walks queued already; wait for them first",
                               retry_after_s=BENCH_RETRY_S)
        if sum(_bench_count.values()) >= BENCH_QUEUE:
            raise ServiceUnavailableError(f"the bench is busy: {sum(_bench_count.values())} walks are queued; try "
                                          f"again in {BENCH_RETRY_S} s", retry_after_s=BENCH_RETRY_S)
        _bench_count[user] += 1
        if _bench is None:
            _bench = anyio.CapacityLimiter(BENCH_WALKS)
    try:
        return await anyio.to_thread.run_sync(functools.partial(fn, *args, **kwargs), limiter=_bench)
    finally:
        with _bench_lock:
            _bench_count[user] -= 1
            if _bench_count[user] <= 0:
                del _bench_count[user]
