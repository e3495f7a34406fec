"""Where a request's blocking work runs.

Walks on the simulated bench (previews, refinements) are CPU work, not waiting: they run one at a time on a queue of
their own as jobs with progress and cancel (:func:`run_bench`, ``backend.jobs``: at most :data:`BENCH_QUEUE` waiting,
:data:`BENCH_PER_USER` per user, refused beyond with 503 or 429 and a Retry-After), so ten refinements at once never
take the request threads a command to a leg needs (safe mode took 42 s behind them).

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

from backend.errors import ConflictError, ServiceUnavailableError, TooManyError
from backend.jobs import BOARD, JobCancelled
from device_bridge.sim import progress

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
_bench: anyio.CapacityLimiter | None = None      # the queue's turn (first come, first served)
_walker: anyio.CapacityLimiter | None = None     # the thread the walk runs on (not a request thread)
_bench_lock = threading.Lock()


def bench_queue() -> dict[str, int]:
    """Walks waiting or walking now, per user (for the API's status and the tests)."""
    return dict(Counter(j.user for j in BOARD.jobs() if j.state in ("queued", "walking")))


def _limiters() -> tuple[anyio.CapacityLimiter, anyio.CapacityLimiter]:
    global _bench, _walker
    if _bench is None or _walker is None:
        _bench, _walker = anyio.CapacityLimiter(BENCH_WALKS), anyio.CapacityLimiter(BENCH_WALKS)
    return _bench, _walker


async def run_bench(user: str, job: tuple[str, str, str], fn: Callable[..., T], *args: object,
                    **kwargs: object) -> T:
    """``fn(*args, **kwargs)`` (a walk on the bench, or work that starts one) as a job on the bench's queue, for
    ``user``; ``job``: its kind, what it walks in words and as the API's path (``backend.jobs``). A cancelled job
    answers 409 and stores nothing."""
    kind, target, path = job
    with _bench_lock:
        queued = bench_queue()
        if queued.get(user, 0) >= BENCH_PER_USER:
            raise TooManyError(f"{user} has {queued[user]} bench walks queued already; wait for them first",
                               retry_after_s=BENCH_RETRY_S)
        if sum(queued.values()) >= BENCH_QUEUE:
            raise ServiceUnavailableError(f"the bench is busy: {sum(queued.values())} walks are queued; try "
                                          f"again in {BENCH_RETRY_S} s", retry_after_s=BENCH_RETRY_S)
        record = BOARD.new(kind, target, path, user)
    turn, walker = _limiters()

    def walk() -> T:
        with progress.reporting(record.tick):
            return fn(*args, **kwargs)

    try:
        with anyio.CancelScope() as scope:
            record._scope = scope        # cancelled while it waits: it leaves the queue at once
            async with turn:
                record._scope = None     # walking: the walk stops at its next simulated second instead
                if record.cancelled_by is not None:
                    raise JobCancelled(record.cancelled_by)
                BOARD.started(record)
                result = await anyio.to_thread.run_sync(walk, limiter=walker)
        if scope.cancelled_caught:
            raise JobCancelled(record.cancelled_by or "someone")
    except JobCancelled as exc:
        BOARD.finished(record, "cancelled")
        raise ConflictError(f"the {kind} of {target} was cancelled by {exc.by}; nothing was stored") from None
    except BaseException as exc:
        BOARD.finished(record, "failed", str(exc) or type(exc).__name__)
        raise
    BOARD.finished(record, "done")
    return result
